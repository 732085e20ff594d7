"""Measurement models: position and heading with noise, per-channel rates, dropouts.

Fossen & Strand (1999), eq. (12): ``y = eta + eta_w + d`` with zero-mean Gaussian
white measurement noise ``d``. The heading channel is wrapped to [-pi, pi), as a
gyro compass reports it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.special
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa
from lookout.components import EARTH_FIXED, Layout, Outage, Plant, Sensor, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Range, Value, component
from lookout.models.vessel import EARTH_AXES, VesselState

#: The keys of a sensor's outage, the same for every sensor.
OUTAGE_VALUES = (
    Value(
        "outage_signals",
        "strings",
        "Measured signals that an outage silences (measured_position: a position reference that loses its fix); default none, and no outage.",
    ),
    Value("outage_start", "float", "When the outage begins (s).", range=NON_NEGATIVE),
    Value("outage_duration", "float", "How long it lasts (s); 0 is none (the sensor keeps an outage's structure).", range=NON_NEGATIVE),
)


def outage_of(layout: Layout, signals: str | Sequence[str] | None, start: ArrayLike, duration: ArrayLike) -> Outage | None:
    """The :class:`~lookout.components.Outage` of ``signals`` (names of ``layout``'s
    signals) over ``[start, start + duration)``; None without signals."""
    if signals is None or len(signals) == 0:
        if check.is_concrete(duration) and float(np.max(duration)) > 0.0:
            raise check.ParameterError("outage_duration", "outage_duration needs outage_signals: name the measured signals the outage silences")
        return None
    if isinstance(signals, str):
        signals = (signals,)
    names = layout.names
    for name in signals:
        if name not in names:
            raise check.ParameterError("outage_signals", f"outage_signals: the sensor measures no {name!r} (it measures {', '.join(names)})")
    for name, value in (("outage_start", start), ("outage_duration", duration)):
        if check.is_concrete(value):
            number = np.asarray(value, dtype=float)
            if number.shape != () or not (np.isfinite(number) and number >= 0.0):
                raise check.ParameterError(check.key(name), f"{name} must be a finite number of seconds >= 0; got {value}")
    channels = tuple(signal.name in signals for signal in layout.signals for _ in range(signal.size))
    return Outage(jnp.asarray(start, dtype=float), jnp.asarray(duration, dtype=float), channels)


#: What a DGPS and a gyro compass report: y = eta + eta_w + d (eq. 12).
POSITION_HEADING = Layout(
    (
        Signal("measured_position", "m", "measured position (held samples; NaN = dropout)", EARTH_FIXED, EARTH_AXES, "earth_axis"),
        Signal("measured_heading", "rad", "measured heading (held samples; NaN = dropout)", EARTH_FIXED, angle=True),
    )
)


@component(
    "sensor",
    "position-heading",
    summary="Position fixes (x, y) and heading, each channel with its own noise and rate.",
    parameters=(
        Value("noise_std", "array", "Standard deviation of d per channel (m, m, rad).", shape="(3,)", range=NON_NEGATIVE),
        Value(
            "sample_period", "array", "Seconds between samples of each channel (s; static: fixes the loop structure).", shape="(3,)", range=POSITIVE
        ),
        Value("dropout_probability", "float", "Probability that a sample of a channel is missing (1).", range=Range(0.0, 1.0, True, False)),
        *OUTAGE_VALUES,
    ),
)
@final
class PositionHeadingSensor(Sensor):
    """Position fixes (x, y) and heading, each channel with its own noise and rate.

    Between two samples of a channel the engine holds the last sample (zero-order
    hold); a dropped sample is NaN and makes the channel invalid until its next
    sample, during which the observer predicts without injection on that channel.

    Parameters
    ----------
    noise_std : array_like, shape (3,), non-negative
        Standard deviation of d per channel (m, m, rad).
    sample_period : float or sequence of 3 floats, positive
        Seconds between samples of each channel (s; static: fixes the loop structure).
    dropout_probability : float in [0, 1)
        Probability that a sample of a channel is missing (1).
    outage_signals : sequence of str, optional
        Measured signals that an outage silences (``measured_position``: a position
        reference that loses its fix); default none, and no outage.
    outage_start : float, non-negative
        When the outage begins (s).
    outage_duration : float, non-negative
        How long it lasts (s); 0 is none (the sensor keeps an outage's structure).
    """

    noise_std: Array
    dropout_probability: Array
    sample_period: tuple[float, ...] = eqx.field(static=True)
    noise_size: int = eqx.field(static=True, default=6, kw_only=True)
    measurement_layout: Layout = eqx.field(static=True, default=POSITION_HEADING, kw_only=True)

    def __init__(
        self,
        noise_std: npt.ArrayLike = 0.0,
        sample_period: npt.ArrayLike = 1.0,
        dropout_probability: float = 0.0,
        outage_signals: str | Sequence[str] | None = None,
        outage_start: ArrayLike = 0.0,
        outage_duration: ArrayLike = 0.0,
    ):
        self.noise_std = jnp.asarray(check.vector("sensor noise_std", noise_std))
        self.dropout_probability = jnp.asarray(float(dropout_probability))
        self.sample_period = tuple(float(p) for p in check.vector("sensor sample_period", sample_period))
        self.outage = outage_of(POSITION_HEADING, outage_signals, outage_start, outage_duration)

    def __check_init__(self):
        check.positive("sensor noise_std", self.noise_std, allow_zero=True)
        check.positive("sensor sample_period", np.asarray(self.sample_period))
        if check.is_concrete(self.dropout_probability):
            p = float(self.dropout_probability)
            if not 0.0 <= p < 1.0:
                raise check.ParameterError("sensor", f"sensor dropout_probability must be in [0, 1); got {p}")

    def ideal(self, state: VesselState) -> Array:
        """Noise-free measurement eta + eta_w with wrapped heading."""
        y = state.eta + state.wave
        return y.at[2].set(ssa(y[2]))

    def measure(self, state: VesselState, noise: Array) -> Array:
        """One noisy sample of every channel; dropped channels are NaN.

        Parameters
        ----------
        state : VesselState
            Plant state at the sample time.
        noise : Array, shape (6,)
            Independent standard normal numbers: three for the measurement noise,
            three turned into uniforms (by the normal CDF) for the dropouts.
        """
        y = state.eta + state.wave + self.noise_std * noise[:3]
        y = y.at[2].set(ssa(y[2]))
        # Phi(n) < p, written as n < Phi^-1(p) (Phi increasing): one scalar inverse
        # instead of an erfc per channel and sample
        dropped = noise[3:] < jax.scipy.special.ndtri(self.dropout_probability)
        return jnp.where(dropped, jnp.nan, y)


# Joint encoders of a manipulator (appended; the vessel sensor above is unchanged).
from lookout.models.manipulators import JOINT_MEASUREMENT, JointState, ManipulatorModel, ManipulatorPlant, joint_layout  # noqa: E402


@component(
    "sensor",
    "joint-encoder",
    summary="Joint position encoders: q with Gaussian noise, quantization, per-joint rates and dropouts.",
    parameters=(
        Part("model", "The manipulator whose joints are measured (names and kinds of the channels)."),
        Value("sample_period", "array", "Seconds between samples of each joint (static: fixes the loop structure).", shape="(n,)"),
        Value("noise_std", "array", "Standard deviation of the measurement noise per joint (rad or m), >= 0.", shape="(n,)"),
        Value("quantization", "array", "Resolution per joint (rad or m), >= 0; 0 means none.", shape="(n,)"),
        Value("dropout_probability", "float", "Probability that a sample of a channel is missing (0 <= p < 1)."),
        *OUTAGE_VALUES,
    ),
)
@final
class JointEncoder(Sensor):
    """Joint position encoders: q with Gaussian noise, quantization, per-joint rates and dropouts.

    Calugi (2002), chapter 2: only the joint positions q are measured. One channel
    per joint, in joint order; a sample is ``step * round((q + sigma n) / step)``
    (rounded to the nearest multiple of the joint's quantization step; no rounding
    where the step is 0), or NaN when dropped. Between two samples of a channel the
    engine holds the last sample. Angles are not wrapped (an incremental encoder
    counts turns).

    Parameters
    ----------
    model : ManipulatorModel or ManipulatorPlant
        The manipulator whose joints are measured (names and kinds of the channels).
    sample_period : float or sequence of n floats
        Seconds between samples of each joint (static: fixes the loop structure).
    noise_std : float or array_like, shape (n,)
        Standard deviation of the measurement noise per joint (rad or m), >= 0.
    quantization : float or array_like, shape (n,)
        Resolution per joint (rad or m), >= 0; 0 means none.
    dropout_probability : float
        Probability that a sample of a channel is missing (0 <= p < 1).
    outage_signals : sequence of str, optional
        Measured signals that an outage silences (``measured_position``: a position
        reference that loses its fix); default none, and no outage.
    outage_start : float, non-negative
        When the outage begins (s).
    outage_duration : float, non-negative
        How long it lasts (s); 0 is none (the sensor keeps an outage's structure).

    Attributes
    ----------
    measurement_layout : Layout
        ``measured_joint_angle`` (rad, over ``revolute_joint``) and ``measured_joint_position``
        (m, over ``prismatic_joint``), labelled by joint name as the plant's signals.
    noise_size : int
        2n: n normals for the noise and n turned into the dropout draws.
    """

    noise_std: Array
    quantization: Array
    dropout_probability: Array
    sample_period: tuple[float, ...] = eqx.field(static=True)
    noise_size: int = eqx.field(static=True)
    measurement_layout: Layout = eqx.field(static=True)

    def __init__(
        self,
        model: ManipulatorModel | ManipulatorPlant,
        *,
        sample_period: npt.ArrayLike,
        noise_std: npt.ArrayLike = 0.0,
        quantization: npt.ArrayLike = 0.0,
        dropout_probability: ArrayLike = 0.0,
        outage_signals: str | Sequence[str] | None = None,
        outage_start: ArrayLike = 0.0,
        outage_duration: ArrayLike = 0.0,
    ):
        if isinstance(model, ManipulatorPlant):
            model = model.model
        if not isinstance(model, ManipulatorModel):
            raise ValueError(f"JointEncoder needs a ManipulatorModel or ManipulatorPlant; got {type(model).__name__}")
        n = model.size
        self.noise_std = jnp.asarray(check.vector("encoder noise_std", noise_std, n))
        self.quantization = jnp.asarray(check.vector("encoder quantization", quantization, n))
        self.dropout_probability = jnp.asarray(dropout_probability, dtype=float)
        self.sample_period = tuple(float(p) for p in check.vector("encoder sample_period", sample_period, n))
        self.noise_size = 2 * n
        self.measurement_layout = joint_layout(model.joint_names, model.joint_kinds, JOINT_MEASUREMENT)
        self.outage = outage_of(self.measurement_layout, outage_signals, outage_start, outage_duration)

    def __check_init__(self):
        check.positive("encoder noise_std", self.noise_std, allow_zero=True)
        check.positive("encoder quantization", self.quantization, allow_zero=True)
        check.positive("encoder sample_period", np.asarray(self.sample_period))
        if check.is_concrete(self.dropout_probability):
            if np.ndim(self.dropout_probability) != 0:
                raise check.ParameterError("encoder", f"encoder dropout_probability must be a scalar; got shape {np.shape(self.dropout_probability)}")
            p = float(self.dropout_probability)
            if not 0.0 <= p < 1.0:
                raise check.ParameterError("encoder", f"encoder dropout_probability must be in [0, 1); got {p}")

    def ideal(self, state: JointState) -> Array:
        """The joint coordinates q, noise-free, unquantized and never dropped."""
        return state.q

    def measure(self, state: JointState, noise: Array) -> Array:
        """One sample of every joint; dropped channels are NaN.

        Parameters
        ----------
        state : JointState
            Plant state at the sample time.
        noise : Array, shape (2n,)
            Independent standard normals: n for the measurement noise, n turned
            into the dropout draws.
        """
        n = state.q.shape[0]
        y = state.q + self.noise_std * noise[:n]
        quantized = self.quantization > 0.0
        step = jnp.where(quantized, self.quantization, 1.0)
        y = jnp.where(quantized, step * jnp.round(y / step), y)
        # Phi(n) < p, written as n < Phi^-1(p), as PositionHeadingSensor does
        dropped = noise[n:] < jax.scipy.special.ndtri(self.dropout_probability)
        return jnp.where(dropped, jnp.nan, y)


# Position, heading AND velocity: an oracle for analysis in simulation only (appended;
# the sensors above are unchanged).
from lookout.components import BODY_FIXED  # noqa: E402
from lookout.models.vessel import BODY_AXES  # noqa: E402

#: POSITION_HEADING followed by the body-fixed velocity nu = [u, v, r] (oracle channels).
POSITION_HEADING_VELOCITY = Layout(
    POSITION_HEADING.signals
    + (
        Signal("measured_velocity", "m/s", "ORACLE measured linear velocity (simulation only; NaN = dropout)", BODY_FIXED, BODY_AXES, "body_axis"),
        Signal("measured_yaw_rate", "rad/s", "ORACLE measured yaw rate (simulation only; NaN = dropout)", BODY_FIXED),
    )
)


@component(
    "sensor",
    "position-heading-velocity",
    summary="ORACLE SENSOR, FOR ANALYSIS IN SIMULATION ONLY: measures eta AND the velocity nu.",
    parameters=(
        Value("noise_std", "array", "Standard deviation per channel (m, m, rad, m/s, m/s, rad/s), >= 0.", shape="(6,)"),
        Value("sample_period", "array", "Seconds between samples of each channel (static).", shape="(6,)"),
        Value("dropout_probability", "float", "Probability that a sample of a channel is missing (0 <= p < 1)."),
        *OUTAGE_VALUES,
    ),
)
@final
class PositionHeadingVelocitySensor(Sensor):
    """ORACLE SENSOR, FOR ANALYSIS IN SIMULATION ONLY: measures eta AND the velocity nu.

    No DP vessel measures its body-fixed velocity nu = [u, v, r] like this; the
    sensor exists so that observers whose continuous-time form needs nu (the
    adaptive observer of Calugi, Robertsson & Johansson (2003), eqs. (13)–(15),
    Remark 2: "not directly implementable because of the presence of the unknown
    signal nu") can be simulated and compared with their implementable discrete
    forms. Do not use it to judge what an observer achieves on a real vessel.

    Layout: ``measured_position`` (m, Earth-fixed north, east),
    ``measured_heading`` (rad, wrapped to [-pi, pi)), ``measured_velocity``
    (m/s, body-fixed surge, sway), ``measured_yaw_rate`` (rad/s): six channels.
    Position and heading are ``eta + eta_w`` as :class:`PositionHeadingSensor`
    reports them (eq. 12 of Fossen & Strand 1999); the velocity channels are the
    low-frequency nu of the plant state (no wave-induced velocity). Each channel has
    its own noise, rate and NaN dropouts, as in :class:`PositionHeadingSensor`.

    Parameters
    ----------
    noise_std : array_like, shape (6,)
        Standard deviation per channel (m, m, rad, m/s, m/s, rad/s), >= 0.
    sample_period : float or sequence of 6 floats
        Seconds between samples of each channel (static).
    dropout_probability : float
        Probability that a sample of a channel is missing (0 <= p < 1).
    outage_signals : sequence of str, optional
        Measured signals that an outage silences (``measured_position``: a position
        reference that loses its fix); default none, and no outage.
    outage_start : float, non-negative
        When the outage begins (s).
    outage_duration : float, non-negative
        How long it lasts (s); 0 is none (the sensor keeps an outage's structure).
    """

    noise_std: Array
    dropout_probability: Array
    sample_period: tuple[float, ...] = eqx.field(static=True)
    noise_size: int = eqx.field(static=True, default=12, kw_only=True)
    measurement_layout: Layout = eqx.field(static=True, default=POSITION_HEADING_VELOCITY, kw_only=True)

    def __init__(
        self,
        noise_std: npt.ArrayLike = 0.0,
        sample_period: npt.ArrayLike = 1.0,
        dropout_probability: float = 0.0,
        outage_signals: str | Sequence[str] | None = None,
        outage_start: ArrayLike = 0.0,
        outage_duration: ArrayLike = 0.0,
    ):
        self.noise_std = jnp.asarray(check.vector("oracle sensor noise_std", noise_std, 6))
        self.dropout_probability = jnp.asarray(float(dropout_probability))
        self.sample_period = tuple(float(p) for p in check.vector("oracle sensor sample_period", sample_period, 6))
        self.outage = outage_of(POSITION_HEADING_VELOCITY, outage_signals, outage_start, outage_duration)

    def __check_init__(self):
        check.positive("oracle sensor noise_std", self.noise_std, allow_zero=True)
        check.positive("oracle sensor sample_period", np.asarray(self.sample_period))
        if check.is_concrete(self.dropout_probability):
            p = float(self.dropout_probability)
            if not 0.0 <= p < 1.0:
                raise check.ParameterError("oracle", f"oracle sensor dropout_probability must be in [0, 1); got {p}")

    def ideal(self, state: VesselState) -> Array:
        """Noise-free [eta + eta_w (heading wrapped), nu]."""
        y = state.eta + state.wave
        return jnp.concatenate([y.at[2].set(ssa(y[2])), state.nu])

    def measure(self, state: VesselState, noise: Array) -> Array:
        """One noisy sample of every channel; dropped channels are NaN.

        Parameters
        ----------
        state : VesselState
            Plant state at the sample time.
        noise : Array, shape (12,)
            Standard normals: six for the noise, six turned into the dropout draws.
        """
        y = jnp.concatenate([state.eta + state.wave, state.nu]) + self.noise_std * noise[:6]
        y = y.at[2].set(ssa(y[2]))
        dropped = noise[6:] < jax.scipy.special.ndtri(self.dropout_probability)
        return jnp.where(dropped, jnp.nan, y)


# ---------------------------------------------------------------------------------
# joint positions and rates: what the on-line parameter estimator of Calugi (2002), ch. 3, reads

from lookout.models.manipulators import PRISMATIC, REVOLUTE  # noqa: E402

#: (name, units, long name) of a measured joint rate, per joint kind.
JOINT_RATE_MEASUREMENT = {
    REVOLUTE: ("measured_joint_rate", "rad/s", "measured joint angular rate (held samples; NaN = dropout)"),
    PRISMATIC: ("measured_joint_speed", "m/s", "measured joint speed (held samples; NaN = dropout)"),
}


def joint_state_layout(model: ManipulatorModel) -> Layout:
    """``measured_joint_angle`` / ``measured_joint_position`` then ``measured_joint_rate`` /
    ``measured_joint_speed``, labelled by joint name: the flat vector is ``[q, q']`` in joint order."""
    names, kinds = model.joint_names, model.joint_kinds
    positions = joint_layout(names, kinds, JOINT_MEASUREMENT)
    rates = joint_layout(names, kinds, JOINT_RATE_MEASUREMENT)
    return Layout(positions.signals + rates.signals)


@component(
    "sensor",
    "joint-state",
    summary="Joint positions and rates y = [q, q'] + noise; NaN marks a dropped channel.",
    parameters=(
        Part("model", "The manipulator whose joints are measured (names and kinds of the channels)."),
        Value("sample_period", "array", "Seconds between samples of each channel (q channels first, then q').", shape="(2n,)"),
        Value("noise_std", "array", "Standard deviation of the measurement noise per channel (rad or m, then rad/s or m/s), >= 0.", shape="(2n,)"),
        Value("dropout_probability", "float", "Probability that a sample of a channel is missing (0 <= p < 1)."),
        *OUTAGE_VALUES,
    ),
)
@final
class JointStateSensor(Sensor):
    """Joint positions and rates ``y = [q, q'] + noise``; NaN marks a dropped channel.

    Parameters
    ----------
    model : ManipulatorModel or a plant with a ``model`` attribute
        The manipulator whose joints are measured (names and kinds of the channels).
    sample_period : float or sequence of 2n floats
        Seconds between samples of each channel (q channels first, then q').
    noise_std : float or array_like, shape (2n,)
        Standard deviation of the measurement noise per channel (rad or m, then
        rad/s or m/s), >= 0.
    dropout_probability : float
        Probability that a sample of a channel is missing (0 <= p < 1).
    outage_signals : sequence of str, optional
        Measured signals that an outage silences (``measured_position``: a position
        reference that loses its fix); default none, and no outage.
    outage_start : float, non-negative
        When the outage begins (s).
    outage_duration : float, non-negative
        How long it lasts (s); 0 is none (the sensor keeps an outage's structure).

    Attributes
    ----------
    measurement_layout : Layout
        See :func:`joint_state_layout`.
    noise_size : int
        4n: 2n normals for the noise and 2n turned into the dropout draws.
    """

    noise_std: Array
    dropout_probability: Array
    sample_period: tuple[float, ...] = eqx.field(static=True)
    noise_size: int = eqx.field(static=True)
    measurement_layout: Layout = eqx.field(static=True)

    def __init__(
        self,
        model: ManipulatorModel | Plant,
        *,
        sample_period: npt.ArrayLike,
        noise_std: npt.ArrayLike = 0.0,
        dropout_probability: ArrayLike = 0.0,
        outage_signals: str | Sequence[str] | None = None,
        outage_start: ArrayLike = 0.0,
        outage_duration: ArrayLike = 0.0,
    ):
        model = getattr(model, "model", model)
        if not isinstance(model, ManipulatorModel):
            raise ValueError(f"JointStateSensor needs a ManipulatorModel or a manipulator plant; got {type(model).__name__}")
        channels = 2 * model.size
        self.noise_std = jnp.asarray(check.vector("joint state sensor noise_std", noise_std, channels))
        self.dropout_probability = jnp.asarray(dropout_probability, dtype=float)
        self.sample_period = tuple(float(p) for p in check.vector("joint state sensor sample_period", sample_period, channels))
        self.noise_size = 2 * channels
        self.measurement_layout = joint_state_layout(model)
        self.outage = outage_of(self.measurement_layout, outage_signals, outage_start, outage_duration)

    def __check_init__(self):
        check.positive("joint state sensor noise_std", self.noise_std, allow_zero=True)
        check.positive("joint state sensor sample_period", np.asarray(self.sample_period))
        if check.is_concrete(self.dropout_probability):
            if np.ndim(self.dropout_probability) != 0:
                raise check.ParameterError(
                    "joint", f"joint state sensor dropout_probability must be a scalar; got shape {np.shape(self.dropout_probability)}"
                )
            p = float(self.dropout_probability)
            if not 0.0 <= p < 1.0:
                raise check.ParameterError("joint", f"joint state sensor dropout_probability must be in [0, 1); got {p}")

    def ideal(self, state: JointState) -> Array:
        """``[q, q']``, noise-free and never dropped."""
        return jnp.concatenate([state.q, state.qdot])

    def measure(self, state: JointState, noise: Array) -> Array:
        """One sample of every channel; dropped channels are NaN.

        Parameters
        ----------
        state : JointState
            Plant state at the sample time.
        noise : Array, shape (4n,)
            Independent standard normals: 2n for the measurement noise, 2n turned
            into the dropout draws.
        """
        channels = 2 * state.q.shape[0]
        y = self.ideal(state) + self.noise_std * noise[:channels]
        # Phi(n) < p written as n < Phi^-1(p), as the other sensors do
        dropped = noise[channels:] < jax.scipy.special.ndtri(self.dropout_probability)
        return jnp.where(dropped, jnp.nan, y)
