"""The figures of ``lookout run``, for any composition, found from the Dataset's names
(``<name>_hat``, ``theta_<name>``, ``measured_<name>``, ``<name>_desired``,
``<name>_commanded`` / ``<name>_applied``, ``thrust``), drawn as
:func:`lookout.plotting.series.plot_estimates` draws:

* :func:`plot_run_estimates` -- every estimate against its truth;
* :func:`plot_run_reference` -- the reference against the truth;
* :func:`plot_run_input` -- the commanded and the applied input;
* :func:`plot_run_thrusters` -- each thruster's thrust and angle, and the allocation's
  shortfall.
"""

from __future__ import annotations

import math
import textwrap
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from lookout.actuators.failures import flag_prefix
from lookout.plotting._common import _runs
from lookout.plotting._panels import (
    _ESTIMATE_STYLE,
    _check_run,
    _dense_title,
    _draw_panel,
    _make_panel,
    _Panel,
    _panel_figure,
    _panel_layout,
    _panel_legend,
    _quantity,
    _run_caption,
    _run_values,
    _window_parts,
    _windows,
    zoom_window,
)
from lookout.results import limited as limited_input

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Rows of panels in one column of a figure of :func:`plot_run_estimates` (and the
#: others of ``lookout run``) before another column is opened; at most this many columns.
RUN_FIGURE_ROWS = 6
RUN_FIGURE_COLUMNS = 3
#: The reference (desired) and the commanded input: wide and blue, under the thin black truth.
_DESIRED_STYLE = {"color": "C0", "lw": 1.4, "zorder": 2}


def _series_variable(ds: xr.Dataset, name: str) -> bool:
    """Whether ``ds[name]`` is a numeric series per run: dims (run, time[, one label dim])."""
    array = ds[name]
    return array.dims[:2] == ("run", "time") and array.ndim <= 3 and np.issubdtype(array.dtype, np.number)


def _labels(array: xr.DataArray) -> list:
    """The components of a series: its labels, or [None] for a scalar."""
    return array[array.dims[2]].values.tolist() if array.ndim == 3 else [None]


def _names(ds: xr.Dataset) -> list[str]:
    """The names of the data variables of ``ds`` (a results Dataset names them with strings)."""
    return [name for name in ds.data_vars if isinstance(name, str)]


def _matching(ds: xr.Dataset, name: str, like: str) -> str | None:
    """``name`` if the dataset has it as a series with the dims of ``like``."""
    return name if name in ds.data_vars and _series_variable(ds, name) and ds[name].dims == ds[like].dims else None


def run_estimates(ds: xr.Dataset) -> list[tuple[str, str | None]]:
    """``(estimate, truth or None)`` of every estimated variable of a results Dataset.

    An estimate is ``<name>_hat`` (the estimate of the plant variable ``<name>``, or
    a parameter estimate) or ``theta_<name>`` (a parameter estimate); its truth is
    ``<name>`` with the same dims, where the dataset records one.
    """
    found: list[tuple[str, str | None]] = []
    for name in _names(ds):
        if (name.endswith("_hat") or name.startswith("theta_")) and _series_variable(ds, name):
            truth = _matching(ds, name[: -len("_hat")], name) if name.endswith("_hat") else None
            found.append((name, truth))
    return found


def run_references(ds: xr.Dataset) -> list[tuple[str, str | None, object]]:
    """``(reference, truth or None, truth's component)`` of every ``<name>_desired``.

    The truth is ``<name>`` with the same dims, or else a component of a vector of
    the same unit named after it: ``pendulum_angle_desired`` is followed by the
    ``pendulum`` component of ``joint_angle`` (its component is then given, for a
    scalar reference; otherwise it is None).
    """
    found: list[tuple[str, str | None, object]] = []
    for name in _names(ds):
        if not (name.endswith("_desired") and _series_variable(ds, name)):
            continue
        base = name[: -len("_desired")]
        truth, component = _matching(ds, base, name), None
        if truth is None and ds[name].ndim == 2:
            units = ds[name].attrs.get("units")
            for other in _names(ds):
                if _series_variable(ds, other) and ds[other].ndim == 3 and ds[other].attrs.get("units") == units:
                    suffix = other.rsplit("_", 1)[-1]
                    hits = [label for label in _labels(ds[other]) if f"{label}_{suffix}" == base]
                    if hits:
                        truth, component = other, hits[0]
                        break
        found.append((name, truth, component))
    return found


def run_inputs(ds: xr.Dataset) -> list[tuple[str, str]]:
    """``(commanded, applied)`` of every input of a results Dataset that is not zero
    throughout (a plant run unforced has nothing to show)."""
    found: list[tuple[str, str]] = []
    for name in _names(ds):
        if name.endswith("_commanded") and _series_variable(ds, name):
            applied = _matching(ds, name[: -len("_commanded")] + "_applied", name)
            if applied is not None:
                values = np.concatenate([np.asarray(ds[name].values, dtype=float).ravel(), np.asarray(ds[applied].values, dtype=float).ravel()])
                if np.any(np.nan_to_num(values) != 0.0):
                    found.append((name, applied))
    return found


def _run_figure(
    ds: xr.Dataset,
    groups: list[list[_Panel]],
    run: int,
    heading: str,
    *,
    zoom: float,
    compared_style,
    compared_label,
    truth_label,
    marked_label="marked",
    columns: int | None = None,
):
    """A figure of :func:`lookout run`: the panels of each group (a variable's
    components) in columns of up to :data:`RUN_FIGURE_ROWS` rows, each a full run and
    a zoom on its end, and the run it shows in the title."""
    time = np.asarray(ds["time"].values, dtype=float)
    windows = _windows(None, time, zoom)
    # a run that diverged: the zoom shows the end of its finite part instead of an empty window
    finite = np.zeros(time.size, dtype=bool)
    for panel in (panel for group in groups for panel in group):
        for series in (panel.truth, panel.compared):
            if series is not None:
                finite |= np.isfinite(series)
    if finite.any() and not finite[-1] and np.flatnonzero(finite)[-1] > 0:
        start, end = zoom_window(time[: np.flatnonzero(finite)[-1] + 1], zoom)
        windows = [(start, end, f"zoom: last finite {end - start:.3g} s (shaded)")]
    caption = _run_caption(ds, run)
    if ds.sizes["run"] > 1:
        assert caption is not None  # _run_caption captions every dataset of several runs
        caption += f"; the figure shows this run only, of the {ds.sizes['run']} in the dataset"
    heading = heading if caption is None else f"{heading}\n{caption}"
    sizes = [len(group) for group in groups]
    if columns is None:
        columns = min(RUN_FIGURE_COLUMNS, math.ceil(sum(sizes) / RUN_FIGURE_ROWS))
    fig, cells, tops = _panel_figure(_panel_layout(sizes, columns), windows, heading)
    parts = _window_parts(time, windows)
    drawn: set[str] = set()
    for (full, zoomed), panel in zip(cells, [panel for group in groups for panel in group]):
        drawn |= _draw_panel(
            full,
            zoomed,
            panel,
            time,
            windows,
            parts,
            compared_style=compared_style,
            compared_label=compared_label,
            truth_label=truth_label,
            clip_start=True,
        )
    _dense_title(tops, drawn, time)
    _panel_legend(fig, drawn, compared_style=compared_style, compared_label=compared_label, truth_label=truth_label, marked_label=marked_label)
    fig.suptitle(heading)
    return fig


def _compared_groups(ds: xr.Dataset, run: int, rows) -> list[list[_Panel]]:
    """The panels of each row ``(compared, truth, truth's component, shown name, note,
    measured)`` (variables or None): one per component of ``compared``, whose truth is
    that component of ``truth`` (or ``truth``'s given component, for a scalar)."""
    return [
        [
            _make_panel(
                ds[truth if truth is not None else compared].attrs,
                _quantity(name, label),
                _run_values(ds[truth], component if component is not None else label, run) if truth is not None else None,
                _run_values(ds[compared], label, run),
                measured=_run_values(ds[measured], label, run) if measured is not None else None,
                note=note,
            )
            for label in _labels(ds[compared])
        ]
        for compared, truth, component, name, note, measured in rows
    ]


def _heading(title: str | None, what: str) -> str:
    return what if title is None else f"{textwrap.fill(title, 110)}\n{what}"


def plot_run_estimates(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None) -> Figure | None:
    """Every estimated variable of a run against its truth (``estimates.png`` of ``lookout run``).

    One panel per component (north, east, heading; surge, sway, yaw rate; each joint
    by name) of every estimate of :func:`run_estimates`, drawn as
    :func:`plot_estimates` draws them: the whole run and a zoom on its end, the
    estimate in orange under the thin black truth, the measurement of the variable
    (``measured_<name>``) as dots in the zoom. An estimate without a truth in the
    dataset (a parameter estimate, a bias estimate of a plant without a bias) is
    drawn alone, and its panel says so. Many panels are laid out in columns of
    :data:`RUN_FIGURE_ROWS`, the components of a variable kept together.

    Parameters
    ----------
    ds : xarray.Dataset
        Results of ``lookout run`` (:meth:`lookout.Trajectory.to_xarray`).
    run : int, default 0
        The run shown, named with its seed in the title when there are several.
    zoom : float, default 200.0
        Seconds of the zoom at the end of the run (its last fifth when shorter than
        ``5 * zoom``), as in :func:`plot_estimates`.
    title : str, optional
        A first title line (the scenario).

    Returns
    -------
    matplotlib.figure.Figure or None
        None when the dataset holds no estimate.
    """
    run = _check_run(ds, run)
    rows = []
    for estimate, truth in run_estimates(ds):
        base = truth if truth is not None else estimate[: -len("_hat")] if estimate.endswith("_hat") else estimate
        name = base
        long_name = str(ds[estimate].attrs.get("long_name", ""))
        if truth is None and long_name.startswith("estimated "):
            name = long_name[len("estimated ") :]  # "parameter masses[1]" rather than "masses 1"
        note = None if truth is not None else "estimate only: no true value recorded"
        rows.append((estimate, truth, None, name, note, _matching(ds, f"measured_{base}", estimate)))
    groups = _compared_groups(ds, run, rows)
    if not groups:
        return None
    return _run_figure(
        ds,
        groups,
        run,
        _heading(title, "true and estimated: every estimated variable"),
        zoom=zoom,
        compared_style=_ESTIMATE_STYLE,
        compared_label="estimate",
        truth_label="true",
    )


def plot_run_reference(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None) -> Figure | None:
    """The reference against the truth (``reference.png`` of ``lookout run``).

    One panel per component of every ``<name>_desired`` (:func:`run_references`):
    the desired value in blue under the thin black true one, the whole run and a zoom
    on its end, where the tracking error is resolved. A reference without a recorded
    truth is drawn alone, and its panel says so. Parameters as
    :func:`plot_run_estimates`.

    Returns
    -------
    matplotlib.figure.Figure or None
        None when the dataset holds no reference.
    """
    run = _check_run(ds, run)
    rows = [
        (reference, truth, component, reference[: -len("_desired")], None if truth is not None else "reference only: no true value recorded", None)
        for reference, truth, component in run_references(ds)
    ]
    groups = _compared_groups(ds, run, rows)
    if not groups:
        return None
    return _run_figure(
        ds,
        groups,
        run,
        _heading(title, "reference and truth"),
        zoom=zoom,
        compared_style=_DESIRED_STYLE,
        compared_label="desired",
        truth_label="true",
    )


def plot_run_input(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None) -> Figure | None:
    """The commanded and the applied input (``input.png`` of ``lookout run``).

    One panel per component of every input that is not zero throughout
    (:func:`run_inputs`): the commanded input in blue under the thin black applied
    one, the whole run and a zoom on its end; where the actuator changed the command
    (a thrust limit) the time is shaded red, and the panel gives the largest
    difference. Parameters as :func:`plot_run_estimates`.

    Returns
    -------
    matplotlib.figure.Figure or None
        None when the dataset holds no input that is not zero throughout.
    """
    run = _check_run(ds, run)
    groups = []
    any_limited = False
    for commanded, applied in run_inputs(ds):
        base = commanded[: -len("_commanded")]
        panels = []
        for label in _labels(ds[commanded]):
            wanted, got = _run_values(ds[commanded], label, run), _run_values(ds[applied], label, run)
            limited, finite = limited_input(wanted, got)
            panel = _make_panel(ds[applied].attrs, _quantity(base, label), got, wanted, marked=limited)
            if limited.any():
                any_limited = True
                assert panel.truth is not None  # the applied input, given as the truth
                peak = np.max(np.abs(panel.truth[finite]))
                panel.note = (
                    f"limited {limited.sum() / finite.sum():.0%} of the time; applied at most {peak:.3g} {panel.quantity.rsplit('(', 1)[-1][:-1]}"
                )
            panels.append(panel)
        groups.append(panels)
    if not groups:
        return None
    if any_limited:
        return _run_figure(
            ds,
            groups,
            run,
            _heading(title, "commanded and applied input"),
            zoom=zoom,
            compared_style=_DESIRED_STYLE,
            compared_label="commanded",
            truth_label="applied",
            marked_label="limited: applied ≠ commanded",
        )
    # the actuator passed every command on: one curve, and the title says so
    for panel in (panel for group in groups for panel in group):
        panel.compared = None
    return _run_figure(
        ds,
        groups,
        run,
        _heading(title, "applied input (= commanded throughout: the actuator limited nothing)"),
        zoom=zoom,
        compared_style=_DESIRED_STYLE,
        compared_label="commanded",
        truth_label="applied (= commanded)",
    )


def _continuous_degrees(angle: np.ndarray) -> np.ndarray:
    """An angle series in degrees without its +-180 deg jumps (an azimuth pointing astern
    would otherwise be drawn as vertical lines that look like turning), shifted by whole
    turns so that its median lies in (-180, 180]."""
    degrees = np.degrees(np.unwrap(np.asarray(angle, dtype=float)))
    return degrees - 360.0 * np.round(np.median(degrees) / 360.0)


def _thruster_failures(ds: xr.Dataset, names: list[str], run: int) -> list[tuple[int, str, np.ndarray]]:
    """``(thruster index, mode, active)`` of each recorded thruster failure
    (``NAME.MODE_failure``, :func:`lookout.actuators.failures.flag_signal`) that is
    active at some sample of ``run``."""
    identifiers = {flag_prefix(name): i for i, name in enumerate(names)}
    found = []
    for variable in ds.data_vars:
        prefix, _, suffix = str(variable).partition(".")
        if prefix in identifiers and suffix.endswith("_failure"):
            active = ds[variable].isel(run=run).values > 0.5
            if active.any():
                mode = suffix.removesuffix("_failure").rstrip("0123456789")
                found.append((identifiers[prefix], mode, active))
    return found


def plot_run_thrusters(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None) -> Figure | None:
    """Each thruster's thrust and angle, commanded and delivered, and the allocation's
    shortfall (``thrusters.png`` of ``lookout run`` with a thruster actuator).

    Left the whole run, right a zoom on its last ``zoom`` seconds (on a run shorter than
    five times that, its last fifth: :func:`zoom_window`). Top: thrust per
    thruster, the delivered thrust solid over the commanded one dotted, in the same
    colour, a failed thruster's time hatched in its colour and named with the failure's
    mode. Middle: the angle of each azimuth and rudder (deg), delivered solid,
    commanded dotted (tunnels have none). Bottom: the largest part of the commanded
    force the thrusters left unproduced, as a fraction of their reach, with the time
    the allocation was saturated shaded.

    Returns
    -------
    matplotlib.figure.Figure or None
        None when the dataset holds no thrusters (no variable ``thrust``).
    """
    import matplotlib.pyplot as plt

    run = _check_run(ds, run)
    if "thrust" not in ds.variables or "thruster" not in ds.dims:
        return None
    time = ds["time"].values
    names = [str(n) for n in ds["thruster"].values]
    turning = [
        i
        for i, name in enumerate(names)
        if np.ptp(ds["thruster_angle"].isel(run=run, thruster=i).values) > 0
        or np.ptp(ds["thruster_angle_commanded"].isel(run=run, thruster=i).values) > 0
    ]
    figure, axes = plt.subplots(3, 2, figsize=(12, 8.5), sharex="col", gridspec_kw={"width_ratios": (2, 1)}, layout="constrained")
    start = zoom_window(time, zoom)[0]  # the estimates' rule: on a short run the last fifth, never the whole run again
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    saturated = ds["allocation_saturated"].isel(run=run).values > 0.5
    failed = _thruster_failures(ds, names, run)
    for column, (low, high) in enumerate(((time[0], time[-1]), (start, time[-1]))):
        window = (time >= low) & (time <= high)
        thrust_axis, angle_axis, short_axis = axes[:, column]
        for i, name in enumerate(names):
            colour = colours[i % len(colours)]
            thrust_axis.plot(time[window], ds["thrust_commanded"].isel(run=run, thruster=i).values[window] / 1e3, ":", color=colour, lw=1.0)
            thrust_axis.plot(time[window], ds["thrust"].isel(run=run, thruster=i).values[window] / 1e3, "-", color=colour, lw=1.1, label=name)
            if i in turning:
                angle_axis.plot(
                    time[window],
                    _continuous_degrees(ds["thruster_angle_commanded"].isel(run=run, thruster=i).values)[window],
                    ":",
                    color=colour,
                    lw=1.0,
                )
                angle_axis.plot(
                    time[window],
                    _continuous_degrees(ds["thruster_angle"].isel(run=run, thruster=i).values)[window],
                    "-",
                    color=colour,
                    lw=1.1,
                    label=name,
                )
        for k, (i, mode, active) in enumerate(failed):
            # a failed thruster's time hatched in its colour, on the thrust panel
            colour = colours[i % len(colours)]
            for first, last in _runs(time[window], active[window]):
                thrust_axis.axvspan(first, last, facecolor="none", edgecolor=colour, hatch="//", alpha=0.5, lw=0)
                thrust_axis.annotate(
                    f"{names[i]} {mode}",
                    (first, 1.0),
                    xycoords=("data", "axes fraction"),
                    xytext=(2, -2 - 10 * k),  # one line per failure: two in one window do not overlap
                    textcoords="offset points",
                    ha="left",
                    va="top",
                    fontsize=8,
                    color=colour,
                )
        short_axis.plot(time[window], ds["allocation_shortfall"].isel(run=run).values[window], color="k", lw=1.0, label="shortfall")
        for first, last in _runs(time[window], saturated[window]):
            short_axis.axvspan(first, last, color="tab:red", alpha=0.15, lw=0)
        thrust_axis.set_ylabel("thrust (kN)")
        angle_axis.set_ylabel("angle (deg)")
        short_axis.set_ylabel("shortfall (1)")
        short_axis.set_xlabel("time (s)")
        for axis in (thrust_axis, angle_axis, short_axis):
            axis.grid(alpha=0.3)
            axis.set_xlim(low, high)
        thrust_axis.set_title("full run" if column == 0 else f"zoom: last {time[-1] - start:g} s")
    if not turning:
        for axis in axes[1]:
            axis.text(0.5, 0.5, "no azimuth or rudder", ha="center", va="center", transform=axis.transAxes)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    handles += [
        plt.Line2D([], [], color="grey", ls="-"),
        plt.Line2D([], [], color="grey", ls=":"),
        plt.matplotlib.patches.Patch(color="tab:red", alpha=0.15),
    ]
    labels += ["delivered", "commanded", "allocation saturated"]
    if failed:
        handles.append(plt.matplotlib.patches.Patch(facecolor="none", edgecolor="grey", hatch="//"))
        labels.append("thruster failed")
    figure.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 7), frameon=False)
    figure.suptitle(_heading(title, f"thrusters: thrust, angle and allocation shortfall\nrun {run} of {ds.sizes['run']}"))
    return figure
