"""Section 4.8's closed loop as compositions (:mod:`lookout.scenario.composition`): the cases, the
order study's and the stress run's, and their simulation."""

from __future__ import annotations

import math
from collections.abc import Callable

import xarray as xr

from lookout.scenario.composition import compose
from lookout.sim import Scenario, seed_keys, simulate

from .config import CASES, LENGTH, MASS, NAME, ORDER_DURATION, ORDER_PERIODS, SAMPLE_PERIODS, STRESS, TITLE, Config


def closed_loop(config: Config, sample_period: float) -> dict:
    """The closed loop of Section 4.8 at Delta = ``sample_period`` as a composition
    (:mod:`lookout.scenario.composition`): the frictionless pendulum, the encoder of q, the observer
    (4.34)–(4.35) with resetting (4.45) on the plant's pendulum with m unknown, and
    tau = A sin(w t); the plant by RK4 at the largest step <= 1 ms that divides Delta,
    recorded every 0.1 s."""
    low, high = config.bounds
    return {
        "simulation": {
            "runs": config.runs,
            "seed": config.seed,
            "plant_step": sample_period / math.ceil(sample_period / 1e-3 - 1e-9),
            "sample_period": sample_period,
            "duration": config.duration,
            "record_every": max(1, int(round(0.1 / sample_period))),
        },
        "plant": {
            "kind": "manipulator",
            "model": {"kind": "pendulum", "mass": MASS, "length": LENGTH, "friction": 0.0},
            "initial": {"q": [0.0], "qdot": [-1.0]},
        },
        "sensor": {"kind": "joint-encoder", "sample_period": sample_period},
        "observer": {
            "kind": "adaptive-manipulator",
            "parameters": {"kind": "model-fields", "fields": ["mass"], "units": ["kg"]},
            "gain": config.gain,
            "adaptation_gain": config.adaptation_gain,
            "sample_period": sample_period,
            "lower": [low],
            "upper": [high],
            "margin": config.margin,
            "initial": {"velocity": [0.0], "theta": [config.initial_mass]},
        },
        "controller": {"kind": "sinusoidal", "amplitude": config.input_amplitude, "frequency": config.input_frequency},
    }


def composition(config: Config, case: str) -> dict:
    """Case ``case`` (one of :data:`CASES`) as a composition: :func:`closed_loop` at its Delta."""
    return closed_loop(config, SAMPLE_PERIODS[CASES.index(case)])


def order_composition(config: Config, sample_period: float, duration: float) -> dict:
    """:func:`closed_loop` at Delta over ``duration``, every sample recorded (the order study)."""
    document = closed_loop(config, sample_period)
    document["simulation"].update(duration=duration, record_every=1)
    return document


def stress_composition(config: Config) -> dict:
    """:func:`closed_loop` at 10 ms with the :data:`STRESS` settings, over min(duration, 50 s)."""
    document = closed_loop(config, SAMPLE_PERIODS[0])
    low, high = STRESS["bounds"]
    document["observer"].update(adaptation_gain=STRESS["adaptation_gain"], lower=[low], upper=[high], margin=STRESS["margin"])
    document["simulation"]["duration"] = min(config.duration, 50.0)
    return document


def study_compositions(config: Config) -> list[dict]:
    """The compositions :func:`run` simulates beyond the cases when ``config.sweep``: the order
    study at each Delta of :data:`ORDER_PERIODS` over :data:`ORDER_DURATION`, and the stress run."""
    return [order_composition(config, period, ORDER_DURATION) for period in ORDER_PERIODS] + [stress_composition(config)]


def build(config: Config, sample_period: float) -> Scenario:
    """The scenario of :func:`closed_loop` at Delta = ``sample_period``."""
    return compose(closed_loop(config, sample_period)).scenario


def simulate_document(document: dict, *, progress: Callable | None = None) -> xr.Dataset:
    """One noise-free run of the composition ``document`` (its seed), as a Dataset."""
    scenario = compose(document).scenario
    return simulate(scenario, seed_keys(document["simulation"]["seed"], 1)[0], progress=progress).to_xarray()


def simulate_case(config: Config, case: str, *, progress: Callable | None = None) -> xr.Dataset:
    """Simulate case ``case``: the Dataset :func:`run` writes."""
    ds = simulate_document(composition(config, case), progress=progress)
    ds.attrs.update({"reproduction": NAME, "title": TITLE, "sample_period_s": SAMPLE_PERIODS[CASES.index(case)], "config": config.model_dump_json()})
    return ds
