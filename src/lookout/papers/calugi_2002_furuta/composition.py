"""The experiments of chapter 6 as compositions (:mod:`lookout.scenario.composition`), and their simulation."""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Callable

import xarray as xr

from lookout.components import JOINT_SPACE, Signal
from lookout.controllers.furuta import PENDULUM_REFERENCE
from lookout.models.furuta import PRINTED_CONSTANTS, PRINTED_COULOMB_FRICTION, FurutaConstants
from lookout.models.parameters import ModelParameters
from lookout.reference import ReferenceFilter
from lookout.scenario.composition import compose
from lookout.sim import Scenario, seed_keys, simulate

from .config import (
    AMPLITUDE,
    EXPERIMENTS,
    FILTER_BANDWIDTH,
    NAME,
    OBSERVER_GAIN,
    PERIOD,
    POSITION_DAMPING,
    POSITION_GAIN,
    QUANTIZATION,
    SAMPLE_PERIOD,
    TITLE,
    UNITS,
    UPRIGHT_START,
    VELOCITY_GAIN,
    Config,
    Experiment,
    experiment_duration,
)

#: The pendulum of (6.1)–(6.4) with the printed constants and tau_C (a ``model`` table).
PENDULUM = {
    "kind": "furuta-constants",
    "alpha": PRINTED_CONSTANTS[0],
    "beta": PRINTED_CONSTANTS[1],
    "gamma": PRINTED_CONSTANTS[2],
    "delta": PRINTED_CONSTANTS[3],
    "coulomb_friction": [PRINTED_COULOMB_FRICTION, 0.0],
    "friction": [0.0, 0.0],
}
#: The setpoint the controller reads (``pendulum_angle_desired``): a scalar, unwrapped angle,
#: none of the plant's variables (the hanging reference lives near pi, where a wrapped one would jump).
PENDULUM_ANGLE = {"name": PENDULUM_REFERENCE, "units": "rad", "long_name": "pendulum angle from the upward vertical", "frame": JOINT_SPACE}


@functools.cache
def parameters(unknowns: tuple[str, ...]) -> ModelParameters:
    """The unknowns of the printed model (the truth is the reference); cached, since the
    affinity check of the construction costs about 0.6 s."""
    return ModelParameters(FurutaConstants(), unknowns, units=tuple(UNITS[name] for name in unknowns))


def reference_table(experiment: Experiment, duration: float) -> dict:
    """theta_d = 27/(s + 3)^3 r over the unwrapped :data:`PENDULUM_ANGLE` (a ``reference``
    table): hanging, r = pi + 0.6 sgn(cos(2 pi t / 2.5)) from pi; upright, r = 0 from 0.02 rad."""
    if experiment.upright:
        return {
            "kind": "reference-filter",
            "signals": [copy.deepcopy(PENDULUM_ANGLE)],
            "bandwidth": FILTER_BANDWIDTH,
            "schedule_times": [0.0],
            "setpoints": [[0.0]],
            "initial": [UPRIGHT_START],
        }
    quarter, half = PERIOD / 4.0, PERIOD / 2.0
    switches = int(math.ceil((duration - quarter) / half)) + 1
    times = [0.0] + [quarter + k * half for k in range(switches)]
    setpoints = [[math.pi + AMPLITUDE * (1 if k % 2 == 0 else -1)] for k in range(len(times))]
    return {
        "kind": "reference-filter",
        "signals": [copy.deepcopy(PENDULUM_ANGLE)],
        "bandwidth": FILTER_BANDWIDTH,
        "schedule_times": times,
        "setpoints": setpoints,
        "initial": [math.pi],
    }


def composition(config: Config, case: str) -> dict:
    """Experiment ``case`` (a key of :data:`EXPERIMENTS`) as a composition: the pendulum with
    stick-slip arm friction, the quantizing encoders, the observer (4.34)–(4.35) with resetting
    (4.45) on the plant's constants with the experiment's unknowns, and the law (6.9)–(6.11)
    on the same model, tracking :func:`reference_table`. Exp. III's printed bounds let M_hat
    lose positive definiteness: its observer is built without that check (``check_bounds``)."""
    if case not in EXPERIMENTS:
        raise ValueError(f"experiment must be one of {', '.join(EXPERIMENTS)}; got {case!r}")
    experiment = EXPERIMENTS[case]
    duration = experiment_duration(config, case)
    observer = {
        "kind": "adaptive-manipulator",
        "parameters": {"kind": "model-fields", "fields": list(experiment.unknowns), "units": [UNITS[name] for name in experiment.unknowns]},
        "gain": OBSERVER_GAIN,
        "adaptation_gain": list(experiment.adaptation_gain),
        "sample_period": SAMPLE_PERIOD,
        "margin": experiment.margin,
        "initial": {"velocity": [0.0, 0.0], "theta": list(experiment.initial)},
    }
    if experiment.lower is not None and experiment.upper is not None:  # the experiments give both bounds or neither
        observer.update(lower=list(experiment.lower), upper=list(experiment.upper))
    if case == "III":
        observer["check_bounds"] = False
    return {
        "simulation": {
            "runs": config.runs,
            "seed": config.seed,
            "plant_step": config.plant_step,
            "sample_period": SAMPLE_PERIOD,
            "duration": duration,
        },
        "plant": {
            "kind": "furuta",
            "model": copy.deepcopy(PENDULUM),
            "initial": {"q": [0.0, UPRIGHT_START if experiment.upright else math.pi], "qdot": [0.0, 0.0]},
        },
        "sensor": {"kind": "joint-encoder", "sample_period": SAMPLE_PERIOD, "quantization": list(QUANTIZATION)},
        "observer": observer,
        "reference": reference_table(experiment, duration),
        "controller": {
            "kind": "furuta-backstepping",
            "position_gain": POSITION_GAIN,
            "position_damping": POSITION_DAMPING,
            "velocity_gain": VELOCITY_GAIN,
            "velocity_damping": experiment.damping,
        },
    }


def build(config: Config, name: str) -> Scenario:
    """The closed loop of experiment ``name`` (a key of :data:`EXPERIMENTS`)."""
    return compose(composition(config, name)).scenario


def reference(experiment: Experiment, duration: float) -> ReferenceFilter:
    """The reference filter of :func:`reference_table`."""
    table = reference_table(experiment, duration)
    signal = table.pop("signals")[0]
    del table["kind"]
    return ReferenceFilter((Signal(**signal),), **table)


def simulate_case(config: Config, case: str, *, progress: Callable | None = None) -> tuple[Scenario, xr.Dataset]:
    """Simulate experiment ``case`` (run 0 only): its scenario and the Dataset :func:`run` writes."""
    scenario = build(config, case)
    ds = simulate(scenario, seed_keys(config.seed, 1)[0], progress=progress).to_xarray().isel(run=0)
    ds.attrs.update({"reproduction": NAME, "title": TITLE, "experiment": case, "config": config.model_dump_json()})
    return scenario, ds
