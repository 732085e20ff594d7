"""Figures of lookout.plotting: layout, styling contract and argument checks.

The estimate figure is checked on small synthetic Datasets laid out like
``Trajectory.to_xarray()`` (one variable per physical quantity, vectors over a
labelled axis, attributes ``units``, ``frame``, ``long_name``, ``angle``): the ship
of Fossen & Strand (1999) and a two-joint arm. The Bode figure is checked on the
real frequency response of the observer of Fossen & Strand (1999) (the
``paper_observer`` fixture).
"""

import math
import re

import matplotlib
import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pytest
import xarray as xr
from matplotlib.patches import Rectangle
from matplotlib.text import Text

from lookout.analysis import frequency_response
from lookout.plotting import is_dense, plot_bode, plot_estimates

DOFS = ("surge", "sway", "yaw")
DPI = 60  # small, so that saving is fast; the size check scales with it
DURATION = 300.0
STEP = 0.5
EARTH = ("north", "east")
BODY = ("surge", "sway")

# the ship's figure per DOF, as in Fossen & Strand (1999), Figs. 9-11: eta, nu, wave, bias rows
SHIP_PANELS = {
    "surge": [("position", "north"), ("velocity", "surge"), ("wave_position", "north"), ("bias_force", "north")],
    "sway": [("position", "east"), ("velocity", "sway"), ("wave_position", "east"), ("bias_force", "east")],
    "yaw": [("heading", None), ("yaw_rate", None), ("wave_heading", None), ("bias_moment", None)],
}
# the y labels those panels must get: (full-run column, zoom column) per row
SHIP_LABELS = {
    "surge": [
        ("Earth-fixed\nposition north (m)", "position north (m)"),
        ("body-fixed\nvelocity surge (m/s)", "velocity surge (m/s)"),
        ("Earth-fixed\nwave position north (m)", "wave position north (m)"),
        ("Earth-fixed\nbias force north (kN)", "bias force north (kN)"),
    ],
    "sway": [
        ("Earth-fixed\nposition east (m)", "position east (m)"),
        ("body-fixed\nvelocity sway (m/s)", "velocity sway (m/s)"),
        ("Earth-fixed\nwave position east (m)", "wave position east (m)"),
        ("Earth-fixed\nbias force east (kN)", "bias force east (kN)"),
    ],
    "yaw": [
        ("Earth-fixed\nheading (deg)", "heading (deg)"),
        ("body-fixed\nyaw rate (deg/s)", "yaw rate (deg/s)"),
        ("Earth-fixed\nwave heading (deg)", "wave heading (deg)"),
        ("Earth-fixed\nbias moment (kN m)", "bias moment (kN m)"),
    ],
}


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def attributes(units, frame, long_name, angle=0):
    return {"units": units, "frame": frame, "long_name": long_name, "angle": angle}


def held(values):
    """Sensor samples at half the recording rate, each held for two records."""
    out = values.copy()
    out[:, 1::2] = values[:, 0:-1:2]
    return out


def synthetic_dataset(runs=1, seeds=None, status=None, duration=DURATION, step=STEP):
    """A ship Dataset laid out like Trajectory.to_xarray(): dims (run, time[, axis])."""
    rng = np.random.default_rng(7)
    time = np.arange(0.0, duration + step / 2, step)
    t = time[None, :]  # (1, time): broadcasts over runs
    offset = np.arange(runs)[:, None]  # each run differs
    ones = np.ones((runs, time.size))

    def noise(scale, *axis):
        return scale * rng.standard_normal((runs, time.size, *axis))

    position = np.stack([0.5 * t + offset, 0.2 * t - offset], axis=-1)
    # the heading grows past +pi, so that the stored (wrapped) heading jumps by 2 pi
    heading = wrap(0.02 * t * ones)
    velocity = np.stack([0.1 + 0.01 * np.sin(0.01 * t) * ones, 0.1 + 0.005 * np.sin(0.01 * t) * ones], axis=-1)
    yaw_rate = 0.02 + 1e-4 * np.sin(0.01 * t) * ones
    wave_position = np.stack([2.0 * np.sin(2 * np.pi * t / 7.0) * ones, 1.5 * np.sin(2 * np.pi * t / 7.0) * ones], axis=-1)
    wave_heading = 0.01 * np.sin(2 * np.pi * t / 7.0) * ones
    bias_force = np.stack([1e4 * np.exp(-t / 500.0) * ones, 5e3 * np.exp(-t / 500.0) * ones], axis=-1)
    bias_moment = 2e4 * np.exp(-t / 500.0) * ones
    measured_position = held(position + wave_position + noise(0.1, 2))
    measured_heading = held(wrap(heading + wave_heading + noise(0.01)))
    measured_position[:, ::17, :] = np.nan  # dropouts
    measured_heading[:, ::17] = np.nan

    earth, body, scalar = ("run", "time", "earth_axis"), ("run", "time", "body_axis"), ("run", "time")
    variables = {
        "position": (earth, position, position + noise(0.05, 2), attributes("m", "Earth-fixed", "low-frequency position")),
        "heading": (scalar, heading, wrap(heading + noise(0.01)), attributes("rad", "Earth-fixed", "low-frequency heading", 1)),
        "velocity": (body, velocity, velocity + noise(0.005, 2), attributes("m/s", "body-fixed", "linear velocity")),
        "yaw_rate": (scalar, yaw_rate, yaw_rate + noise(1e-4), attributes("rad/s", "body-fixed", "yaw rate")),
        "bias_force": (earth, bias_force, bias_force + noise(500.0, 2), attributes("N", "Earth-fixed", "bias force")),
        "bias_moment": (scalar, bias_moment, bias_moment + noise(500.0), attributes("N m", "Earth-fixed", "bias moment")),
        "wave_position": (earth, wave_position, wave_position + noise(0.1, 2), attributes("m", "Earth-fixed", "wave-induced position")),
        "wave_heading": (scalar, wave_heading, wave_heading + noise(0.002), attributes("rad", "Earth-fixed", "wave-induced heading", 1)),
    }
    data = {}
    for name, (dims, truth, estimate, attrs) in variables.items():
        data[name] = xr.Variable(dims, truth, attrs)
        data[f"{name}_hat"] = xr.Variable(dims, estimate, attrs | {"long_name": "estimated " + attrs["long_name"]})
    data["measured_position"] = xr.Variable(earth, measured_position, attributes("m", "Earth-fixed", "measured position"))
    data["measured_heading"] = xr.Variable(scalar, measured_heading, attributes("rad", "Earth-fixed", "measured heading", 1))
    # an input: a variable without an estimate
    data["force_applied"] = xr.Variable(body, noise(1.0, 2), attributes("N", "body-fixed", "applied thrust force"))
    data["status"] = xr.Variable(("run",), np.array(status if status is not None else ["finite"] * runs, dtype=object))
    ds = xr.Dataset(data, coords={"run": np.arange(runs), "time": time, "earth_axis": list(EARTH), "body_axis": list(BODY)})
    if seeds is not None:
        ds = ds.assign_coords(seed=("run", list(seeds)))
    return ds


def arm_dataset(duration=60.0, step=0.1):
    """A two-joint arm: one vector variable over a joint axis, in joint space."""
    rng = np.random.default_rng(11)
    time = np.arange(0.0, duration + step / 2, step)
    angle = np.stack([0.8 * np.sin(0.3 * time), -1.2 + 0.5 * np.cos(0.7 * time)], axis=-1)[None]
    dims = ("run", "time", "revolute_joint")
    attrs = attributes("rad", "joint space", "joint angle")
    measured = angle + 0.01 * rng.standard_normal(angle.shape)
    measured[:, ::13, :] = np.nan
    return xr.Dataset(
        {
            "joint_angle": xr.Variable(dims, angle, attrs),
            "joint_angle_hat": xr.Variable(dims, angle + 0.02 * rng.standard_normal(angle.shape), attrs),
            "measured_joint_angle": xr.Variable(dims, measured, attrs),
        },
        coords={"run": [0], "time": time, "revolute_joint": ["shoulder", "elbow"]},
    )


@pytest.fixture(scope="module")
def ds():
    return synthetic_dataset()


@pytest.fixture(scope="module")
def response(paper_observer):
    return frequency_response(paper_observer)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def figure_text(fig) -> str:
    return "\n".join(t.get_text() for t in fig.findobj(Text))


def lines_by_label(ax):
    return {line.get_label(): line for line in ax.get_lines()}


def legend_labels(fig):
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    return {text.get_text() for legend in legends for text in legend.get_texts()}


def estimate_axes(fig, rows):
    assert len(fig.axes) == 2 * rows
    return np.asarray(fig.axes).reshape(rows, 2)


def assert_png(fig, path, figsize):
    fig.savefig(path, dpi=DPI)
    image = matplotlib.image.imread(path)
    width, height = figsize
    assert image.shape[:2] == (round(height * DPI), round(width * DPI))
    assert float(np.std(image[..., :3])) > 0.05, "the figure looks blank"


def assert_truth_above_estimate(ax):
    lines = lines_by_label(ax)
    assert {"true", "estimate"} <= set(lines), ax.get_ylabel()
    truth, estimate = lines["true"], lines["estimate"]
    for line in (truth, estimate):
        y = np.asarray(line.get_ydata(), dtype=float)
        assert line.get_visible() and line.get_linewidth() > 0 and line.get_alpha() in (None, 1.0)
        assert y.size > 1 and np.isfinite(y).any()
    order = ax.get_children()
    above = truth.get_zorder() > estimate.get_zorder() or (truth.get_zorder() == estimate.get_zorder() and order.index(truth) > order.index(estimate))
    assert above or estimate.get_linestyle() not in ("-", "solid"), f"truth hidden under the estimate: {ax.get_ylabel()!r}"
    assert matplotlib.colors.to_rgb(truth.get_color()) != matplotlib.colors.to_rgb(estimate.get_color())


# --------------------------------------------------------------------------- estimates


@pytest.mark.parametrize("dof", DOFS)
@pytest.mark.slow
def test_estimates_png_has_the_figure_size_and_is_not_blank(ds, dof, tmp_path):
    fig = plot_estimates(ds, SHIP_PANELS[dof])
    assert_png(fig, tmp_path / f"{dof}.png", fig.get_size_inches())
    assert tuple(fig.get_size_inches()) == pytest.approx((11.0, 9.0))


@pytest.mark.parametrize("dof", DOFS)
def test_every_panel_draws_truth_above_estimate(ds, dof):
    fig = plot_estimates(ds, SHIP_PANELS[dof])
    for ax in estimate_axes(fig, 4).ravel():
        assert_truth_above_estimate(ax)


def test_panels_plot_the_selected_components_in_order_and_in_plot_units(ds):
    run0 = ds.isel(run=0)
    fig = plot_estimates(ds, SHIP_PANELS["surge"])
    axes = estimate_axes(fig, 4)
    np.testing.assert_allclose(lines_by_label(axes[0, 0])["true"].get_ydata(), run0.position.sel(earth_axis="north"))
    np.testing.assert_allclose(lines_by_label(axes[1, 0])["estimate"].get_ydata(), run0.velocity_hat.sel(body_axis="surge"))
    # forces are shown in kN
    np.testing.assert_allclose(lines_by_label(axes[3, 0])["true"].get_ydata(), run0.bias_force.sel(earth_axis="north") / 1e3)
    np.testing.assert_allclose(lines_by_label(axes[3, 0])["estimate"].get_ydata(), run0.bias_force_hat.sel(earth_axis="north") / 1e3)
    # any panels, in the order given: a moment in kN m, a rate in deg/s, another component
    fig = plot_estimates(ds, [("bias_moment", None), ("yaw_rate", None), ("position", "east")])
    axes = estimate_axes(fig, 3)
    np.testing.assert_allclose(lines_by_label(axes[0, 0])["true"].get_ydata(), run0.bias_moment / 1e3)
    np.testing.assert_allclose(lines_by_label(axes[1, 0])["true"].get_ydata(), np.degrees(run0.yaw_rate))
    np.testing.assert_allclose(lines_by_label(axes[2, 0])["true"].get_ydata(), run0.position.sel(earth_axis="east"))
    assert [ax.get_ylabel() for ax in axes[:, 1]] == ["bias moment (kN m)", "yaw rate (deg/s)", "position east (m)"]
    assert tuple(fig.get_size_inches()) == pytest.approx((11.0, 3 * 2.25 + 1.2))  # room for title and legend under 4 rows


def test_heading_is_unwrapped_and_in_degrees(ds):
    fig = plot_estimates(ds, SHIP_PANELS["yaw"])
    full, zoomed = estimate_axes(fig, 4)[0]
    assert np.ptp(ds.heading.values) > 6.0, "the synthetic heading must cross +-pi"
    lines = lines_by_label(full)
    truth, estimate = (np.asarray(lines[name].get_ydata()) for name in ("true", "estimate"))
    for name, y in (("true", truth), ("estimate", estimate)):
        assert np.max(np.abs(np.diff(y))) < 60.0, f"{name} heading jumps by ~360 deg: not unwrapped"
    np.testing.assert_allclose(truth, np.degrees(0.02 * ds.time.values), atol=1e-9)
    assert np.max(np.abs(estimate - truth)) < 30.0  # on the same branch as the truth
    # the zoom column too, past 180 deg, with the measurement on the same branch
    lines = lines_by_label(zoomed)
    x = np.asarray(lines["true"].get_xdata())
    np.testing.assert_allclose(lines["true"].get_ydata(), np.degrees(0.02 * x), atol=1e-9)
    assert np.min(lines["true"].get_ydata()) > 180.0
    dots = lines["measured"]
    y = np.asarray(dots.get_ydata(), dtype=float)
    assert y.size > 0 and np.isfinite(y).all()
    assert np.max(np.abs(y - np.degrees(0.02 * np.asarray(dots.get_xdata())))) < 30.0


def test_measurement_is_drawn_as_dots_in_the_zoom_column_only(ds):
    fig = plot_estimates(ds, SHIP_PANELS["sway"])
    axes = estimate_axes(fig, 4)
    assert "measured" not in lines_by_label(axes[0, 0])
    dots = lines_by_label(axes[0, 1])["measured"]
    assert dots.get_linestyle() in ("None", "none", "") and dots.get_marker() not in (None, "None", "none", "")
    x, y = np.asarray(dots.get_xdata(), dtype=float), np.asarray(dots.get_ydata(), dtype=float)
    measured = ds.measured_position.isel(run=0).sel(earth_axis="east")
    np.testing.assert_allclose(y, measured.sel(time=x))  # finite: dropouts are not drawn
    in_window = measured.sel(time=slice(x.min(), None))
    # one dot per new (held) sample, not one per record
    assert 0 < x.size < int(np.isfinite(in_window).sum())
    # rows without a measured_<variable> have no dots
    assert all("measured" not in lines_by_label(ax) for ax in axes[1:].ravel())


def test_a_held_heading_gets_one_dot_per_sample_after_the_unwrapping(ds):
    # the heading is put on the unwrapped truth's branch; a held sample must stay one dot
    fig = plot_estimates(ds, SHIP_PANELS["yaw"])
    dots = lines_by_label(estimate_axes(fig, 4)[0, 1])["measured"]
    x = np.asarray(dots.get_xdata(), dtype=float)
    measured = ds.measured_heading.isel(run=0).sel(time=slice(x.min(), None)).values
    new = np.r_[True, measured[1:] != measured[:-1]] & np.isfinite(measured)
    assert x.size == int(new.sum()) < int(np.isfinite(measured).sum())


def test_legend_names_truth_estimate_measurement_and_window(ds):
    labels = legend_labels(plot_estimates(ds, SHIP_PANELS["sway"]))
    assert {"true", "estimate", "measured (zoom)", "zoom window"} <= labels


@pytest.mark.parametrize(("zoom", "window"), [(50.0, 50.0), (200.0, DURATION / 5)])
def test_zoom_column_shows_the_last_zoom_seconds(ds, zoom, window):
    fig = plot_estimates(ds, SHIP_PANELS["surge"], zoom=zoom)
    end = float(ds.time[-1])
    for full, zoomed in estimate_axes(fig, 4):
        assert zoomed.get_xlim() == pytest.approx((end - window, end))
        assert full.get_xlim() == pytest.approx((0.0, end))
        # the window is marked on the full-run panel
        spans = [p for p in full.patches if isinstance(p, Rectangle)]
        assert any(p.get_x() == pytest.approx(end - window) and p.get_width() == pytest.approx(window) for p in spans)
        # the zoomed curves cover the window: wave motion is resolved, not clipped away
        x = np.asarray(lines_by_label(zoomed)["true"].get_xdata())
        assert x.min() <= end - window and x.max() == pytest.approx(end)
        assert x.size < 0.5 * ds.sizes["time"]


@pytest.mark.parametrize("dof", DOFS)
def test_axis_labels_name_frame_quantity_and_units(ds, dof):
    fig = plot_estimates(ds, SHIP_PANELS[dof])
    axes = estimate_axes(fig, 4)
    assert [(full.get_ylabel(), zoomed.get_ylabel()) for full, zoomed in axes] == SHIP_LABELS[dof]
    assert all(ax.get_xlabel() == "time (s)" for ax in axes[-1])


def test_figure_names_the_run_and_its_seed():
    two = synthetic_dataset(runs=2, seeds=[3, 4])
    fig = plot_estimates(two, SHIP_PANELS["surge"], run=1)
    text = figure_text(fig)
    assert "run 1 of 2" in text and "seed 4" in text and "seed 3" not in text
    axes = estimate_axes(fig, 4)
    np.testing.assert_allclose(lines_by_label(axes[0, 0])["true"].get_ydata(), two.position.isel(run=1).sel(earth_axis="north"))
    # a custom title keeps the run caption
    fig = plot_estimates(two, SHIP_PANELS["yaw"], run=0, title="Fig. 11")
    assert fig.get_suptitle().startswith("Fig. 11") and "seed 3" in fig.get_suptitle()


def test_run_caption_without_seed_for_a_single_run_and_with_a_failed_status(ds):
    text = figure_text(plot_estimates(synthetic_dataset(runs=2), SHIP_PANELS["sway"], run=0))
    assert "run 0 of 2" in text and "seed" not in text
    text = figure_text(plot_estimates(ds, SHIP_PANELS["sway"]))
    assert "run 0 of" not in text and "east" in text
    assert "seed 9" in figure_text(plot_estimates(ds.assign_coords(seed=("run", [9])), SHIP_PANELS["sway"]))
    # a run that did not finish says so; a finite one does not
    failed = synthetic_dataset(runs=2, seeds=[3, 4], status=["finite", "diverged"])
    assert "status: diverged" in plot_estimates(failed, SHIP_PANELS["surge"], run=1).get_suptitle()
    assert "status" not in plot_estimates(failed, SHIP_PANELS["surge"], run=0).get_suptitle()


def test_title_is_used(ds):
    fig = plot_estimates(ds, SHIP_PANELS["surge"], title="Fig. 9: surge")
    assert fig.get_suptitle().startswith("Fig. 9: surge")


def test_works_without_measurement(ds):
    fig = plot_estimates(ds.drop_vars(["measured_position", "measured_heading"]), SHIP_PANELS["yaw"])
    axes = estimate_axes(fig, 4)
    assert all("measured" not in lines_by_label(ax) for ax in axes.ravel())
    assert "measured (zoom)" not in legend_labels(fig) and {"true", "estimate"} <= legend_labels(fig)


def test_panels_work_for_another_plant_a_two_joint_arm(tmp_path):
    arm = arm_dataset()
    fig = plot_estimates(arm, [("joint_angle", "shoulder"), ("joint_angle", "elbow")])
    axes = estimate_axes(fig, 2)
    assert_png(fig, tmp_path / "arm.png", fig.get_size_inches())
    assert tuple(fig.get_size_inches()) == pytest.approx((11.0, 2 * 2.25 + 1.2))
    assert [(full.get_ylabel(), zoomed.get_ylabel()) for full, zoomed in axes] == [
        ("joint space\njoint angle shoulder (deg)", "joint angle shoulder (deg)"),
        ("joint space\njoint angle elbow (deg)", "joint angle elbow (deg)"),
    ]
    for row, joint in enumerate(("shoulder", "elbow")):
        for ax in axes[row]:
            assert_truth_above_estimate(ax)
        lines = lines_by_label(axes[row, 0])
        np.testing.assert_allclose(lines["true"].get_ydata(), np.degrees(arm.joint_angle.isel(run=0).sel(revolute_joint=joint)))
        np.testing.assert_allclose(lines["estimate"].get_ydata(), np.degrees(arm.joint_angle_hat.isel(run=0).sel(revolute_joint=joint)))
        dots = lines_by_label(axes[row, 1])["measured"]
        measured = arm.measured_joint_angle.isel(run=0).sel(revolute_joint=joint)
        np.testing.assert_allclose(dots.get_ydata(), np.degrees(measured.sel(time=np.asarray(dots.get_xdata()))))
    assert all(ax.get_xlabel() == "time (s)" for ax in axes[-1])
    assert {"true", "estimate", "measured (zoom)"} <= legend_labels(fig)
    # the ship's axes are not assumed: the arm has no heading and no earth_axis
    with pytest.raises(ValueError, match=r"^panels\b"):
        plot_estimates(arm, [("joint_angle", "north")])


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"panels": [("heave", None)]}, "panels"),  # no such variable
        ({"panels": [("force_applied", "surge")]}, "panels"),  # no estimate force_applied_hat
        ({"panels": [("position", "up")]}, "panels"),  # no such component
        ({"panels": [("position", None)]}, "panels"),  # a vector needs a component
        ({"panels": [("heading", "north")]}, "panels"),  # a scalar has none
        ({"panels": []}, "panels"),
        ({"panels": "position"}, "panels"),  # not pairs
        ({"panels": [("position",)]}, "panels"),
        ({"panels": [("position", "north", "m")]}, "panels"),
        ({"panels": None}, "panels"),
        ({"run": 1}, "run"),
        ({"run": -1}, "run"),
        ({"run": 0.5}, "run"),
        ({"zoom": 0.0}, "zoom"),
        ({"zoom": -10.0}, "zoom"),
        ({"zoom": float("nan")}, "zoom"),
        ({"zoom": float("inf")}, "zoom"),
        ({"zoom": "wide"}, "zoom"),
    ],
)
def test_bad_arguments_raise_value_error_naming_the_parameter(ds, kwargs, parameter):
    arguments = {"panels": SHIP_PANELS["surge"]} | kwargs
    panels = arguments.pop("panels")
    with pytest.raises(ValueError, match=rf"^{parameter}\b"):
        plot_estimates(ds, panels, **arguments)


# --------------------------------------------------------------------------- comparisons


def long_dataset(duration=3000.0):
    """The ship over 3000 s: the 7 s waves make 430 cycles, a solid band if drawn sample by sample."""
    return synthetic_dataset(duration=duration)


def test_is_dense_tells_wave_motion_over_hours_from_slow_signals():
    time = np.arange(0.0, 3000.0, 0.5)
    rng = np.random.default_rng(3)
    assert is_dense(time, np.sin(2 * np.pi * time / 7.0))
    assert is_dense(time, 5.0 + 0.01 * time + np.sin(2 * np.pi * time / 7.0))  # a trend does not hide it
    assert not is_dense(time, np.sin(2 * np.pi * time / 600.0))
    assert not is_dense(time, 1e4 * np.exp(-time / 500.0) + 50.0 * np.cumsum(rng.standard_normal(time.size)) * np.sqrt(0.5))  # a random walk
    assert not is_dense(time[:300], np.sin(2 * np.pi * time[:300] / 7.0))  # 21 cycles: resolved
    assert not is_dense(time, np.zeros_like(time)) and not is_dense(time, np.full_like(time, np.nan))
    gappy = np.sin(2 * np.pi * time / 7.0)
    gappy[::17] = np.nan
    assert is_dense(time, gappy)


def test_a_dense_signal_is_drawn_as_ranges_that_do_not_hide_each_other():
    """Fossen & Strand Figs. 9-11 over a long run: the wave panel's full run shows the true
    range shaded and outlined in black and the estimate's range outlined in orange, both
    visible; the zoom keeps every sample; slow panels keep every sample in both columns."""
    ds = long_dataset()
    fig = plot_estimates(ds, SHIP_PANELS["surge"])
    axes = estimate_axes(fig, 4)
    wave_full, wave_zoom = axes[2]
    lines = lines_by_label(wave_full)
    truth, estimate = lines["true"], lines["estimate"]
    for line in (truth, estimate):
        y = np.asarray(line.get_ydata(), dtype=float)
        # an upper and a lower edge per bin, broken by one NaN: far fewer points than samples
        assert np.isnan(y).sum() == 1 and y.size < 0.2 * ds.sizes["time"]
    assert_truth_above_estimate(wave_full)
    bands = [c for c in wave_full.collections if c.get_label() == "true (range)"]
    assert len(bands) == 1
    # the true range spans the true wave motion
    upper = np.asarray(truth.get_ydata(), dtype=float)
    assert np.nanmax(upper) == pytest.approx(float(ds.wave_position.isel(run=0).sel(earth_axis="north").max()))
    # every sample in the zoom
    x = np.asarray(lines_by_label(wave_zoom)["true"].get_xdata())
    assert np.all(np.diff(x) > 0) and x.size > 200
    # slow rows unchanged: every sample in the full run
    np.testing.assert_allclose(lines_by_label(axes[0, 0])["true"].get_ydata(), ds.position.isel(run=0).sel(earth_axis="north"))
    assert not [c for c in axes[0, 0].collections if c.get_label() == "true (range)"]
    assert "range per" in axes[0, 0].get_title()
    assert "true (range per bin)" in legend_labels(fig)
    # the 300 s run resolves its 43 wave cycles: no ranges
    short = plot_estimates(synthetic_dataset(), SHIP_PANELS["surge"])
    assert "range" not in estimate_axes(short, 4)[0, 0].get_title()


def test_a_target_is_drawn_between_estimate_and_truth_in_its_own_colour(ds):
    """Kim's Fig. 7: the bias estimate converges to the bias plus the model-error force."""
    lumped = (ds.bias_force + 3e3).assign_attrs(ds.bias_force.attrs | {"long_name": "bias + model-error force"})
    fig = plot_estimates(ds.assign(bias_lumped=lumped), [("bias_force", "north"), ("position", "north")], targets={"bias_force": "bias_lumped"})
    axes = estimate_axes(fig, 2)
    for ax in axes[0]:
        lines = lines_by_label(ax)
        assert {"true", "estimate", "target"} <= set(lines)
        colours = {name: matplotlib.colors.to_rgb(lines[name].get_color()) for name in ("true", "estimate", "target")}
        assert len(set(colours.values())) == 3
        assert lines["estimate"].get_zorder() < lines["target"].get_zorder() < lines["true"].get_zorder()
        assert_truth_above_estimate(ax)
    np.testing.assert_allclose(lines_by_label(axes[0, 0])["target"].get_ydata(), lumped.isel(run=0).sel(earth_axis="north") / 1e3)
    assert all("target" not in lines_by_label(ax) for ax in axes[1])  # only the panels of its variable
    assert "bias + model-error force" in legend_labels(fig)
    with pytest.raises(ValueError, match="^targets"):
        plot_estimates(ds, [("bias_force", "north")], targets={"bias_force": "missing"})
    with pytest.raises(ValueError, match="^targets"):
        plot_estimates(ds, [("bias_force", "north")], targets={"position": "position_hat"})


def test_several_zoom_windows_get_a_column_each_and_are_shaded_on_the_full_run(ds):
    windows = [(0.0, 20.0), (150.0, 170.0)]
    fig = plot_estimates(ds, SHIP_PANELS["sway"], window=windows)
    axes = np.asarray(fig.axes).reshape(4, 3)
    for row in axes:
        full, *zooms = row
        for zoomed, (start, end) in zip(zooms, windows):
            assert zoomed.get_xlim() == pytest.approx((start, end))
            assert_truth_above_estimate(zoomed)
            spans = [p for p in full.patches if isinstance(p, Rectangle)]
            assert any(p.get_x() == pytest.approx(start) and p.get_width() == pytest.approx(end - start) for p in spans)
    assert "measured" in lines_by_label(axes[0, 1]) and "measured" in lines_by_label(axes[0, 2])
    assert fig.get_size_inches()[0] > 11.0
    with pytest.raises(ValueError, match="^window"):
        plot_estimates(ds, SHIP_PANELS["sway"], window=[(0.0, 20.0), (170.0, 150.0)])
    with pytest.raises(ValueError, match="^window"):
        plot_estimates(ds, SHIP_PANELS["sway"], window="start")


def test_a_start_transient_is_left_out_of_the_full_run_scale_and_shown_in_the_zoom():
    """Wondergem's velocities: the initial estimate is far off; it must not set the scale."""
    spiked = synthetic_dataset()
    velocity = spiked.velocity_hat.copy()
    velocity[:, :10, 0] = 5.0  # 50 x the velocity for the first 5 s
    spiked = spiked.assign(velocity_hat=velocity)
    fig = plot_estimates(spiked, [("velocity", "surge"), ("position", "north")], window=(0.0, 20.0), transient=10.0)
    (full, zoomed), (position_full, _) = estimate_axes(fig, 2)
    low, high = full.get_ylim()
    later = spiked.velocity.isel(run=0).sel(body_axis="surge").values
    assert high < 1.0 and low <= later.min() and high >= later.max()
    assert any(t.get_gid() == "transient_note" for t in full.texts)
    assert zoomed.get_ylim()[1] >= 5.0  # the spike is whole in the zoom
    assert not any(t.get_gid() == "transient_note" for t in position_full.texts)  # nothing clipped there
    with pytest.raises(ValueError, match="^transient"):
        plot_estimates(spiked, [("velocity", "surge")], transient=-1.0)


def test_a_long_title_gets_room_of_its_own(ds):
    short = plot_estimates(ds, [("position", "north")], title="one line")
    long = plot_estimates(ds, [("position", "north")], title="line 1\nline 2\nline 3\nline 4")
    assert long.get_size_inches()[1] == pytest.approx(short.get_size_inches()[1] + 2 * 0.25)  # two lines beyond the usual two


# --------------------------------------------------------------------------- Bode

MARKERS = {
    "marker_1/T": "bias_filter_frequency",
    "marker_lambda/kappa": "bias_gain_ratio",
    "marker_w_o": "wave_frequency",
    "marker_w_c": "cutoff_frequency",
}


def bode_axes(fig):
    return np.asarray(fig.axes).reshape(-1, 3)


def annotation_numbers(ax):
    texts = [t for t in ax.texts if t.get_gid() == "min_phase_annotation"]
    assert len(texts) == 1
    text = texts[0].get_text().replace("\N{MINUS SIGN}", "-")
    match = re.search(r"min phase of h (-?\d+\.\d+)° at (\d+(?:\.\d+)?) rad/s.*margin (-?\d+\.\d+)° to -90°", text, re.S)
    assert match, text
    return tuple(float(value) for value in match.groups())


def expected_minimum(response, dof):
    inside = response.frequency <= 10 * response.cutoff_frequency.sel(dof=dof)
    phase = response.h_phase_deg.sel(dof=dof).where(inside)
    return float(phase.min()), float(response.frequency[int(phase.argmin(dim="frequency"))])


def test_bode_png_has_the_figure_size_and_is_not_blank(response, tmp_path):
    fig = plot_bode(response)
    assert_png(fig, tmp_path / "bode.png", fig.get_size_inches())
    assert "Fig. 6" in fig.get_suptitle()


def split_by_dof(response, name, dof):
    """``name`` (hB_magnitude, h_magnitude, velocity_injection_gain) for ``dof`` from the
    split layout: ``<name>_translation`` over ``translation``, ``<name>_yaw``."""
    if dof == "yaw":
        return response[f"{name}_yaw"]
    return response[f"{name}_translation"].sel(translation=dof)


def test_bode_has_one_column_per_dof_with_normalized_magnitudes(response):
    fig = plot_bode(response)
    axes = bode_axes(fig)
    units = {"surge": "N/m", "sway": "N/m", "yaw": "N m/rad"}
    for column, dof in enumerate(DOFS):
        kappa = float(split_by_dof(response, "velocity_injection_gain", dof))
        # the column names its DOF and kappa with its own unit
        assert axes[0, column].get_title().startswith(dof) and axes[0, column].get_title().endswith(units[dof])
        lines = lines_by_label(axes[0, column])
        np.testing.assert_allclose(lines["$h/\\kappa$"].get_ydata(), 20 * np.log10(split_by_dof(response, "h_magnitude", dof) / kappa))
        np.testing.assert_allclose(lines["$h_0$"].get_ydata(), 20 * np.log10(response.h0_magnitude.sel(dof=dof)))
        lines = lines_by_label(axes[1, column])
        np.testing.assert_allclose(lines["$h_B/\\kappa$"].get_ydata(), 20 * np.log10(split_by_dof(response, "hB_magnitude", dof) / kappa))
    assert "dB re 1 s" in axes[0, 0].get_ylabel() and "dimensionless" in axes[1, 0].get_ylabel()
    # the SPR bound in every phase panel
    phase_rows = [row for row in axes if "phase" in row[0].get_ylabel()]
    assert len(phase_rows) == 1
    for ax in phase_rows[0]:
        assert any(np.allclose(line.get_ydata(), -90.0) for line in ax.get_lines())


def test_bode_marks_the_tuning_rule_frequencies_in_every_panel(response):
    # different frequencies per DOF, so that a column showing another DOF's markers fails
    shifted = response.assign(cutoff_frequency=response.cutoff_frequency * xr.DataArray([1.0, 2.0, 3.0], dims="dof"))
    fig = plot_bode(shifted)
    for column, dof in enumerate(DOFS):
        for ax in bode_axes(fig)[:, column]:
            found = {line.get_gid(): line for line in ax.get_lines() if line.get_gid() in MARKERS}
            assert set(found) == set(MARKERS)
            for gid, variable in MARKERS.items():
                assert np.allclose(found[gid].get_xdata(), float(shifted[variable].sel(dof=dof)))
    labels = {text.get_text() for legend in fig.legends for text in legend.get_texts()}
    assert {"1/T", "λ/κ", r"$\omega_o$", r"$\omega_c$"} <= labels


def test_bode_writes_the_minimum_phase_of_h_below_ten_cutoffs(response):
    # yaw's cut-off lowered so that its limit 10 w_c excludes the global minimum
    changed = response.assign(cutoff_frequency=response.cutoff_frequency * xr.DataArray([1.0, 1.0, 0.02], dims="dof"))
    fig = plot_bode(changed)
    phase_row = next(row for row in bode_axes(fig) if "phase" in row[0].get_ylabel())
    minima = []
    for column, dof in enumerate(DOFS):
        lowest, where, margin = annotation_numbers(phase_row[column])
        expected, at = expected_minimum(changed, dof)
        assert lowest == pytest.approx(round(expected, 2), abs=0.006)
        assert margin == pytest.approx(round(expected + 90.0, 2), abs=0.006)
        assert where == pytest.approx(at, rel=5e-3)
        minima.append(lowest)
    assert minima[0] == minima[1] != minima[2]
    # with the paper's gains the margin to -90 deg is below one degree
    assert 0.0 < minima[0] + 90.0 < 1.0


def test_bode_margin_is_readable_on_its_axis(response):
    fig = plot_bode(response)
    lowest, _ = expected_minimum(response, "surge")
    for ax in bode_axes(fig)[-1]:
        bottom, top = ax.get_ylim()
        # the margin (a fraction of a degree) is inside the axis, not squashed onto its edge
        assert ax.get_yscale() == "log" and bottom < lowest + 90.0 < top


def test_bode_title_and_missing_variables(response):
    assert plot_bode(response, title="Fig. 6").get_suptitle() == "Fig. 6"
    for name in ("velocity_injection_gain_yaw", "hB_magnitude_translation", "h_magnitude_yaw"):
        with pytest.raises(ValueError, match=name.rsplit("_", 1)[0]):
            plot_bode(response.drop_vars(name))
    with pytest.raises(ValueError, match="h0_magnitude"):
        plot_bode(response.drop_vars("h0_magnitude"))


#: one UDUNITS unit: no list of per-DOF units ("surge: N/m, yaw: N m/rad")
ONE_UNIT = re.compile(r"^[A-Za-z0-9 /.\-^()]+$")


def test_bode_dataset_has_one_unit_per_variable_and_cf_attributes(response, paper_observer, tmp_path):
    """bode.nc as fossen-strand-1999 writes it: every variable and coordinate with a unit
    has one unit (no ':' or ','), and the file says its conventions and lookout version."""
    from lookout import __version__
    from lookout.results import CONVENTIONS, write_netcdf

    path = write_netcdf(response, tmp_path / "bode.nc", history="test")
    with xr.open_dataset(path) as loaded:
        assert loaded.attrs["Conventions"] == CONVENTIONS and loaded.attrs["lookout_version"] == __version__
        assert "history" in loaded.attrs
        for name, variable in loaded.variables.items():
            if name in ("dof", "translation"):  # labels, no unit
                continue
            unit = variable.attrs.get("units")
            assert unit, f"{name} has no units"
            assert ":" not in unit and "," not in unit and ONE_UNIT.match(unit), f"{name}: {unit!r} is not one unit"
        assert loaded.hB_magnitude_translation.attrs["units"] == "N/m" and loaded.hB_magnitude_yaw.attrs["units"] == "N m/rad"
        assert loaded.h_magnitude_translation.attrs["units"] == "N s/m" and loaded.h_magnitude_yaw.attrs["units"] == "N m s/rad"
        assert loaded.h0_magnitude.attrs["units"] == "s" and loaded.frequency.attrs["units"] == "rad/s"
        assert loaded.translation.values.tolist() == ["surge", "sway"]
        # the split keeps the numbers: kappa per DOF as the observer has it
        kappa = np.r_[loaded.velocity_injection_gain_translation.values, loaded.velocity_injection_gain_yaw.values]
        np.testing.assert_allclose(kappa, np.asarray(paper_observer.velocity_injection_gain))
        # and plot_bode draws the file as it reads it
        assert len(plot_bode(loaded).axes) == 12


def test_bode_of_a_failing_design_shades_the_violation_and_keeps_the_note_clear():
    """Waves of 100 s with the paper's gains: the phase of h dips below -90 deg. The
    frequencies where it does are shaded in the phase and margin panels, the phase axis
    reaches the minimum, and the minimum-phase note sits above every curve."""
    from lookout import PassiveObserver, northern_clipper

    wave_frequency = 2 * math.pi / 100
    observer = PassiveObserver.design(
        northern_clipper(),
        wave_frequency=wave_frequency,
        wave_damping=0.1,
        notch_damping=1.0,
        cutoff_frequency=1.1,
        velocity_injection_gain=[5.91e4, 5.91e4, 3.43e7],
        bias_injection_gain=[2121.0, 2121.0, 1.23e6],
        bias_time_constant=1000.0,
    )
    failing = frequency_response(observer)
    fig = plot_bode(failing)
    rows = bode_axes(fig)
    phase_row = next(row for row in rows if "phase" in row[0].get_ylabel())
    below = failing.frequency.values[failing.h_phase_deg.sel(dof="surge").values <= -90.0]
    assert below.size > 0
    for panel in (phase_row[0], rows[-1][0]):
        spans = [p for p in panel.patches if p.get_label().startswith("SPR violated")]
        assert len(spans) == 1
        left, right = spans[0].get_x(), spans[0].get_x() + spans[0].get_width()
        assert left == pytest.approx(below.min()) and right == pytest.approx(below.max())
    lowest, _, margin = annotation_numbers(phase_row[0])
    assert margin < 0 and phase_row[0].get_ylim()[0] <= lowest
    note = next(t for t in phase_row[0].texts if t.get_gid() == "min_phase_annotation")
    fig.canvas.draw()
    box = note.get_window_extent().transformed(phase_row[0].transData.inverted())
    highest = max(float(np.nanmax(line.get_ydata())) for line in phase_row[0].get_lines() if line.get_gid() is None and len(line.get_ydata()) > 2)
    assert box.y0 > highest
    labels = {text.get_text() for legend in fig.legends for text in legend.get_texts()}
    assert "SPR violated: phase of h ≤ −90°" in labels


def test_bode_draws_one_column_per_loop_for_any_number_of_loops(response):
    fig = plot_bode(response.isel(dof=[2]))
    assert len(fig.axes) == 4 and fig.axes[0].get_title().startswith("yaw")
    fig = plot_bode(response.isel(dof=[0, 1]))
    assert len(fig.axes) == 8


def test_an_azimuth_pointing_astern_is_drawn_without_jumps():
    """An angle wandering across +-180 deg (an azimuth astern) is drawn as a continuous
    line near 180 deg, not as jumps between +-180 that look like turning."""
    from lookout._math import ssa
    from lookout.plotting import _continuous_degrees

    truth = np.pi + 0.2 * np.sin(np.linspace(0.0, 20.0, 500))
    drawn = _continuous_degrees(np.asarray(ssa(truth)))
    assert np.abs(np.diff(drawn)).max() < 1.0
    np.testing.assert_allclose(drawn, np.degrees(truth) - 360.0 * (np.median(np.degrees(truth)) > 180.0), atol=1e-9)
