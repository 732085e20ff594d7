"""The bound-constrained QP solver (lookout.actuators.box_qp) against the KKT conditions,
SciPy's bounded least squares, and lookout's general active-set method."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import lsq_linear

from lookout.actuators.box_qp import AT_LOWER, AT_UPPER, FREE, MOST_VARIABLES, PRIMAL_DUAL_STEPS, box_qp
from lookout.actuators.qp import active_set

solve = jax.jit(box_qp)
#: the primal method from the first step's point on (it takes over whenever the primal-dual one has not converged)
solve_primal = jax.jit(lambda H, f, lower, upper, warm: box_qp(H, f, lower, upper, warm, primal_dual_steps=1))


def _problem(rng, n: int, fixed: bool = False):
    """A random strictly convex QP with bounds around 0 (some of them binding)."""
    A = rng.normal(size=(n + 2, n))
    H = A.T @ A + 1e-3 * np.eye(n)
    f = 3.0 * rng.normal(size=n)
    lower, upper = -rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
    if fixed:
        lower[0] = upper[0] = 0.3
    return H, f, lower, upper


def _kkt_error(H, f, lower, upper, x) -> float:
    """The largest violation of the KKT conditions: bounds, a free variable's gradient,
    and a held variable's multiplier sign."""
    g = H @ x + f
    span = np.maximum(np.abs(g), 1.0)
    at_lower, at_upper = np.isclose(x, lower, atol=1e-12), np.isclose(x, upper, atol=1e-12)
    fixed = lower >= upper
    errors = [np.max(lower - x), np.max(x - upper)]
    free = ~at_lower & ~at_upper
    errors.append(np.max(np.abs(g[free]) / span[free], initial=0.0))
    errors.append(np.max(np.where(at_lower & ~at_upper & ~fixed, -g, 0.0) / span))  # g >= 0 at a lower bound
    errors.append(np.max(np.where(at_upper & ~at_lower & ~fixed, g, 0.0) / span))  # g <= 0 at an upper bound
    return float(max(errors))


@pytest.mark.slow
def test_random_problems_meet_the_kkt_conditions_and_agree_with_scipy_and_the_general_method():
    """200 problems of 1 to 8 variables, one in five with a fixed variable, from random warm
    starts: the KKT conditions hold to 1e-9, the primal method alone (after one
    primal-dual step) finds the same solution, the objective is SciPy's bounded least
    squares' to 1e-9 (never above it by more), and the solution is the general active-set
    method's (bounds as rows of G) to 1e-8."""
    rng = np.random.default_rng(0)
    general = jax.jit(lambda H, f, G, h, x0: active_set(H, f, G, h, x0, max_iterations=40))
    for trial in range(200):
        n = int(rng.integers(1, 9))
        H, f, lower, upper = _problem(rng, n, fixed=trial % 5 == 0)
        warm = rng.integers(FREE, AT_UPPER + 1, n)
        x, state, iterations, converged = (np.asarray(a) for a in solve(H, f, lower, upper, warm))
        assert converged and iterations <= PRIMAL_DUAL_STEPS + 3 * n + 3, trial
        assert _kkt_error(H, f, lower, upper, x) < 1e-9, trial
        primal = np.asarray(solve_primal(H, f, lower, upper, warm)[0])
        np.testing.assert_allclose(primal, x, atol=1e-9, err_msg=str(trial))
        # SciPy: 1/2 x^T H x + f^T x = 1/2 |L^T x - b|^2 + const, L L^T = H, L b = -f
        L = np.linalg.cholesky(H)
        reference = lsq_linear(L.T, -np.linalg.solve(L, f), bounds=(lower, np.maximum(upper, lower + 1e-15)), method="trf", tol=1e-14)
        objective = lambda z: 0.5 * z @ H @ z + f @ z  # noqa: E731
        assert objective(x) <= objective(reference.x) + 1e-9, trial
        G = np.concatenate([np.eye(n), -np.eye(n)])
        h = np.concatenate([upper, -lower])
        y, _, _, done = general(H, f, G, h, np.clip(np.zeros(n), lower, upper))
        assert bool(done)
        np.testing.assert_allclose(x, np.asarray(y), atol=1e-8, err_msg=str(trial))
        # the held bounds are the working set's
        held = state != FREE
        np.testing.assert_array_equal(x[state == AT_LOWER], lower[state == AT_LOWER])
        np.testing.assert_array_equal(x[state == AT_UPPER], upper[state == AT_UPPER])
        assert np.all((x[~held] > lower[~held]) | (lower[~held] >= upper[~held]) | np.isclose(x[~held], lower[~held]))


def test_a_warm_start_on_the_solution_s_working_set_takes_one_step_and_the_same_answer():
    rng = np.random.default_rng(1)
    for _ in range(20):
        H, f, lower, upper = _problem(rng, 6)
        x, state, iterations, _ = solve(H, f, lower, upper, None)
        again, same, one, converged = solve(H, f, lower, upper, state)
        assert int(one) == 1 and bool(converged)
        np.testing.assert_array_equal(np.asarray(same), np.asarray(state))
        np.testing.assert_allclose(np.asarray(again), np.asarray(x), atol=1e-12)


def test_a_fixed_variable_stays_at_its_value_and_the_batch_equals_each_problem():
    """Under vmap (the batch iterates until its slowest member is done) each problem's
    answer is the one it gets alone; lower == upper holds a variable there exactly."""
    rng = np.random.default_rng(2)
    problems = [_problem(rng, 5, fixed=True) for _ in range(16)]
    H, f, lower, upper = (np.stack(p) for p in zip(*problems, strict=True))
    warm = np.full((16, 5), FREE)
    batch = jax.jit(jax.vmap(box_qp))(H, f, lower, upper, warm)
    for k in range(16):
        alone = solve(H[k], f[k], lower[k], upper[k], warm[k])
        np.testing.assert_allclose(np.asarray(batch[0][k]), np.asarray(alone[0]), atol=1e-12)
        assert float(batch[0][k][0]) == 0.3
    assert np.all(np.asarray(batch[3]))


@pytest.mark.slow
def test_the_solution_is_differentiable_with_its_working_set_held():
    """d x / d f against central differences (a step that changes no active bound)."""
    rng = np.random.default_rng(3)
    H, f, lower, upper = _problem(rng, 5)
    weights = rng.normal(size=5)

    def loss(f):
        return jnp.dot(weights, box_qp(H, f, lower, upper)[0])

    gradient = np.asarray(jax.grad(loss)(jnp.asarray(f)))
    step = 1e-6
    for i in range(5):
        e = np.zeros(5)
        e[i] = step
        numeric = (float(loss(f + e)) - float(loss(f - e))) / (2 * step)
        assert gradient[i] == pytest.approx(numeric, abs=1e-6)


def test_non_finite_input_returns_unconverged_without_looping_forever():
    H, f, lower, upper = _problem(np.random.default_rng(4), 4)
    f[1] = np.nan
    x, _, iterations, converged = solve(H, f, lower, upper, None)
    assert not bool(converged) and int(iterations) == 0


@pytest.mark.parametrize(
    ("H", "f", "steps", "message"),
    [
        (np.eye(3), np.zeros(2), 6, "H must be"),
        (np.eye(MOST_VARIABLES + 1), np.zeros(MOST_VARIABLES + 1), 6, "at most 12 variables"),
        (np.eye(2), np.zeros(2), 0, "primal_dual_steps must be at least 1"),
    ],
)
def test_bad_arguments_are_a_value_error(H, f, steps, message):
    n = f.shape[0]
    with pytest.raises(ValueError, match=message):
        box_qp(H, f, -np.ones(n), np.ones(n), primal_dual_steps=steps)
