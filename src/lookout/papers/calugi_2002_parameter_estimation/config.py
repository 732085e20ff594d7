"""The settings of the chapter 3 reproduction and the thesis's runs: the printed and the
chosen numbers of Sims 1 and 2, and the two runs without excitation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import ConfigDict, Field, ValidationInfo, field_validator

from lookout.papers import CATALOG
from lookout.scenario.settings import NoiseFreeConfig, PositiveFloat, whole_samples

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
    """One run: which parameters (a ``parameters`` table of a composition, on the
    frictionless pendulum), the truth over time, gain h, initial conditions, input."""

    label: str
    parameters: dict
    values: tuple[tuple[float, ...], ...]
    switch_times: tuple[float, ...]
    gain: float
    initial_position: float
    initial_velocity: float
    initial_estimate: tuple[float, ...]
    excited: bool


def _pendulum(mass: float) -> dict:
    """The frictionless pendulum of mass ``mass`` and length :data:`LENGTH` as a ``model`` table."""
    return {"kind": "pendulum", "mass": mass, "length": LENGTH, "friction": 0.0}


#: Sim 1, theta = m (3.13), m piecewise constant; Sim 2, theta = (m l^2, m l) (3.16).
SIM1_PARAMETERS = {"kind": "model-fields", "base": _pendulum(SIM1_MASSES[0]), "fields": ["mass"], "units": ["kg"]}
SIM2_PARAMETERS = {"kind": "pendulum-inertia", "base": _pendulum(SIM2_MASS)}
_SIM1_VALUES = tuple((mass,) for mass in SIM1_MASSES)
_SIM2_VALUES = ((SIM2_MASS * LENGTH**2, SIM2_MASS * LENGTH),)

#: The four runs: Sims 1 and 2 of Section 3.2, and each without excitation (tau = 0).
SIMULATIONS = {
    "sim1": Simulation("Sim 1: theta = m, piecewise constant", SIM1_PARAMETERS, _SIM1_VALUES, SIM1_SWITCH_TIMES, 10.0, 1.0, 0.0, (1.0,), True),
    "sim2": Simulation("Sim 2: theta = (m l^2, m l)", SIM2_PARAMETERS, _SIM2_VALUES, (), 100.0, 0.0, 0.0, (4.5, 2.0), True),
    "sim1_free_swing": Simulation(
        "Sim 1 with tau = 0 (free swing from q(0) = 1 rad)", SIM1_PARAMETERS, _SIM1_VALUES, SIM1_SWITCH_TIMES, 10.0, 1.0, 0.0, (1.0,), False
    ),
    "sim2_rest": Simulation("Sim 2 with tau = 0 at rest", SIM2_PARAMETERS, _SIM2_VALUES, (), 100.0, 0.0, 0.0, (4.5, 2.0), False),
}
#: The cases, one per run of :data:`SIMULATIONS`; the first is the default.
CASES: tuple[str, ...] = tuple(SIMULATIONS)


class Config(NoiseFreeConfig):
    """Settings of the reproduction; the runs themselves are :data:`SIMULATIONS`."""

    # defaults are validated too: a changed plant_step must still divide the default sample_period
    model_config = ConfigDict(validate_default=True)  # merged with Settings: frozen, strict, no unknown keys

    plant_step: PositiveFloat = Field(default=2e-4, description="RK4 step of plant and estimator (s); Sim 2 is stiff")
    sample_period: PositiveFloat = Field(default=1e-2, description="input hold and record period (s)")
    input_amplitude: float = Field(default=5.0, description="tau = amplitude sin(frequency t) (N m), chosen")
    input_frequency: PositiveFloat = Field(default=1.0, description="rad/s, chosen")
    filter_pole: PositiveFloat = Field(default=1.0, description="a of the filter 1/(s + a) (rad/s); the thesis's 1")
    pe_window: PositiveFloat = Field(default=5.0, description="T of the persistence-of-excitation check (s)")
    duration: PositiveFloat = Field(default=60.0, description="simulated time per run (s)")

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
