"""A vessel's M and D identified from a log with thrust.

The model is Fossen & Strand (1999), eqs. (1) and (3) without mooring::

    eta' = J(psi) nu,      M nu' + D nu = tau + J(psi)^T b

with M symmetric positive definite and D's symmetric part positive semi-definite by
construction (M = S_M L L^T S_M, D = S_D (P P^T + K) S_D, L and P lower triangular with
positive diagonals, K skew-symmetric, S scalings from the first estimate), and the
environment's force b (Earth-fixed) a slowly varying input: one constant per window.

Two stages, on a log resampled at the observer's step (the measured position and
heading, NaN where no new fix came; the applied thrust; the smoothed state of an
observer without a hull model, :mod:`lookout.observers.model_free` and
:mod:`lookout.observers.smoothing`):

1. **Equation error** (a first estimate): tau = M nu' + D nu - J^T b by least squares on
   the smoothed nu and its central difference, b one constant (Ljung (1999), System
   Identification: Theory for the User, Section 7.3, the linear regression form).
2. **Output error** (the fit): each window simulated from its start under the logged
   thrust (RK4 at the log's step), its predicted eta compared with the measured
   position and heading, weighted by their noise; M, D, each window's b and each
   window's start (from the smoothed state: multiple shooting, Bock & Plitt 1984)
   moved by Adam (Kingma & Ba 2015) on the gradient through the simulation, as the
   tuner moves gains (:mod:`lookout.tuning.tune`).

The last ``held_out`` share of the windows is not fitted: each is predicted from its
smoothed start with the last fitted window's b, and its error is the validation.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import optax

from lookout._math import ssa

#: Seconds per window: long enough for the vessel's own dynamics to show (a DP vessel's
#: time constants M/D are 10-200 s; on the example log 60 s windows gave M within 9 %
#: and D within 74 %, 300 s windows 1 % and 6 %, from the true states), short enough for
#: the environment to stay nearly constant.
WINDOW = 300.0
#: Share of the windows held out for validation (the log's last ones).
HELD_OUT = 0.2
#: Adam's steps and rate on the normalized parameters.
ITERATIONS, LEARNING_RATE = 600, 0.02


@dataclass
class Identification:
    """What :func:`identify` found.

    Attributes
    ----------
    mass_matrix, damping_matrix : numpy.ndarray, shape (3, 3)
        The identified M and D.
    first_mass_matrix, first_damping_matrix : numpy.ndarray, shape (3, 3)
        The equation-error estimate the fit started from.
    bias : numpy.ndarray, shape (windows, 3)
        b per fitted window (N, N, N m; Earth-fixed).
    fit_rms, validation_rms : numpy.ndarray, shape (3,)
        RMS of (measured - predicted) position north, east (m) and heading (rad) over
        the fitted and the held-out windows.
    times, measured, predicted : numpy.ndarray
        The log's times, its measurement and the windows' predictions (NaN outside a
        window), for the figure.
    held_out_from : float
        The time the held-out windows start.
    """

    mass_matrix: np.ndarray
    damping_matrix: np.ndarray
    first_mass_matrix: np.ndarray
    first_damping_matrix: np.ndarray
    bias: np.ndarray
    fit_rms: np.ndarray
    validation_rms: np.ndarray
    times: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    held_out_from: float


def _equation_error(step: float, states: np.ndarray, thrust: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M, D) by least squares on tau = M nu' + D nu - J(psi)^T b, b constant; M projected
    onto the symmetric positive definite matrices, D's symmetric part onto the positive
    semi-definite ones."""
    nu = states[:, 3:]
    rate = np.gradient(nu, step, axis=0)
    cos, sin = np.cos(states[:, 2]), np.sin(states[:, 2])
    # column i of J(psi): (J^T b)_i = sum_j J_ji b_j
    columns = [
        np.stack([cos, sin, np.zeros_like(cos)], axis=1),
        np.stack([-sin, cos, np.zeros_like(cos)], axis=1),
        np.tile([0.0, 0.0, 1.0], (len(cos), 1)),
    ]
    blocks, targets = [], []
    for i in range(3):
        block = np.zeros((len(nu), 21))
        block[:, 3 * i : 3 * i + 3] = rate
        block[:, 9 + 3 * i : 9 + 3 * i + 3] = nu
        block[:, 18:21] = -columns[i]
        blocks.append(block)
        targets.append(thrust[:, i])
    a, y = np.concatenate(blocks), np.concatenate(targets)
    scale = np.maximum(np.abs(a).max(axis=0), 1e-300)
    solution = np.linalg.lstsq(a / scale, y, rcond=None)[0] / scale
    mass, damping = solution[:9].reshape(3, 3), solution[9:18].reshape(3, 3)
    mass = 0.5 * (mass + mass.T)
    values, vectors = np.linalg.eigh(mass)
    mass = vectors @ np.diag(np.maximum(values, 1e-3 * abs(values).max())) @ vectors.T
    symmetric = 0.5 * (damping + damping.T)
    values, vectors = np.linalg.eigh(symmetric)
    floor = 1e-3 * max(abs(values).max(), 1e-300)
    damping = vectors @ np.diag(np.maximum(values, floor)) @ vectors.T + 0.5 * (damping - damping.T)
    return mass, damping


def _lower(entries: jax.Array) -> jax.Array:
    """A lower-triangular 3x3 matrix from 6 entries, its diagonal exp of theirs (positive)."""
    matrix = jnp.zeros((3, 3)).at[jnp.tril_indices(3)].set(entries)
    return matrix.at[jnp.diag_indices(3)].set(jnp.exp(jnp.diagonal(matrix)))


def _log_lower(matrix: np.ndarray) -> np.ndarray:
    """The 6 entries of :func:`_lower` for the Cholesky factor of ``matrix``."""
    factor = np.linalg.cholesky(matrix)
    factor[np.diag_indices(3)] = np.log(np.diagonal(factor))
    return factor[np.tril_indices(3)]


def _matrices(theta, mass_scale, damping_scale):
    mass_factor = _lower(theta["mass"])
    damping_factor = _lower(theta["damping"])
    skew = jnp.array(
        [[0.0, theta["skew"][0], theta["skew"][1]], [-theta["skew"][0], 0.0, theta["skew"][2]], [-theta["skew"][1], -theta["skew"][2], 0.0]]
    )
    mass = mass_scale[:, None] * (mass_factor @ mass_factor.T) * mass_scale[None, :]
    damping = damping_scale[:, None] * (damping_factor @ damping_factor.T + skew) * damping_scale[None, :]
    return mass, damping


def _simulate(mass, damping, bias, start, thrust, step):
    """eta over one window from ``start`` (eta, nu) under ``thrust`` (RK4, thrust held)."""
    inverse = jnp.linalg.inv(mass)

    def field(state, tau):
        eta, nu = state[:3], state[3:]
        turn = jnp.array([[jnp.cos(eta[2]), -jnp.sin(eta[2]), 0.0], [jnp.sin(eta[2]), jnp.cos(eta[2]), 0.0], [0.0, 0.0, 1.0]])
        return jnp.concatenate([turn @ nu, inverse @ (tau + turn.T @ bias - damping @ nu)])

    def row(state, tau):
        k1 = field(state, tau)
        k2 = field(state + 0.5 * step * k1, tau)
        k3 = field(state + 0.5 * step * k2, tau)
        k4 = field(state + step * k3, tau)
        return state + step / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4), state[:3]

    _, eta = jax.lax.scan(row, start, thrust)
    return eta


def _residual(eta, measured, sigma):
    difference = measured - eta
    difference = difference.at[:, 2].set(ssa(difference[:, 2]))
    return jnp.where(jnp.isfinite(measured), difference / sigma, 0.0)


def identify(
    step: float,
    measured: np.ndarray,
    thrust: np.ndarray,
    states: np.ndarray,
    sigma: np.ndarray,
    *,
    window: float = WINDOW,
    held_out: float = HELD_OUT,
    iterations: int = ITERATIONS,
) -> Identification:
    """M and D of a vessel from a log resampled at ``step`` (module docstring).

    Parameters
    ----------
    step : float
        Seconds between rows.
    measured : array_like, shape (n, 3)
        Position north, east (m) and heading (rad) measured at each row; NaN where no
        new fix or heading came.
    thrust : array_like, shape (n, 3)
        The thrust applied from each row to the next (N, N, N m; body-fixed).
    states : array_like, shape (n, 6)
        A smoothed estimate of eta and nu at each row (the windows start from it).
    sigma : array_like, shape (3,)
        The measurement noise (m, m, rad) that weights the residuals.
    window : float
        Seconds per window (the log is cut into the whole number of windows nearest its
        span over ``window``, of equal length); held_out: the share of windows held out
        (0 < . < 1).

    Raises
    ------
    ValueError
        Naming the argument: shapes that differ, a window longer than half the log,
        held_out outside (0, 1), non-finite thrust or states.
    """
    measured, thrust, states = (np.asarray(a, dtype=float) for a in (measured, thrust, states))
    sigma = np.asarray(sigma, dtype=float)
    n = measured.shape[0]
    if measured.shape != (n, 3) or thrust.shape != (n, 3) or states.shape != (n, 6):
        raise ValueError(f"measured, thrust and states must be (n, 3), (n, 3), (n, 6); got {measured.shape}, {thrust.shape}, {states.shape}")
    if not (np.all(np.isfinite(thrust)) and np.all(np.isfinite(states))):
        raise ValueError("thrust and states must be finite at every row")
    if not 0.0 < held_out < 1.0:
        raise ValueError(f"held_out must be a share between 0 and 1; got {held_out!r}")
    # windows of equal length covering the log: as many as the window fits, each a
    # little longer or shorter than asked (the last rows, fewer than the windows, dropped)
    count = int(round(n * step / window))
    if count < 2 or window <= 0:
        raise ValueError(f"window must be at most half the log ({n * step:g} s); got {window:g} s")
    per = n // count
    validation = max(int(round(held_out * count)), 1)
    fitted = count - validation
    if fitted < 1:
        raise ValueError(f"held_out leaves no window to fit ({count} windows of {window:g} s)")
    first_mass, first_damping = _equation_error(step, states[: fitted * per], thrust[: fitted * per])
    mass_scale = np.sqrt(np.diagonal(first_mass))
    damping_scale = np.sqrt(np.maximum(np.diagonal(0.5 * (first_damping + first_damping.T)), 1e-6 * np.diagonal(first_mass) / 100.0))
    normalized_mass = first_mass / np.outer(mass_scale, mass_scale)
    symmetric = 0.5 * (first_damping + first_damping.T) / np.outer(damping_scale, damping_scale)
    skew = 0.5 * (first_damping - first_damping.T) / np.outer(damping_scale, damping_scale)
    bias_scale = np.maximum(np.std(thrust, axis=0), 1e-9)
    theta = {
        "mass": jnp.asarray(_log_lower(normalized_mass)),
        "damping": jnp.asarray(_log_lower(symmetric + 1e-9 * np.eye(3))),
        "skew": jnp.asarray([skew[0, 1], skew[0, 2], skew[1, 2]]),
        "bias": jnp.zeros((fitted, 3)),
        "start": jnp.zeros((fitted, 6)),
    }
    shaped = lambda a: jnp.asarray(a[: count * per].reshape(count, per, -1))  # noqa: E731
    windows_measured, windows_thrust, windows_states = shaped(measured), shaped(thrust), shaped(states)
    starts = windows_states[:, 0]
    scales = (jnp.asarray(mass_scale), jnp.asarray(damping_scale))
    sigma_j = jnp.asarray(sigma)

    # each fitted window's start is moved too (multiple shooting): the smoothed state's
    # error at a window's start is not the model's; normalized by the smoother's typical error
    start_scale = jnp.asarray([sigma[0], sigma[1], sigma[2], 0.02, 0.02, 1e-3])

    def predictions(theta, which, biases, moves):
        mass, damping = _matrices(theta, *scales)
        return jax.vmap(lambda b, s, u: _simulate(mass, damping, b * bias_scale, s, u, step))(
            biases, starts[which] + moves * start_scale, windows_thrust[which]
        )

    def loss(theta):
        eta = predictions(theta, slice(0, fitted), theta["bias"], theta["start"])
        residual = jax.vmap(_residual, in_axes=(0, 0, None))(eta, windows_measured[:fitted], sigma_j)
        return jnp.sum(residual**2) / jnp.maximum(jnp.sum(jnp.isfinite(windows_measured[:fitted])), 1)

    optimizer = optax.adam(LEARNING_RATE)
    state = optimizer.init(theta)

    @jax.jit
    def update(theta, state):
        value, gradient = jax.value_and_grad(loss)(theta)
        changes, state = optimizer.update(gradient, state, theta)
        return optax.apply_updates(theta, changes), state, value

    for _ in range(int(iterations)):
        theta, state, _ = update(theta, state)
    mass, damping = (np.asarray(m) for m in _matrices(theta, *scales))
    last_bias = jnp.repeat(theta["bias"][-1:], validation, axis=0)
    fitted_eta = np.asarray(predictions(theta, slice(0, fitted), theta["bias"], theta["start"]))
    held_eta = np.asarray(predictions(theta, slice(fitted, count), last_bias, jnp.zeros((validation, 6))))
    predicted = np.full((n, 3), np.nan)
    predicted[: count * per] = np.concatenate([fitted_eta, held_eta]).reshape(count * per, 3)

    def rms(rows: slice) -> np.ndarray:
        difference = measured[rows] - predicted[rows]
        difference[:, 2] = np.angle(np.exp(1j * difference[:, 2]))
        return np.sqrt(np.nanmean(difference**2, axis=0))

    return Identification(
        mass,
        damping,
        first_mass,
        first_damping,
        np.asarray(theta["bias"]) * bias_scale,
        rms(slice(0, fitted * per)),
        rms(slice(fitted * per, count * per)),
        step * np.arange(n),
        measured,
        predicted,
        fitted * per * step,
    )


__all__ = ["HELD_OUT", "ITERATIONS", "WINDOW", "Identification", "identify"]
