"""Kim (2002): the paper's numbers, the choices made where it is silent (the package
docstring lists them), the model error, and the reproduction's settings."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt
from pydantic import Field, ValidationInfo, field_validator

from lookout.environment import BodyDisturbance
from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_MASS, DPVessel
from lookout.observers import SlidingModeObserver, injection_gains_from_normalized
from lookout.papers import CATALOG
from lookout.papers._config import VesselSettings
from lookout.scenario.settings import PositiveCount, PositiveFloat, RunsConfig, Settings, finite_positive, whole_samples

NAME = "kim-2002"
TITLE = CATALOG[NAME].title

#: Kim (2002), (A.4): the observer's H3 and H4 (SI; the appendix swaps the labels of
#: observer and controller gains, NOTES.md) and Kbar.
BIAS_GAIN = (1e5, 1e5, 1e8)  # H3 = 1e6 diag(0.1, 0.1, 100)
VELOCITY_GAIN = (1e4, 1e4, 1e7)  # H4 = 1e5 diag(0.1, 0.1, 100)
SWITCHING_GAIN = (10.0, 10.0, 0.01)  # Kbar (m/s, m/s, rad/s)
#: Kim (2002), (A.2) and (A.3): bias time constants (s), the wave model and the notch.
BIAS_TIME_CONSTANT = (1000.0, 1000.0, 10000.0)
WAVE = {"wave_frequency": 0.8976, "wave_damping": 0.1, "notch_damping": 1.0, "cutoff_frequency": 1.1}

#: The two observers of Fig. 8: with and without the switching term, same controller.
OBSERVERS = ("sliding-mode", "conventional")
#: Setpoint schedule (time s, [north m, east m, heading rad]), through the reference filter.
WAYPOINTS = (
    (0.0, (0.0, 0.0, 0.0)),
    (200.0, (30.0, 0.0, 0.0)),
    (800.0, (30.0, 30.0, 0.2)),
    (1400.0, (0.0, 30.0, 0.2)),
    (2000.0, (0.0, 0.0, 0.0)),
)
#: Lever arm (m) of the unmodelled yaw moment: N = 5 m x F.
FORCE_LEVER_ARM = 5.0
#: A run has diverged when its low-frequency position leaves the reference, or its
#: position estimate leaves the true position, by more than this (m) at any time.
DIVERGED_DISTANCE = 100.0


def printed_observer(vessel: DPVessel, *, boundary_layer: npt.ArrayLike, **overrides: Any) -> SlidingModeObserver:
    """The sliding-mode observer with the printed gains of (A.2)–(A.4) for ``vessel``;
    ``overrides`` replace any of them (keywords of :meth:`SlidingModeObserver.from_gains`).
    The boundary layer eps is not given in the paper: it must be chosen."""
    settings = {
        **WAVE,
        "velocity_injection_gain": VELOCITY_GAIN,
        "bias_injection_gain": BIAS_GAIN,
        "bias_time_constant": BIAS_TIME_CONSTANT,
        "switching_gain": SWITCHING_GAIN,
        "boundary_layer": boundary_layer,
        **overrides,
    }
    return SlidingModeObserver.from_gains(vessel, **settings)


def gain_sets(mass: float = NORTHERN_CLIPPER_MASS, length: float = NORTHERN_CLIPPER_LENGTH) -> dict[str, dict]:
    """Observer bias and velocity injection gains H3, H4 (SI): printed (the paper's
    numbers, for its vessel), and satisfying (14) (Fossen & Strand's normalized gains
    (60) scaled to SI with the vessel's ``mass`` and ``length``)."""
    kappa, lam = injection_gains_from_normalized((0.1, 0.1, 0.01), (0.01, 0.01, 0.001), mass=mass, length=length)
    return {
        "printed": {"bias_injection_gain": BIAS_GAIN, "velocity_injection_gain": VELOCITY_GAIN},
        "kyp": {"bias_injection_gain": tuple(float(v) for v in lam), "velocity_injection_gain": tuple(float(v) for v in kappa)},
    }


class ModelError(Settings):
    """How the plant differs from the observer's and controller's model."""

    mass: float = Field(default=0.2, description="relative error of M: M_true = (1 + mass) M")
    damping: float = Field(default=0.5, description="relative error of D: D_true = (1 + damping) D")
    force: float = Field(default=4000.0, description="unmodelled body-fixed force F (N): F [1, 1, 5 m] (1 + sin(2 pi t / period)) / 2")
    force_period: PositiveFloat = Field(default=100.0, description="period of the unmodelled force (s)")

    @field_validator("mass", "damping")
    @classmethod
    def _above_minus_one(cls, value):
        if not (math.isfinite(value) and value > -1.0):
            raise ValueError(f"must be a finite number above -1 (the true matrix stays positive); got {value:g}")
        return value

    @field_validator("force")
    @classmethod
    def _finite_non_negative(cls, value):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"must be a finite number >= 0; got {value:g}")
        return value

    def disturbance(self) -> BodyDisturbance:
        half = 0.5 * self.force * np.array([1.0, 1.0, FORCE_LEVER_ARM])
        return BodyDisturbance(constant=half, amplitude=half, period=self.force_period)


class Config(RunsConfig):
    """Settings of the reproduction; every field has the paper's value or a stated choice."""

    runs: int = Field(default=1, description="Monte Carlo runs per observer (vmapped); run i uses seed + i")
    seed: int = Field(default=0, description="PRNG seed of run 0")
    plant_step: PositiveFloat = Field(default=0.1, description="RK4 step of the plant (s), the paper's 0.1 s")
    sample_period: PositiveFloat = Field(default=0.1, description="observer and controller period (s)")
    measurement_period: PositiveFloat = Field(default=1.0, description="position and heading fixes (s), as the Fossen & Strand reproduction")
    duration: PositiveFloat = Field(default=2600.0, description="simulated time (s)")
    gains: str = Field(default="printed", description="observer H3, H4: 'printed' (A.4) or 'kyp' (Fossen & Strand (60) in SI, satisfies (14))")
    vessel: VesselSettings = Field(
        default=VesselSettings(),
        description="the vessel: the paper's supply ship (Northern Clipper) or your own M and D (thrust limits stay the Northern Clipper's)",
    )
    boundary_layer: tuple[float, float, float] = (5.0, 5.0, float(np.radians(1.0)))
    integral_gain: float = Field(default=0.01, description="K_I (1/s); printed 100")
    position_gain: PositiveFloat = Field(default=0.1, description="C1 (1/s), (A.5)")
    velocity_gain: PositiveFloat = Field(default=0.1, description="C2 (1/s), (A.5)")
    coupling_gain: PositiveFloat = Field(default=0.01, description="P1 (1/s^2); 1 is Kim's law as printed")
    damping_weights: tuple[float, float, float, float, float, float] = (1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2)
    reference_bandwidth: PositiveFloat = Field(default=0.03, description="reference filter bandwidth (rad/s)")
    model_error: ModelError = ModelError()
    wave_amplitude: tuple[float, float, float] = (10.0, 10.0, float(np.radians(1.0)))
    bias_std: tuple[float, float, float] = (2e3, 2e3, 5e4)
    bias_initial: tuple[float, float, float] = (1e4, 5e3, 1e5)
    noise_std: tuple[float, float, float] = (0.5, 0.5, float(np.radians(0.1)))
    sweep: bool = Field(default=True, description="run the model-error sweep of the Fig. 8 claim")
    sweep_seeds: PositiveCount = Field(default=2, description="seeds per point of the sweep")
    sweep_duration: PositiveFloat = Field(default=1400.0, description="simulated time of each sweep run (s)")

    @field_validator("integral_gain")
    @classmethod
    def _non_negative(cls, value):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"must be a finite number >= 0; got {value:g}")
        return value

    @field_validator("gains")
    @classmethod
    def _known_gains(cls, value):
        if value not in ("printed", "kyp"):
            raise ValueError(f"must be 'printed' or 'kyp'; got {value!r}")
        return value

    @field_validator("boundary_layer", "wave_amplitude", "noise_std", "bias_std")
    @classmethod
    def _positive_triple(cls, value):
        for item in value:
            finite_positive(item)
        return value

    @field_validator("duration", "sweep_duration")
    @classmethod
    def _whole(cls, value, info: ValidationInfo):
        whole_samples(value, info.data.get("sample_period"))
        fixes = info.data.get("measurement_period")
        if fixes is not None:
            whole_samples(value, fixes, "the measurement period")
        if value < 100.0:
            raise ValueError(f"must be at least 100 s; got {value:g} s")
        return value
