"""A small dense quadratic program with bounds only, solved exactly in plain arithmetic.

    minimize  1/2 x^T H x + f^T x   subject to  lower <= x <= upper

with H symmetric positive definite and a handful of variables (n <= 12): a thrust
allocation whose azimuths hold their steered angles, once each azimuth's force is one
variable along its angle (:class:`lookout.actuators.allocation.Allocator`).

The working set is a state per variable: free, held at its lower bound or held at its
upper. A working set's sub-problem is the free variables' block of H solved with the
held ones at their bounds (a Cholesky factor of the masked H). Two methods share it:

1. the primal-dual active-set method (Hintermueller, Ito & Kunisch, SIAM J. Optim.
   13(3), 2003, Algorithm 1; for bounds on both sides, Kunisch & Rendl, SIAM J. Optim.
   14(1), 2003): from the warm working set, hold every free variable the sub-problem
   put beyond a bound and free every held one whose multiplier has the wrong sign, until
   nothing changes. It changes any number of bounds in a step and usually converges in
   one to three, but it may cycle, so after :data:`PRIMAL_DUAL_STEPS` steps
2. the primal active-set method of Nocedal & Wright, *Numerical Optimization* (2nd ed.,
   2006), Algorithm 16.3, specialised to bounds, takes over from the last point clipped
   into the bounds: a step adds the first bound it meets, a zero step drops the bound
   with the most negative multiplier. It terminates (a strictly convex objective
   decreases at each nonzero step).

Why a second solver beside :func:`lookout.actuators.qp.active_set`: every operation here
is an elementwise operation on scalars (the Cholesky factor, the products, the choice
of the bounds to add or drop are unrolled over the variables: no gather, no dot, no
LAPACK call), so under ``vmap`` a step of a batch of runs is about 20 fused loops over
the batch. On XLA:CPU a batch's while-loop iteration costs its kernels' launches, not
their arithmetic, and under ``vmap`` the loop runs until the batch's slowest run is done
(docs/benchmarks.md).

The warm start is the previous sample's working set; when it has not changed (the usual
case from one sample to the next) the first step confirms it.

The solution is exact (the KKT conditions hold to ``tolerance`` at return, ``converged``
says so), jit-safe and vmappable, and differentiable the way
:func:`lookout.actuators.qp.active_set`'s is: the steps only find the working set, and
the returned solution is one more sub-problem solve on it with the inputs' derivatives.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

#: A variable's state in the working set: free, or held at one of its bounds.
FREE, AT_LOWER, AT_UPPER = -1, 0, 1
#: Steps of the primal-dual method before the primal method takes over (which always
#: terminates; the primal-dual method changes any number of bounds in a step and
#: usually converges in two or three, but may cycle on some H).
PRIMAL_DUAL_STEPS = 6
#: The most variables :func:`box_qp` takes: its arithmetic is unrolled over them, and
#: the graph grows as n^3 (a Cholesky factor per step), so compiling it would take
#: longer than solving a larger QP another way.
MOST_VARIABLES = 12

Scalars = list[Array]


def _cholesky_solve(M: list[Scalars], r: Scalars) -> Scalars:
    """``x`` with ``M x = r`` for a small symmetric positive definite ``M`` given as rows
    of scalars, by its Cholesky factor, unrolled into plain arithmetic."""
    n = len(r)
    L: list[Scalars] = [[] for _ in range(n)]
    for j in range(n):
        diagonal = jnp.sqrt(M[j][j] - sum((L[j][k] * L[j][k] for k in range(j)), jnp.zeros(())))
        L[j].append(diagonal)
        for i in range(j + 1, n):
            L[i].append((M[i][j] - sum((L[i][k] * L[j][k] for k in range(j)), jnp.zeros(()))) / diagonal)
    y: Scalars = []
    for i in range(n):
        y.append((r[i] - sum((L[i][k] * y[k] for k in range(i)), jnp.zeros(()))) / L[i][i])
    x: Scalars = [jnp.zeros(())] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), jnp.zeros(()))) / L[i][i]
    return x


def _subproblem(H: list[Scalars], f: Scalars, lower: Scalars, upper: Scalars, state: list[Array]) -> Scalars:
    """The minimizer with the working set's variables held at their bounds: the free
    block H_FF x_F = -(f_F + H_FA x_A), as one system whose held rows are identity rows."""
    n = len(f)
    free = [s == FREE for s in state]
    held = [jnp.where(free[i], 0.0, jnp.where(state[i] == AT_UPPER, upper[i], lower[i])) for i in range(n)]
    rhs = [jnp.where(free[i], -(f[i] + sum((H[i][j] * held[j] for j in range(n)), jnp.zeros(()))), held[i]) for i in range(n)]
    M = [[jnp.where(free[i], H[i][i], 1.0) if i == j else jnp.where(free[i] & free[j], H[i][j], 0.0) for j in range(n)] for i in range(n)]
    return _cholesky_solve(M, rhs)


def _primal_step(H, f, lower, upper, fixed, tolerance, x: Scalars, state: list[Array], target: Scalars) -> tuple[Scalars, list[Array], Array]:
    """One iteration of Algorithm 16.3 from the feasible ``x`` with its working set
    ``state``, whose sub-problem's minimizer is ``target``: ``(x, state, optimal)``."""
    n = len(f)
    p = [target[i] - x[i] for i in range(n)]
    size = sum((jnp.abs(v) for v in x), jnp.zeros(()))
    moving = jnp.zeros((), dtype=bool)
    for i in range(n):
        moving = moving | (jnp.abs(p[i]) > tolerance * (1.0 + size))
    # a zero step: optimal unless a held bound's multiplier is negative (the gradient
    # pushes the variable off it); then the most negative one is dropped
    gradient = [f[i] + sum((H[i][j] * x[j] for j in range(n)), jnp.zeros(())) for i in range(n)]
    worst, drop = jnp.asarray(tolerance), jnp.asarray(-1)
    for i in range(n):
        wrong = jnp.where(state[i] == AT_UPPER, gradient[i], jnp.where(state[i] == AT_LOWER, -gradient[i], -jnp.inf))
        wrong = jnp.where(fixed[i], -jnp.inf, wrong)
        # (a non-finite multiplier is not optimal)
        worse = (wrong > worst) | ((state[i] != FREE) & ~fixed[i] & ~jnp.isfinite(wrong))
        worst, drop = jnp.where(worse, jnp.where(jnp.isfinite(wrong), wrong, jnp.inf), worst), jnp.where(worse, i, drop)
    optimal = drop < 0
    # a nonzero step: as far as the first bound it meets allows
    first, length = jnp.asarray(-1), jnp.asarray(1.0)
    for i in range(n):
        up = (state[i] == FREE) & (p[i] > 0.0)
        down = (state[i] == FREE) & (p[i] < 0.0)
        room = jnp.where(up, upper[i] - x[i], jnp.where(down, lower[i] - x[i], 0.0))
        ratio = jnp.where(up | down, jnp.maximum(room / jnp.where(up | down, p[i], 1.0), 0.0), jnp.inf)
        shorter = ratio < length
        first, length = jnp.where(shorter, i, first), jnp.where(shorter, ratio, length)
    new_x, new_state = [], []
    for i in range(n):
        met = moving & (first == i)  # a step that met its bound lands on it exactly
        new_x.append(jnp.where(met, jnp.where(p[i] > 0.0, upper[i], lower[i]), jnp.where(moving, x[i] + length * p[i], x[i])))
        if_moving = jnp.where(first == i, jnp.where(p[i] > 0.0, AT_UPPER, AT_LOWER), state[i])
        new_state.append(jnp.where(moving, if_moving, jnp.where(drop == i, FREE, state[i])))
    return new_x, new_state, ~moving & optimal


def _primal_dual_step(H, f, lower, upper, fixed, tolerance, state: list[Array], target: Scalars) -> tuple[list[Array], Array]:
    """One iteration of the primal-dual active-set method (Hintermueller, Ito & Kunisch,
    "The primal-dual active set strategy as a semismooth Newton method", SIAM J. Optim.
    13(3), 2003, Algorithm 1, for bounds on both sides as in Kunisch & Rendl, "An
    infeasible active set method for quadratic problems with simple bounds", SIAM J.
    Optim. 14(1), 2003) from the working set ``state`` whose sub-problem's minimizer is
    ``target``: a free variable beyond a bound is held at it, a held one whose
    multiplier has the wrong sign is freed. ``(state, optimal)``: optimal when nothing
    changes (``target`` then meets its bounds and the KKT conditions)."""
    n = len(f)
    gradient = [f[i] + sum((H[i][j] * target[j] for j in range(n)), jnp.zeros(())) for i in range(n)]
    new_state = []
    same = jnp.ones((), dtype=bool)
    for i in range(n):
        free = jnp.where(target[i] > upper[i], AT_UPPER, jnp.where(target[i] < lower[i], AT_LOWER, FREE))
        # held at the upper bound while the gradient is <= 0 (its multiplier >= 0), at the lower while >= 0
        held = jnp.where(
            state[i] == AT_UPPER, jnp.where(gradient[i] <= tolerance, AT_UPPER, FREE), jnp.where(gradient[i] >= -tolerance, AT_LOWER, FREE)
        )
        changed = jnp.where(fixed[i], state[i], jnp.where(state[i] == FREE, free, held))
        same = same & (changed == state[i])
        new_state.append(changed)
    return new_state, same


def box_qp(
    H: ArrayLike,
    f: ArrayLike,
    lower: ArrayLike,
    upper: ArrayLike,
    warm: ArrayLike | None = None,
    *,
    max_iterations: int | None = None,
    primal_dual_steps: int = PRIMAL_DUAL_STEPS,
    tolerance: float = 1e-10,
) -> tuple[Array, Array, Array, Array]:
    """Solve the bound-constrained QP (module docstring) exactly.

    Parameters
    ----------
    H : Array, shape (n, n)
        Symmetric positive definite.
    f : Array, shape (n,)
    lower, upper : Array, shape (n,)
        The bounds, ``lower <= upper``; a variable with ``lower == upper`` is fixed there.
    warm : Array of int, shape (n,), optional
        The previous solution's working set (the returned ``state``: :data:`FREE`,
        :data:`AT_LOWER` or :data:`AT_UPPER` per variable); default all free.
    max_iterations : int, optional
        Cap on the steps (static); default ``primal_dual_steps`` + 3 n + 3. From a
        warm start that is right the method takes one step.
    primal_dual_steps : int
        Steps of the primal-dual method before the primal one takes over (static, at
        least 1; default :data:`PRIMAL_DUAL_STEPS`).
    tolerance : float
        Relative size below which a step, and a multiplier of the wrong sign, count as
        zero (H and f are scaled so that H's largest entry is 1).

    Returns
    -------
    x : Array, shape (n,)
        The minimizer (differentiable in H, f and the bounds with the working set held).
    state : Array of int, shape (n,)
        The final working set, for the next call's ``warm``.
    iterations : Array of int
        Steps taken (the first one confirms a warm start that was right).
    converged : Array of bool
        Whether the KKT conditions held before the cap (False: ``x`` is feasible but
        may not be optimal; non-finite input: False, and ``x`` is not finite).
    """
    H, f, lower, upper = (jnp.asarray(a, dtype=float) for a in (H, f, lower, upper))
    n = f.shape[0]
    if H.shape != (n, n) or lower.shape != (n,) or upper.shape != (n,):
        raise ValueError(f"box_qp: H must be (n, n) and f, lower, upper (n,); got H {H.shape}, f {f.shape}, lower {lower.shape}, upper {upper.shape}")
    if n > MOST_VARIABLES:
        raise ValueError(f"box_qp: at most {MOST_VARIABLES} variables (its arithmetic is unrolled over them); got {n}")
    if int(primal_dual_steps) < 1:
        raise ValueError(f"box_qp: primal_dual_steps must be at least 1; got {primal_dual_steps}")
    primal_dual_steps = int(primal_dual_steps)
    max_iterations = primal_dual_steps + 3 * n + 3 if max_iterations is None else int(max_iterations)
    warm = jnp.full(n, FREE) if warm is None else jnp.asarray(warm)

    def scalars(a):
        return [a[i] for i in range(n)]

    def rows(a):
        return [[a[i, j] for j in range(n)] for i in range(n)]

    # the same minimizer with H's largest entry 1: the tolerances are then relative
    size = jnp.max(jnp.abs(H))
    size = jnp.where(size > 0, size, 1.0)
    Hs, fs, lo, up = jax.tree.map(jax.lax.stop_gradient, (rows(H / size), scalars(f / size), scalars(lower), scalars(upper)))
    fixed = [lo[i] >= up[i] for i in range(n)]
    finite = jnp.all(jnp.isfinite(H)) & jnp.all(jnp.isfinite(f)) & jnp.all(jnp.isfinite(lower)) & jnp.all(jnp.isfinite(upper))

    # the primal-dual method from the warm working set (a right one is confirmed by its
    # first step), at most primal_dual_steps steps
    state = jnp.stack([jnp.where(fixed[i], AT_UPPER, jnp.clip(warm[i], FREE, AT_UPPER)) for i in range(n)])

    def going(carry):
        iteration, finished = carry[2], carry[3]
        return ~finished & (iteration < max_iterations)

    def primal_dual(carry):
        _, state, iteration, _, _ = carry
        state = scalars(state)
        target = _subproblem(Hs, fs, lo, up, state)
        switched, optimal = _primal_dual_step(Hs, fs, lo, up, fixed, tolerance, state, target)
        # (the next state, or on the last step the point handed to the primal method:
        # clipped into the bounds, the variables the clip moved held where it put them)
        last = (iteration == primal_dual_steps - 1) & ~optimal
        handed = [
            jnp.where(state[i] != FREE, state[i], jnp.where(target[i] > up[i], AT_UPPER, jnp.where(target[i] < lo[i], AT_LOWER, FREE)))
            for i in range(n)
        ]
        next_state = [jnp.where(last, handed[i], switched[i]) for i in range(n)]
        x = [jnp.clip(target[i], lo[i], up[i]) for i in range(n)]
        return jnp.stack(x), jnp.stack(next_state), iteration + 1, optimal | last, optimal

    start = (jnp.zeros(n), state, jnp.asarray(0), ~finite, jnp.asarray(False))
    # (solved: the last step changed nothing, so its point meets the KKT conditions)
    x_array, state_array, iterations, _, solved = jax.lax.while_loop(going, primal_dual, start)

    # then, where it did not converge (under vmap: while a run of the batch has not), the
    # primal method, which always terminates
    def primal(carry):
        x, state, iteration, _ = carry
        x, state = scalars(x), scalars(state)
        target = _subproblem(Hs, fs, lo, up, state)
        stepped_x, stepped_state, optimal = _primal_step(Hs, fs, lo, up, fixed, tolerance, x, state, target)
        return jnp.stack(stepped_x), jnp.stack(stepped_state), iteration + 1, optimal

    x_array, state_array, iterations, converged = jax.lax.while_loop(going, primal, (x_array, state_array, iterations, solved | ~finite))
    converged = converged & finite
    x_array = jnp.where(finite, x_array, jnp.nan)
    # the derivative: the sub-problem's on the working set found (computed only when
    # differentiated; its value is the solution's)
    return _on_working_set(x_array, H, f, lower, upper, state_array), state_array, iterations, converged


@jax.custom_jvp
def _on_working_set(x: Array, H: Array, f: Array, lower: Array, upper: Array, state: Array) -> Array:
    """``x``, the solution with the working set ``state``, whose derivative in H, f and
    the bounds is that of the sub-problem on ``state`` (the implicit-function derivative
    of the optimum with its working set held)."""
    return x


@_on_working_set.defjvp
def _on_working_set_jvp(primals, tangents):
    x, H, f, lower, upper, state = primals
    _, dH, df, dlower, dupper, _ = tangents
    n = f.shape[0]

    def solve(H, f, lower, upper):
        rows = [[H[i, j] for j in range(n)] for i in range(n)]
        return jnp.stack(
            _subproblem(rows, [f[i] for i in range(n)], [lower[i] for i in range(n)], [upper[i] for i in range(n)], [state[i] for i in range(n)])
        )

    _, tangent = jax.jvp(solve, (H, f, lower, upper), (dH, df, dlower, dupper))
    return x, tangent
