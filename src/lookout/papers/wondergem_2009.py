"""Wondergem, Lefeber, Pettersen & Nijmeijer (2009): output-feedback tracking of Cybership II
around an ellipse (Section 5, Table 1).

Three conditions:

* ``simulation``: the paper's initial conditions and gains, plant and scheme with the
  same model (39) (D_n in both), no noise, the observer integrated with the plant and
  the controller sampled at 0.01 s; Table 1's simulation row (9.3056e-2 over 714.2 s).
* ``basin-calm``: the basin as we rebuild it in simulation: D_n in the plant only (the
  basin scheme used linear damping), thrust limits 2 N, 1.5 N, 1.5 N m, observer and
  controller by forward Euler at 0.05 s (20 Hz), position and heading measured at
  10 Hz (the basin's 9 Hz rounded to a multiple of 0.05 s) with noise; Table 1's
  experiment without waves (0.11145 over 715.1 s).
* ``basin-waves``: the same plus JONSWAP waves (Hs = 0.01 m, mean period 0.75 s,
  gamma = 3.3) as first-order motion added to the measurement; Table 1's experiment
  with waves (0.12686 over 730.6 s).

Chosen where the paper is silent (docs/reproductions.md): the ellipse a = 3.5 m,
b = 1.823 m (perimeter 17.14 m, so four laps at 0.05, 0.1, 0.15, 0.2 m/s take 714.2 s),
centre (0, 0), start at theta_0 = 0 with the yaw rate positive (psi_ref(0) = pi/2 =
psi_0); the printed initial velocity estimate [0.5, 0.5, -0.5] taken as v_hat(0) =
eta_hat'(0); measurement noise 2 mm and 0.1 deg; waves travelling along +x.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

import numpy as np
import xarray as xr
from pydantic import Field, ValidationInfo, field_validator

from lookout.actuators import SaturatingActuator
from lookout.controllers.tracking import TrackingController
from lookout.models.cybership import CYBERSHIP_THRUST_LIMIT, CybershipPlant, CybershipState, cybership2
from lookout.observers.earth_fixed import EarthFixedObserver
from lookout.settings import RunsConfig
from lookout.papers import CATALOG
from lookout.papers._report import Table, save_figures, significant, write_summary
from lookout.reference import EllipseReference
from lookout.results import write_netcdf
from lookout.sensors import PositionHeadingSensor
from lookout.sim import Scenario, keys_of_seeds, simulate_batch, stack_scenarios

NAME = "wondergem-2009"
TITLE = CATALOG[NAME].title
CONDITIONS = ("simulation", "basin-calm", "basin-waves")
#: Table 1: error index (43) and its horizon t2 (s), t1 = 0.
TABLE_1 = {"simulation": (9.3056e-2, 714.2), "basin-calm": (0.11145, 715.1), "basin-waves": (0.12686, 730.6)}
LAP_SPEEDS = (0.05, 0.10, 0.15, 0.20)
#: Initial conditions of Section 5.
INITIAL_ETA = (3.8, -1.2, 0.5 * math.pi)
INITIAL_ETA_HAT = (4.0, -1.0, 2.94)
INITIAL_VELOCITY_HAT = (0.5, 0.5, -0.5)
PLANT_STEP = 0.01
BASIN_PERIOD = 0.05
BASIN_MEASUREMENT_PERIOD = 0.1


class Config(RunsConfig):
    """Settings of the reproduction; every field has the paper's value or a stated choice."""

    conditions: tuple[str, ...] = Field(CONDITIONS, description="which of simulation, basin-calm, basin-waves to run")
    runs: int = Field(1, description="runs per condition (vmapped); run i uses seed + i")
    seed: int = Field(0, description="PRNG seed of run 0")
    duration: float = Field(714.2, description="simulated time (s); Table 1's simulation horizon")
    semi_axes: tuple[float, float] = Field((3.5, 1.823), description="ellipse semi-axes a (north), b (east) in m")
    start_angle: float = Field(0.0, description="theta_0 (rad) of the start on the ellipse")
    direction: int = Field(1, description="1: yaw rate positive, -1: negative")
    initial_velocity: str = Field("estimate", description="the printed [0.5, 0.5, -0.5] is v_hat(0) ('estimate') or zeta(0) ('state')")
    noise_std: tuple[float, float, float] = Field((0.002, 0.002, float(np.radians(0.1))), description="basin measurement noise (m, m, rad)")
    wave_height: float = Field(0.01, description="significant wave height Hs (m), basin-waves")
    wave_period: float = Field(0.75, description="JONSWAP mean period T1 (s), basin-waves")
    sweep: bool = Field(True, description="sweep the choices the paper leaves open (start, direction, initial velocity, saturation) and run the measurement-hold study")

    @field_validator("conditions")
    @classmethod
    def _conditions(cls, value):
        if not value or any(c not in CONDITIONS for c in value) or len(set(value)) != len(value):
            raise ValueError(f"must be distinct names from {', '.join(CONDITIONS)}; got {', '.join(value) or 'none'}")
        return tuple(value)

    @field_validator("duration")
    @classmethod
    def _duration(cls, value):
        if not (math.isfinite(value) and 10.0 <= value <= 3600.0):
            raise ValueError(f"must be between 10 s and 3600 s; got {value:g}")
        if abs(value / BASIN_MEASUREMENT_PERIOD - round(value / BASIN_MEASUREMENT_PERIOD)) > 1e-9 * value / BASIN_MEASUREMENT_PERIOD:
            raise ValueError(f"must be a whole multiple of the 0.1 s measurement period; got {value:g}")
        return value

    @field_validator("semi_axes")
    @classmethod
    def _axes(cls, value):
        if not all(math.isfinite(v) and v > 0 for v in value):
            raise ValueError(f"must be finite and positive (m); got {value}")
        return value

    @field_validator("direction")
    @classmethod
    def _direction(cls, value):
        if value not in (1, -1):
            raise ValueError(f"must be 1 or -1; got {value}")
        return value

    @field_validator("initial_velocity")
    @classmethod
    def _initial_velocity(cls, value):
        if value not in ("estimate", "state"):
            raise ValueError(f"must be 'estimate' or 'state'; got {value!r}")
        return value

    @field_validator("noise_std")
    @classmethod
    def _noise(cls, value):
        if not all(math.isfinite(v) and v >= 0 for v in value):
            raise ValueError(f"must be finite and >= 0; got {value}")
        return value

    @field_validator("wave_height", "wave_period", "start_angle")
    @classmethod
    def _finite(cls, value, info: ValidationInfo):
        if not math.isfinite(value) or (info.field_name != "start_angle" and value < 0) or (info.field_name == "wave_period" and value == 0):
            raise ValueError(f"must be finite{' and positive' if info.field_name == 'wave_period' else ''}{' and >= 0' if info.field_name == 'wave_height' else ''}; got {value:g}")
        return value



def build(config: Config, condition: str = "simulation", *, start_angle=None, direction=None, initial_velocity=None, saturate=None) -> Scenario:
    """The closed loop of Section 5 under one condition (module docstring); keyword
    arguments override the config's choices (the sweep's variables)."""
    if condition not in CONDITIONS:
        raise ValueError(f"condition must be one of {', '.join(CONDITIONS)}; got {condition!r}")
    true_ship = cybership2()
    basin = condition != "simulation"
    scheme_ship = true_ship.linear() if basin else true_ship
    observer = EarthFixedObserver(
        scheme_ship, 15.0, 50.0, method="euler" if basin else "rk4",
        initial_velocity=config.initial_velocity if initial_velocity is None else initial_velocity,
    )
    controller = TrackingController(scheme_ship, natural_frequency=(0.72, 0.42, 0.64), damping_ratio=1.0)
    reference = EllipseReference(
        config.semi_axes, LAP_SPEEDS,
        start_angle=config.start_angle if start_angle is None else start_angle,
        direction=config.direction if direction is None else direction,
    )
    waves = None
    if condition == "basin-waves" and config.wave_height > 0:
        from lookout.environment import JonswapWaves

        waves = JonswapWaves(config.wave_height, config.wave_period)
    plant = CybershipPlant(true_ship, waves)
    saturate = basin if saturate is None else saturate
    actuator = SaturatingActuator(CYBERSHIP_THRUST_LIMIT if saturate else (math.inf,) * 3)
    if basin:
        sensor = PositionHeadingSensor(config.noise_std, BASIN_MEASUREMENT_PERIOD)
        period = BASIN_PERIOD
    else:
        sensor = PositionHeadingSensor((0.0, 0.0, 0.0), PLANT_STEP)
        period = PLANT_STEP
    return Scenario(
        plant, sensor, observer, controller,
        CybershipState.build(eta=INITIAL_ETA), observer.guess(eta=INITIAL_ETA_HAT, velocity=INITIAL_VELOCITY_HAT),
        plant_step=PLANT_STEP, sample_period=period, duration=config.duration, reference=reference, actuator=actuator,
        observer_mode="sampled" if basin else "continuous",
        record_every=1 if basin else 10,  # every 0.05 s step: the 10 Hz hold makes thrust alternate at 10 Hz
    )


#: The scenarios a scenario file can name as its ``case`` (one per condition); the first is the
#: default. See :mod:`lookout.studies.scenario_file`.
CASES: tuple[str, ...] = CONDITIONS

#: :func:`run` vmaps its runs over scenarios stacked per run (see :mod:`lookout.studies.scenario_file`).
STACKED_BATCHES = True


def case_scenario(config: Config, case: str) -> Scenario:
    """The scenario of ``case`` (one of :data:`CASES`) for ``config``, as :func:`run` simulates it."""
    return build(config, case)


def scenarios(config: Config) -> list[Scenario]:
    """The scenarios :func:`run` simulates (one per condition), for estimates before running."""
    return [build(config, condition) for condition in config.conditions]


# ---------------------------------------------------------------------------------
# metrics


def tracking_errors(ds: xr.Dataset) -> xr.Dataset:
    """Body-frame position errors [e_xb, e_yb] = J^T(psi) [x - x_ref, y - y_ref] and the
    heading error e_psi = ssa(psi - psi_ref) of the true motion (the error index's terms)."""
    dx = ds.position - ds.position_desired
    c, s = np.cos(ds.heading), np.sin(ds.heading)
    north, east = dx.isel(earth_axis=0, drop=True), dx.isel(earth_axis=1, drop=True)
    return xr.Dataset({
        "surge_error": c * north + s * east,
        "sway_error": -s * north + c * east,
        "heading_error": np.arctan2(np.sin(ds.heading - ds.heading_desired), np.cos(ds.heading - ds.heading_desired)),
    })


def error_index(time, surge_error, sway_error, heading_error, start=0.0, end=None) -> np.ndarray:
    """Wondergem et al. (2009), eq. (43): EI = 1/(t2 - t1) int_t1^t2 (e_xb^2 + e_yb^2 + e_psi^2) dt,
    by the trapezoidal rule over the samples in [t1, t2] (last axis time). Units are mixed
    (m^2 + rad^2), as in the paper."""
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
    """Per run: EI over [0, T], RMS errors per lap, time saturated, peak thrust."""
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


REFERENCE_POINTS = 4000


def _reference_samples(config: Config):
    """eta_ref, nu_ref, nu_ref' on REFERENCE_POINTS phases over the four laps (lap k's speed
    on [theta_0 + 2 pi k, theta_0 + 2 pi (k + 1)))."""
    import jax
    import jax.numpy as jnp

    from lookout.controllers.tracking import reference_velocity

    reference = build(config, "simulation").reference
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
    reference = build(config, "simulation").reference
    eta_ref0, nu_ref0, _ = reference_velocity(reference.sample(reference.init()))
    return {
        "yaw_rate_max": float(np.abs(nu_ref[:, 2]).max()),
        "speed_max": float(np.linalg.norm(nu_ref, axis=1).max()),
        "acceleration_max": float(np.linalg.norm(nu_ref_rate, axis=1).max()),
        "position0": np.asarray(eta_ref0), "velocity0": np.asarray(nu_ref0),
    }


def reference_thrust(config: Config) -> dict:
    """Is the chosen ellipse feasible under the thrust limits? The thrust that holds the true
    ship (39) exactly on the reference, tau_ref = M nu_ref' + C(nu_ref) nu_ref + D(nu_ref) nu_ref,
    per DOF over the four laps, and the jump of the printed controller's damping term
    Kd (nu_ref^+ - nu_ref^-) when the speed steps between laps; each as a fraction of the
    limit (feasible below 1)."""
    import jax

    ship = cybership2()
    _, nu_ref, nu_ref_rate = _reference_samples(config)
    M = np.asarray(ship.mass_matrix)
    coriolis = np.asarray(jax.vmap(lambda nu: ship.coriolis(nu) @ nu)(nu_ref))
    damping = np.asarray(jax.vmap(ship.damping_force)(nu_ref))
    tau = nu_ref_rate @ M.T + coriolis + damping
    limit = np.asarray(CYBERSHIP_THRUST_LIMIT)
    controller = build(config, "simulation").controller
    Kd = np.asarray(controller.damping_gain)
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
    scenario = build(config, "simulation")
    y0 = jnp.asarray(INITIAL_ETA)
    start = scenario.observer.output(scenario.observer.init(y0, scenario.initial_estimate), y0)
    return {"eta0": INITIAL_ETA, "nu0": (0.0, 0.0, 0.0), "eta_hat0": INITIAL_ETA_HAT,
            "velocity_hat0": np.append(np.asarray(start["position_rate"]), float(start["heading_rate"]))}


def _reference_arguments(config: Config, bounds: dict | None) -> dict:
    """The reference's data as the keyword arguments of the gain conditions and the search
    (``bounds`` from :func:`reference_bounds`, computed here when not given)."""
    bounds = reference_bounds(config) if bounds is None else bounds
    return {
        "reference_position0": bounds["position0"], "reference_velocity0": bounds["velocity0"], "yaw_rate_max": bounds["yaw_rate_max"],
        "reference_speed_max": bounds["speed_max"], "reference_acceleration_max": bounds["acceleration_max"],
    }


def gain_conditions(config: Config, velocity_bound: float = 0.3, *, estimate: str = "printed", gains: dict | None = None, epsilon3=None,
                    bounds: dict | None = None):
    """Conditions (25), Prop. 3.1 and Prop. 3.3
    (:func:`lookout.analysis.tracking.check_wondergem_2009`) at the configured start, for
    the printed gains or ``gains`` (keys L1, L2, natural_frequency, damping_ratio)."""
    from lookout.analysis.tracking import check_wondergem_2009

    chosen = {"L1": 15.0, "L2": 50.0, "natural_frequency": (0.72, 0.42, 0.64), "damping_ratio": 1.0, **(gains or {})}
    return check_wondergem_2009(
        cybership2(), observer_gains=(chosen["L1"], chosen["L2"]),
        natural_frequency=chosen["natural_frequency"], damping_ratio=chosen["damping_ratio"], **_start(config, estimate),
        **_reference_arguments(config, bounds), velocity_bound=velocity_bound, epsilon3=epsilon3,
    )


def gain_study(config: Config) -> dict:
    """summary.json's gain part: the printed gains at the printed start and with the
    estimate started at the measurement, the search's proposal, and the ellipse's thrust."""
    bounds = reference_bounds(config)
    proposal = proposed_gains(config, bounds=bounds)
    return {
        "gain_conditions": gain_conditions(config, bounds=bounds).to_dict(),
        "gain_conditions_measured_start": gain_conditions(config, estimate="measured", bounds=bounds).to_dict(),
        "gain_proposal": proposal.to_dict(),
        "reference_thrust": reference_thrust(config),
    }


def proposed_gains(config: Config, velocity_bound: float = 0.3, *, estimate: str = "measured", damping_ratio: float = 1.0,
                   bounds: dict | None = None):
    """:func:`lookout.analysis.tracking.propose_wondergem_2009` at the configured start."""
    from lookout.analysis.tracking import propose_wondergem_2009

    return propose_wondergem_2009(
        cybership2(), damping_ratio=damping_ratio, **_start(config, estimate), **_reference_arguments(config, bounds),
        velocity_bound=velocity_bound,
    )


# ---------------------------------------------------------------------------------
# the choices the paper leaves open


SWEEP_STARTS = (0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi)


def choice_sweep(config: Config, condition: str = "simulation") -> xr.Dataset:
    """EI over the choices the paper does not give, as one vmapped batch: start angle on
    the ellipse, direction, which state receives the printed velocity estimate, and the
    thrust limits on or off."""
    cases = [
        (start, direction, velocity, saturate)
        for start in SWEEP_STARTS
        for direction in (1, -1)
        for velocity in ("estimate", "state")
        for saturate in (False, True)
    ]
    scenario = stack_scenarios([
        build(config, condition, start_angle=start, direction=direction, initial_velocity=velocity, saturate=saturate)
        for start, direction, velocity, saturate in cases
    ])
    ds = simulate_batch(scenario, keys_of_seeds([config.seed] * len(cases)), batched_scenario=True).to_xarray()
    metrics = loop_metrics(ds, config)
    shape = (len(SWEEP_STARTS), 2, 2, 2)
    return xr.Dataset(
        {
            "error_index": (("start_angle", "direction", "initial_velocity", "saturation"), metrics["error_index"].reshape(shape)),
            "time_saturated_s": (("start_angle", "direction", "initial_velocity", "saturation"), metrics["time_saturated_s"].reshape(shape)),
        },
        coords={"start_angle": list(SWEEP_STARTS), "direction": [1, -1], "initial_velocity": ["estimate", "state"], "saturation": ["off", "on"]},
        attrs={"title": f"{NAME}: error index (43) over the choices the paper leaves open ({condition})", "condition": condition, "duration_s": config.duration},
    )


#: The hold study: (label, measurement period (s), noise on, thrust limits on).
HOLD_CASES = (
    ("10 Hz held", BASIN_MEASUREMENT_PERIOD, False, True),
    ("10 Hz held, noise", BASIN_MEASUREMENT_PERIOD, True, True),
    ("10 Hz held, no limits", BASIN_MEASUREMENT_PERIOD, False, False),
    ("20 Hz", BASIN_PERIOD, False, True),
    ("20 Hz, noise", BASIN_PERIOD, True, True),
)


def hold_study(config: Config) -> list[dict]:
    """basin-calm with the 10 Hz measurement held over the scheme's two 20 Hz steps, against
    20 Hz measurements, with and without noise and thrust limits (seed ``config.seed``): the
    lap-4 mean body-frame errors (after its first 20 s; None when the run ends before), EI,
    time beyond a limit, and the mean step-to-step change of the commanded surge force after
    t = 20 s (large when it alternates at 10 Hz). One batch per
    measurement rate (the rate fixes the loop structure)."""
    import dataclasses

    quiet = (0.0, 0.0, 0.0)
    rows = []
    for period in (BASIN_MEASUREMENT_PERIOD, BASIN_PERIOD):
        cases = [case for case in HOLD_CASES if case[1] == period]
        scenarios_ = []
        for _, _, noisy, limited in cases:
            scenario = build(config.model_copy(update={"noise_std": config.noise_std if noisy else quiet}), "basin-calm", saturate=limited)
            scenarios_.append(dataclasses.replace(scenario, sensor=PositionHeadingSensor(config.noise_std if noisy else quiet, period)))
        ds = simulate_batch(stack_scenarios(scenarios_), keys_of_seeds([config.seed] * len(cases)), batched_scenario=True).to_xarray()
        errors = tracking_errors(ds)
        metrics = loop_metrics(ds, config)
        time = ds.time.values
        laps = lap_times(config)
        lap4 = (time > laps[-2] + 20.0) & (time < laps[-1])
        for i, (label, _, noisy, limited) in enumerate(cases):
            surge_force = ds.force_commanded.values[i, time > 20.0, 0]
            rows.append({
                "case": label, "measurement_period_s": period, "noise": noisy, "thrust_limits": limited,
                "lap4_surge_error_m": float(errors.surge_error.values[i, lap4].mean()) if lap4.any() else None,
                "lap4_sway_error_m": float(errors.sway_error.values[i, lap4].mean()) if lap4.any() else None,
                "surge_command_step_N": float(np.abs(np.diff(surge_force)).mean()),
                "error_index": float(metrics["error_index"][i]), "time_beyond_limit_s": float(metrics["time_saturated_s"][i]),
            })
    return rows


# ---------------------------------------------------------------------------------
# figures


#: The first seconds of a run, where the initial estimate converges: zoomed in the
#: velocity figures and left out of their full-run scale.
START_WINDOW = 30.0


def _figures(results: dict[str, xr.Dataset], config: Config, out: Path) -> list[str]:
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_estimates

    colors = {"simulation": "tab:blue", "basin-calm": "tab:orange", "basin-waves": "tab:green"}
    figures = {}
    figure, axis = plt.subplots(figsize=(7, 5))
    first = next(iter(results.values())).isel(run=0)
    axis.plot(first.position_desired.isel(earth_axis=1), first.position_desired.isel(earth_axis=0), "k--", lw=1.0, label="reference ellipse")
    for condition, ds in results.items():
        run = ds.isel(run=0)
        axis.plot(run.position.isel(earth_axis=1), run.position.isel(earth_axis=0), color=colors[condition], lw=0.9, label=condition)
    axis.plot(INITIAL_ETA[1], INITIAL_ETA[0], "ko", ms=4, label="start")
    axis.set_xlabel("east y (m)")
    axis.set_ylabel("north x (m)")
    axis.set_aspect("equal")
    axis.legend(fontsize=8)
    axis.set_title("Wondergem et al. (2009): the track around the ellipse (run 0)", fontsize=10)
    figure.tight_layout()
    figures["track.png"] = figure

    figure, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for condition, ds in results.items():
        errors = tracking_errors(ds.isel(run=0))
        for axis, name, unit in zip(axes, ("surge_error", "sway_error", "heading_error"), ("m", "m", "rad")):
            axis.plot(ds.time, errors[name], color=colors[condition], lw=0.8, label=condition)
            axis.set_ylabel(f"{name.split('_')[0]} error ({unit})")
    for lap_end in lap_times(config)[:-1]:
        for axis in axes:
            axis.axvline(lap_end, color="0.6", lw=0.6, ls=":")
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")
    figure.suptitle("Body-frame tracking errors (true motion; dotted: lap ends, speed steps)", fontsize=10)
    figure.tight_layout()
    figures["errors.png"] = figure

    # true and estimated velocities, one figure per condition (overlaid, the conditions hid
    # each other): the start, where the initial estimate is far off, in a zoom of its own
    # and left out of the full run's scale; a second zoom around the last speed step
    last_step = float(lap_times(config)[-2])
    for condition, ds in results.items():
        seeded = ds.assign_coords(seed=("run", np.asarray(config.seeds[: ds.sizes["run"]], dtype=np.int64)))
        end = float(ds.time[-1])
        windows = [(0.0, min(START_WINDOW, end))]
        if last_step + 10.0 <= end and last_step - 10.0 > START_WINDOW:
            windows.append((last_step - 10.0, last_step + 10.0))
        figures[f"velocities_{condition.replace('-', '_')}.png"] = plot_estimates(
            seeded,
            [("velocity", "surge"), ("velocity", "sway"), ("yaw_rate", None)],
            window=windows,
            transient=min(START_WINDOW, 0.5 * end),
            title=(
                f"Wondergem et al. (2009): true and estimated body-fixed velocities, {condition}\n"
                f"initial estimate v_hat(0) = {list(INITIAL_VELOCITY_HAT)}; zooms: the start and the last speed step (t = {last_step:.1f} s)"
            ),
        )

    figure, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for condition, ds in results.items():
        run = ds.isel(run=0)
        samples = max(1, int(round(1.0 / float(run.time[1] - run.time[0]))))  # 1 s
        for k, (axis, label) in enumerate(zip(axes, ("surge force (N)", "sway force (N)", "yaw moment (N m)"))):
            applied = run.force_applied.isel(body_axis=k) if k < 2 else run.moment_applied
            axis.plot(run.time, applied, color=colors[condition], lw=0.4, alpha=0.25)
            mean = applied.rolling(time=samples, center=True).mean()
            axis.plot(run.time, mean, color=colors[condition], lw=1.0, label=f"{condition}: 1 s mean (light: every sample)")
            axis.set_ylabel(label)
    for axis, limit in zip(axes, CYBERSHIP_THRUST_LIMIT):
        axis.axhline(limit, color="k", lw=0.6, ls=":")
        axis.axhline(-limit, color="k", lw=0.6, ls=":")
        axis.set_ylim(-3 * limit, 3 * limit)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("time (s)")
    figure.suptitle("Applied thrust (dotted: the basin's limits; the simulation condition has none)", fontsize=10)
    figure.tight_layout()
    figures["thrust.png"] = figure
    return save_figures(figures, out)


# ---------------------------------------------------------------------------------
# run


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate each condition (``runs`` seeds each) and the choice sweep; write NetCDF,
    figures and summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    results, per_condition, files = {}, {}, []
    parts = len(config.conditions) + (1 if config.sweep else 0)
    for index, condition in enumerate(config.conditions):
        scenario = stack_scenarios([build(config, condition) for _ in config.seeds])
        ds = simulate_batch(scenario, keys_of_seeds(config.seeds), batched_scenario=True).to_xarray()
        ds.attrs.update({"reproduction": NAME, "title": TITLE, "condition": condition, "config": config.model_dump_json()})
        filename = f"wondergem_2009_{condition.replace('-', '_')}.nc"
        write_netcdf(ds, out / filename, history=f"lookout reproduce {NAME} ({condition}, seeds {config.seeds[0]}..{config.seeds[-1]})")
        files.append(filename)
        results[condition] = ds
        metrics = loop_metrics(ds, config)
        paper_value, paper_horizon = TABLE_1[condition]
        per_condition[condition] = {
            "error_index": metrics["error_index"].tolist(),
            "table_1": paper_value,
            "table_1_horizon_s": paper_horizon,
            "lap_position_rms_m": metrics["lap_position_rms_m"].tolist(),
            "time_saturated_s": metrics["time_saturated_s"].tolist(),
            "thrust_peak_commanded": metrics["thrust_peak_commanded"].tolist(),
            "thrust_peak_applied": metrics["thrust_peak_applied"].tolist(),
            "status": ds.status.values.tolist(),
        }
        if progress is not None:
            progress(index + 1, parts)
    sweep = None
    if config.sweep:
        sweep = choice_sweep(config)
        sweep.to_netcdf(out / "wondergem_2009_choice_sweep.nc")
        files.append("wondergem_2009_choice_sweep.nc")
        if progress is not None:
            progress(parts, parts)
    hold = hold_study(config) if config.sweep else None
    files += _figures(results, config, out)
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "seeds": config.seeds,
        "ellipse_perimeter_m": EllipseReference(config.semi_axes, LAP_SPEEDS).perimeter(),
        "lap_end_times_s": lap_times(config).tolist(),
        "status": [status for condition in config.conditions for status in per_condition[condition]["status"]],
        "conditions": per_condition,
        "choice_sweep": None if sweep is None else _sweep_summary(sweep),
        "hold_study": hold,
        **gain_study(config),
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def _sweep_summary(sweep: xr.Dataset) -> dict:
    index = sweep.error_index
    result = {
        "condition": sweep.attrs["condition"],
        "min": float(index.min()),
        "max": float(index.max()),
        "by_saturation": {s: {"min": float(index.sel(saturation=s).min()), "max": float(index.sel(saturation=s).max())} for s in ("off", "on")},
        "runs": [],
    }
    for start in sweep.start_angle.values:
        for direction in sweep.direction.values:
            for velocity in sweep.initial_velocity.values:
                for saturation in sweep.saturation.values:
                    cell = dict(start_angle=start, direction=direction, initial_velocity=velocity, saturation=saturation)
                    result["runs"].append({**{k: (v.item() if hasattr(v, "item") else v) for k, v in cell.items()},
                                           "error_index": float(index.sel(**cell)), "time_saturated_s": float(sweep.time_saturated_s.sel(**cell))})
    return result


def tables(summary: dict) -> list[Table]:
    """Error index per condition against Table 1; the choice sweep's range."""
    rows, spreads = [], []
    for condition, values in summary["conditions"].items():
        index = np.asarray(values["error_index"], dtype=float)
        laps = np.asarray(values["lap_position_rms_m"], dtype=float).mean(axis=0)
        spreads.append(f"{condition} {index.min():.3g}-{index.max():.3g}")
        rows.append((
            condition, significant(float(index.mean())), f"{values['table_1']:.5g}",
            "/".join(f"{100 * v:.2g}" if np.isfinite(v) else "-" for v in laps), f"{np.mean(values['time_saturated_s']):.1f}",
        ))
    horizons = ", ".join(f"{values['table_1_horizon_s']:g}" for values in summary["conditions"].values())
    runs = len(summary["seeds"])
    result = [Table(
        f"Error index (43) over [0, {summary['config']['duration']:g}] s",
        ("condition", "EI", "Table 1", "RMS error, laps 1/2/3/4 (cm)", "beyond a limit (s)"),
        tuple(rows),
        f"EI: mean over the runs{' (range: ' + '; '.join(spreads) + ')' if runs > 1 else ''}; Table 1 over its own t2 "
        f"({horizons} s). RMS: body-frame x-y position error.",
    )]
    conditions, measured = summary.get("gain_conditions"), summary.get("gain_conditions_measured_start")
    if conditions and measured:
        sides = {item["name"]: item for item in measured["inequalities"]}
        rows = tuple(
            (item["name"], f"{item['left']:.4g}", f"{item['right']:.4g}", item["verdict"],
             *((f"{sides[item['name']]['right']:.4g}", sides[item["name"]]["verdict"]) if item["name"] in sides else ("-", "-")))
            for item in conditions["inequalities"]
        )
        result.append(Table(
            "Gain conditions for the printed gains: (25), Proposition 3.1 (V_M = 0.3 m/s), Proposition 3.3",
            ("", "left", "right", "verdict", "right, eta_hat0 = eta0", "verdict"), rows,
            "sufficient conditions, at the printed start and with the estimate started at the measurement (v_hat0 = 0)",
        ))
    proposal = summary.get("gain_proposal")
    if proposal and proposal["found"]:
        result.append(Table(
            "Gains the search proposes (eta_hat0 = eta0, v_hat0 = 0): every condition holds",
            ("Omega (rad/s)", "L1 (1/s)", "L2 (1/s2)", "eps3", "Euler step needed (s)"),
            ((f"{proposal['natural_frequency']:.4g} I", f"{proposal['observer_gains']['L1']:.4g}", f"{proposal['observer_gains']['L2']:.4g}",
              f"{proposal['epsilon3']:.3g}", f"{proposal['euler_step_max_s']:.3g}"),),
            "lookout design tracking-gains --propose; the basin runs the scheme at 0.05 s",
        ))
    thrust = summary.get("reference_thrust")
    if thrust:
        result.append(Table(
            "Thrust of the reference, as a fraction of the limits (surge 2 N, sway 1.5 N, yaw 1.5 N m)",
            ("", "surge", "sway", "yaw"),
            (("on the ellipse: M nu_ref' + C nu_ref + D(nu_ref) nu_ref", *(f"{v:.3f}" for v in thrust["steady_fraction_of_limit"])),
             ("speed step between laps: Kd (nu_ref+ - nu_ref-)", *(f"{v:.3f}" for v in thrust["lap_step_fraction_of_limit"]))),
            "feasible below 1 (the initial transient is not included)",
        ))
    if summary.get("hold_study"):
        result.append(Table(
            "basin-calm: the 10 Hz measurement held over two 20 Hz steps, against 20 Hz measurements",
            ("case", "lap 4 e_x, e_y (m)", "EI", "> limit (s)", "|dF| (N)"),
            tuple((row["case"], f"{row['lap4_surge_error_m']:+.3f}, {row['lap4_sway_error_m']:+.3f}", f"{row['error_index']:.3g}",
                   f"{row['time_beyond_limit_s']:.1f}", f"{row['surge_command_step_N']:.2f}")
                  for row in summary["hold_study"] if row["lap4_surge_error_m"] is not None),
            "mean body-frame errors in lap 4 after its first 20 s; > limit: time some axis is commanded beyond its limit; "
            "|dF|: mean step-to-step change of the commanded surge force after 20 s",
        ))
    if summary.get("choice_sweep"):
        sweep = summary["choice_sweep"]
        rows = [(saturation, significant(values["min"]), significant(values["max"])) for saturation, values in sweep["by_saturation"].items()]
        result.append(Table(
            f"EI over the choices the paper leaves open ({sweep['condition']}; {len(sweep['runs'])} runs)",
            ("thrust limits", "min EI", "max EI"), tuple(rows),
            "start on the ellipse (4), direction (2), initial velocity as v_hat or zeta (2)",
        ))
    return result


__all__ = [
    "CONDITIONS", "Config", "TABLE_1", "build", "choice_sweep", "error_index", "gain_conditions", "gain_study", "hold_study", "proposed_gains",
    "reference_bounds", "reference_thrust", "run", "tables", "tracking_errors",
]
