"""The panel every time-series figure is drawn from: a full run and zoomed windows.

A panel shows one component of a variable: the truth thin and black on top, the
compared series (an estimate, a reference, a commanded input) wide and coloured
under it, a target and a measurement where there is one. Angles are unwrapped onto the
truth's branch and units are those shown (degrees, kN); a dense signal (wave motion over
hours) is drawn in the full-run column as its range per bin. Used by
:mod:`lookout.plotting.series` and :mod:`lookout.plotting.run_figures`.
"""

from __future__ import annotations

import math
import operator
import textwrap
from dataclasses import dataclass
from typing import Any, overload

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.artist import Artist
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from lookout._math import ssa
from lookout.plotting._common import _minus

#: Units shown in figures instead of the stored SI ones: (factor, shown unit).
_DISPLAY_UNITS = {"rad": (math.degrees(1.0), "deg"), "rad/s": (math.degrees(1.0), "deg/s"), "N": (1e-3, "kN"), "N m": (1e-3, "kN m")}

#: Line styles: the estimate is drawn first, wide and coloured; the truth thin, black,
#: on top, so that it stays visible where the estimate lies on it.
_ESTIMATE_STYLE: dict[str, Any] = {"color": "C1", "lw": 1.4, "zorder": 2}
_TRUTH_STYLE: dict[str, Any] = {"color": "k", "lw": 0.7, "zorder": 3}
_MEASURED_STYLE: dict[str, Any] = {"color": "0.45", "ls": "none", "marker": ".", "ms": 2.5, "alpha": 0.5, "zorder": 1}
_WINDOW_STYLE: dict[str, Any] = {"color": "C0", "alpha": 0.12, "lw": 0, "zorder": 0}


def _wrap_to_pi(angle: np.ndarray) -> np.ndarray:
    return np.asarray(ssa(angle))


def _component(array: xr.DataArray, label: str | None) -> xr.DataArray:
    """The scalar series of ``array`` (dims run, time[, label dim]) for ``label``."""
    extra = [dim for dim in array.dims if dim not in ("run", "time")]
    if label is None:
        if extra:
            raise ValueError(f"panels: {array.name!r} is a vector over {extra[0]!r}; give one of {array[extra[0]].values.tolist()}")
        return array
    if not extra or label not in array[extra[0]].values.tolist():
        choices = array[extra[0]].values.tolist() if extra else "none (a scalar)"
        raise ValueError(f"panels: {array.name!r} has no component {label!r}; its components: {choices}")
    return array.sel({extra[0]: label})


def _check_run(ds: xr.Dataset, run) -> int:
    """``run`` as an index of the dataset's runs."""
    runs = ds.sizes.get("run", 0)
    try:
        run = operator.index(run)
    except TypeError:
        raise ValueError(f"run must be an integer index with 0 <= run < {runs}; got {run!r}") from None
    if not 0 <= run < runs:
        raise ValueError(f"run must satisfy 0 <= run < {runs} (the dataset's number of runs); got {run}")
    return run


def _check_estimate_arguments(ds: xr.Dataset, panels, run, zoom) -> tuple[list, int, float]:
    try:
        panels = [(variable, label) for variable, label in panels]
    except (TypeError, ValueError):
        raise ValueError(f"panels must be a sequence of (variable, component or None) pairs; got {panels!r}") from None
    if not panels:
        raise ValueError("panels must name at least one (variable, component) pair")
    for variable, label in panels:
        if variable not in ds or f"{variable}_hat" not in ds:
            raise ValueError(f"panels: the dataset has no variable {variable!r} with an estimate {variable + '_hat'!r}")
        _component(ds[variable], label)
    run = _check_run(ds, run)
    try:
        zoom = float(zoom)
    except (TypeError, ValueError):
        raise ValueError(f"zoom must be a finite number of seconds > 0; got {zoom!r}") from None
    if not math.isfinite(zoom) or zoom <= 0:
        raise ValueError(f"zoom must be a finite number of seconds > 0; got {zoom!r}")
    return panels, run, zoom


def zoom_window(time, zoom: float) -> tuple[float, float]:
    """The window (start, end) in seconds shown in the zoom column of :func:`plot_estimates`.

    The last ``zoom`` seconds of the run, or its last fifth when the run lasts less
    than ``5 * zoom``.
    """
    time = np.asarray(time, dtype=float)
    start, end = float(time[0]), float(time[-1])
    duration = end - start
    width = zoom if duration >= 5.0 * zoom else duration / 5.0
    return end - width, end


def _run_caption(ds: xr.Dataset, run: int) -> str | None:
    """'run i of n (seed s)', when the dataset holds several runs or a seed coordinate."""
    runs = ds.sizes["run"]
    has_seed = "seed" in ds.coords or "seed" in ds.variables
    if runs <= 1 and not has_seed:
        return None
    caption = f"run {run} of {runs}"
    if has_seed:
        seed = np.asarray(ds["seed"].isel(run=run).values).item()
        caption += f" (seed {seed})"
    if "status" in ds.variables and ds["status"].dims == ("run",):
        status = str(np.asarray(ds["status"].isel(run=run).values).item())
        if status != "finite":
            caption += f", status: {status}"
    return caption


#: Dense signals (wave motion over hours) are drawn in the full-run column as their
#: range per bin: a line per sample would fill a band in which the curve drawn last
#: hides the others. A signal is dense when most of its variance lies at more than
#: this many cycles per run (a few pixels per cycle at the written size).
DENSE_CYCLES = 150.0
#: Bins of the range drawn for a dense signal across the full run.
ENVELOPE_BINS = 300
_TARGET_STYLE: dict[str, Any] = {"color": "C0", "lw": 0.9, "zorder": 2.5}
_TRUTH_BAND_STYLE: dict[str, Any] = {"color": "0.6", "alpha": 0.35, "lw": 0, "zorder": 1.5}


def is_dense(time, values, cycles: float = DENSE_CYCLES) -> bool:
    """Whether most of the variance of ``values`` lies above ``cycles`` cycles per run.

    Such a signal, drawn sample by sample across the whole run, is a solid band at the
    size a figure is written: :func:`plot_estimates` then draws its range per bin.
    """
    time = np.asarray(time, dtype=float)
    values = np.asarray(values, dtype=float)
    finite = np.isfinite(values)
    if time.size < 8 or finite.sum() < 8:
        return False
    duration = float(time[-1] - time[0])
    if not duration > 0:
        return False
    # fill gaps and remove the trend, so that a drift or a dropout is not read as fast motion
    values = np.interp(time, time[finite], values[finite])
    values = values - np.polyval(np.polyfit(time - time[0], values, 1), time - time[0])
    power = np.abs(np.fft.rfft(values)) ** 2
    power[0] = 0.0
    total = power.sum()
    if not total > 0:
        return False
    cycles_per_run = np.arange(power.size)  # rfft bin k holds k cycles over the record
    return bool(power[cycles_per_run > cycles].sum() > 0.5 * total)


def _envelope(time: np.ndarray, values: np.ndarray, bins: int = ENVELOPE_BINS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(bin centres, minimum, maximum) of ``values`` in ``bins`` equal slices of the run."""
    edges = np.linspace(time[0], time[-1], bins + 1)
    index = np.clip(np.searchsorted(edges, time, side="right") - 1, 0, bins - 1)
    low = np.full(bins, np.inf)
    high = np.full(bins, -np.inf)
    finite = np.isfinite(values)
    np.minimum.at(low, index[finite], values[finite])
    np.maximum.at(high, index[finite], values[finite])
    empty = ~np.isfinite(low)
    low[empty] = high[empty] = np.nan
    return 0.5 * (edges[:-1] + edges[1:]), low, high


def _outline(centres: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The upper and lower edge of a range as one line (x, y), broken by a NaN."""
    return np.r_[centres, np.nan, centres], np.r_[high, np.nan, low]


def _windows(window, time: np.ndarray, zoom: float) -> list[tuple[float, float, str]]:
    """The zoom windows (start, end, column title) of :func:`plot_estimates`."""
    if window is None:
        start, end = zoom_window(time, zoom)
        return [(start, end, f"zoom: last {end - start:.3g} s (shaded on the left)")]
    try:
        pairs = [tuple(float(value) for value in window)] if np.ndim(window) == 1 else [tuple(float(v) for v in pair) for pair in window]
    except (TypeError, ValueError):
        raise ValueError(f"window must be (start, end) in seconds, or a sequence of such pairs; got {window!r}") from None
    result = []
    for pair in pairs:
        if len(pair) != 2 or not (time[0] <= pair[0] < pair[1] <= time[-1]):
            raise ValueError(f"window must satisfy {time[0]:g} <= start < end <= {time[-1]:g} (the run); got {window!r}")
        result.append((pair[0], pair[1], f"zoom: {pair[0]:.4g} to {pair[1]:.4g} s" + (" (shaded on the left)" if len(pairs) == 1 else " (shaded)")))
    if not result:
        raise ValueError(f"window must name at least one (start, end) pair; got {window!r}")
    return result


def _check_targets(ds: xr.Dataset, panels, targets) -> dict[str, str]:
    if targets is None:
        return {}
    try:
        targets = {str(variable): str(target) for variable, target in dict(targets).items()}
    except (TypeError, ValueError):
        raise ValueError(f"targets must map a panel's variable to a dataset variable; got {targets!r}") from None
    for variable, target in targets.items():
        if variable not in {name for name, _ in panels}:
            raise ValueError(f"targets: {variable!r} is not the variable of any panel")
        if target not in ds or ds[target].dims != ds[variable].dims:
            raise ValueError(f"targets: the dataset has no variable {target!r} with the dims of {variable!r} {ds[variable].dims}")
    return targets


@dataclass
class _Panel:
    """One panel's curves in plot units (angles unwrapped, on the truth's branch).

    ``truth`` is drawn thin and black on top; ``compared`` (an estimate, a reference,
    a commanded input) wide and coloured under it; either may be missing, not both.
    """

    quantity: str
    frame: str
    truth: np.ndarray | None
    compared: np.ndarray | None
    target: np.ndarray | None = None
    measured: np.ndarray | None = None
    #: where ``measured`` holds a new sensor sample (told from the stored held values)
    sampled: np.ndarray | None = None
    #: a line written in the full-run panel (e.g. an estimate with no truth recorded)
    note: str | None = None
    #: samples shaded in every column (e.g. where the actuator limited the input)
    marked: np.ndarray | None = None


@overload
def _run_values(array: xr.DataArray, label: str | None, run: int) -> np.ndarray: ...
@overload
def _run_values(array: None, label: str | None, run: int) -> None: ...
@overload
def _run_values(array: xr.DataArray | None, label: str | None, run: int) -> np.ndarray | None: ...
def _run_values(array: xr.DataArray | None, label: str | None, run: int) -> np.ndarray | None:
    """The series of one component of ``array`` in one run, as floats (None stays None)."""
    if array is None:
        return None
    return np.asarray(_component(array, label).isel(run=run).values, dtype=float)


def _unwrap(angle: np.ndarray) -> np.ndarray:
    """``np.unwrap`` over the finite samples (a NaN would end the unwrapping there)."""
    out = np.array(angle, dtype=float)
    finite = np.isfinite(out)
    out[finite] = np.unwrap(out[finite])
    return out


def _quantity(variable: str, label) -> str:
    """A panel's quantity: the variable's name in words and the component: "position north"."""
    return f"{variable.replace('_', ' ')}{' ' + str(label) if label is not None else ''}"


def _display_unit(units: str, series) -> tuple[float, str]:
    """(factor, shown unit) of a panel: :data:`_DISPLAY_UNITS`, except that forces and
    moments below 1 kN (an arm's joint torques) stay in N and N m."""
    scale, shown = _DISPLAY_UNITS.get(units, (1.0, units))
    if shown.startswith("kN"):
        peaks = [np.nanmax(np.abs(values), initial=0.0) for values in series if values is not None and np.isfinite(values).any()]
        if peaks and max(peaks) < 1e3:
            return 1.0, units
    return scale, shown


def _make_panel(attrs, quantity: str, truth, compared, *, target=None, measured=None, note=None, marked=None) -> _Panel:
    """A :class:`_Panel` of raw series in the dataset's units: angles unwrapped and put
    on one branch, every series scaled to the displayed unit."""
    sampled = None
    if measured is not None:
        # one dot per sensor sample: the held value changes at a new sample (told before
        # the unwrapping, which would make every held value differ in its last bits)
        sampled = np.r_[True, measured[1:] != measured[:-1]] & np.isfinite(measured)
    if attrs.get("angle"):
        # unwrap the truth (the compared series where there is none), then put the others on its branch
        base = _unwrap(truth if truth is not None else compared)

        def on_branch(values):
            with np.errstate(invalid="ignore"):  # inf - inf where a run diverged: NaN, not drawn
                return None if values is None else base + _wrap_to_pi(values - base)

        if truth is not None:
            truth, compared = base, on_branch(compared)
        else:
            compared = base
        target, measured = on_branch(target), on_branch(measured)
    scale, units = _display_unit(attrs.get("units", ""), (truth, compared, target))

    def scaled(values):
        return None if values is None else values * scale

    return _Panel(
        f"{quantity} ({units})", attrs.get("frame", ""), scaled(truth), scaled(compared), scaled(target), scaled(measured), sampled, note, marked
    )


def _panel_layout(groups: list[int], columns: int) -> list[list[int]]:
    """The panels (indices 0..sum(groups)-1) of each column of a figure of ``columns``
    columns, filled top to bottom: as few rows as the columns allow, and a group (the
    components of one variable) kept in one column where it fits in one."""
    total = sum(groups)
    columns = max(1, min(columns, total))
    rows = math.ceil(total / columns)
    while True:
        layout: list[list[int]] = []
        index = 0
        for size in groups:
            if not layout or (len(layout[-1]) + size > rows and size <= rows and layout[-1]):
                layout.append([])
            for _ in range(size):
                if len(layout[-1]) == rows:
                    layout.append([])
                layout[-1].append(index)
                index += 1
        if len(layout) <= columns:
            return layout
        rows += 1


#: Relative width of the gap between two columns of panels (each a full run and its zooms).
_COLUMN_GAP = 0.12


def _panel_figure(layout: list[list[int]], windows, heading: str):
    """A figure of panels laid out by ``layout`` (panel indices per column of panels),
    each a full-run axis and one axis per zoom window; the x axes of a column are
    shared. Returns the figure, ``(full, zoomed axes)`` per panel index and the top
    full-run axis of each column."""
    rows = max(len(column) for column in layout)
    per_panel = 1 + len(windows)
    ratios: list[float] = []
    for number in range(len(layout)):
        ratios += ([_COLUMN_GAP] if number else []) + [1.6] + [1.0] * len(windows)
    # a title of more than two lines gets its own room, so that the panels keep theirs
    title_room = 0.25 * max(0, heading.count("\n") - 1)
    width = 11 + 3.6 * (len(windows) - 1) if len(layout) == 1 else len(layout) * (9.5 + 3.2 * (len(windows) - 1)) + 0.5
    fig, axes = plt.subplots(
        rows,
        len(ratios),
        figsize=(width, 2.25 * rows + (1.2 if rows < 4 else 0.0) + title_room),
        layout="constrained",
        sharex="col",
        squeeze=False,
        gridspec_kw={"width_ratios": tuple(ratios)},
    )
    cells: dict[int, tuple] = {}
    tops = []
    for number, column in enumerate(layout):
        first = number * (per_panel + 1)
        if number:
            for ax in axes[:, first - 1]:
                ax.set_axis_off()
        for row in range(rows):
            row_axes = axes[row, first : first + per_panel]
            if row < len(column):
                cells[column[row]] = (row_axes[0], row_axes[1:])
            else:
                for ax in row_axes:
                    ax.set_visible(False)
        for ax in axes[len(column) - 1, first : first + per_panel]:
            ax.xaxis.set_tick_params(which="both", labelbottom=True)
            ax.set_xlabel("time (s)")
        for ax, (_, _, column_title) in zip(axes[0, first : first + per_panel], [(None, None, "full run")] + list(windows)):
            ax.set_title(column_title, fontsize=10)
        tops.append(axes[0, first])
    return fig, [cells[index] for index in range(len(cells))], tops


def _window_parts(time: np.ndarray, windows) -> list[slice]:
    """The samples of each zoom window, one sample of margin either side so that the
    zoomed curves reach the frame."""

    def part_of(start, end):
        first = max(int(np.searchsorted(time, start, side="left")) - 1, 0)
        last = min(int(np.searchsorted(time, end, side="right")) + 1, time.size)
        return slice(first, last)

    return [part_of(start, end) for start, end, _ in windows]


#: Where an input was limited (applied differs from commanded).
_MARKED_STYLE: dict[str, Any] = {"color": "tab:red", "alpha": 0.15, "lw": 0, "zorder": 0.5}


#: Characters of a y label's line (the quantity and unit are wrapped at this width).
_LABEL_WIDTH = 28
#: A start that spans more than this many times the range of the rest of the run is
#: a spike (a first sample far off) that :func:`_start_spike` keeps off the scale.
SPIKE_RATIO = 5.0
#: The part of the run that such a start may last.
SPIKE_FRACTION = 0.02


def _start_spike(time: np.ndarray, series) -> float | None:
    """Seconds at the start of the run to leave off the full-run scale, or None: the
    first :data:`SPIKE_FRACTION` of the run, when the curves span more than
    :data:`SPIKE_RATIO` times their range over the rest of it."""
    if time.size < 20 or not series:
        return None
    seconds = SPIKE_FRACTION * (time[-1] - time[0])
    rest = time >= time[0] + seconds
    values = np.concatenate(series)
    later = np.concatenate([values[rest] for values in series])
    values, later = values[np.isfinite(values)], later[np.isfinite(later)]
    if not later.size or rest.sum() < 0.5 * time.size:
        return None
    span, later_span = float(values.max() - values.min()), float(later.max() - later.min())
    return seconds if later_span > 0 and span > SPIKE_RATIO * later_span else None


def _draw_panel(
    full,
    zoomed,
    panel: _Panel,
    time: np.ndarray,
    windows,
    parts,
    *,
    compared_style,
    compared_label="estimate",
    truth_label="true",
    transient=None,
    clip_start=False,
) -> set[str]:
    """Draw one panel into its full-run axis and zoom axes; return what it holds
    (``dense``, ``measured``, ``target``, ``marked``, ``truth``, ``compared``) for the legend.

    ``transient`` seconds at the start are left off the full-run scale; with
    ``clip_start``, a start spike found by :func:`_start_spike` is, and the note gives
    its extreme."""
    drawn = {name for name in ("truth", "compared", "target") if getattr(panel, name) is not None}
    truth, compared, target = panel.truth, panel.compared, panel.target
    for start, end, _ in windows:
        full.axvspan(start, end, **_WINDOW_STYLE, label="zoom window")
    if panel.marked is not None and panel.marked.any():
        drawn.add("marked")
        for ax, part in [(full, slice(None))] + list(zip(zoomed, parts)):
            ax.fill_between(time[part], 0, 1, where=panel.marked[part], transform=ax.get_xaxis_transform(), **_MARKED_STYLE, label="marked")
    spike = _start_spike(time, [series for series in (truth, compared) if series is not None]) if clip_start and transient is None else None
    # a spike at the start is no fast motion: the rest of the run tells whether the signal is dense
    after = time >= time[0] + (spike or 0.0)
    shown = truth if truth is not None else compared
    assert shown is not None, "a panel has a truth or a compared series"  # _Panel: either may be missing, not both
    dense = is_dense(time[after], shown[after])
    if dense:
        drawn.add("dense")
        if truth is not None:
            centres, low, high = _envelope(time, truth)
            full.fill_between(centres, low, high, **_TRUTH_BAND_STYLE, label=f"{truth_label} (range)")
        if compared is not None:
            full.plot(*_outline(*_envelope(time, compared)), **compared_style, label=compared_label)
        if target is not None:
            full.plot(*_outline(*_envelope(time, target)), **_TARGET_STYLE, label="target")
        if truth is not None:
            full.plot(*_outline(centres, low, high), **_TRUTH_STYLE, label=truth_label)
    else:
        if compared is not None:
            full.plot(time, compared, **compared_style, label=compared_label)
        if target is not None:
            full.plot(time, target, **_TARGET_STYLE, label="target")
        if truth is not None:
            full.plot(time, truth, **_TRUTH_STYLE, label=truth_label)
    for ax, part in zip(zoomed, parts):
        if compared is not None:
            ax.plot(time[part], compared[part], **compared_style, label=compared_label)
        if target is not None:
            ax.plot(time[part], target[part], **_TARGET_STYLE, label="target")
        if truth is not None:
            ax.plot(time[part], truth[part], **_TRUTH_STYLE, label=truth_label)
    for ax in (full, *zoomed):
        ax.grid(alpha=0.3)
        ax.ticklabel_format(axis="y", useOffset=False)  # "+4.247e6" above a panel reads as a value; a factor 1e6 does not
    if panel.measured is not None:
        drawn.add("measured")
        assert panel.sampled is not None  # _make_panel sets it with measured
        for ax, part in zip(zoomed, parts):
            new = panel.sampled[part]
            ax.plot(time[part][new], panel.measured[part][new], **_MEASURED_STYLE, label="measured")
    notes = [] if panel.note is None else [panel.note]
    message = None
    if transient is not None:
        message = f"clipped: the first {float(transient):g} s leave this scale (see the zoom)"
    else:
        transient = spike
    if transient is not None:
        kept = time >= time[0] + float(transient)
        present = [series for series in (truth, compared, target) if series is not None]
        values = np.concatenate([series[kept] for series in present])
        values = values[np.isfinite(values)]
        if values.size:
            y_low, y_high = float(values.min()), float(values.max())
            pad = 0.08 * (y_high - y_low) if y_high > y_low else max(abs(y_high), 1.0) * 0.05
            everything = np.concatenate([series for series in (truth, compared) if series is not None])
            everything = everything[np.isfinite(everything)]
            if everything.size and (everything.min() < y_low - pad or everything.max() > y_high + pad):
                if message is None:  # a spike found here: said in the panel's note, placed clear of the curves
                    extreme = everything.min() if y_low - everything.min() > everything.max() - y_high else everything.max()
                    notes.append(
                        _minus(f"clipped: the first {float(transient):.2g} s reach {extreme:.3g} {panel.quantity.rsplit('(', 1)[-1].rstrip(')')}")
                    )
                else:
                    full.text(
                        0.01,
                        0.03,
                        message,
                        transform=full.transAxes,
                        fontsize=7.5,
                        va="bottom",
                        ha="left",
                        gid="transient_note",
                        bbox={"boxstyle": "round,pad=0.2", "facecolor": "white", "edgecolor": "none", "alpha": 0.8},
                    )
            full.set_ylim(y_low - pad, y_high + pad)
    if notes:
        # a legend of no entries: matplotlib puts it where it covers the fewest curves
        note = full.legend(handles=[], title="\n".join(notes), loc="best", title_fontsize=7.5, framealpha=0.85, borderpad=0.3)
        note.set_gid("panel_note")
    quantity = textwrap.fill(panel.quantity, _LABEL_WIDTH, break_long_words=False)  # a long label stays beside its panel
    full.set_ylabel(f"{panel.frame}\n{quantity}" if panel.frame else quantity)
    for ax in zoomed:
        ax.set_ylabel(quantity)
    full.set_xlim(time[0], time[-1])
    for ax, (start, end, _) in zip(zoomed, windows):
        ax.set_xlim(start, end)
    return drawn


def _without_zorder(style: dict) -> dict:
    return {k: v for k, v in style.items() if k != "zorder"}


def _panel_legend(
    fig, drawn: set[str], *, compared_style, compared_label="estimate", truth_label="true", target_labels=(), marked_label="marked"
) -> None:
    """One legend below the panels for what :func:`_draw_panel` drew."""
    handles: list[Artist] = []
    if "truth" in drawn:
        handles.append(Line2D([], [], **_without_zorder(_TRUTH_STYLE), label=truth_label))
    if "compared" in drawn:
        handles.append(Line2D([], [], **_without_zorder(compared_style), label=compared_label))
    if "target" in drawn:
        handles.append(Line2D([], [], **_without_zorder(_TARGET_STYLE), label="; ".join(target_labels)))
    if "dense" in drawn and "truth" in drawn:
        handles.append(Patch(**_without_zorder(_TRUTH_BAND_STYLE), label=f"{truth_label} (range per bin)"))
    if "measured" in drawn:
        handles.append(Line2D([], [], **{k: v for k, v in _MEASURED_STYLE.items() if k not in ("zorder", "alpha")}, label="measured (zoom)"))
    if "marked" in drawn:
        handles.append(Patch(**_without_zorder(_MARKED_STYLE), label=marked_label))
    handles.append(Patch(facecolor="C0", alpha=0.12, label="zoom window"))
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 6), fontsize=9, frameon=False)


def _dense_title(tops, drawn: set[str], time: np.ndarray) -> None:
    """Say in the full-run columns' titles that dense signals are drawn as ranges."""
    if "dense" in drawn:
        bin_width = (time[-1] - time[0]) / ENVELOPE_BINS
        for ax in tops:
            ax.set_title(f"full run (dense signals: range per {bin_width:.3g} s)", fontsize=10)
