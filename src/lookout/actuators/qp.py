"""A small dense quadratic program, solved by a primal active-set method in JAX.

    minimize  1/2 x^T P x + q^T x   subject to  G x <= h

with P symmetric positive definite, a few variables (n <= ~20) and a few dozen
inequality rows: the size of a thrust allocation at one sample. The method is the
primal active-set method of Nocedal & Wright, *Numerical Optimization* (2nd ed., 2006),
Algorithm 16.3, with the working set kept as at most n row indices (a working set of
linearly independent rows has at most n of them, and a blocking row the method adds
is independent of the rows already in it), so each iteration solves one (2n x 2n)
KKT system whatever the number of rows; given P's inverse (a P that is the same at
every call, as a thrust allocation's is), the range-space form of that solve instead
(Nocedal & Wright, Section 16.2): a Cholesky factor of at most n x n, unrolled into
plain arithmetic for small n, about twice as fast under ``vmap`` on XLA:CPU.

It is jit-safe and vmappable (a ``lax.while_loop`` with a static iteration cap) and
differentiable: the loop only finds the active set (its inputs are under
``stop_gradient``), and the returned solution is one more KKT solve on that set,
whose derivative is the implicit-function derivative of the optimum with the active
set held (correct away from active-set switches, where the solution is not
differentiable).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import jax.scipy.linalg
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


#: Up to this many variables the range-space solves are unrolled into scalar arithmetic
#: (:func:`_cholesky`); above it, the graph would grow as n^3 and they call LAPACK.
UNROLLED = 12


def _cholesky(S: Array) -> list[list[Array]]:
    """The lower Cholesky factor of a small symmetric positive definite ``S`` as rows of
    scalars (``L[i][j]``, j <= i), unrolled into plain arithmetic: under ``vmap`` each
    entry is one vector operation over the batch, with no LAPACK call."""
    n = S.shape[-1]
    L: list[list[Array]] = [[] for _ in range(n)]
    for j in range(n):
        diagonal = jnp.sqrt(S[j, j] - sum((L[j][k] ** 2 for k in range(j)), jnp.zeros(())))
        L[j].append(diagonal)
        for i in range(j + 1, n):
            L[i].append((S[i, j] - sum((L[i][k] * L[j][k] for k in range(j)), jnp.zeros(()))) / diagonal)
    return L


def _cholesky_solve(L: list[list[Array]], r: Array) -> Array:
    """``x`` with ``L L^T x = r`` by forward and back substitution (``L`` from
    :func:`_cholesky`)."""
    n = len(L)
    y: list[Array] = []
    for i in range(n):
        y.append((r[i] - sum((L[i][k] * y[k] for k in range(i)), jnp.zeros(()))) / L[i][i])
    x: list[Array] = [jnp.zeros(())] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), jnp.zeros(()))) / L[i][i]
    return jnp.stack(x)


def _factor(S: Array) -> Callable[[Array], Array]:
    """The solve ``r -> S^-1 r`` of a symmetric positive definite ``S`` by its Cholesky
    factor: unrolled up to :data:`UNROLLED` rows, LAPACK's above."""
    if S.shape[-1] <= UNROLLED:
        L = _cholesky(S)
        return functools.partial(_cholesky_solve, L)
    factor = jax.scipy.linalg.cho_factor(S, lower=True)
    return functools.partial(jax.scipy.linalg.cho_solve, factor)


def solve_on_working_set_range_space(P: Array, P_inverse: Array, q: Array, G: Array, h: Array, working: Array) -> tuple[Array, Array]:
    """:func:`solve_on_working_set` by the range-space method (Nocedal & Wright, 2006,
    Section 16.2, eq. 16.16) with ``P_inverse`` given: the multipliers from
    (G_W P^-1 G_W^T) mu = -G_W P^-1 q - h_W, a Cholesky solve of at most n x n (free
    slots an identity row), then x = -P^-1 (q + G_W^T mu); then one step of iterative
    refinement on the KKT residual with the same factor (P^-1 can be large where a
    penalty is heavy, and the first solve then loses digits that the step recovers)."""
    on = working >= 0
    # the working set's rows as a one-hot product (no gather: cheaper under vmap)
    selection = (working[:, None] == jnp.arange(G.shape[0])).astype(G.dtype)
    rows, bounds = selection @ G, selection @ h
    spread = P_inverse @ rows.T
    solve_schur = _factor(rows @ spread + jnp.diag(jnp.where(on, 0.0, 1.0)))

    def solve(stationarity, feasibility):
        # [[P, G_W^T], [G_W, 0]] [x, mu] = [stationarity, feasibility]
        free = P_inverse @ stationarity
        multipliers = jnp.where(on, solve_schur(rows @ free - feasibility), 0.0)
        return free - spread @ multipliers, multipliers

    x, multipliers = solve(-q, bounds)
    dx, dmultipliers = solve(-q - P @ x - rows.T @ multipliers, bounds - rows @ x)
    return x + dx, multipliers + dmultipliers


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
    P_inverse: ArrayLike | None = None,
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
    P_inverse : Array, shape (n, n), optional
        P's inverse, when the caller has it (a P that is the same at every call): each
        working-set solve is then the range-space one
        (:func:`solve_on_working_set_range_space`: a Cholesky factor of at most n x n in
        plain array operations) instead of an LU factorization of the (2n x 2n) KKT
        matrix. The solution is then differentiable in q, G and h, with P held.

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
    if P_inverse is None:
        solve = functools.partial(solve_on_working_set, P_)
    else:
        # the inverse of the scaled P, held (no derivative in P)
        inverse = jax.lax.stop_gradient(jnp.asarray(P_inverse, dtype=float) * size)
        solve = functools.partial(solve_on_working_set_range_space, P_, inverse)

    def body(carry):
        x, working, iteration, done = carry
        on = working >= 0
        # the step p to the minimizer on the working set (G_W p = 0): the same sub-problem
        # with the gradient at x for q and zero right-hand sides
        p, multipliers = solve(P_ @ x + q_, G_, jnp.zeros(m), working)
        # n independent rows leave no step: what a solve returns then is rounding
        still = jnp.all(on) | (jnp.max(jnp.abs(p)) <= tolerance * (1.0 + jnp.max(jnp.abs(x))))
        p = jnp.where(jnp.all(on), 0.0, p)

        # at a zero step: optimal unless a multiplier is negative; then drop the most negative
        weakest = jnp.argmin(jnp.where(on, multipliers, jnp.inf))
        # (a singular working set gives non-finite multipliers: not optimal)
        optimal = ~jnp.any(on & ~(multipliers >= -tolerance))
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
        guess, multipliers = solve(q_, G_, h_, warm)
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
    if P_inverse is None:
        exact, _ = solve_on_working_set(P, q, G, h, working)
    else:
        exact, _ = solve(q, G, h, working)
    x = jnp.where(converged & ~skip, exact, x)
    return x, working, iterations, converged & ~skip
