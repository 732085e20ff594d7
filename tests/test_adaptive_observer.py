"""Adaptive observer of Calugi, Robertsson & Johansson (2003): (13)–(15) and (65)–(67).

The plant is the Northern Clipper (M of eq. 59) without bias noise and without waves
(``VesselPlant(vessel, GaussMarkovBias(1000.0), LinearWaveModel(0.8976, 0.1, 0.0))``,
bias starting at 0), so the observer's model is exact except theta = m11. Gains are
chosen for short runs (K1 = K2 = 0.5 I, 1/s), not the paper's 1e-3 I, under which
nothing moves in a test's horizon.

Scenarios share one structure per form (0.1 s samples, 150 s) and are varied with
``eqx.tree_at``, so each structure compiles once.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lookout.analysis import estimation_errors
from lookout.controllers import SinusoidalInput
from lookout.environment import GaussMarkovBias, LinearWaveModel
from lookout.models.vessel import VesselPlant, VesselState, northern_clipper
from lookout.observers.adaptive_dp import AdaptiveEstimate, AdaptiveObserver, AdaptiveObserverState, InertiaParametrization
from lookout.sensors import PositionHeadingSensor, PositionHeadingVelocitySensor
from lookout.sim import Scenario, simulate
from lookout.sim import filter as run_filter

VESSEL = northern_clipper()
M11 = float(np.asarray(VESSEL.mass_matrix)[0, 0])
LOWER, UPPER = 0.5 * M11, 2.0 * M11
GAIN = 0.5  # K1 = K2 = 0.5 I (1/s)
SAMPLE = 0.1
DURATION = 150.0
#: A persistently exciting surge force (N) and a slow yaw moment (N m), so J(psi) varies.
EXCITING = SinusoidalInput([5e5, 0.0, 2e6], [0.2, 0.0, 0.05])


def _plant() -> VesselPlant:
    return VesselPlant(VESSEL, GaussMarkovBias(1000.0), LinearWaveModel(0.8976, 0.1, 0.0))


def _parametrization() -> InertiaParametrization:
    return InertiaParametrization(VESSEL, ("m11",), [LOWER], [UPPER])


def _observer(form="discrete", gamma=0.0, theta0=M11) -> AdaptiveObserver:
    return AdaptiveObserver(_parametrization(), GAIN, GAIN, gamma, form=form, initial_theta=theta0)


@functools.cache
def _scenario(form: str, mode: str | None = None) -> Scenario:
    """The shared structure: the discrete form in sampled mode, or the continuous form on
    the oracle sensor, integrated with the plant (observer_mode="continuous", the
    default for it) or by its own RK4 predict with y held (``mode="sampled"``)."""
    observer = _observer(form, gamma=1e8, theta0=0.7 * M11)
    sensor = PositionHeadingSensor(0.0, SAMPLE) if form == "discrete" else PositionHeadingVelocitySensor(0.0, SAMPLE)
    mode = mode or ("sampled" if form == "discrete" else "continuous")
    start = VesselState.build()
    return Scenario(
        _plant(),
        sensor,
        observer,
        EXCITING,
        start,
        observer.guess(theta=0.7 * M11),
        plant_step=SAMPLE,
        sample_period=SAMPLE,
        duration=DURATION,
        observer_mode=mode,
    )


def _with(scenario: Scenario, *, gamma=None, guess=None, controller=None) -> Scenario:
    """The scenario with Gamma, the initial estimate or the input swapped (no retrace)."""
    if gamma is not None:
        scenario = eqx.tree_at(lambda s: s.observer.adaptation_gain, scenario, jnp.asarray([[float(gamma)]]))
    if guess is not None:
        scenario = eqx.tree_at(lambda s: s.initial_estimate, scenario, guess)
    if controller is not None:
        scenario = eqx.tree_at(lambda s: s.controller, scenario, controller)
    return scenario


# The parametrization ---------------------------------------------------------------------


def test_the_printed_setting():
    """Section V: theta = m11, K1 = K2 = 1e-3 I, Gamma = 1e3 (bounds and start chosen)."""
    observer = AdaptiveObserver.calugi_2003(VESSEL)
    assert observer.parametrization.names == ("m11",) and observer.form == "discrete"
    np.testing.assert_array_equal(observer.position_gain, 1e-3)
    np.testing.assert_array_equal(observer.velocity_gain, 1e-3)
    np.testing.assert_array_equal(observer.adaptation_gain, [[1e3]])
    np.testing.assert_allclose(observer.guess().theta, [0.8 * M11])
    assert [s.name for s in observer.extra_signals] == ["theta_m11", "innovation_position", "innovation_heading"]
    assert [s.name for s in observer.estimate_signals] == ["position", "heading", "velocity", "yaw_rate"]


def test_names_units_and_true_values():
    par = InertiaParametrization(
        VESSEL,
        ("m11", ("mass", 2, 2), ("mass", 2, 1), "d23", ("damping", 0, 0), ("stiffness", 0, 2), "k22"),
        [1e6, 1e9, -1e6, -1e7, 1e4, -1.0, 0.0],
        [1e7, 1e10, 1e6, 0.0, 1e5, 1.0, 1.0],
    )
    assert par.names == ("m11", "m33", "m23", "d23", "d11", "k13", "k22")
    assert par.units == ("kg", "kg m2", "kg m", "kg m s-1", "kg s-1", "kg m s-2", "kg s-2")
    assert [s.name for s in par.signals] == [f"theta_{n}" for n in par.names]
    np.testing.assert_allclose(par.values(VESSEL), [M11, 3.7454e9, 0.0, -4.3933e6, 5.0242e4, 0.0, 0.0])


def test_the_regressor_is_linear_in_the_parameter_error():
    """M~ xi + D~ nu_hat + K~ eta_hat = phi theta~ (eq. 8, derivations C1), off-diagonal pairs included."""
    rng = np.random.default_rng(0)
    vessel = type(VESSEL)(VESSEL.mass_matrix, VESSEL.damping_matrix, np.diag([1e4, 2e4, 3e6]))
    par = InertiaParametrization(
        vessel, ("m11", "m23", "d22", "d23", "k33", "k12"), [1e6, -1e6, 1e5, -1e7, 0.0, -1e3], [1e7, 1e6, 1e6, 0.0, 1e7, 1e3]
    )
    for _ in range(5):
        theta = jnp.asarray(rng.uniform(par.lower, par.upper))
        theta_hat = jnp.asarray(rng.uniform(par.lower, par.upper))
        xi, nu_hat, eta_hat = (jnp.asarray(rng.normal(size=3)) for _ in range(3))
        eta_hat = eta_hat.at[2].set(5.0)  # the stiffness term wraps the heading, as the plant does
        (m, d, k), (mh, dh, kh) = par.matrices(theta), par.matrices(theta_hat)
        wrapped = eta_hat.at[2].set(5.0 - 2 * np.pi)
        lhs = (m - mh) @ xi + (d - dh) @ nu_hat + (k - kh) @ wrapped
        np.testing.assert_allclose(par.regressor(xi, nu_hat, eta_hat) @ (theta - theta_hat), lhs, rtol=1e-12, atol=1e-9)
    phi = _parametrization().regressor(jnp.asarray([0.3, -2.0, 7.0]), jnp.ones(3), jnp.ones(3))
    np.testing.assert_array_equal(phi, [[0.3], [0.0], [0.0]])  # theta = m11: phi = [xi_1, 0, 0]^T


# Bad inputs -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: AdaptiveObserver(_parametrization(), 0.0, GAIN, 1.0), "position_gain"),
        (lambda: AdaptiveObserver(_parametrization(), GAIN, [1.0, -1.0, 1.0], 1.0), "velocity_gain"),
        (lambda: AdaptiveObserver(_parametrization(), GAIN, GAIN, -1.0), "adaptation_gain"),
        (lambda: AdaptiveObserver(_parametrization(), GAIN, GAIN, [[1.0, 2.0], [0.0, 1.0]]), "adaptation_gain"),
        (lambda: AdaptiveObserver(_parametrization(), GAIN, GAIN, 1.0, form="euler"), "form"),
        (lambda: AdaptiveObserver(_parametrization(), GAIN, GAIN, 1.0, initial_theta=3 * M11), "initial_theta"),
        (lambda: InertiaParametrization(VESSEL, ("m11",), [UPPER], [LOWER]), "theta bounds of m11"),
        (lambda: InertiaParametrization(VESSEL, ("m11",), [LOWER], [np.inf]), "theta upper bound"),
        (lambda: InertiaParametrization(VESSEL, (("inertia", 0, 0),), [LOWER], [UPPER]), "kind"),
        (lambda: InertiaParametrization(VESSEL, (("mass", 0, 3),), [LOWER], [UPPER]), "row and col"),
        (lambda: InertiaParametrization(VESSEL, ("m12", "m21"), [0, 0], [1, 1]), "distinct"),
        (lambda: InertiaParametrization(VESSEL, ("m11",), [0.0], [UPPER]), "lower bound of m11 must be positive"),
        # m23 large enough that m22 m33 - m23^2 < 0 at a vertex of the box
        (lambda: InertiaParametrization(VESSEL, ("m23",), [-1e10], [1e10]), "positive definite"),
        (lambda: InertiaParametrization(VESSEL.mass_matrix, ("m11",), [LOWER], [UPPER]), "DPVessel"),
    ],
)
def test_bad_inputs_fail_with_one_line_naming_the_parameter(build, message):
    with pytest.raises(ValueError, match=message) as error:
        build()
    assert "\n" not in str(error.value)


def test_the_continuous_form_needs_the_oracle_velocity():
    observer = _observer("continuous")
    with pytest.raises(
        ValueError,
        match=r"observer adaptive-dp needs measurement measured_velocity, measured_yaw_rate, which sensor position-heading does not measure \(it measures measured_position, measured_heading\)",
    ):
        Scenario(
            _plant(),
            PositionHeadingSensor(0.0, SAMPLE),
            observer,
            EXCITING,
            VesselState.build(),
            observer.guess(),
            plant_step=SAMPLE,
            sample_period=SAMPLE,
            duration=1.0,
        )
    with pytest.raises(ValueError, match="no vector field"):
        _observer("discrete").vector_field(0.0, None, jnp.zeros(6), jnp.zeros(3))


# Discrete-form mechanics (no engine) -------------------------------------------------------


def test_first_update_is_the_identity_and_missing_samples_predict_with_the_model():
    """init stores eta(0) = y0; the update at t_0 changes nothing. With every channel
    of eta(i) missing, (66) becomes nu_hat + Delta xi and (67) leaves theta_hat alone."""
    observer = _observer("discrete", gamma=1e8, theta0=0.7 * M11)
    y0 = jnp.asarray([1.0, 2.0, 3.1])
    guess = observer.guess(eta=[0.0, 1.0, 3.0], nu=[0.4, -0.1, 0.02])
    state = observer.init(y0, guess)
    np.testing.assert_array_equal(state.measured, y0)
    same = observer.update(state, 0.0, y0)
    for a, b in zip(jax.tree.leaves(same), jax.tree.leaves(state)):
        np.testing.assert_array_equal(a, b)
    tau, dt = jnp.asarray([2e5, 1e5, 1e7]), 0.1
    predicted = observer.predict(same, 0.0, y0, tau, dt)
    missing = observer.update(predicted, dt, jnp.full(3, jnp.nan))
    xi = observer.model_acceleration(same.theta, same.eta, same.nu, tau)
    np.testing.assert_allclose(missing.nu, same.nu + dt * xi, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(missing.theta, same.theta, rtol=1e-12)
    # the stand-in eta(i-1) + Delta J nu_hat becomes the base of the next difference
    np.testing.assert_allclose(
        missing.measured[:2], y0[:2] + dt * np.array([np.cos(3.1) * 0.4 + np.sin(3.1) * 0.1, np.sin(3.1) * 0.4 - np.cos(3.1) * 0.1]), rtol=1e-12
    )


def test_continuous_projection_stops_outward_rates_at_a_bound():
    observer = _observer("continuous", gamma=1e8)
    tau = jnp.asarray([1e5, 0.0, 0.0])  # xi_1 > 0 with nu_hat = 0
    at_upper = AdaptiveObserverState(jnp.zeros(3), jnp.zeros(3), jnp.asarray([UPPER]), jnp.zeros(3), jnp.zeros(3), jnp.zeros((3, 1)))
    outward = observer.vector_field(0.0, at_upper, jnp.asarray([0, 0, 0, -0.1, 0, 0.0]), tau)  # -Gamma xi_1 u~ > 0
    inward = observer.vector_field(0.0, at_upper, jnp.asarray([0, 0, 0, 0.1, 0, 0.0]), tau)
    assert float(outward.theta[0]) == 0.0
    assert float(inward.theta[0]) < 0.0


# The discrete form tends to the continuous one --------------------------------------------


@pytest.mark.slow
def test_discrete_form_converges_to_the_continuous_form_at_first_order():
    """theta known (theta_hat = m11, Gamma = 0), no noise, the same imperfect start.

    The continuous form (13)–(14) is integrated with the plant (observer_mode=
    "continuous", oracle sensor, RK4 at 0.0125 s, samples every 0.025 s). The input
    is constant, so the plant's trajectory does not depend on the sample period:
    the discrete form (65)–(66) at Delta is run by ``lookout.sim.filter`` (the
    engine's update/output/predict order) over that run's own noise-free positions
    and headings taken every Delta. Its velocity estimate differs from the
    continuous one by O(Delta) (measured order 1.00–1.01 for u, v and r). The
    heading starts at 3.0 rad and turns through +-pi, so the ssa of delta_psi is exercised.
    """
    fine, horizon = 0.025, 20.0
    continuous, discrete = _observer("continuous"), _observer("discrete")
    start = VesselState.build(eta=[10.0, -5.0, 3.0], nu=[0.5, 0.1, 0.01])
    guess = continuous.guess(eta=np.asarray(start.eta) + [5.0, -3.0, 0.1], nu=np.asarray(start.nu) + [-0.2, 0.1, -0.005], theta=M11)
    scenario = Scenario(
        _plant(),
        PositionHeadingVelocitySensor(0.0, fine),
        continuous,
        SinusoidalInput.constant([2e5, 1e5, 2e7]),
        start,
        guess,
        plant_step=fine / 2,
        sample_period=fine,
        duration=horizon + fine,
        observer_mode="continuous",
    )
    reference = simulate(scenario, jax.random.key(0))
    y, u, t = np.asarray(reference.measurement), np.asarray(reference.applied), np.asarray(reference.time)
    assert y[:, 2].max() > 3.1 and y[:, 2].min() < -3.1  # the heading wrapped

    def velocities(estimate):
        return np.concatenate([np.reshape(estimate["velocity"], (-1, 2)), np.reshape(estimate["yaw_rate"], (-1, 1))], axis=1)

    common = 0.2  # compare at t = 0, 0.2, ..., 20 s
    exact = velocities(reference.estimate)[:: round(common / fine)]
    deltas = np.array([0.2, 0.1, 0.05, 0.025])
    differences = []
    for delta in deltas:
        every = round(delta / fine)
        ds = run_filter(discrete, t[::every], y[::every, :3], u[::every], guess=guess)
        estimate = velocities({"velocity": ds["velocity_hat"].values, "yaw_rate": ds["yaw_rate_hat"].values})[:: round(common / delta)]
        n = min(len(estimate), len(exact))
        differences.append(np.abs(estimate[:n] - exact[:n]).max(axis=0))
    differences = np.array(differences)
    orders = [np.polyfit(np.log(deltas), np.log(differences[:, j]), 1)[0] for j in range(3)]
    print(f"first-order convergence: orders (u, v, r) = {np.round(orders, 3).tolist()}, max |nu_hat_d - nu_hat_c| = {differences.tolist()}")
    for order in orders:
        assert 0.8 < order < 1.2, orders
    assert differences[-1, 0] < 1e-3  # 0.7 mm/s at Delta = 0.025 s


# Projection ------------------------------------------------------------------------------


@settings(max_examples=6)
@given(log_gamma=st.floats(0.0, 16.0), fraction=st.floats(0.0, 1.0))
@pytest.mark.slow
def test_theta_hat_never_leaves_its_bounds(log_gamma, fraction):
    """Gamma from 1 to 1e16, theta_hat(0) anywhere in [0.5 m11, 2 m11], an imperfect
    velocity estimate and an exciting input: both forms keep theta_hat in the box
    (discrete: clip after (67); continuous, integrated with the plant or by its own
    RK4 predict: projected rate and a clip after each step)."""
    theta0 = LOWER + fraction * (UPPER - LOWER)
    guess = AdaptiveEstimate(jnp.asarray([2.0, -1.0, 0.05]), jnp.asarray([0.3, -0.1, 0.002]), jnp.asarray([theta0]))
    for form, mode in (("discrete", None), ("continuous", None), ("continuous", "sampled")):
        trajectory = simulate(_with(_scenario(form, mode), gamma=10.0**log_gamma, guess=guess), jax.random.key(0))
        theta = np.asarray(trajectory.estimate["theta_m11"])
        assert np.all(np.isfinite(theta)) and np.all(np.isfinite(np.asarray(trajectory.estimate["velocity"])))
        assert theta.min() >= LOWER and theta.max() <= UPPER, (form, theta.min() / M11, theta.max() / M11)


@pytest.mark.slow
def test_a_large_gain_drives_theta_hat_onto_a_bound():
    """The check above can fail: with Gamma = 1e14 theta_hat reaches a bound and stays in."""
    guess = AdaptiveEstimate(jnp.zeros(3), jnp.asarray([0.3, 0.0, 0.0]), jnp.asarray([M11]))
    for form, mode in (("discrete", None), ("continuous", None), ("continuous", "sampled")):
        theta = np.asarray(simulate(_with(_scenario(form, mode), gamma=1e14, guess=guess), jax.random.key(0)).estimate["theta_m11"])
        assert np.any((theta == LOWER) | (theta == UPPER)), (form, mode)


# Adaptation ------------------------------------------------------------------------------


def test_theta_hat_converges_with_excitation_and_stays_without():
    """Exact model except m11, no noise, theta_hat(0) = 0.7 m11, Gamma = 1e8 (kg s2 m-2),
    surge force 5e5 sin(0.2 t) N: the discrete form (Delta = 0.1 s) brings theta_hat
    within 1.5 % of m11 over the last 50 s of 150 s (its residual, 0.55 %, halves with
    Delta: 0.28 % at 0.05 s, 0.14 % at 0.025 s); the continuous form (oracle nu) within
    1e-6. With zero input (eta_hat off by 5 m, nu_hat = nu = 0) there is no excitation
    (phi = [xi_1, 0, 0] = 0) and theta_hat stays exactly where it started."""
    guess = AdaptiveEstimate(jnp.zeros(3), jnp.zeros(3), jnp.asarray([0.7 * M11]))
    last = int(50.0 / SAMPLE)
    for form, tolerance in (("discrete", 0.015), ("continuous", 1e-6)):
        theta = np.asarray(simulate(_with(_scenario(form), gamma=1e8, guess=guess), jax.random.key(0)).estimate["theta_m11"])
        assert theta[0] == 0.7 * M11
        assert np.abs(theta[-last:] / M11 - 1.0).max() < tolerance, (form, theta[-1] / M11)

    offset = AdaptiveEstimate(jnp.asarray([5.0, -5.0, 0.1]), jnp.zeros(3), jnp.asarray([0.7 * M11]))
    for form in ("discrete", "continuous"):
        quiet = _with(_scenario(form), gamma=1e8, guess=offset, controller=SinusoidalInput.constant([0.0, 0.0, 0.0]))
        theta = np.asarray(simulate(quiet, jax.random.key(0)).estimate["theta_m11"])
        np.testing.assert_array_equal(theta, 0.7 * M11)


# Exactness of the continuous form ------------------------------------------------------------


def test_continuous_form_from_a_perfect_start_stays_exact():
    """Perfect start, theta_hat = m11, noise-free, observer_mode="continuous": nu~ = 0
    keeps theta_hat' = 0 (Gamma = 1e8 nonetheless) and the estimate equals the truth."""
    start = VesselState.build(eta=[3.0, -2.0, 3.1], nu=[0.2, -0.05, 0.01])
    scenario = _with(_scenario("continuous"), gamma=1e8, guess=AdaptiveEstimate(start.eta, start.nu, jnp.asarray([M11])))
    scenario = eqx.tree_at(lambda s: s.initial_state, scenario, start)
    trajectory = simulate(scenario, jax.random.key(0))
    ds = trajectory.to_xarray()
    errors = estimation_errors(ds)
    assert set(errors.data_vars) == {"position", "heading", "velocity", "yaw_rate"}
    for name, error in errors.items():
        scale = 1.0 + float(np.abs(ds[name]).max())
        assert float(np.abs(error).max()) <= 1e-12 * scale, (name, float(np.abs(error).max()))
    assert np.abs(np.asarray(trajectory.estimate["theta_m11"]) / M11 - 1.0).max() < 1e-12


# The conformance protocol (tests/test_conformance.py, Case.build) ---------------------------
