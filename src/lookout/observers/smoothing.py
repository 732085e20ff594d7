"""A log known end to end: the Rauch-Tung-Striebel smoother after a Kalman-type
observer (the extended, the unscented and the model-free filters).

The forward pass is the filter itself, row by row as :func:`lookout.filter` runs it
(correction at t_k, then prediction to t_{k+1}), keeping at each row the posterior
x_k|k, P_k|k, the prior x_k+1|k, P_k+1|k and the Jacobian F_k = dPhi/dx of the step
from t_k to t_k+1 at x_k|k (:meth:`~lookout.observers.kalman.KalmanFilter.linearized`,
the propagation the extended filter uses). The backward pass, from the last row's
posterior, is Rauch, Tung & Striebel (1965), "Maximum likelihood estimates of linear
dynamic systems", AIAA Journal 3(8), 1445-1450, eqs. (3.30)-(3.32) in the form of
Saerkkae (2013), Bayesian Filtering and Smoothing, Theorem 8.2::

    C_k    = P_k|k F_k^T P_k+1|k^-1
    x_k|N  = x_k|k + C_k (x_k+1|N - x_k+1|k)       (angle differences wrapped)
    P_k|N  = P_k|k + C_k (P_k+1|N - P_k+1|k) C_k^T

On a linear model the filter is the exact Kalman filter and this the exact RTS
smoother. On a nonlinear model it is the extended RTS smoother (Saerkkae 2013,
Section 9.1); after the unscented filter the gain is taken with the same linearized
F_k rather than the unscented cross-covariance (an approximation of the unscented RTS
smoother, Saerkkae 2013, Section 9.3, whose cross-covariance the filter does not keep).
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import xarray as xr
from jax import Array

from lookout._math import ssa
from lookout.components import Layout
from lookout.observers.kalman import KalmanFilter, KalmanState
from lookout.sim.filtering import checked_log, filtered_dataset


def _forward(observer: KalmanFilter, guess, times: Array, measurements: Array, inputs: Array):
    steps = jnp.diff(times, append=times[-1:])  # the last row is not propagated

    def row(state, data):
        t, y, u, dt = data
        posterior = observer.update(state, t, y)
        transition, _, _ = observer.linearized(posterior.mean, t, u, dt)
        prior = observer.predict(posterior, t, y, u, dt)
        return prior, (posterior.mean, posterior.covariance, prior.mean, prior.covariance, transition)

    first = observer.init(measurements[0], guess)
    _, rows = jax.lax.scan(row, first, (times, measurements, inputs, steps))
    return rows


def _backward(observer: KalmanFilter, rows):
    means, covariances, prior_means, prior_covariances, transitions = rows
    angles = jnp.asarray(observer.state_angles)

    def row(carry, data):
        smoothed_mean, smoothed_covariance = carry
        mean, covariance, prior_mean, prior_covariance, transition = data
        gain = jnp.linalg.solve(prior_covariance, transition @ covariance).T  # P F^T P-^-1 (P- symmetric)
        difference = smoothed_mean - prior_mean
        difference = jnp.where(angles, ssa(difference), difference)
        new_mean = observer.normalized(mean + gain @ difference)
        new_covariance = covariance + gain @ (smoothed_covariance - prior_covariance) @ gain.T
        new_covariance = 0.5 * (new_covariance + new_covariance.T)
        return (new_mean, new_covariance), (new_mean, new_covariance)

    last = (means[-1], covariances[-1])
    earlier = jax.tree.map(lambda a: a[:-1], (means, covariances, prior_means, prior_covariances, transitions))
    _, (smoothed_means, smoothed_covariances) = jax.lax.scan(row, last, earlier, reverse=True)
    return jnp.concatenate([smoothed_means, means[-1:]]), jnp.concatenate([smoothed_covariances, covariances[-1:]])


@eqx.filter_jit
def _smooth(observer: KalmanFilter, guess, times, measurements, inputs):
    rows = _forward(observer, guess, times, measurements, inputs)
    means, covariances = _backward(observer, rows)
    output = jax.vmap(lambda m, p, y: observer.output(KalmanState(m, p), y))
    return output(rows[0], rows[1], measurements), output(means, covariances, measurements), means, covariances


def smooth(
    observer: Any,
    times: npt.ArrayLike,
    measurements: npt.ArrayLike,
    inputs: npt.ArrayLike | None = None,
    *,
    guess: Any = None,
    measurement_layout: Layout | None = None,
    input_layout: Layout | None = None,
) -> xr.Dataset:
    """Run a Kalman-type ``observer`` over a log and smooth it back (module docstring).

    Parameters
    ----------
    observer : KalmanFilter
        An extended, unscented or model-free filter (:mod:`lookout.observers.kalman`).
    times, measurements, inputs, guess, measurement_layout, input_layout
        As :func:`lookout.filter`, and checked as it checks them.

    Returns
    -------
    xarray.Dataset
        :func:`lookout.filter`'s Dataset (the filtered estimates ``v_hat``), with the
        smoothed estimates beside them as ``v_smoothed`` and the smoothed state's
        standard deviations as ``state_std_smoothed`` (dims time, state).

    Raises
    ------
    ValueError
        Naming ``observer`` when it is not a Kalman-type filter; as :func:`lookout.filter`
        for the log.
    """
    if not isinstance(observer, KalmanFilter):
        raise ValueError(f"observer must be a Kalman-type filter (ekf, ukf, model-free) to be smoothed; got {type(observer).__name__}")
    times, measurements, inputs, guess, measurement_layout, input_layout = checked_log(
        observer, times, measurements, inputs, guess, measurement_layout, input_layout
    )
    filtered, smoothed, _, covariances = _smooth(observer, guess, jnp.asarray(times), jnp.asarray(measurements), jnp.asarray(inputs))
    ds = filtered_dataset(observer, times, filtered, measurements, inputs, measurement_layout, input_layout)
    for name in filtered:
        value = np.asarray(smoothed[name])
        hat = ds[f"{name}_hat"]
        ds[f"{name}_smoothed"] = (hat.dims, value.reshape(hat.shape), {**hat.attrs, "long_name": f"smoothed {hat.attrs.get('long_name', name)}"})
    std = np.sqrt(np.clip(np.diagonal(np.asarray(covariances), axis1=1, axis2=2), 0.0, None))
    ds["state_std_smoothed"] = (("time", "state"), std, {"long_name": "standard deviation of the smoothed state (raveled)"})
    return ds


__all__ = ["smooth"]
