"""The chapter 6 figures: per experiment, the panels of Figs. 6.2–6.18."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from lookout.controllers.furuta import PENDULUM_REFERENCE
from lookout.observers.adaptive_manipulator import theta_signal_name
from lookout.papers._report import save_figures

from .config import EXPERIMENTS, PERIOD, SAMPLE_PERIOD, SYMBOLS, TRUTH, UNITS


def save_experiment_figures(results: dict, out: Path) -> list[str]:
    """Per experiment, the panels of Figs. 6.2–6.18: theta with theta_d, phi, x1_hat_2 with the
    true theta', x1_hat_1 with the true phi', tau_u and the estimates. A run that fails is drawn
    up to where the pendulum leaves its half-plane (or the numbers stop being finite)."""
    import matplotlib.pyplot as plt

    figures = {}
    for name, ds in results.items():
        experiment = EXPERIMENTS[name]
        time = ds.time.values
        upright = 0.0 if experiment.upright else math.pi
        bad = ~np.isfinite(ds.joint_torque_applied.values[:, 0]) | (np.abs(ds.joint_angle.values[:, 1] - upright) > math.pi / 2)
        end = len(time) if not bad.any() else max(1, int(np.argmax(bad)))
        window = slice(0, end)
        t = time[window]
        figure, grid = plt.subplots(6, 2, figsize=(12, 13), gridspec_kw={"width_ratios": (3, 1)})
        axes, zooms = grid[:, 0], grid[:, 1]
        for axis in axes[1:]:
            axis.sharex(axes[0])
        # the zoom: the last reference period drawn (2.5 s), or the last 0.5 s before a failure
        span = PERIOD if end == len(time) else 0.5
        tail = slice(max(0, end - int(round(span / SAMPLE_PERIOD))), end)
        angle, rate, rate_hat = ds.joint_angle.values, ds.joint_rate.values, ds.joint_rate_hat.values
        tau, desired = ds.joint_torque_applied.values[:, 0], ds[f"{PENDULUM_REFERENCE}_desired"].values
        axes[0].plot(t, desired[window], color="k", lw=1.2, label="theta_d")
        axes[0].plot(t, angle[window, 1], color="C0", lw=0.9, ls="--", label="theta")
        axes[0].set_ylabel("pendulum theta (rad)")
        zooms[0].plot(time[tail], angle[tail, 1] - desired[tail], color="C0", lw=0.9, label="theta - theta_d")
        zooms[0].set_ylabel("z1 (rad)")
        axes[1].plot(t, angle[window, 0], color="C4", lw=0.9, label="phi (arm, not controlled)")
        axes[1].set_ylabel("arm phi (rad)")
        for row, joint, truth_label, estimate_label, unit_label in (
            (2, 1, "theta' (true, the 'analog' signal)", "x1_hat_2 (observer)", "pendulum rate (rad/s)"),
            (3, 0, "phi' (true, the 'analog' signal)", "x1_hat_1 (observer)", "arm rate (rad/s)"),
        ):
            for axis, part in ((axes[row], window), (zooms[row], tail)):
                axis.plot(time[part], rate[part, joint], color="k", lw=1.2, label=truth_label)
                axis.plot(time[part], rate_hat[part, joint], color="C1", lw=0.7, ls="--", label=estimate_label)
            axes[row].set_ylabel(unit_label)
        for axis, part in ((axes[4], window), (zooms[4], tail)):
            axis.plot(time[part], tau[part], color="C2", lw=0.7, label="tau_u")
        axes[4].set_ylabel("arm torque (N m)")
        for k, unknown in enumerate(experiment.unknowns):
            symbol, color = SYMBOLS[unknown], ("C3", "C0")[k]
            axis = axes[5] if k == 0 else axes[5].twinx()
            axis.plot(t, ds[theta_signal_name(unknown)].values[window], color=color, lw=1.0, ls="--", label=f"{symbol}_hat")
            axis.axhline(TRUTH[unknown], color=color, lw=0.8, label=f"{symbol} (true)")
            axis.set_ylabel(f"{symbol} ({UNITS[unknown]})", color=color)
            axis.legend(fontsize=7, loc="lower right" if k == 0 else "center right")
        axes[5].set_xlabel("time (s)")
        for axis in axes[:5]:
            axis.legend(fontsize=7, loc="upper right")
        zooms[0].set_title(f"zoom: the last {time[tail][-1] - time[tail][0] + SAMPLE_PERIOD:.2f} s drawn", fontsize=8)
        for row in (1, 5):
            zooms[row].axis("off")
        for row in (2, 3):
            zooms[row].sharex(zooms[0])
        zooms[4].sharex(zooms[0])
        zooms[4].set_xlabel("time (s)")
        status = str(ds.status.values)
        ending = "" if end == len(time) else f"; the pendulum leaves its half-plane at {time[int(np.argmax(bad))]:.2f} s ({status})"
        figure.suptitle(f"Exp. {name} (cf. Figs. {experiment.figures}): {experiment.note}{ending}", fontsize=9)
        figure.tight_layout()
        figures[f"exp_{name.replace('-', '_')}.png"] = figure
    return save_figures(figures, out)
