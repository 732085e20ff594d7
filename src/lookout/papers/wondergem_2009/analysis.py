"""What the reproduction measures: the tracking errors and the error index (43), per-lap
errors and thrust, the reference's bounds and thrust, and the gain conditions of
Section 3 at the configured start."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import xarray as xr

from lookout.models.cybership import CYBERSHIP_THRUST_LIMIT, cybership2
from lookout.papers._reproduction import built_as
from lookout.papers.wondergem_2009.composition import scenario
from lookout.papers.wondergem_2009.config import (
    DAMPING_RATIO,
    INITIAL_ETA,
    INITIAL_ETA_HAT,
    LAP_SPEEDS,
    NATURAL_FREQUENCY,
    OBSERVER_POSITION_GAIN,
    OBSERVER_VELOCITY_GAIN,
    VELOCITY_BOUND,
    Config,
)
from lookout.reference import EllipseReference

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.analysis.tracking import GainProposal

#: Phases of the reference sampled over the four laps (for its bounds and thrust).
REFERENCE_POINTS = 4000


def tracking_errors(ds: xr.Dataset) -> xr.Dataset:
    """Body-frame position errors [e_xb, e_yb] = J^T(psi) [x - x_ref, y - y_ref] and the
    heading error e_psi = ssa(psi - psi_ref) of the true motion (the error index's terms)."""
    dx = ds.position - ds.position_desired
    c, s = np.cos(ds.heading), np.sin(ds.heading)
    north, east = dx.isel(earth_axis=0, drop=True), dx.isel(earth_axis=1, drop=True)
    return xr.Dataset(
        {
            "surge_error": c * north + s * east,
            "sway_error": -s * north + c * east,
            "heading_error": np.arctan2(np.sin(ds.heading - ds.heading_desired), np.cos(ds.heading - ds.heading_desired)),
        }
    )


def error_index(
    time: npt.ArrayLike,
    surge_error: npt.ArrayLike,
    sway_error: npt.ArrayLike,
    heading_error: npt.ArrayLike,
    start: float = 0.0,
    end: float | None = None,
) -> np.ndarray | np.float64:
    """Wondergem et al. (2009), eq. (43): EI = 1/(t2 - t1) int_t1^t2 (e_xb^2 + e_yb^2 + e_psi^2) dt,
    by the trapezoidal rule over the samples in [t1, t2] (last axis time; a scalar for one
    run's errors). Units are mixed (m^2 + rad^2), as in the paper."""
    time = np.asarray(time, dtype=float)
    end = time[-1] if end is None else end
    if not (np.isfinite(start) and np.isfinite(end) and end > start):
        raise ValueError(f"error_index needs start < end; got {start!r}, {end!r}")
    inside = (time >= start - 1e-9) & (time <= end + 1e-9)
    if inside.sum() < 2:
        raise ValueError("error_index needs at least two samples in [start, end]")
    square = np.asarray(surge_error) ** 2 + np.asarray(sway_error) ** 2 + np.asarray(heading_error) ** 2
    t = time[inside]
    return np.trapezoid(square[..., inside], t, axis=-1) / (t[-1] - t[0])


def lap_times(config: Config) -> np.ndarray:
    """End time of each lap (s) for the configured ellipse."""
    perimeter = EllipseReference(config.semi_axes, LAP_SPEEDS).perimeter()
    return np.cumsum(perimeter / np.asarray(LAP_SPEEDS))


def loop_metrics(ds: xr.Dataset, config: Config) -> dict:
    """Per run: EI (43) over [0, T], RMS position error per lap, time some axis is
    commanded beyond the basin's limit, peak thrust commanded and applied."""
    errors = tracking_errors(ds)
    time = ds.time.values
    index = error_index(time, errors.surge_error.values, errors.sway_error.values, errors.heading_error.values)
    laps = np.concatenate([[0.0], lap_times(config)])
    per_lap = []
    for k in range(len(LAP_SPEEDS)):
        inside = (time >= laps[k]) & (time < min(laps[k + 1], time[-1] + 1e-9))
        if inside.sum() < 2:
            per_lap.append(np.full(ds.sizes["run"], np.nan))
            continue
        distance = (errors.surge_error**2 + errors.sway_error**2).values[:, inside]
        per_lap.append(np.sqrt(distance.mean(axis=-1)))
    applied = np.concatenate([ds.force_applied.values, ds.moment_applied.values[..., None]], axis=-1)
    commanded = np.concatenate([ds.force_commanded.values, ds.moment_commanded.values[..., None]], axis=-1)
    saturated = np.any(np.abs(commanded) > np.asarray(CYBERSHIP_THRUST_LIMIT) + 1e-12, axis=-1)
    dt = float(time[1] - time[0])
    return {
        "error_index": index,
        "lap_position_rms_m": np.stack(per_lap, axis=-1),
        "time_saturated_s": saturated.sum(axis=-1) * dt,
        "thrust_peak_commanded": np.abs(commanded).max(axis=1),
        "thrust_peak_applied": np.abs(applied).max(axis=1),
    }


def _reference_samples(config: Config):
    """eta_ref, nu_ref, nu_ref' on REFERENCE_POINTS phases over the four laps (lap k's speed
    on [theta_0 + 2 pi k, theta_0 + 2 pi (k + 1)))."""
    import jax
    import jax.numpy as jnp

    from lookout.controllers.tracking import reference_velocity

    reference = built_as(scenario(config, "simulation").reference, EllipseReference, "the reference")
    laps = len(LAP_SPEEDS)
    theta = reference.init() + jnp.linspace(0.0, 2.0 * np.pi * laps, REFERENCE_POINTS, endpoint=False)
    eta_ref, nu_ref, nu_ref_rate = jax.vmap(lambda t: reference_velocity(reference.sample(t)))(theta)
    return np.asarray(eta_ref), np.asarray(nu_ref), np.asarray(nu_ref_rate)


def reference_bounds(config: Config) -> dict:
    """The reference's data for Prop. 3.3: r_ref_max, sup ||nu_ref||, sup ||nu_ref'|| over the
    four laps (the smooth part: the speed steps between laps are impulses in nu_ref',
    outside the proposition's bounded-acceleration assumption), and eta_ref, nu_ref at t_0."""
    from lookout.controllers.tracking import reference_velocity

    _, nu_ref, nu_ref_rate = _reference_samples(config)
    reference = built_as(scenario(config, "simulation").reference, EllipseReference, "the reference")
    eta_ref0, nu_ref0, _ = reference_velocity(reference.sample(reference.init()))
    return {
        "yaw_rate_max": float(np.abs(nu_ref[:, 2]).max()),
        "speed_max": float(np.linalg.norm(nu_ref, axis=1).max()),
        "acceleration_max": float(np.linalg.norm(nu_ref_rate, axis=1).max()),
        "position0": np.asarray(eta_ref0),
        "velocity0": np.asarray(nu_ref0),
    }


def reference_thrust(config: Config) -> dict:
    """Is the chosen ellipse feasible under the thrust limits? The thrust that holds the true
    ship (39) exactly on the reference, tau_ref = M nu_ref' + C(nu_ref) nu_ref + D(nu_ref) nu_ref,
    per DOF over the four laps, and the jump of the printed controller's damping term
    Kd (nu_ref^+ - nu_ref^-) when the speed steps between laps; each as a fraction of the
    limit (feasible below 1)."""
    import jax

    from lookout.controllers.tracking import TrackingController

    ship = cybership2()
    _, nu_ref, nu_ref_rate = _reference_samples(config)
    M = np.asarray(ship.mass_matrix)
    coriolis = np.asarray(jax.vmap(lambda nu: ship.coriolis(nu) @ nu)(nu_ref))
    damping = np.asarray(jax.vmap(ship.damping_force)(nu_ref))
    tau = nu_ref_rate @ M.T + coriolis + damping
    limit = np.asarray(CYBERSHIP_THRUST_LIMIT)
    Kd = np.asarray(built_as(scenario(config, "simulation").controller, TrackingController, "the controller").damping_gain)
    per_lap = len(nu_ref) // len(LAP_SPEEDS)
    steps = [np.abs(Kd @ (nu_ref[k * per_lap] - nu_ref[k * per_lap - 1])) for k in range(1, len(LAP_SPEEDS))]
    step_peak = np.max(steps, axis=0)
    return {
        "steady_peak": np.abs(tau).max(axis=0).tolist(),
        "steady_fraction_of_limit": (np.abs(tau).max(axis=0) / limit).tolist(),
        "lap_step_peak": step_peak.tolist(),
        "lap_step_fraction_of_limit": (step_peak / limit).tolist(),
        "limit": limit.tolist(),
        "feasible": bool(np.all(np.abs(tau).max(axis=0) < limit) and np.all(step_peak < limit)),
    }


def _start(config: Config, estimate: str) -> dict:
    """Initial state and estimates for the gain conditions: 'printed' is Section 5's eta_hat(0)
    and the velocity estimate as the observer's ``init`` makes it; 'measured' starts the
    estimate at the measurement and at rest (eta_hat(0) = eta(0), v_hat(0) = 0)."""
    import jax.numpy as jnp

    if estimate not in ("printed", "measured"):
        raise ValueError(f"estimate must be 'printed' or 'measured'; got {estimate!r}")
    if estimate == "measured":
        return {"eta0": INITIAL_ETA, "nu0": (0.0, 0.0, 0.0), "eta_hat0": INITIAL_ETA, "velocity_hat0": (0.0, 0.0, 0.0)}
    simulated = scenario(config, "simulation")
    y0 = jnp.asarray(INITIAL_ETA)
    start = simulated.observer.output(simulated.observer.init(y0, simulated.initial_estimate), y0)
    return {
        "eta0": INITIAL_ETA,
        "nu0": (0.0, 0.0, 0.0),
        "eta_hat0": INITIAL_ETA_HAT,
        "velocity_hat0": np.append(np.asarray(start["position_rate"]), float(start["heading_rate"])),
    }


def _reference_arguments(config: Config, bounds: dict | None) -> dict:
    """The reference's data as the keyword arguments of the gain conditions and the search
    (``bounds`` from :func:`reference_bounds`, computed here when not given)."""
    bounds = reference_bounds(config) if bounds is None else bounds
    return {
        "reference_position0": bounds["position0"],
        "reference_velocity0": bounds["velocity0"],
        "yaw_rate_max": bounds["yaw_rate_max"],
        "reference_speed_max": bounds["speed_max"],
        "reference_acceleration_max": bounds["acceleration_max"],
    }


def gain_conditions(
    config: Config,
    velocity_bound: float = VELOCITY_BOUND,
    *,
    estimate: str = "printed",
    gains: dict | None = None,
    epsilon3: float | None = None,
    bounds: dict | None = None,
) -> Report:
    """Conditions (25), Prop. 3.1 and Prop. 3.3
    (:func:`lookout.analysis.tracking.check_wondergem_2009`) at the configured start, for
    the printed gains or ``gains`` (keys L1, L2, natural_frequency, damping_ratio)."""
    from lookout.analysis.tracking import check_wondergem_2009

    chosen = {
        "L1": OBSERVER_POSITION_GAIN,
        "L2": OBSERVER_VELOCITY_GAIN,
        "natural_frequency": NATURAL_FREQUENCY,
        "damping_ratio": DAMPING_RATIO,
        **(gains or {}),
    }
    return check_wondergem_2009(
        cybership2(),
        observer_gains=(chosen["L1"], chosen["L2"]),
        natural_frequency=chosen["natural_frequency"],
        damping_ratio=chosen["damping_ratio"],
        **_start(config, estimate),
        **_reference_arguments(config, bounds),
        velocity_bound=velocity_bound,
        epsilon3=epsilon3,
    )


def proposed_gains(
    config: Config,
    velocity_bound: float = VELOCITY_BOUND,
    *,
    estimate: str = "measured",
    damping_ratio: float = DAMPING_RATIO,
    bounds: dict | None = None,
) -> GainProposal:
    """:func:`lookout.analysis.tracking.propose_wondergem_2009` at the configured start."""
    from lookout.analysis.tracking import propose_wondergem_2009

    return propose_wondergem_2009(
        cybership2(),
        damping_ratio=damping_ratio,
        **_start(config, estimate),
        **_reference_arguments(config, bounds),
        velocity_bound=velocity_bound,
    )


def gain_study(config: Config) -> dict:
    """summary.json's gain part: the printed gains at the printed start and with the
    estimate started at the measurement, the search's proposal (a report: the check of the
    gains found, the search's numbers in ``quantities["proposal"]``), and the ellipse's thrust."""
    bounds = reference_bounds(config)
    proposal = proposed_gains(config, bounds=bounds)
    return {
        "gain_conditions": gain_conditions(config, bounds=bounds).to_dict(),
        "gain_conditions_measured_start": gain_conditions(config, estimate="measured", bounds=bounds).to_dict(),
        "gain_proposal": proposal.outcome().to_dict(),
        "reference_thrust": reference_thrust(config),
    }
