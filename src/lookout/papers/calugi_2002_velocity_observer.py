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

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
from pydantic import Field, ValidationInfo, field_validator

from lookout.analysis import fit_decay_rate
from lookout.analysis.velocity import configuration_bounds, velocity_observer_condition
from lookout.models.manipulators import ManipulatorModel
from lookout.papers import CATALOG
from lookout.papers._report import Table, significant, summary_header, write_summary
from lookout.papers._reproduction import Reproduction, simulate_each
from lookout.scenario.composition import compose
from lookout.scenario.settings import NoiseFreeConfig, PositiveFloat, whole_samples
from lookout.sim import Scenario, seed_keys, simulate

NAME = "calugi-2002-velocity-observer"
TITLE = CATALOG[NAME].title


@dataclass(frozen=True)
class System:
    """One simulation of Section 2.3: model, gain, initial conditions, input, figures.

    ``model`` and ``input`` are composition tables (:mod:`lookout.scenario.composition`): the
    manipulator (a ``model`` kind) and the open-loop input (a ``controller`` kind).
    """

    label: str
    model: dict
    gain: float
    initial_position: tuple[float, ...]
    initial_velocity: tuple[float, ...]
    initial_estimate: tuple[float, ...]
    input: dict
    input_description: str
    trajectory_figure: str | None
    velocity_figure: str


def _constant_input(value: list[float]) -> dict:
    """A constant input as a ``sinusoidal`` controller table (zero amplitude, the value as offset)."""
    return {"kind": "sinusoidal", "amplitude": 0.0, "frequency": 0.0, "offset": value}


#: Section 2.3 with its printed parameters; the cart and Furuta inputs are chosen.
SYSTEMS = {
    "pendulum": System(
        "free pendulum",
        {"kind": "pendulum", "mass": 0.5, "length": 0.5, "friction": 0.1},
        2.0 - 0.1 / (0.5 * 0.5**2),
        (2.0,),
        (0.0,),
        (2.2,),
        _constant_input([0.0]),
        "tau = 0 (printed)",
        None,
        "2.2",
    ),
    "two_link": System(
        "two-link manipulator",
        {"kind": "two-link-arm", "masses": [0.5, 0.7], "lengths": [1.0, 1.5], "friction": [0.5, 0.1]},
        5.0,
        (-math.pi / 4, -math.pi / 4),
        (0.0, 0.0),
        (-4.0, -4.0),
        _constant_input([2.0, 1.0]),
        "tau = (2, 1) N m (printed)",
        "2.3",
        "2.4",
    ),
    "cart": System(
        "pendulum on the coach",
        {"kind": "cart-pendulum", "cart_mass": 2.0, "pendulum_mass": 0.2, "pendulum_length": 0.5, "friction": [0.4, 0.1]},
        5.0,
        (-1.0, 1.0),
        (0.0, 0.0),
        (-5.0, 5.0),
        {"kind": "sinusoidal", "amplitude": [2.0, 0.0], "frequency": [2.0, 0.0]},
        "F(t) = 2 sin(2 t) N on the cart (chosen), tau2 = 0 (printed)",
        "2.5",
        "2.6",
    ),
    "furuta": System(
        "Furuta pendulum",
        {
            "kind": "furuta-pendulum",
            "pillar_inertia": 1.0,
            "arm_mass": 0.4,
            "pendulum_mass": 0.1,
            "tip_mass": 0.5,
            "arm_length": 0.7,
            "pendulum_length": 0.5,
            "friction": [0.4, 0.2],
        },
        5.0,
        (1.0, -1.0),
        (0.0, 0.0),
        (-5.0, -5.0),
        {"kind": "sinusoidal", "amplitude": [0.5, 0.0], "frequency": [1.0, 0.0]},
        "tau(t) = 0.5 sin(t) N m on the arm (chosen), tau2 = 0 (printed)",
        "2.7",
        "2.8",
    ),
}


class Config(NoiseFreeConfig):
    """Settings of the reproduction; the systems themselves are :data:`SYSTEMS`."""

    plant_step: PositiveFloat = Field(default=1e-3, description="RK4 step of plant and observer (s)")
    sample_period: PositiveFloat = Field(default=1e-2, description="record and input period (s)")
    duration: PositiveFloat = Field(default=10.0, description="simulated time per system (s)")

    @field_validator("duration")
    @classmethod
    def _whole_samples(cls, value, info: ValidationInfo):
        period = info.data.get("sample_period")
        whole_samples(value, period, "the sample period")
        if period is not None and value < 100 * period:
            raise ValueError(f"must be at least {100 * period:g} s (100 samples, for the decay fit); got {value:g} s")
        return value


#: The cases, one per system of :data:`SYSTEMS`; the first is the default.
CASES: tuple[str, ...] = tuple(SYSTEMS)


def composition(config: Config, case: str) -> dict:
    """System ``case`` (a key of :data:`SYSTEMS`) as a composition (:mod:`lookout.scenario.composition`):
    the manipulator (2.1) with the encoder of q and the observer (2.6)–(2.7) on the plant's
    own model, integrated jointly with the plant on the exact q (``observer_mode = "continuous"``)."""
    system = SYSTEMS[case]
    return copy.deepcopy(
        {  # the document is the caller's: SYSTEMS' tables stay as they are
            "simulation": {
                "runs": config.runs,
                "seed": config.seed,
                "plant_step": config.plant_step,
                "sample_period": config.sample_period,
                "duration": config.duration,
                "observer_mode": "continuous",
            },
            "plant": {
                "kind": "manipulator",
                "model": system.model,
                "initial": {"q": list(system.initial_position), "qdot": list(system.initial_velocity)},
            },
            "sensor": {"kind": "joint-encoder", "sample_period": config.sample_period},
            "observer": {"kind": "velocity", "gain": system.gain, "initial": {"velocity": list(system.initial_estimate)}},
            "controller": system.input,
        }
    )


def build(config: Config, name: str) -> Scenario:
    """The scenario of system ``name`` (a key of :data:`SYSTEMS`)."""
    return compose(composition(config, name)).scenario


def simulate_system(config: Config, name: str, *, progress: Callable | None = None) -> tuple[Scenario, xr.Dataset]:
    """Simulate system ``name`` (one noise-free run): its scenario and the Dataset :func:`run` writes."""
    scenario = build(config, name)
    ds = simulate(scenario, seed_keys(config.seed, 1)[0], progress=progress).to_xarray()
    # the runs draw no random numbers: the seed is an attribute, not a coordinate that
    # figures would name as "the run's seed"
    ds.attrs.update({"reproduction": NAME, "system": SYSTEMS[name].label, "title": TITLE, "config": config.model_dump_json(), "seed": config.seed})
    return scenario, ds


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


def summarize(ds: xr.Dataset, name: str, model: ManipulatorModel) -> dict:
    """Per joint and for the norm: the velocity error at the start and end, the fitted
    decay rate, and Theorem 2.1 for the observer's ``model`` with omega_max the largest
    speed of the run."""
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
    report = velocity_observer_condition(model, system.gain, speed, initial_error=float(norm[0]), bounds=configuration_bounds(model))
    return {
        "label": system.label,
        "gain": system.gain,
        "input": system.input_description,
        "initial_position": list(system.initial_position),
        "initial_velocity": list(system.initial_velocity),
        "initial_estimate": list(system.initial_estimate),
        "joints": joints,
        "error_norm": {"initial_error": float(norm[0]), "final_error": float(norm[-1]), **_decay(time, norm)},
        "theorem_2_1": report.report.to_dict(),
    }


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate the four systems; write NetCDF, figures and summary.json under ``out``."""
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_estimates, plot_trajectories

    out.mkdir(parents=True, exist_ok=True)
    files, systems, status = [], {}, []
    each = simulate_each(
        SYSTEMS,
        lambda name, progress: simulate_system(config, name, progress=progress),
        out,
        "calugi_2002_{case}.nc",
        lambda name: f"lookout reproduce {NAME}: {SYSTEMS[name].label}",
        progress=progress,
    )
    for name, scenario, ds, filename in each:
        system = SYSTEMS[name]
        files.append(filename)
        status += ds.status.values.tolist()
        velocities = [(variable, label) for variable in _velocity_names(ds) for label in ds[variable][ds[variable].dims[-1]].values.tolist()]
        positions = [
            (variable, label)
            for variable in ("joint_position", "joint_angle")
            if variable in ds
            for label in ds[variable][ds[variable].dims[-1]].values.tolist()
        ]
        figures = {}
        if system.trajectory_figure:
            figures[f"fig{system.trajectory_figure.replace('.', '_')}_{name}_positions.png"] = plot_trajectories(
                ds, positions, title=f"Calugi (2002), Fig. {system.trajectory_figure}: {system.label}, joint trajectories"
            )
        figures[f"fig{system.velocity_figure.replace('.', '_')}_{name}_velocities.png"] = plot_estimates(
            ds,
            velocities,
            window=(0.0, min(2.0, float(ds.time[-1]))),
            title=f"Calugi (2002), Fig. {system.velocity_figure}: {system.label}, true and estimated velocities",
        )
        for filename, figure in figures.items():
            figure.savefig(out / filename, dpi=110)
            plt.close(figure)
            files.append(filename)
        systems[name] = summarize(ds, name, scenario.observer.model)
    summary = {
        **summary_header(NAME, config, status, runs=1, seeds=[config.seed]),
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
            errors.append(
                (f"{name} {joint}", significant(values["initial_error"]), significant(values["final_error"]), "-" if rate is None else f"{rate:.3f}")
            )
        report = system["theorem_2_1"]
        numbers = report["quantities"]
        radius = numbers["radius"]
        theorem.append(
            (
                name,
                f"{numbers['effective_gain']:.3g}",
                f"{numbers['threshold']:.3g}",
                report["verdicts"]["theorem_2_1"],
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


#: Calugi (2002), Section 2.3: the reduced-order velocity observer on four manipulators.
REPRODUCTION = Reproduction(NAME, Config, CASES, composition, run, tables)
