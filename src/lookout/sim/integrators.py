"""Fixed-step integrators over PyTree states."""

from __future__ import annotations

from typing import Callable

import jax


def _axpy(a, x, y):
    return jax.tree.map(lambda xi, yi: yi + a * xi, x, y)


def rk4_step(field: Callable, t, state, step):
    """One classical fourth-order Runge–Kutta step of ``state' = field(t, state)``.

    Parameters
    ----------
    field : callable
        ``field(t, state) -> derivative`` with the same PyTree structure as ``state``.
    t : float
        Time at the start of the step (s).
    state : PyTree
        State at ``t``.
    step : float
        Step length (s).

    Returns
    -------
    PyTree
        State at ``t + step``.
    """
    half = 0.5 * step
    k1 = field(t, state)
    k2 = field(t + half, _axpy(half, k1, state))
    k3 = field(t + half, _axpy(half, k2, state))
    k4 = field(t + step, _axpy(step, k3, state))
    increment = jax.tree.map(lambda a, b, c, d: (a + 2.0 * (b + c) + d) / 6.0, k1, k2, k3, k4)
    return _axpy(step, increment, state)


def euler_step(field: Callable, t, state, step):
    """One explicit Euler step of ``state' = field(t, state)`` (same signature as rk4_step)."""
    return _axpy(step, field(t, state), state)


#: The integrators a scenario (and a Kalman filter's propagation) may name.
INTEGRATORS = {"rk4": rk4_step, "euler": euler_step}
