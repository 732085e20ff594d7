"""Calugi (2002), Section 4.8: the adaptive observer on a pendulum of unknown mass (Figs 4.2, 4.3).

The free pendulum M = m l^2, G = m g l sin q, no friction, theta = m unknown (the
regressor is phi = l^2 psi + g l sin q = tau / theta_hat, :mod:`lookout.models.parameters`);
only q is measured. The discrete observer (4.34)–(4.35) with resetting (4.45),
:class:`~lookout.observers.adaptive_manipulator.AdaptiveManipulatorObserver`, at the
printed settings: K = 20, Gamma = 10, m = 1 kg, l = 1.5 m, theta_hat(0) = 0.1 kg,
q(0) = 0, q'(0) = -1 rad/s, x1_hat(0) = 0, Delta = 10 ms (and 1 ms).

Chosen where the thesis is silent (docs/reproductions.md):

* the input tau = sin t N m (the thesis gives none; with tau = 0 the mass cannot be
  identified, and the separate long-term Fig. 4.3 suggests slow convergence);
* the resetting bounds [0.05, 5] kg and mu = 0.01 kg (M = m l^2 is positive definite
  for every m > 0, so any mu < 0.05 keeps M_hat positive definite);
* the plant integrated by RK4 at the largest step <= 1 ms that divides Delta, tau held over each sample.

Beyond the thesis: the order of (4.34)–(4.35) against the continuous observer (4.5)–(4.7)
(given the true q'), and a run in which the resets fire (:data:`STRESS`: Gamma = 1000,
bounds [0.5, 1.5] kg, mu = 0.01 kg).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from pydantic import Field, field_validator

from lookout.analysis.adaptive_manipulator import check_theorem_4_1
from lookout.controllers import SinusoidalInput
from lookout.models.manipulators import FreePendulum, ManipulatorPlant
from lookout.models.parameters import ModelParameters
from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver
from lookout.settings import NoiseFreeConfig, finite_positive, whole_samples
from lookout.papers import CATALOG
from lookout.papers._report import Table, save_figures, significant, write_summary
from lookout.results import write_netcdf
from lookout.sensors import JointEncoder
from lookout.sim import Scenario, simulate

NAME = "calugi-2002-adaptive-observer"
TITLE = CATALOG[NAME].title
MASS, LENGTH = 1.0, 1.5
SAMPLE_PERIODS = (0.01, 0.001)
ORDER_PERIODS = (0.02, 0.01, 0.005, 0.0025)
#: The run in which the resets fire: Gamma, bounds l, h (kg) and mu (kg).
STRESS = {"adaptation_gain": 1000.0, "bounds": (0.5, 1.5), "margin": 0.01}
REPORT_TIMES = (1.0, 10.0, 20.0, 50.0)


class Config(NoiseFreeConfig):
    """Settings of the reproduction; every field has the thesis's value or a stated choice."""

    duration: float = Field(300.0, description="simulated time (s); Fig. 4.3's long run")
    gain: float = Field(20.0, description="K (1/s)")
    adaptation_gain: float = Field(10.0, description="Gamma")
    initial_mass: float = Field(0.1, description="theta_hat(0) (kg)")
    input_amplitude: float = Field(1.0, description="tau = A sin(w t): A (N m), chosen")
    input_frequency: float = Field(1.0, description="tau = A sin(w t): w (rad/s), chosen")
    bounds: tuple[float, float] = Field((0.05, 5.0), description="resetting bounds [l, h] of m (kg), chosen")
    margin: float = Field(0.01, description="resetting margin mu (kg), chosen")
    sweep: bool = Field(True, description="the studies: the order against the continuous observer, and the run in which the resets fire")

    @field_validator("duration")
    @classmethod
    def _duration(cls, value):
        finite_positive(value)
        whole_samples(value, 0.1, "the 0.1 s record period")
        if value < 20.0:
            raise ValueError(f"must be at least 20 s (Fig. 4.2's window); got {value:g} s")
        return value

    @field_validator("gain", "adaptation_gain", "initial_mass", "input_frequency")
    @classmethod
    def _positive(cls, value):
        return finite_positive(value)

    @field_validator("input_amplitude", "margin")
    @classmethod
    def _non_negative(cls, value):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"must be finite and >= 0; got {value:g}")
        return value

    @field_validator("bounds")
    @classmethod
    def _bounds(cls, value):
        low, high = value
        if not (math.isfinite(low) and math.isfinite(high) and 0 < low < MASS < high):
            raise ValueError(f"must satisfy 0 < l < m = {MASS:g} kg < h; got {value}")
        return value


def parameters() -> ModelParameters:
    """theta = m of the pendulum (m = 1 kg, l = 1.5 m, no friction)."""
    return ModelParameters(FreePendulum(MASS, LENGTH, 0.0), ("mass",), units=("kg",))


def observer(config: Config, sample_period: float, stress: bool = False) -> AdaptiveManipulatorObserver:
    """The observer at Delta; ``stress``: the :data:`STRESS` settings."""
    gain, bounds, margin = (STRESS["adaptation_gain"], STRESS["bounds"], STRESS["margin"]) if stress else (config.adaptation_gain, config.bounds, config.margin)
    return AdaptiveManipulatorObserver(parameters(), config.gain, gain, sample_period=sample_period, lower=bounds[0], upper=bounds[1], margin=margin)


def build(config: Config, sample_period: float, *, stress: bool = False, duration: float | None = None) -> Scenario:
    """The closed loop of Section 4.8 at sample period Delta (records every 0.1 s)."""
    pendulum = FreePendulum(MASS, LENGTH, 0.0)
    plant = ManipulatorPlant(pendulum)
    estimator = observer(config, sample_period, stress)
    return Scenario(
        plant, JointEncoder(pendulum, sample_period=sample_period), estimator,
        SinusoidalInput(config.input_amplitude, config.input_frequency, size=1),
        plant.state(0.0, -1.0), estimator.guess(0.0, config.initial_mass),
        plant_step=sample_period / math.ceil(sample_period / 1e-3 - 1e-9), sample_period=sample_period, duration=config.duration if duration is None else duration,
        record_every=max(1, int(round(0.1 / sample_period))),
    )


#: The scenarios a scenario file can name as its ``case`` (one per sample interval Delta (s)); the first is the
#: default. See :mod:`lookout.studies.scenario_file`.
CASES: tuple[str, ...] = tuple(f"delta-{period:g}" for period in SAMPLE_PERIODS)


def case_scenario(config: Config, case: str) -> Scenario:
    """The scenario of ``case`` (one of :data:`CASES`) for ``config``, as :func:`run` simulates it."""
    return build(config, SAMPLE_PERIODS[CASES.index(case)])


def scenarios(config: Config) -> list[Scenario]:
    """The scenarios :func:`run` simulates first (one per Delta)."""
    return [build(config, period) for period in SAMPLE_PERIODS]


def continuous_reference(config: Config, duration: float, step: float = 1e-4, record: float = 0.0025) -> dict[str, np.ndarray]:
    """Plant and the continuous observer (4.5)–(4.7), fed the true q', integrated jointly
    by RK4 at ``step`` with tau = A sin(w t) evaluated at each stage; recorded every
    ``record`` s (a multiple of every Delta of the order study)."""
    model = FreePendulum(MASS, LENGTH, 0.0)
    estimator = observer(config, 0.01)

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


def order_study(config: Config, duration: float = 20.0) -> dict:
    """max |theta_hat - theta_hat_cont| and |x1_hat - x1_hat_cont| over [0, duration] at the
    sample times of the coarsest Delta, for Delta in :data:`ORDER_PERIODS`, and the fitted
    order log2(error(Delta) / error(Delta / 2))."""
    reference = continuous_reference(config, duration)
    coarse = ORDER_PERIODS[0]
    times = np.arange(int(round(duration / coarse))) * coarse  # the record ends one sample before the duration
    pick = np.rint(times / 0.0025).astype(int)
    errors = {"theta": [], "velocity": []}
    for period in ORDER_PERIODS:
        scenario = build(config, period, duration=duration)
        scenario = dataclasses.replace(scenario, record_every=1)
        ds = simulate(scenario, jax.random.PRNGKey(config.seed)).to_xarray().isel(run=0)
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


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate Delta = 10 ms and 1 ms (and the studies); write NetCDF, figures, summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    results, per_period, files = {}, {}, []
    parts = len(SAMPLE_PERIODS) + (2 if config.sweep else 0)
    for index, period in enumerate(SAMPLE_PERIODS):
        ds = simulate(build(config, period), jax.random.PRNGKey(config.seed)).to_xarray()
        ds.attrs.update({"reproduction": NAME, "title": TITLE, "sample_period_s": period, "config": config.model_dump_json()})
        filename = f"calugi_2002_adaptive_observer_{int(round(period * 1000))}ms.nc"
        write_netcdf(ds, out / filename, history=f"lookout reproduce {NAME} (Delta = {period:g} s)")
        files.append(filename)
        results[period] = ds.isel(run=0)
        per_period[f"{period:g}"] = summarize(results[period], config)
        if progress is not None:
            progress(index + 1, parts)
    study = {}
    if config.sweep:
        study["order"] = order_study(config)
        if progress is not None:
            progress(len(SAMPLE_PERIODS) + 1, parts)
        stress = simulate(build(config, SAMPLE_PERIODS[0], stress=True, duration=min(config.duration, 50.0)),
                          jax.random.PRNGKey(config.seed)).to_xarray().isel(run=0)
        study["stress"] = {**STRESS, **summarize(stress, config),
                           "theta_hat_range": [float(stress.mass_hat.min()), float(stress.mass_hat.max())]}
        if progress is not None:
            progress(parts, parts)
    theorem = check_theorem_4_1(parameters(), config.gain, config.adaptation_gain, max_speed=_max_speed(results),
                                initial_error=(np.array([-1.0]), np.array([MASS - config.initial_mass])))
    files += _figures(results, config, out)
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "seeds": [config.seed],
        "status": [s for values in per_period.values() for s in values["status"]],
        "sample_periods": per_period,
        "theorem_4_1": theorem.to_dict(),
        **study,
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def _max_speed(results: dict) -> float:
    return float(max(np.abs(ds.joint_rate.values).max() for ds in results.values()))


def _figures(results: dict, config: Config, out: Path) -> list[str]:
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
    figure.suptitle(f"Fig. 4.2: velocity and mass estimates (tau = {config.input_amplitude:g} sin({config.input_frequency:g} t), chosen)", fontsize=10)
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


def _number(value) -> str:
    """A side of an inequality: None in JSON is an unbounded region (C_M = 0)."""
    return "inf" if value is None else f"{value:.4g}"


def tables(summary: dict) -> list[Table]:
    """theta_hat over time per Delta, Theorem 4.1, the studies."""
    rows = []
    for period, values in summary["sample_periods"].items():
        at = values["theta_hat_at"]
        rows.append((f"{float(period) * 1000:g} ms", *(f"{v:.4f}" for v in at.values()),
                     f"{values['theta_hat_band_late'][0]:.3f}-{values['theta_hat_band_late'][1]:.3f}",
                     significant(values["velocity_error_rms_after_1s"]), f"{values['resets']:g}"))
    result = [Table(
        "Mass estimate theta_hat (kg) at times (s); m = 1 kg, theta_hat(0) = 0.1 kg",
        ("Delta", *(f"{t:g}" for t in REPORT_TIMES), "band after 100 s", "RMS x1~", "resets"),
        tuple(rows), "tau = A sin(w t) chosen (the thesis gives none); RMS of the velocity error after 1 s, rad/s",
    )]
    theorem = summary["theorem_4_1"]
    result.append(Table(
        "Theorem 4.1 (C_M = 0 for the pendulum: the region is global)",
        ("", "condition", "left", "right", "verdict"),
        tuple((item["name"], item["relation"], _number(item["left"]), _number(item["right"]), item["verdict"]) for item in theorem["inequalities"]),
        f"sigma = K m l^2 = {theorem['quantities']['sigma']:.4g}; w_max from the run",
    ))
    if summary.get("order"):
        order = summary["order"]
        result.append(Table(
            f"(4.34)-(4.35) against the continuous (4.5)-(4.7), max error over {order['duration_s']:g} s",
            ("Delta (s)", "theta_hat (kg)", "x1_hat (rad/s)"),
            tuple((f"{p:g}", significant(a), significant(b)) for p, a, b in zip(order["sample_periods"], order["max_error"]["theta"], order["max_error"]["velocity"])),
            "fitted orders: theta " + ", ".join(f"{v:.2f}" for v in order["order"]["theta"]) + "; x1 " + ", ".join(f"{v:.2f}" for v in order["order"]["velocity"]),
        ))
    if summary.get("stress"):
        stress = summary["stress"]
        result.append(Table(
            f"Gamma = {stress['adaptation_gain']:g}, bounds {stress['bounds'][0]:g}-{stress['bounds'][1]:g} kg, "
            f"mu = {stress['margin']:g} kg, Delta = 10 ms: resetting at work",
            ("resets", "theta_hat range (kg)", "final theta_hat (kg)"),
            ((f"{stress['resets']:g}", f"{stress['theta_hat_range'][0]:.3f}-{stress['theta_hat_range'][1]:.3f}", f"{stress['theta_hat_final']:.4f}"),),
            "theta_hat(0) = 0.1 kg lies below l - mu and is reset at t_0",
        ))
    return result


__all__ = ["Config", "NAME", "TITLE", "build", "continuous_reference", "order_study", "run", "scenarios", "tables"]
