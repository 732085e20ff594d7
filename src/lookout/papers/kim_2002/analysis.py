"""Kim (2002): the closed loop's metrics, when a run counts as diverged, and the force
the bias estimate stands for under model error."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

from lookout.analysis import estimation_errors
from lookout.models.vessel import NORTHERN_CLIPPER_THRUST_LIMIT, VesselPlant
from lookout.papers._report import significant
from lookout.papers._reproduction import built_as
from lookout.papers.kim_2002.composition import build
from lookout.papers.kim_2002.config import DIVERGED_DISTANCE, Config, gain_sets

# ---------------------------------------------------------------------------------
# metrics


def closed_loop_metrics(ds: xr.Dataset) -> dict[str, np.ndarray]:
    """Per run: RMS tracking error (horizontal m, heading rad), RMS estimation errors,
    peak and RMS applied thrust, time saturated, and whether the run diverged.

    Tracking is the low-frequency position and heading against the reference
    (position - position_desired), over the whole run. ``diverged``: non-finite, or
    the position more than :data:`DIVERGED_DISTANCE` from the reference, or the
    position estimate that far from the position, at any time (thrust limits can keep
    a vessel near its track while the observer behind it has diverged).
    """
    distance = np.sqrt(((ds.position - ds.position_desired) ** 2).sum("earth_axis"))
    heading = np.arctan2(np.sin(ds.heading - ds.heading_desired), np.cos(ds.heading - ds.heading_desired))
    errors = estimation_errors(ds)
    force = ds.force_applied
    moment = ds.moment_applied
    limit = np.asarray(NORTHERN_CLIPPER_THRUST_LIMIT)
    commanded = np.concatenate([ds.force_commanded.values, ds.moment_commanded.values[..., None]], axis=-1)
    saturated = np.any(np.abs(commanded) > limit, axis=-1)
    finite = np.isfinite(distance.values).all(axis=-1)
    worst = np.where(np.isfinite(distance.values), distance.values, np.inf).max(axis=-1)
    estimate_distance = np.sqrt((errors.position**2).sum("earth_axis")).values
    worst_estimate = np.where(np.isfinite(estimate_distance), estimate_distance, np.inf).max(axis=-1)
    return {
        "tracking_rms_m": np.sqrt((distance**2).mean("time")).values,
        "tracking_max_m": worst,
        "heading_tracking_rms_rad": np.sqrt((heading**2).mean("time")).values,
        "position_error_rms_m": np.sqrt((errors.position**2).sum("earth_axis").mean("time")).values,
        "velocity_error_rms_m_s": np.sqrt((errors.velocity**2).sum("body_axis").mean("time")).values,
        "bias_error_rms_n": np.sqrt((errors.bias_force**2).sum("earth_axis").mean("time")).values,
        "thrust_peak_n": np.abs(force).max("time").values.max(axis=-1),
        "thrust_rms_n": np.sqrt((force**2).mean("time")).values.max(axis=-1),
        "moment_peak_n_m": np.abs(moment).max("time").values,
        "time_saturated": saturated.mean(axis=-1),
        "estimate_error_max_m": worst_estimate,
        "diverged": ~finite | (worst > DIVERGED_DISTANCE) | (worst_estimate > DIVERGED_DISTANCE),
    }


def _aggregate(metrics: dict[str, np.ndarray], index) -> dict:
    out: dict[str, Any] = {}
    for name, values in metrics.items():
        chosen = np.asarray(values)[index]
        if name == "diverged":
            out[name] = int(chosen.sum())
            continue
        kept = chosen[np.isfinite(chosen)]
        out[name] = {
            "mean": float(kept.mean()) if kept.size else None,
            "std": float(kept.std()) if kept.size > 1 else 0.0,
            "runs": [float(v) for v in chosen],
        }
    return out


# ---------------------------------------------------------------------------------
# the sweep (Fig. 8 claim)


def bias_with_model_error(ds: xr.Dataset, config: Config) -> xr.Dataset:
    """The force the observer's bias state stands for: the bias plus the model error.

    The observer's model is M nu' = -D nu + tau + J^T(psi) b (eq. 6 with its own M, D);
    the plant is M_true nu' = -D_true nu + tau + J^T(psi) b + F. Along the true motion the
    observer's model holds exactly with b replaced by

        b + J(psi) [F + (M - M_true) nu' + (D - D_true) nu],   nu' from the plant,

    computed here from the recorded true state and applied thrust and the plant's true
    M, D and F (:class:`ModelError`). The bias state can follow it only below the corner
    of its loop, lambda/kappa = H3/H4 per axis (the zero of hB, :func:`gain_sets`), so
    the result is passed through a first-order low-pass at that corner. Returns
    ``bias_force_with_model_error`` (run, time, earth_axis; N) and
    ``bias_moment_with_model_error`` (run, time; N m).
    """
    from scipy.signal import lfilter

    plant = built_as(build(config).plant, VesselPlant, "the plant")
    model = config.vessel.dp_vessel()
    mass, damping = np.asarray(model.mass_matrix), np.asarray(model.damping_matrix)
    true_mass, true_damping = np.asarray(plant.vessel.mass_matrix), np.asarray(plant.vessel.damping_matrix)
    time = ds.time.values
    heading = ds.heading.values
    nu = np.concatenate([ds.velocity.transpose("run", "time", "body_axis").values, ds.yaw_rate.values[..., None]], axis=-1)
    tau = np.concatenate([ds.force_applied.transpose("run", "time", "body_axis").values, ds.moment_applied.values[..., None]], axis=-1)
    bias = np.concatenate([ds.bias_force.transpose("run", "time", "earth_axis").values, ds.bias_moment.values[..., None]], axis=-1)
    error = config.model_error
    force = error.disturbance()
    force = np.asarray(force.constant)[None, :] + np.asarray(force.amplitude)[None, :] * np.sin(2.0 * math.pi * time[:, None] / error.force_period)
    cos, sin = np.cos(heading), np.sin(heading)
    body_bias = np.stack([cos * bias[..., 0] + sin * bias[..., 1], -sin * bias[..., 0] + cos * bias[..., 1], bias[..., 2]], axis=-1)
    acceleration = np.einsum("ij,...j->...i", np.linalg.inv(true_mass), tau + force + body_bias - np.einsum("ij,...j->...i", true_damping, nu))
    body = force + np.einsum("ij,...j->...i", mass - true_mass, acceleration) + np.einsum("ij,...j->...i", damping - true_damping, nu)
    lumped = bias + np.stack([cos * body[..., 0] - sin * body[..., 1], sin * body[..., 0] + cos * body[..., 1], body[..., 2]], axis=-1)
    gains = gain_sets(config.vessel.mass, config.vessel.length)[config.gains]
    corner = np.asarray(gains["bias_injection_gain"], dtype=float) / np.asarray(gains["velocity_injection_gain"], dtype=float)
    step = float(time[1] - time[0])
    filtered = np.empty_like(lumped)
    for axis in range(3):
        weight = 1.0 - math.exp(-corner[axis] * step)
        start = lumped[:, :1, axis]
        filtered[..., axis] = lfilter([weight], [1.0, weight - 1.0], lumped[..., axis], axis=-1, zi=(1.0 - weight) * start)[0]
    long_name = f"bias + model-error force (low-passed at lambda/kappa = {significant(corner[0])} 1/s)"
    attrs = {"frame": ds.bias_force.attrs.get("frame", "Earth-fixed"), "long_name": long_name, "angle": 0}
    return xr.Dataset(
        {
            "bias_force_with_model_error": (("run", "time", "earth_axis"), filtered[..., :2], {**attrs, "units": "N"}),
            "bias_moment_with_model_error": (("run", "time"), filtered[..., 2], {**attrs, "units": "N m"}),
        },
        coords={"run": ds.run.values, "time": time, "earth_axis": ds.earth_axis.values},
    )


def diverged_at(ds: xr.Dataset) -> np.ndarray:
    """Per run, the first time (s) at which it counts as diverged (:func:`closed_loop_metrics`),
    NaN for a run that did not diverge."""
    distance = np.sqrt(((ds.position - ds.position_desired) ** 2).sum("earth_axis")).values
    estimate = np.sqrt(((ds.position_hat - ds.position) ** 2).sum("earth_axis")).values
    bad = ~np.isfinite(distance) | ~np.isfinite(estimate) | (distance > DIVERGED_DISTANCE) | (estimate > DIVERGED_DISTANCE)
    time = ds.time.values
    return np.where(bad.any(axis=-1), time[np.argmax(bad, axis=-1)], np.nan)
