"""The Middleton–Goodwin parameter estimator of Calugi (2002), ch. 3 (observers.parameter_estimator)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from lookout.controllers import SinusoidalInput
from lookout.models.manipulators import FreePendulum, JointState, ManipulatorPlant, TwoLinkArm
from lookout.models.parameters import ModelParameters, PendulumInertia
from lookout.models.scheduled_parameters import ScheduledParameterPlant
from lookout.observers.parameter_estimator import ParameterEstimator, ParameterEstimatorState, windowed_excitation
from lookout.sensors import JointStateSensor
from lookout.sim import Scenario, simulate
from lookout.sim.integrators import rk4_step

PENDULUM = FreePendulum(2.0, 1.5, 0.0)
MASS = ModelParameters(PENDULUM, ("mass",), units=("kg",))
ARM = TwoLinkArm((0.5, 0.7), (1.0, 1.5), (0.5, 0.1))
ARM_MASSES = ModelParameters(ARM, ("masses[0]", "masses[1]"), units=("kg", "kg"))

# A smooth joint trajectory with q'(0) != 0 (so the q'(0) e^{-a t} term matters), two joints.
AMPLITUDE = np.array([0.8, -0.6])
FREQUENCY = np.array([1.3, 2.1])
OFFSET = np.array([0.3, 0.9])


def _trajectory(t):
    """q, q', q'' of q = OFFSET + AMPLITUDE sin(FREQUENCY t + 0.4) (jnp or numpy)."""
    phase = FREQUENCY * t + 0.4
    q = OFFSET + AMPLITUDE * jnp.sin(phase)
    return q, AMPLITUDE * FREQUENCY * jnp.cos(phase), -AMPLITUDE * FREQUENCY**2 * jnp.sin(phase)


@dataclasses.dataclass(frozen=True)
class Filtered:
    time: np.ndarray
    phi0_f: np.ndarray
    phi_f: np.ndarray


def _estimator_along(estimator: ParameterEstimator, joints: int, step: float, steps: int) -> tuple[Filtered, Filtered]:
    """phi0_f, phi_f of the estimator fed the analytic trajectory (first ``joints`` joints), RK4;
    as built, and with the q'(0) e^{-a t} term E dropped (E(0) = 0), in one compilation."""

    def measurement(t):
        q, qdot, _ = _trajectory(t)
        return jnp.concatenate([q[:joints], qdot[:joints]])

    @jax.jit
    @jax.vmap
    def run(keep):
        state = estimator.init(measurement(0.0), jnp.ones(estimator.parameters.size))
        state = dataclasses.replace(state, transient=keep * state.transient)

        def one(state, k):
            t = k * step
            new = rk4_step(lambda time, s: estimator.vector_field(time, s, measurement(time), jnp.zeros(joints)), t, state, step)
            return new, estimator.filtered_regressors(new, measurement(t + step))

        _, (phi0_f, phi_f) = jax.lax.scan(one, state, jnp.arange(steps))
        return phi0_f, phi_f

    phi0_f, phi_f = (np.asarray(part) for part in run(jnp.array([1.0, 0.0])))
    time = step * np.arange(1, steps + 1)
    return Filtered(time, phi0_f[0], phi_f[0]), Filtered(time, phi0_f[1], phi_f[1])


def _direct_filter(parameters, joints: int, pole: float, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x' = -pole x + [phi0, phi](q, q', q'') with the exact q'' of the trajectory, solve_ivp at 1e-12."""
    split = jax.jit(lambda t: parameters.split(*(part[:joints] for part in _trajectory(t))))
    n, p = joints, parameters.size

    def field(t, x):
        phi0, phi = split(t)
        return -pole * x + np.concatenate([np.asarray(phi0), np.asarray(phi).ravel()])

    solution = solve_ivp(field, (0.0, times[-1]), np.zeros(n + n * p), t_eval=times, rtol=1e-12, atol=1e-13, method="DOP853")
    x = solution.y.T
    return x[:, :n], x[:, n:].reshape(-1, n, p)


@pytest.mark.parametrize(
    "parameters, joints, pole",
    [(MASS, 1, 1.0), (ARM_MASSES, 2, 2.5)],
    ids=["pendulum m, 1/(s+1)", "two-link m1 m2, 1/(s+2.5)"],
)
def test_the_filtered_regressor_is_the_filter_of_the_regressor_with_the_true_acceleration(parameters, joints, pole):
    """phi_f from q and q' alone (A q' - a W - E + R) equals 1/(s + a) applied to
    phi(q, q', q'') with the exact q'': on the pendulum this is the filtered-acceleration
    identity 1/(s+1) q'' = q' - q'_f - q'(0) e^{-t} (times l^2); on the two-link arm A(q)
    depends on q, which the A' q' term accounts for."""
    estimator = ParameterEstimator(parameters, 1.0, filter_pole=pole)
    step, steps = 1e-3, 4000
    mine, dropped = _estimator_along(estimator, joints, step, steps)
    picks = np.arange(99, steps, 100)
    phi0_ref, phi_ref = _direct_filter(parameters, joints, pole, mine.time[picks])
    scale = np.abs(phi_ref).max()
    assert scale > 1.0
    # RK4 at 1 ms against DOP853 at 1e-12: the difference is RK4's global error, O(step^4)
    np.testing.assert_allclose(mine.phi_f[picks], phi_ref, atol=1e-9 * scale)
    np.testing.assert_allclose(mine.phi0_f[picks], phi0_ref, atol=1e-9 * max(scale, np.abs(phi0_ref).max()))
    # without the q'(0) e^{-a t} term (zero initial filter state alone) the identity fails at the start
    assert np.abs(dropped.phi_f[99] - phi_ref[0]).max() > 1e-2 * scale


def _free_swing(estimator: ParameterEstimator, duration: float = 10.0, step: float = 1e-3):
    """The pendulum unforced from q = 1 rad, q' = 0.8 rad/s, integrated jointly with the
    estimator (RK4): as built, and with the q'(0) e^{-a t} term dropped, in one compilation."""
    plant = ManipulatorPlant(PENDULUM)
    sensor = JointStateSensor(PENDULUM, sample_period=step)

    @jax.jit
    @jax.vmap
    def run(keep):
        x0 = plant.state(1.0, 0.8)
        s0 = estimator.init(sensor.ideal(x0), jnp.array([1.0]))
        s0 = dataclasses.replace(s0, transient=keep * s0.transient)
        zero = jnp.zeros(1)

        def field(t, pair):
            x, s = pair
            return plant.vector_field(t, x, zero, zero), estimator.vector_field(t, s, sensor.ideal(x), zero)

        def one(pair, k):
            pair = rk4_step(field, k * step, pair, step)
            return pair, (pair[1].theta[0], estimator.filtered_regressors(pair[1], sensor.ideal(pair[0]))[1][0, 0], pair[0].q[0])

        _, records = jax.lax.scan(one, (x0, s0), jnp.arange(int(round(duration / step))))
        return records

    records = [np.asarray(r) for r in run(jnp.array([1.0, 0.0]))]
    return [r[0] for r in records], [r[1] for r in records]


def test_no_excitation_in_a_free_swing_leaves_the_mass_estimate_alone():
    """Unforced, m (l^2 q'' + g l sin q) = 0, so phi = 0 along the motion although the
    pendulum swings: phi_f = 0 and m_hat stays at m_hat(0). Only with the q'(0) e^{-t}
    term: without it phi_f = l^2 q'(0) e^{-t} and m_hat moves."""
    estimator = ParameterEstimator(MASS, 10.0)
    (mass, phi_f, angle), (dropped_mass, dropped_phi_f, _) = _free_swing(estimator)
    assert np.abs(angle).max() > 0.9  # it swings
    assert np.abs(phi_f).max() < 1e-9  # RK4 error only
    assert np.abs(mass - 1.0).max() < 1e-12
    assert abs(dropped_phi_f[0] - 1.5**2 * 0.8) < 0.01  # l^2 q'(0) e^{-t} at t = 1 ms
    assert np.abs(dropped_mass - 1.0).max() > 0.1


@settings(max_examples=25)
@given(
    seed=st.integers(0, 2**31 - 1),
    gain=st.floats(0.1, 1e3),
)
def test_v_decreases_at_rate_h_e_squared_whatever_the_state(seed, gain):
    """Lyapunov (3.10)-(3.11): with theta constant and tau_f consistent with it
    (tau_f = phi0_f + phi_f theta, as filtering tau = phi0 + phi theta gives),
    V = 1/2 |theta~|^2 has V' = -theta~ . theta_hat' = -h |phi_f theta~|^2 <= 0,
    at any measurement and filter state (two-link arm, two masses)."""
    rng = np.random.default_rng(seed)
    v_rate, bound = _lyapunov_rate(
        *(jnp.asarray(rng.normal(size=shape)) for shape in ((2,), (2,), (2, 3), (2, 3), (2, 3), (4,))),
        jnp.asarray(gain),
        jnp.asarray(rng.uniform(0.3, 3.0, 2)),
    )
    assert float(v_rate) <= 0.0
    np.testing.assert_allclose(float(v_rate), -float(bound), rtol=1e-9, atol=1e-12 * float(bound) + 1e-300)


@jax.jit
def _lyapunov_rate(theta_hat, _, inertial, remainder, transient, y, gain, theta):
    estimator = ParameterEstimator(ARM_MASSES, gain)
    state = ParameterEstimatorState(theta_hat, jnp.zeros(2), inertial, remainder, transient, y)
    phi0_f, phi_f = estimator.filtered_regressors(state, y)
    state = dataclasses.replace(state, torque=phi0_f + phi_f @ theta)
    rate = estimator.vector_field(0.0, state, y, jnp.zeros(2)).theta
    error = theta - theta_hat
    return -error @ rate, gain * jnp.sum((phi_f @ error) ** 2)


@pytest.mark.slow
def test_missing_measurements_hold_the_estimate_and_keep_it_finite():
    """Sampled operation with 30 % dropouts on every channel (q and q'): theta_hat is
    finite throughout and does not change over a sample whose measurement has a NaN."""
    parameters = PendulumInertia(FreePendulum(1.0, 1.5, 0.0))
    plant = ScheduledParameterPlant(parameters, parameters.reference)
    sensor = JointStateSensor(plant.parameters.model(parameters.reference), sample_period=2e-3, dropout_probability=0.3)
    estimator = ParameterEstimator(parameters, 100.0)
    scenario = Scenario(
        plant,
        sensor,
        estimator,
        SinusoidalInput(5.0, 1.0),
        plant.state(0.0, 0.0),
        jnp.array([4.5, 2.0]),
        plant_step=2e-3,
        sample_period=2e-3,
        duration=10.0,
    )
    ds = simulate(scenario, jax.random.key(3)).to_xarray()
    theta = estimator.estimates(ds)
    y = np.column_stack([ds.measured_joint_angle.isel(run=0).values, ds.measured_joint_rate.isel(run=0).values])
    missing = ~np.all(np.isfinite(y), axis=1)
    assert 0.3 < missing.mean() < 0.7  # 1 - 0.7^2 of the samples miss a channel
    assert np.all(np.isfinite(theta))
    held = missing[:-1]
    np.testing.assert_array_equal(theta[1:][held], theta[:-1][held])
    assert np.abs(theta[-1] - np.asarray(parameters.reference)).max() < np.abs(theta[0] - np.asarray(parameters.reference)).max()
    # directly: an all-NaN measurement gives a finite derivative and no adaptation
    state = estimator.init(jnp.array([0.2, 0.1]), jnp.array([4.5, 2.0]))
    rate = estimator.vector_field(0.0, state, jnp.full(2, jnp.nan), jnp.ones(1))
    assert all(bool(jnp.all(jnp.isfinite(leaf))) for leaf in jax.tree.leaves(rate))
    assert float(jnp.abs(rate.theta).max()) == 0.0


def test_windowed_excitation_of_known_regressors():
    """phi_f = [sin t, cos t] (one joint, two parameters): never rank 2 at an instant,
    yet int over a period is pi I, so lambda_min = pi for a 2 pi window; a constant
    phi_f = [1, 1] is never persistently exciting (lambda_min = 0)."""
    time = np.linspace(0.0, 20 * np.pi, 20001)
    step = time[1] - time[0]
    window = 2000 * step  # 2 pi
    phi = np.stack([np.sin(time), np.cos(time)], axis=-1)[:, None, :]
    ends, lam = windowed_excitation(time, phi, window)
    assert ends[0] == pytest.approx(window)
    np.testing.assert_allclose(lam, np.pi, rtol=1e-5)
    _, lam = windowed_excitation(time, np.ones((time.size, 1, 2)), window)
    assert np.abs(lam).max() < 1e-9
    with pytest.raises(ValueError, match="^window must be a positive whole number of sample intervals"):
        windowed_excitation(time, phi, 1.5 * step)
    with pytest.raises(ValueError, match="^window must be at most the span"):
        windowed_excitation(time, phi, 30000 * step)


def test_bad_settings_are_refused_with_one_line():
    with pytest.raises(ValueError, match=r"^parameter estimator gain must be positive"):
        ParameterEstimator(MASS, 0.0)
    with pytest.raises(ValueError, match=r"^parameter estimator gain must be a scalar or have 2 entries"):
        ParameterEstimator(ARM_MASSES, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"^filter_pole must be positive"):
        ParameterEstimator(MASS, 1.0, filter_pole=-1.0)
    with pytest.raises(ValueError, match=r"^filter_pole must be finite"):
        ParameterEstimator(MASS, 1.0, filter_pole=np.nan)
    with pytest.raises(ValueError, match=r"^parameters.units must give every parameter's unit"):
        ParameterEstimator(ModelParameters(PENDULUM, ("mass",)), 1.0)
    with pytest.raises(ValueError, match=r"^the initial estimate theta_hat\(0\) must be a scalar or have 2 entries"):
        ParameterEstimator(ARM_MASSES, 1.0).init(jnp.zeros(4), jnp.ones(3))
    with pytest.raises(ValueError, match=r"^switch_times must be strictly increasing"):
        ScheduledParameterPlant(MASS, [[1.0], [2.0], [3.0]], [5.0, 5.0])
    with pytest.raises(ValueError, match=r"^joint state sensor dropout_probability must be in \[0, 1\)"):
        JointStateSensor(PENDULUM, sample_period=0.01, dropout_probability=1.0)


def test_the_scheduled_plant_switches_its_parameters_and_records_them():
    plant = ScheduledParameterPlant(MASS, [[2.0], [3.0]], [1.0])
    x = JointState(jnp.array([0.5]), jnp.array([0.0]))
    before = plant.vector_field(0.999, x, jnp.zeros(1), jnp.zeros(1)).qdot
    after = plant.vector_field(1.0, x, jnp.zeros(1), jnp.zeros(1)).qdot
    # unforced, q'' = -(g/l) sin q whatever the mass; with a torque, q'' = tau / (m l^2) - ...
    np.testing.assert_allclose(before, after, rtol=1e-14)
    forced = [float(plant.vector_field(t, x, jnp.ones(1), jnp.zeros(1)).qdot[0] - before[0]) for t in (0.5, 1.5)]
    np.testing.assert_allclose(forced, [1 / (2.0 * 1.5**2), 1 / (3.0 * 1.5**2)], rtol=1e-12)
    np.testing.assert_array_equal(plant.truth([0.0, 0.999, 1.0, 2.0])["mass"], [2.0, 2.0, 3.0, 3.0])
