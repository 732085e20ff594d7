"""The continuous-discrete extended Kalman filter over any Plant and Sensor.

Propagation, noise, masking and defaults: :mod:`lookout.observers.kalman`. Per
sample, with x the raveled state, P its covariance and Phi the model's discrete step:

    prior        x- = Phi(x, 0),   P- = F P F^T + Q_d,   F = dPhi/dx at x
    correction   H = dh/dx at x-,  nu = y - h(x-) (masked, angles wrapped)
                 S = H P- H^T + R,  K = P- H^T S^-1
                 x+ = x- + K nu (angles wrapped)
                 P+ = (I - K H) P- (I - K H)^T + K R K^T   (Joseph form, symmetrized)

The extended Kalman filter as in Jazwinski (1970), Stochastic Processes and
Filtering Theory, Section 8.4 (continuous-discrete, with the covariance carried by the
linearized discrete step); the covariance update in Joseph's form, which stays
symmetric positive semi-definite for any gain (Bucy & Joseph 1968, Filtering for
Stochastic Processes with Applications to Guidance, Section 9.5).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout.components import Plant, Sensor
from lookout.declare import NON_NEGATIVE, POSITIVE, Context, Part, Value, component
from lookout.observers.kalman import PARAMETERS, KalmanFilter, KalmanState, _symmetric, kalman_fields, masked, masked_noise


def _with_imu_biases(plant: Plant, sensor: Sensor, imu_bias: npt.ArrayLike) -> Plant:
    """``plant`` with the IMU's biases as states, for a suite with an IMU."""
    from lookout import _validation as check
    from lookout.models.imu_biases import ImuBiases
    from lookout.sensing.motion import InertialUnit
    from lookout.sensing.suite import SensorSuite

    if not (isinstance(sensor, SensorSuite) and any(isinstance(each, InertialUnit) for each in sensor.instruments)):
        raise check.ParameterError("imu_bias", "imu_bias: the filter's sensor has no IMU (a suite with an imu instrument) whose biases to estimate")
    return ImuBiases(plant, imu_bias)


@component(
    "observer",
    "ekf",
    summary="Continuous-discrete extended Kalman filter on the plant's own model (lookout.observers.ekf).",
    family="lookout.tuning.families.kalman:KalmanFamily",
    parameters=(
        Part(
            "plant",
            "The filter's model of the plant (default: the composition's plant; give a [observer.plant] table for a model that differs from the truth).",
        ),
        Part("sensor", "The filter's model of the sensor (default: the composition's sensor)."),
        Value(
            "process_noise",
            "array",
            "Intensity of each of the model's unit white noise inputs (1: the model's own; default all 1).",
            shape="(noise_size,)",
            range=NON_NEGATIVE,
        ),
        Value(
            "state_noise",
            "parts",
            "Continuous-time process noise intensity added per state entry (units^2/s): one per raveled state entry, or a table of the plant's state parts as [plant.initial] takes them (default 0).",
            range=NON_NEGATIVE,
            broadcast=False,
        ),
        Value(
            "measurement_noise",
            "array",
            "Standard deviation of each measured channel, R = diag(std^2) (default: the sensor's own noise).",
            shape="(m,)",
            range=POSITIVE,
        ),
        Value(
            "initial_std",
            "parts",
            "Standard deviation of the initial guess per state entry, or a table of the plant's state parts and input_disturbance (default: the steady-state filter's, from the Riccati equation).",
            range=NON_NEGATIVE,
            broadcast=False,
        ),
        Value(
            "input_disturbance",
            "array",
            "Estimate an unknown disturbance added to the plant's input, a random walk of this intensity per input entry (units^2/s; 0: a constant, and with an initial std of 0 none on that entry): the usual DP bias state, for a model without one (default none).",
            range=NON_NEGATIVE,
        ),
        Value(
            "imu_bias",
            "array",
            "Estimate the suite's IMU's biases as states, random walks of these intensities' square roots [accelerometers (m/s2/sqrt(s)) x2, gyro (rad/s/sqrt(s))], so that its specific force is a measurement of the model's acceleration with its bias (acceleration feedback, lookout.models.imu_biases); default none.",
            shape="(3,)",
            range=NON_NEGATIVE,
        ),
        Context(
            "plant_step",
            "Step of the propagation (s); default the composition's simulation.plant_step, which makes the propagation the simulated plant's own discretization.",
            own=True,
        ),
        Context("filter_period", "The filter's sample period (s), for the steady-state P_0; default the composition's simulation.sample_period."),
        Context("integrator", "rk4 or euler; default the composition's simulation.integrator.", own=True),
    ),
)
class ExtendedKalmanFilter(KalmanFilter):
    __doc__ = (
        """Continuous-discrete extended Kalman filter on the plant's own model
    (:mod:`lookout.observers.ekf`). Estimates every state of its model: its estimate
    signals are the model plant's variables.

    Parameters
    ----------"""
        + PARAMETERS
        + """
    imu_bias : array_like, shape (3,), non-negative, optional
        Estimate the suite's IMU's biases as states, random walks of these intensities'
        square roots [accelerometers (m/s2/sqrt(s)) x2, gyro (rad/s/sqrt(s))], so that its
        specific force is a measurement of the model's acceleration with its bias
        (acceleration feedback, :mod:`lookout.models.imu_biases`); default none."""
    )

    def __init__(
        self,
        plant: Plant,
        sensor: Sensor,
        process_noise: npt.ArrayLike | None = None,
        state_noise: npt.ArrayLike | dict[str, Any] | None = None,
        measurement_noise: npt.ArrayLike | None = None,
        initial_std: npt.ArrayLike | dict[str, Any] | None = None,
        input_disturbance: npt.ArrayLike | None = None,
        imu_bias: npt.ArrayLike | None = None,
        *,
        plant_step: float,
        filter_period: float,
        integrator: str = "rk4",
    ):
        if imu_bias is not None:
            plant = _with_imu_biases(plant, sensor, imu_bias)
        fields = kalman_fields(
            plant,
            sensor,
            process_noise=process_noise,
            state_noise=state_noise,
            measurement_noise=measurement_noise,
            initial_std=initial_std,
            plant_step=plant_step,
            sample_period=filter_period,
            integrator=integrator,
            input_disturbance=input_disturbance,
        )
        for name, value in fields.items():
            setattr(self, name, value)

    def propagate(self, state: KalmanState, t: ArrayLike, u: Array, dt: ArrayLike) -> KalmanState:
        mean, covariance = state.mean, state.covariance
        transition, noise, stepped = self.linearized(mean, t, u, dt)
        prior = self.normalized(stepped)
        return KalmanState(prior, _symmetric(transition @ covariance @ transition.T + noise))

    def _innovation(self, state: KalmanState, t: ArrayLike, y: Array, due: Array):
        """(nu, S, H, R) at ``t`` on the channels that are ``due`` and finite, the others masked."""
        h = lambda x: self.measurement(x, state.applied, t)  # noqa: E731  (the state's input: a suite's IMU)
        predicted = h(state.mean)
        innovation, mask = masked(y, predicted, due, self.channel_angles)
        observation = jax.jacfwd(h)(state.mean) * mask[:, None]
        noise = masked_noise(self.measurement_covariance, mask)
        return innovation, _symmetric(observation @ state.covariance @ observation.T + noise), observation, noise

    def innovation_statistics(self, state: KalmanState, y: Array) -> tuple[Array, Array]:
        """nu = y - h(x-) and S = H P- H^T + R at the prior (:meth:`KalmanFilter.innovation_statistics`)."""
        innovation, innovation_covariance, _, _ = self._innovation(state, self._time(state), y, jnp.ones(jnp.shape(y), dtype=bool))
        return innovation, innovation_covariance

    def correct(self, state: KalmanState, t: ArrayLike, y: Array) -> KalmanState:
        mean, covariance = state.mean, state.covariance
        innovation, innovation_covariance, observation, noise = self._innovation(state, t, y, self.due(t))
        gain = jnp.linalg.solve(innovation_covariance, observation @ covariance).T
        posterior = self.normalized(mean + gain @ innovation)
        factor = jnp.eye(mean.size) - gain @ observation
        return KalmanState(posterior, _symmetric(factor @ covariance @ factor.T + gain @ noise @ gain.T))
