"""The figure of a replayed or live session: estimates against the measurements and,
for a simulated log, against the truth beside it."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from lookout.plotting import plot_estimates, plot_run_estimates

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Panels of a vessel session compared with a truth.
PANELS = (("position", "north"), ("position", "east"), ("heading", None), ("velocity", "surge"), ("velocity", "sway"))


def with_truth(session: xr.Dataset, truth: xr.Dataset) -> xr.Dataset:
    """The session's estimates and measurements with the truth's variables on the
    session's times (the truth of a simulated log: ``lookout write-log``).

    Raises
    ------
    ValueError
        Naming ``truth`` when it lacks the session's times or the panels' variables.
    """
    missing = [name for name, _ in PANELS if name not in truth]
    if missing:
        raise ValueError(f"truth has no {', '.join(sorted(set(missing)))} (a run of a vessel scenario, e.g. NAME-truth.nc of lookout write-log)")
    times = session["time"].values
    try:
        aligned = truth.isel(run=0).sel(time=times, method="nearest", tolerance=1e-6)
    except KeyError:
        raise ValueError(f"truth does not have the session's times ({times[0]:g} to {times[-1]:g} s, every {np.diff(times[:2])[0]:g} s)") from None
    merged = session.copy()
    for name in {name for name, _ in PANELS}:
        merged[name] = aligned[name].expand_dims("run").assign_coords(time=session["time"])
    return merged


def plot_session(session: xr.Dataset, truth: xr.Dataset | None = None, *, title: str | None = None) -> Figure | None:
    """Estimates of a session: against the truth when one is given (the whole session
    and a zoom on its first position outage, every position reference silent, or its end; a smoothed session's smoothed
    estimates in blue beside them), else every estimate with its measurement."""
    if truth is None:
        return plot_run_estimates(session, title=title)
    merged = with_truth(session, truth)
    time = session["time"].values
    window, note = None, ""
    # the combined position's outage, or every position reference's at once (a Kalman
    # filter reading each: outage_dgnss1_position, outage_dgnss2_position)
    flags = [name for name in map(str, session.data_vars) if name == "outage_position" or (name.startswith("outage_") and name.endswith("_position"))]
    silent = np.all([np.asarray(session[name].values[0]) > 0 for name in flags], axis=0) if flags else np.zeros(time.size, dtype=bool)
    if silent.any():
        lost = time[silent]
        first = lost[lost < lost[0] + 120.0]
        window = (max(time[0], first[0] - 20.0), min(time[-1], first[-1] + 30.0))
        note = f"; no position fix used from {first[0]:g} to {first[-1]:g} s (dead reckoning)"
    heading = (title or "replayed log") + ": estimates against the simulation's truth" + note
    # a smoothed session (lookout replay --smooth): its smoothed estimates beside the filtered ones
    smoothed = {name: f"{name}_smoothed" for name, _ in PANELS if f"{name}_smoothed" in session}
    for name in smoothed:
        merged[f"{name}_smoothed"] = session[f"{name}_smoothed"].assign_attrs(long_name="smoothed (Rauch-Tung-Striebel)")
    return plot_estimates(merged, PANELS, window=window, title=heading, targets=smoothed or None)
