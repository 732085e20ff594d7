"""Position references of a DP vessel: GNSS receivers, a hydroacoustic reference and a
relative reference (a taut wire, or a laser or radar to a platform).

Each measures the position of a point on the vessel, its antenna or transducer or the
wire's attachment, at a body-fixed lever arm ``r`` from the vessel's reference point:
``p + R(psi) r`` with p and psi the total (low-frequency plus wave-frequency) position
and heading (:func:`lookout.vessel_signals.vessel_kinematics`). A combining stage takes
the reference point back as ``y - R(psi_m) r`` with a measured heading
(:meth:`PositionReference.reference_point`).
"""

from __future__ import annotations

import abc
from typing import Any, ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array

from lookout import _validation as check
from lookout.components import EARTH_FIXED, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Value, component
from lookout.sensing.instrument import (
    POSITION,
    SOURCE,
    GaussMarkovError,
    Instrument,
    at_lever_arm,
    gauss_markov,
    lever_arm_vector,
    period_value,
    source_value,
    whole_periods,
)
from lookout.vessel_signals import EARTH_AXES

MEASURED_POSITION = Signal("measured_position", "m", "measured position of the antenna or transducer", EARTH_FIXED, EARTH_AXES, "earth_axis")
MEASURED_OFFSET = Signal(
    "measured_offset", "m", "measured position of the attachment relative to the reference's fixed point", EARTH_FIXED, EARTH_AXES, "earth_axis"
)

LEVER_ARM = Value(
    "lever_arm",
    "array",
    "Body-fixed position [x, y] of the antenna or transducer from the vessel's reference point (m, forward and starboard).",
    shape="(2,)",
    broadcast=False,
)


class PositionReference(Instrument):
    """A position reference (abstract): two channels, north and east (m), of a point at
    :attr:`lever_arm`; a combining stage reads it through :meth:`reference_point`."""

    provides: ClassVar[str] = POSITION
    lever_arm: eqx.AbstractVar[Array]

    def reference_point(self, y: Array, heading: Array) -> Array:
        """The vessel's reference point from a sample ``y`` and a heading: its lever arm
        taken back, ``position(y) - R(psi) r``."""
        return self.position_of(y) - (at_lever_arm(jnp.zeros(2), heading, self.lever_arm))

    @abc.abstractmethod
    def position_of(self, y: Array) -> Array:
        """The Earth-fixed position (north, east) a sample ``y`` says the point at the lever arm is at."""

    def weight_std(self) -> Array:
        """The standard deviation (m) a combining stage weights this reference by: the
        root mean square over its axes of :meth:`measurement_std` (its white noise, and
        a GNSS receiver's slow error), the spread a Kalman filter's default R states."""
        return jnp.sqrt(jnp.mean(self.measurement_std() ** 2))

    def std_at(self, y: Array) -> Array:
        """The standard deviation (m) of a fix ``y`` as the reference states it at that
        fix: :meth:`weight_std`, the same for every fix, unless the reference's noise
        depends on where it is (a hydroacoustic reference's slant range); a non-finite
        ``y`` gives :meth:`weight_std`."""
        return self.weight_std()


@component(
    "instrument",
    "gnss",
    summary="A GNSS (DGNSS) position reference at a lever arm: white noise and an optional Gauss-Markov error.",
    parameters=(
        LEVER_ARM,
        Value("noise_std", "float", "Standard deviation of the white noise per axis (m).", range=NON_NEGATIVE),
        Value("sample_period", "float", "Seconds between fixes (s).", range=POSITIVE),
        Value(
            "error_std",
            "float",
            "Stationary standard deviation of the Gauss-Markov error per axis (multipath, atmosphere; m); 0 for none.",
            range=NON_NEGATIVE,
        ),
        Value("error_time_constant", "float", "Time constant of the Gauss-Markov error (s).", range=POSITIVE),
        Value(
            "latency",
            "float",
            "Age of each fix when it is given (s): a whole number of sample periods; 0 for none.",
            range=NON_NEGATIVE,
        ),
        SOURCE,
    ),
)
@final
class GnssReceiver(PositionReference):
    """A GNSS (DGNSS) position reference: the antenna's position plus a first-order
    Gauss–Markov error (multipath and atmosphere, time constant of minutes) and white noise,
    given ``latency`` seconds after the instant it is of (the receiver's computation and
    the link; before the run the vessel is taken to have rested at its initial position).
    A Kalman filter's h takes the fix as current: a latency is a model error it does not know.

    Parameters
    ----------
    lever_arm : array_like, shape (2,)
        Body-fixed position [x, y] of the antenna or transducer from the vessel's reference point (m, forward and starboard).
    noise_std : float, non-negative
        Standard deviation of the white noise per axis (m).
    sample_period : float, positive
        Seconds between fixes (s).
    error_std : float, non-negative
        Stationary standard deviation of the Gauss-Markov error per axis (multipath, atmosphere; m); 0 for none.
    error_time_constant : float, positive
        Time constant of the Gauss-Markov error (s).
    latency : float, non-negative
        Age of each fix when it is given (s): a whole number of sample periods; 0 for none.
    source : str, optional
        Where lookout live and lookout replay take its readings from: a talker ID, a sender or both
        (GP, @10.0.0.5, GP@10.0.0.5); simulation ignores it.
    """

    lever_arm: Array
    noise: Array
    error: GaussMarkovError
    sample_period: float = eqx.field(static=True)
    latency_samples: int = eqx.field(static=True, default=0, kw_only=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(MEASURED_POSITION,), kw_only=True)
    noise_count: int = eqx.field(static=True, default=4, kw_only=True)
    source: str | None = eqx.field(static=True, default=None, kw_only=True)

    def __init__(
        self,
        lever_arm: npt.ArrayLike = (0.0, 0.0),
        noise_std: float = 1.0,
        sample_period: float = 1.0,
        error_std: float = 0.0,
        error_time_constant: float = 300.0,
        latency: float = 0.0,
        source: str | None = None,
    ):
        self.lever_arm = jnp.asarray(lever_arm_vector("lever_arm", lever_arm))
        check.positive("noise_std", noise_std, allow_zero=True)
        self.noise = jnp.asarray(float(noise_std))
        self.sample_period = period_value("sample_period", sample_period)
        self.error = gauss_markov("error", error_std, error_time_constant, self.sample_period, 2)
        self.latency_samples = whole_periods("latency", latency, self.sample_period)
        self.source = source_value("source", source)

    def initial_memory(self, kinematics: dict[str, Array]) -> tuple[Array, Array]:
        # the Gauss-Markov error, and the fixes computed but not yet given (oldest first)
        return jnp.zeros(2), jnp.tile(self.expected(kinematics), (self.latency_samples, 1))

    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        error, waiting = memory
        value = self.expected(kinematics) + error
        if self.latency_samples:
            waiting, value = jnp.concatenate([waiting[1:], value[None]], axis=0), waiting[0]
        return (self.error.advance(error, normals[2:4]), waiting), value, self.noise * normals[:2]

    def expected(self, kinematics: dict[str, Array]) -> Array:
        return at_lever_arm(kinematics["position"], kinematics["heading"], self.lever_arm)

    def noise_std(self) -> Array:
        return jnp.full(2, 1.0) * self.noise

    def measurement_std(self) -> Array:
        """The white noise widened by the Gauss–Markov error's stationary variance,
        per axis (:meth:`Instrument.measurement_std`)."""
        return self.error.widened(self.noise_std())

    def position_of(self, y: Array) -> Array:
        return y

    def weight_std(self) -> Array:
        # the base class's, without measurement_std's square root taken and squared again
        return jnp.sqrt(self.noise**2 + jnp.mean(self.error.std**2))


@component(
    "instrument",
    "hydroacoustic",
    summary="A hydroacoustic (HPR/USBL) position reference: noise growing with the slant range to a seabed transponder.",
    parameters=(
        LEVER_ARM,
        Value("transponder", "array", "Earth-fixed position [north, east] of the seabed transponder (m).", shape="(2,)", broadcast=False),
        Value("depth", "float", "Water depth below the transducer (m).", range=POSITIVE),
        Value("noise_std", "float", "Standard deviation of the white noise per axis at zero slant range (m).", range=NON_NEGATIVE),
        Value("range_fraction", "float", "Further standard deviation per metre of slant range (1; 0.005 is 0.5 % of the range).", range=NON_NEGATIVE),
        Value("sample_period", "float", "Seconds between fixes (s).", range=POSITIVE),
        SOURCE,
    ),
)
@final
class HydroacousticReference(PositionReference):
    """A hydroacoustic position reference (HPR, USBL): the transducer's position from a
    seabed transponder, with a white noise whose standard deviation grows with the slant
    range ``rho = sqrt(d^2 + |p_t - p_transponder|^2)``: ``sigma = sigma_0 + f rho``
    per axis (a USBL's accuracy is stated as a fraction of the slant range).

    Parameters
    ----------
    lever_arm : array_like, shape (2,)
        Body-fixed position [x, y] of the antenna or transducer from the vessel's reference point (m, forward and starboard).
    transponder : array_like, shape (2,)
        Earth-fixed position [north, east] of the seabed transponder (m).
    depth : float, positive
        Water depth below the transducer (m).
    noise_std : float, non-negative
        Standard deviation of the white noise per axis at zero slant range (m).
    range_fraction : float, non-negative
        Further standard deviation per metre of slant range (1; 0.005 is 0.5 % of the range).
    sample_period : float, positive
        Seconds between fixes (s).
    source : str, optional
        Where lookout live and lookout replay take its readings from: a talker ID, a sender or both
        (GP, @10.0.0.5, GP@10.0.0.5); simulation ignores it.
    """

    lever_arm: Array
    transponder: Array
    depth: Array
    noise: Array
    range_fraction: Array
    sample_period: float = eqx.field(static=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(MEASURED_POSITION,), kw_only=True)
    noise_count: int = eqx.field(static=True, default=2, kw_only=True)
    source: str | None = eqx.field(static=True, default=None, kw_only=True)

    def __init__(
        self,
        lever_arm: npt.ArrayLike = (0.0, 0.0),
        transponder: npt.ArrayLike = (0.0, 0.0),
        depth: float = 100.0,
        noise_std: float = 0.5,
        range_fraction: float = 0.005,
        sample_period: float = 2.0,
        source: str | None = None,
    ):
        self.lever_arm = jnp.asarray(lever_arm_vector("lever_arm", lever_arm))
        self.transponder = jnp.asarray(lever_arm_vector("transponder", transponder))
        self.depth = jnp.asarray(period_value("depth", depth))
        for name, value in (("noise_std", noise_std), ("range_fraction", range_fraction)):
            check.positive(name, value, allow_zero=True)
        self.noise = jnp.asarray(float(noise_std))
        self.range_fraction = jnp.asarray(float(range_fraction))
        self.sample_period = period_value("sample_period", sample_period)
        self.source = source_value("source", source)

    def _std(self, point: Array) -> Array:
        slant = jnp.sqrt(self.depth**2 + jnp.sum((point - self.transponder) ** 2))
        return self.noise + self.range_fraction * slant

    def initial_memory(self, kinematics: dict[str, Array]) -> tuple[()]:
        return ()

    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        point = self.expected(kinematics)
        return memory, point, self._std(point) * normals[:2]

    def expected(self, kinematics: dict[str, Array]) -> Array:
        return at_lever_arm(kinematics["position"], kinematics["heading"], self.lever_arm)

    def noise_std(self) -> Array:
        # at the transponder's horizontal position: what a filter can state without the vessel's
        return jnp.full(2, 1.0) * (self.noise + self.range_fraction * self.depth)

    def position_of(self, y: Array) -> Array:
        return y

    def std_at(self, y: Array) -> Array:
        # at the fix's own slant range (a USBL's accuracy is stated as a part of it); at the
        # transponder's horizontal position for a missing fix
        finite = jnp.all(jnp.isfinite(y))
        return jnp.where(finite, self._std(jnp.where(finite, y, self.transponder)), self.weight_std())


@component(
    "instrument",
    "taut-wire",
    summary="A relative position reference (taut wire, or a laser or radar to a fixed target): the attachment's offset from a fixed point.",
    parameters=(
        LEVER_ARM,
        Value(
            "anchor",
            "array",
            "Earth-fixed position [north, east] of the fixed point (the wire's depressor weight, the target) (m).",
            shape="(2,)",
            broadcast=False,
        ),
        Value("noise_std", "float", "Standard deviation of the white noise per axis (m).", range=NON_NEGATIVE),
        Value("sample_period", "float", "Seconds between samples (s).", range=POSITIVE),
    ),
)
@final
class RelativeReference(PositionReference):
    """A relative position reference: a taut wire's angle and length, or a laser or radar
    to a target, as the offset (north, east) of the attachment at the lever arm from a
    fixed point: ``y = p + R(psi) r - anchor`` plus white noise.

    Parameters
    ----------
    lever_arm : array_like, shape (2,)
        Body-fixed position [x, y] of the antenna or transducer from the vessel's reference point (m, forward and starboard).
    anchor : array_like, shape (2,)
        Earth-fixed position [north, east] of the fixed point (the wire's depressor weight, the target) (m).
    noise_std : float, non-negative
        Standard deviation of the white noise per axis (m).
    sample_period : float, positive
        Seconds between samples (s).
    """

    lever_arm: Array
    anchor: Array
    noise: Array
    sample_period: float = eqx.field(static=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(MEASURED_OFFSET,), kw_only=True)
    noise_count: int = eqx.field(static=True, default=2, kw_only=True)

    def __init__(self, lever_arm: npt.ArrayLike = (0.0, 0.0), anchor: npt.ArrayLike = (0.0, 0.0), noise_std: float = 0.3, sample_period: float = 1.0):
        self.lever_arm = jnp.asarray(lever_arm_vector("lever_arm", lever_arm))
        self.anchor = jnp.asarray(lever_arm_vector("anchor", anchor))
        check.positive("noise_std", noise_std, allow_zero=True)
        self.noise = jnp.asarray(float(noise_std))
        self.sample_period = period_value("sample_period", sample_period)

    def initial_memory(self, kinematics: dict[str, Array]) -> tuple[()]:
        return ()

    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        return memory, self.expected(kinematics), self.noise * normals[:2]

    def expected(self, kinematics: dict[str, Array]) -> Array:
        return at_lever_arm(kinematics["position"], kinematics["heading"], self.lever_arm) - self.anchor

    def noise_std(self) -> Array:
        return jnp.full(2, 1.0) * self.noise

    def position_of(self, y: Array) -> Array:
        return y + self.anchor


__all__ = ["GnssReceiver", "HydroacousticReference", "PositionReference", "RelativeReference"]
