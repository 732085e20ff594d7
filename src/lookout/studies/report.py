"""The static HTML report of a campaign store: one self-contained page.

:func:`write_report` reads a store written by :class:`~lookout.studies.store.CampaignStore`
and writes one HTML file that needs no server and loads nothing from the network: the
figures are PNG images embedded as ``data:`` URIs, the style sheet is inline, and the
only script is a few lines that count the images the browser managed to decode (shown
in the page's footnote, ``images loaded: N of M``; a browser test reads it).

The page holds, in order:

- **provenance**: the title, the completion status (chunks and runs done; a store
  whose campaign is still running says it is partial), lookout version, creation time,
  campaign fingerprint, sweep kind and sizes, compute time and workers;
- the **campaign spec** as tables: the base scenario (its components, the keys that
  differ from their kind's defaults, and every key, dotted, collapsed),
  the seeds, chunks, metrics, metric window, divergence rule and kept trajectories, and
  the sweep axes (fields, values or range, units, scale); the spec as JSON, collapsed;
- a **summary** table per metric (median and 10th/90th percentiles over every computed run);
- per metric and per sweep axis, the **metric against the axis value** (see
  :func:`report_figures`), two figures a row on a wide page, one on a narrow one;
- for a grid of two or more axes, a **heat map** per metric over the first two axes;
- **divergence**: when a run diverged, the fraction of runs diverged against each axis
  and a table of the diverged runs; otherwise one sentence, "No run diverged (n of N
  runs finished)".

Runs not computed yet are NaN in the store and are left out of every statistic; a
statistic with no run behind it is not drawn (and a heat-map cell is grey). A store
with no finished chunk gets a page that says so, with its spec and no figures.
"""

from __future__ import annotations

import base64
import datetime
import html
import io
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.typing import RcKeyType

__all__ = ["report_figures", "write_report", "default_report_path"]

#: Figure resolution (dots per inch) of the figures' layout: a 7 in figure is 700 px.
DPI = 100
#: Resolution of the PNGs: 1.5x the layout's, so a figure stays sharp in a column of a
#: wide page (up to about 1000 px) and on high-density screens.
PNG_DPI = 150
#: The diverged-runs table shows at most this many rows.
MAX_DIVERGED_ROWS = 200
#: Percentiles of the spread bands and error bars.
LOW, HIGH = 10, 90

_RC: dict[RcKeyType, Any] = {
    "font.size": 10,
    "axes.titlesize": 11,
    "axes.labelsize": 10,
    "legend.fontsize": 9,
    "xtick.labelsize": 9,
    "ytick.labelsize": 9,
}


# ----------------------------------------------------------------------------------
# the data behind the figures


@dataclass(frozen=True)
class _Axis:
    """A sweep axis: its store coordinate, label for plots, per-point values and levels."""

    name: str  # coordinate name in the store
    label: str  # axis label, units included
    values: np.ndarray  # (points,)
    levels: np.ndarray  # distinct values, sorted when numeric
    numeric: bool

    def positions(self) -> np.ndarray:
        """Where the levels sit on a plot's axis: the values, or 0, 1, ... when categorical."""
        return self.levels.astype(float) if self.numeric else np.arange(len(self.levels), dtype=float)

    def point_positions(self) -> np.ndarray:
        """Where each point sits on a plot's axis."""
        if self.numeric:
            return self.values.astype(float)
        index = {value: i for i, value in enumerate(self.levels.tolist())}
        return np.asarray([index[value] for value in self.values.tolist()], dtype=float)


@dataclass(frozen=True)
class _Metric:
    """A metric variable: name in the store, its ``KIND:SIGNAL``, units, description, data."""

    variable: str
    name: str
    units: str
    description: str
    data: np.ndarray  # (points, seeds), NaN where not computed or diverged

    @property
    def label(self) -> str:
        return f"{self.name} ({self.units})" if self.units else self.name


@dataclass
class _Figure:
    key: str  # file name of the PNG
    figure: Any  # matplotlib.figure.Figure
    caption: str
    section: str  # "metric", "heatmap" or "diverged"
    metric: str | None = None


def _fmt(value) -> str:
    """A number for a tick label or table cell: 4 significant digits, no trailing noise."""
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value)).lower()
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        if not np.isfinite(value):
            return str(float(value))
        return f"{float(value):.4g}"
    return str(value)


def _stats(values: np.ndarray) -> tuple[float, float, float, int]:
    """(median, 10th percentile, 90th percentile, count) of the finite ``values``; NaNs if none."""
    finite = np.asarray(values, dtype=float).ravel()
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return np.nan, np.nan, np.nan, 0
    low, high = np.percentile(finite, [LOW, HIGH])
    return float(np.median(finite)), float(low), float(high), int(finite.size)


def _fraction(values: np.ndarray) -> tuple[float, int]:
    """(mean, count) of the non-NaN ``values`` (a fraction for 0/1 values); NaN if none."""
    known = np.asarray(values, dtype=float).ravel()
    known = known[~np.isnan(known)]
    return (float(known.mean()), int(known.size)) if known.size else (np.nan, 0)


def _spans_decades(values: np.ndarray, decades: float = 2.0) -> bool:
    """Whether the finite ``values`` are all positive and span more than ``decades``."""
    finite = np.asarray(values, dtype=float).ravel()
    finite = finite[np.isfinite(finite)]
    return finite.size > 1 and finite.min() > 0 and finite.max() / finite.min() > 10.0**decades


_UNIT = re.compile(r"\(([A-Za-z%][A-Za-z0-9/^*.·%-]{0,11})\)")


def _setting_units(document: dict | None, fields: list[str]) -> str | None:
    """The units of a scenario key, read from its description (``"Dominating wave
    frequency w0_i (rad/s)."`` -> ``rad/s``); None when the description gives none."""
    if not document or not fields:
        return None
    try:
        from lookout.scenario.file import composition_comments

        description = composition_comments(document["scenario"]).get(re.sub(r"\[.*?\]", "", fields[0]), "")
    except Exception:  # best effort: a label without units is still a label
        return None
    match = _UNIT.search(description)
    return match.group(1) if match else None


def _axes(ds, document: dict | None) -> list[_Axis]:
    names = json.loads(ds.attrs.get("axes", "[]"))
    axes = []
    for name in names:
        coordinate = ds[name]
        values = np.asarray(coordinate.values)
        attrs = coordinate.attrs
        label = str(attrs.get("long_name", name))
        fields = [f.strip() for f in str(attrs.get("fields", "")).split(",") if f.strip()]
        numeric = np.issubdtype(values.dtype, np.number) and not np.issubdtype(values.dtype, np.bool_)
        if int(attrs.get("scale", 0)):
            label += " (× base value)"
        elif numeric:  # a choice ("printed", "kyp") has no units
            units = attrs.get("units") or _setting_units(document, fields)
            if units:
                label += f" ({units})"
        if numeric:
            levels = np.unique(values)
        else:
            seen = []
            for value in values.tolist():
                if value not in seen:
                    seen.append(value)
            levels = np.asarray(seen, dtype=object)
        axes.append(_Axis(name, label, values, levels, bool(numeric)))
    return axes


def _metrics(ds, document: dict | None) -> list[_Metric]:
    candidates = [
        name for name, variable in ds.data_vars.items() if name != "diverged" and variable.dims == ("point", "seed") and "metric" in variable.attrs
    ]
    order = [m.replace(":", "__") for m in (document or {}).get("metrics", [])]
    candidates.sort(key=lambda name: order.index(name) if name in order else len(order))
    result = []
    for name in candidates:
        variable = ds[name]
        attrs = variable.attrs
        result.append(
            _Metric(
                name,
                str(attrs.get("metric", name)),
                str(attrs.get("units", "")),
                str(attrs.get("long_name", name)),
                np.asarray(variable.values, dtype=float),
            )
        )
    return result


def _diverged(ds) -> np.ndarray:
    if "diverged" in ds:
        return np.asarray(ds["diverged"].values, dtype=float)
    return np.full((ds.sizes["point"], ds.sizes["seed"]), np.nan)


# ----------------------------------------------------------------------------------
# figures


def _new_figure(size=(7.0, 4.2)):
    from matplotlib.figure import Figure

    return Figure(figsize=size, dpi=DPI, layout="constrained")


def _no_data(ax, message: str = "no runs computed yet") -> None:
    ax.text(0.5, 0.5, message, transform=ax.transAxes, ha="center", va="center", color="0.4")


def _x_axis(ax, axis: _Axis, kind: str) -> None:
    """Label the x axis; tick at every level of a short grid; log scale for a grid whose
    positive values span more than two decades (a Latin hypercube's strata are linear)."""
    ax.set_xlabel(axis.label)
    if not axis.numeric:
        ax.set_xticks(axis.positions(), [_fmt(v) for v in axis.levels])
    elif kind == "grid" and _spans_decades(axis.levels):
        ax.set_xscale("log")
    elif kind == "grid" and len(axis.levels) <= 12:
        ax.set_xticks(axis.positions(), [_fmt(v) for v in axis.levels])


def _metric_figure(metric: _Metric, axis: _Axis, axes: list[_Axis], kind: str) -> _Figure:
    """The metric against one axis's value.

    Grid: the median over seeds (and over the other axes' points at the same axis
    value) as a line with markers, and the 10th-90th percentile band over the same
    runs, shaded. Latin hypercube: each point's median over its seeds against the
    point's axis value, with a 10th-90th percentile error bar.
    """
    figure = _new_figure()
    ax = figure.add_subplot()
    others = [a.name for a in axes if a.name != axis.name]
    if kind == "grid":
        stats = np.asarray([_stats(metric.data[axis.values == level]) for level in axis.levels.tolist()])
        median, low, high, count = stats.T if len(stats) else np.zeros((4, 0))
        x = axis.positions()
        over = "seeds" + (f" and the other axes' points ({', '.join(others)}) at the same {axis.name}" if others else "")
        if axis.numeric:
            ax.fill_between(x, low, high, alpha=0.25, color="C0", linewidth=0, label=f"{LOW}th–{HIGH}th percentile")
            ax.plot(x, median, "o-", color="C0", label="median")
            caption = (
                f"{metric.description} against {axis.name}: the median over {over} (line), "
                f"and the {LOW}th–{HIGH}th percentile of the same runs (band)."
            )
        else:  # choices: nothing lies between them, so no line
            ax.errorbar(
                x,
                median,
                yerr=[median - low, high - median],
                fmt="o",
                color="C0",
                ecolor="C0",
                elinewidth=1.5,
                capsize=4,
                label=f"median; bar: {LOW}th–{HIGH}th percentile",
            )
            ax.set_xlim(x.min() - 0.5, x.max() + 0.5)
            caption = (
                f"{metric.description} for each {axis.name}: the median over {over} (marker), "
                f"and the {LOW}th–{HIGH}th percentile of the same runs (bar)."
            )
    else:
        stats = np.asarray([_stats(row) for row in metric.data])
        median, low, high, count = stats.T if len(stats) else np.zeros((4, 0))
        x = axis.point_positions()
        ax.errorbar(
            x,
            median,
            yerr=[median - low, high - median],
            fmt="o",
            color="C0",
            ecolor="C0",
            elinewidth=1,
            capsize=2,
            markersize=4,
            label=f"point median over seeds; bar: {LOW}th–{HIGH}th percentile",
        )
        caption = (
            f"{metric.description} against {axis.name}: one marker per Latin-hypercube point, the median over its seeds, "
            f"with a bar from the {LOW}th to the {HIGH}th percentile over its seeds"
            + (f" (the other axes, {', '.join(others)}, vary between points)." if others else ".")
        )
    computed = int(np.isfinite(metric.data).sum())
    if computed < metric.data.size:
        caption += f" Based on {computed} of {metric.data.size} runs (the rest not computed yet or diverged)."
    if not np.isfinite(median).any():
        _no_data(ax)
    elif _spans_decades(metric.data):
        ax.set_yscale("log")
    _x_axis(ax, axis, kind)
    ax.set_ylabel(metric.label)
    ax.set_title(f"{metric.description}\nagainst {axis.name}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    return _Figure(f"{metric.variable}-vs-{axis.name}.png", figure, caption, "metric", metric.variable)


def _heatmap_figure(metric: _Metric, axes: list[_Axis]) -> _Figure:
    """The median over seeds of a metric on the grid of the first two axes (the first
    across, the second up); over more axes, the median over seeds and every other axis."""
    import matplotlib
    from matplotlib.colors import LogNorm, Normalize

    first, second = axes[0], axes[1]
    grid = np.full((len(second.levels), len(first.levels)), np.nan)
    for i, a in enumerate(first.levels.tolist()):
        for j, b in enumerate(second.levels.tolist()):
            grid[j, i] = _stats(metric.data[(first.values == a) & (second.values == b)])[0]
    figure = _new_figure((7.0, 5.0))
    ax = figure.add_subplot()
    finite = grid[np.isfinite(grid)]
    if finite.size == 0:
        norm = Normalize(0.0, 1.0)
    elif _spans_decades(finite):
        norm = LogNorm(finite.min(), finite.max())
    else:
        low, high = float(finite.min()), float(finite.max())
        norm = Normalize(low, high if high > low else low + (abs(low) or 1.0) * 1e-9)
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="#d9d9d9")
    image = ax.imshow(np.ma.masked_invalid(grid), origin="lower", aspect="auto", cmap=cmap, norm=norm, interpolation="nearest")
    colorbar = figure.colorbar(image, ax=ax)
    colorbar.set_label(f"median {metric.label}")
    for axis, set_ticks in ((first, ax.set_xticks), (second, ax.set_yticks)):
        step = max(1, int(np.ceil(len(axis.levels) / 12)))
        ticks = np.arange(len(axis.levels))[::step]
        set_ticks(ticks, [_fmt(axis.levels[t]) for t in ticks])
    ax.set_xlabel(first.label)
    ax.set_ylabel(second.label)
    if grid.size <= 64:
        for (j, i), value in np.ndenumerate(grid):
            if np.isfinite(value):
                shade = norm(value)
                ax.text(i, j, f"{value:.3g}", ha="center", va="center", fontsize=8, color="white" if shade < 0.6 else "black")
    if finite.size == 0:
        _no_data(ax)
    rest = [a.name for a in axes[2:]]
    ax.set_title(f"median {metric.description}")
    caption = (
        f"Median of {metric.description} over seeds"
        + (f" and over the other axes ({', '.join(rest)})" if rest else "")
        + f" at each ({first.name}, {second.name}) of the grid."
    )
    if np.isnan(grid).any():
        caption += " Grey cells: no run computed yet (or every run there diverged)."
    return _Figure(f"heatmap-{metric.variable}.png", figure, caption, "heatmap", metric.variable)


def _diverged_figure(diverged: np.ndarray, axis: _Axis, axes: list[_Axis], kind: str) -> _Figure:
    """The fraction of runs that diverged against one axis's value: over seeds and the
    other axes' points at each value (grid, a line), or over each point's seeds (Latin
    hypercube, one marker per point)."""
    figure = _new_figure()
    ax = figure.add_subplot()
    others = [a.name for a in axes if a.name != axis.name]
    if kind == "grid":
        fractions = np.asarray([_fraction(diverged[axis.values == level])[0] for level in axis.levels.tolist()])
        ax.plot(axis.positions(), fractions, "o-", color="C3", label="fraction diverged")
        over = "seeds" + (f" and the other axes' points ({', '.join(others)})" if others else "")
        caption = f"Fraction of the computed runs that diverged at each {axis.name}, over {over}."
    else:
        fractions = np.asarray([_fraction(row)[0] for row in diverged])
        ax.plot(axis.point_positions(), fractions, "o", color="C3", markersize=4, label="fraction of a point's seeds diverged")
        caption = f"Fraction of each Latin-hypercube point's computed runs that diverged, against {axis.name}."
    known = int((~np.isnan(diverged)).sum())
    if known < diverged.size:
        caption += f" Based on {known} of {diverged.size} runs (the rest not computed yet)."
    if not np.isfinite(fractions).any():
        _no_data(ax)
    ax.set_ylim(-0.04, 1.04)
    _x_axis(ax, axis, kind)
    ax.set_ylabel("fraction of runs diverged (1)")
    ax.set_title(f"runs diverged against {axis.name}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    return _Figure(f"diverged-vs-{axis.name}.png", figure, caption, "diverged")


def _build(ds, document: dict | None) -> list[_Figure]:
    """The figures worth drawing: none before any run has finished; a metric's only
    when some run has a value of it; the divergence figures only when a run diverged."""
    import matplotlib

    kind = str(ds.attrs.get("sweep_kind", "grid"))
    axes = _axes(ds, document)
    metrics = [metric for metric in _metrics(ds, document) if np.isfinite(metric.data).any()]
    diverged = _diverged(ds)
    figures: list[_Figure] = []
    if np.isnan(diverged).all():  # nothing finished: a plot would be an empty frame
        return figures
    with matplotlib.rc_context(_RC):
        for metric in metrics:
            for axis in axes:
                figures.append(_metric_figure(metric, axis, axes, kind))
        if kind == "grid" and len(axes) >= 2:
            for metric in metrics:
                figures.append(_heatmap_figure(metric, axes))
        if (diverged == 1).any():
            for axis in axes:
                figures.append(_diverged_figure(diverged, axis, axes, kind))
    return figures


def report_figures(ds: xr.Dataset, campaign_document: dict | None) -> dict:
    """The report's figures, by PNG file name, as :class:`matplotlib.figure.Figure`\\ s.

    ``ds`` is the store's Dataset (:meth:`CampaignStore.open`), ``campaign_document`` its
    :meth:`CampaignStore.campaign_document` (for the order of the metrics and the units
    of the swept settings; None will do). The figures:

    - ``METRIC-vs-AXIS.png`` (each metric, each axis): on a grid, the median over seeds
      and over the other axes' points at each axis value (line with markers) and the
      10th-90th percentile band of those runs; on a Latin hypercube, each point's median
      over its seeds with a 10th-90th percentile error bar. Log y scale when the metric
      is positive and spans more than two decades.
    - ``heatmap-METRIC.png`` (grids of two or more axes): the median over seeds (and over
      every axis after the second) on the grid of the first two axes, with a colorbar.
    - ``diverged-vs-AXIS.png`` (each axis): the fraction of runs diverged.

    Only figures with something to show are made: none while no run has finished
    (``diverged`` is NaN everywhere), none for a metric without a finite value (every
    finished run diverged), and the divergence figures only when at least one run
    diverged. The figures are made without pyplot (nothing to close; save with
    ``savefig``).
    """
    return {figure.key: figure.figure for figure in _build(ds, campaign_document)}


# ----------------------------------------------------------------------------------
# the page


def default_report_path(store_path: str | Path) -> Path:
    """``DIR/NAME-report.html`` beside the store ``DIR/NAME.zarr`` (or ``DIR/NAME``)."""
    path = Path(str(store_path).rstrip("/"))
    name = path.name[: -len(".zarr")] if path.name.endswith(".zarr") else path.name
    return path.with_name(f"{name}-report.html")


def _pretty_json(value, indent: str = "") -> str:
    """JSON with one key per line, but a list of numbers or strings on one line."""
    inner = indent + "  "
    if isinstance(value, dict) and value:
        items = [f"{inner}{json.dumps(str(k))}: {_pretty_json(v, inner)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    if isinstance(value, list) and value and any(isinstance(v, (dict, list)) for v in value):
        return "[\n" + ",\n".join(inner + _pretty_json(v, inner) for v in value) + "\n" + indent + "]"
    return json.dumps(value)


def _png(figure) -> bytes:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=PNG_DPI)
    return buffer.getvalue()


def _table(header: list[str], rows: list[list[str]], attrs: str = "") -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "\n".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table{attrs}>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


def _definition_table(items: Sequence[tuple[str, str | list[str]]], attrs: str = ' class="provenance"') -> str:
    """A two-column table of names and values; a list value is one line per entry."""

    def cell(value):
        return "<br>".join(html.escape(line) for line in value) if isinstance(value, list) else html.escape(value)

    rows = "\n".join(f"<tr><th>{html.escape(k)}</th><td>{cell(v)}</td></tr>" for k, v in items)
    return f"<table{attrs}>\n{rows}\n</table>"


# ----------------------------------------------------------------------------------
# the spec as tables


def _spec_value(value) -> str:
    """A setting's value for a table cell: numbers to 6 significant digits, lists inline."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_spec_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_spec_value(v)}" for k, v in value.items()) + "}"
    return str(value)


def _flatten(settings: dict, prefix: str = "") -> dict[str, Any]:
    """Nested settings tables as dotted keys (``vessel.mass``); a list stays one value."""
    flat: dict[str, Any] = {}
    for key, value in settings.items():
        if isinstance(value, dict) and value:
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def _axis_rows(document: dict, kind: str) -> list[list[str]]:
    """One row per sweep axis: its name, field(s), values (with units) and how it applies."""
    from lookout.studies.campaign import Axis
    from lookout.studies.store import variable_name

    rows = []
    for raw in document.get("sweep", {}).get("axes", []):
        try:
            axis = Axis.model_validate(raw)
        except Exception:  # a store written by another version: show what it holds
            rows.append(["?", _spec_value(raw.get("field")), _spec_value(raw), ""])
            continue
        if axis.cases is not None:
            values = "; ".join(
                f"{_spec_value(label)}: " + (", ".join(f"{key} = {_spec_value(value)}" for key, value in case.items()) or "the base")
                for label, case in zip(axis.case_labels, axis.cases)
            )
            rows.append([variable_name(axis.label), ", ".join(axis.fields), values, "each case sets its keys"])
            continue
        tables = axis.values is not None and any(isinstance(v, dict) for v in axis.values)
        units = None if axis.scale or tables else _setting_units(document, list(axis.fields))
        suffix = f" ({units})" if units else ""
        if axis.values is not None:
            values = ", ".join(_spec_value(axis.value_label(v)) for v in axis.values) + suffix
        elif kind == "grid":
            assert axis.range is not None and axis.steps is not None  # Sweep: a grid axis without values has range and steps
            grid = np.linspace(axis.range[0], axis.range[1], axis.steps).tolist()
            values = f"{axis.steps} steps over [{_spec_value(axis.range[0])}, {_spec_value(axis.range[1])}]{suffix}: " + ", ".join(
                _spec_value(v) for v in grid
            )
        else:
            assert axis.range is not None  # Sweep: a latin-hypercube axis has range
            values = f"range [{_spec_value(axis.range[0])}, {_spec_value(axis.range[1])}]{suffix}"
        applied = "replaces the component" if tables else ("× base value" if axis.scale else "sets the value")
        rows.append([variable_name(axis.label), ", ".join(axis.fields), values, applied])
    return rows


def _spec_html(document: dict | None, metrics: list[_Metric], n_points: int, chunk_runs: int, total_chunks: int) -> str:
    """The campaign spec as tables: the base scenario, the campaign's settings, the sweep;
    then the spec as JSON, collapsed (what a resume compares, for provenance)."""
    if document is None:
        return "<p>The store holds no campaign spec.</p>"
    parts = []
    scenario = document.get("scenario") or {}
    parts += _composition_html(scenario)
    settings = _flatten(scenario.get("simulation") or {})
    parts += _campaign_html(document, metrics, settings, n_points, chunk_runs, total_chunks)
    return "\n".join(parts)


def _composition_html(scenario: dict) -> list[str]:
    """The base scenario of a composition: its components, then every key with its
    description (the keys that differ from their kind's default first)."""
    from lookout.scenario import registry
    from lookout.scenario.file import composition_comments

    components = [
        (role, f"{scenario[role].get('kind', '?')}" + (f" (design {scenario[role]['design']})" if "design" in scenario[role] else ""))
        for role in registry.COMPONENT_ROLES
        if isinstance(scenario.get(role), dict)
    ]
    try:
        descriptions = composition_comments(scenario)
    except Exception:  # a store written by another version: the values still show
        descriptions = {}
    rows, changed = [], []
    for role in ("simulation", *registry.COMPONENT_ROLES):
        for key, value in _flatten(scenario.get(role) or {}, f"{role}.").items():
            if key.endswith(".kind") or key.endswith(".design"):
                continue
            rows.append([key, _spec_value(value), descriptions.get(key, "")])
            default = _kind_default(scenario, key)
            if default is not _NO_DEFAULT and json.dumps(value) != json.dumps(default):
                changed.append([key, _spec_value(value), _spec_value(default), descriptions.get(key, "")])
    parts = ["<h3>Base scenario</h3>", _definition_table(components, ' class="provenance" id="spec-scenario"')]
    if changed:
        parts += [
            f"<p>The keys that differ from their kind's default ({len(changed)}):</p>",
            _table(["key", "value", "default", "description"], changed, ' id="spec-changed" class="numbers"'),
        ]
    parts.append(
        f"<details><summary>all {len(rows)} keys of the base scenario</summary>\n"
        + _table(["key", "value", "description"], rows, ' id="spec-settings" class="numbers"')
        + "\n</details>"
    )
    return parts


_NO_DEFAULT = object()


def _kind_default(scenario: dict, key: str):
    """The default of a component's parameter at the dotted ``key`` (or _NO_DEFAULT)."""
    from lookout.scenario import registry
    from lookout.scenario.composition import plain

    parts = key.split(".")
    role = parts[0]
    table: Any = scenario.get(parts[0])  # None for a role the scenario leaves out: indexing it fails below, and no default is shown
    if role == "simulation":
        from lookout.scenario.composition import SimulationSettings

        field = SimulationSettings.model_fields.get(parts[-1])
        return _NO_DEFAULT if field is None else field.default
    try:
        for part in parts[1:-1]:
            role, table = part, table[part]
        kind = registry.kind(role, table["kind"])
        parameter = next(p for p in kind.parameters(table.get("design")) if p.name == parts[-1])
    except Exception:  # initial values, simulation keys, an unknown kind: no default to show
        return _NO_DEFAULT
    return _NO_DEFAULT if parameter.required else plain(parameter.default)


def _campaign_html(document: dict, metrics: list, settings: dict, n_points: int, chunk_runs: int, total_chunks: int) -> list[str]:
    """The campaign around the base scenario: seeds, chunks, metrics, window, the sweep."""
    parts = []
    seeds = int(document.get("seeds_per_point", 1))
    first = int(document.get("seed", 0))
    blocks = max(1, seeds // max(1, chunk_runs))
    descriptions_of = {m.name: m for m in metrics}
    metric_lines = []
    for name in document.get("metrics", []):
        metric = descriptions_of.get(name)
        metric_lines.append(f"{name}: {metric.description}" + (f" ({metric.units})" if metric.units else "") if metric else name)
    after = document.get("after")
    duration = settings.get("duration")
    if after is not None:
        window = f"t ≥ {_spec_value(float(after))} s (after = {_spec_value(float(after))})"
    elif isinstance(duration, (int, float)):
        window = f"t ≥ {_spec_value(duration / 2)} s: the second half of the run (the default)"
    else:
        window = "the second half of the run (the default)"
    divergence = document.get("divergence")
    if divergence:
        signal, limit = str(divergence.get("signal")), float(divergence.get("limit"))
        units = next(
            (
                m.units
                for m in metrics
                if m.name.split(":", 1)[-1] == signal
                and m.name.split(":", 1)[0] in ("rms_error", "max_error", "rms_tracking", "max_tracking", "max_excursion")
                and m.units
            ),
            "",
        )
        rule = (
            f"the {signal} error beyond {_spec_value(limit)}{' ' + units if units else ''} at any record, or a truth or estimate that is not finite"
        )
    else:
        rule = "a truth or estimate that is not finite at any record (no divergence limit)"
    kept = document.get("trajectories")
    items: list[tuple[str, str | list[str]]] = [
        ("seeds", f"{seeds} per point: seeds {first} to {first + seeds - 1}, the same at every point"),
        (
            "chunks",
            f"{chunk_runs} runs per chunk: {total_chunks} chunks ({n_points} point{'s' * (n_points != 1)} × "
            f"{blocks} block{'s' * (blocks != 1)} of seeds)",
        ),
        ("metrics", metric_lines or ["none"]),
        ("metric window", window),
        ("diverged", rule),
        ("trajectories kept", f"{', '.join(kept.get('signals', []))}, one record in {kept.get('every', 10)}" if kept else "none"),
    ]
    parts += ["<h3>Campaign</h3>", _definition_table(items, ' class="provenance" id="spec-campaign"')]

    sweep = document.get("sweep") or {}
    kind = str(sweep.get("kind", "grid"))
    rows = _axis_rows(document, kind)
    if not rows:
        how = "no axes: one point"
    elif kind == "grid":
        how = f"grid: {n_points} point{'s' * (n_points != 1)}, every combination of the axes' values (the last axis varies fastest)"
    else:
        how = f"Latin hypercube: {n_points} points drawn with seed {sweep.get('seed', 0)}, one in each of {n_points} equal strata of every axis"
    parts += ["<h3>Sweep</h3>", f"<p>{html.escape(how)}.</p>"]
    if rows:
        parts.append(_table(["axis", "field", "values", "applied"], rows, ' id="spec-axes" class="numbers"'))
    parts.append(
        "<details><summary>the spec as JSON, scenario inlined (what a resume compares)</summary>\n"
        f"<pre>{html.escape(_pretty_json(document))}</pre>\n</details>"
    )
    return parts


# ----------------------------------------------------------------------------------
# the page


_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif;
       margin: 0 auto; padding: 1.5rem 2rem 3rem; max-width: 1800px; color: #1d1d1f; background: #fff; line-height: 1.45; }
h1 { font-size: 1.6rem; margin: 0 0 .4rem; }
h2 { font-size: 1.25rem; margin: 2rem 0 .6rem; border-bottom: 1px solid #ddd; padding-bottom: .2rem; }
h3 { font-size: 1.05rem; margin: 1.2rem 0 .4rem; }
.status { display: inline-block; padding: .2rem .6rem; border-radius: .3rem; font-weight: 600; }
.status.complete { background: #e3f4e6; color: #17612a; }
.status.partial { background: #fff1d6; color: #8a5300; }
.status.empty { background: #e8eef8; color: #23466e; }
.notice { background: #f4f7fb; border-left: 4px solid #5b7fb0; padding: .6rem 1rem; margin: .8rem 0; }
table { border-collapse: collapse; font-size: .9rem; margin: .4rem 0 1rem; }
th, td { border: 1px solid #ddd; padding: .25rem .6rem; text-align: left; vertical-align: top; }
thead th { background: #f4f4f6; }
table.provenance th { background: #f8f8fa; font-weight: 600; white-space: nowrap; }
td.number, table.numbers td { font-variant-numeric: tabular-nums; }
.figures { display: grid; grid-template-columns: repeat(2, minmax(0, 1fr)); gap: 1.2rem 1.5rem; align-items: start; }
@media (max-width: 1100px) { .figures { grid-template-columns: minmax(0, 1fr); } }
figure { margin: 0; min-width: 0; }
figure img { display: block; width: 100%; height: auto; border: 1px solid #eee; }
figcaption { font-size: .85rem; color: #444; margin-top: .3rem; }
details { margin: .4rem 0 1rem; }
summary { cursor: pointer; color: #2a5db0; }
code { background: #f3f3f5; padding: 0 .25rem; border-radius: .2rem; font-size: .9em; }
pre { background: #f6f8fa; border: 1px solid #e1e4e8; padding: .8rem; font-size: .8rem; overflow-x: auto; max-height: 40rem; }
nav { display: flex; flex-wrap: wrap; gap: .2rem 1rem; }
#image-check { font-size: .75rem; color: #888; margin-top: 2rem; }
"""

_SCRIPT = """
window.addEventListener("load", function () {
  var images = document.images, loaded = 0;
  for (var i = 0; i < images.length; i++) {
    if (images[i].complete && images[i].naturalWidth > 0) { loaded++; }
  }
  document.getElementById("image-check").textContent = "images loaded: " + loaded + " of " + images.length;
});
"""


def _figure_html(figure: _Figure, png: bytes) -> str:
    data = base64.b64encode(png).decode("ascii")
    alt = html.escape(figure.caption, quote=True)
    return (
        f'<figure id="{html.escape(figure.key, quote=True)}">'
        f'<img src="data:image/png;base64,{data}" alt="{alt}">'
        f"<figcaption>{html.escape(figure.caption)}</figcaption></figure>"
    )


def _figures_html(figures: list[_Figure], images: dict[str, bytes]) -> str:
    return '<div class="figures">' + "\n".join(_figure_html(f, images[f.key]) for f in figures) + "</div>"


def write_report(store_path: str | Path, out: str | Path | None = None, *, figures_dir: Path | None = None) -> Path:
    """Write the store's report as one self-contained HTML page; return its path.

    ``out`` defaults to :func:`default_report_path` (``NAME-report.html`` beside the
    store). With ``figures_dir``, every figure is also saved there as a PNG under its
    :func:`report_figures` name. A store whose campaign is not finished gets a report
    of what is done, marked partial; a store with no finished chunk gets a page that
    says so, with the spec and no figures (and ``figures_dir`` gets none).
    """
    from lookout.studies.store import CampaignStore

    store = CampaignStore(store_path)
    if not store.path.exists():
        raise FileNotFoundError(f"no campaign store at {store.path}")
    document = store.campaign_document()
    full = store.open()
    keep = [name for name, variable in full.data_vars.items() if not str(name).startswith("trajectory__")]  # names are strings
    ds = full[keep].load()
    attrs = ds.attrs
    done = store.done()
    axes = _axes(ds, document)
    metrics = _metrics(ds, document)
    diverged = _diverged(ds)

    n_points, n_seeds = ds.sizes["point"], ds.sizes["seed"]
    chunk_runs = int(attrs.get("chunk_runs", n_seeds) or n_seeds)
    seeds_per_point = int((document or {}).get("seeds_per_point", n_seeds))
    total_chunks = n_points * max(1, seeds_per_point // chunk_runs)
    total_runs = n_points * seeds_per_point
    runs_done = sum(int(r["seeds"][1]) - int(r["seeds"][0]) + 1 for r in done.values())
    started = bool(done)
    complete = len(done) >= total_chunks
    state = "complete" if complete else ("partial" if started else "empty")
    status = (
        f"{'complete' if complete else 'partial' if started else 'not started'}: {len(done)} of {total_chunks} chunks done "
        f"({runs_done} of {total_runs} runs)"
    )
    seconds = sum(float(r.get("seconds", 0.0) or 0.0) for r in done.values() if np.isfinite(float(r.get("seconds", np.nan))))
    workers = sorted({str(r.get("worker", "")) for r in done.values()})
    finished = sorted(str(r.get("finished", "")) for r in done.values())
    kind = str(attrs.get("sweep_kind", "grid"))

    figures = _build(ds, document) if started else []
    images = {figure.key: _png(figure.figure) for figure in figures}
    if figures_dir is not None and images:
        figures_dir = Path(figures_dir)
        figures_dir.mkdir(parents=True, exist_ok=True)
        for key, png in images.items():
            (figures_dir / key).write_bytes(png)

    title = str(attrs.get("title", f"lookout campaign {store.path.name}"))
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{html.escape(title)}</title>",
        f"<style>{_STYLE}</style>",
        "</head>",
        "<body>",
        "<header>",
        f"<h1>{html.escape(title)}</h1>",
        f'<p><span class="status {state}" id="status">{html.escape(status)}</span></p>',
    ]
    if not started:
        parts.append(
            f'<p class="notice" id="not-started">No chunk has finished yet: 0 of {total_chunks} chunks '
            f"({total_runs} runs). Run <code>lookout campaign run SPEC --out {html.escape(str(store.path))}</code> "
            "with the campaign's spec to compute it, then write the report again; the spec the store holds is below.</p>"
        )
    elif not complete:
        parts.append(
            f'<p class="notice">The campaign is not finished: {len(done)} of {total_chunks} chunks done '
            f"({runs_done} of {total_runs} runs). Runs not computed yet are left out of every figure and table; "
            "resume the campaign and write the report again for the full results.</p>"
        )
    parts.append("</header>")
    nav = ['<a href="#provenance">provenance</a>', '<a href="#spec">spec</a>']
    if started:
        nav.append('<a href="#summary">summary</a>')
        nav += [f'<a href="#metric-{html.escape(m.variable, quote=True)}">{html.escape(m.name)}</a>' for m in metrics]
        if any(f.section == "heatmap" for f in figures):
            nav.append('<a href="#heatmaps">heat maps</a>')
        nav.append('<a href="#divergence">divergence</a>')
    parts.append("<nav>" + "".join(nav) + "</nav>")

    # provenance
    provenance = [
        ("store", str(store.path.resolve())),
        ("status", status),
        ("lookout version (store)", str(attrs.get("lookout_version", "?"))),
        ("created", str(attrs.get("created", "?"))),
        ("campaign fingerprint", str(attrs.get("campaign_fingerprint", "?"))),
        ("sweep", f"{kind}; {n_points} point{'s' * (n_points != 1)} over " + (", ".join(a.name for a in axes) or "no axes")),
        ("seeds per point", f"{seeds_per_point} (seeds {_fmt(ds['seed'].values[0])} to {_fmt(ds['seed'].values[-1])}), {chunk_runs} per chunk"),
        ("compute time", f"{seconds:.1f} s over {len(done)} chunk{'s' * (len(done) != 1)}" + (f" on {', '.join(workers)}" if workers else "")),
    ]
    if finished:
        provenance.append(("chunks finished", f"{finished[0]} to {finished[-1]}"))
    from lookout.studies.store import _version

    provenance.append(("report written", f"{datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')} by lookout {_version()}"))
    parts += ['<section id="provenance">', "<h2>Provenance</h2>", _definition_table(provenance), "</section>"]

    # spec: what was run, before what came out
    parts += ['<section id="spec">', "<h2>Campaign spec</h2>", _spec_html(document, metrics, n_points, chunk_runs, total_chunks), "</section>"]

    if started:
        parts += _results_html(ds, axes, metrics, diverged, figures, images)

    parts += ['<p id="image-check">images loaded: not checked (scripts off)</p>', f"<script>{_SCRIPT}</script>", "</body>", "</html>"]
    out = default_report_path(store.path) if out is None else Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(parts) + "\n", encoding="utf-8")
    return out


def _results_html(ds, axes: list[_Axis], metrics: list[_Metric], diverged: np.ndarray, figures: list[_Figure], images: dict[str, bytes]) -> list[str]:
    """The summary, the figures per metric, the heat maps and the divergence section."""
    parts = []
    rows = []
    for metric in metrics:
        median, low, high, count = _stats(metric.data)
        rows.append([metric.name, metric.description, metric.units or "1", f"{count} of {metric.data.size}", _fmt(median), _fmt(low), _fmt(high)])
    known, n_diverged = int((~np.isnan(diverged)).sum()), int((diverged == 1).sum())
    parts += [
        '<section id="summary">',
        "<h2>Summary</h2>",
        "<p>Each metric over every computed run of every sweep point (runs: those with a value; a diverged run has none).</p>",
        _table(["metric", "description", "units", "runs", "median", f"{LOW}th percentile", f"{HIGH}th percentile"], rows, ' class="numbers"'),
        f"<p>Diverged: {n_diverged} of {known} computed run{'s' * (known != 1)}"
        + (f" ({100 * n_diverged / known:.3g} %)" if n_diverged else "")
        + '; see <a href="#divergence">divergence</a>.</p>',
        "</section>",
    ]

    # figures per metric
    for metric in metrics:
        mine = [f for f in figures if f.section == "metric" and f.metric == metric.variable]
        parts += [
            f'<section id="metric-{html.escape(metric.variable, quote=True)}">',
            f"<h2>{html.escape(metric.name)}: {html.escape(metric.description)}"
            + (f" ({html.escape(metric.units)})" if metric.units else "")
            + "</h2>",
        ]
        if mine:
            parts.append(_figures_html(mine, images))
        elif not np.isfinite(metric.data).any():
            parts.append(
                f"<p>No finished run has a value of {html.escape(metric.name)}: {n_diverged} of the {known} "
                "finished runs diverged, and a diverged run's metrics are NaN. Nothing to plot.</p>"
            )
        else:
            parts.append("<p>The campaign sweeps no axis: see the summary.</p>")
        parts.append("</section>")
    heatmaps = [f for f in figures if f.section == "heatmap"]
    if heatmaps:
        parts += ['<section id="heatmaps">', "<h2>Heat maps</h2>", _figures_html(heatmaps, images), "</section>"]

    # divergence: figures and the list only when a run diverged
    parts += ['<section id="divergence">', "<h2>Divergence</h2>"]
    if not n_diverged:
        parts.append(f'<p id="diverged-count">No run diverged ({known} of {diverged.size} runs finished).</p>')
    else:
        mine = [f for f in figures if f.section == "diverged"]
        if mine:
            parts.append(_figures_html(mine, images))
        sentence = f"{n_diverged} of {known} computed run{'s' * (known != 1)} diverged"
        if n_diverged > MAX_DIVERGED_ROWS:
            sentence += f"; the first {MAX_DIVERGED_ROWS} are listed"
        parts.append(f'<p id="diverged-count">{html.escape(sentence)}.</p>')
        seeds = ds["seed"].values
        rows = [
            [str(int(point))] + [_fmt(axis.values[point]) for axis in axes] + [_fmt(seeds[seed])]
            for point, seed in np.argwhere(diverged == 1)[:MAX_DIVERGED_ROWS]
        ]
        parts.append(_table(["point"] + [a.name for a in axes] + ["seed"], rows, ' id="diverged-runs" class="numbers"'))
    parts.append("</section>")
    return parts
