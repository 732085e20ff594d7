"""Kim (2002): Figs. 4-8 from the closed-loop runs, and the sweep's figure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from lookout.papers.kim_2002.analysis import bias_with_model_error, diverged_at
from lookout.papers.kim_2002.config import DIVERGED_DISTANCE, OBSERVERS, Config


def _model_error_text(config: Config) -> str:
    error = config.model_error
    return f"{config.gains} gains; model error M x {1 + error.mass:g}, D x {1 + error.damping:g}, F {error.force / 1e3:g} kN"


def _track_figure(ds: xr.Dataset, config: Config, runs: dict[str, int]):
    """Fig. 8: the X-Y track of the first run of each observer; a track that leaves the
    axes is cut there with a mark, and a diverged run says so in the legend."""
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6.5, 7.0), layout="constrained")
    first = ds.isel(run=runs["sliding-mode"])
    desired_north = first.position_desired.sel(earth_axis="north").values
    desired_east = first.position_desired.sel(earth_axis="east").values
    low = min(desired_north.min(), desired_east.min()) - 40.0
    high = max(desired_north.max(), desired_east.max()) + 40.0
    axis.plot(desired_east, desired_north, color="0.6", lw=3, label="reference", zorder=1)
    when = diverged_at(ds)
    styles: dict[str, dict[str, Any]] = {"sliding-mode": {"color": "tab:blue", "lw": 1.2}, "conventional": {"color": "tab:red", "lw": 1.0, "ls": ":"}}
    names = {"sliding-mode": "sliding-mode observer", "conventional": "conventional observer (Kbar = 0)"}
    notes = []
    for observer, run in runs.items():
        member = ds.isel(run=run)
        north = member.position.sel(earth_axis="north").values
        east = member.position.sel(earth_axis="east").values
        inside = np.isfinite(north) & np.isfinite(east) & (north >= low) & (north <= high) & (east >= low) & (east <= high)
        # the track up to where it first leaves the axes: a diverged track that comes back
        # across the plot later would only hide the shown one
        stop = int(np.argmin(inside)) if not inside.all() else north.size
        label = names[observer]
        if np.isfinite(when[run]):
            label += f": diverged at t = {when[run]:.0f} s"
        axis.plot(east[:stop], north[:stop], **styles[observer], label=label, zorder=2)
        if stop < north.size and stop > 0:
            axis.plot(
                east[stop - 1],
                north[stop - 1],
                marker="X",
                ms=9,
                color=styles[observer]["color"],
                mec="k",
                mew=0.6,
                ls="none",
                zorder=4,
                gid=f"leaves_{observer}",
            )
            notes.append((observer, stop, east[stop - 1], north[stop - 1]))
    middle = 0.5 * (low + high)
    for observer, stop, x, y in notes:
        # the note sits next to the mark, on the side of the plot's middle
        right, up = x <= middle, y <= middle
        axis.annotate(
            f"{observer}: leaves the plot\nat t = {float(ds.time.values[stop]):.0f} s",
            (x, y),
            xytext=(8 if right else -8, 10 if up else -10),
            textcoords="offset points",
            ha="left" if right else "right",
            va="bottom" if up else "top",
            fontsize=8,
            color=styles[observer]["color"],
            gid="leaves_note",
            bbox={"boxstyle": "round,pad=0.2", "facecolor": "white", "edgecolor": "none", "alpha": 0.85},
            zorder=5,
        )
    axis.plot([], [], marker="X", ms=8, color="0.4", mec="k", mew=0.6, ls="none", label="where a track leaves the plot (cut there)")
    axis.set_xlabel("Earth-fixed east Y (m)")
    axis.set_ylabel("Earth-fixed north X (m)")
    axis.set_xlim(low, high)
    axis.set_ylim(low, high)
    axis.set_aspect("equal", adjustable="box")
    axis.grid(alpha=0.3)
    figure.legend(fontsize=8, loc="outside lower center", frameon=False, ncols=1)
    seed = int(first.seed) if "seed" in first.coords else config.seed
    axis.set_title(f"Kim (2002), Fig. 8: X-Y track, seed {seed}\n{_model_error_text(config)}", fontsize=9)
    return figure


def _figures(ds: xr.Dataset, sweep: xr.Dataset | None, out: Path, config: Config) -> list[str]:
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_estimates

    files = []
    observers = ds.observer.values
    runs = {observer: int(np.flatnonzero(observers == observer)[0]) for observer in OBSERVERS}
    sliding_runs = ds.isel(run=np.flatnonzero(observers == "sliding-mode"))
    sliding = ds.isel(run=runs["sliding-mode"])
    setting = _model_error_text(config)
    # what the bias estimate stands for, computed from the plant's true M, D and F
    lumped = bias_with_model_error(sliding_runs, config)
    with_target = sliding_runs.assign(lumped)
    estimate = sliding.bias_force_hat.sel(earth_axis="north").values
    target = lumped.bias_force_with_model_error.isel(run=0).sel(earth_axis="north").values
    truth = sliding.bias_force.sel(earth_axis="north").values
    rms = lambda values: float(np.sqrt(np.nanmean(values**2))) / 1e3  # noqa: E731
    figures = {
        "fig04_x_position.png": plot_estimates(
            sliding_runs,
            [("position", "north")],
            title=f"Kim (2002), Fig. 4: X (north) position, true and estimated (sliding-mode observer)\n{setting}",
        ),
        "fig06_surge_velocity.png": plot_estimates(
            sliding_runs, [("velocity", "surge")], title=f"Kim (2002), Fig. 6: surge velocity, true and estimated (sliding-mode observer)\n{setting}"
        ),
        "fig07_surge_bias.png": plot_estimates(
            with_target,
            [("bias_force", "north")],
            targets={"bias_force": "bias_force_with_model_error"},
            title=(
                f"Kim (2002), Fig. 7: bias in X (north), sliding-mode observer; {setting}\n"
                r"blue: what $\hat b$ stands for, the bias plus the model-error force $J(\psi)\,[F + (M - M_{true})\dot\nu + (D - D_{true})\nu]$"
                f"\nRMS over the run: estimate {rms(estimate):.3g} kN, blue {rms(target):.3g} kN, true bias {rms(truth):.3g} kN, "
                f"estimate - blue {rms(estimate - target):.3g} kN"
            ),
        ),
    }
    # Fig. 5: measured, true total and low-frequency X, and the estimate, over 100 s
    t = sliding.time.values
    window = (t >= 900.0) & (t <= 1000.0)
    if not window.any():
        window = t >= t[-1] - 100.0
    figure, axis = plt.subplots(figsize=(8, 4.4), layout="constrained")
    measured = sliding.measured_position.sel(earth_axis="north").values
    change = np.r_[True, np.diff(measured) != 0]
    total = (sliding.position + sliding.wave_position).sel(earth_axis="north").values
    axis.plot(t[window & change], measured[window & change], ".", color="0.5", label="measured y (1 Hz fixes)")
    axis.plot(t[window], total[window], color="tab:blue", lw=0.8, label="true total (low-frequency + waves)")
    axis.plot(t[window], sliding.position.sel(earth_axis="north").values[window], color="k", lw=1.2, label="true low-frequency")
    axis.plot(t[window], sliding.position_hat.sel(earth_axis="north").values[window], color="tab:orange", lw=1.5, ls="--", label="estimate")
    axis.set_xlabel("time (s)")
    axis.set_ylabel("Earth-fixed X (north) position (m)")
    seed = int(sliding.seed) if "seed" in sliding.coords else config.seed
    axis.set_title(f"Kim (2002), Fig. 5: wave filtering, sliding-mode observer, seed {seed}\n{setting}", fontsize=9)
    axis.legend(fontsize=8)
    figures["fig05_wave_filtering.png"] = figure
    figures["fig08_xy_track.png"] = _track_figure(ds, config, runs)
    if sweep is not None:
        figures["sweep_tracking_vs_model_error.png"] = _sweep_figure(sweep)
    for filename, figure in figures.items():
        figure.savefig(out / filename, dpi=110)
        plt.close(figure)
        files.append(filename)
    return files


def _sweep_figure(sweep: xr.Dataset):
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    labels = sweep.model_error.values.tolist()
    x = np.arange(len(labels))
    for axis, gains in zip(axes, sweep.gains.values.tolist()):
        for observer, color, offset in (("sliding-mode", "tab:blue", -0.12), ("conventional", "tab:red", 0.12)):
            values = sweep.rms_tracking__position.sel(gains=gains, observer=observer).values
            diverged = sweep.diverged.sel(gains=gains, observer=observer).values.astype(bool)
            for s in range(values.shape[1]):
                shown = np.where(diverged[:, s], 1e3, values[:, s])
                axis.scatter(x + offset, shown, color=color, marker="x" if s else "o", s=18, label=observer if s == 0 else None)
        axis.axhline(DIVERGED_DISTANCE, color="0.5", ls=":", lw=0.8)
        axis.text(0, DIVERGED_DISTANCE * 1.3, "diverged (drawn at 1000 m)", fontsize=7, color="0.4")
        axis.set_yscale("log")
        axis.set_xticks(x, labels, rotation=60, ha="right", fontsize=7)
        axis.set_title(f"observer gains: {gains}" + (" (A.4)" if gains == "printed" else " (F&S (60) in SI, satisfy (14))"), fontsize=9)
        axis.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("RMS tracking error, horizontal (m)")
    axes[0].legend(fontsize=8)
    figure.suptitle("Kim (2002), Fig. 8 claim: tracking error against model error (one axis at a time; one mark per seed)", fontsize=10)
    figure.tight_layout()
    return figure
