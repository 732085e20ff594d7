"""The reproduction's figures: the track, the tracking errors, the velocities and the thrust."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from lookout.models.cybership import CYBERSHIP_THRUST_LIMIT
from lookout.papers._report import save_figures
from lookout.papers.wondergem_2009.analysis import lap_times, tracking_errors
from lookout.papers.wondergem_2009.config import INITIAL_ETA, INITIAL_VELOCITY_HAT, Config

#: The first seconds of a run, where the initial estimate converges: zoomed in the
#: velocity figures and left out of their full-run scale.
START_WINDOW = 30.0


def figures(results: dict[str, xr.Dataset], config: Config, out: Path) -> list[str]:
    """Draw the figures of ``results`` (condition -> its Dataset) under ``out``; their file names."""
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_estimates

    colors = {"simulation": "tab:blue", "basin-calm": "tab:orange", "basin-waves": "tab:green"}
    drawn = {}
    figure, axis = plt.subplots(figsize=(7, 5))
    first = next(iter(results.values())).isel(run=0)
    axis.plot(first.position_desired.isel(earth_axis=1), first.position_desired.isel(earth_axis=0), "k--", lw=1.0, label="reference ellipse")
    for condition, ds in results.items():
        run = ds.isel(run=0)
        axis.plot(run.position.isel(earth_axis=1), run.position.isel(earth_axis=0), color=colors[condition], lw=0.9, label=condition)
    axis.plot(INITIAL_ETA[1], INITIAL_ETA[0], "ko", ms=4, label="start")
    axis.set_xlabel("east y (m)")
    axis.set_ylabel("north x (m)")
    axis.set_aspect("equal")
    axis.legend(fontsize=8)
    axis.set_title("Wondergem et al. (2009): the track around the ellipse (run 0)", fontsize=10)
    figure.tight_layout()
    drawn["track.png"] = figure

    figure, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for condition, ds in results.items():
        errors = tracking_errors(ds.isel(run=0))
        for axis, name, unit in zip(axes, ("surge_error", "sway_error", "heading_error"), ("m", "m", "rad")):
            axis.plot(ds.time, errors[name], color=colors[condition], lw=0.8, label=condition)
            axis.set_ylabel(f"{name.split('_')[0]} error ({unit})")
    for lap_end in lap_times(config)[:-1]:
        for axis in axes:
            axis.axvline(lap_end, color="0.6", lw=0.6, ls=":")
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")
    figure.suptitle("Body-frame tracking errors (true motion; dotted: lap ends, speed steps)", fontsize=10)
    figure.tight_layout()
    drawn["errors.png"] = figure

    # true and estimated velocities, one figure per condition (overlaid, the conditions hid
    # each other): the start, where the initial estimate is far off, in a zoom of its own
    # and left out of the full run's scale; a second zoom around the last speed step
    last_step = float(lap_times(config)[-2])
    for condition, ds in results.items():
        seeded = ds.assign_coords(seed=("run", np.asarray(config.seeds[: ds.sizes["run"]], dtype=np.int64)))
        end = float(ds.time[-1])
        windows = [(0.0, min(START_WINDOW, end))]
        if last_step + 10.0 <= end and last_step - 10.0 > START_WINDOW:
            windows.append((last_step - 10.0, last_step + 10.0))
        drawn[f"velocities_{condition.replace('-', '_')}.png"] = plot_estimates(
            seeded,
            [("velocity", "surge"), ("velocity", "sway"), ("yaw_rate", None)],
            window=windows,
            transient=min(START_WINDOW, 0.5 * end),
            title=(
                f"Wondergem et al. (2009): true and estimated body-fixed velocities, {condition}\n"
                f"initial estimate v_hat(0) = {list(INITIAL_VELOCITY_HAT)}; zooms: the start and the last speed step (t = {last_step:.1f} s)"
            ),
        )

    figure, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for condition, ds in results.items():
        run = ds.isel(run=0)
        samples = max(1, int(round(1.0 / float(run.time[1] - run.time[0]))))  # 1 s
        for k, (axis, label) in enumerate(zip(axes, ("surge force (N)", "sway force (N)", "yaw moment (N m)"))):
            applied = run.force_applied.isel(body_axis=k) if k < 2 else run.moment_applied
            axis.plot(run.time, applied, color=colors[condition], lw=0.4, alpha=0.25)
            mean = applied.rolling(time=samples, center=True).mean()
            axis.plot(run.time, mean, color=colors[condition], lw=1.0, label=f"{condition}: 1 s mean (light: every sample)")
            axis.set_ylabel(label)
    for axis, limit in zip(axes, CYBERSHIP_THRUST_LIMIT):
        axis.axhline(limit, color="k", lw=0.6, ls=":")
        axis.axhline(-limit, color="k", lw=0.6, ls=":")
        axis.set_ylim(-3 * limit, 3 * limit)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("time (s)")
    figure.suptitle("Applied thrust (dotted: the basin's limits; the simulation condition has none)", fontsize=10)
    figure.tight_layout()
    drawn["thrust.png"] = figure
    return save_figures(drawn, out)
