"""Heading references: gyrocompasses."""

from __future__ import annotations

from typing import Any, ClassVar, final

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from lookout import _validation as check
from lookout.components import EARTH_FIXED, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Value, component
from lookout.sensing.instrument import HEADING, SOURCE, GaussMarkovError, Instrument, gauss_markov, period_value, source_value

MEASURED_HEADING = Signal("measured_heading", "rad", "measured heading", EARTH_FIXED, angle=True)


@component(
    "instrument",
    "gyrocompass",
    summary="A gyrocompass: the heading with white noise and an optional slow Gauss-Markov error, wrapped to [-pi, pi).",
    parameters=(
        Value("noise_std", "float", "Standard deviation of the white noise (rad).", range=NON_NEGATIVE),
        Value("sample_period", "float", "Seconds between samples (s).", range=POSITIVE),
        Value("error_std", "float", "Stationary standard deviation of the slow error (rad); 0 for none.", range=NON_NEGATIVE),
        Value("error_time_constant", "float", "Time constant of the slow error (s).", range=POSITIVE),
        SOURCE,
    ),
)
@final
class Gyrocompass(Instrument):
    """A gyrocompass: the total heading psi + psi_w, a slow first-order Gauss–Markov
    error (settling and speed errors) and white noise, wrapped to [-pi, pi).

    Parameters
    ----------
    noise_std : float, non-negative
        Standard deviation of the white noise (rad).
    sample_period : float, positive
        Seconds between samples (s).
    error_std : float, non-negative
        Stationary standard deviation of the slow error (rad); 0 for none.
    error_time_constant : float, positive
        Time constant of the slow error (s).
    source : str, optional
        Where lookout live and lookout replay take its readings from: a talker ID, a sender or both
        (GP, @10.0.0.5, GP@10.0.0.5); simulation ignores it.
    """

    provides: ClassVar[str] = HEADING
    noise: Array
    error: GaussMarkovError
    sample_period: float = eqx.field(static=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(MEASURED_HEADING,), kw_only=True)
    noise_count: int = eqx.field(static=True, default=2, kw_only=True)
    source: str | None = eqx.field(static=True, default=None, kw_only=True)

    def __init__(
        self,
        noise_std: float = 0.002,
        sample_period: float = 0.1,
        error_std: float = 0.0,
        error_time_constant: float = 600.0,
        source: str | None = None,
    ):
        check.positive("noise_std", noise_std, allow_zero=True)
        self.noise = jnp.asarray(float(noise_std))
        self.sample_period = period_value("sample_period", sample_period)
        self.error = gauss_markov("error", error_std, error_time_constant, self.sample_period, 1)
        self.source = source_value("source", source)

    def initial_memory(self, kinematics: dict[str, Array]) -> Array:
        return jnp.zeros(1)

    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        return self.error.advance(memory, normals[1:2]), self.expected(kinematics) + memory, self.noise * normals[:1]

    def expected(self, kinematics: dict[str, Array]) -> Array:
        return jnp.reshape(kinematics["heading"], (1,))

    def noise_std(self) -> Array:
        return jnp.reshape(self.noise, (1,))

    def measurement_std(self) -> Array:
        """The white noise widened by the slow error's stationary variance
        (:meth:`Instrument.measurement_std`)."""
        return self.error.widened(self.noise_std())

    def heading_of(self, y: Array) -> Array:
        """The heading a sample says (rad)."""
        return y[0]


__all__ = ["Gyrocompass"]
