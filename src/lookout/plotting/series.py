"""True and estimated signals of chosen variables (:func:`plot_estimates`), and the
true course of some signals (:func:`plot_trajectories`)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from lookout.plotting._panels import (
    _DISPLAY_UNITS,
    _ESTIMATE_STYLE,
    _TRUTH_STYLE,
    _check_estimate_arguments,
    _check_targets,
    _component,
    _dense_title,
    _draw_panel,
    _make_panel,
    _panel_figure,
    _panel_legend,
    _quantity,
    _run_caption,
    _run_values,
    _window_parts,
    _windows,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def plot_estimates(
    ds: xr.Dataset,
    panels: Iterable[tuple[str, str | None]],
    *,
    run: int = 0,
    zoom: float = 200.0,
    window: Sequence[float] | Sequence[Sequence[float]] | None = None,
    title: str | None = None,
    targets: Mapping[str, str] | None = None,
    transient: float | None = None,
) -> Figure:
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


def plot_trajectories(ds: xr.Dataset, panels: Iterable[tuple[str, str | None]], *, run: int = 0, title: str | None = None) -> Figure:
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
