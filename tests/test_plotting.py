"""Figures of lookout.plotting: layout, styling contract and argument checks.

The estimate figure is checked on a small synthetic Dataset shaped like
``Trajectory.to_xarray()``; the Bode figure on the real frequency response of the
observer of Fossen & Strand (1999) (the ``paper_observer`` fixture).
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
from lookout.plotting import plot_bode, plot_estimates

DOFS = ("surge", "sway", "yaw")
DPI = 60  # small, so that saving is fast; the size check scales with it
DURATION = 300.0
STEP = 0.5

# per row: the frame word in the left y label and the unit per DOF
ROWS = (
    ("Earth-fixed", {"surge": "north", "sway": "east", "yaw": "heading"}, {"surge": "(m)", "sway": "(m)", "yaw": "(deg)"}),
    ("body-fixed", {"surge": "surge", "sway": "sway", "yaw": "yaw rate"}, {"surge": "(m/s)", "sway": "(m/s)", "yaw": "(deg/s)"}),
    ("Earth-fixed", {"surge": "north", "sway": "east", "yaw": "heading"}, {"surge": "(m)", "sway": "(m)", "yaw": "(deg)"}),
    ("Earth-fixed", {"surge": "north", "sway": "east", "yaw": "yaw"}, {"surge": "(kN)", "sway": "(kN)", "yaw": "(kN m)"}),
)


def synthetic_dataset(runs=1, seeds=None, duration=DURATION, step=STEP):
    """A Dataset shaped like Trajectory.to_xarray(): dims (run, time, dof)."""
    rng = np.random.default_rng(7)
    time = np.arange(0.0, duration + step / 2, step)
    shape = (runs, time.size, 3)
    t = time[None, :, None]
    offset = np.arange(runs)[:, None, None]  # each run differs
    # heading grows past +pi so that the stored (wrapped) heading jumps by 2 pi
    eta = np.concatenate([0.5 * t + offset, 0.2 * t - offset, np.broadcast_to(0.02 * t, (runs, time.size, 1))], axis=2)
    eta[..., 2] = (eta[..., 2] + np.pi) % (2 * np.pi) - np.pi
    nu = np.broadcast_to(0.1 + 0.01 * np.sin(0.01 * t) * np.array([1.0, 0.5, 0.01]), shape)
    wave = np.broadcast_to(np.sin(2 * np.pi * t / 7.0) * np.array([2.0, 1.5, 0.01]), shape)
    bias = np.broadcast_to(np.array([1e4, 5e3, 2e4]) * np.exp(-t / 500.0), shape)
    noise = lambda scale: scale * rng.standard_normal(shape)  # noqa: E731
    measurement = eta + wave + noise(0.1)
    measurement[:, ::17, :] = np.nan  # dropouts
    data = {
        "eta": eta,
        "eta_hat": eta + noise(0.05),
        "nu": nu,
        "nu_hat": nu + noise(0.005),
        "wave": wave,
        "wave_hat": wave + noise(0.1),
        "bias": bias,
        "bias_hat": bias + noise(500.0),
        "measurement": measurement,
        "tau": noise(1.0),
    }
    ds = xr.Dataset(
        {name: (("run", "time", "dof"), value) for name, value in data.items()},
        coords={"run": np.arange(runs), "time": time, "dof": list(DOFS)},
    )
    ds["eta_hat"][..., 2] = (ds["eta_hat"][..., 2] + np.pi) % (2 * np.pi) - np.pi
    if seeds is not None:
        ds = ds.assign_coords(seed=("run", list(seeds)))
    return ds


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


def assert_png(fig, path, figsize):
    fig.savefig(path, dpi=DPI)
    image = matplotlib.image.imread(path)
    width, height = figsize
    assert image.shape[:2] == (round(height * DPI), round(width * DPI))
    assert float(np.std(image[..., :3])) > 0.05, "the figure looks blank"


# --------------------------------------------------------------------------- estimates


@pytest.mark.parametrize("dof", DOFS)
def test_estimates_png_has_the_figure_size_and_is_not_blank(ds, dof, tmp_path):
    fig = plot_estimates(ds, dof)
    assert_png(fig, tmp_path / f"{dof}.png", fig.get_size_inches())
    assert tuple(fig.get_size_inches()) == pytest.approx((11.0, 9.0))


@pytest.mark.parametrize("dof", DOFS)
def test_every_panel_draws_truth_above_estimate(ds, dof):
    fig = plot_estimates(ds, dof)
    axes = np.asarray(fig.axes).reshape(4, 2)
    for ax in axes.ravel():
        lines = lines_by_label(ax)
        assert {"true", "estimate"} <= set(lines), ax.get_ylabel()
        truth, estimate = lines["true"], lines["estimate"]
        for line in (truth, estimate):
            y = np.asarray(line.get_ydata(), dtype=float)
            assert line.get_visible() and line.get_linewidth() > 0 and line.get_alpha() in (None, 1.0)
            assert y.size > 1 and np.isfinite(y).any()
        order = ax.get_children()
        above = truth.get_zorder() > estimate.get_zorder() or (
            truth.get_zorder() == estimate.get_zorder() and order.index(truth) > order.index(estimate)
        )
        assert above or estimate.get_linestyle() not in ("-", "solid"), "truth hidden under the estimate"
        assert matplotlib.colors.to_rgb(truth.get_color()) != matplotlib.colors.to_rgb(estimate.get_color())


def test_panels_plot_the_selected_dof_in_plot_units(ds):
    fig = plot_estimates(ds, "surge")
    axes = np.asarray(fig.axes).reshape(4, 2)
    np.testing.assert_allclose(lines_by_label(axes[0, 0])["true"].get_ydata(), ds.eta.isel(run=0).sel(dof="surge"))
    # bias is shown in kN
    np.testing.assert_allclose(lines_by_label(axes[3, 0])["true"].get_ydata(), ds.bias.isel(run=0).sel(dof="surge") / 1e3)


def test_heading_is_unwrapped_and_in_degrees(ds):
    fig = plot_estimates(ds, "yaw")
    axes = np.asarray(fig.axes).reshape(4, 2)
    lines = lines_by_label(axes[0, 0])
    truth, estimate = (np.asarray(lines[name].get_ydata()) for name in ("true", "estimate"))
    for name, y in (("true", truth), ("estimate", estimate)):
        assert np.max(np.abs(np.diff(y))) < 60.0, f"{name} heading jumps by ~360 deg: not unwrapped"
    np.testing.assert_allclose(truth, np.degrees(0.02 * ds.time.values), atol=1e-9)
    assert np.max(np.abs(estimate - truth)) < 30.0  # on the same branch as the truth


def test_legend_names_truth_and_estimate(ds):
    fig = plot_estimates(ds, "sway")
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    labels = {text.get_text() for legend in legends for text in legend.get_texts()}
    assert {"true", "estimate"} <= labels


@pytest.mark.parametrize(("zoom", "window"), [(50.0, 50.0), (200.0, DURATION / 5)])
def test_zoom_column_shows_the_last_zoom_seconds(ds, zoom, window):
    fig = plot_estimates(ds, "surge", zoom=zoom)
    axes = np.asarray(fig.axes).reshape(4, 2)
    end = float(ds.time[-1])
    for full, zoomed in axes:
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
def test_axis_labels_name_frame_and_units(ds, dof):
    fig = plot_estimates(ds, dof)
    axes = np.asarray(fig.axes).reshape(4, 2)
    for (full, zoomed), (frame, direction, unit) in zip(axes, ROWS):
        label = full.get_ylabel()
        assert frame in label and direction[dof] in label and unit[dof] in label, label
        assert unit[dof] in zoomed.get_ylabel()
    assert all(ax.get_xlabel() == "time (s)" for ax in axes[-1])


def test_figure_names_the_run_and_its_seed():
    two = synthetic_dataset(runs=2, seeds=[3, 4])
    fig = plot_estimates(two, "surge", run=1)
    text = figure_text(fig)
    assert "run 1 of 2" in text and "seed 4" in text and "seed 3" not in text
    axes = np.asarray(fig.axes).reshape(4, 2)
    np.testing.assert_allclose(lines_by_label(axes[0, 0])["true"].get_ydata(), two.eta.isel(run=1).sel(dof="surge"))
    # a custom title keeps the run caption
    assert "seed 3" in figure_text(plot_estimates(two, "yaw", run=0, title="Fig. 11"))


def test_run_caption_without_seed_and_for_a_single_run(ds):
    text = figure_text(plot_estimates(synthetic_dataset(runs=2), "sway", run=0))
    assert "run 0 of 2" in text and "seed" not in text
    text = figure_text(plot_estimates(ds, "sway"))
    assert "run 0 of" not in text and "sway" in text
    assert "seed 9" in figure_text(plot_estimates(ds.assign_coords(seed=("run", [9])), "sway"))


def test_title_is_used(ds):
    fig = plot_estimates(ds, "surge", title="Fig. 9: surge")
    assert fig.get_suptitle().startswith("Fig. 9: surge")


def test_works_without_measurement(ds):
    fig = plot_estimates(ds.drop_vars("measurement"), "yaw")
    assert len(fig.axes) == 8


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"dof": "heave"}, "dof"),
        ({"dof": 0}, "dof"),
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
    arguments = {"dof": "surge"} | kwargs
    dof = arguments.pop("dof")
    with pytest.raises(ValueError, match=rf"^{parameter} "):
        plot_estimates(ds, dof, **arguments)


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


def test_bode_has_one_column_per_dof_with_normalized_magnitudes(response):
    fig = plot_bode(response)
    axes = bode_axes(fig)
    for column, dof in enumerate(DOFS):
        assert axes[0, column].get_title().startswith(dof)
        kappa = float(response.velocity_injection_gain.sel(dof=dof))
        lines = lines_by_label(axes[0, column])
        np.testing.assert_allclose(lines["$h/\\kappa$"].get_ydata(), 20 * np.log10(response.h_magnitude.sel(dof=dof) / kappa))
        np.testing.assert_allclose(lines["$h_0$"].get_ydata(), 20 * np.log10(response.h0_magnitude.sel(dof=dof)))
        lines = lines_by_label(axes[1, column])
        np.testing.assert_allclose(lines["$h_B/\\kappa$"].get_ydata(), 20 * np.log10(response.hB_magnitude.sel(dof=dof) / kappa))
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
    with pytest.raises(ValueError, match="velocity_injection_gain"):
        plot_bode(response.drop_vars("velocity_injection_gain"))


def test_bode_of_a_failing_design_shades_the_violation_and_keeps_the_note_clear():
    """Waves of 100 s with the paper's gains: the phase of h dips below -90 deg. The
    frequencies where it does are shaded in the phase and margin panels, the phase axis
    reaches the minimum, and the minimum-phase note sits above every curve."""
    from lookout import PassiveObserver, northern_clipper

    wave_frequency = 2 * math.pi / 100
    observer = PassiveObserver.design(
        northern_clipper(), wave_frequency=wave_frequency, wave_damping=0.1, notch_damping=1.0, cutoff_frequency=1.1,
        velocity_injection_gain=[5.91e4, 5.91e4, 3.43e7], bias_injection_gain=[2121.0, 2121.0, 1.23e6], bias_time_constant=1000.0,
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
