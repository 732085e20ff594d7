"""Calugi et al. (2003): Figs. 1-4 from the closed-loop runs, the Delta sweep's and the
convergence study's figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from lookout.analysis import estimation_errors
from lookout.analysis.adaptive_dp import noise_drift_rate
from lookout.papers._report import save_figures
from lookout.papers.calugi_2003.config import DIVERGED_DISTANCE, GAIN_SETS, Config, gains, m11


def _forces_and_theta_figure(ds: xr.Dataset, config: Config | None = None):
    """Fig. 4: the applied surge and sway force of the printed gains' first run, each in
    its own panel; theta_hat / m11 of both gain sets with the truth, the start and the
    projection's lower bound; and theta_hat - theta_hat(0) in kg, which shows how little
    it moves and says why (Gamma with theta = m11 in kg; docs/reproductions.md)."""
    import matplotlib.pyplot as plt

    config = Config.model_validate_json(ds.attrs["config"]) if config is None else config
    true_m11 = m11()
    first = ds.isel(run=0)
    t = first.time.values
    seed = int(first.seed) if "seed" in first.coords else config.seed
    figure, axes = plt.subplots(2, 2, figsize=(12, 6.4), layout="constrained", sharex=True)
    for axis, (component, color) in zip(axes[:, 0], (("surge", "tab:blue"), ("sway", "tab:green"))):
        axis.plot(t, first.force_applied.sel(body_axis=component) / 1e3, color=color, lw=0.7)
        axis.set_ylabel(f"body-fixed\n{component} force applied (kN)")
        axis.grid(alpha=0.3)
    axes[0, 0].set_title(f"applied thrust: {first.gains.item()} gains, seed {seed}", fontsize=9)
    # both start at the same value and hardly move: the printed wide, the satisfying dashed on top
    styles = {"printed": {"color": "tab:blue", "lw": 2.2, "zorder": 2}, "satisfying": {"color": "tab:red", "lw": 1.1, "ls": "--", "zorder": 3}}
    moves = []
    for name in GAIN_SETS:  # run 0 of each gain set (the runs are grouped by gain set)
        member = ds.isel(run=int(np.flatnonzero(ds.gains.values == name)[0]))
        theta = member.theta_m11.values
        axes[0, 1].plot(t, theta / true_m11, **styles[name], label=f"theta_hat ({name} gains)")
        axes[1, 1].plot(t, theta - theta[0], **styles[name], label=f"{name} gains")
        moves.append(f"{theta[-1] - theta[0]:+,.0f} kg ({name}, {(theta[-1] - theta[0]) / true_m11:+.1e} m11)")
    low, high = config.theta_bounds
    axes[0, 1].axhline(1.0, color="k", lw=1.0, ls=":", label="true m11")
    axes[0, 1].axhline(config.initial_theta, color="0.5", lw=0.8, ls="--", label=f"theta_hat(0) = {config.initial_theta:g} m11")
    axes[0, 1].axhline(low, color="tab:purple", lw=0.8, ls="-.", label=f"projection bounds [{low:g}, {high:g}] m11 (upper off scale)")
    axes[0, 1].set_ylim(low - 0.05, 1.2)
    axes[0, 1].set_ylabel("theta_hat / m11")
    axes[0, 1].legend(fontsize=7, loc="upper center", ncols=2)
    axes[0, 1].set_title(f"inertia estimate theta_hat (m11 = {true_m11 / 1e6:.3g}e6 kg)", fontsize=9)
    axes[1, 1].axhline(0.0, color="k", lw=0.6)
    axes[1, 1].set_ylabel("theta_hat - theta_hat(0) (kg)")
    axes[1, 1].legend(fontsize=7, loc="lower left")
    printed = {key: gains("printed")[key] for key in ("K1", "K2", "d", "C1", "C2")}
    drift = noise_drift_rate(**printed, gamma=config.adaptation_gain, noise_std=config.noise_std[0], interval=config.sample_interval)
    why = (
        f"Why flat: Gamma = {config.adaptation_gain:g} (the printed value) with theta = m11 in kg.\n"
        f"In {t[-1] - t[0]:.0f} s theta_hat moves by {moves[0]}\nand {moves[1]} (below).\n"
        f"Printed gains: that is the measurement-noise drift of the discrete\nlaw (67), {drift:.2g} kg/s predicted. "
        "theta_hat moves visibly only\nfor Gamma >= 1e8 (theta_convergence.png, docs/reproductions.md)."
    )
    # in the empty band between the lower bound and the start
    axes[0, 1].text(
        0.5,
        0.26,
        why,
        transform=axes[0, 1].transAxes,
        fontsize=7.5,
        va="center",
        ha="center",
        gid="theta_note",
        bbox={"boxstyle": "round,pad=0.3", "facecolor": "white", "edgecolor": "0.7", "alpha": 0.9},
    )
    for axis in axes[1]:
        axis.set_xlabel("time (s)")
    for axis in axes[:, 1]:
        axis.grid(alpha=0.3)
    axes[0, 0].set_xlim(t[0], t[-1])
    figure.suptitle(f"Calugi et al. (2003), Fig. 4: control forces and the inertia estimate (Delta = {config.sample_interval:g} s)", fontsize=10)
    return figure


def _figures(ds: xr.Dataset, sweep: xr.Dataset | None, convergence: xr.Dataset | None, out: Path, config: Config | None = None) -> list[str]:
    import matplotlib.pyplot as plt

    figures = {}
    run = ds.isel(run=0)
    t = run.time.values
    # Fig. 1: reference, true and filtered positions; measured and filtered
    figure, axes = plt.subplots(1, 2, figsize=(11, 4))
    for axis_label, color in (("north", "tab:blue"), ("east", "tab:green")):
        axes[0].plot(t, run.position_desired.sel(earth_axis=axis_label), color="0.6", lw=3)
        axes[0].plot(t, run.position.sel(earth_axis=axis_label), color="k", lw=0.8)
        axes[0].plot(t, run.position_hat.sel(earth_axis=axis_label), color=color, lw=1.0, ls="--", label=f"{axis_label}: estimate")
        axes[1].plot(t, run.measured_position.sel(earth_axis=axis_label), ".", ms=1, color="0.6")
        axes[1].plot(t, run.position_hat.sel(earth_axis=axis_label), color=color, lw=1.0, label=f"{axis_label}: filtered")
    axes[0].plot([], [], color="0.6", lw=3, label="reference")
    axes[0].plot([], [], color="k", lw=0.8, label="true")
    axes[0].set_title("tracking of the reference", fontsize=9)
    axes[1].set_title("measured (grey) and filtered positions", fontsize=9)
    for axis in axes:
        axis.set_xlabel("time (s)")
        axis.set_ylabel("Earth-fixed position (m)")
        axis.legend(fontsize=7)
    figure.suptitle("Calugi et al. (2003), Fig. 1 (printed gains, seed 0)", fontsize=10)
    figure.tight_layout()
    figures["fig1_tracking_and_filtering.png"] = figure
    # Fig. 2: tracking errors; true and estimated velocities
    figure, axes = plt.subplots(1, 2, figsize=(11, 4))
    for axis_label, color in (("north", "tab:blue"), ("east", "tab:green")):
        axes[0].plot(t, (run.position - run.position_desired).sel(earth_axis=axis_label), color=color, lw=0.8, label=axis_label)
    axes[0].set_ylabel("tracking error eta - eta_d (m)")
    for axis_label, color in (("surge", "tab:blue"), ("sway", "tab:green")):
        axes[1].plot(t, run.velocity.sel(body_axis=axis_label), color="k", lw=0.8)
        axes[1].plot(t, run.velocity_hat.sel(body_axis=axis_label), color=color, lw=1.0, ls="--", label=f"{axis_label}: estimate")
    axes[1].plot([], [], color="k", lw=0.8, label="true")
    axes[1].set_ylabel("body-fixed velocity (m/s)")
    for axis in axes:
        axis.set_xlabel("time (s)")
        axis.legend(fontsize=7)
    figure.suptitle("Calugi et al. (2003), Fig. 2: tracking errors; true and estimated velocities", fontsize=10)
    figure.tight_layout()
    figures["fig2_errors_and_velocities.png"] = figure
    # Fig. 3: velocity estimation errors
    figure, axis = plt.subplots(figsize=(8, 3.5))
    errors = estimation_errors(run)
    for axis_label, color in (("surge", "tab:blue"), ("sway", "tab:green")):
        axis.plot(t, errors.velocity.sel(body_axis=axis_label), color=color, lw=0.8, label=axis_label)
    axis.set_xlabel("time (s)")
    axis.set_ylabel("velocity estimation error (m/s)")
    axis.legend(fontsize=7)
    axis.set_title("Calugi et al. (2003), Fig. 3: velocity estimation errors", fontsize=10)
    figure.tight_layout()
    figures["fig3_velocity_errors.png"] = figure
    # Fig. 4: control forces (one panel per component, so that neither hides the other)
    # and theta_hat, with why it hardly moves
    figures["fig4_forces_and_theta.png"] = _forces_and_theta_figure(ds, config)
    if sweep is not None:
        figure, axes = plt.subplots(1, 2, figsize=(11, 4))
        for name, color in (("printed", "tab:red"), ("satisfying", "tab:blue")):
            values = sweep.rms_tracking__position.sel(gains=name)
            diverged = sweep.diverged.sel(gains=name).astype(bool)
            shown = values.where(~diverged, 1e3)
            for s in range(sweep.sizes["seed"]):
                axes[0].loglog(
                    sweep.sample_interval, shown.isel(seed=s), "o-" if s == 0 else "x--", color=color, label=name if s == 0 else None, ms=4
                )
                axes[1].semilogx(
                    sweep.sample_interval,
                    np.abs(sweep.theta_relative_error.sel(gains=name).isel(seed=s)),
                    "o-" if s == 0 else "x--",
                    color=color,
                    ms=4,
                )
        axes[0].axhline(DIVERGED_DISTANCE, color="0.5", ls=":")
        axes[0].set_ylabel("RMS tracking error (m); diverged drawn at 1000")
        axes[1].set_ylabel("|theta_hat(T) / m11 - 1|")
        for axis in axes:
            axis.set_xlabel("sample interval Delta (s)")
            axis.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=8)
        figure.suptitle(f"Calugi et al. (2003): the discrete loop against Delta ({sweep.attrs['duration_s']:g} s runs)", fontsize=10)
        figure.tight_layout()
        figures["sweep_sample_interval.png"] = figure
    if convergence is not None:
        figure, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True, sharey=True)
        colors = ("tab:gray", "tab:blue", "tab:red", "tab:green", "tab:purple")
        for row, noise in enumerate(convergence.noise.values.tolist()):
            for column, reference in enumerate(("exciting", "constant")):
                axis = axes[row, column]
                for gamma, color in zip(convergence.gamma.values, colors):
                    for initial in convergence.initial.values:
                        axis.plot(
                            convergence.time,
                            convergence.theta_ratio.sel(noise=noise, reference=reference, gamma=gamma, initial=initial),
                            color=color,
                            lw=1.0,
                            label=f"Gamma = {gamma:g}" if initial == convergence.initial.values[0] else None,
                        )
                axis.axhline(1.0, color="k", lw=0.8, ls=":")
                axis.set_title(f"{reference} setpoint, {'noise as in the paper' if noise == 'paper' else 'no noise'}", fontsize=9)
                axis.grid(True, alpha=0.3)
            axes[row, 0].set_ylabel("theta_hat / m11")
        for axis in axes[1]:
            axis.set_xlabel("time (s)")
        axes[0, 0].legend(fontsize=7)
        figure.suptitle("Calugi et al. (2003): theta_hat from several starts, printed gains, discrete law (67)", fontsize=10)
        figure.tight_layout()
        figures["theta_convergence.png"] = figure
    return save_figures(figures, out)
