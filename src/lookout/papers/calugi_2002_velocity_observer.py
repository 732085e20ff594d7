"""Reproduction of Calugi (2002), master thesis, chapter 2: the reduced-order velocity
observer (2.6)–(2.7) on the four manipulators of Section 2.3.

Printed: the models and parameters, the gains K and the initial conditions q(0),
q'(0), x1_hat(0) of each system, and the constant two-link torques tau = (2, 1) N m.
Shown only in figures, chosen here: the cart force F(t) = 2 sin(2 t) N and the
Furuta arm torque tau(t) = 0.5 sin(t) N m (second joints unforced, as printed).
The thesis simulated in continuous time (Simulink); here the observer is integrated
jointly with the plant on the exact joint positions (``observer_mode="continuous"``),
RK4 at 1 ms, recorded every 10 ms, for 10 s. The runs are noise-free, so a
reproduction has one run; the seed is recorded but draws nothing.

Reported per system: the velocity error at the start and at the end per joint, the
fitted exponential decay rate of the error norm and per joint, and Theorem 2.1's
sufficient condition with the bounds M_m and C_M found over the configuration space
and the largest speed of the run as omega_max.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import jax.numpy as jnp
import numpy as np
import xarray as xr
from pydantic import Field, ValidationInfo, field_validator

from lookout.analysis import fit_decay_rate
from lookout.analysis.velocity import configuration_bounds, velocity_observer_condition
from lookout.components import Controller
from lookout.controllers import SinusoidalInput
from lookout.models.manipulators import CartPendulum, FreePendulum, FurutaPendulum, ManipulatorModel, ManipulatorPlant, TwoLinkArm
from lookout.observers import VelocityObserver
from lookout.settings import NoiseFreeConfig, finite_positive, whole_samples
from lookout.papers import CATALOG
from lookout.papers._report import Table, significant, write_summary
from lookout.results import write_netcdf
from lookout.sensors import JointEncoder
from lookout.sim import Scenario, seed_keys, simulate

NAME = "calugi-2002-velocity-observer"
TITLE = CATALOG[NAME].title


@dataclass(frozen=True)
class System:
    """One simulation of Section 2.3: model, gain, initial conditions, input, figures."""

    label: str
    model: ManipulatorModel
    gain: float
    initial_position: tuple[float, ...]
    initial_velocity: tuple[float, ...]
    initial_estimate: tuple[float, ...]
    controller: Controller
    input_description: str
    trajectory_figure: str | None
    velocity_figure: str


#: Section 2.3 with its printed parameters; the cart and Furuta inputs are chosen.
SYSTEMS = {
    "pendulum": System(
        "free pendulum", FreePendulum(), 2.0 - 0.1 / (0.5 * 0.5**2), (2.0,), (0.0,), (2.2,),
        SinusoidalInput.constant([0.0]), "tau = 0 (printed)", None, "2.2",
    ),
    "two_link": System(
        "two-link manipulator", TwoLinkArm(), 5.0, (-math.pi / 4, -math.pi / 4), (0.0, 0.0), (-4.0, -4.0),
        SinusoidalInput.constant([2.0, 1.0]), "tau = (2, 1) N m (printed)", "2.3", "2.4",
    ),
    "cart": System(
        "pendulum on the coach", CartPendulum(), 5.0, (-1.0, 1.0), (0.0, 0.0), (-5.0, 5.0),
        SinusoidalInput([2.0, 0.0], [2.0, 0.0]), "F(t) = 2 sin(2 t) N on the cart (chosen), tau2 = 0 (printed)", "2.5", "2.6",
    ),
    "furuta": System(
        "Furuta pendulum", FurutaPendulum(), 5.0, (1.0, -1.0), (0.0, 0.0), (-5.0, -5.0),
        SinusoidalInput([0.5, 0.0], [1.0, 0.0]), "tau(t) = 0.5 sin(t) N m on the arm (chosen), tau2 = 0 (printed)", "2.7", "2.8",
    ),
}


class Config(NoiseFreeConfig):
    """Settings of the reproduction; the systems themselves are :data:`SYSTEMS`."""

    plant_step: float = Field(1e-3, description="RK4 step of plant and observer (s)")
    sample_period: float = Field(1e-2, description="record and input period (s)")
    duration: float = Field(10.0, description="simulated time per system (s)")

    @field_validator("plant_step", "sample_period", "duration")
    @classmethod
    def _finite_positive(cls, value):
        return finite_positive(value)

    @field_validator("duration")
    @classmethod
    def _whole_samples(cls, value, info: ValidationInfo):
        period = info.data.get("sample_period")
        whole_samples(value, period, "the sample period")
        if period is not None and value < 100 * period:
            raise ValueError(f"must be at least {100 * period:g} s (100 samples, for the decay fit); got {value:g} s")
        return value


def build(config: Config, name: str) -> Scenario:
    """The scenario of system ``name`` (a key of :data:`SYSTEMS`)."""
    system = SYSTEMS[name]
    plant = ManipulatorPlant(system.model)
    return Scenario(
        plant,
        JointEncoder(system.model, sample_period=config.sample_period),
        VelocityObserver(system.model, system.gain),
        system.controller,
        plant.state(system.initial_position, system.initial_velocity),
        jnp.asarray(system.initial_estimate, dtype=float),
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
        observer_mode="continuous",
    )


#: The scenarios a scenario file can name as its ``case`` (one per system); the first is the
#: default. See :mod:`lookout.studies.scenario_file`.
CASES: tuple[str, ...] = tuple(SYSTEMS)


def case_scenario(config: Config, case: str) -> Scenario:
    """The scenario of ``case`` (one of :data:`CASES`) for ``config``, as :func:`run` simulates it."""
    return build(config, case)


def scenarios(config: Config) -> list[Scenario]:
    """The scenarios :func:`run` simulates, one per system."""
    return [build(config, name) for name in SYSTEMS]


def _velocity_names(ds: xr.Dataset) -> list[str]:
    return [name for name in ("joint_speed", "joint_rate") if name in ds]


def _joint_series(ds: xr.Dataset, suffix: str = "") -> dict[str, np.ndarray]:
    """Velocity (or its estimate) per joint name, run 0."""
    series = {}
    for name in _velocity_names(ds):
        array = ds[name + suffix].isel(run=0)
        dim = next(d for d in array.dims if d != "time")
        for label in array[dim].values.tolist():
            series[label] = np.asarray(array.sel({dim: label}).values, dtype=float)
    return series


def _decay(time: np.ndarray, magnitude: np.ndarray) -> dict:
    """The fitted decay of ``magnitude`` from 10 % to 1e-9 of its start, or why there is none."""
    try:
        fit = fit_decay_rate(time, magnitude, upper=1e-1, lower=1e-9)
    except ValueError as error:
        return {"rate": None, "r_squared": None, "note": str(error)}
    return {"rate": fit["rate"], "r_squared": fit["r_squared"], "fitted_from_s": fit["t_start"], "fitted_to_s": fit["t_end"]}


def summarize(ds: xr.Dataset, name: str) -> dict:
    """Per joint and for the norm: the velocity error at the start and end, the fitted
    decay rate, and Theorem 2.1 with omega_max the largest speed of the run."""
    system = SYSTEMS[name]
    time = ds.time.values
    truth, estimate = _joint_series(ds), _joint_series(ds, "_hat")
    joints = {}
    for joint in truth:
        error = np.abs(truth[joint] - estimate[joint])
        joints[joint] = {"initial_error": float(error[0]), "final_error": float(error[-1]), **_decay(time, error)}
    errors = np.stack([truth[j] - estimate[j] for j in truth], axis=-1)
    norm = np.linalg.norm(errors, axis=-1)
    speed = float(np.linalg.norm(np.stack(list(truth.values()), axis=-1), axis=-1).max())
    report = velocity_observer_condition(system.model, system.gain, speed, initial_error=float(norm[0]), bounds=configuration_bounds(system.model))
    return {
        "label": system.label,
        "gain": system.gain,
        "input": system.input_description,
        "initial_position": list(system.initial_position),
        "initial_velocity": list(system.initial_velocity),
        "initial_estimate": list(system.initial_estimate),
        "joints": joints,
        "error_norm": {"initial_error": float(norm[0]), "final_error": float(norm[-1]), **_decay(time, norm)},
        "theorem_2_1": report.to_dict(),
    }


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate the four systems; write NetCDF, figures and summary.json under ``out``."""
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_estimates, plot_trajectories

    out.mkdir(parents=True, exist_ok=True)
    files, systems, status = [], {}, []
    key = seed_keys(config.seed, 1)[0]
    for index, (name, system) in enumerate(SYSTEMS.items()):
        step = None if progress is None else (lambda done, total, i=index: progress(i + done / total, len(SYSTEMS)))
        ds = simulate(build(config, name), key, progress=step).to_xarray()
        # the runs draw no random numbers: the seed is an attribute, not a coordinate that
        # figures would name as "the run's seed"
        ds.attrs.update({"reproduction": NAME, "system": system.label, "title": TITLE, "config": config.model_dump_json(), "seed": config.seed})
        filename = f"calugi_2002_{name}.nc"
        write_netcdf(ds, out / filename, history=f"lookout reproduce {NAME}: {system.label}")
        files.append(filename)
        status += ds.status.values.tolist()
        velocities = [(variable, label) for variable in _velocity_names(ds) for label in ds[variable][ds[variable].dims[-1]].values.tolist()]
        positions = [(variable, label) for variable in ("joint_position", "joint_angle") if variable in ds for label in ds[variable][ds[variable].dims[-1]].values.tolist()]
        figures = {}
        if system.trajectory_figure:
            figures[f"fig{system.trajectory_figure.replace('.', '_')}_{name}_positions.png"] = plot_trajectories(
                ds, positions, title=f"Calugi (2002), Fig. {system.trajectory_figure}: {system.label}, joint trajectories"
            )
        figures[f"fig{system.velocity_figure.replace('.', '_')}_{name}_velocities.png"] = plot_estimates(
            ds, velocities, window=(0.0, min(2.0, float(ds.time[-1]))),
            title=f"Calugi (2002), Fig. {system.velocity_figure}: {system.label}, true and estimated velocities",
        )
        for filename, figure in figures.items():
            figure.savefig(out / filename, dpi=110)
            plt.close(figure)
            files.append(filename)
        systems[name] = summarize(ds, name)
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "runs": 1,
        "seeds": [config.seed],
        "status": status,
        "systems": systems,
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def tables(summary: dict) -> list[Table]:
    """Velocity errors and decay rates per joint; Theorem 2.1 per system."""
    errors, theorem = [], []
    for name, system in summary["systems"].items():
        for joint, values in system["joints"].items():
            rate = values["rate"]
            errors.append((f"{name} {joint}", significant(values["initial_error"]), significant(values["final_error"]), "-" if rate is None else f"{rate:.3f}"))
        condition = system["theorem_2_1"]
        radius = condition["radius"]
        theorem.append(
            (
                name,
                f"{condition['effective_gain']:.3g}",
                f"{condition['threshold']:.3g}",
                "holds" if condition["satisfied"] else "fails",
                "unbounded" if radius is None else f"{radius:.3g}",
            )
        )
    return [
        Table(
            "Velocity error |x1 - x1_hat| (rad/s, m/s): at t = 0, at the end, fitted decay rate (1/s)",
            ("system joint", "start", "end", "rate"),
            tuple(errors),
            "rate: log-linear fit of |x1~| from 10 % to 1e-9 of its start",
        ),
        Table(
            "Theorem 2.1: sigma > 3 C_M w_max / M_m (w_max: the run's largest speed)",
            ("system", "sigma_eff", "3 C_M w_max / M_m", "verdict", "region (2.13)"),
            tuple(theorem),
            "sufficient only; sigma_eff: lambda_min(K) plus friction where it can only hurt; "
            "region (2.13): the initial errors it guarantees, M_m sigma_eff / C_M - 2 w_max",
        ),
    ]
