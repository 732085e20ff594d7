"""An IMU-aided observer for the horizontal plane: strapdown navigation from a suite's IMU,
its biases estimated, aided by the suite's position references and gyros.

The extended Kalman filter (:mod:`lookout.observers.ekf`) on
:class:`~lookout.models.strapdown.StrapdownVessel`: between samples the state is
propagated by the strapdown mechanization with the IMU's last reading held as its input,
and at a sample the position references (each antenna or transducer at its lever arm)
and the gyrocompasses correct it, as a loosely coupled aided INS does (Farrell (2008),
Aided Navigation: GPS with High Rate Sensors; Groves (2013), Principles of GNSS,
Inertial, and Multisensor Integrated Navigation Systems, 2nd ed., loosely coupled
integration). The filter carries the total state (position, velocity, heading, biases)
and linearizes about its estimate at each sample, which to first order is the
error-state (indirect) filter of those books with the error reset after each correction.

**What it reads.** The suite's instruments' channels (:func:`~lookout.observers.kalman.filter_layout`),
with the IMU's specific force and yaw rate taken as the model's input and never as a
measurement. A missing IMU sample (NaN, a dropout) holds the last reading.

**What it estimates.** Low-frequency position, heading and velocity, the yaw rate (the
gyro's reading less its estimated bias), the accelerometer and gyro biases, and with
``wave_period`` and ``wave_std`` the wave-frequency motion of Fossen & Strand (1999),
eqs. (10)-(11), separated from the low-frequency motion as the model-based observers
separate it: the references measure low-frequency plus wave motion, the IMU drives the
low-frequency part (:mod:`lookout.models.strapdown`, "Waves").

**Its tuning** comes from the IMU: the accelerometers' and gyro's noise densities from
their white noise per sample (``std * sqrt(period)``: a sample averages over its period)
and the biases' drift from the instrument's (:attr:`~lookout.sensing.motion.InertialUnit.bias_drift`,
a Gauss-Markov spread sigma and time constant T), modelled as a random walk of the
drift's own intensity 2 sigma^2 / T: the bias is a constant (the switch-on bias, which
a decaying Gauss-Markov state would pull toward zero between fixes) plus a slow drift.
Without a drift the biases are constants; each figure can be given instead. The references' R is each
instrument's white noise and slow error (:mod:`lookout.observers.kalman`).

**Conditions** (``lookout design``, :mod:`lookout.analysis.ins`): the linearized model
observable from the aiding channels (position references and a heading: without a
heading the gyro bias and the accelerometers' directions are not), the IMU sampled at
every filter sample, and the Kalman filter's own (R > 0, Q >= 0, P_0 >= 0).
"""

from __future__ import annotations

import math
from typing import Any, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import Layout, Sensor
from lookout.declare import NON_NEGATIVE, POSITIVE, Context, Part, Value, component
from lookout.models.strapdown import StrapdownVessel
from lookout.observers.ekf import ExtendedKalmanFilter
from lookout.observers.kalman import KalmanState, filter_layout, kalman_fields
from lookout.observers.model_free import WAVE_PERIOD, WAVE_STD, sea_model
from lookout.sensing.motion import InertialUnit
from lookout.sensing.suite import SensorSuite

#: The prior spread of the biases [accelerometers (m/s2), gyro (rad/s)] unless told: a
#: consumer MEMS unit's switch-on bias (a few mg, a few tenths of a degree a second) is
#: within it, so that the filter starts open to any grade's.
INITIAL_BIAS_STD = (0.05, 0.05, 0.005)
#: The prior spread of the velocity (m/s): a vessel at DP or at a few knots.
INITIAL_VELOCITY_STD = 1.0


def _imu_member(sensor: Sensor, name: str | None) -> tuple[str, InertialUnit, int]:
    """(name, instrument, first channel) of the suite's IMU the filter integrates."""
    if not isinstance(sensor, SensorSuite):
        raise check.ParameterError("sensor", f"sensor: the IMU-aided observer reads a sensor suite with an IMU; got {type(sensor).__name__}")
    imus = [member for member, each in zip(sensor.names, sensor.instruments) if isinstance(each, InertialUnit)]
    if name is None:
        if len(imus) != 1:
            found = f"{len(imus)} ({', '.join(imus)})" if imus else "none"
            raise check.ParameterError("imu", f"imu: name the suite's IMU to integrate; the suite has {found}")
        name = imus[0]
    if name not in imus:
        raise check.ParameterError("imu", f"imu: the suite has no IMU named {name!r} (its IMUs: {', '.join(imus) or 'none'})")
    index = sensor.names.index(name)
    first = sum(each.size for each in sensor.instruments[:index])
    instrument = sensor.instruments[index]
    assert isinstance(instrument, InertialUnit)
    return name, instrument, first


def _bias_drift(imu: InertialUnit) -> tuple[np.ndarray, float]:
    """(stationary spread (3,), time constant) of the IMU's drifting bias; a spread of
    zero and an infinite time constant where it has none."""
    drift = imu.bias_drift
    spread = np.broadcast_to(np.asarray(drift.std, dtype=float), (3,)).copy()
    if not np.any(spread > 0):
        return np.zeros(3), math.inf
    return spread, float(np.asarray(drift.time_constant))


def random_walk_std(spread: np.ndarray, time_constant: float) -> np.ndarray:
    """The random walk whose intensity is the Gauss-Markov drift's driving noise,
    ``sigma sqrt(2 / T)`` per sqrt(s): the filter's model of a bias that is a constant
    (the switch-on bias) plus a slow drift, which a decaying state would pull to zero."""
    return spread * math.sqrt(2.0 / time_constant) if math.isfinite(time_constant) else spread


def _number(name: str, value: Any, *, allow_zero: bool = True, allow_inf: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value) or (math.isinf(value) and not allow_inf):
        raise check.ParameterError(name, f"{name} must be a finite number; got {value!r}")
    check.positive(name, value, allow_zero=allow_zero)
    return float(value)


@component(
    "observer",
    "ins",
    summary="IMU-aided observer: strapdown navigation from the suite's IMU with its biases estimated, aided by the position references and gyros (lookout.observers.ins).",
    checks="lookout.analysis.ins:check_ins",
    parameters=(
        Part("sensor", "The filter's model of the sensor suite (default: the composition's sensor)."),
        Value("imu", "str", "The suite's IMU to integrate (default: its only one)."),
        Value(
            "accelerometer_noise",
            "float",
            "Accelerometers' noise density, velocity random walk (m/s2/sqrt(Hz)); default the IMU's std * sqrt(sample_period).",
            range=NON_NEGATIVE,
        ),
        Value("gyro_noise", "float", "Gyro's noise density, angle random walk (rad/s/sqrt(Hz)); default the IMU's.", range=NON_NEGATIVE),
        Value(
            "bias_std",
            "array",
            "Stationary spread of the biases' drift [accelerometers (m/s2) x2, gyro (rad/s)]; default the IMU's bias drift, else 0 (constant biases).",
            shape="(3,)",
            range=NON_NEGATIVE,
        ),
        Value(
            "bias_time_constant",
            "float",
            "Correlation time of the biases' drift (s), modelled as Gauss-Markov; default none: a random walk of the drift's intensity 2 bias_std^2 / T of the IMU's T.",
            range=POSITIVE,
        ),
        Value(
            "initial_bias_std",
            "array",
            "Prior spread of the biases [accelerometers (m/s2) x2, gyro (rad/s)] (default 0.05, 0.05, 0.005).",
            shape="(3,)",
            range=POSITIVE,
        ),
        WAVE_PERIOD,
        WAVE_STD,
        Value(
            "measurement_noise",
            "array",
            "Standard deviation of each channel of the suite's instruments, R = diag(std^2); the IMU's entries are not used (default: each instrument's own noise).",
            shape="(m,)",
            range=POSITIVE,
        ),
        Context("plant_step", "Step of the propagation (s); default the composition's simulation.plant_step.", own=True),
        Context("filter_period", "The filter's sample period (s); default the composition's simulation.sample_period."),
        Context("integrator", "rk4 or euler; default the composition's simulation.integrator.", own=True),
    ),
)
@final
class InertialNavigationFilter(ExtendedKalmanFilter):
    """The IMU-aided observer (module docstring): the extended Kalman filter on
    :class:`~lookout.models.strapdown.StrapdownVessel`, the suite's IMU its input.

    Parameters
    ----------
    sensor : SensorSuite
        The filter's model of the sensor suite (default: the composition's sensor).
    imu : str, optional
        The suite's IMU to integrate (default: its only one).
    accelerometer_noise : float, non-negative, optional
        Accelerometers' noise density, velocity random walk (m/s2/sqrt(Hz)); default the IMU's std * sqrt(sample_period).
    gyro_noise : float, non-negative, optional
        Gyro's noise density, angle random walk (rad/s/sqrt(Hz)); default the IMU's.
    bias_std : array_like, shape (3,), non-negative, optional
        Stationary spread of the biases' drift [accelerometers (m/s2) x2, gyro (rad/s)]; default the IMU's bias drift, else 0 (constant biases).
    bias_time_constant : float, positive, optional
        Correlation time of the biases' drift (s), modelled as Gauss-Markov; default none: a random walk of the drift's intensity 2 bias_std^2 / T of the IMU's T.
    initial_bias_std : array_like, shape (3,), positive, optional
        Prior spread of the biases [accelerometers (m/s2) x2, gyro (rad/s)] (default 0.05, 0.05, 0.005).
    wave_period : float, positive, optional
        Peak period of the waves the vessel moves in (s); none: calm water (default none).
    wave_std : array_like, shape (3,), non-negative, optional
        Standard deviation of the wave-frequency motion (m, m, rad), with wave_period (default none).
    measurement_noise : array_like, shape (m,), positive, optional
        Standard deviation of each channel of the suite's instruments, R = diag(std^2); the IMU's entries are not used (default: each instrument's own noise).
    plant_step : float
        Step of the propagation (s); default the composition's simulation.plant_step.
    filter_period : float
        The filter's sample period (s); default the composition's simulation.sample_period.
    integrator : str
        rk4 or euler; default the composition's simulation.integrator.

    Raises
    ------
    ValueError
        Naming the parameter: a sensor that is not a suite with one IMU (or the IMU
        named), no position reference or no heading, one of ``wave_period`` and
        ``wave_std`` without the other, a noise or spread not finite and >= 0.
    """

    imu_start: int = eqx.field(static=True)

    def __init__(
        self,
        sensor: Sensor,
        imu: str | None = None,
        accelerometer_noise: float | None = None,
        gyro_noise: float | None = None,
        bias_std: npt.ArrayLike | None = None,
        bias_time_constant: float | None = None,
        initial_bias_std: npt.ArrayLike = INITIAL_BIAS_STD,
        wave_period: float | None = None,
        wave_std: npt.ArrayLike | None = None,
        measurement_noise: npt.ArrayLike | None = None,
        *,
        plant_step: float,
        filter_period: float,
        integrator: str = "rk4",
    ):
        name, unit, first = _imu_member(sensor, imu)
        assert isinstance(sensor, SensorSuite)
        layout = filter_layout(sensor)
        names = [signal.name for signal in layout.signals]
        if not any(each.endswith("position") for each in names) or not any(each.endswith("heading") for each in names):
            raise check.ParameterError(
                "sensor", f"sensor: the IMU-aided observer needs a position reference and a heading in the suite; it measures {', '.join(names)}"
            )
        period = float(unit.sample_period)
        density_a = (
            float(unit.accelerometer_std) * math.sqrt(period) if accelerometer_noise is None else _number("accelerometer_noise", accelerometer_noise)
        )
        density_g = float(unit.gyro_std) * math.sqrt(period) if gyro_noise is None else _number("gyro_noise", gyro_noise)
        drift_std, drift_time = _bias_drift(unit)
        if bias_std is not None:
            drift_std = np.broadcast_to(np.asarray(check.vector("bias_std", bias_std), dtype=float), (3,)).copy()
            check.positive("bias_std", drift_std, allow_zero=True)
        if bias_time_constant is None:  # a random walk of the drift's intensity (random_walk_std)
            drift_std, drift_time = random_walk_std(drift_std, drift_time), math.inf
        else:
            drift_time = _number("bias_time_constant", bias_time_constant, allow_zero=False, allow_inf=True)
        prior = np.broadcast_to(np.asarray(check.vector("initial_bias_std", initial_bias_std), dtype=float), (3,))
        if not (np.all(np.isfinite(prior)) and np.all(prior > 0)):
            raise check.ParameterError("initial_bias_std", f"initial_bias_std must be 3 finite numbers > 0; got {prior.tolist()}")
        waves, wave_prior = sea_model(wave_period, wave_std), None
        if waves is not None and wave_period is not None:  # given together (sea_model)
            frequency = 2 * math.pi / float(wave_period)
            spread = np.broadcast_to(np.asarray(wave_std, dtype=float), (3,))
            wave_prior = np.concatenate([np.maximum(spread / frequency, 1e-6), np.maximum(spread, 1e-6)])
        model = StrapdownVessel(density_a, density_g, drift_std, drift_time, np.asarray(unit.lever_arm), waves)
        position_std, heading_std = _aiding_spread(sensor)
        initial = {"eta": [position_std, position_std, heading_std], "velocity": INITIAL_VELOCITY_STD, "bias": prior.tolist()}
        if wave_prior is not None:
            initial["wave_state"] = wave_prior.tolist()
        imu_channels = tuple(first <= channel < first + unit.size for channel in range(layout.size))
        fields = kalman_fields(
            model,
            sensor,
            process_noise=None,
            state_noise=None,
            measurement_noise=measurement_noise,
            initial_std=initial,
            plant_step=plant_step,
            sample_period=filter_period,
            integrator=integrator,
            ignored_channels=imu_channels,
        )
        for key, value in fields.items():
            setattr(self, key, value)
        self.imu_start = first
        # what the engine gives predict: the IMU's reading is in the measurement, thrust is not needed
        self.input_layout = Layout()
        del name

    # ---------------------------------------------------------------- the IMU as input
    def reading(self, state: KalmanState, y: Array) -> Array:
        """The IMU's reading in ``y`` (its specific force and yaw rate); where missing,
        the last one the filter held."""
        fresh = jnp.asarray(y, dtype=float)[self.imu_start : self.imu_start + 3]
        held = jnp.zeros(3) if state.applied is None else state.applied
        return jnp.where(jnp.isfinite(fresh), fresh, held)

    def measurement(self, mean: Array, applied: Array | None = None, t: ArrayLike = 0.0) -> Array:
        """h(x) under the IMU's reading ``applied`` (zero when None)."""
        return super().measurement(mean, jnp.zeros(3) if applied is None else applied, t)

    def init(self, y0: Array, guess: Any) -> KalmanState:
        state = super().init(y0, guess)
        start = KalmanState(state.mean, state.covariance, jnp.zeros(3), state.time)
        return KalmanState(state.mean, state.covariance, self.reading(start, y0), state.time)

    def update(self, state: KalmanState, t: ArrayLike, y: Array) -> KalmanState:
        # the correction takes h under the reading of this sample (the rate the gyro gives now)
        corrected = super().update(KalmanState(state.mean, state.covariance, self.reading(state, y), state.time), t, y)
        return corrected

    def predict(self, state: KalmanState, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> KalmanState:
        """From t to t + dt with the IMU's reading at t held (``u``, the thrust, unused)."""
        del u
        reading = self.reading(state, y)
        prior = self.propagate(state, t, reading, dt)
        return KalmanState(prior.mean, prior.covariance, reading, jnp.asarray(t + dt, dtype=float))

    def output(self, state: KalmanState, y: Array) -> dict[str, Array]:
        """The model's variables, the yaw rate the held reading less the gyro bias's estimate."""
        estimate = super().output(state, y)
        reading = jnp.zeros(3) if state.applied is None else state.applied
        estimate["yaw_rate"] = reading[2] - estimate["gyro_bias"]
        return estimate


def _aiding_spread(sensor: SensorSuite) -> tuple[float, float]:
    """The prior spread of position (m) and heading (rad): the least of the suite's
    position and heading channels' (the first fix sets them; the spread is its error)."""
    from lookout.observers.kalman import suite_measurement_std

    std = suite_measurement_std(sensor)
    position, heading, start = math.inf, math.inf, 0
    for signal in sensor.instrument_layout.signals:
        values = std[start : start + signal.size]
        if signal.name.endswith("position"):
            position = min(position, float(np.max(values)))
        elif signal.name.endswith("heading"):
            heading = min(heading, float(np.max(values)))
        start += signal.size
    return max(position, 1e-3), max(heading, 1e-5)


__all__ = ["INITIAL_BIAS_STD", "InertialNavigationFilter", "random_walk_std"]
