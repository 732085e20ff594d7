"""The settings of the chapter 4 reproduction: the thesis's values and the stated choices."""

from __future__ import annotations

import math
from typing import Any

from pydantic import Field, field_validator

from lookout.models.manipulators import FreePendulum
from lookout.models.parameters import ModelParameters
from lookout.papers import CATALOG
from lookout.scenario.settings import NoiseFreeConfig, PositiveFloat, finite_positive, whole_samples

NAME = "calugi-2002-adaptive-observer"
TITLE = CATALOG[NAME].title
MASS, LENGTH = 1.0, 1.5
#: The cases' sample intervals Delta (s), and the order study's.
SAMPLE_PERIODS = (0.01, 0.001)
ORDER_PERIODS = (0.02, 0.01, 0.005, 0.0025)
#: The order study's horizon (s): within Fig. 4.2's window.
ORDER_DURATION = 20.0
#: The run in which the resets fire: Gamma, bounds l, h (kg) and mu (kg).
STRESS: dict[str, Any] = {"adaptation_gain": 1000.0, "bounds": (0.5, 1.5), "margin": 0.01}
REPORT_TIMES = (1.0, 10.0, 20.0, 50.0)


class Config(NoiseFreeConfig):
    """Settings of the reproduction; every field has the thesis's value or a stated choice."""

    duration: float = Field(default=300.0, description="simulated time (s); Fig. 4.3's long run")
    gain: PositiveFloat = Field(default=20.0, description="K (1/s)")
    adaptation_gain: PositiveFloat = Field(default=10.0, description="Gamma")
    initial_mass: PositiveFloat = Field(default=0.1, description="theta_hat(0) (kg)")
    input_amplitude: float = Field(default=1.0, description="tau = A sin(w t): A (N m), chosen")
    input_frequency: PositiveFloat = Field(default=1.0, description="tau = A sin(w t): w (rad/s), chosen")
    bounds: tuple[float, float] = Field(default=(0.05, 5.0), description="resetting bounds [l, h] of m (kg), chosen")
    margin: float = Field(default=0.01, description="resetting margin mu (kg), chosen")
    sweep: bool = Field(default=True, description="the studies: the order against the continuous observer, and the run in which the resets fire")

    @field_validator("duration")
    @classmethod
    def _duration(cls, value):
        finite_positive(value)
        whole_samples(value, 0.1, "the 0.1 s record period")
        if value < 20.0:
            raise ValueError(f"must be at least 20 s (Fig. 4.2's window); got {value:g} s")
        return value

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
    """theta = m of the pendulum (m = 1 kg, l = 1.5 m, no friction), as the observer of
    :func:`closed_loop` has it."""
    return ModelParameters(FreePendulum(MASS, LENGTH, 0.0), ("mass",), units=("kg",))


#: The cases, one per sample interval Delta (s) of :data:`SAMPLE_PERIODS`; the first is the default.
CASES: tuple[str, ...] = tuple(f"delta-{period:g}" for period in SAMPLE_PERIODS)
