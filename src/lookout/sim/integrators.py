"""Fixed-step integrators over PyTree states."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax.typing import ArrayLike


def _axpy(a, x, y):
    return jax.tree.map(lambda xi, yi: yi + a * xi, x, y)


def rk4_step(field: Callable, t: ArrayLike, state: Any, step: ArrayLike) -> Any:
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


def euler_step(field: Callable, t: ArrayLike, state: Any, step: ArrayLike) -> Any:
    """One explicit Euler step of ``state' = field(t, state)`` (same signature as rk4_step)."""
    return _axpy(step, field(t, state), state)


#: The integrators a scenario (and a Kalman filter's propagation) may name.
INTEGRATORS = {"rk4": rk4_step, "euler": euler_step}


#: Steps of one sample that :func:`integrate_sample` writes out in the trace; more run
#: as a ``lax.scan``, so that the program (and its gradient) stops growing with the
#: step count, as the engine does with its plant substeps.
UNROLL_LIMIT = 4


def integrate_sample(
    field: Callable,
    t: ArrayLike,
    state: Any,
    dt: ArrayLike,
    steps: int,
    *,
    method: str = "rk4",
    normalize: Callable | None = None,
    normalize_each_step: bool = False,
    unroll_limit: int | None = None,
) -> Any:
    """Integrate ``state' = field(t, state)`` over one sample [t, t + dt] in equal steps.

    The sampled ``predict`` of every continuous-time observer: ``field`` is its vector
    field with what it holds over the sample (the measurement, or the innovation, and
    the input) closed over; this takes ``steps`` steps of ``dt / steps`` of the
    classical fourth-order Runge–Kutta method (:func:`rk4_step`) or explicit Euler
    (:func:`euler_step`), step i starting at ``t + i dt / steps``, and wraps angles
    with ``normalize``.

    Parameters
    ----------
    field : callable
        ``field(time, state) -> derivative``, a PyTree shaped like ``state``.
    t : float
        Time at the start of the sample (s).
    state : PyTree
        State at ``t``.
    dt : float
        Sample period (s).
    steps : int
        Number of steps (static, positive).
    method : {"rk4", "euler"}
        The integrator of each step (a key of :data:`INTEGRATORS`).
    normalize : callable, optional
        ``normalize(state) -> state``: angles wrapped (parameters projected); applied
        to the result, or after every step with ``normalize_each_step``.
    normalize_each_step : bool
        Apply ``normalize`` after every step instead of once at the end.
    unroll_limit : int, optional
        Up to this many steps are written out in the trace; more run as a ``lax.scan``
        (the same arithmetic per step; the program no longer grows with ``steps``).
        Default :data:`UNROLL_LIMIT`, read at the call; 1 loops from two steps on.

    Returns
    -------
    PyTree
        State at ``t + dt``.
    """
    if not (isinstance(steps, int) and not isinstance(steps, bool) and steps >= 1):
        raise ValueError(f"steps must be a positive integer; got {steps!r}")
    if method not in INTEGRATORS:
        raise ValueError(f"method must be one of {sorted(INTEGRATORS)}; got {method!r}")
    integrate = INTEGRATORS[method]
    h = dt / steps
    after_step = normalize if (normalize is not None and normalize_each_step) else (lambda x: x)

    def advance(x, i):
        return after_step(integrate(field, t + i * h, x, h))

    if steps <= (UNROLL_LIMIT if unroll_limit is None else unroll_limit):
        for i in range(steps):
            state = advance(state, i)
    else:
        # the carry keeps one dtype per leaf: a weakly typed or Python-number leaf of
        # ``state`` takes the (strong) dtype a step gives it, the same value
        stepped = jax.eval_shape(advance, state, 0)
        state = jax.tree.map(lambda x, s: jnp.asarray(x, s.dtype), state, stepped)
        state, _ = jax.lax.scan(lambda x, i: (advance(x, i), None), state, jnp.arange(steps))
    return normalize(state) if (normalize is not None and not normalize_each_step) else state
