"""The chapter 4 studies and metrics: the continuous reference (4.5)–(4.7) and the order of
(4.34)–(4.35) against it, the summary of a run, and the tables for the terminal."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from lookout.analysis.conditions import inequalities_in
from lookout.models.manipulators import ManipulatorPlant
from lookout.papers._report import Table, significant
from lookout.papers._reproduction import built_as

from .composition import build, order_composition, simulate_document
from .config import ORDER_DURATION, ORDER_PERIODS, REPORT_TIMES, SAMPLE_PERIODS, Config


def continuous_reference(config: Config, duration: float, step: float = 1e-4, record: float = 0.0025) -> dict[str, np.ndarray]:
    """Plant and the continuous observer (4.5)–(4.7), fed the true q', integrated jointly
    by RK4 at ``step`` with tau = A sin(w t) evaluated at each stage; recorded every
    ``record`` s (a multiple of every Delta of the order study)."""
    scenario = build(config, SAMPLE_PERIODS[0])
    model, estimator = built_as(scenario.plant, ManipulatorPlant, "the plant").model, scenario.observer

    def field(t, x):
        q, qdot, velocity, theta = x[0:1], x[1:2], x[2:3], x[3:4]
        tau = jnp.atleast_1d(config.input_amplitude * jnp.sin(config.input_frequency * t))
        rate, theta_rate = estimator.continuous_rate(velocity, theta, q, qdot, tau)
        return jnp.concatenate([qdot, model.acceleration(q, qdot, tau), rate, theta_rate])

    def rk4(x, t):
        k1 = field(t, x)
        k2 = field(t + step / 2, x + step / 2 * k1)
        k3 = field(t + step / 2, x + step / 2 * k2)
        k4 = field(t + step, x + step * k3)
        return x + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    inner = int(round(record / step))
    outer = int(round(duration / record))

    def block(x, k):
        x = jax.lax.fori_loop(0, inner, lambda j, x: rk4(x, (k * inner + j) * step), x)
        return x, x

    x0 = jnp.array([0.0, -1.0, 0.0, config.initial_mass])
    _, xs = jax.jit(lambda x: jax.lax.scan(block, x, jnp.arange(outer)))(x0)
    xs = np.concatenate([np.asarray(x0)[None], np.asarray(xs)])
    return {"time": np.arange(outer + 1) * record, "velocity": xs[:, 2], "theta": xs[:, 3], "qdot": xs[:, 1]}


def order_study(config: Config, duration: float = ORDER_DURATION) -> dict:
    """max |theta_hat - theta_hat_cont| and |x1_hat - x1_hat_cont| over [0, duration] at the
    sample times of the coarsest Delta, for Delta in :data:`ORDER_PERIODS`, and the fitted
    order log2(error(Delta) / error(Delta / 2))."""
    reference = continuous_reference(config, duration)
    coarse = ORDER_PERIODS[0]
    times = np.arange(int(round(duration / coarse))) * coarse  # the record ends one sample before the duration
    pick = np.rint(times / 0.0025).astype(int)
    errors: dict[str, list[float]] = {"theta": [], "velocity": []}
    for period in ORDER_PERIODS:
        ds = simulate_document(order_composition(config, period, duration)).isel(run=0)
        index = np.rint(times / period).astype(int)
        errors["theta"].append(float(np.max(np.abs(ds.mass_hat.values[index] - reference["theta"][pick]))))
        errors["velocity"].append(float(np.max(np.abs(ds.joint_rate_hat.values[index, 0] - reference["velocity"][pick]))))
    orders = {key: [math.log2(a / b) for a, b in zip(values[:-1], values[1:])] for key, values in errors.items()}
    return {"sample_periods": list(ORDER_PERIODS), "max_error": errors, "order": orders, "duration_s": duration}


def _at(ds: xr.Dataset, times) -> list[float]:
    return [float(ds.mass_hat.sel(time=t, method="nearest")) for t in times]


def summarize(ds: xr.Dataset, config: Config) -> dict:
    """theta_hat at :data:`REPORT_TIMES`, its band after 100 s, the RMS of x1~ and the resets."""
    error = ds.joint_rate.values[:, 0] - ds.joint_rate_hat.values[:, 0]
    late = ds.time.values >= min(100.0, 0.5 * float(ds.time.values[-1]))
    band = ds.mass_hat.values[late]
    return {
        "theta_hat_at": dict(zip([f"{t:g} s" for t in REPORT_TIMES], _at(ds, [t for t in REPORT_TIMES]))),
        "theta_hat_final": float(ds.mass_hat.values[-1]),
        "theta_hat_band_late": [float(band.min()), float(band.max())],
        "band_from_s": float(ds.time.values[late][0]),
        "velocity_error_rms": float(np.sqrt(np.mean(error**2))),
        "velocity_error_rms_after_1s": float(np.sqrt(np.mean(error[ds.time.values >= 1.0] ** 2))),
        "resets": float(ds.resets.values[-1]),
        "status": [str(ds.status.values)],
    }


def max_speed(results: dict) -> float:
    """The largest |q'| over the runs ``results`` (for Theorem 4.1's w_max)."""
    return float(max(np.abs(ds.joint_rate.values).max() for ds in results.values()))


def _number(value) -> str:
    """A side of an inequality: None in JSON is an unbounded region (C_M = 0)."""
    return "inf" if value is None else f"{value:.4g}"


def tables(summary: dict) -> list[Table]:
    """theta_hat over time per Delta, Theorem 4.1, the studies."""
    rows = []
    for period, values in summary["sample_periods"].items():
        at = values["theta_hat_at"]
        rows.append(
            (
                f"{float(period) * 1000:g} ms",
                *(f"{v:.4f}" for v in at.values()),
                f"{values['theta_hat_band_late'][0]:.3f}-{values['theta_hat_band_late'][1]:.3f}",
                significant(values["velocity_error_rms_after_1s"]),
                f"{values['resets']:g}",
            )
        )
    result = [
        Table(
            "Mass estimate theta_hat (kg) at times (s); m = 1 kg, theta_hat(0) = 0.1 kg",
            ("Delta", *(f"{t:g}" for t in REPORT_TIMES), "band after 100 s", "RMS x1~", "resets"),
            tuple(rows),
            "tau = A sin(w t) chosen (the thesis gives none); RMS of the velocity error after 1 s, rad/s",
        )
    ]
    theorem = summary["theorem_4_1"]
    result.append(
        Table(
            "Theorem 4.1 (C_M = 0 for the pendulum: the region is global)",
            ("", "condition", "left", "right", "verdict"),
            tuple(
                (item["name"], item["relation"], _number(item["left"]), _number(item["right"]), item["verdict"]) for item in inequalities_in(theorem)
            ),
            f"sigma = K m l^2 = {theorem['quantities']['sigma']:.4g}; w_max from the run",
        )
    )
    if summary.get("order"):
        order = summary["order"]
        result.append(
            Table(
                f"(4.34)-(4.35) against the continuous (4.5)-(4.7), max error over {order['duration_s']:g} s",
                ("Delta (s)", "theta_hat (kg)", "x1_hat (rad/s)"),
                tuple(
                    (f"{p:g}", significant(a), significant(b))
                    for p, a, b in zip(order["sample_periods"], order["max_error"]["theta"], order["max_error"]["velocity"])
                ),
                "fitted orders: theta "
                + ", ".join(f"{v:.2f}" for v in order["order"]["theta"])
                + "; x1 "
                + ", ".join(f"{v:.2f}" for v in order["order"]["velocity"]),
            )
        )
    if summary.get("stress"):
        stress = summary["stress"]
        result.append(
            Table(
                f"Gamma = {stress['adaptation_gain']:g}, bounds {stress['bounds'][0]:g}-{stress['bounds'][1]:g} kg, "
                f"mu = {stress['margin']:g} kg, Delta = 10 ms: resetting at work",
                ("resets", "theta_hat range (kg)", "final theta_hat (kg)"),
                (
                    (
                        f"{stress['resets']:g}",
                        f"{stress['theta_hat_range'][0]:.3f}-{stress['theta_hat_range'][1]:.3f}",
                        f"{stress['theta_hat_final']:.4f}",
                    ),
                ),
                "theta_hat(0) = 0.1 kg lies below l - mu and is reset at t_0",
            )
        )
    return result
