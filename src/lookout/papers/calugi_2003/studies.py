"""Calugi et al. (2003): the questions the paper leaves open, as studies: theta_hat from
several starts, the discrete law against the continuous one, and the drift of theta_hat
that measurement noise causes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from lookout.analysis.adaptive_dp import noise_drift_rate
from lookout.papers.calugi_2003.composition import build
from lookout.papers.calugi_2003.config import GAIN_SETS, NAME, NOISE_LEVELS, WAYPOINTS, Config, gains, m11
from lookout.papers.calugi_2003.sweep import sweep_record_every
from lookout.sim import integer_ratio, keys_of_seeds, simulate_batch, stack_scenarios


def convergence_study(
    config: Config, ratios: Sequence[float] = (0.55, 0.75, 1.25, 1.5, 1.9), gammas: Sequence[float] = (1e3, 1e8, 1e9)
) -> xr.Dataset:
    """theta_hat / m11 from several initial theta_hat with the printed gains (discrete law,
    Delta of ``config``), for the printed Gamma and faster ones, with the exciting schedule
    and with a constant setpoint (no excitation), with the paper's measurement noise
    (``config.noise_std``) and without. One vmapped batch per (noise, setpoint)."""
    noises = {"paper": tuple(config.noise_std), "none": (0.0, 0.0, 0.0)}
    setpoints = {"exciting": WAYPOINTS, "constant": ((0.0, (10.0, 5.0, 0.0)),)}
    cases = [(gamma, ratio) for gamma in gammas for ratio in ratios]
    results = {}
    for noise, std in noises.items():
        noisy = config.model_copy(update={"noise_std": std})
        for label, waypoints in setpoints.items():
            scenario = stack_scenarios(
                [
                    build(
                        noisy,
                        "printed",
                        duration=config.sweep_duration,
                        initial_theta=ratio,
                        adaptation_gain=gamma,
                        waypoints=waypoints,
                        record_every=sweep_record_every(config.sample_interval, config.sweep_duration),
                    )
                    for gamma, ratio in cases
                ]
            )
            ds = simulate_batch(scenario, keys_of_seeds([config.seed] * len(cases)), batched_scenario=True).to_xarray()
            results[noise, label] = (ds.theta_m11.values / m11()).reshape(len(gammas), len(ratios), -1)
            time = ds.time.values
    data = np.stack([np.stack([results[noise, label] for label in setpoints]) for noise in noises])
    return xr.Dataset(
        {"theta_ratio": (("noise", "reference", "gamma", "initial", "time"), data)},
        coords={"noise": list(noises), "reference": list(setpoints), "gamma": list(gammas), "initial": list(ratios), "time": time},
        attrs={
            "title": f"{NAME}: theta_hat / m11 from several starts (printed gains, discrete law)",
            "units": "1",
            "paper_noise_std": list(config.noise_std),
            "sample_interval_s": config.sample_interval,
        },
    )


def discretization_order(
    config: Config, intervals: Sequence[float] = (0.04, 0.02, 0.01), gamma: float = 1e8, duration: float = 200.0, plant_step: float = 0.005
) -> xr.Dataset:
    """The discrete loop (65)-(67) against the continuous form (13)-(15) at the same Delta:
    noise-free, both gain sets, theta_hat(0) = 0.8 m11 and ``gamma``. The continuous
    observer (oracle velocity) is integrated with the plant, the controller is sampled at
    Delta in both, so the difference is the observer's discretization. Largest differences
    of the true position, the velocity estimate and theta_hat / m11 over the run; the fitted
    order is the slope of their logarithms against log Delta."""
    quiet = config.model_copy(update={"noise_std": (0.0, 0.0, 0.0)})
    rows = []
    for interval in intervals:
        runs = {}
        for form in ("discrete", "continuous"):
            scenario = stack_scenarios(
                [
                    build(
                        quiet,
                        name,
                        sample_interval=interval,
                        duration=duration,
                        adaptation_gain=gamma,
                        form=form,
                        plant_step=plant_step,
                        observer_mode="continuous" if form == "continuous" else "sampled",
                        record_every=integer_ratio(intervals[0], interval),
                    )
                    for name in GAIN_SETS
                ]
            )
            runs[form] = simulate_batch(scenario, keys_of_seeds([config.seed] * len(GAIN_SETS)), batched_scenario=True).to_xarray()
        a, b = runs["discrete"], runs["continuous"]
        rows.append(
            [
                np.abs(a.position - b.position).max(("time", "earth_axis")).values,
                np.abs(a.velocity_hat - b.velocity_hat).max(("time", "body_axis")).values,
                (np.abs(a.theta_m11 - b.theta_m11).max("time") / m11()).values,
            ]
        )
    data = np.asarray(rows)  # (interval, quantity, gains)
    names = ("position_difference", "velocity_hat_difference", "theta_ratio_difference")
    units = ("m", "m s-1", "1")
    log_delta = np.log(np.asarray(intervals))
    variables: dict[str, tuple] = {}
    for k, (name, unit) in enumerate(zip(names, units)):
        variables[name] = (("sample_interval", "gains"), data[:, k, :], {"units": unit})
        order = [
            float(np.polyfit(log_delta, np.log(data[:, k, g]), 1)[0]) if np.all(data[:, k, g] > 0) else float("nan") for g in range(len(GAIN_SETS))
        ]
        variables[name.replace("_difference", "_order")] = (("gains",), order, {"units": "1"})
    return xr.Dataset(
        variables,
        coords={"sample_interval": list(intervals), "gains": list(GAIN_SETS)},
        attrs={
            "title": f"{NAME}: discrete against continuous observer in closed loop",
            "gamma": gamma,
            "duration_s": duration,
            "plant_step_s": plant_step,
        },
    )


def noise_drift(
    config: Config,
    levels: Sequence[float] = NOISE_LEVELS,
    intervals: Sequence[float] = (0.05, 0.1, 0.2),
    gamma: float = 1e8,
    seeds: int = 32,
    window: float = 5.0,
    gain_sets: Sequence[str] = GAIN_SETS,
) -> xr.Dataset:
    """The drift of theta_hat that measurement noise causes in the discrete law (67):
    measured over the first ``window`` seconds from theta_hat(0) = m11 (no excitation
    yet: the reference starts at rest), mean slope over ``seeds`` seeds, against
    :func:`lookout.analysis.adaptive_dp.noise_drift_rate`. Position noise std
    ``level`` m in north and east, heading ``level`` x 0.1 deg; one vmapped batch per Delta."""
    rows = []
    for interval in intervals:
        cases = [(name, level, seed) for name in gain_sets for level in levels for seed in range(config.seed, config.seed + seeds)]
        scenario = stack_scenarios(
            [
                build(
                    config.model_copy(update={"noise_std": (level, level, level * float(np.radians(0.1)))}),
                    name,
                    sample_interval=interval,
                    duration=window,
                    initial_theta=1.0,
                    adaptation_gain=gamma,
                )
                for name, level, _ in cases
            ]
        )
        ds = simulate_batch(scenario, keys_of_seeds([seed for *_, seed in cases]), batched_scenario=True).to_xarray()
        time = ds.time.values
        fitted = time >= 2 * interval
        theta = ds.theta_m11.values[:, fitted]
        slopes = np.polyfit(time[fitted], theta.T, 1)[0].reshape(len(gain_sets), len(levels), seeds)
        loop_gains = {name: {key: gains(name)[key] for key in ("K1", "K2", "d", "C1", "C2")} for name in gain_sets}
        predicted = np.array(
            [[noise_drift_rate(**loop_gains[name], gamma=gamma, noise_std=level, interval=interval) for level in levels] for name in gain_sets]
        )
        rows.append((slopes.mean(axis=-1), slopes.std(axis=-1, ddof=1) / np.sqrt(seeds), predicted))
    dims = ("sample_interval", "gains", "noise_std")
    return xr.Dataset(
        {
            "measured_rate": (dims, np.stack([r[0] for r in rows]), {"units": "kg s-1", "long_name": "mean d theta_hat/dt over the window"}),
            "measured_rate_error": (dims, np.stack([r[1] for r in rows]), {"units": "kg s-1", "long_name": "standard error of the mean"}),
            "predicted_rate": (dims, np.stack([r[2] for r in rows]), {"units": "kg s-1", "long_name": "noise_drift_rate"}),
        },
        coords={"sample_interval": list(intervals), "gains": list(gain_sets), "noise_std": list(levels)},
        attrs={"title": f"{NAME}: drift of theta_hat caused by measurement noise", "gamma": gamma, "window_s": window, "seeds": seeds},
    )


def _convergence_summary(convergence: xr.Dataset) -> dict:
    final = convergence.theta_ratio.isel(time=-1)
    return {
        noise: {
            reference: {
                f"{gamma:g}": {
                    f"{initial:g}": float(final.sel(noise=noise, reference=reference, gamma=gamma, initial=initial))
                    for initial in convergence.initial.values
                }
                for gamma in convergence.gamma.values
            }
            for reference in convergence.reference.values.tolist()
        }
        for noise in convergence.noise.values.tolist()
    }


def _order_summary(order: xr.Dataset) -> dict:
    return {
        name: {
            key: {
                "difference": {
                    f"{interval:g}": float(order[f"{key}_difference"].sel(gains=name, sample_interval=interval))
                    for interval in order.sample_interval.values
                },
                "order": float(order[f"{key}_order"].sel(gains=name)),
            }
            for key in ("position", "velocity_hat", "theta_ratio")
        }
        for name in order.gains.values.tolist()
    } | {"gamma": order.attrs["gamma"], "duration_s": order.attrs["duration_s"]}


def _drift_summary(drift: xr.Dataset) -> dict:
    return {
        name: {
            f"{interval:g}": {
                f"{level:g}": {
                    key: float(drift[key].sel(gains=name, sample_interval=interval, noise_std=level))
                    for key in ("measured_rate", "measured_rate_error", "predicted_rate")
                }
                for level in drift.noise_std.values
            }
            for interval in drift.sample_interval.values
        }
        for name in drift.gains.values.tolist()
    } | {"gamma": drift.attrs["gamma"], "window_s": drift.attrs["window_s"], "seeds": drift.attrs["seeds"]}
