"""The figures of ``lookout run``: written, listed, sane PNGs, drawn from the Dataset.

One short closed-loop run (Kim 2002: an observer, a reference, a controller and thrust
limits, two runs) is simulated once for the module; the figure functions are checked
on its Dataset and on variants of it (a truth dropped, a limit that cuts, no input).
A short run on a sensor suite with failures (:data:`SUITE`) checks ``references.png``.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import struct

import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.plotting import (
    _panel_layout,
    plot_run_estimates,
    plot_run_input,
    plot_run_reference,
    plot_run_sensor_references,
    run_estimates,
    run_inputs,
    run_references,
)
from lookout.plotting.suite_references import _moving_median, sensor_reference_errors, suite_sensors
from lookout.studies.cli import RUN_FIGURE_DPI, RUN_FIGURES, RUN_FILES, _write_figures

#: meant for one worker (make test runs pytest --dist loadgroup); the run below is shared
#: through a lock in any case, since the groups have not always held
pytestmark = pytest.mark.xdist_group("run_figures")


@contextlib.contextmanager
def _locked(path):
    with open(path.with_name(path.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


@pytest.fixture(scope="module")
def shared(tmp_path_factory):
    """A folder that the xdist workers of this pytest run share."""
    root = tmp_path_factory.getbasetemp()
    root = (root.parent if "PYTEST_XDIST_WORKER" in os.environ else root) / "run_figures"
    root.mkdir(exist_ok=True)
    return root


@pytest.fixture(scope="module")
def scenario(shared):
    path = shared / "kim.toml"
    with _locked(path):
        if not path.exists():
            assert main(["reproduce", "kim-2002", "--duration", "100", "--write-scenario", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def ran(scenario, shared):
    """Kim (2002) closed loop, 100 s, two runs: simulated once per pytest run."""
    out = shared / "out"
    with _locked(out):
        if not (out / "summary.json").exists():
            assert main(["run", str(scenario), "--out", str(out), "--runs", "2"]) == 0
    return out


@pytest.fixture(scope="module")
def ds(ran):
    with xr.open_dataset(ran / "run.nc") as opened:
        return opened.load()


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def png_size(path):
    """(width, height) in pixels from the PNG header."""
    header = path.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name} is not a PNG"
    return struct.unpack(">II", header[16:24])


def panels(fig):
    """{y label of the full-run axis: (full axis, zoom axis)} of a run figure."""
    visible = [ax for ax in fig.axes if ax.get_visible() and ax.axison]
    found = {}
    # the axes come row by row; a panel is a full-run axis followed by its zoom axis on that row
    rows = {}
    for ax in visible:
        rows.setdefault(round(ax.get_position().y0, 3), []).append(ax)
    for row in rows.values():
        row.sort(key=lambda ax: ax.get_position().x0)
        for full, zoom in zip(row[0::2], row[1::2]):
            found[full.get_ylabel()] = (full, zoom)
    return found


def lines(ax):
    return {line.get_label(): line for line in ax.get_lines()}


# ---------------------------------------------------------------------------------- the command


@pytest.mark.slow
def test_the_figures_are_written_listed_and_sane_pngs(ran):
    summary = json.loads((ran / "summary.json").read_text())
    # Kim: estimates, a reference and a limited thrust; no thrusters (thrusters.png: tests/test_thrusters.py), no sensor suite
    drawn = [name for name in RUN_FIGURES if name not in ("thrusters.png", "references.png")]
    assert summary["files"] == list(RUN_FILES) + drawn
    assert sorted(path.name for path in ran.iterdir()) == sorted(summary["files"])
    for name in drawn:
        width, height = png_size(ran / name)
        # at RUN_FIGURE_DPI: between a small figure and one of three columns of panels
        assert 8 * RUN_FIGURE_DPI <= width <= 32 * RUN_FIGURE_DPI and 4 * RUN_FIGURE_DPI <= height <= 20 * RUN_FIGURE_DPI, (name, width, height)
        pixels = matplotlib.image.imread(ran / name)
        assert pixels[..., :3].std() > 0.05, f"{name} is blank"


def test_a_folder_in_the_way_of_a_figure_is_refused_before_simulating(scenario, tmp_path, capsys):
    (tmp_path / "out" / "estimates.png").mkdir(parents=True)
    code = main(["run", str(scenario), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    path = tmp_path / "out" / "estimates.png"
    assert code == 2 and err == f"error: --out: {path} is a folder, and lookout run writes the file estimates.png there; give another --out\n", err
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["estimates.png"]  # nothing simulated, nothing written


@pytest.mark.slow
def test_a_figure_that_does_not_apply_is_not_written_and_an_old_one_is_removed(ds, tmp_path):
    (tmp_path / "reference.png").write_bytes(b"from an earlier run")
    unforced = ds.drop_vars([name for name in ds.data_vars if name.endswith(("_desired", "_desired_rate", "_desired_acceleration"))])
    unforced = unforced.assign({name: ds[name] * 0.0 for name in ds.data_vars if name.endswith(("_commanded", "_applied"))})
    assert _write_figures(unforced, tmp_path, "a title") == ["estimates.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["estimates.png"]


# ---------------------------------------------------------------------------------- estimates


def test_every_component_of_every_estimate_gets_a_panel_with_truth_and_estimate(ds):
    fig = plot_run_estimates(ds)
    found = panels(fig)
    expected = sum(ds[name].sizes.get(ds[name].dims[-1], 1) if ds[name].ndim == 3 else 1 for name, _ in run_estimates(ds))
    assert len(found) == expected == 12  # position, heading, velocity, yaw rate, bias force and moment, wave position and heading
    for label, (full, zoom) in found.items():
        assert {"true", "estimate"} <= set(lines(full)) and {"true", "estimate"} <= set(lines(zoom)), label
    # two columns of six panels, the components of a variable together
    assert len({round(full.get_position().x0, 3) for full, _ in found.values()}) == 2


def test_the_plotted_data_are_the_datasets_values_in_plot_units(ds):
    found = panels(plot_run_estimates(ds))
    full, zoom = found["Earth-fixed\nposition north (m)"]
    np.testing.assert_array_equal(lines(full)["true"].get_ydata(), ds.position.sel(earth_axis="north").isel(run=0).values)
    np.testing.assert_array_equal(lines(full)["estimate"].get_ydata(), ds.position_hat.sel(earth_axis="north").isel(run=0).values)
    np.testing.assert_array_equal(lines(full)["true"].get_xdata(), ds.time.values)
    # the measurement: one dot per new fix, in the zoom only
    dots = lines(zoom)["measured"]
    measured = ds.measured_position.sel(earth_axis="north").isel(run=0)
    assert (
        set(np.round(dots.get_ydata(), 9)) <= set(np.round(measured.values, 9)) and 0 < len(dots.get_ydata()) < zoom.get_lines()[0].get_xdata().size
    )
    assert "measured" not in lines(full)
    # angles in degrees, unwrapped
    full, _ = found["Earth-fixed\nheading (deg)"]
    np.testing.assert_allclose(lines(full)["true"].get_ydata(), np.degrees(np.unwrap(ds.heading.isel(run=0).values)))
    full, _ = found["Earth-fixed\nbias force north (kN)"]
    np.testing.assert_allclose(lines(full)["true"].get_ydata(), ds.bias_force.sel(earth_axis="north").isel(run=0).values * 1e-3)


def test_an_estimate_without_a_truth_is_drawn_alone_and_says_so(ds):
    theta = xr.full_like(ds.heading, 4.2e6).assign_attrs(units="kg", long_name="estimate of the unknown mass entry m11", frame="")
    fig = plot_run_estimates(ds.drop_vars(["bias_force", "bias_moment"]).assign(theta_m11=theta))
    found = panels(fig)
    # labelled by the estimate's long name, less "estimated"
    moment = "Earth-fixed\nbias moment about the\nvertical axis (kN m)"
    for label in ("Earth-fixed\nbias force north (kN)", "Earth-fixed\nbias force east (kN)", moment, "theta m11 (kg)"):
        full, zoom = found[label]
        assert set(lines(full)) == {"estimate"} and set(lines(zoom)) == {"estimate"}, label
        assert "estimate only: no true value recorded" in full.get_legend().get_title().get_text()
    np.testing.assert_array_equal(lines(found["theta m11 (kg)"][0])["estimate"].get_ydata(), theta.isel(run=0).values)
    full, _ = found["Earth-fixed\nposition north (m)"]
    assert "true" in lines(full) and full.get_legend() is None


def test_several_runs_show_run_0_and_say_so(ds):
    for draw in (plot_run_estimates, plot_run_reference, plot_run_input):
        heading = draw(ds, title="scenario").get_suptitle()
        assert heading.startswith("scenario\n") and "run 0 of 2 (seed 0); the figure shows this run only" in heading
    one = ds.isel(run=[1])
    assert "shows this run only" not in plot_run_estimates(one).get_suptitle()
    with pytest.raises(ValueError, match="run must satisfy"):
        plot_run_estimates(ds, run=2)


def test_panels_of_a_variable_stay_in_one_column():
    assert _panel_layout([2, 1, 2, 1, 2, 1, 2, 1], 2) == [list(range(6)), list(range(6, 12))]
    assert _panel_layout([2, 1, 2, 1, 1], 2) == [[0, 1, 2], [3, 4, 5, 6]]  # not [0..3], [4..6]: velocity kept whole
    assert _panel_layout([1, 2], 1) == [[0, 1, 2]]
    assert _panel_layout([9], 2) == [[0, 1, 2, 3, 4], [5, 6, 7, 8]]  # a group larger than a column is split


# ---------------------------------------------------------------------------------- reference and input


def test_the_reference_is_drawn_against_the_truth(ds):
    assert [name for name, _, _ in run_references(ds)] == ["position_desired", "heading_desired"]
    found = panels(plot_run_reference(ds))
    full, zoom = found["Earth-fixed\nposition east (m)"]
    np.testing.assert_array_equal(lines(full)["desired"].get_ydata(), ds.position_desired.sel(earth_axis="east").isel(run=0).values)
    np.testing.assert_array_equal(lines(full)["true"].get_ydata(), ds.position.sel(earth_axis="east").isel(run=0).values)
    assert plot_run_reference(ds.drop_vars(["position_desired", "heading_desired"])) is None


def test_a_scalar_reference_follows_the_component_of_a_vector_named_after_it():
    time = np.arange(0.0, 10.0, 0.1)
    angles = np.stack([np.sin(time), np.cos(time)], axis=-1)[None]
    ds = xr.Dataset(
        {
            "joint_angle": (("run", "time", "revolute_joint"), angles, {"units": "rad", "frame": "joint space", "angle": 1}),
            "pendulum_angle_desired": (("run", "time"), np.cos(time)[None] + 0.1, {"units": "rad", "frame": "joint space", "angle": 1}),
        },
        coords={"run": [0], "time": time, "revolute_joint": ["arm", "pendulum"]},
    )
    assert run_references(ds) == [("pendulum_angle_desired", "joint_angle", "pendulum")]
    ((full, _),) = panels(plot_run_reference(ds)).values()
    np.testing.assert_allclose(lines(full)["true"].get_ydata(), np.degrees(np.cos(time)))
    np.testing.assert_allclose(lines(full)["desired"].get_ydata(), np.degrees(np.cos(time) + 0.1))


def test_the_input_shows_where_the_actuator_limited_it(ds):
    limit = 0.5 * float(np.abs(ds.force_commanded.sel(body_axis="surge")).max())
    limited = ds.assign(force_applied=ds.force_commanded.clip(-limit, limit), moment_applied=ds.moment_commanded)
    found = panels(plot_run_input(limited))
    full, zoom = found["body-fixed\nforce surge (kN)"]
    np.testing.assert_allclose(lines(full)["commanded"].get_ydata(), limited.force_commanded.sel(body_axis="surge").isel(run=0).values * 1e-3)
    np.testing.assert_allclose(lines(full)["applied"].get_ydata(), limited.force_applied.sel(body_axis="surge").isel(run=0).values * 1e-3)
    assert any(collection.get_label() == "marked" for collection in full.collections), "no shading where the limit cut"
    assert "limited" in full.get_legend().get_title().get_text()
    full, _ = found["body-fixed\nmoment (kN m)"]  # this one was not limited
    assert not any(collection.get_label() == "marked" for collection in full.collections) and full.get_legend() is None


def test_an_input_passed_on_unchanged_is_one_curve_and_no_input_is_no_figure(ds):
    passed = ds.assign(force_applied=ds.force_commanded, moment_applied=ds.moment_commanded)
    fig = plot_run_input(passed)
    assert "= commanded throughout" in fig.get_suptitle()
    for full, zoom in panels(fig).values():
        assert set(lines(full)) == set(lines(zoom)) == {"applied (= commanded)"}
    zero = ds.assign({name: ds[name] * 0.0 for name in ("force_commanded", "moment_commanded", "force_applied", "moment_applied")})
    assert run_inputs(zero) == [] and plot_run_input(zero) is None


def test_a_start_spike_is_kept_off_the_scale_and_named(ds):
    spiked = ds.copy()
    applied = spiked.force_applied.values.copy()
    applied[:, 0, 0] = 1e3 * np.abs(applied).max()
    spiked = spiked.assign(
        force_applied=(ds.force_applied.dims, applied, ds.force_applied.attrs),
        force_commanded=(ds.force_applied.dims, applied, ds.force_applied.attrs),
    )
    full, _ = panels(plot_run_input(spiked))["body-fixed\nforce surge (kN)"]
    assert full.get_ylim()[1] < applied[0, 0, 0] * 1e-3 / 10
    assert "clipped: the first" in full.get_legend().get_title().get_text()


def test_a_run_that_diverged_is_zoomed_at_the_end_of_its_finite_part(ds):
    diverged = ds.copy(deep=True)
    cut = ds.time.values[ds.sizes["time"] // 2]
    for name in ("position", "position_hat", "measured_position"):
        diverged[name] = diverged[name].where(diverged.time < cut)
    full, zoom = panels(plot_run_estimates(diverged[["position", "position_hat", "measured_position", "status"]]))["Earth-fixed\nposition north (m)"]
    assert zoom.get_xlim()[1] < cut and zoom.get_xlim()[1] >= ds.time.values[ds.sizes["time"] // 2 - 1]
    assert "last finite" in zoom.get_title()


# ---------------------------------------------------------------------------------- a sensor suite

#: A minute on a sensor suite: two DGNSS receivers at lever arms (the second drifts from
#: 20 s), a hydroacoustic reference with a dropout, two gyrocompasses (the second jumps
#: 2 deg from 30 s to 45 s) and an IMU, the passive observer on the combined channels.
SUITE = """
[simulation]
duration = 60.0

[plant]
kind = "dp-vessel"
[plant.bias]
time_constant = 1000.0
std = [2000.0, 2000.0, 50000.0]
[plant.waves]
kind = "linear"
peak_frequency = 0.8976
damping_ratio = 0.1
amplitude = [3.0, 3.0, 0.01]
[plant.initial]
nu = [0.3, 0.1, 0.005]

[sensors.dgnss1]
kind = "gnss"
lever_arm = [30.0, 5.0]
noise_std = 0.5

[sensors.dgnss2]
kind = "gnss"
lever_arm = [-25.0, -4.0]
noise_std = 0.7
[[sensors.dgnss2.failures]]
mode = "drift"
start = 20.0
rate = [0.2, 0.1]

[sensors.hpr]
kind = "hydroacoustic"
lever_arm = [5.0, 0.0]
[[sensors.hpr.failures]]
mode = "dropout"
start = 10.0
duration = 10.0

[sensors.gyro1]
kind = "gyrocompass"

[sensors.gyro2]
kind = "gyrocompass"
[[sensors.gyro2.failures]]
mode = "jump"
start = 30.0
duration = 15.0
size = 0.03490658503988659

[sensors.imu]
kind = "imu"

[observer]
kind = "passive"
"""


@pytest.fixture(scope="module")
def suite_ran(shared):
    """:data:`SUITE` run by ``lookout run``: simulated once per pytest run."""
    out = shared / "suite-out"
    with _locked(out):
        if not (out / "summary.json").exists():
            path = shared / "suite.toml"
            path.write_text(SUITE)
            assert main(["run", str(path), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def suite_ds(suite_ran):
    with xr.open_dataset(suite_ran / "run.nc") as opened:
        return opened.load()


@pytest.mark.slow
def test_a_sensor_suite_adds_references_png_and_a_plain_sensor_does_not(suite_ran, ds, tmp_path):
    summary = json.loads((suite_ran / "summary.json").read_text())
    assert summary["files"] == list(RUN_FILES) + ["estimates.png", "references.png"]
    width, height = png_size(suite_ran / "references.png")
    assert 8 * RUN_FIGURE_DPI <= width <= 32 * RUN_FIGURE_DPI and 4 * RUN_FIGURE_DPI <= height <= 20 * RUN_FIGURE_DPI, (width, height)
    assert matplotlib.image.imread(suite_ran / "references.png")[..., :3].std() > 0.05
    # Kim's run reads one position-heading sensor: no figure, and one left from an earlier run goes
    assert suite_sensors(ds) is None and plot_run_sensor_references(ds) is None
    (tmp_path / "references.png").write_bytes(b"from an earlier run")
    assert "references.png" not in _write_figures(ds, tmp_path, "a title")
    assert not (tmp_path / "references.png").exists()


def _rotated(heading, arm):
    c, s = np.cos(heading), np.sin(heading)
    return np.stack([c * arm[0] - s * arm[1], s * arm[0] + c * arm[1]], axis=-1)


@pytest.mark.slow
def test_each_reference_is_its_fixes_taken_back_with_the_true_heading_less_the_true_position(suite_ds):
    positions, headings = sensor_reference_errors(suite_ds)
    assert [each.name for each in positions] == ["dgnss1", "dgnss2", "hpr", "combined"]
    assert [each.name for each in headings] == ["gyro1", "gyro2", "combined"]  # the IMU is no position or heading reference
    run = suite_ds.isel(run=0)
    time = run.time.values
    truth = (run.position + run.wave_position).values
    heading = (run.heading + run.wave_heading).values
    dgnss2 = positions[1]
    at = np.isin(time, dgnss2.time)
    # one error per fix (1 s), not per record (0.1 s): a held fix against the moving truth would show the waves
    assert at.sum() == 60 and np.allclose(np.diff(dgnss2.time), 1.0)
    expected = run["dgnss2.measured_position"].values - _rotated(heading, np.array([-25.0, -4.0])) - truth
    np.testing.assert_allclose(dgnss2.error, expected[at])
    # the drift from 20 s is what the errors show: 0.2 and 0.1 m/s, under the noise
    late = dgnss2.time >= 20.0
    slope = np.polyfit(dgnss2.time[late], dgnss2.error[late], 1)[0]
    np.testing.assert_allclose(slope, [0.2, 0.1], atol=0.06)
    # the hydroacoustic reference every 2 s, its dropout as gaps
    hpr = positions[2]
    assert np.allclose(np.diff(hpr.time), 2.0)
    assert np.isnan(hpr.error[(hpr.time >= 10.0) & (hpr.time < 20.0)]).all() and np.isfinite(hpr.error[hpr.time < 10.0]).all()
    # a gyro's error in degrees, wrapped; the jump is 2 deg, and the combined (the median of two: their mean) moves 1 deg
    gyro2, combined = headings[1], headings[2]
    jumped = (gyro2.time >= 30.5) & (gyro2.time < 45.0)
    np.testing.assert_allclose(np.median(gyro2.error[jumped]), 2.0, atol=0.1)
    np.testing.assert_allclose(np.median(combined.error[(combined.time >= 30.5) & (combined.time < 45.0)]), 1.0, atol=0.1)
    np.testing.assert_allclose(np.median(gyro2.error[gyro2.time < 30.0]), 0.0, atol=0.1)
    # each failure's window from its recorded flag
    assert dgnss2.failures == [("dgnss2.drift_failure", [(20.0, pytest.approx(60.0))])]
    assert [(flag, [tuple(np.round(w, 6)) for w in windows]) for flag, windows in gyro2.failures] == [("gyro2.jump_failure", [(30.0, 45.0)])]


@pytest.mark.slow
def test_the_references_figure_draws_every_reference_shades_the_failures_and_zooms_on_the_first(suite_ds):
    fig = plot_run_sensor_references(suite_ds, title="a suite")
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["Earth-fixed\nnorth error (m)", "north error (m)", "Earth-fixed\neast error (m)", "east error (m)"] + [
        "Earth-fixed\nheading error (deg)",
        "heading error (deg)",
    ]
    north_full, north_zoom, _, _, heading_full, heading_zoom = fig.axes
    # the truth: the zero line, thin and black, on top of the errors
    zero = [line for line in north_full.get_lines() if np.array_equal(line.get_ydata(), [0, 0])]
    assert zero and zero[0].get_color() == "k"
    # the zoom: 150 fixes of the fastest instrument, at most a fifth of the run, from a quarter before the first failure
    fifth = 59.9 / 5
    assert north_zoom.get_xlim() == pytest.approx((10.0 - fifth / 4, 10.0 + 3 * fifth / 4))  # the dropout at 10 s
    assert heading_zoom.get_xlim() == pytest.approx((30.0 - fifth / 4, 30.0 + 3 * fifth / 4))  # not 15 s of 0.1 s fixes: a fifth
    assert plot_run_sensor_references(suite_ds, fixes=40).axes[-1].get_xlim() == pytest.approx((29.0, 33.0))  # 4 s of 0.1 s fixes
    # failures shaded: the drift and the dropout on the position rows, the jump on the heading row
    spans = {ax: [patch.get_x() for patch in ax.patches] for ax in (north_full, heading_full)}
    assert sorted(round(x, 6) for x in spans[north_full]) == [10.0, 20.0]
    assert [round(x, 6) for x in spans[heading_full]] == [30.0]
    texts = {text.get_text() for ax in fig.axes for text in ax.texts}
    assert {"dgnss2 drift", "hpr dropout", "gyro2 jump"} <= texts
    legend = {text.get_text() for text in fig.legends[0].get_texts()}
    assert "true (error 0)" in legend and "dgnss1 (gnss at [30, 5] m, 1 s)" in legend and "gyro2.jump_failure (shaded)" in legend
    assert fig.get_suptitle().startswith("a suite\nsensor suite:")
    # several runs: run 0 shown, and said
    two = xr.concat([suite_ds, suite_ds.assign_coords(seed=("run", [1]))], dim="run").assign_coords(run=[0, 1])
    assert "run 0 of 2 (seed 0); the figure shows this run only" in plot_run_sensor_references(two).get_suptitle()
    with pytest.raises(ValueError, match="fixes must be"):
        plot_run_sensor_references(suite_ds, fixes=1)


def test_the_moving_median_keeps_a_step_and_passes_over_a_wild_point():
    time = np.arange(0.0, 100.0, 1.0)
    values = np.where(time >= 50.0, 2.0, 0.0)
    values[20] = 100.0  # a wild point
    values[70] = np.nan  # a dropout
    smooth = _moving_median(time, values, 20.0, np.array([50.0]))
    np.testing.assert_array_equal(smooth, np.where(time >= 50.0, 2.0, 0.0))
    # across the step without its edge, the median crosses it within half a window
    across = _moving_median(time, values, 20.0, np.array([]))
    assert across[39] == 0.0 and across[61] == 2.0
    # an edge a rounding above a sample's time (19.999999999999996 against 20.0) still parts there
    nearly = np.arange(0.0, 40.0, 2.0) + np.where(np.arange(20) == 10, -4e-15, 0.0)
    dropped = np.where((nearly >= 10.0) & (nearly < 19.0), np.nan, 1.0)
    dropped[10] = 5.0
    smooth = _moving_median(nearly, dropped, 100.0, np.array([10.0, 20.0]))
    assert np.isnan(smooth[5:10]).all() and smooth[10] == 1.0
