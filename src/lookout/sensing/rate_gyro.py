"""A rate-of-turn sensor: the yaw rate a rate gyro or a rate-of-turn indicator gives
(the ROT sentence of NMEA 0183)."""

from __future__ import annotations

from typing import Any, final

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from lookout import _validation as check
from lookout.components import Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Value, component
from lookout.sensing.instrument import SOURCE, GaussMarkovError, Instrument, gauss_markov, period_value, source_value
from lookout.sensing.motion import ANGULAR_RATE


@component(
    "instrument",
    "rate-gyro",
    summary="A rate gyro or rate-of-turn indicator: the yaw rate with white noise and an optional slowly drifting bias.",
    parameters=(
        Value("noise_std", "float", "Standard deviation of the white noise (rad/s).", range=NON_NEGATIVE),
        Value("sample_period", "float", "Seconds between samples (s).", range=POSITIVE),
        Value("error_std", "float", "Stationary standard deviation of the drifting bias (rad/s); 0 for none.", range=NON_NEGATIVE),
        Value("error_time_constant", "float", "Time constant of the drifting bias (s).", range=POSITIVE),
        SOURCE,
    ),
)
@final
class RateGyro(Instrument):
    """A rate gyro: the yaw rate r (a rigid hull turns at one rate wherever the sensor
    sits, so it has no lever arm), a first-order Gauss–Markov bias and white noise. A
    bridge's rate-of-turn indicator sends it as ROT in degrees per minute, positive when
    the bow turns to starboard (:mod:`lookout.io.nmea`).

    Parameters
    ----------
    noise_std : float, non-negative
        Standard deviation of the white noise (rad/s).
    sample_period : float, positive
        Seconds between samples (s).
    error_std : float, non-negative
        Stationary standard deviation of the drifting bias (rad/s); 0 for none.
    error_time_constant : float, positive
        Time constant of the drifting bias (s).
    source : str, optional
        Where lookout live and lookout replay take its readings from: a talker ID, a sender or both
        (GP, @10.0.0.5, GP@10.0.0.5); simulation ignores it.
    """

    noise: Array
    error: GaussMarkovError
    sample_period: float = eqx.field(static=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(ANGULAR_RATE,), kw_only=True)
    noise_count: int = eqx.field(static=True, default=2, kw_only=True)
    source: str | None = eqx.field(static=True, default=None, kw_only=True)

    def __init__(
        self,
        noise_std: float = 0.0005,
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
        return jnp.reshape(kinematics["yaw_rate"], (1,))

    def noise_std(self) -> Array:
        return jnp.reshape(self.noise, (1,))

    def measurement_std(self) -> Array:
        """The white noise widened by the drifting bias's stationary variance
        (:meth:`Instrument.measurement_std`)."""
        return self.error.widened(self.noise_std())


__all__ = ["RateGyro"]
