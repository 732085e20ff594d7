"""The chapter 3 figures: Figs. 3.2 and 3.3, and the excitation of the filtered regressor."""

from __future__ import annotations

import xarray as xr

from lookout.observers.parameter_estimator import ParameterEstimator, windowed_excitation

from .config import LENGTH, SIM1_SWITCH_TIMES, SIM2_MASS, Config


def input_text(config: Config) -> str:
    frequency = "t" if config.input_frequency == 1.0 else f"{config.input_frequency:g} t"
    return f"tau = {config.input_amplitude:g} sin({frequency}) N m"


def paper_figures(results: dict[str, xr.Dataset], estimators: dict[str, ParameterEstimator], config: Config) -> dict:
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_estimates

    figures = {}
    sim1, sim2 = results["sim1"], results["sim2"]
    end1 = float(sim1.time[-1])
    jump = next((t for t in SIM1_SWITCH_TIMES if t + 5.0 <= end1), None)
    window = (jump - 1.0, jump + 5.0) if jump is not None else (0.0, min(6.0, end1))
    figures["fig3_2_mass_estimate.png"] = plot_estimates(
        sim1,
        [("mass", None)],
        window=window,
        title=f"Calugi (2002), Fig. 3.2: pendulum mass, true (stepwise, chosen) and estimated; h = 10, {input_text(config)}",
    )
    end2 = float(sim2.time[-1])
    figures["fig3_3_inertia_moment_estimates.png"] = plot_estimates(
        sim2,
        [("inertia", None), ("moment", None)],
        window=(0.0, min(5.0, end2)),
        title=f"Calugi (2002), Fig. 3.3: theta = (m l^2, m l), m = {SIM2_MASS:g} kg, l = {LENGTH:g} m (chosen); h = 100, {input_text(config)}",
    )
    figure = plt.figure(figsize=(11, 5.2), layout="constrained")
    grid = figure.add_gridspec(2, 2)
    pe_axis, swing_axis, still_axis = figure.add_subplot(grid[:, 0]), figure.add_subplot(grid[0, 1]), figure.add_subplot(grid[1, 1])
    for name, label in (("sim1", "Sim 1 (theta = m)"), ("sim2", "Sim 2 (theta = (m l^2, m l))")):
        ds, estimator = results[name], estimators[name]
        ends, lam = windowed_excitation(ds.time.values, estimator.regressor_series(ds), config.pe_window)
        pe_axis.semilogy(ends, lam, label=label)
    pe_axis.set_ylabel(f"lambda_min of the integral of phi_f^T phi_f over {config.pe_window:g} s\n(SI units of phi_f, squared, times s)")
    pe_axis.set_title("persistence of excitation, window ending at t", fontsize=10)
    swing = results["sim1_free_swing"]
    swing_axis.plot(swing.time.values, swing.joint_angle.isel(run=0).values[:, 0], color="0.4", lw=0.8)
    swing_axis.set_ylabel("q (rad)")
    swing_axis.set_title("tau = 0: Sim 1 swinging freely from q(0) = 1 rad (top), Sim 2 at rest", fontsize=10)
    for name, names in (
        ("sim1_free_swing", ("m_hat, free swing (kg)",)),
        ("sim2_rest", ("theta_hat_1, at rest (kg m2)", "theta_hat_2, at rest (kg m)")),
    ):
        ds, estimator = results[name], estimators[name]
        for column, label in zip(estimator.estimates(ds).T, names):
            still_axis.plot(ds.time.values, column, label=label)
    still_axis.set_ylabel("estimate")
    still_axis.set_ylim(0.0, 5.0)
    still_axis.legend(fontsize=7, loc="center right", bbox_to_anchor=(1.0, 0.66))
    pe_axis.legend(fontsize=8)
    for axis in (pe_axis, swing_axis, still_axis):
        axis.grid(alpha=0.3)
    for axis in (pe_axis, still_axis):
        axis.set_xlabel("time (s)")
    figure.suptitle("Calugi (2002), ch. 3: excitation of the filtered regressor, and runs without it (the estimates stay put)", fontsize=10)
    figures["excitation.png"] = figure
    return figures
