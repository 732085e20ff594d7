"""Reproduction of Calugi (2002), master thesis, chapter 3: on-line parameter estimation
(Middleton–Goodwin, (3.9) with (3.13)–(3.16)) on the frictionless pendulum, Figs. 3.2 and 3.3.

Printed: the pendulum M = m l^2, G = m g l sin q; Sim 1, theta = m, piecewise
constant, l = 1.5 m, h = 10, q(0) = 1 rad, q'(0) = 0, m_hat(0) = 1 kg; Sim 2,
theta = (m l^2, m l), h = 100, q(0) = q'(0) = 0, theta_hat(0) = (4.5, 2); the filter
1/(s + 1).

Not printed, chosen here (docs/reproductions.md): the input tau = 5 sin t N m in both
simulations; T = 60 s; Sim 1's mass m = 2 kg on [0, 20) s, 3 kg on [20, 40) s and
1.5 kg from 40 s; Sim 2's m = 1 kg and l = 1.5 m, so theta = (2.25 kg m^2, 1.5 kg m);
no friction. The estimator (:class:`lookout.observers.parameter_estimator.ParameterEstimator`)
is integrated jointly with the plant on the exact q and q' (``observer_mode="continuous"``),
RK4 at 0.2 ms (Sim 2 is stiff: h |phi_f|^2 reaches about 1.3e3 1/s), the input held
over 10 ms samples, recorded every 10 ms.

Two runs without excitation: Sim 2 with tau = 0 at rest (nothing moves), and Sim 1
with tau = 0 from q(0) = 1 rad (the pendulum swings, but phi = l^2 q'' + g l sin q is
zero along the free motion, so phi_f is zero and m_hat must stay at 1 kg: this holds
only with the q'(0) e^{-t} term of the filtered acceleration).

Reported: Sim 1, the estimate 1, 2 and 10 s after the start and after each jump and the
time to settle within 1 %; Sim 2, the time to settle within 1 %, the final estimates
and errors; for both, persistence of excitation as the smallest windowed
lambda_min(int_{t-T}^t phi_f^T phi_f) over the run, the stiffness h lambda_max(phi_f^T phi_f),
and whether V = 1/2 |theta~|^2 ever increases while theta is constant; the
no-excitation runs' largest change of the estimate.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import jax.numpy as jnp
import numpy as np
import xarray as xr
from pydantic import ConfigDict, Field, ValidationInfo, field_validator

from lookout.controllers import SinusoidalInput
from lookout.models.manipulators import FreePendulum
from lookout.models.parameters import AffineParameters, ModelParameters, PendulumInertia
from lookout.models.scheduled_parameters import ScheduledParameterPlant
from lookout.observers.parameter_estimator import ParameterEstimator, windowed_excitation
from lookout.settings import NoiseFreeConfig, finite_positive, whole_samples
from lookout.papers import CATALOG
from lookout.papers._report import Table, save_figures, significant, write_summary
from lookout.results import write_netcdf
from lookout.sensors import JointStateSensor
from lookout.sim import Scenario, seed_keys, simulate

NAME = "calugi-2002-parameter-estimation"
TITLE = CATALOG[NAME].title

#: Pendulum length of both simulations (m): printed for Sim 1, chosen for Sim 2.
LENGTH = 1.5
#: Sim 1: the mass on each interval (kg) and the switch times (s), chosen.
SIM1_MASSES = (2.0, 3.0, 1.5)
SIM1_SWITCH_TIMES = (20.0, 40.0)
#: Sim 2: the true mass (kg), chosen; theta = (m l^2, m l).
SIM2_MASS = 1.0
#: Times after the start and after each jump at which Sim 1's estimate is reported (s).
REPORT_DELAYS = (1.0, 2.0, 10.0)
#: The settling band, relative to the true value.
SETTLE_BAND = 0.01


@dataclass(frozen=True)
class Simulation:
    """One run: which parameters, the truth over time, gain, initial conditions, input."""

    label: str
    parameters: AffineParameters
    values: tuple[tuple[float, ...], ...]
    switch_times: tuple[float, ...]
    gain: float
    initial_position: float
    initial_velocity: float
    initial_estimate: tuple[float, ...]
    excited: bool


def _sim1_parameters() -> ModelParameters:
    return ModelParameters(FreePendulum(SIM1_MASSES[0], LENGTH, 0.0), ("mass",), units=("kg",))


def _sim2_parameters() -> PendulumInertia:
    return PendulumInertia(FreePendulum(SIM2_MASS, LENGTH, 0.0))


def simulations() -> dict[str, Simulation]:
    """The four runs: Sims 1 and 2 of Section 3.2, and each without excitation (tau = 0)."""
    return dict(_simulations())


@functools.cache
def _simulations() -> dict[str, Simulation]:
    # built once: the parameter sets check their affinity on random points when built
    sim1, sim2 = _sim1_parameters(), _sim2_parameters()
    masses = tuple((m,) for m in SIM1_MASSES)
    truth2 = (tuple(float(v) for v in np.asarray(sim2.reference)),)
    return {
        "sim1": Simulation("Sim 1: theta = m, piecewise constant", sim1, masses, SIM1_SWITCH_TIMES, 10.0, 1.0, 0.0, (1.0,), True),
        "sim2": Simulation("Sim 2: theta = (m l^2, m l)", sim2, truth2, (), 100.0, 0.0, 0.0, (4.5, 2.0), True),
        "sim1_free_swing": Simulation("Sim 1 with tau = 0 (free swing from q(0) = 1 rad)", sim1, masses, SIM1_SWITCH_TIMES, 10.0, 1.0, 0.0, (1.0,), False),
        "sim2_rest": Simulation("Sim 2 with tau = 0 at rest", sim2, truth2, (), 100.0, 0.0, 0.0, (4.5, 2.0), False),
    }


class Config(NoiseFreeConfig):
    """Settings of the reproduction; the runs themselves are :func:`simulations`."""

    # defaults are validated too: a changed plant_step must still divide the default sample_period
    model_config = ConfigDict(validate_default=True)  # merged with Settings: frozen, strict, no unknown keys

    plant_step: float = Field(2e-4, description="RK4 step of plant and estimator (s); Sim 2 is stiff")
    sample_period: float = Field(1e-2, description="input hold and record period (s)")
    input_amplitude: float = Field(5.0, description="tau = amplitude sin(frequency t) (N m), chosen")
    input_frequency: float = Field(1.0, description="rad/s, chosen")
    filter_pole: float = Field(1.0, description="a of the filter 1/(s + a) (rad/s); the thesis's 1")
    pe_window: float = Field(5.0, description="T of the persistence-of-excitation check (s)")
    duration: float = Field(60.0, description="simulated time per run (s)")

    @field_validator("plant_step", "sample_period", "duration", "input_frequency", "filter_pole", "pe_window")
    @classmethod
    def _finite_positive(cls, value):
        return finite_positive(value)

    @field_validator("input_amplitude")
    @classmethod
    def _finite_nonzero(cls, value):
        if not (np.isfinite(value) and value != 0):
            raise ValueError(f"must be a finite nonzero number (the excited runs need an input); got {value:g}")
        return value

    # sample_period a whole multiple of plant_step: RunsConfig checks it

    @field_validator("pe_window")
    @classmethod
    def _window_whole_samples(cls, value, info: ValidationInfo):
        return whole_samples(value, info.data.get("sample_period"), "the sample period")

    @field_validator("duration")
    @classmethod
    def _whole_samples_beyond_the_window(cls, value, info: ValidationInfo):
        period, window = info.data.get("sample_period"), info.data.get("pe_window")
        whole_samples(value, period, "the sample period")
        if period is not None and window is not None and value < window + period:
            raise ValueError(f"must be at least {window + period:g} s (the PE window pe_window, {window:g} s, plus one sample); got {value:g} s")
        return value


def build(config: Config, name: str) -> Scenario:
    """The scenario of run ``name`` (a key of :func:`simulations`)."""
    sim = simulations()[name]
    plant = ScheduledParameterPlant(sim.parameters, sim.values, sim.switch_times)
    amplitude = config.input_amplitude if sim.excited else 0.0
    return Scenario(
        plant,
        JointStateSensor(sim.parameters.model(sim.parameters.reference), sample_period=config.sample_period),
        ParameterEstimator(sim.parameters, sim.gain, filter_pole=config.filter_pole),
        SinusoidalInput(amplitude, config.input_frequency),
        plant.state(sim.initial_position, sim.initial_velocity),
        jnp.asarray(sim.initial_estimate, dtype=float),
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
        observer_mode="continuous",
    )


#: The scenarios a scenario file can name as its ``case`` (one per simulation); the first is the
#: default. See :mod:`lookout.studies.scenario_file`.
CASES: tuple[str, ...] = ("sim1", "sim2", "sim1_free_swing", "sim2_rest")  # the keys of simulations()


def case_scenario(config: Config, case: str) -> Scenario:
    """The scenario of ``case`` (one of :data:`CASES`) for ``config``, as :func:`run` simulates it."""
    return build(config, case)


def scenarios(config: Config) -> list[Scenario]:
    """The scenarios :func:`run` simulates, one per run of :func:`simulations`."""
    return [build(config, name) for name in simulations()]


# ----------------------------------------------------------------------------------
# Metrics


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
        "lyapunov": _lyapunov(time, estimate[:, None], truth[:, None], until=sim.switch_times[0] - config.sample_period if sim.switch_times else None),
        "max_abs_angle": float(np.abs(ds.joint_angle.values).max()),
    }


def _sim2_summary(ds: xr.Dataset, estimator: ParameterEstimator, sim: Simulation, config: Config) -> dict:
    time = ds.time.values
    estimates = estimator.estimates(ds)
    truth = np.asarray(sim.values[0])
    parameters = {}
    for j, (name, unit) in enumerate(zip(sim.parameters.names, sim.parameters.units)):
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


# ----------------------------------------------------------------------------------
# Figures


def _input_text(config: Config) -> str:
    frequency = "t" if config.input_frequency == 1.0 else f"{config.input_frequency:g} t"
    return f"tau = {config.input_amplitude:g} sin({frequency}) N m"


def _figures(results: dict[str, xr.Dataset], estimators: dict[str, ParameterEstimator], config: Config) -> dict:
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_estimates

    figures = {}
    sim1, sim2 = results["sim1"], results["sim2"]
    end1 = float(sim1.time[-1])
    jump = next((t for t in SIM1_SWITCH_TIMES if t + 5.0 <= end1), None)
    window = (jump - 1.0, jump + 5.0) if jump is not None else (0.0, min(6.0, end1))
    figures["fig3_2_mass_estimate.png"] = plot_estimates(
        sim1, [("mass", None)], window=window,
        title=f"Calugi (2002), Fig. 3.2: pendulum mass, true (stepwise, chosen) and estimated; h = 10, {_input_text(config)}",
    )
    end2 = float(sim2.time[-1])
    figures["fig3_3_inertia_moment_estimates.png"] = plot_estimates(
        sim2, [("inertia", None), ("moment", None)], window=(0.0, min(5.0, end2)),
        title=f"Calugi (2002), Fig. 3.3: theta = (m l^2, m l), m = {SIM2_MASS:g} kg, l = {LENGTH:g} m (chosen); h = 100, {_input_text(config)}",
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
    for name, names in (("sim1_free_swing", ("m_hat, free swing (kg)",)), ("sim2_rest", ("theta_hat_1, at rest (kg m2)", "theta_hat_2, at rest (kg m)"))):
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


# ----------------------------------------------------------------------------------
# Run


def simulate_run(config: Config, name: str, *, progress: Callable | None = None) -> tuple[Scenario, xr.Dataset]:
    """Simulate run ``name`` of :func:`simulations`; the Dataset gets the true parameters
    (``mass``; ``inertia`` and ``moment``) next to the estimates (``<name>_hat``)."""
    scenario = build(config, name)
    ds = simulate(scenario, seed_keys(config.seed, 1)[0], progress=progress).to_xarray()
    plant = scenario.plant
    truth = plant.truth(ds.time.values)
    for signal in plant.parameter_layout.signals:
        ds[signal.name] = (("run", "time"), truth[signal.name][None, :], {"units": signal.units, "long_name": signal.long_name, "frame": "", "angle": 0})
    ds.attrs.update({"reproduction": NAME, "simulation": simulations()[name].label, "title": TITLE, "config": config.model_dump_json(), "seed": config.seed})
    return scenario, ds


def summarize(config: Config, results: dict[str, xr.Dataset], estimators: dict[str, ParameterEstimator]) -> dict:
    """The summary's numbers from the four runs' Datasets and estimators."""
    runs = simulations()
    return {
        "sim1": _sim1_summary(results["sim1"], estimators["sim1"], runs["sim1"], config),
        "sim2": _sim2_summary(results["sim2"], estimators["sim2"], runs["sim2"], config),
        "no_excitation": {name: _still_summary(results[name], estimators[name], runs[name]) for name in ("sim1_free_swing", "sim2_rest")},
    }


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate the four runs; write NetCDF, figures and summary.json under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    runs = simulations()
    results, estimators, files, status = {}, {}, [], []
    for index, name in enumerate(runs):
        step = None if progress is None else (lambda done, total, i=index: progress(i + done / total, len(runs)))
        scenario, ds = simulate_run(config, name, progress=step)
        filename = f"calugi_2002_ch3_{name}.nc"
        write_netcdf(ds, out / filename, history=f"lookout reproduce {NAME}: {runs[name].label}")
        files.append(filename)
        status += ds.status.values.tolist()
        results[name], estimators[name] = ds, scenario.observer
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "runs": 1,
        "seeds": [config.seed],
        "status": status,
        "input": f"{_input_text(config)} (chosen), held over {config.sample_period:g} s",
        **summarize(config, results, estimators),
    }
    files += save_figures(_figures(results, estimators, config), out)
    summary["files"] = sorted([*files, "summary.json"])
    return write_summary(summary, out)


def tables(summary: dict) -> list[Table]:
    """Sim 1 per interval, Sim 2 per parameter, excitation, and the runs without excitation."""
    fmt = lambda value: "-" if value is None else significant(value)  # noqa: E731
    sim1 = []
    for segment in summary["sim1"]["segments"]:
        after = [fmt(None if v is None else v["estimate"]) for v in segment["after_s"].values()]
        sim1.append((f"{segment['from_s']:g}", fmt(segment["mass"]), *after, fmt(segment["settle_1pct_s"])))
    sim2 = []
    for name, p in summary["sim2"]["parameters"].items():
        sim2.append((f"{name} ({p['unit']})", fmt(p["truth"]), *(fmt(v) for v in p["at_s"].values()), fmt(p["final_estimate"]), f"{p['final_relative_error']:.1e}", fmt(p["settle_1pct_s"])))
    excitation = []
    for name in ("sim1", "sim2"):
        e = summary[name]["excitation"]
        excitation.append((name, fmt(e["lambda_min"]), fmt(e["lambda_min_at_s"]), f"{e['pointwise_lambda_min_max']:.1e}", fmt(e["stiffness_per_s"]), f"{summary[name]['lyapunov']['largest_increase_relative']:.1e}"))
    still = [(name, f"{s['max_estimate_change']:.1e}", fmt(s["max_abs_angle"])) for name, s in summary["no_excitation"].items()]
    delays = tuple(f"+{d:g} s" for d in REPORT_DELAYS)
    return [
        Table("Sim 1: m_hat (kg) after the start and after each jump", ("from (s)", "m", *delays, "settle 1 % (s)"), tuple(sim1), "settle: time after the interval's start from which m_hat stays within 1 % of m"),
        Table("Sim 2: theta_hat", ("parameter", "truth", *(f"{d:g} s" for d in REPORT_DELAYS), "final", "final rel. error", "settle 1 % (s)"), tuple(sim2)),
        Table(
            "Excitation: windowed lambda_min(int phi_f^T phi_f) (min over the run)",
            ("run", "lambda_min", "at (s)", "pointwise max", "h lambda_max (1/s)", "max dV / V_max"),
            tuple(excitation),
            "pointwise max: largest lambda_min(phi_f^T phi_f) at one instant (Lemma 3.1(2)'s rank condition); dV: V = |theta~|^2/2 between records where theta is constant since t = 0 (Sim 1: before the first jump)",
        ),
        Table("No excitation (tau = 0)", ("run", "max |theta_hat - theta_hat(0)|", "max |q| (rad)"), tuple(still)),
    ]
