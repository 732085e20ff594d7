"""The continuous-discrete unscented Kalman filter over any Plant and Sensor.

Propagation, noise, masking and defaults: :mod:`lookout.observers.kalman` (the same
discrete step Phi and the same Q_d as the extended filter, linearized at the mean).
Per sample, with n states, the scaled unscented transformation of Wan & van der
Merwe (2000), "The unscented Kalman filter for nonlinear estimation", Section 3
(after Julier & Uhlmann 1997):

    lambda = alpha^2 (n + kappa) - n
    chi_0 = x,  chi_i = x + [sqrt((n + lambda) P)]_i,  chi_(n+i) = x - [...]_i
                (sqrt: the Cholesky factor, taken on the correlation matrix)
    W0_m = lambda / (n + lambda),  W0_c = W0_m + 1 - alpha^2 + beta,
    Wi_m = Wi_c = 1 / (2 (n + lambda))

    prior        chi_i- = Phi(chi_i, 0);  x- = sum W_m chi_i-;  P- = sum W_c d_i d_i^T + Q_d
    correction   sigma points redrawn from (x-, P-);  Y_i = h(chi_i)
                 y^ = sum W_m Y_i;  S = sum W_c e_i e_i^T + R;  C = sum W_c d_i e_i^T
                 K = C S^-1;  x+ = x- + K nu;  P+ = P- - K S K^T

with d_i = chi_i - x and e_i = Y_i - y^. Angles stay angles: means are taken as
the first point plus the weighted mean of the wrapped differences from it, and every
deviation of an angle (state or channel) is wrapped by ``ssa``, so a heading near
+-pi averages to +-pi rather than to 0. A missing channel's deviations and
innovation are zero (the masking of the extended filter).
"""

from __future__ import annotations

from typing import Any, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa
from lookout.components import Plant, Sensor
from lookout.declare import NON_NEGATIVE, POSITIVE, Context, Part, Range, Value, component
from lookout.observers.kalman import PARAMETERS, KalmanFilter, KalmanState, _symmetric, kalman_fields, masked, masked_noise


def _wrapped(deviations: Array, angles: tuple[bool, ...]) -> Array:
    return jnp.where(jnp.asarray(angles), ssa(deviations), deviations)


def square_root(covariance: Array) -> Array:
    """A lower-triangular L with L L^T = ``covariance``, for a covariance whose entries
    span many decades (a vessel's states: 1e-4 to 1e10) and may have exactly zero
    variances (a state known exactly, such as a wave state the model has none of): the
    Cholesky factor of the correlation matrix (unit diagonal where a variance is zero),
    scaled by the standard deviations. Rows of zero variance are zero."""
    covariance = _symmetric(covariance)
    std = jnp.sqrt(jnp.maximum(jnp.diagonal(covariance), 0.0))
    known = std > 0.0
    scale = jnp.where(known, std, 1.0)
    correlation = covariance / jnp.outer(scale, scale)
    correlation = jnp.where(jnp.outer(known, known), correlation, jnp.diag(jnp.where(known, 0.0, 1.0)))
    return jnp.linalg.cholesky(correlation) * std[:, None]


def _mean(points: Array, weights: Array, angles: tuple[bool, ...]) -> Array:
    """The weighted mean of ``points`` (rows), angle entries through wrapped differences
    from the first point."""
    deviations = _wrapped(points - points[0], angles)
    return points[0] + weights @ deviations


@component(
    "observer",
    "ukf",
    summary="Continuous-discrete unscented Kalman filter on the plant's own model (lookout.observers.ukf): the extended filter's propagation and masking, with sigma points in place of Jacobians for the mean and the measurement.",
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
        Value("alpha", "float", "Spread of the sigma points around the mean (Wan & van der Merwe's alpha).", range=Range(0.0, 1.0, False, True)),
        Value("beta", "float", "Prior knowledge of the distribution (2 for a Gaussian).", range=NON_NEGATIVE),
        Value("kappa", "float", "Secondary scaling; n + kappa must be positive."),
        Context(
            "plant_step",
            "Step of the propagation (s); default the composition's simulation.plant_step, which makes the propagation the simulated plant's own discretization.",
            own=True,
        ),
        Context("filter_period", "The filter's sample period (s), for the steady-state P_0; default the composition's simulation.sample_period."),
        Context("integrator", "rk4 or euler; default the composition's simulation.integrator.", own=True),
    ),
)
@final
class UnscentedKalmanFilter(KalmanFilter):
    __doc__ = (
        """Continuous-discrete unscented Kalman filter on the plant's own model
    (:mod:`lookout.observers.ukf`): the extended filter's propagation and masking, with
    sigma points in place of Jacobians for the mean and the measurement.

    Parameters
    ----------"""
        + PARAMETERS
        + """
    alpha : float, in (0, 1]
        Spread of the sigma points around the mean (Wan & van der Merwe's alpha).
    beta : float, non-negative
        Prior knowledge of the distribution (2 for a Gaussian).
    kappa : float
        Secondary scaling; n + kappa must be positive."""
    )

    alpha: float = eqx.field(static=True)
    beta: float = eqx.field(static=True)
    kappa: float = eqx.field(static=True)

    def __init__(
        self,
        plant: Plant,
        sensor: Sensor,
        process_noise: npt.ArrayLike | None = None,
        state_noise: npt.ArrayLike | dict[str, Any] | None = None,
        measurement_noise: npt.ArrayLike | None = None,
        initial_std: npt.ArrayLike | dict[str, Any] | None = None,
        input_disturbance: npt.ArrayLike | None = None,
        alpha: float = 1.0,
        beta: float = 2.0,
        kappa: float = 0.0,
        *,
        plant_step: float,
        filter_period: float,
        integrator: str = "rk4",
    ):
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
        n = fields["initial_covariance"].shape[0]
        if not 0.0 < float(alpha) <= 1.0:
            raise check.ParameterError("alpha", f"alpha must be in (0, 1]; got {alpha}")
        if not float(beta) >= 0.0:
            raise check.ParameterError("beta", f"beta must be >= 0; got {beta}")
        if not n + float(kappa) > 0.0:
            raise check.ParameterError("kappa", f"kappa must exceed -n = {-n} (the state has {n} entries); got {kappa}")
        self.alpha, self.beta, self.kappa = float(alpha), float(beta), float(kappa)

    def _weights(self, n: int) -> tuple[Array, Array, float]:
        spread = self.alpha**2 * (n + self.kappa) - n
        rest = jnp.full(2 * n, 1.0 / (2.0 * (n + spread)))
        mean_weights = jnp.concatenate([jnp.asarray([spread / (n + spread)]), rest])
        covariance_weights = mean_weights.at[0].add(1.0 - self.alpha**2 + self.beta)
        return mean_weights, covariance_weights, n + spread

    def _points(self, mean: Array, covariance: Array, scale: float) -> Array:
        root = square_root(scale * covariance)
        return jnp.concatenate([mean[None, :], mean + root.T, mean - root.T])

    def propagate(self, state: KalmanState, t: ArrayLike, u: Array, dt: ArrayLike) -> KalmanState:
        n = state.mean.size
        mean_weights, covariance_weights, scale = self._weights(n)
        points = jax.vmap(lambda x: self.step(x, t, u, dt))(self._points(state.mean, state.covariance, scale))
        prior = _mean(points, mean_weights, self.state_angles)
        deviations = _wrapped(points - prior, self.state_angles)
        covariance = (deviations * covariance_weights[:, None]).T @ deviations + self.process_covariance(state.mean, t, u, dt)
        return KalmanState(self.normalized(prior), _symmetric(covariance))

    def _innovation(self, state: KalmanState, t: ArrayLike, y: Array, due: Array):
        """(nu, S, sigma points, their measurement deviations, covariance weights) at ``t``
        on the channels that are ``due`` and finite, the others masked."""
        mean_weights, covariance_weights, scale = self._weights(state.mean.size)
        points = self._points(state.mean, state.covariance, scale)
        measured = jax.vmap(lambda x: self.measurement(x, state.applied, t))(points)
        predicted = _mean(measured, mean_weights, self.channel_angles)
        innovation, mask = masked(y, predicted, due, self.channel_angles)
        errors = _wrapped(measured - predicted, self.channel_angles) * mask[None, :]
        noise = masked_noise(self.measurement_covariance, mask)
        innovation_covariance = _symmetric((errors * covariance_weights[:, None]).T @ errors + noise)
        return innovation, innovation_covariance, points, errors, covariance_weights

    def innovation_statistics(self, state: KalmanState, y: Array) -> tuple[Array, Array]:
        """nu = y - y_hat and S = sum W_c e_i e_i^T + R at the prior (:meth:`KalmanFilter.innovation_statistics`)."""
        innovation, innovation_covariance, *_ = self._innovation(state, self._time(state), y, jnp.ones(jnp.shape(y), dtype=bool))
        return innovation, innovation_covariance

    def correct(self, state: KalmanState, t: ArrayLike, y: Array) -> KalmanState:
        innovation, innovation_covariance, points, errors, covariance_weights = self._innovation(state, t, y, self.due(t))
        deviations = _wrapped(points - state.mean, self.state_angles)
        cross = (deviations * covariance_weights[:, None]).T @ errors
        gain = jnp.linalg.solve(innovation_covariance, cross.T).T
        posterior = self.normalized(state.mean + gain @ innovation)
        return KalmanState(posterior, _symmetric(state.covariance - gain @ innovation_covariance @ gain.T))
