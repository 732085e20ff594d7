"""The chapter 3 metrics: settling, persistence of excitation, the Lyapunov function
V = 1/2 |theta~|^2, the runs without excitation, and the tables for the terminal."""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from lookout.observers.parameter_estimator import ParameterEstimator, windowed_excitation
from lookout.papers._report import Table, significant

from .config import LENGTH, REPORT_DELAYS, SETTLE_BAND, SIM2_MASS, SIMULATIONS, Config, Simulation


def settle_time(time: np.ndarray, estimate: np.ndarray, truth: float, band: float = SETTLE_BAND) -> float | None:
    """Time (from ``time[0]``) after which |estimate - truth| <= band |truth| at every
    later record of ``time``; None when the last record is outside the band."""
    inside = np.abs(estimate - truth) <= band * abs(truth)
    if not inside[-1]:
        return None
    outside = np.flatnonzero(~inside)
    first = 0 if outside.size == 0 else outside[-1] + 1
    return float(time[first] - time[0])


def _at(time: np.ndarray, values: np.ndarray, t: float):
    index = int(np.searchsorted(time, t - 1e-9))
    return None if index >= time.size else values[index]


def _excitation(estimator: ParameterEstimator, ds: xr.Dataset, config: Config, gain: float) -> dict:
    """Windowed PE (min over the run and when), the stiffness of (3.9) and its RK4 margin."""
    time = ds.time.values
    phi = estimator.regressor_series(ds)
    ends, lam = windowed_excitation(time, phi, config.pe_window)
    worst = int(np.argmin(lam))
    largest = float(np.linalg.eigvalsh(np.einsum("kia,kib->kab", phi, phi))[:, -1].max())
    pointwise = float(np.linalg.eigvalsh(np.einsum("kia,kib->kab", phi, phi))[:, 0].max())
    return {
        "window_s": config.pe_window,
        "lambda_min": float(lam[worst]),
        "lambda_min_at_s": float(ends[worst]),
        "lambda_min_final": float(lam[-1]),
        "pointwise_lambda_min_max": pointwise,
        "stiffness_per_s": gain * largest,
        "rk4_step_times_stiffness": gain * largest * config.plant_step,
    }


def _lyapunov(time: np.ndarray, estimates: np.ndarray, truth: np.ndarray, until: float | None = None) -> dict:
    """V = 1/2 |theta~|^2 at the start and the end, and its largest increase between two
    records before ``until`` (theta constant from t = 0 there: after a jump, tau_f still
    carries the old theta for a few 1/a, and V may rise)."""
    v = 0.5 * np.sum((truth - estimates) ** 2, axis=-1)
    keep = time <= (time[-1] if until is None else until) + 1e-9
    steps = np.diff(v[keep])
    increase = float(max(steps.max(), 0.0)) if steps.size else 0.0
    peak = float(v[keep].max())
    return {
        "until_s": float(time[keep][-1]),
        "initial": float(v[0]),
        "final": float(v[keep][-1]),
        "largest_increase": increase,
        "largest_increase_relative": increase / peak if peak > 0 else 0.0,
    }


def _sim1_summary(ds: xr.Dataset, estimator: ParameterEstimator, sim: Simulation, config: Config) -> dict:
    time = ds.time.values
    estimate = estimator.estimates(ds)[:, 0]
    truth = ds["mass"].isel(run=0).values
    starts = [0.0] + [t for t in sim.switch_times if t < time[-1]]
    ends = starts[1:] + [float(time[-1]) + config.sample_period]
    segments = []
    for start, end in zip(starts, ends):
        inside = (time >= start - 1e-9) & (time < end - 1e-9)
        mass = float(truth[inside][0])
        after = {}
        for delay in REPORT_DELAYS:
            value = _at(time, estimate, start + delay) if start + delay < end - 1e-9 else None
            after[f"{delay:g}"] = None if value is None else {"estimate": float(value), "relative_error": float(value / mass - 1.0)}
        segments.append(
            {
                "from_s": start,
                "to_s": min(end, float(time[-1])),
                "mass": mass,
                "estimate_at_start": float(estimate[inside][0]),
                "after_s": after,
                "settle_1pct_s": settle_time(time[inside], estimate[inside], mass),
                "estimate_at_end": float(estimate[inside][-1]),
            }
        )
    return {
        "label": sim.label,
        "gain": sim.gain,
        "length": LENGTH,
        "masses": [v[0] for v in sim.values],
        "switch_times": list(sim.switch_times),
        "initial_position": sim.initial_position,
        "initial_velocity": sim.initial_velocity,
        "initial_estimate": list(sim.initial_estimate),
        "segments": segments,
        "excitation": _excitation(estimator, ds, config, sim.gain),
        "lyapunov": _lyapunov(
            time, estimate[:, None], truth[:, None], until=sim.switch_times[0] - config.sample_period if sim.switch_times else None
        ),
        "max_abs_angle": float(np.abs(ds.joint_angle.values).max()),
    }


def _sim2_summary(ds: xr.Dataset, estimator: ParameterEstimator, sim: Simulation, config: Config) -> dict:
    time = ds.time.values
    estimates = estimator.estimates(ds)
    truth = np.asarray(sim.values[0])
    parameters: dict[str, dict[str, Any]] = {}
    for j, (name, unit) in enumerate(zip(estimator.parameters.names, estimator.parameters.units)):
        at = {f"{d:g}": (None if d > time[-1] else float(_at(time, estimates[:, j], d))) for d in REPORT_DELAYS}
        parameters[name] = {
            "unit": unit,
            "truth": float(truth[j]),
            "initial_estimate": float(estimates[0, j]),
            "at_s": at,
            "final_estimate": float(estimates[-1, j]),
            "final_error": float(truth[j] - estimates[-1, j]),
            "final_relative_error": float(estimates[-1, j] / truth[j] - 1.0),
            "settle_1pct_s": settle_time(time, estimates[:, j], float(truth[j])),
        }
    settles = [p["settle_1pct_s"] for p in parameters.values()]
    return {
        "label": sim.label,
        "gain": sim.gain,
        "mass": SIM2_MASS,
        "length": LENGTH,
        "initial_position": sim.initial_position,
        "initial_velocity": sim.initial_velocity,
        "parameters": parameters,
        "settle_1pct_all_s": None if None in settles else max(settles),
        "excitation": _excitation(estimator, ds, config, sim.gain),
        "lyapunov": _lyapunov(time, estimates, np.broadcast_to(truth, estimates.shape)),
        "max_abs_angle": float(np.abs(ds.joint_angle.values).max()),
    }


def _still_summary(ds: xr.Dataset, estimator: ParameterEstimator, sim: Simulation) -> dict:
    estimates = estimator.estimates(ds)
    phi = estimator.regressor_series(ds)
    return {
        "label": sim.label,
        "initial_estimate": list(sim.initial_estimate),
        "max_estimate_change": float(np.abs(estimates - estimates[0]).max()),
        "final_estimate": estimates[-1].tolist(),
        "max_abs_angle": float(np.abs(ds.joint_angle.values).max()),
        "max_abs_filtered_regressor": float(np.abs(phi).max()),
    }


def summarize(config: Config, results: dict[str, xr.Dataset], estimators: dict[str, ParameterEstimator]) -> dict:
    """The summary's numbers from the four runs' Datasets and estimators."""
    runs = SIMULATIONS
    return {
        "sim1": _sim1_summary(results["sim1"], estimators["sim1"], runs["sim1"], config),
        "sim2": _sim2_summary(results["sim2"], estimators["sim2"], runs["sim2"], config),
        "no_excitation": {name: _still_summary(results[name], estimators[name], runs[name]) for name in ("sim1_free_swing", "sim2_rest")},
    }


def tables(summary: dict) -> list[Table]:
    """Sim 1 per interval, Sim 2 per parameter, excitation, and the runs without excitation."""
    fmt = lambda value: "-" if value is None else significant(value)  # noqa: E731
    sim1 = []
    for segment in summary["sim1"]["segments"]:
        after = [fmt(None if v is None else v["estimate"]) for v in segment["after_s"].values()]
        sim1.append((f"{segment['from_s']:g}", fmt(segment["mass"]), *after, fmt(segment["settle_1pct_s"])))
    sim2 = []
    for name, p in summary["sim2"]["parameters"].items():
        sim2.append(
            (
                f"{name} ({p['unit']})",
                fmt(p["truth"]),
                *(fmt(v) for v in p["at_s"].values()),
                fmt(p["final_estimate"]),
                f"{p['final_relative_error']:.1e}",
                fmt(p["settle_1pct_s"]),
            )
        )
    excitation = []
    for name in ("sim1", "sim2"):
        e = summary[name]["excitation"]
        excitation.append(
            (
                name,
                fmt(e["lambda_min"]),
                fmt(e["lambda_min_at_s"]),
                f"{e['pointwise_lambda_min_max']:.1e}",
                fmt(e["stiffness_per_s"]),
                f"{summary[name]['lyapunov']['largest_increase_relative']:.1e}",
            )
        )
    still = [(name, f"{s['max_estimate_change']:.1e}", fmt(s["max_abs_angle"])) for name, s in summary["no_excitation"].items()]
    delays = tuple(f"+{d:g} s" for d in REPORT_DELAYS)
    return [
        Table(
            "Sim 1: m_hat (kg) after the start and after each jump",
            ("from (s)", "m", *delays, "settle 1 % (s)"),
            tuple(sim1),
            "settle: time after the interval's start from which m_hat stays within 1 % of m",
        ),
        Table(
            "Sim 2: theta_hat",
            ("parameter", "truth", *(f"{d:g} s" for d in REPORT_DELAYS), "final", "final rel. error", "settle 1 % (s)"),
            tuple(sim2),
        ),
        Table(
            "Excitation: windowed lambda_min(int phi_f^T phi_f) (min over the run)",
            ("run", "lambda_min", "at (s)", "pointwise max", "h lambda_max (1/s)", "max dV / V_max"),
            tuple(excitation),
            "pointwise max: largest lambda_min(phi_f^T phi_f) at one instant (Lemma 3.1(2)'s rank condition); dV: V = |theta~|^2/2 between records where theta is constant since t = 0 (Sim 1: before the first jump)",
        ),
        Table("No excitation (tau = 0)", ("run", "max |theta_hat - theta_hat(0)|", "max |q| (rad)"), tuple(still)),
    ]
