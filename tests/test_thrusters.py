"""Thrusters and allocation: the weighted pseudo-inverse, the QP against SciPy, the
thrusters' limits in a closed loop, records, and refusals. (The closed loop's vmap,
trace and gradient checks are a case of tests/test_conformance.py.)"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import LinearConstraint, minimize

from lookout.actuators import Allocator, ThrusterLayout, ThrusterSystem
from lookout.actuators.qp import active_set
from lookout.actuators.thrusters import at_limit, relative_power
from lookout.studies.metrics import reduce, resolve, summarize

LAYOUTS = {"supply-vessel": ThrusterLayout.supply_vessel, "cybership-ii": ThrusterLayout.cybership_ii}
DT = 0.1


def _weighted_pseudo_inverse(layout: ThrusterLayout, allocator: Allocator, tau) -> np.ndarray:
    """u = W^-1 B^T (B W^-1 B^T)^-1 tau in newtons, W = diag(weight / largest^2), written
    here from the layout alone (not from the allocator's scaled matrices)."""
    B = layout.B
    largest = np.array([layout.max_thrust[i] * (layout.rudder_lift[i] * layout.max_rudder[i] if part == "lift" else 1.0)
                        for i, part in layout.variables])
    W_inverse = np.diag(largest**2 / np.array([layout.weight[i] for i, _ in layout.variables]))
    return W_inverse @ B.T @ np.linalg.solve(B @ W_inverse @ B.T, np.asarray(tau))


@pytest.mark.parametrize("name", LAYOUTS)
def test_unsaturated_allocation_is_the_weighted_pseudo_inverse(name):
    layout = LAYOUTS[name]()
    allocator = Allocator(layout)
    allocate = eqx.filter_jit(lambda a, tau, previous, angle: a.allocate(tau, previous, angle, DT))
    rng = np.random.default_rng(1)
    for _ in range(20):
        # ahead on the main propellers (their rudders lift only ahead), within every limit
        tau = rng.uniform([0.1, -0.05, -0.05], [0.3, 0.05, 0.05]) * layout.force_scale
        expected = _weighted_pseudo_inverse(layout, allocator, tau)
        # thrusters already there: no rate limit binds, azimuths and rudders at their angles
        previous = expected / np.asarray(allocator.scale)
        angle = np.asarray(ThrusterSystem(layout).commands(jnp.asarray(previous), jnp.zeros(layout.size), jnp.asarray(previous))[1])
        u, info = allocate(allocator, jnp.asarray(tau), jnp.asarray(previous), jnp.asarray(angle))
        assert not bool(info["saturated"])
        np.testing.assert_allclose(np.asarray(u) * allocator.scale, expected, rtol=0, atol=1e-10 * layout.max_thrust.max())
        assert float(info["shortfall"]) < 1e-14


@pytest.mark.parametrize("name", LAYOUTS)
def test_steady_state_delivers_the_commanded_force_exactly(name):
    layout = LAYOUTS[name]()  # with lags, rate limits and turning rates
    system = ThrusterSystem(layout)
    tau = jnp.asarray([0.2, -0.05, 0.03]) * layout.force_scale  # within every limit once there

    def run(state, _):
        state, applied, _ = system.step(state, 0.0, tau, DT)
        return state, applied

    _, applied = jax.jit(lambda s: jax.lax.scan(run, s, None, length=3000))(system.init())
    np.testing.assert_allclose(np.asarray(applied[-1]), np.asarray(tau), rtol=0, atol=1e-10 * layout.force_scale.max())
    # and it got there through the rate limits: the first samples fall short
    assert np.max(np.abs(np.asarray(applied[0] - tau)) / layout.force_scale) > 0.05


def _objective(allocator, G, h, tau, x):
    target = np.asarray(allocator.target_matrix) @ (np.asarray(tau) / allocator.force_scale)
    slack = allocator.B @ x - target
    return 0.5 * x @ np.diag(allocator.weights) @ x + 0.5 * slack @ np.diag(allocator.slack_weights) @ slack


def _random_state(system: ThrusterSystem, rng, steps: int):
    """A state reached by the thrusters under random commands (feasible by construction)."""
    state = system.init()
    step = eqx.filter_jit(lambda s, st, tau: s.step(st, 0.0, tau, DT))
    for _ in range(steps):
        state, _, _ = step(system, state, jnp.asarray(rng.uniform(-1.5, 1.5, 3) * system.layout.force_scale))
    return state


@pytest.mark.filterwarnings("ignore:Singular Jacobian matrix:UserWarning")  # SciPy's, at degenerate vertices
@pytest.mark.parametrize("name", LAYOUTS)
def test_saturated_allocation_meets_every_limit_and_minimizes_the_weighted_slack(name):
    """At random states and random tau (within reach and far beyond it): the QP's command
    meets every limit, and no point SciPy finds on the same QP does better."""
    layout = LAYOUTS[name]()
    system = ThrusterSystem(layout, clip_to_reach=False)
    allocator = system.allocator
    allocate = eqx.filter_jit(lambda a, tau, previous, angle: a.allocate(tau, previous, angle, DT))
    rng = np.random.default_rng(5)
    infeasible = 0
    for trial in range(12):
        state = _random_state(system, rng, 5 + trial)
        tau = rng.uniform(-1, 1, 3) * layout.force_scale * (0.4 if trial % 2 else 2.5)
        u, info = allocate(allocator, jnp.asarray(tau), state[2], state[1])
        G, h, start = (np.asarray(a) for a in allocator.constraints(state[2], state[1], DT, info["unconstrained"]))
        u = np.asarray(u)
        assert bool(info["converged"]) and bool(info["saturated"])
        assert np.all(G @ u <= h + 1e-9), (trial, np.max(G @ u - h))
        ours = _objective(allocator, G, h, tau, u)
        finite = h < 1e29
        target = np.asarray(allocator.target_matrix) @ (tau / allocator.force_scale)
        hessian = np.diag(allocator.weights) + allocator.B.T @ np.diag(allocator.slack_weights) @ allocator.B
        reference = minimize(
            lambda x: _objective(allocator, G, h, tau, x), np.asarray(start), method="trust-constr",
            jac=lambda x: hessian @ x - allocator.B.T @ (allocator.slack_weights * target), hess=lambda x: hessian,
            constraints=[LinearConstraint(G[finite], -np.inf, h[finite])], options={"gtol": 1e-12, "xtol": 1e-14, "maxiter": 5000},
        )
        assert np.all(G @ reference.x <= h + 1e-7)
        assert ours <= reference.fun + 1e-9 * max(1.0, abs(reference.fun)), (trial, ours, reference.fun)
        infeasible += float(info["shortfall"]) > 1e-3
    assert infeasible >= 3  # the far-off commands could not be produced


def test_the_qp_solver_agrees_with_scipy_on_random_problems():
    rng = np.random.default_rng(11)
    solve = jax.jit(lambda P, q, G, h, x0: active_set(P, q, G, h, x0, max_iterations=60))
    for _ in range(20):
        n, m = 6, 20
        A = rng.normal(size=(n, n))
        P = A @ A.T + 0.1 * np.eye(n)
        q = rng.normal(size=n) * 5
        G = rng.normal(size=(m, n))
        x0 = rng.normal(size=n) * 0.1
        h = G @ x0 + rng.uniform(0, 1, m)  # x0 strictly feasible
        x, working, iterations, converged = solve(P, q, G, h, x0)
        assert bool(converged)
        reference = minimize(lambda z: 0.5 * z @ P @ z + q @ z, x0, jac=lambda z: P @ z + q, method="SLSQP",
                             constraints=[{"type": "ineq", "fun": lambda z: h - G @ z, "jac": lambda z: -G}], options={"ftol": 1e-15})
        np.testing.assert_allclose(np.asarray(x), reference.x, atol=1e-6)


def test_qp_solution_is_differentiable_with_its_active_set_held():
    rng = np.random.default_rng(2)
    n, m = 4, 10
    A = rng.normal(size=(n, n))
    P = A @ A.T + np.eye(n)
    G = rng.normal(size=(m, n))
    h = 0.5 + np.abs(rng.normal(size=m))
    q0 = rng.normal(size=n) * 3

    def f(q):
        return jnp.sum(active_set(P, q, G, h, jnp.zeros(n), max_iterations=40)[0] ** 2)

    gradient = np.asarray(jax.grad(f)(jnp.asarray(q0)))
    step = 1e-6
    central = [(f(q0 + step * e) - f(q0 - step * e)) / (2 * step) for e in np.eye(n)]
    np.testing.assert_allclose(gradient, central, rtol=1e-6, atol=1e-9)
    assert np.any(np.abs(gradient) > 1e-3)


def test_closed_loop_thrusters_never_exceed_their_limits():
    """Kim's loop with the supply vessel's thrusters, 60 s from 3 m off: every sample of
    every thruster within its force, rate and turning limits, and the allocation saturated
    at times (the check can fail)."""
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from test_conformance import _sliding_mode_loop

    from lookout.sim import simulate

    scenario = _sliding_mode_loop(thrusters=True, duration=60.0)
    layout = scenario.actuator.layout
    records = simulate(scenario, jax.random.key(0))
    thrust = np.asarray(records.actuation["thrust"])
    angle = np.asarray(records.actuation["thruster_angle"])
    assert np.all(np.isfinite(np.asarray(records.applied)))
    tolerance = 1e-9 * layout.max_thrust
    assert np.all(thrust <= layout.max_thrust + tolerance) and np.all(thrust >= layout.min_thrust - tolerance)
    change = np.abs(np.diff(np.concatenate([np.zeros((1, layout.size)), thrust]), axis=0))
    assert np.all(change <= layout.thrust_rate * scenario.sample_period * (1 + 1e-9))
    turning = np.abs((np.diff(angle, axis=0) + np.pi) % (2 * np.pi) - np.pi)
    azimuth = layout.is_kind("azimuth")
    assert np.all(turning[:, azimuth] <= layout.turn_rate[azimuth] * scenario.sample_period * (1 + 1e-9))
    saturated = np.asarray(records.actuation["allocation_saturated"])
    assert 0.05 < saturated.mean()
    assert np.any(thrust.max(axis=0) > 0.5 * layout.max_thrust)


def test_limits_and_power_metrics():
    layout = ThrusterLayout.supply_vessel()
    thrust = np.array([[1.3e5, -1.3e5, 3.0e5, 0.0], [0.0, 0.0, 0.0, 0.0], [6.5e4, 0.0, 1.5e5, 1.5e5]])
    np.testing.assert_array_equal(at_limit(thrust, layout.max_thrust, layout.min_thrust), [[True, True, True, False], [False] * 4, [False] * 4])
    power = np.asarray(relative_power(thrust, layout.max_thrust))
    assert power[1] == 0.0
    # at full thrust everywhere the installed power; at half thrust 2^-1.5 of it
    assert float(relative_power(layout.max_thrust, layout.max_thrust)) == pytest.approx(1.0)
    assert float(relative_power(0.5 * layout.max_thrust, layout.max_thrust)) == pytest.approx(0.5**1.5)


def test_an_infeasible_command_is_a_shortfall_and_a_nan_command_is_nan():
    layout = ThrusterLayout.cybership_ii()
    system = ThrusterSystem(layout)
    step = eqx.filter_jit(lambda s, st, tau: s.step(st, 0.0, tau, DT))
    state = system.init()
    for _ in range(100):
        state, applied, outputs = step(system, state, jnp.asarray([50.0, -40.0, 30.0]))
    assert np.all(np.isfinite(np.asarray(applied)))
    assert float(outputs["allocation_shortfall"]) > 1.0 and float(outputs["allocation_saturated"]) == 1.0
    assert np.all(np.abs(np.asarray(outputs["thrust"])) <= layout.max_thrust + 1e-12)
    _, applied, outputs = step(system, state, jnp.asarray([np.nan, 0.0, 0.0]))
    assert np.all(np.isnan(np.asarray(applied)))


def test_thrusters_are_recorded_with_units_and_a_thruster_dimension(tmp_path):
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from test_conformance import _sliding_mode_loop

    import xarray as xr

    from lookout.sim import simulate

    scenario = _sliding_mode_loop(thrusters=True, duration=10.0)
    ds = simulate(scenario, jax.random.key(0)).to_xarray()
    assert ds.thrust.dims == ("run", "time", "thruster") and ds.thrust.attrs["units"] == "N"
    assert list(ds.thruster.values) == list(ThrusterLayout.supply_vessel().names)
    assert ds.thruster_angle.attrs["units"] == "rad" and ds.thruster_angle.attrs["angle"] == 1
    assert ds.allocation_shortfall.dims == ("run", "time")
    path = ds.pipe(lambda d: __import__("lookout.results", fromlist=["write_netcdf"]).write_netcdf(d, tmp_path / "run.nc"))
    with xr.open_dataset(path) as back:
        np.testing.assert_array_equal(back.thrust.values, ds.thrust.values)

    import matplotlib

    matplotlib.use("Agg")
    from lookout.plotting import plot_run_thrusters

    figure = plot_run_thrusters(ds)
    lines = [line for axis in figure.axes for line in axis.get_lines()]
    assert len(lines) >= 2 * 4 * 2  # delivered and commanded thrust of 4 thrusters, whole run and zoom
    assert plot_run_thrusters(ds.drop_vars(["thrust"])) is None


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"names": ["a", "b"], "kinds": ["tunnel"]}, "kinds must have one entry per thruster"),
        ({"max_thrust": [1.0, 0.0, 1.0]}, "max_thrust must be positive"),
        ({"min_thrust": [-2.0, 0.0, 0.0]}, "min_thrust must be in"),
        ({"time_constant": -1.0}, "time_constant must be non-negative"),
        ({"thrust_rate": [1.0, math.nan, 1.0]}, "thrust_rate must not be NaN"),
        ({"kinds": ["tunnel", "tunnel", "tunnel"], "direction": [math.pi / 2] * 3}, "span only 2"),
    ],
)
def test_a_bad_layout_is_refused_naming_the_parameter(arguments, message):
    base = dict(names=["bow", "port", "starboard"], kinds=["tunnel", "azimuth", "azimuth"], x=[1.0, -1.0, -1.0], y=[0.0, -0.2, 0.2],
                direction=[math.pi / 2, 0.0, 0.0], max_thrust=[1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=message):
        ThrusterLayout(**{**base, **arguments})


@pytest.mark.parametrize(
    ("arguments", "message"),
    [({"allocation": "lp"}, "allocation must be one of"), ({"slack_weight": 0.0}, "slack_weight must be"),
     ({"slack_weight": [1.0, 2.0]}, "slack_weight must be"), ({"polygon_sides": 3}, "polygon_sides must be")],
)
def test_bad_allocation_options_are_refused_naming_the_parameter(arguments, message):
    with pytest.raises(ValueError, match=message):
        ThrusterSystem(ThrusterLayout.supply_vessel(), **arguments)


def test_the_shipped_layouts_reach_what_their_documentation_says():
    cybership = Allocator(ThrusterLayout.cybership_ii())
    reach = cybership.reach * cybership.force_scale
    # Wondergem et al. (2009): at most 2 N surge, 1.5 N sway, 1.5 N m yaw
    assert reach[1, 0] == pytest.approx(2.0, rel=1e-6) and reach[0, 0] == pytest.approx(-1.0, rel=1e-6)
    assert np.all(np.abs(reach[:, 1]) <= 1.5 + 1e-9) and np.all(np.abs(reach[:, 2]) <= 1.5 + 1e-9)
    supply = Allocator(ThrusterLayout.supply_vessel())
    reach = supply.reach * supply.force_scale
    assert reach[1, 0] == pytest.approx(6.0e5, rel=1e-6)  # two azimuths of 300 kN ahead


def test_thruster_metrics_in_the_scan_equal_them_from_the_records():
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from test_conformance import _sliding_mode_loop

    from lookout.sim import simulate_batch

    scenario = _sliding_mode_loop(thrusters=True, duration=20.0)
    metrics = resolve(["mean_power:thrust", "time_at_limit:thrust", "rms_error:velocity"], scenario)
    keys = jax.random.split(jax.random.key(1), 2)
    inside = summarize(scenario, keys, metrics, after=0.0)
    batch = simulate_batch(scenario, keys)
    outside = reduce(batch, metrics, after=0.0)
    for name in ("mean_power__thrust", "time_at_limit__thrust"):
        np.testing.assert_allclose(inside[name], outside[name], rtol=1e-12)
    layout = scenario.actuator.layout
    thrust = np.asarray(batch.actuation["thrust"])
    np.testing.assert_allclose(inside["mean_power__thrust"], np.asarray(relative_power(thrust, layout.max_thrust)).mean(axis=1), rtol=1e-12)
    expected = np.asarray(at_limit(thrust, layout.max_thrust, layout.min_thrust)).any(axis=-1).mean(axis=1)
    np.testing.assert_allclose(inside["time_at_limit__thrust"], expected)
    assert np.all(inside["mean_power__thrust"] > 0)
    with pytest.raises(ValueError, match="mean_power:thrust"):
        resolve(["mean_power:force"], scenario)


@pytest.mark.parametrize("name", LAYOUTS)
def test_qpax_and_the_active_set_method_find_the_same_allocation(name):
    """The two QP solvers (lookout's active set, qpax's interior point) on the same
    saturated problems: the same command to 1e-8 of the largest thrust."""
    pytest.importorskip("qpax")
    layout = LAYOUTS[name]()
    ours, theirs = ThrusterSystem(layout), ThrusterSystem(layout, solver="qpax")
    allocate = eqx.filter_jit(lambda a, tau, previous, angle: a.allocate(tau, previous, angle, DT))
    rng = np.random.default_rng(3)
    saturated = 0
    for trial in range(10):
        state = _random_state(ours, rng, 3 + trial)
        tau = jnp.asarray(rng.uniform(-1, 1, 3) * layout.force_scale)
        u, info = allocate(ours.allocator, tau, state[2], state[1])
        v, _ = allocate(theirs.allocator, tau, state[2], state[1])
        np.testing.assert_allclose(np.asarray(u), np.asarray(v), atol=1e-8)
        saturated += bool(info["saturated"])
    assert saturated >= 5
