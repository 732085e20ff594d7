"""Fixed-step integrators over PyTree states."""

from __future__ import annotations

from typing import Callable

import jax
from jax.flatten_util import ravel_pytree


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
    flat, unravel = ravel_pytree(state)

    def f(time, x):
        return ravel_pytree(field(time, unravel(x)))[0]

    half = 0.5 * step
    k1 = f(t, flat)
    k2 = f(t + half, flat + half * k1)
    k3 = f(t + half, flat + half * k2)
    k4 = f(t + step, flat + step * k3)
    return unravel(flat + step * (k1 + 2.0 * (k2 + k3) + k4) / 6.0)


def euler_step(field: Callable, t, state, step):
    """One explicit Euler step of ``state' = field(t, state)`` (same signature as rk4_step)."""
    return _axpy(step, field(t, state), state)
