"""A small dense quadratic program, solved by a primal active-set method in JAX.

    minimize  1/2 x^T P x + q^T x   subject to  G x <= h

with P symmetric positive definite, a few variables (n <= ~20) and a few dozen
inequality rows: the size of a thrust allocation at one sample. The method is the
primal active-set method of Nocedal & Wright, *Numerical Optimization* (2nd ed., 2006),
Algorithm 16.3, with the working set kept as at most n row indices (a working set of
linearly independent rows has at most n of them, and a blocking row the method adds
is independent of the rows already in it), so each iteration solves one (2n x 2n)
KKT system whatever the number of rows.

It is jit-safe and vmappable (a ``lax.while_loop`` with a static iteration cap) and
differentiable: the loop only finds the active set (its inputs are under
``stop_gradient``), and the returned solution is one more KKT solve on that set,
whose derivative is the implicit-function derivative of the optimum with the active
set held (correct away from active-set switches, where the solution is not
differentiable).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

#: Working-set slot that holds no row.
EMPTY = -1


def _system(P, G, working):
    """The KKT matrix [[P, G_W^T], [G_W, I_free]] of the working set (free slots get an
    identity row, so their multipliers are 0)."""
    on = working >= 0
    rows = jnp.where(on[:, None], G[jnp.maximum(working, 0)], 0.0)
    top = jnp.concatenate([P, rows.T], axis=1)
    bottom = jnp.concatenate([rows, jnp.diag(jnp.where(on, 0.0, 1.0))], axis=1)
    return jnp.concatenate([top, bottom], axis=0), on


def solve_on_working_set(P: Array, q: Array, G: Array, h: Array, working: Array) -> tuple[Array, Array]:
    """The minimizer of 1/2 x^T P x + q^T x with the working set's rows held as
    equalities (G_W x = h_W), and their multipliers (0 in free slots)."""
    n = P.shape[0]
    K, on = _system(P, G, working)
    rhs = jnp.concatenate([-q, jnp.where(on, h[jnp.maximum(working, 0)], 0.0)])
    solution = jnp.linalg.solve(K, rhs)
    return solution[:n], jnp.where(on, solution[n:], 0.0)


def active_set(
    P: ArrayLike,
    q: ArrayLike,
    G: ArrayLike,
    h: ArrayLike,
    x0: ArrayLike,
    *,
    max_iterations: int,
    tolerance: float = 1e-10,
    needed: ArrayLike = True,
    warm: ArrayLike | None = None,
) -> tuple[Array, Array, Array, Array]:
    """Solve the QP from the feasible point ``x0`` (Nocedal & Wright, Algorithm 16.3).

    Parameters
    ----------
    P : Array, shape (n, n)
        Symmetric positive definite.
    q : Array, shape (n,)
    G : Array, shape (m, n)
    h : Array, shape (m,)
        Rows with ``h`` at 1e30 or more never bind.
    x0 : Array, shape (n,)
        A point with ``G x0 <= h`` (the previous sample's solution).
    max_iterations : int
        Cap on the iterations (static); each adds or drops one row.
    tolerance : float
        A step shorter than this (in the units of x) counts as zero.
    needed : bool or Array of bool
        False skips the iterations (the caller has the answer another way; under
        ``vmap`` a batch iterates only while one of its members needs it). A
        non-finite ``q`` or ``x0`` also skips them.
    warm : Array of int, shape (n,), optional
        A guess of the active set (the previous sample's ``working``): when the
        minimizer on it is feasible and its multipliers are non-negative, it is the
        solution (the KKT conditions hold) and no iteration is taken; else the
        iterations start from ``x0`` with an empty working set.

    Returns
    -------
    x : Array, shape (n,)
        The minimizer (differentiable in P, q, G and h with the active set held).
    working : Array of int, shape (n,)
        The row indices of the final working set, ``EMPTY`` in free slots.
    iterations : Array of int
        Iterations taken.
    converged : Array of bool
        Whether the multipliers were all non-negative at a zero step before the cap.
        When False, ``x`` is still feasible (the method keeps feasibility) but may
        not be optimal.
    """
    P, q, G, h, x0 = (jnp.asarray(a, dtype=float) for a in (P, q, G, h, x0))
    n, m = P.shape[0], G.shape[0]
    # the same minimizer with P's largest entry 1: the KKT systems stay well scaled when
    # P carries a large weight (multipliers of order 1, not of the weight)
    size = jnp.max(jnp.abs(P))
    P, q = P / size, q / size
    P_, q_, G_, h_, x0_ = (jax.lax.stop_gradient(a) for a in (P, q, G, h, x0))

    def body(carry):
        x, working, iteration, done = carry
        on = working >= 0
        # the step p to the minimizer on the working set (G_W p = 0): the same sub-problem
        # with the gradient at x for q and zero right-hand sides
        p, multipliers = solve_on_working_set(P_, P_ @ x + q_, G_, jnp.zeros(m), working)
        # n independent rows leave no step: what a solve returns then is rounding
        still = jnp.all(on) | (jnp.max(jnp.abs(p)) <= tolerance * (1.0 + jnp.max(jnp.abs(x))))
        p = jnp.where(jnp.all(on), 0.0, p)

        # at a zero step: optimal unless a multiplier is negative; then drop the most negative
        weakest = jnp.argmin(jnp.where(on, multipliers, jnp.inf))
        optimal = ~jnp.any(on & (multipliers < -tolerance))
        dropped = working.at[weakest].set(EMPTY)

        # a nonzero step: go as far as the first row not in the working set allows
        in_working = jnp.zeros(m, dtype=bool).at[jnp.where(on, working, m)].set(True, mode="drop")
        Gp = G_ @ p
        room = jnp.maximum(h_ - G_ @ x, 0.0)
        blocking = (~in_working) & (Gp > tolerance)
        ratios = jnp.where(blocking, room / jnp.where(blocking, Gp, 1.0), jnp.inf)
        first = jnp.argmin(ratios)
        length = jnp.minimum(1.0, ratios[first])
        blocked = ratios[first] < 1.0
        free_slot = jnp.argmin(on)  # the first free slot (one exists while p != 0)
        added = jnp.where(blocked, working.at[free_slot].set(first), working)

        x_next = jnp.where(still, x, x + length * p)
        working_next = jnp.where(still, jnp.where(optimal, working, dropped), added)
        return x_next, working_next, iteration + 1, still & optimal

    def going(carry):
        _, _, iteration, done = carry
        return (~done) & (iteration < max_iterations)

    skip = ~jnp.asarray(needed) | ~jnp.all(jnp.isfinite(q_)) | ~jnp.all(jnp.isfinite(x0_))
    start_working, start_x, guessed = jnp.full(n, EMPTY), x0_, jnp.asarray(False)
    if warm is not None:
        warm = jnp.asarray(warm)
        guess, multipliers = solve_on_working_set(P_, q_, G_, h_, warm)
        guessed = (
            jnp.all(jnp.isfinite(guess))
            & jnp.all(jnp.isfinite(multipliers))
            & jnp.all(G_ @ guess <= h_ + tolerance)
            & jnp.all(multipliers >= -tolerance)
        )
        start_working = jnp.where(guessed, warm, start_working)
        start_x = jnp.where(guessed, guess, start_x)
    start = (start_x, start_working, jnp.asarray(0), skip | guessed)
    x, working, iterations, converged = jax.lax.while_loop(going, body, start)
    converged = converged | (guessed & ~skip)
    # the differentiable solution: one solve on the active set found
    exact, _ = solve_on_working_set(P, q, G, h, working)
    x = jnp.where(converged & ~skip, exact, x)
    return x, working, iterations, converged & ~skip
