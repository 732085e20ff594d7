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
from lookout.papers._config import RunsConfig
from lookout.papers._report import Table, save_figures, significant, write_summary
from lookout.reference import EllipseReference
from lookout.results import write_netcdf
from lookout.sensors import PositionHeadingSensor
from lookout.sim import Scenario, keys_of_seeds, simulate_batch, stack_scenarios

NAME = "wondergem-2009"
TITLE = "Wondergem, Lefeber, Pettersen & Nijmeijer (2009): output-feedback tracking of Cybership II (Section 5, Table 1)"
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
    sweep: bool = Field(True, description="sweep the choices the paper leaves open (start, direction, initial velocity, saturation)")

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
        record_every=int(round(BASIN_MEASUREMENT_PERIOD / period)) if basin else 10,
    )


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


def gain_conditions(config: Config, velocity_bound: float = 0.3):
    """Conditions (25) and Prop. 3.1 (:func:`lookout.analysis.tracking.check_wondergem_2009`)
    for the simulation condition's gains at the configured start: eta_ref0, nu_ref0 from the
    reference at t_0, r_ref_max the largest |r_ref| over the four laps (1000 points), and
    v_hat(0) as the observer's ``init`` makes it from the guess."""
    import jax
    import jax.numpy as jnp

    from lookout.analysis.tracking import check_wondergem_2009
    from lookout.controllers.tracking import reference_velocity

    scenario = build(config, "simulation")
    observer, controller, reference = scenario.observer, scenario.controller, scenario.reference
    eta_ref0, nu_ref0, _ = reference_velocity(reference.sample(reference.init()))
    theta = config.start_angle + jnp.linspace(0.0, 2.0 * np.pi * len(LAP_SPEEDS), 1001)[:-1]
    yaw_rate = np.abs(np.asarray(jax.vmap(reference.sample)(theta)["heading_desired_rate"]))
    y0 = jnp.asarray(INITIAL_ETA)
    start = observer.output(observer.init(y0, scenario.initial_estimate), y0)
    return check_wondergem_2009(
        scenario.plant.ship, observer_gains=(np.asarray(observer.position_gain), np.asarray(observer.velocity_gain)),
        natural_frequency=np.asarray(controller.natural_frequency), damping_ratio=np.asarray(controller.damping_ratio),
        eta0=INITIAL_ETA, nu0=(0.0, 0.0, 0.0), eta_hat0=INITIAL_ETA_HAT,
        velocity_hat0=np.append(np.asarray(start["position_rate"]), float(start["heading_rate"])),
        reference_position0=np.asarray(eta_ref0), reference_velocity0=np.asarray(nu_ref0), yaw_rate_max=float(yaw_rate.max()),
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


# ---------------------------------------------------------------------------------
# figures


def _figures(results: dict[str, xr.Dataset], config: Config, out: Path) -> list[str]:
    import matplotlib.pyplot as plt

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

    figure, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for condition, ds in results.items():
        run = ds.isel(run=0)
        for k, (axis, label) in enumerate(zip(axes, ("u (m/s)", "v (m/s)", "r (rad/s)"))):
            true = run.velocity.isel(body_axis=k) if k < 2 else run.yaw_rate
            estimate = run.velocity_hat.isel(body_axis=k) if k < 2 else run.yaw_rate_hat
            axis.plot(run.time, true, color=colors[condition], lw=0.9, label=f"{condition} true")
            axis.plot(run.time, estimate, color=colors[condition], lw=0.7, ls="--", label=f"{condition} estimate")
            axis.set_ylabel(label)
    axes[0].legend(fontsize=7, ncol=3)
    axes[-1].set_xlabel("time (s)")
    figure.suptitle("True and estimated body-frame velocities", fontsize=10)
    figure.tight_layout()
    figures["velocities.png"] = figure

    figure, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for condition, ds in results.items():
        run = ds.isel(run=0)
        for k, (axis, label) in enumerate(zip(axes, ("surge force (N)", "sway force (N)", "yaw moment (N m)"))):
            applied = run.force_applied.isel(body_axis=k) if k < 2 else run.moment_applied
            axis.plot(run.time, applied, color=colors[condition], lw=0.7, label=f"{condition} applied")
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
        "gain_conditions": gain_conditions(config).to_dict(),
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
    rows = []
    for condition, values in summary["conditions"].items():
        index = np.asarray(values["error_index"], dtype=float)
        laps = np.asarray(values["lap_position_rms_m"], dtype=float).mean(axis=0)
        rows.append((
            condition, significant(float(index.mean())), f"{values['table_1']:.5g}", f"{values['table_1_horizon_s']:g}",
            " ".join(significant(float(v)) if np.isfinite(v) else "-" for v in laps), f"{np.mean(values['time_saturated_s']):.1f}",
        ))
    result = [Table(
        f"Error index (43) over [0, {summary['config']['duration']:g}] s",
        ("condition", "EI", "Table 1", "paper t2 (s)", "RMS position error per lap (m)", "saturated (s)"),
        tuple(rows),
        "EI: mean over the runs; Table 1 over its own t2. RMS per lap: body-frame x-y error.",
    )]
    conditions = summary.get("gain_conditions")
    if conditions:
        rows = tuple((item["name"], item["relation"], f"{item['left']:.4g}", f"{item['right']:.4g}", item["verdict"]) for item in conditions["inequalities"])
        result.append(Table(
            "Gain conditions for the printed gains: (25) and Proposition 3.1 (V_M = 0.3 m/s)",
            ("", "condition", "left", "right", "verdict"), rows,
            "sufficient conditions; the combined procedure (27)-(34) is not evaluated (derivations section 4)",
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


__all__ = ["CONDITIONS", "Config", "TABLE_1", "build", "choice_sweep", "error_index", "run", "tables", "tracking_errors"]
