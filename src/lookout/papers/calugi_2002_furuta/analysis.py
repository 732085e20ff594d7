"""The chapter 6 metrics (the derivation notes' "what a reproduction should output") and
the table for the terminal."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from lookout.controllers.furuta import PENDULUM_REFERENCE
from lookout.models.furuta import FurutaConstants
from lookout.observers.adaptive_manipulator import theta_signal_name
from lookout.papers._report import Table
from lookout.papers._reproduction import built_as

from .composition import parameters
from .config import EXPERIMENTS, SYMBOLS, TRUTH


def _settling_time(time: np.ndarray, values: np.ndarray, target: float, tolerance: float = 0.05) -> float | None:
    """First time after which |value - target| <= tolerance |target| to the end; None if never."""
    inside = np.abs(values - target) <= tolerance * abs(target)
    if not inside.size or not inside[-1]:
        return None
    outside = np.flatnonzero(~inside)
    return float(time[0]) if not outside.size else float(time[outside[-1] + 1])


def summarize(ds: xr.Dataset, name: str) -> dict:
    """The numbers of the derivation notes' "what a reproduction should output" (ch. 6)."""
    experiment = EXPERIMENTS[name]
    time = ds.time.values
    angle, rate = ds.joint_angle.values, ds.joint_rate.values
    rate_hat = ds.joint_rate_hat.values
    tau = ds.joint_torque_applied.values[:, 0]
    desired = ds[f"{PENDULUM_REFERENCE}_desired"].values
    hats = {unknown: ds[theta_signal_name(unknown)].values for unknown in experiment.unknowns}
    finite = np.all(np.isfinite(angle), axis=1) & np.all(np.isfinite(rate_hat), axis=1) & np.isfinite(tau)
    for values in hats.values():
        finite &= np.isfinite(values)
    last = len(time) if finite.all() else int(np.argmin(finite))
    ok = slice(0, last)
    error = angle[ok, 1] - desired[ok]
    late = time[ok] >= 5.0
    # the pendulum leaves its half-plane: |theta| > pi/2 upright, |theta - pi| > pi/2 hanging
    offset = angle[ok, 1] - (0.0 if experiment.upright else math.pi)
    left = np.flatnonzero(np.abs(offset) > math.pi / 2)
    fell_at = float(time[left[0]]) if left.size else None
    # det M_hat(q; theta_hat) along the run, at the observer's q (the measurement) and theta_hat
    unknowns = parameters(experiment.unknowns)
    theta_hat = np.stack([hats[u][ok] for u in experiment.unknowns], axis=1)
    q_hat = ds.joint_angle_hat.values[ok]
    det = np.asarray(
        jax.jit(jax.vmap(lambda q, th: built_as(unknowns.model(th), FurutaConstants, "the model of theta_hat").determinant(q)))(
            jnp.asarray(q_hat), jnp.asarray(theta_hat)
        )
    )
    dt = float(time[1] - time[0])
    status = str(ds.status.values)
    if status == "finite" and fell_at is not None:
        status = "fell"
    result = {
        "experiment": name,
        "figures": experiment.figures,
        "printed_setting": experiment.printed,
        "note": experiment.note,
        "duration_s": float(time[-1] + dt),
        "status": status,
        "finite_until_s": float(time[last - 1]) if last > 0 else 0.0,
        "pendulum_left_half_plane_at_s": fell_at,
        "rms_tracking_error_after_5s": float(np.sqrt(np.mean(error[late] ** 2))) if late.any() else None,
        "max_abs_tracking_error_after_5s": float(np.abs(error[late]).max()) if late.any() else None,
        "max_abs_tau_u": float(np.abs(tau[ok]).max()) if last > 0 else None,
        "max_abs_tau_u_after_1s": float(np.abs(tau[ok][time[ok] >= 1.0]).max()) if (time[ok] >= 1.0).any() else None,
        "arm_rate_range": [float(rate[ok, 0].min()), float(rate[ok, 0].max())],
        "pendulum_rate_range": [float(rate[ok, 1].min()), float(rate[ok, 1].max())],
        "arm_rate_hat_range": [float(rate_hat[ok, 0].min()), float(rate_hat[ok, 0].max())],
        "pendulum_rate_hat_range": [float(rate_hat[ok, 1].min()), float(rate_hat[ok, 1].max())],
        "arm_angle_final": float(angle[last - 1, 0]) if last > 0 else None,
        "arm_mean_rate": float((angle[last - 1, 0] - angle[0, 0]) / max(time[last - 1] - time[0], dt)) if last > 1 else None,
        "arm_stuck_time_s": float(ds.arm_stuck_time.values[last - 1]) if last > 0 else None,
        "det_m_hat_nonpositive_s": float(np.count_nonzero(det <= 0) * dt),
        "det_m_hat_min": float(det.min()) if det.size else None,
        "resets": int(ds.resets.values[last - 1]) if last > 0 else 0,
        "initial_estimates": dict(zip(experiment.unknowns, experiment.initial)),
        "final_estimates": {u: float(hats[u][last - 1]) if last > 0 else None for u in experiment.unknowns},
        "estimate_within_5pct_from_s": {u: _settling_time(time[ok], hats[u][ok], TRUTH[u]) for u in experiment.unknowns},
    }
    return result


def _value(value, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(f"{v:.{digits}g}" for v in value) + "]"
    return f"{value:.{digits}g}"


def tables(summary: dict) -> list[Table]:
    """One column per experiment."""
    experiments = summary["experiments"]
    keys = (
        ("status", "status"),
        ("finite until (s)", "finite_until_s"),
        ("fell at (s)", "pendulum_left_half_plane_at_s"),
        ("RMS z1, t>5 s (rad)", "rms_tracking_error_after_5s"),
        ("max |tau_u| (N m)", "max_abs_tau_u"),
        ("max |tau_u|, t>1 s", "max_abs_tau_u_after_1s"),
        ("phi' range (rad/s)", "arm_rate_range"),
        ("theta' range (rad/s)", "pendulum_rate_range"),
        ("mean phi' (rad/s)", "arm_mean_rate"),
        ("arm stuck (s)", "arm_stuck_time_s"),
        ("det M_hat <= 0 (s)", "det_m_hat_nonpositive_s"),
        ("resets", "resets"),
    )
    rows = []
    for label, key in keys:
        if key == "status":
            rows.append((label, *(v["status"] for v in experiments.values())))
        elif key == "resets":
            rows.append((label, *(str(v["resets"]) for v in experiments.values())))
        else:
            rows.append((label, *(_value(v[key]) for v in experiments.values())))
    for unknown, truth in TRUTH.items():
        rows.append((f"final {SYMBOLS[unknown]}_hat ({truth:g})", *(_value(v["final_estimates"].get(unknown), 4) for v in experiments.values())))
        rows.append(
            (f"{SYMBOLS[unknown]}_hat in 5 % from (s)", *(_value(v["estimate_within_5pct_from_s"].get(unknown)) for v in experiments.values()))
        )
    return [
        Table(
            "Calugi (2002) ch. 6: Furuta pendulum experiments in simulation",
            ("", *experiments),
            tuple(rows),
            "z1 = theta - theta_d; fell: the pendulum left its half-plane; -fixed: the nearest working setting; M_hat is positive definite for all theta iff alpha_hat > gamma^2/beta = "
            f"{summary['alpha_minimum_for_positive_m_hat']:.4g}",
        )
    ]
