"""The three conditions of Section 5 as compositions (:mod:`lookout.scenario.composition`), and
compositions changed key by key for the studies."""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

from lookout.models.cybership import CYBERSHIP_LENGTH, CYBERSHIP_THRUST_LIMIT
from lookout.papers.wondergem_2009.config import (
    BASIN_MEASUREMENT_PERIOD,
    BASIN_PERIOD,
    CONDITIONS,
    DAMPING_RATIO,
    INITIAL_ETA,
    INITIAL_ETA_HAT,
    INITIAL_VELOCITY_HAT,
    LAP_SPEEDS,
    NATURAL_FREQUENCY,
    OBSERVER_POSITION_GAIN,
    OBSERVER_VELOCITY_GAIN,
    PLANT_STEP,
    Config,
)
from lookout.scenario.composition import compose, set_path

if TYPE_CHECKING:
    from lookout.sim import Scenario

#: The scheme's model in the basin: Cybership II of (39) with linear damping only.
LINEAR_SHIP = {"kind": "cybership-ii", "quadratic_damping": [0.0, 0.0, 0.0]}
#: The basin's thrust limits (surge N, sway N, yaw N m).
THRUST_LIMITS = {"kind": "thrust-limits", "limit": list(CYBERSHIP_THRUST_LIMIT)}
#: No thrust limits: the simulation condition.
NO_LIMITS = {"kind": "ideal"}


def composition(config: Config, case: str) -> dict:
    """The closed loop of Section 5 under the condition ``case`` (one of :data:`CONDITIONS`).

    Every condition: Cybership II of (39) as the plant, the observer (6) with the
    printed L1 = 15 I, L2 = 50 I, the controller (18) evaluated on the estimates as
    (23) with the printed Omega and Lambda = I (20), the ellipse of four laps at
    :data:`LAP_SPEEDS`, and Section 5's initial state and estimate.

    * ``simulation``: the scheme's model is the plant's (D_n in both), no noise, no
      thrust limits, the observer integrated with the plant (``observer_mode =
      "continuous"``) and the controller sampled every 0.01 s; every 10th step recorded.
    * ``basin-calm``: the scheme's model has linear damping only, the thrust limits,
      observer and controller by forward Euler at 20 Hz, position and heading at 10 Hz
      with ``config.noise_std``.
    * ``basin-waves``: ``basin-calm`` in JONSWAP waves of ``config.wave_height`` and
      ``config.wave_period`` (gamma = 3.3, along +x, a hull of Cybership II's length).
    """
    if case not in CONDITIONS:
        raise ValueError(f"case must be one of {', '.join(CONDITIONS)}; got {case!r}")
    basin = case != "simulation"
    plant = {"kind": "cybership-ii", "ship": {"kind": "cybership-ii"}, "initial": {"eta": list(INITIAL_ETA)}}
    if case == "basin-waves" and config.wave_height > 0:
        plant["waves"] = {
            "kind": "jonswap",
            "significant_height": config.wave_height,
            "mean_period": config.wave_period,
            "hull_length": CYBERSHIP_LENGTH,
        }
    observer = {
        "kind": "earth-fixed",
        "position_gain": OBSERVER_POSITION_GAIN,
        "velocity_gain": OBSERVER_VELOCITY_GAIN,
        "method": "euler" if basin else "rk4",
        "initial_velocity": config.initial_velocity,
        "initial": {"eta": list(INITIAL_ETA_HAT), "velocity": list(INITIAL_VELOCITY_HAT)},
    }
    controller = {"kind": "tracking", "natural_frequency": list(NATURAL_FREQUENCY), "damping_ratio": DAMPING_RATIO}
    if basin:  # the scheme's own model: without a table, observer and controller take the plant's ship
        observer["ship"] = dict(LINEAR_SHIP)
        controller["ship"] = dict(LINEAR_SHIP)
    return {
        "simulation": {
            "runs": config.runs,
            "seed": config.seed,
            "batch": "stacked",
            "plant_step": PLANT_STEP,
            "sample_period": BASIN_PERIOD if basin else PLANT_STEP,
            "duration": config.duration,
            # basin: every 0.05 s step (the 10 Hz hold makes the thrust alternate at 10 Hz)
            "record_every": 1 if basin else 10,
            "observer_mode": "sampled" if basin else "continuous",
        },
        "plant": plant,
        "sensor": {
            "kind": "position-heading",
            "noise_std": list(config.noise_std) if basin else [0.0, 0.0, 0.0],
            "sample_period": BASIN_MEASUREMENT_PERIOD if basin else PLANT_STEP,
        },
        "observer": observer,
        "reference": {
            "kind": "ellipse",
            "semi_axes": list(config.semi_axes),
            "lap_speeds": list(LAP_SPEEDS),
            "start_angle": config.start_angle,
            "direction": config.direction,
        },
        "controller": controller,
        "actuator": dict(THRUST_LIMITS if basin else NO_LIMITS),
    }


def changed(document: dict, changes: dict) -> dict:
    """A copy of ``document`` with ``changes`` (key paths such as ``reference.start_angle``,
    or a whole table: ``actuator``) set."""
    result = copy.deepcopy(document)
    for path, value in changes.items():
        if "." in path:
            set_path(result, path, copy.deepcopy(value))
        else:
            result[path] = copy.deepcopy(value)
    return result


def scenario(config: Config, case: str, changes: dict | None = None) -> Scenario:
    """The :class:`~lookout.sim.Scenario` of ``case``, with ``changes`` (:func:`changed`)."""
    return compose(changed(composition(config, case), changes or {})).scenario
