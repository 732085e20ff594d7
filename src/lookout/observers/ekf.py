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

from typing import final

import jax
import jax.numpy as jnp
from jax import Array

from lookout.components import Plant, Sensor
from lookout.observers.kalman import PARAMETERS, KalmanFilter, KalmanState, _symmetric, kalman_fields, masked, masked_noise


@final
class ExtendedKalmanFilter(KalmanFilter):
    __doc__ = """Continuous-discrete extended Kalman filter on the plant's own model
    (:mod:`lookout.observers.ekf`). Estimates every state of its model: its estimate
    signals are the model plant's variables.

    Parameters
    ----------""" + PARAMETERS

    def __init__(self, plant: Plant, sensor: Sensor, process_noise=None, state_noise=None, measurement_noise=None, initial_std=None,
                 input_disturbance=None, *,
                 plant_step: float, filter_period: float, integrator: str = "rk4"):
        fields = kalman_fields(plant, sensor, process_noise=process_noise, state_noise=state_noise, measurement_noise=measurement_noise,
                               initial_std=initial_std, plant_step=plant_step, sample_period=filter_period, integrator=integrator,
                               input_disturbance=input_disturbance)
        for name, value in fields.items():
            setattr(self, name, value)

    def propagate(self, state: KalmanState, t, u: Array, dt) -> KalmanState:
        mean, covariance = state.mean, state.covariance
        transition, noise, stepped = self.linearized(mean, t, u, dt)
        prior = self.normalized(stepped)
        return KalmanState(prior, _symmetric(transition @ covariance @ transition.T + noise))

    def _innovation(self, state: KalmanState, y: Array, due: Array):
        """(nu, S, H, R) on the channels that are ``due`` and finite, the others masked."""
        predicted = self.measurement(state.mean)
        innovation, mask = masked(y, predicted, due, self.channel_angles)
        observation = jax.jacfwd(self.measurement)(state.mean) * mask[:, None]
        noise = masked_noise(self.measurement_covariance, mask)
        return innovation, _symmetric(observation @ state.covariance @ observation.T + noise), observation, noise

    def innovation_statistics(self, state: KalmanState, y: Array) -> tuple[Array, Array]:
        """nu = y - h(x-) and S = H P- H^T + R at the prior (:meth:`KalmanFilter.innovation_statistics`)."""
        innovation, innovation_covariance, _, _ = self._innovation(state, y, jnp.ones(jnp.shape(y), dtype=bool))
        return innovation, innovation_covariance

    def correct(self, state: KalmanState, t, y: Array) -> KalmanState:
        mean, covariance = state.mean, state.covariance
        innovation, innovation_covariance, observation, noise = self._innovation(state, y, self.due(t))
        gain = jnp.linalg.solve(innovation_covariance, observation @ covariance).T
        posterior = self.normalized(mean + gain @ innovation)
        factor = jnp.eye(mean.size) - gain @ observation
        return KalmanState(posterior, _symmetric(factor @ covariance @ factor.T + gain @ noise @ gain.T))
