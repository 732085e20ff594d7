"""The settings of the chapter 6 reproduction and the experiments' table (the module
docstring of :mod:`lookout.papers.calugi_2002_furuta`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydantic import Field, field_validator

from lookout.models.furuta import PRINTED_CONSTANTS, PRINTED_COULOMB_FRICTION
from lookout.papers import CATALOG
from lookout.scenario.settings import NoiseFreeConfig, finite_positive, whole_samples
from lookout.sim import integer_ratio

NAME = "calugi-2002-furuta"
TITLE = CATALOG[NAME].title
SAMPLE_PERIOD = 0.0075
PLANT_STEP = 0.00025
#: Encoder resolution (rad): arm phi, pendulum theta (printed).
QUANTIZATION = (0.01, 0.001)
#: K of (4.34) (1/s), on both joints.
OBSERVER_GAIN = 5.0
#: w of the reference filter (w / (s + w))^3 = 27/(s + 3)^3 (rad/s).
FILTER_BANDWIDTH = 3.0
#: Hanging reference: r = pi + AMPLITUDE sgn(cos(2 pi t / PERIOD)).
AMPLITUDE, PERIOD = 0.6, 2.5
UPRIGHT_START = 0.02
IV_DURATION = 20.0
#: c1, d1, c2 of (6.9)–(6.11) (1/s); d2 is the experiment's.
POSITION_GAIN, POSITION_DAMPING, VELOCITY_GAIN = 10.0, 1.0, 10.0
#: gamma^2 / beta: alpha_hat must exceed it for M_hat to be positive definite at every theta.
ALPHA_MINIMUM = PRINTED_CONSTANTS[2] ** 2 / PRINTED_CONSTANTS[1]
TRUTH = {"coulomb_friction[0]": PRINTED_COULOMB_FRICTION, "alpha": PRINTED_CONSTANTS[0]}
UNITS = {"coulomb_friction[0]": "N m", "alpha": "kg m2"}
SYMBOLS = {"coulomb_friction[0]": "tau_C", "alpha": "alpha"}


@dataclass(frozen=True)
class Experiment:
    """One row of the table in the module docstring."""

    name: str
    figures: str
    unknowns: tuple[str, ...]
    damping: float
    adaptation_gain: tuple[float, ...]
    initial: tuple[float, ...]
    lower: tuple[float, ...] | None
    upper: tuple[float, ...] | None
    margin: float
    upright: bool
    printed: bool
    note: str


EXPERIMENTS = {
    "I": Experiment(
        "I",
        "6.2–6.5",
        ("coulomb_friction[0]",),
        2.0,
        (0.0,),
        (PRINTED_COULOMB_FRICTION,),
        None,
        None,
        0.0,
        False,
        True,
        "ch. 2 observer (Gamma = 0), tau_C known",
    ),
    "II": Experiment("II", "6.6–6.9", ("coulomb_friction[0]",), 1.0, (0.01,), (0.001,), (0.001,), (0.04,), 1e-4, False, True, "tau_C adapted"),
    "III": Experiment(
        "III",
        "6.10–6.14",
        ("coulomb_friction[0]", "alpha"),
        1.0,
        (0.01, 0.001),
        (0.001, 1e-4),
        (0.001, 1e-4),
        (0.04, 5e-3),
        1e-5,
        False,
        True,
        "tau_C and alpha adapted, printed alpha_hat(0) = alpha_l = 1e-4",
    ),
    "III-fixed": Experiment(
        "III-fixed",
        "6.10–6.14",
        ("coulomb_friction[0]", "alpha"),
        1.0,
        (0.01, 0.001),
        (0.001, 0.002),
        (0.001, 0.002),
        (0.04, 5e-3),
        1e-5,
        False,
        False,
        "as III with alpha_hat(0) = alpha_l = 0.002 > gamma^2/beta",
    ),
    "IV": Experiment(
        "IV",
        "6.15–6.18",
        ("coulomb_friction[0]",),
        1.0,
        (0.003,),
        (0.001,),
        (0.001,),
        (0.04,),
        1e-4,
        True,
        True,
        "upright, printed tau_C_hat(0) = 0.001",
    ),
    "IV-fixed": Experiment(
        "IV-fixed",
        "6.15–6.18",
        ("coulomb_friction[0]",),
        1.0,
        (0.003,),
        (0.026,),
        (0.001,),
        (0.04,),
        1e-4,
        True,
        False,
        "upright, tau_C_hat(0) = 0.026 (Fig. 6.18's axis)",
    ),
}
#: The cases, one per experiment; the first is the default.
CASES: tuple[str, ...] = tuple(EXPERIMENTS)


class Config(NoiseFreeConfig):
    """Settings of the reproduction; every field has the thesis's value or a stated choice.
    The runs are noise-free (quantization only), so ``runs`` must be 1."""

    duration: float = Field(default=30.0, description="simulated time of I–III (s, figure axes); IV runs min(duration, 20 s)")
    experiments: tuple[str, ...] = Field(default=tuple(EXPERIMENTS), description="which experiments to run")
    plant_step: float = Field(default=PLANT_STEP, description="plant RK4 step (s), at most 0.25 ms, dividing 7.5 ms")

    @field_validator("duration")
    @classmethod
    def _duration(cls, value):
        finite_positive(value)
        return whole_samples(value, SAMPLE_PERIOD, "the 7.5 ms sample period")

    @field_validator("experiments")
    @classmethod
    def _experiments(cls, value):
        unknown = [name for name in value if name not in EXPERIMENTS]
        if unknown or not value or len(set(value)) != len(value):
            raise ValueError(f"must be distinct names among {', '.join(EXPERIMENTS)}; got {', '.join(value) or 'none'}")
        return value

    @field_validator("plant_step")
    @classmethod
    def _plant_step(cls, value):
        finite_positive(value)
        if value > PLANT_STEP * (1 + 1e-12) or integer_ratio(SAMPLE_PERIOD, value) is None:
            raise ValueError(f"must be at most 0.25 ms and divide the 7.5 ms sample period; got {value:g} s")
        return value


def experiment_duration(config: Config, name: str) -> float:
    """I–III: the configured duration; IV: the whole samples covering min(duration, 20 s)."""
    if not EXPERIMENTS[name].upright:
        return config.duration
    samples = math.ceil(min(config.duration, IV_DURATION) / SAMPLE_PERIOD - 1e-9)
    return samples * SAMPLE_PERIOD
