"""Motion sensors: an IMU (or an MRU's horizontal channels), GNSS speed and course over
ground, and a speed log.

The accelerometers of an IMU at a body-fixed lever arm ``r`` feel the inertial
acceleration of that point in body axes, ``a + r' x r + r x (r x r)`` of the reference
point's acceleration ``a`` (:func:`lookout.vessel_signals.vessel_kinematics`), which in
the horizontal plane with yaw rate ``w`` is ``a + w' [-r_y, r_x] - w^2 [r_x, r_y]``.
"""

from __future__ import annotations

from typing import Any, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import rotation
from lookout.components import BODY_FIXED, EARTH_FIXED, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Value, component
from lookout.sensing.imu_grades import GRADE_NAMES, imu_grade
from lookout.sensing.instrument import SOURCE, GaussMarkovError, Instrument, lever_arm_vector, period_value, source_value, std_value
from lookout.vessel_signals import BODY_AXES

SPECIFIC_FORCE = Signal("measured_specific_force", "m/s2", "measured specific force (accelerometers)", BODY_FIXED, BODY_AXES, "body_axis")
ANGULAR_RATE = Signal("measured_yaw_rate", "rad/s", "measured yaw rate (rate gyro)", BODY_FIXED)
SPEED_OVER_GROUND = Signal("measured_speed_over_ground", "m/s", "measured speed over ground")
COURSE_OVER_GROUND = Signal("measured_course_over_ground", "rad", "measured course over ground", EARTH_FIXED, angle=True)
WATER_VELOCITY = Signal("measured_water_velocity", "m/s", "measured velocity through the water (speed log)", BODY_FIXED, BODY_AXES, "body_axis")

LEVER_ARM = Value(
    "lever_arm", "array", "Body-fixed position [x, y] of the sensor from the vessel's reference point (m).", shape="(2,)", broadcast=False
)


def _velocity_at(kinematics: dict[str, Array], arm: Array) -> Array:
    """The body-fixed velocity of the point at ``arm``: v + w x r."""
    r = kinematics["yaw_rate"]
    return kinematics["velocity"] + r * jnp.stack([-arm[1], arm[0]])


@component(
    "instrument",
    "imu",
    summary="An IMU (or an MRU's horizontal channels): specific force and yaw rate in body axes, with constant and drifting biases and white noise.",
    parameters=(
        LEVER_ARM,
        Value(
            "accelerometer_std",
            "float",
            "Standard deviation of each accelerometer's white noise (m/s2; default: the grade's, else 0.01).",
            range=NON_NEGATIVE,
        ),
        Value(
            "gyro_std", "float", "Standard deviation of the rate gyro's white noise (rad/s; default: the grade's, else 0.001).", range=NON_NEGATIVE
        ),
        Value("accelerometer_bias", "array", "Constant bias of the accelerometers [surge, sway] (m/s2).", shape="(2,)"),
        Value("gyro_bias", "float", "Constant bias of the rate gyro (rad/s)."),
        Value("sample_period", "float", "Seconds between samples (s).", range=POSITIVE),
        Value(
            "accelerometer_bias_std",
            "array",
            "Stationary standard deviation of the accelerometers' drifting bias [surge, sway] (m/s2; default: the grade's, else 0 for none).",
            shape="(2,)",
            range=NON_NEGATIVE,
        ),
        Value(
            "gyro_bias_std",
            "float",
            "Stationary standard deviation of the rate gyro's drifting bias (rad/s; default: the grade's, else 0 for none).",
            range=NON_NEGATIVE,
        ),
        Value(
            "bias_time_constant",
            "float",
            "Time constant of the drifting biases' Gauss-Markov process (s; default: the grade's, else 3600).",
            range=POSITIVE,
        ),
        Value(
            "accelerometer_turn_on_std",
            "array",
            "Standard deviation of the accelerometers' turn-on bias [surge, sway], drawn once and constant through the run (m/s2; default: the grade's, else 0 for none).",
            shape="(2,)",
            range=NON_NEGATIVE,
        ),
        Value(
            "gyro_turn_on_std",
            "float",
            "Standard deviation of the rate gyro's turn-on bias, constant through the run (rad/s; default: the grade's, else 0 for none).",
            range=NON_NEGATIVE,
        ),
        Value(
            "grade",
            "str",
            "The IMU's grade, whose figures give the white noise and the turn-on and drifting biases that are not given (lookout.sensing.imu_grades).",
            choices=GRADE_NAMES,
        ),
    ),
)
@final
class InertialUnit(Instrument):
    """An IMU: the specific force (surge, sway) and the yaw rate in body axes at its lever
    arm, plus biases and white noise. In the horizontal plane gravity does not enter, so
    the specific force is the inertial acceleration of the point.

    Each channel's bias is the sum of a given constant (``accelerometer_bias``,
    ``gyro_bias``), a turn-on bias (:attr:`turn_on_std`: a normal drawn at the first sample
    and constant through the run, the bias repeatability of a datasheet) and an in-run
    first-order Gauss-Markov drift (:attr:`bias_drift`, the bias instability: stationary
    standard deviations ``accelerometer_bias_std`` and ``gyro_bias_std``, time constant
    ``bias_time_constant``), stepped at the sample period and started from its stationary
    distribution at the first sample. Runs over seeds see the spread of biases an IMU has
    after switch-on. Without turn-on and drift spreads (the default without a grade) it
    has neither: three normals a sample and no memory; each adds three normals a sample.

    A ``grade`` (:data:`lookout.sensing.imu_grades.GRADES`: consumer, industrial, tactical,
    navigation) sets the white noise per sample from its noise densities,
    ``density / sqrt(sample_period)`` (a sample averaging over its period), the turn-on
    spread from its turn-on biases and the drift from its bias instabilities and
    correlation time; a value given here wins over the grade's.

    Parameters
    ----------
    lever_arm : array_like, shape (2,)
        Body-fixed position [x, y] of the sensor from the vessel's reference point (m).
    accelerometer_std : float, non-negative, optional
        Standard deviation of each accelerometer's white noise (m/s2; default: the
        grade's, else 0.01).
    gyro_std : float, non-negative, optional
        Standard deviation of the rate gyro's white noise (rad/s; default: the grade's,
        else 0.001).
    accelerometer_bias : array_like, shape (2,)
        Constant bias of the accelerometers [surge, sway] (m/s2).
    gyro_bias : float
        Constant bias of the rate gyro (rad/s).
    sample_period : float, positive
        Seconds between samples (s).
    accelerometer_bias_std : array_like, shape (2,), non-negative, optional
        Stationary standard deviation of the accelerometers' drifting bias [surge, sway]
        (m/s2; default: the grade's, else 0 for none). One number stands for both.
    gyro_bias_std : float, non-negative, optional
        Stationary standard deviation of the rate gyro's drifting bias (rad/s; default:
        the grade's, else 0 for none).
    bias_time_constant : float, positive, optional
        Time constant of the drifting biases' Gauss-Markov process (s; default: the
        grade's, else 3600).
    accelerometer_turn_on_std : array_like, shape (2,), non-negative, optional
        Standard deviation of the accelerometers' turn-on bias [surge, sway], drawn once
        and constant through the run (m/s2; default: the grade's, else 0 for none). One
        number stands for both.
    gyro_turn_on_std : float, non-negative, optional
        Standard deviation of the rate gyro's turn-on bias, constant through the run
        (rad/s; default: the grade's, else 0 for none).
    grade : {"consumer", "industrial", "tactical", "navigation"}, optional
        The IMU's grade, whose figures give the white noise and the turn-on and drifting
        biases that are not given (lookout.sensing.imu_grades).

    Attributes
    ----------
    bias : Array, shape (3,)
        The constant biases [surge accel, sway accel, gyro].
    turn_on_std : Array, shape (3,)
        The turn-on biases' spreads [surge accel, sway accel, gyro].
    bias_drift : GaussMarkovError
        The drifting biases: ``std`` of shape (3,) [surge accel, sway accel, gyro] and
        one ``time_constant``, stepped at the sample period (zero ``std``: none).
    """

    lever_arm: Array
    accelerometer_std: Array
    gyro_std: Array
    bias: Array
    turn_on_std: Array
    bias_drift: GaussMarkovError
    sample_period: float = eqx.field(static=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(SPECIFIC_FORCE, ANGULAR_RATE), kw_only=True)
    noise_count: int = eqx.field(static=True, default=3, kw_only=True)
    # whether it has a drift and a turn-on bias (a spread > 0), fixed when built
    random_biases: tuple[bool, bool] = eqx.field(static=True, default=(False, False), kw_only=True)

    def __init__(
        self,
        lever_arm: npt.ArrayLike = (0.0, 0.0),
        accelerometer_std: float | None = None,
        gyro_std: float | None = None,
        accelerometer_bias: npt.ArrayLike = (0.0, 0.0),
        gyro_bias: float = 0.0,
        sample_period: float = 0.1,
        accelerometer_bias_std: npt.ArrayLike | None = None,
        gyro_bias_std: float | None = None,
        bias_time_constant: float | None = None,
        accelerometer_turn_on_std: npt.ArrayLike | None = None,
        gyro_turn_on_std: float | None = None,
        grade: str | None = None,
    ):
        self.lever_arm = jnp.asarray(lever_arm_vector("lever_arm", lever_arm))
        self.sample_period = period_value("sample_period", sample_period)
        chosen = None if grade is None else imu_grade(grade)
        if accelerometer_std is None:
            accelerometer_std = 0.01 if chosen is None else chosen.accelerometer_std(self.sample_period)
        if gyro_std is None:
            gyro_std = 0.001 if chosen is None else chosen.gyro_std(self.sample_period)
        check.positive("accelerometer_std", accelerometer_std, allow_zero=True)
        check.positive("gyro_std", gyro_std, allow_zero=True)
        self.accelerometer_std = jnp.asarray(float(accelerometer_std))
        self.gyro_std = jnp.asarray(float(gyro_std))
        bias = lever_arm_vector("accelerometer_bias", accelerometer_bias)
        check.finite("gyro_bias", gyro_bias)
        self.bias = jnp.asarray([bias[0], bias[1], float(gyro_bias)])
        if accelerometer_bias_std is None:
            accelerometer_bias_std = 0.0 if chosen is None else chosen.accelerometer_bias_instability
        if gyro_bias_std is None:
            gyro_bias_std = 0.0 if chosen is None else chosen.gyro_bias_instability
        if bias_time_constant is None:
            bias_time_constant = 3600.0 if chosen is None else chosen.bias_time_constant
        check.positive("gyro_bias_std", gyro_bias_std, allow_zero=True)
        drift_std = jnp.concatenate([std_value("accelerometer_bias_std", accelerometer_bias_std, 2), jnp.asarray([float(gyro_bias_std)])])
        time_constant = period_value("bias_time_constant", bias_time_constant)
        self.bias_drift = GaussMarkovError(drift_std, jnp.asarray(time_constant), self.sample_period)
        if accelerometer_turn_on_std is None:
            accelerometer_turn_on_std = 0.0 if chosen is None else chosen.accelerometer_turn_on_bias
        if gyro_turn_on_std is None:
            gyro_turn_on_std = 0.0 if chosen is None else chosen.gyro_turn_on_bias
        check.positive("gyro_turn_on_std", gyro_turn_on_std, allow_zero=True)
        self.turn_on_std = jnp.concatenate(
            [std_value("accelerometer_turn_on_std", accelerometer_turn_on_std, 2), jnp.asarray([float(gyro_turn_on_std)])]
        )
        # the drift's and the turn-on bias's normals and memory only where they have a
        # spread: without, the draws and the memory are those of an IMU of constant biases
        self.random_biases = (bool(np.any(np.asarray(drift_std) > 0)), bool(np.any(np.asarray(self.turn_on_std) > 0)))
        self.noise_count = 3 + 3 * self.drifting + 3 * self.turned_on

    @property
    def drifting(self) -> bool:
        """Whether its biases drift (a drift spread > 0): three more normals a sample,
        and the drift in its memory."""
        return self.random_biases[0]

    @property
    def turned_on(self) -> bool:
        """Whether it draws a turn-on bias (a turn-on spread > 0): three more normals a
        sample (used at the first), and the bias in its memory."""
        return self.random_biases[1]

    def initial_memory(self, kinematics: dict[str, Array]) -> tuple[()] | tuple[Array, Array, Array]:
        # the drift, the turn-on bias, and whether they have been drawn (at the first
        # sample: the drift from its stationary distribution)
        return (jnp.zeros(3), jnp.zeros(3), jnp.asarray(False)) if self.drifting or self.turned_on else ()

    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        value, white = self.expected(kinematics) + self.bias, self.noise_std() * normals[:3]
        if not (self.drifting or self.turned_on):
            return memory, value, white
        drift, turn_on, drawn = memory
        if self.drifting:
            drift = jnp.where(drawn, self.bias_drift.advance(drift, normals[3:6]), self.bias_drift.std * normals[3:6])
        if self.turned_on:
            start = 6 if self.drifting else 3
            turn_on = jnp.where(drawn, turn_on, self.turn_on_std * normals[start : start + 3])
        return (drift, turn_on, jnp.asarray(True)), value + drift + turn_on, white

    def expected(self, kinematics: dict[str, Array]) -> Array:
        w, w_rate, (x, y) = kinematics["yaw_rate"], kinematics["yaw_acceleration"], self.lever_arm
        acceleration = kinematics["acceleration"] + w_rate * jnp.stack([-y, x]) - w**2 * self.lever_arm
        # a filter's model with the IMU's biases as states (lookout.models.imu_biases) carries them
        acceleration = acceleration + kinematics.get("accelerometer_bias", 0.0)
        return jnp.concatenate([acceleration, jnp.reshape(w + kinematics.get("gyro_bias", 0.0), (1,))])

    def noise_std(self) -> Array:
        return jnp.stack([self.accelerometer_std, self.accelerometer_std, self.gyro_std])

    def measurement_std(self) -> Array:
        """A Kalman filter's R for an IMU that models none of its biases (the extended
        filter reading a suite's IMU as a measurement of its model's acceleration): the
        white noise, widened by the turn-on bias's spread and the drift's stationary
        spread where the IMU has them (:attr:`turn_on_std`, :attr:`bias_drift`), as a
        GNSS receiver's slow error widens its R (:meth:`Instrument.measurement_std`);
        exactly the white noise without them. The given constant biases are left out. An
        observer that estimates the biases as states (the IMU-aided observer) reads the
        noise and the drift from the instrument instead."""
        return jnp.hypot(self.bias_drift.widened(self.noise_std()), self.turn_on_std)


@component(
    "instrument",
    "gnss-velocity",
    summary="GNSS speed and course over ground of the antenna at a lever arm.",
    parameters=(
        LEVER_ARM,
        Value("speed_std", "float", "Standard deviation of the speed's white noise (m/s).", range=NON_NEGATIVE),
        Value("course_std", "float", "Standard deviation of the course's white noise (rad).", range=NON_NEGATIVE),
        Value("sample_period", "float", "Seconds between samples (s).", range=POSITIVE),
        SOURCE,
    ),
)
@final
class GnssVelocity(Instrument):
    """GNSS speed over ground |v_t| and course over ground atan2(v_east, v_north) of the
    antenna at its lever arm (v_t = R(psi) (v + w x r)), each with white noise; the
    course is wrapped to [-pi, pi) and is meaningless at rest, as a receiver's is.

    Parameters
    ----------
    lever_arm : array_like, shape (2,)
        Body-fixed position [x, y] of the sensor from the vessel's reference point (m).
    speed_std : float, non-negative
        Standard deviation of the speed's white noise (m/s).
    course_std : float, non-negative
        Standard deviation of the course's white noise (rad).
    sample_period : float, positive
        Seconds between samples (s).
    source : str, optional
        Where lookout live and lookout replay take its readings from: a talker ID, a sender or both
        (GP, @10.0.0.5, GP@10.0.0.5); simulation ignores it.
    """

    lever_arm: Array
    speed_std: Array
    course_std: Array
    sample_period: float = eqx.field(static=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(SPEED_OVER_GROUND, COURSE_OVER_GROUND), kw_only=True)
    noise_count: int = eqx.field(static=True, default=2, kw_only=True)
    source: str | None = eqx.field(static=True, default=None, kw_only=True)

    def __init__(
        self,
        lever_arm: npt.ArrayLike = (0.0, 0.0),
        speed_std: float = 0.05,
        course_std: float = 0.02,
        sample_period: float = 1.0,
        source: str | None = None,
    ):
        self.lever_arm = jnp.asarray(lever_arm_vector("lever_arm", lever_arm))
        check.positive("speed_std", speed_std, allow_zero=True)
        check.positive("course_std", course_std, allow_zero=True)
        self.speed_std = jnp.asarray(float(speed_std))
        self.course_std = jnp.asarray(float(course_std))
        self.sample_period = period_value("sample_period", sample_period)
        self.source = source_value("source", source)

    def initial_memory(self, kinematics: dict[str, Array]) -> tuple[()]:
        return ()

    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        return memory, self.expected(kinematics), self.noise_std() * normals[:2]

    def expected(self, kinematics: dict[str, Array]) -> Array:
        earth = rotation(kinematics["heading"])[:2, :2] @ _velocity_at(kinematics, self.lever_arm)
        # the gradient of a norm at 0 is NaN: the speed through the squared norm kept off 0
        squared = jnp.sum(earth**2)
        moving = squared > 0
        speed = jnp.where(moving, jnp.sqrt(jnp.where(moving, squared, 1.0)), 0.0)
        # and atan2's at 0: the course at rest is 0 with a zero gradient, not NaN
        course = jnp.arctan2(jnp.where(moving, earth[1], 0.0), jnp.where(moving, earth[0], 1.0))
        return jnp.stack([speed, course])

    def noise_std(self) -> Array:
        return jnp.stack([self.speed_std, self.course_std])


@component(
    "instrument",
    "speed-log",
    summary="A speed log (Doppler or electromagnetic): the velocity through the water in body axes at a lever arm.",
    parameters=(
        LEVER_ARM,
        Value("noise_std", "array", "Standard deviation of the white noise [surge, sway] (m/s).", shape="(2,)", range=NON_NEGATIVE),
        Value("sample_period", "float", "Seconds between samples (s).", range=POSITIVE),
        SOURCE,
    ),
)
@final
class SpeedLog(Instrument):
    """A speed log: the velocity of its point through the water in body axes,
    ``v + w x r`` plus white noise. The plant models have no current (the environment
    enters as the bias force), so the velocity through the water is the low-frequency
    velocity over ground.

    Parameters
    ----------
    lever_arm : array_like, shape (2,)
        Body-fixed position [x, y] of the sensor from the vessel's reference point (m).
    noise_std : array_like, shape (2,)
        Standard deviation of the white noise [surge, sway] (m/s).
    sample_period : float, positive
        Seconds between samples (s).
    source : str, optional
        Where lookout live and lookout replay take its readings from: a talker ID, a sender or both
        (GP, @10.0.0.5, GP@10.0.0.5); simulation ignores it.
    """

    lever_arm: Array
    noise: Array
    sample_period: float = eqx.field(static=True)
    signals: tuple[Signal, ...] = eqx.field(static=True, default=(WATER_VELOCITY,), kw_only=True)
    noise_count: int = eqx.field(static=True, default=2, kw_only=True)
    source: str | None = eqx.field(static=True, default=None, kw_only=True)

    def __init__(self, lever_arm: npt.ArrayLike = (0.0, 0.0), noise_std: ArrayLike = 0.05, sample_period: float = 1.0, source: str | None = None):
        self.lever_arm = jnp.asarray(lever_arm_vector("lever_arm", lever_arm))
        self.noise = std_value("noise_std", noise_std, 2)
        self.sample_period = period_value("sample_period", sample_period)
        self.source = source_value("source", source)

    def initial_memory(self, kinematics: dict[str, Array]) -> tuple[()]:
        return ()

    def emit(self, memory: Any, kinematics: dict[str, Array], normals: Array) -> tuple[Any, Array, Array]:
        return memory, self.expected(kinematics), self.noise * normals[:2]

    def expected(self, kinematics: dict[str, Array]) -> Array:
        return _velocity_at(kinematics, self.lever_arm)

    def noise_std(self) -> Array:
        return self.noise


__all__ = ["GnssVelocity", "InertialUnit", "SpeedLog"]
