"""An observer for a vessel nobody modelled: the extended Kalman filter on the kinematic
vessel (:mod:`lookout.observers.ekf` on :class:`~lookout.models.kinematic_vessel.KinematicVessel`),
tuned from the sensors' noise alone.

Without M and D, the filter knows the vessel by what it measures: its velocities are a
random walk driven by white acceleration of intensity q per degree of freedom. The one
choice is how fast the estimate follows a change of velocity, ``settling_time``; q
then follows from the measurement noise. For one axis, position x with velocity v,
x' = v, v' = sqrt(q) w, measured every T seconds with noise sigma (a continuous-time
measurement noise density r = sigma^2 T), the steady-state Kalman-Bucy filter's error
dynamics are the second-order Butterworth polynomial

    s^2 + sqrt(2) omega s + omega^2,       omega = (q / r)^(1/4)

(the steady-state alpha-beta filter of the continuous white noise acceleration model;
Bar-Shalom, Li & Kirubarajan (2001), Estimation with Applications to Tracking and
Navigation, Chapter 6; Kalata (1984), "The tracking index", IEEE Transactions on
Aerospace and Electronic Systems 20(2), 174-182). Its 2 % settling time is
4 / (zeta omega) = 4 sqrt(2) / omega with zeta = 1 / sqrt(2), so

    q = sigma^2 T (4 sqrt(2) / settling_time)^4

per axis: surge and sway from the position channels (the most precise reference,
smallest sigma^2 T), yaw from the heading channels. A shorter settling time follows a
manoeuvre sooner and passes more noise to the velocity estimate.

On a sensor suite it reads the position references and gyros; an IMU's channels are left
out (the model has no acceleration to compare them with: its velocity's mean is constant).

In waves (``wave_period``, ``wave_std``), the model carries the first-order wave motion
of Fossen & Strand (1999), eqs. (10)-(11), with relative damping 0.1 at the given peak
period, and the filter separates it from the low-frequency motion as the model-based
observers do.
"""

from __future__ import annotations

import math
from typing import final

import numpy as np
import numpy.typing as npt

from lookout import _validation as check
from lookout.components import Sensor
from lookout.declare import NON_NEGATIVE, POSITIVE, Context, Part, Value, component
from lookout.environment import LinearWaveModel
from lookout.models.kinematic_vessel import KinematicVessel
from lookout.observers.ekf import ExtendedKalmanFilter
from lookout.observers.kalman import default_measurement_covariance, filter_layout, kalman_fields
from lookout.sensing.motion import InertialUnit
from lookout.sensing.suite import SensorSuite

#: The settling time of the velocity estimate unless told (s): a DP vessel's or a
#: yacht's manoeuvre changes its speed over tens of seconds.
SETTLING_TIME = 20.0
#: The wave model's relative damping (Fossen & Strand (1999), Section 6.1, use 0.1).
WAVE_DAMPING = 0.1


#: The two parameters that put a kinematic observer in waves (this one and the IMU-aided one).
WAVE_PERIOD = Value("wave_period", "float", "Peak period of the waves the vessel moves in (s); none: calm water (default none).", range=POSITIVE)
WAVE_STD = Value(
    "wave_std",
    "array",
    "Standard deviation of the wave-frequency motion (m, m, rad), with wave_period (default none).",
    shape="(3,)",
    range=NON_NEGATIVE,
)


def sea_model(wave_period: float | None, wave_std: npt.ArrayLike | None) -> LinearWaveModel | None:
    """The first-order wave model of Fossen & Strand (1999), eqs. (10)-(11), at the peak
    period ``wave_period`` with relative damping :data:`WAVE_DAMPING` and the motion's
    standard deviation ``wave_std``; None for calm water (neither given).

    Raises
    ------
    ValueError
        Naming ``wave_period``: one given without the other, or a period not positive.
    """
    if (wave_period is None) != (wave_std is None):
        raise check.ParameterError("wave_period", "wave_period and wave_std go together: give both for a vessel in waves, or neither")
    if wave_period is None or wave_std is None:
        return None
    check.positive("wave_period", wave_period)
    return LinearWaveModel.from_std(np.full(3, 2 * math.pi / float(wave_period)), np.full(3, WAVE_DAMPING), wave_std)


def acceleration_intensity(noise_density: float, settling_time: float) -> float:
    """q = r (4 sqrt(2) / settling_time)^4, r = sigma^2 T: the white acceleration's
    intensity whose steady-state filter settles in ``settling_time`` (module docstring)."""
    return noise_density * (4.0 * math.sqrt(2.0) / settling_time) ** 4


def _axis_noise(sensor: Sensor, covariance: np.ndarray, periods: np.ndarray, suffix: str) -> float:
    """The smallest sigma^2 T over the channels whose signal ends with ``suffix``."""
    layout = filter_layout(sensor)
    std = np.sqrt(np.diag(covariance))
    best, start = math.inf, 0
    for signal in layout.signals:
        if signal.name.endswith(suffix):
            for channel in range(start, start + (signal.size if suffix == "position" else 1)):
                best = min(best, float(std[channel] ** 2 * periods[channel]))
        start += signal.size
    return best


@component(
    "observer",
    "model-free",
    summary="Extended Kalman filter on a vessel without a hull model (velocities a random walk), tuned from the sensors' noise (lookout.observers.model_free).",
    parameters=(
        Part("sensor", "The filter's model of the sensor (default: the composition's sensor)."),
        Value(
            "settling_time",
            "float",
            "2 % settling time of the velocity estimate after a change of velocity (s); sets the white acceleration's intensity from the measurement noise (20).",
            range=POSITIVE,
        ),
        WAVE_PERIOD,
        WAVE_STD,
        Value(
            "measurement_noise",
            "array",
            "Standard deviation of each measured channel, R = diag(std^2), for the tuning and the filter (default: the sensor's own noise).",
            shape="(m,)",
            range=POSITIVE,
        ),
        Context("plant_step", "Step of the propagation (s); default the composition's simulation.plant_step.", own=True),
        Context("filter_period", "The filter's sample period (s), for the steady-state P_0; default the composition's simulation.sample_period."),
        Context("integrator", "rk4 or euler; default the composition's simulation.integrator.", own=True),
    ),
)
@final
class ModelFreeFilter(ExtendedKalmanFilter):
    """The extended Kalman filter on :class:`~lookout.models.kinematic_vessel.KinematicVessel`,
    its white acceleration from the sensor's noise (module docstring).

    Parameters
    ----------
    sensor : Sensor
        The filter's model of the sensor (default: the composition's sensor).
    settling_time : float, positive
        2 % settling time of the velocity estimate after a change of velocity (s); sets the white acceleration's intensity from the measurement noise (20).
    wave_period : float, positive, optional
        Peak period of the waves the vessel moves in (s); none: calm water (default none).
    wave_std : array_like, shape (3,), non-negative, optional
        Standard deviation of the wave-frequency motion (m, m, rad), with wave_period (default none).
    measurement_noise : array_like, shape (m,), positive, optional
        Standard deviation of each measured channel, R = diag(std^2), for the tuning and the filter (default: the sensor's own noise).
    plant_step : float
        Step of the propagation (s); default the composition's simulation.plant_step.
    filter_period : float
        The filter's sample period (s), for the steady-state P_0; default the composition's simulation.sample_period.
    integrator : str
        rk4 or euler; default the composition's simulation.integrator.
    Raises
    ------
    ValueError
        Naming the parameter: a settling time not finite and positive, one of
        ``wave_period`` and ``wave_std`` without the other, or a sensor without a
        position and a heading channel.
    """

    def __init__(
        self,
        sensor: Sensor,
        settling_time: float = SETTLING_TIME,
        wave_period: float | None = None,
        wave_std: npt.ArrayLike | None = None,
        measurement_noise: npt.ArrayLike | None = None,
        *,
        plant_step: float,
        filter_period: float,
        integrator: str = "rk4",
    ):
        if isinstance(settling_time, bool) or not isinstance(settling_time, (int, float)) or not (math.isfinite(settling_time) and settling_time > 0):
            raise check.ParameterError("settling_time", f"settling_time must be a finite positive number of seconds; got {settling_time!r}")
        waves = sea_model(wave_period, wave_std)
        names = [signal.name for signal in filter_layout(sensor).signals]
        if not (any(name.endswith("position") for name in names) and any(name.endswith("heading") for name in names)):
            raise check.ParameterError(
                "sensor", f"sensor: the model-free observer reads a vessel's position and heading; the sensor measures {', '.join(names)}"
            )
        if measurement_noise is None:
            covariance = default_measurement_covariance(sensor, KinematicVessel(waves=waves))
        else:
            std = np.asarray(measurement_noise, dtype=float)
            if std.shape != (filter_layout(sensor).size,) or not (np.all(np.isfinite(std)) and np.all(std > 0)):
                raise check.ParameterError(
                    "measurement_noise",
                    f"measurement_noise must be {filter_layout(sensor).size} finite standard deviations > 0 (one per measured channel); got {std.tolist()}",
                )
            covariance = np.diag(std**2)
        periods = np.asarray(sensor.sample_period, dtype=float)[: filter_layout(sensor).size]
        position, heading = (_axis_noise(sensor, covariance, periods, suffix) for suffix in ("position", "heading"))
        if not (math.isfinite(position) and math.isfinite(heading)):
            raise check.ParameterError("sensor", "sensor: the model-free observer needs a position and a heading channel with noise of their own")
        q = np.array([acceleration_intensity(position, settling_time)] * 2 + [acceleration_intensity(heading, settling_time)])
        # an IMU in a suite measures an acceleration this model does not have (its mean is zero)
        layout_size = filter_layout(sensor).size
        imu = [False] * layout_size
        if isinstance(sensor, SensorSuite):
            start = 0
            for each in sensor.instruments:
                if isinstance(each, InertialUnit):
                    imu[start : start + each.size] = [True] * each.size
                start += each.size
        fields = kalman_fields(
            KinematicVessel(np.sqrt(q), waves),
            sensor,
            process_noise=None,
            state_noise=None,
            measurement_noise=measurement_noise,
            initial_std=None,
            plant_step=plant_step,
            sample_period=filter_period,
            integrator=integrator,
            ignored_channels=tuple(imu),
        )
        for name, value in fields.items():
            setattr(self, name, value)


__all__ = ["SETTLING_TIME", "WAVE_PERIOD", "WAVE_STD", "ModelFreeFilter", "acceleration_intensity", "sea_model"]
