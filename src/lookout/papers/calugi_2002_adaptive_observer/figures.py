"""The chapter 4 figures: Figs. 4.2 and 4.3."""

from __future__ import annotations

from pathlib import Path

from lookout.papers._report import save_figures

from .config import MASS, SAMPLE_PERIODS, Config


def save_paper_figures(results: dict, config: Config, out: Path) -> list[str]:
    import matplotlib.pyplot as plt

    colors = {0.01: "C0", 0.001: "C1"}
    figures = {}
    figure, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    first = results[SAMPLE_PERIODS[0]]
    window = first.time.values <= 20.0
    axes[0].plot(first.time[window], first.joint_rate.values[window, 0], color="k", lw=1.6, label="q' (true)")
    for period, ds in results.items():
        w = ds.time.values <= 20.0
        axes[0].plot(ds.time[w], ds.joint_rate_hat.values[w, 0], color=colors[period], lw=0.9, ls="--", label=f"x1_hat, Delta = {period * 1000:g} ms")
        axes[1].plot(ds.time[w], ds.mass_hat.values[w], color=colors[period], lw=0.9, label=f"theta_hat, Delta = {period * 1000:g} ms")
    axes[1].axhline(MASS, color="k", lw=1.2, label="m (true)")
    axes[0].set_ylabel("velocity (rad/s)")
    axes[1].set_ylabel("mass (kg)")
    axes[1].set_xlabel("time (s)")
    for axis in axes:
        axis.legend(fontsize=8)
    figure.suptitle(
        f"Fig. 4.2: velocity and mass estimates (tau = {config.input_amplitude:g} sin({config.input_frequency:g} t), chosen)", fontsize=10
    )
    figure.tight_layout()
    figures["fig_4_2.png"] = figure

    figure, axis = plt.subplots(figsize=(9, 3.5))
    for period, ds in results.items():
        axis.plot(ds.time, ds.mass_hat, color=colors[period], lw=0.9, label=f"theta_hat, Delta = {period * 1000:g} ms")
    axis.axhline(MASS, color="k", lw=1.2, label="m (true)")
    axis.set_xlabel("time (s)")
    axis.set_ylabel("mass (kg)")
    axis.legend(fontsize=8)
    figure.suptitle("Fig. 4.3: the mass estimate over the long run", fontsize=10)
    figure.tight_layout()
    figures["fig_4_3.png"] = figure
    return save_figures(figures, out)
