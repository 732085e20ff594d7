"""The position and heading references of a sensor suite against the truth
(``references.png`` of ``lookout run``, :func:`plot_run_sensor_references`).

Each position reference's fixes are taken back to the vessel's reference point with the
true heading, ``p_i = y_i - R(psi) r_i`` (``y_i + anchor`` first for a taut wire), and
drawn as their error from the true position, waves included, ``p_i - (p + p_w)``; each
gyrocompass's as its error from the true heading ``psi + psi_w``. An error is taken at
the instrument's own sample instants only: between them the suite holds the last fix,
and a held fix against the moving truth would show the waves, not the instrument. The
combining stage's ``measured_position`` and ``measured_heading`` are drawn the same way,
at the instants its fastest position reference (gyrocompass) samples, as the stage gives
them (its lever arms taken back with the measured heading). The failures of the suite
(``NAME.MODE_failure``, 1 while a failure acts) are shaded in their sensor's colour.

What the figure needs of the Dataset beyond the recorded channels (the instruments'
kinds, lever arms, anchors and sample periods) it reads from the composition that
``lookout run`` stores in the attributes (``ds.attrs["composition"]``, JSON).
"""

from __future__ import annotations

import json
import textwrap
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr

from lookout.plotting._common import _runs
from lookout.plotting._panels import _TRUTH_STYLE, _check_run, _run_caption, _without_zorder

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: The instrument kinds drawn, and the channel of each: position references (taken back
#: to the reference point) and heading references.
POSITION_KINDS = {"gnss": "measured_position", "hydroacoustic": "measured_position", "taut-wire": "measured_offset"}
HEADING_KINDS = {"gyrocompass": "measured_heading"}
#: Seconds of the moving median drawn over the fixes across the full run.
SMOOTHING = 60.0
#: Samples of a row's fastest instrument in its zoom.
ZOOM_FIXES = 150
#: Each sensor's colour, in the order of the suite (C1, orange, is the combined channel's).
_SENSOR_COLOURS = ("C0", "C2", "C4", "C9", "C5", "C6", "C8", "C7")
_COMBINED_COLOUR = "C1"
_FAILURE_ALPHA = 0.13
#: The zoom window's edges in the full-run column (a fill would mix with the failures' shading).
_ZOOM_EDGE_STYLE: dict[str, Any] = {"color": "0.3", "ls": "--", "lw": 0.9, "zorder": 0.6}


@dataclass
class ReferenceErrors:
    """One instrument's (or the combining stage's) errors at its sample instants."""

    name: str
    description: str
    colour: str
    time: np.ndarray
    #: (n, 2) north and east (m), or (n, 1) heading (deg)
    error: np.ndarray
    #: seconds between its samples
    period: float
    #: (name of the flag, [(first, last), ...]) of each of its failures, in the record's time
    failures: list[tuple[str, list[tuple[float, float]]]] = field(default_factory=list)


def suite_sensors(ds: xr.Dataset) -> dict[str, dict[str, Any]] | None:
    """The ``[sensors.NAME]`` tables of the composition stored with ``ds`` (spelled out
    as ``lookout run`` stores them), or None when its sensor is no suite or the Dataset
    holds no composition."""
    text = ds.attrs.get("composition")
    if not isinstance(text, str):
        return None
    try:
        document = json.loads(text)
    except ValueError:
        return None
    sensors = document.get("sensors") if isinstance(document, dict) else None
    return sensors if isinstance(sensors, dict) and sensors else None


def _values(ds: xr.Dataset, name: str, run: int) -> np.ndarray | None:
    if name not in ds.data_vars:
        return None
    return np.asarray(ds[name].isel(run=run).values, dtype=float)


def _instants(time: np.ndarray, period: float) -> np.ndarray:
    """Whether each record's time is a sample instant of an instrument of ``period`` (s)."""
    ratio = time / period
    return np.abs(ratio - np.round(ratio)) < 1e-6 * np.maximum(1.0, np.abs(ratio))


def _rotate(heading: np.ndarray, arm: np.ndarray) -> np.ndarray:
    """R(psi) r per record: (n, 2) north and east of the body-fixed ``arm``."""
    c, s = np.cos(heading), np.sin(heading)
    return np.stack([c * arm[0] - s * arm[1], s * arm[0] + c * arm[1]], axis=-1)


def _wrap_degrees(angle: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return np.degrees((angle + np.pi) % (2.0 * np.pi) - np.pi)


def _failures(ds: xr.Dataset, name: str, run: int, time: np.ndarray) -> list[tuple[str, list[tuple[float, float]]]]:
    """The failures of sensor ``name``: (flag name, its windows), each window extended by
    one record so that a flag of one sample (a wild point) still shows."""
    step = float(time[1] - time[0]) if time.size > 1 else 0.0
    found = []
    for variable in ds.data_vars:
        if isinstance(variable, str) and variable.startswith(f"{name}.") and variable.endswith("_failure"):
            flag = np.nan_to_num(np.asarray(ds[variable].isel(run=run).values, dtype=float)) > 0.5
            found.append((variable, [(first, last + step) for first, last in _runs(time, flag)]))
    return found


def _moving_median(time: np.ndarray, values: np.ndarray, seconds: float, edges: np.ndarray) -> np.ndarray:
    """The centred moving median of ``values`` (n,) over ``seconds``, NaNs left out, taken
    apart at each of ``edges`` (a failure's start or end): a step stays a step, and a
    wild point does not move it."""
    if time.size < 2:
        return values.copy()
    half = max(0, int(round(0.5 * seconds / float(np.median(np.diff(time))))))
    out = np.full(values.shape, np.nan)
    # an edge at t belongs to the segment after it, times a rounding below t included
    segment = np.searchsorted(edges - 1e-6 * np.maximum(1.0, np.abs(edges)), time, side="right")
    for number in np.unique(segment):
        (index,) = np.nonzero(segment == number)
        padded = np.concatenate([np.full(half, np.nan), values[index], np.full(half, np.nan)])
        windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a window of dropouts only: NaN
            out[index] = np.nanmedian(windows, axis=1)
    return out


def _truth(ds: xr.Dataset, run: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The true total position (n, 2) and heading (n,): low-frequency plus wave motion."""
    position, heading = _values(ds, "position", run), _values(ds, "heading", run)
    if position is None or heading is None or position.ndim != 2:
        return None
    wave_position, wave_heading = _values(ds, "wave_position", run), _values(ds, "wave_heading", run)
    if wave_position is not None and wave_position.shape == position.shape:
        position = position + wave_position
    if wave_heading is not None and wave_heading.shape == heading.shape:
        heading = heading + wave_heading
    return position, heading


def sensor_reference_errors(ds: xr.Dataset, *, run: int = 0) -> tuple[list[ReferenceErrors], list[ReferenceErrors]] | None:
    """``(position errors, heading errors)`` of the suite recorded in ``ds`` (run
    ``run``): each position reference and gyrocompass, then the combined channel,
    at their sample instants (see the module docstring); None when ``ds`` holds no
    suite with a position or heading reference, or no true position and heading."""
    sensors = suite_sensors(ds)
    truth = _truth(ds, run)
    if sensors is None or truth is None:
        return None
    time = np.asarray(ds["time"].values, dtype=float)
    position, heading = truth
    positions: list[ReferenceErrors] = []
    headings: list[ReferenceErrors] = []
    colours = iter(_SENSOR_COLOURS * (1 + len(sensors) // len(_SENSOR_COLOURS)))
    fastest = {"position": np.inf, "heading": np.inf}
    for name, table in sensors.items():
        kind = str(table.get("kind"))
        channel = POSITION_KINDS.get(kind) or HEADING_KINDS.get(kind)
        y = _values(ds, f"{name}.{channel}", run) if channel is not None else None
        if y is None:
            continue
        period = float(table.get("sample_period", 1.0))
        at = _instants(time, period)
        failures = _failures(ds, name, run, time)
        if kind in POSITION_KINDS:
            fastest["position"] = min(fastest["position"], period)
            arm = np.asarray(table.get("lever_arm", (0.0, 0.0)), dtype=float)
            point = y + np.asarray(table.get("anchor", (0.0, 0.0)), dtype=float) - _rotate(heading, arm)
            where = f"at [{arm[0]:g}, {arm[1]:g}] m"
            positions.append(
                ReferenceErrors(name, f"{name} ({kind} {where}, {period:g} s)", next(colours), time[at], (point - position)[at], period, failures)
            )
        else:
            fastest["heading"] = min(fastest["heading"], period)
            error = _wrap_degrees(y - heading)[:, None]
            headings.append(ReferenceErrors(name, f"{name} ({kind}, {period:g} s)", next(colours), time[at], error[at], period, failures))
    combined_position, combined_heading = _values(ds, "measured_position", run), _values(ds, "measured_heading", run)
    # a stage that tests the references (dp-class) records each one's state beside them
    of = " of the accepted" if "references.heading_alarm" in ds else ""
    if positions and combined_position is not None and combined_position.shape == position.shape:
        at = _instants(time, fastest["position"])
        positions.append(
            ReferenceErrors(
                "combined",
                f"combined: measured_position (weighted mean{of})",
                _COMBINED_COLOUR,
                time[at],
                (combined_position - position)[at],
                fastest["position"],
            )
        )
    if headings and combined_heading is not None and combined_heading.shape == heading.shape:
        at = _instants(time, fastest["heading"])
        error = _wrap_degrees(combined_heading - heading)[:, None]
        headings.append(
            ReferenceErrors("combined", f"combined: measured_heading (median{of})", _COMBINED_COLOUR, time[at], error[at], fastest["heading"])
        )
    if not positions and not headings:
        return None
    return positions, headings


def _zoom(time: np.ndarray, series: list[ReferenceErrors], fixes: int) -> tuple[float, float, str]:
    """The zoom window of a row: ``fixes`` samples of its fastest instrument (at most a
    fifth of the run), from a quarter of them before the onset of its first failure, or
    the run's last ones when none of its instruments fails."""
    width = min(fixes * min(each.period for each in series), float(time[-1] - time[0]) / 5.0)
    onsets = [windows[0][0] for each in series for _, windows in each.failures if windows]
    if not onsets:
        return float(time[-1]) - width, float(time[-1]), f"zoom: the last {width:.3g} s"
    onset = min(onsets)
    start = min(max(float(time[0]), onset - 0.25 * width), float(time[-1]) - width)
    return start, start + width, f"zoom: {start:.4g} to {start + width:.4g} s, the first failure at {onset:.4g} s"


def _edges(series: list[ReferenceErrors]) -> np.ndarray:
    """Every start and end of a failure of ``series``, sorted; not a wild point's (the
    median passes over those)."""
    return np.unique([edge for each in series for flag, windows in each.failures if not _is_wild(flag) for window in windows for edge in window])


def _is_wild(flag: str) -> bool:
    return flag.rsplit(".", 1)[-1].startswith("wild")


def _draw(
    full: Axes,
    zoomed: Axes,
    series: list[ReferenceErrors],
    column: int,
    window: tuple[float, float, str],
    smoothing: float,
    time: np.ndarray,
) -> None:
    """One row: the errors of one axis (north, east or heading) of every series, the
    moving median of an instrument taken apart at its own failures' edges, the combined
    channel's at those of every instrument of the row."""
    start, end, _ = window
    for edge in (start, end):
        full.axvline(edge, **_ZOOM_EDGE_STYLE)
    for each in series:
        for _, windows in each.failures:
            for first, last in windows:
                for ax in (full, zoomed):
                    ax.axvspan(first, last, color=each.colour, alpha=_FAILURE_ALPHA, lw=0, zorder=0.5)
    for each in series:
        values = each.error[:, column]
        inside = (each.time >= start) & (each.time <= end)
        if each.name == "combined":
            full.plot(each.time, _moving_median(each.time, values, smoothing, _edges(series)), color=each.colour, lw=2.4, zorder=2.6)
            zoomed.plot(each.time[inside], values[inside], color=each.colour, lw=1.2, zorder=2.6)
        else:
            full.plot(each.time, values, ls="none", marker=".", ms=1.5, alpha=0.3, color=each.colour, zorder=1, rasterized=True)
            full.plot(each.time, _moving_median(each.time, values, smoothing, _edges([each])), color=each.colour, lw=1.2, zorder=2.4)
            zoomed.plot(each.time[inside], values[inside], ls="none", marker=".", ms=3.5, color=each.colour, zorder=2.4)
    for ax in (full, zoomed):
        ax.axhline(0.0, **_TRUTH_STYLE)
        ax.grid(alpha=0.3)
    full.set_xlim(time[0], time[-1])
    zoomed.set_xlim(start, end)


def _name_failures(ax: Axes, series: list[ReferenceErrors]) -> None:
    """Write each failure's sensor and mode at the top of its first window."""
    for each in series:
        for flag, windows in each.failures:
            if windows:
                mode = flag.split(".", 1)[1].removesuffix("_failure")
                ax.annotate(
                    f"{each.name} {mode}",
                    (windows[0][0], 1.0),
                    xycoords=("data", "axes fraction"),
                    xytext=(3, -3),
                    textcoords="offset points",
                    va="top",
                    ha="left",
                    fontsize=8,
                    color=each.colour,
                    bbox={"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": "none", "alpha": 0.8},
                )


def plot_run_sensor_references(
    ds: xr.Dataset, *, run: int = 0, fixes: int = ZOOM_FIXES, smoothing: float = SMOOTHING, title: str | None = None
) -> Figure | None:
    """Every position reference and gyrocompass of a sensor suite against the truth,
    and the combining stage's output (``references.png`` of ``lookout run``).

    Rows: the north and the east error (m) of each position reference, taken back to
    the vessel's reference point with the true heading, from the true position with
    the waves; then the heading error (deg) of each gyrocompass. Each at its own sample
    instants, the combined ``measured_position`` and ``measured_heading`` (orange)
    too; the truth is the black zero line. Left the whole run, each instrument's fixes
    as faint dots under their ``smoothing``-second moving median; right a zoom on
    ``fixes`` samples of the row's fastest instrument (at most a fifth of the run),
    every fix drawn, from a quarter
    of them before the first failure of the row's instruments (the position rows
    share theirs), or at the end of the run when none fails. Each failure
    (``NAME.MODE_failure``) is shaded in its sensor's colour and named at its start;
    the moving median is taken apart at its edges, so that a step stays a step.

    Parameters
    ----------
    ds : xarray.Dataset
        Results of ``lookout run`` with a sensor suite (``[sensors.NAME]``): its
        composition in ``ds.attrs["composition"]`` gives the kinds, lever arms and
        sample periods.
    run : int, default 0
        The run shown, named with its seed in the title when there are several.
    fixes : int, default 150
        Samples of the row's fastest instrument in its zoom.
    smoothing : float, default 60.0
        Seconds of the moving median across the full run (at most a twentieth of it).
    title : str, optional
        A first title line (the scenario).

    Returns
    -------
    matplotlib.figure.Figure or None
        None when the Dataset holds no suite with a position reference or a
        gyrocompass (or no true position and heading to compare with).
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    run = _check_run(ds, run)
    if isinstance(fixes, bool) or not isinstance(fixes, int) or fixes < 2:
        raise ValueError(f"fixes must be a whole number of samples >= 2; got {fixes!r}")
    if not (isinstance(smoothing, (int, float)) and np.isfinite(smoothing) and smoothing > 0):
        raise ValueError(f"smoothing must be a finite number of seconds > 0; got {smoothing!r}")
    found = sensor_reference_errors(ds, run=run)
    if found is None:
        return None
    positions, headings = found
    time = np.asarray(ds["time"].values, dtype=float)
    smoothing = min(float(smoothing), float(time[-1] - time[0]) / 20.0)  # a short run keeps its shape
    rows = []
    if positions:
        window = _zoom(time, positions, fixes)
        rows += [(positions, 0, "north error (m)", window), (positions, 1, "east error (m)", window)]
    if headings:
        rows += [(headings, 0, "heading error (deg)", _zoom(time, headings, fixes))]
    figure, axes = plt.subplots(
        len(rows), 2, figsize=(13, 2.5 * len(rows) + 2.4), squeeze=False, layout="constrained", gridspec_kw={"width_ratios": (2.2, 1)}
    )
    for number, ((full, zoomed), (series, column, quantity, window)) in enumerate(zip(axes, rows)):
        _draw(full, zoomed, series, column, window, smoothing, time)
        full.set_ylabel(f"Earth-fixed\n{quantity}")
        zoomed.set_ylabel(quantity)
        _name_failures(full, series)
        if number:
            full.sharex(axes[0, 0])
            if window == rows[number - 1][3]:
                zoomed.sharex(axes[number - 1, 1])
        if number == 0 or window != rows[number - 1][3]:
            zoomed.set_title(window[2], fontsize=9.5)
        if number + 1 < len(rows):
            full.tick_params(labelbottom=False)
            if window == rows[number + 1][3]:
                zoomed.tick_params(labelbottom=False)
    axes[0, 0].set_title(f"full run: each fix (dots) and its {smoothing:.3g} s moving median (line)", fontsize=9.5)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    handles: list[Any] = [Line2D([], [], **_without_zorder(_TRUTH_STYLE), label="true (error 0)")]
    for each in positions + headings:
        if each.name != "combined":
            handles.append(Line2D([], [], color=each.colour, lw=1.2, marker=".", ms=5, label=each.description))
    for each in positions + headings:
        if each.name == "combined":
            handles.append(Line2D([], [], color=each.colour, lw=2.4, label=each.description))
    for each in positions + headings:
        for flag, windows in each.failures:
            if windows:
                handles.append(Patch(color=each.colour, alpha=_FAILURE_ALPHA, lw=0, label=f"{flag} (shaded)"))
    handles.append(Line2D([], [], **_without_zorder(_ZOOM_EDGE_STYLE), label="zoom window (in the full run)"))
    figure.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8.5, frameon=False)
    what = (
        "sensor suite: each position reference and gyrocompass against the truth, failures shaded\n"
        "a fix taken back to the reference point with the true heading, less the true position with the waves;\n"
        "the combined channels as the stage gives them (its lever arms taken back with the measured heading)"
    )
    heading = textwrap.fill(title, 120) + "\n" + what if title else what
    caption = _run_caption(ds, run)
    if caption is not None:
        if ds.sizes["run"] > 1:
            caption += f"; the figure shows this run only, of the {ds.sizes['run']} in the dataset"
        heading += "\n" + caption
    figure.suptitle(heading, fontsize=10.5)
    return figure


__all__ = [
    "HEADING_KINDS",
    "POSITION_KINDS",
    "SMOOTHING",
    "ZOOM_FIXES",
    "ReferenceErrors",
    "plot_run_sensor_references",
    "sensor_reference_errors",
    "suite_sensors",
]
