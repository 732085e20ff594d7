"""Figures drawn from xarray Datasets (matplotlib, no display needed).

Two figures, after Fossen & Strand (1999), Figs. 6 and 9–11:

* :func:`plot_estimates` -- true and estimated signals, one panel each (labels,
  units and frames from the Dataset), full run and a zoomed window;
* :func:`plot_bode` -- the frequency response of the error loops h0, hB and h of
  all three degrees of freedom, with the frequencies of the tuning rule (48).

And the figures of ``lookout run``, for any composition, found from the Dataset's
names (``<name>_hat``, ``theta_<name>``, ``measured_<name>``, ``<name>_desired``,
``<name>_commanded`` / ``<name>_applied``), drawn as :func:`plot_estimates` draws:

* :func:`plot_run_estimates` -- every estimate against its truth;
* :func:`plot_run_reference` -- the reference against the truth;
* :func:`plot_run_input` -- the commanded and the applied input.
"""

from __future__ import annotations

import math
import operator
import textwrap
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import NullLocator  # noqa: E402

from lookout._math import ssa  # noqa: E402
from lookout.results import limited as limited_input  # noqa: E402

# --------------------------------------------------------------------------- estimates

#: Units shown in figures instead of the stored SI ones: (factor, shown unit).
_DISPLAY_UNITS = {"rad": (math.degrees(1.0), "deg"), "rad/s": (math.degrees(1.0), "deg/s"), "N": (1e-3, "kN"), "N m": (1e-3, "kN m")}

#: Line styles: the estimate is drawn first, wide and coloured; the truth thin, black,
#: on top, so that it stays visible where the estimate lies on it.
_ESTIMATE_STYLE = {"color": "C1", "lw": 1.4, "zorder": 2}
_TRUTH_STYLE = {"color": "k", "lw": 0.7, "zorder": 3}
_MEASURED_STYLE = {"color": "0.45", "ls": "none", "marker": ".", "ms": 2.5, "alpha": 0.5, "zorder": 1}
_WINDOW_STYLE = {"color": "C0", "alpha": 0.12, "lw": 0, "zorder": 0}


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
_TARGET_STYLE = {"color": "C0", "lw": 0.9, "zorder": 2.5}
_TRUTH_BAND_STYLE = {"color": "0.6", "alpha": 0.35, "lw": 0, "zorder": 1.5}


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
_MARKED_STYLE = {"color": "tab:red", "alpha": 0.15, "lw": 0, "zorder": 0.5}


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
    dense = is_dense(time[after], (truth if truth is not None else compared)[after])
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
            low, high = float(values.min()), float(values.max())
            pad = 0.08 * (high - low) if high > low else max(abs(high), 1.0) * 0.05
            everything = np.concatenate([series for series in (truth, compared) if series is not None])
            everything = everything[np.isfinite(everything)]
            if everything.size and (everything.min() < low - pad or everything.max() > high + pad):
                if message is None:  # a spike found here: said in the panel's note, placed clear of the curves
                    extreme = everything.min() if low - everything.min() > everything.max() - high else everything.max()
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
            full.set_ylim(low - pad, high + pad)
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
    handles = []
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


def plot_estimates(
    ds: xr.Dataset,
    panels,
    *,
    run: int = 0,
    zoom: float = 200.0,
    window=None,
    title: str | None = None,
    targets=None,
    transient: float | None = None,
):
    """True and estimated signals, one row per panel: the full run and zoomed windows.

    The comparison of Fossen & Strand (1999), Figs. 9–11 and Calugi (2002),
    Figs. 2.2–2.8, for any results of :meth:`lookout.Trajectory.to_xarray`: each
    panel shows a variable ``v`` (one component of a vector, or a scalar) and its
    estimate ``v_hat``, the whole run on the left and the last ``zoom`` seconds (or
    the ``window``\\ s) on the right, where fast motion (wave periods of seconds) is
    resolved. The estimate is drawn in orange, the truth as a thin black line on top
    of it; a measured ``measured_v`` appears as dots (one per new sample) in the
    zoomed panels. A dense signal (:func:`is_dense`: wave motion over hours) is drawn
    in the full-run column as its range per bin, the truth's shaded and outlined in
    black, the estimate's outlined in orange, so that neither band hides the other.
    Axis labels give the frame, the quantity and its unit, from the variables'
    attributes; angles are shown in degrees (unwrapped), forces in kN.

    Parameters
    ----------
    ds : xarray.Dataset
        Results with dims (run, time[, label dim]); a ``seed`` coordinate along
        ``run``, when present, is named in the subtitle.
    panels : sequence of (str, str or None)
        ``(variable, component)``: e.g. ``("position", "north")``, ``("heading", None)``.
    run : int, default 0
        Index of the run along ``run``, ``0 <= run < ds.sizes["run"]``.
    zoom : float, default 200.0
        Width in seconds of the zoomed window at the end of the run; when the run
        lasts less than ``5 * zoom``, its last fifth is shown instead.
    window : (float, float) or sequence of them, optional
        The zoomed window ``(start, end)`` in seconds instead (e.g. the first
        seconds, where an observer converges), or several, one column each; within
        the run, start < end.
    title : str, optional
        Figure title; default "true and estimated".
    targets : mapping of str to str, optional
        ``{variable: other}``: draw the dataset variable ``other`` (same dims as
        ``variable``, labelled by its ``long_name``) in blue in the panels of
        ``variable``, for an estimate that converges to something other than the
        truth (a bias estimate that also absorbs a model error).
    transient : float, optional
        Seconds at the start of the run left out of the full-run column's vertical
        scale: a start transient (an initial estimate far off) is clipped there,
        with a note, and is shown whole in a zoom window that covers it.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If a panel names a missing variable or component, ``run`` is out of range,
        ``zoom`` is not a finite positive number, a window lies outside the run or
        a target is missing.
    """
    panels, run, zoom = _check_estimate_arguments(ds, panels, run, zoom)
    targets = _check_targets(ds, panels, targets)
    time = np.asarray(ds["time"].values, dtype=float)
    windows = _windows(window, time, zoom)
    if transient is not None and not (math.isfinite(float(transient)) and 0 <= float(transient) < time[-1] - time[0]):
        raise ValueError(f"transient must be a number of seconds with 0 <= transient < {time[-1] - time[0]:g} (the run); got {transient!r}")

    heading = title if title is not None else "true and estimated"
    caption = _run_caption(ds, run)
    heading = heading if caption is None else f"{heading}\n{caption}"
    fig, cells, tops = _panel_figure([list(range(len(panels)))], windows, heading)
    parts = _window_parts(time, windows)
    drawn: set[str] = set()
    target_labels = []
    for (full, zoomed), (variable, label) in zip(cells, panels):
        measured = f"measured_{variable}"
        panel = _make_panel(
            ds[variable].attrs,
            _quantity(variable, label),
            _run_values(ds[variable], label, run),
            _run_values(ds[f"{variable}_hat"], label, run),
            target=_run_values(ds[targets[variable]], label, run) if variable in targets else None,
            measured=_run_values(ds[measured], label, run) if measured in ds else None,
        )
        if variable in targets:
            name = ds[targets[variable]].attrs.get("long_name", targets[variable])
            if name not in target_labels:
                target_labels.append(name)
        drawn |= _draw_panel(full, zoomed, panel, time, windows, parts, compared_style=_ESTIMATE_STYLE, transient=transient)
    _dense_title(tops, drawn, time)
    _panel_legend(fig, drawn, compared_style=_ESTIMATE_STYLE, target_labels=target_labels)
    fig.suptitle(heading)
    return fig


def plot_trajectories(ds: xr.Dataset, panels, *, run: int = 0, title: str | None = None):
    """The true course of some signals, one row per panel (Calugi 2002, Figs. 2.3, 2.5, 2.7).

    Parameters
    ----------
    ds : xarray.Dataset
        Results of :meth:`lookout.Trajectory.to_xarray`.
    panels : sequence of (str, str or None)
        ``(variable, component)`` as in :func:`plot_estimates`; the variable need not
        have an estimate.
    run : int, default 0
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    panels = [(variable, label) for variable, label in panels]
    if not panels:
        raise ValueError("panels must name at least one (variable, component) pair")
    for variable, label in panels:
        if variable not in ds:
            raise ValueError(f"panels: the dataset has no variable {variable!r}")
        _component(ds[variable], label)
    if not 0 <= run < ds.sizes["run"]:
        raise ValueError(f"run must satisfy 0 <= run < {ds.sizes['run']}; got {run}")
    time = np.asarray(ds["time"].values, dtype=float)
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 2.2 * len(panels) + 0.6), layout="constrained", sharex=True, squeeze=False)
    for ax, (variable, label) in zip(axes[:, 0], panels):
        attrs = ds[variable].attrs
        values = np.asarray(_component(ds[variable], label).isel(run=run).values, dtype=float)
        scale, units = _DISPLAY_UNITS.get(attrs.get("units", ""), (1.0, attrs.get("units", "")))
        ax.plot(time, values * scale, color=_TRUTH_STYLE["color"], lw=1.2)
        frame = attrs.get("frame", "")
        quantity = f"{_quantity(variable, label)} ({units})"
        ax.set_ylabel(f"{frame}\n{quantity}" if frame else quantity)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 0].set_xlim(time[0], time[-1])
    caption = _run_caption(ds, run)
    heading = title if title is not None else "trajectories"
    fig.suptitle(heading if caption is None else f"{heading}\n{caption}")
    return fig


# --------------------------------------------------------------------------- lookout run

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


def _matching(ds: xr.Dataset, name: str, like: str) -> str | None:
    """``name`` if the dataset has it as a series with the dims of ``like``."""
    return name if name in ds.data_vars and _series_variable(ds, name) and ds[name].dims == ds[like].dims else None


def run_estimates(ds: xr.Dataset) -> list[tuple[str, str | None]]:
    """``(estimate, truth or None)`` of every estimated variable of a results Dataset.

    An estimate is ``<name>_hat`` (the estimate of the plant variable ``<name>``, or
    a parameter estimate) or ``theta_<name>`` (a parameter estimate); its truth is
    ``<name>`` with the same dims, where the dataset records one.
    """
    found = []
    for name in ds.data_vars:
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
    found = []
    for name in ds.data_vars:
        if not (name.endswith("_desired") and _series_variable(ds, name)):
            continue
        base = name[: -len("_desired")]
        truth, component = _matching(ds, base, name), None
        if truth is None and ds[name].ndim == 2:
            units = ds[name].attrs.get("units")
            for other in ds.data_vars:
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
    found = []
    for name in ds.data_vars:
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


def plot_run_estimates(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None):
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


def plot_run_reference(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None):
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


def plot_run_input(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None):
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


def plot_run_thrusters(ds: xr.Dataset, *, run: int = 0, zoom: float = 200.0, title: str | None = None):
    """Each thruster's thrust and angle, commanded and delivered, and the allocation's
    shortfall (``thrusters.png`` of ``lookout run`` with a thruster actuator).

    Left the whole run, right a zoom on its last ``zoom`` seconds (on a run shorter than
    five times that, its last fifth: :func:`zoom_window`). Top: thrust per
    thruster, the delivered thrust solid over the commanded one dotted, in the same
    colour. Middle: the angle of each azimuth and rudder (deg), delivered solid,
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
    figure.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 7), frameon=False)
    figure.suptitle(_heading(title, f"thrusters: thrust, angle and allocation shortfall\nrun {run} of {ds.sizes['run']}"))
    return figure


# --------------------------------------------------------------------------- Bode

#: The frequencies of the tuning rule (48): dataset variable, legend label, gid, style.
_MARKERS = (
    ("bias_filter_frequency", "1/T", "marker_1/T", {"color": "tab:purple", "ls": ":", "lw": 1.3}),
    ("bias_gain_ratio", "λ/κ", "marker_lambda/kappa", {"color": "tab:olive", "ls": "-.", "lw": 1.2}),
    ("wave_frequency", r"$\omega_o$", "marker_w_o", {"color": "tab:cyan", "ls": "--", "lw": 1.2}),
    ("cutoff_frequency", r"$\omega_c$", "marker_w_c", {"color": "tab:brown", "ls": (0, (6, 2, 1, 2, 1, 2)), "lw": 1.2}),
)
_CURVES = {
    "h0": {"color": "tab:blue", "lw": 1.3},
    "hB": {"color": "tab:green", "lw": 1.3, "ls": "--"},
    "h": {"color": "k", "lw": 1.1},
}
_SPR_STYLE = {"color": "tab:red", "ls": ":", "lw": 1.2}
_VIOLATION_STYLE = {"color": "tab:red", "alpha": 0.18, "lw": 0, "zorder": 0.5}


def _runs(x: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """The (first, last) x of each run of consecutive True values of ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(float(x[start]), float(x[stop - 1])) for start, stop in zip(edges[::2], edges[1::2])]


_REQUIRED = (
    "h0_magnitude",
    "h0_phase_deg",
    "hB_phase_deg",
    "h_phase_deg",
) + tuple(marker[0] for marker in _MARKERS)


def _per_dof(response: xr.Dataset, name: str, dof: str) -> tuple[np.ndarray, str]:
    """The values of ``name`` (``hB_magnitude``, ``h_magnitude``, ``velocity_injection_gain``)
    for ``dof`` and their unit.

    :func:`lookout.analysis.frequency_response` splits these by kind of DOF, since a
    force per metre and a moment per radian share no unit: ``<name>_translation`` over
    ``translation`` (surge, sway) and ``<name>_yaw``. A variable ``name`` over ``dof``
    with one unit is read too.
    """
    if name in response.variables and "dof" in response[name].dims:
        variable = response[name].sel(dof=dof)
    elif f"{name}_translation" in response.variables and "translation" in response.coords and dof in response["translation"].values.tolist():
        variable = response[f"{name}_translation"].sel(translation=dof)
    elif f"{name}_{dof}" in response.variables:
        variable = response[f"{name}_{dof}"]
    else:
        raise ValueError(
            f"response must be a frequency_response() Dataset; it has no {name!r} for the DOF {dof!r} ({name}_translation or {name}_{dof})"
        )
    return np.asarray(variable.values, dtype=float), str(variable.attrs.get("units", ""))


def minimum_phase_of_h(response: xr.Dataset, dof: str) -> tuple[float, float]:
    """Minimum phase of h (deg) over frequencies up to 10 w_c, and where (rad/s)
    (:func:`lookout.analysis.minimum_phase_in_band` on the dataset's grid)."""
    from lookout.analysis import minimum_phase_in_band

    return minimum_phase_in_band(
        response["frequency"].values, response["h_phase_deg"].sel(dof=dof).values, float(response["cutoff_frequency"].sel(dof=dof))
    )


def _minus(text: str) -> str:
    return text.replace("-", "\N{MINUS SIGN}")


def plot_bode(response: xr.Dataset, *, title: str | None = None):
    """Bode plot of the error loops h0, hB and h = hB h0 of all three DOFs.

    Fossen & Strand (1999), Fig. 6 (and the tuning behind Figs. 9–11): one column
    per degree of freedom (surge, sway, yaw). Because hB and h carry units that
    differ by DOF, they are shown normalized by the velocity injection gain kappa:
    hB/kappa is dimensionless and h/kappa, like h0, is in seconds. Rows:

    1. magnitude of h0 and h/kappa in dB re 1 s;
    2. magnitude of hB/kappa in dB (dimensionless);
    3. phase of h0, hB and h in degrees, with the SPR bound at -90 deg and the
       minimum phase of h below 10 w_c written on the panel;
    4. the margin of the phase of h to -90 deg on a log axis, so that a margin of
       a fraction of a degree is readable.

    Every panel marks the frequencies of the tuning rule (48),
    1/T << lambda/kappa < w_o < w_c, with vertical lines (gids ``marker_1/T``,
    ``marker_lambda/kappa``, ``marker_w_o``, ``marker_w_c``).

    Parameters
    ----------
    response : xarray.Dataset
        From :func:`lookout.analysis.frequency_response`: ``h0_magnitude`` and the
        ``*_phase_deg`` variables with dims (frequency, dof); per DOF
        ``bias_filter_frequency``, ``bias_gain_ratio``, ``wave_frequency`` and
        ``cutoff_frequency`` (rad/s); and hB, h and kappa, which have one unit per
        kind of DOF, as ``hB_magnitude_translation``, ``h_magnitude_translation``,
        ``velocity_injection_gain_translation`` over ``translation`` (surge, sway)
        and ``hB_magnitude_yaw``, ``h_magnitude_yaw``, ``velocity_injection_gain_yaw``.
    title : str, optional
        Figure title; default "Error-loop frequency response h0, hB, h
        (Fossen & Strand 1999, Fig. 6)".

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If a required variable, or hB, h or kappa of one of its DOFs, is missing
        from ``response``.
    """
    missing = [name for name in _REQUIRED if name not in response.variables]
    if missing:
        raise ValueError(f"response must be a frequency_response() Dataset; missing variables {missing}")
    frequency = np.asarray(response["frequency"].values, dtype=float)
    dofs = response["dof"].values.tolist()  # one column per loop, however many

    fig, axes = plt.subplots(
        4,
        len(dofs),
        figsize=(13 * len(dofs) / 3, 10),
        layout="constrained",
        sharex=True,
        sharey="row",
        squeeze=False,
        gridspec_kw={"height_ratios": (1.0, 0.8, 1.0, 0.8)},
    )
    magnitude, gain, phase, margin = axes
    # every DOF's hB, h and kappa are there before anything is drawn
    split = {dof: {name: _per_dof(response, name, dof) for name in ("hB_magnitude", "h_magnitude", "velocity_injection_gain")} for dof in dofs}
    for column, dof in enumerate(dofs):
        kappa, unit = split[dof]["velocity_injection_gain"]
        kappa = float(kappa)
        curve = {"h0": response["h0_magnitude"].sel(dof=dof).values, "hB": split[dof]["hB_magnitude"][0], "h": split[dof]["h_magnitude"][0]}
        angle = {name: response[f"{name}_phase_deg"].sel(dof=dof).values for name in ("h0", "hB", "h")}

        ax = magnitude[column]
        ax.semilogx(frequency, 20 * np.log10(curve["h0"]), **_CURVES["h0"], label="$h_0$")
        ax.semilogx(frequency, 20 * np.log10(curve["h"] / kappa), **_CURVES["h"], label=r"$h/\kappa$")
        ax.set_title(f"{dof}:  κ = {kappa:.3g} {unit}".rstrip(), fontsize=10)

        ax = gain[column]
        ax.semilogx(frequency, 20 * np.log10(curve["hB"] / kappa), **_CURVES["hB"], label=r"$h_B/\kappa$")

        ax = phase[column]
        for name, label in (("h0", "$h_0$"), ("hB", "$h_B$"), ("h", "$h$")):
            ax.semilogx(frequency, angle[name], **_CURVES[name], label=label)
        ax.axhline(-90.0, **_SPR_STYLE, label="−90° (SPR bound)")
        lowest, where = minimum_phase_of_h(response, dof)
        ax.plot([where], [lowest], "o", color="k", ms=4, zorder=4)
        text = _minus(f"min phase of h {lowest:.2f}° at {where:.3g} rad/s\nmargin {lowest + 90.0:.2f}° to -90° ($\\omega \\leq 10\\,\\omega_c$)")
        ax.text(
            0.98,
            0.97,
            text,
            transform=ax.transAxes,
            fontsize=8,
            va="top",
            ha="right",
            gid="min_phase_annotation",
            bbox={"boxstyle": "round,pad=0.3", "facecolor": "white", "edgecolor": "0.7", "alpha": 0.9},
        )

        ax = margin[column]
        distance = angle["h"] + 90.0
        positive = np.where(distance > 0, distance, np.nan)
        ax.semilogx(frequency, positive, **_CURVES["h"], label=r"$\angle h + 90°$")
        if lowest > -90.0:
            ax.plot([where], [lowest + 90.0], "o", color="k", ms=4, zorder=4)
        # where the phase of h is at or below -90 deg the margin has no log value: shade it
        for start, stop in _runs(frequency, distance <= 0):
            for panel in (phase[column], ax):
                panel.axvspan(start, stop, **_VIOLATION_STYLE, label="SPR violated: phase of h ≤ −90°")
        ax.axvspan(10.0 * float(response["cutoff_frequency"].sel(dof=dof)), frequency[-1], color="0.5", alpha=0.15, lw=0)
        ax.set_yscale("log")

        for ax in axes[:, column]:
            for variable, label, gid, style in _MARKERS:
                ax.axvline(float(response[variable].sel(dof=dof)), **style, label=label, gid=gid, zorder=1.5)
            ax.grid(alpha=0.3, which="major")
            # no minor ticks: on 12 log axes they were 1100 tick objects and 4 of the 5 s it took to save
            ax.xaxis.set_minor_locator(NullLocator())
            ax.yaxis.set_minor_locator(NullLocator())

    magnitude[0].set_ylabel("magnitude (dB re 1 s)\n$h_0$ and $h/\\kappa$")
    gain[0].set_ylabel("magnitude (dB)\n$h_B/\\kappa$ (dimensionless)")
    phase[0].set_ylabel("phase (deg)")
    margin[0].set_ylabel("margin to −90°\n$\\angle h + 90°$ (deg)")
    for ax in margin:
        ax.set_xlabel("frequency ω (rad/s)")
    # -120 to 90 deg holds a passing design's phases (h0's notch lead stays below +90 deg);
    # a deeper minimum or a higher peak widens it; the band above the top tick holds the
    # minimum-phase note, clear of every curve
    phases = np.asarray(response[["h0_phase_deg", "hB_phase_deg", "h_phase_deg"]].to_array().values, dtype=float)
    bottom = min(-120.0, 30.0 * np.floor(np.nanmin(phases) / 30.0))
    top = max(90.0, 30.0 * np.ceil(np.nanmax(phases) / 30.0))
    phase[0].set_ylim(bottom, top + 60.0)
    phase[0].set_yticks(np.arange(bottom, top + 1.0, 30.0))
    margins = np.asarray(response["h_phase_deg"].values, dtype=float) + 90.0
    positive = margins[margins > 0]
    low = min(0.1, 0.5 * positive.min()) if positive.size else 0.1
    margin[0].set_ylim(low, 200.0)
    magnitude[0].set_xlim(frequency[0], frequency[-1])

    # one legend for the whole figure, below the panels, so that none covers a curve
    def style(name, **extra):
        return {k: v for k, v in {**_CURVES[name], **extra}.items() if k != "zorder"}

    handles = [
        Line2D([], [], **style("h0"), label="$h_0$"),
        Line2D([], [], **style("hB"), label=r"$h_B$ (magnitude: $h_B/\kappa$)"),
        Line2D([], [], **style("h"), label=r"$h$ (magnitude: $h/\kappa$; margin $\angle h + 90°$)"),
        Line2D([], [], **_SPR_STYLE, label="−90° (SPR bound)"),
        Patch(facecolor="0.5", alpha=0.3, label=r"$\omega > 10\,\omega_c$ (margin not judged)"),
    ]
    if np.any(margins <= 0):
        handles.append(Patch(**{k: v for k, v in _VIOLATION_STYLE.items() if k != "zorder"}, label="SPR violated: phase of h ≤ −90°"))
    handles += [Line2D([], [], **style, label=label) for _, label, _, style in _MARKERS]
    fig.legend(
        handles=handles,
        loc="outside lower center",
        ncols=5,
        fontsize=9,
        frameon=False,
        title=r"markers: the tuning rule (48), $1/T \ll \lambda/\kappa < \omega_o < \omega_c$",
        title_fontsize=9,
    )
    fig.suptitle(title if title is not None else "Error-loop frequency response h0, hB, h (Fossen & Strand 1999, Fig. 6)")
    return fig
