"""What every member of a sensor suite provides: named channels sampled at one rate
from the plant's kinematics, with white noise the suite's failures can act on.

An instrument is one device: a GNSS receiver, a gyrocompass, an IMU. It measures the
kinematics of a vessel (:func:`lookout.vessel_signals.vessel_kinematics`: position,
heading, velocity, yaw rate, acceleration) at its lever arm, and may carry a memory
of its own (a Gauss–Markov error). A :class:`~lookout.sensing.suite.SensorSuite`
names its instruments, prefixes their channels with the name (``dgnss1.measured_position``),
holds their samples between their sampling instants and applies their failures.
"""

from __future__ import annotations

import abc
import math
from typing import Any, ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array

from lookout import _validation as check
from lookout._math import rotation
from lookout.components import Signal
from lookout.declare import Value

#: What a position reference contributes to a combining stage, what a heading
#: reference does, and what an instrument that is neither does.
POSITION, HEADING, OTHER = "position", "heading", "other"


class Instrument(eqx.Module):
    """One device of a sensor suite (abstract).

    Attributes
    ----------
    signals : tuple of Signal
        Its channels, unprefixed (``measured_position``), in order.
    sample_period : float
        Seconds between its samples (static: fixes the loop's structure).
    noise_count : int
        Standard normals it draws per sample (static).
    provides : str
        :data:`POSITION`, :data:`HEADING` or :data:`OTHER`: what a combining stage takes of it.
    """

    signals: eqx.AbstractVar[tuple[Signal, ...]]
    sample_period: eqx.AbstractVar[float]
    noise_count: eqx.AbstractVar[int]
    provides: ClassVar[str] = OTHER

    @property
    def size(self) -> int:
        """Number of channels."""
        return sum(signal.size for signal in self.signals)

    @abc.abstractmethod
    def initial_memory(self, kinematics: dict[str, Array]) -> Any:
        """The instrument's own memory before its first sample (``()`` for none)."""

    @abc.abstractmethod
    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        """``(memory, value, white)``: one sample is ``value + white``, ``white`` the
        white measurement noise (a ``noise`` failure scales it), ``value`` everything
        else (the kinematics at the lever arm and any slowly varying error)."""

    @abc.abstractmethod
    def expected(self, kinematics: dict[str, Array]) -> Array:
        """The noise-free, error-free sample (a Kalman filter's h)."""

    @abc.abstractmethod
    def noise_std(self) -> Array:
        """The standard deviation of each channel's white noise, in its units (what
        a ``noise`` failure scales; :meth:`measurement_std` adds a slow error's)."""

    def measurement_std(self) -> Array:
        """The standard deviation of each channel's error about :meth:`expected`, in its
        units, for a filter that models none of the instrument's memory (a Kalman
        filter's default R on a suite): the white noise (:meth:`noise_std`), and where the
        instrument has a slow Gauss–Markov error, its stationary variance added,
        ``sqrt(noise_std^2 + error_std^2)``.

        The time-correlated error is then taken as white of its stationary variance,
        its correlation in time neglected: the simplest treatment of a sequentially
        correlated measurement error, where the exact ones estimate it as a state or
        difference successive measurements (Bryson & Henrikson 1968, "Estimation using
        sampled data containing sequentially correlated noise", Journal of Spacecraft
        and Rockets 5(6), 662–665). Each sample's variance is then the error's, but the
        filter still averages successive fixes as if their errors were independent,
        which a slow error's are not: a variance inflation factor derived from the
        correlation widens R further (Kermarrec, Jain & Schön 2022, "Kalman filter and
        correlated measurement noise: the variance inflation factor", IEEE Transactions
        on Aerospace and Electronic Systems 58(2), 766–780). A constant bias (an IMU's)
        is left out: it is not a spread about zero."""
        return self.noise_std()

    def angles(self) -> tuple[bool, ...]:
        """Per channel: whether it is an angle (wrapped to [-pi, pi))."""
        return tuple(signal.angle for signal in self.signals for _ in range(signal.size))


#: The key that binds an instrument to the readings of a live stream (docs/live.md,
#: "Named sensors"): :func:`lookout.io.nmea.source_spec` spells it.
SOURCE = Value(
    "source",
    "str",
    "Where lookout live and lookout replay take its readings from: a talker ID, a sender or both (GP, @10.0.0.5, GP@10.0.0.5); simulation ignores it.",
)


def source_value(name: str, value: str | None) -> str | None:
    """A live source (:data:`SOURCE`), checked for its spelling; None for none."""
    if value is None:
        return None
    from lookout.io.nmea import source_spec  # here: a simulation never reads a stream

    try:
        source_spec(value)
    except ValueError as error:
        raise check.ParameterError(name, f"{name} {error}") from None
    return value


def lever_arm_vector(name: str, value: npt.ArrayLike) -> np.ndarray:
    """A lever arm ``[x, y]`` (m, body-fixed: forward, starboard) from a vessel's
    reference point, checked (finite, two entries)."""
    arm = np.asarray(value, dtype=float)
    if arm.shape != (2,) or not np.all(np.isfinite(arm)):
        raise check.ParameterError(name, f"{name} must be two finite numbers [x, y] (m, body-fixed, forward and starboard); got {check.short(value)}")
    return arm


def at_lever_arm(position: Array, heading: Array, arm: Array) -> Array:
    """Where a point at the body-fixed ``arm`` is, Earth-fixed: p + R(psi) r."""
    return position + rotation(heading)[:2, :2] @ arm


def period_value(name: str, value: float) -> float:
    """A sample period (s): finite and > 0."""
    number = float(value)
    if not (math.isfinite(number) and number > 0):
        raise check.ParameterError(name, f"{name} must be a finite number of seconds > 0; got {value}")
    return number


def whole_periods(name: str, value: float, period: float) -> int:
    """A delay (s), finite, >= 0 and a whole number of ``period``, as a number of periods."""
    number = float(value)
    ratio = number / period if math.isfinite(number) and number >= 0 else math.nan
    if not (math.isfinite(ratio) and abs(ratio - round(ratio)) <= 1e-9 * max(1.0, ratio)):
        raise check.ParameterError(name, f"{name} must be a whole number of the sample period ({period:g} s), >= 0; got {value}")
    return int(round(ratio))


def std_value(name: str, value: npt.ArrayLike, size: int) -> Array:
    """A standard deviation per channel (one number for all, or ``size``), >= 0."""
    std = np.broadcast_to(np.asarray(value, dtype=float), (size,)) if np.ndim(value) == 0 else np.asarray(value, dtype=float)
    if std.shape != (size,) or not (np.all(np.isfinite(std)) and np.all(std >= 0)):
        raise check.ParameterError(name, f"{name} must be {size} finite numbers >= 0 (or one for all); got {check.short(value)}")
    return jnp.asarray(std)


class GaussMarkovError(eqx.Module):
    """A first-order Gauss–Markov error e' = -e / T + w, sampled exactly at the
    instrument's rate: ``e_{k+1} = a e_k + sigma sqrt(1 - a^2) n_k``, ``a = exp(-h/T)``,
    with stationary standard deviation ``sigma`` (a GNSS receiver's multipath and
    atmospheric error, a gyrocompass's slow error). It starts at zero (a receiver
    just locked on) and reaches its stationary spread within a few time constants."""

    std: Array
    time_constant: Array
    step: float = eqx.field(static=True)

    def widened(self, noise_std: Array) -> Array:
        """``sqrt(noise_std^2 + std^2)`` per channel: a white noise of ``noise_std``
        widened by this error's stationary variance
        (:meth:`Instrument.measurement_std`); exactly ``noise_std`` where ``std`` is 0."""
        return jnp.hypot(noise_std, self.std)

    def advance(self, error: Array, normals: Array) -> Array:
        a = jnp.exp(-self.step / self.time_constant)
        return a * error + self.std * jnp.sqrt(1.0 - a * a) * normals


def gauss_markov(name: str, std: npt.ArrayLike, time_constant: float, step: float, size: int) -> GaussMarkovError:
    """A checked :class:`GaussMarkovError` of ``size`` channels (``name`` prefixes the keys)."""
    return GaussMarkovError(std_value(f"{name}_std", std, size), jnp.asarray(period_value(f"{name}_time_constant", time_constant)), float(step))
