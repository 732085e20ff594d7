"""The runs of chapter 3 as compositions (:mod:`lookout.scenario.composition`), and their simulation."""

from __future__ import annotations

import copy
from collections.abc import Callable

import xarray as xr

from lookout.models.scheduled_parameters import ScheduledParameterPlant
from lookout.papers._reproduction import built_as
from lookout.scenario.composition import compose
from lookout.sim import Scenario, seed_keys, simulate

from .config import NAME, SIMULATIONS, TITLE, Config


def composition(config: Config, case: str) -> dict:
    """Run ``case`` (a key of :data:`SIMULATIONS`) as a composition: the pendulum with the
    scheduled parameters theta(t), measured q and q', the estimator (3.9) with the filter
    1/(s + a) on the plant's parameters, integrated jointly with the plant on the exact q
    and q' (``observer_mode = "continuous"``), under tau = A sin(w t) (A = 0 without excitation)."""
    sim = SIMULATIONS[case]
    return copy.deepcopy(
        {  # the document is the caller's: SIMULATIONS' tables stay as they are
            "simulation": {
                "runs": config.runs,
                "seed": config.seed,
                "plant_step": config.plant_step,
                "sample_period": config.sample_period,
                "duration": config.duration,
                "observer_mode": "continuous",
            },
            "plant": {
                "kind": "scheduled-parameters",
                "parameters": sim.parameters,
                "values": [list(row) for row in sim.values],
                "switch_times": list(sim.switch_times),
                "initial": {"q": [sim.initial_position], "qdot": [sim.initial_velocity]},
            },
            "sensor": {"kind": "joint-state", "sample_period": config.sample_period},
            "observer": {
                "kind": "parameter-estimator",
                "gain": sim.gain,
                "filter_pole": config.filter_pole,
                "initial": {"theta": list(sim.initial_estimate)},
            },
            "controller": {"kind": "sinusoidal", "amplitude": config.input_amplitude if sim.excited else 0.0, "frequency": config.input_frequency},
        }
    )


def build(config: Config, name: str) -> Scenario:
    """The scenario of run ``name`` (a key of :data:`SIMULATIONS`)."""
    return compose(composition(config, name)).scenario


def simulate_run(config: Config, name: str, *, progress: Callable | None = None) -> tuple[Scenario, xr.Dataset]:
    """Simulate run ``name`` of :data:`SIMULATIONS`; the Dataset gets the true parameters
    (``mass``; ``inertia`` and ``moment``) next to the estimates (``<name>_hat``)."""
    scenario = build(config, name)
    ds = simulate(scenario, seed_keys(config.seed, 1)[0], progress=progress).to_xarray()
    plant = built_as(scenario.plant, ScheduledParameterPlant, f"the plant of {name!r}")
    truth = plant.truth(ds.time.values)
    for signal in plant.parameter_layout.signals:
        ds[signal.name] = (
            ("run", "time"),
            truth[signal.name][None, :],
            {"units": signal.units, "long_name": signal.long_name, "frame": "", "angle": 0},
        )
    ds.attrs.update(
        {"reproduction": NAME, "simulation": SIMULATIONS[name].label, "title": TITLE, "config": config.model_dump_json(), "seed": config.seed}
    )
    return scenario, ds
