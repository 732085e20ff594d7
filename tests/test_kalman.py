"""The extended and unscented Kalman filters (lookout.observers.ekf, .ukf) against
references: an exact Kalman filter on a linear plant (the discrete model and the
Riccati recursion written here), filterpy's ExtendedKalmanFilter on the DP vessel,
and the masking of missing channels against a filter that is never given them."""

from __future__ import annotations

import copy
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout.components import Layout, Plant, Sensor, Signal
from lookout.observers.ekf import ExtendedKalmanFilter
from lookout.observers.ukf import UnscentedKalmanFilter
from lookout.scenario.composition import compose

# ------------------------------------------------------------------ a linear plant

A = np.array([[0.0, 1.0], [-0.4, -0.3]])
B = np.array([[0.0], [1.0]])
G = np.array([[0.0], [0.5]])
C = np.array([[1.0, 0.0]])
NOISE_STD = 0.2
STEP, SAMPLE = 0.05, 0.2  # four RK4 steps per sample


class LinearPlant(Plant):
    """x' = A x + B u + G w."""

    input_layout: Layout = eqx.field(static=True, default=Layout((Signal("force", "N", "force"),)))
    noise_size: int = eqx.field(static=True, default=1)
    variable_signals: tuple = eqx.field(static=True, default=(Signal("state", "1", "state", labels=("position", "rate"), dim="linear_axis"),))

    def vector_field(self, t, x, u, w):
        return jnp.asarray(A) @ x + jnp.asarray(B) @ u + jnp.asarray(G) @ w

    def normalize(self, x):
        return x

    def variables(self, x):
        return {"state": x}

    def realize(self, key):
        return self

    def state(self, position=0.0, rate=0.0):
        return jnp.asarray([position, rate], dtype=float)

    def models(self):
        return ()


class LinearSensor(Sensor):
    """y = C x + v, v ~ N(0, NOISE_STD^2)."""

    measurement_layout: Layout = eqx.field(static=True, default=Layout((Signal("measured_position", "1", "measured position"),)))
    sample_period: tuple = eqx.field(static=True, default=(SAMPLE,))
    noise_size: int = eqx.field(static=True, default=1)

    def measure(self, x, normals):
        return jnp.asarray(C) @ x + NOISE_STD * normals

    def ideal(self, x):
        return jnp.asarray(C) @ x


def _discrete_model():
    """The RK4 discretization of x' = A x + B u + G w over one sample, w held over
    each step with variance 1/STEP: x+ = T^n x + (sum T^k) V_u u, Q = sum T^k V V^T T^k' / STEP."""
    h = STEP
    Ah = A * h
    T = np.eye(2) + Ah + Ah @ Ah / 2 + Ah @ Ah @ Ah / 6 + Ah @ Ah @ Ah @ Ah / 24
    V = h * (np.eye(2) + Ah / 2 + Ah @ Ah / 6 + Ah @ Ah @ Ah / 24)
    n = round(SAMPLE / STEP)
    F = np.linalg.matrix_power(T, n)
    Bd = sum(np.linalg.matrix_power(T, k) for k in range(n)) @ V @ B
    Q = sum(np.linalg.matrix_power(T, k) @ V @ G @ G.T @ V.T @ np.linalg.matrix_power(T, k).T for k in range(n)) / h
    return F, Bd, Q


def _drive(filter_, ys, us, guess, dt=SAMPLE):
    """Step a filter through samples ``ys`` with inputs ``us``: (posterior means, covariances)."""
    update = eqx.filter_jit(lambda f, s, t, y: f.update(s, t, y))
    predict = eqx.filter_jit(lambda f, s, t, y, u: f.predict(s, t, y, u, dt))
    state = filter_.init(ys[0], guess)
    means, covariances = [], []
    for k, (y, u) in enumerate(zip(ys, us)):
        t = jnp.asarray(k * dt)  # an array: one compiled update for every sample
        state = update(filter_, state, t, jnp.asarray(y))
        means.append(np.asarray(state.mean))
        covariances.append(np.asarray(state.covariance))
        state = predict(filter_, state, t, jnp.asarray(y), jnp.asarray(u))
    return np.asarray(means), np.asarray(covariances)


def _kalman(ys, us, x0, P0):
    """The exact Kalman filter of the discrete model (the Riccati recursion, Joseph form)."""
    F, Bd, Q = _discrete_model()
    R = np.array([[NOISE_STD**2]])
    x, P = x0.copy(), P0.copy()
    means, covariances = [], []
    for y, u in zip(ys, us):
        if np.all(np.isfinite(y)):
            S = C @ P @ C.T + R
            K = P @ C.T @ np.linalg.inv(S)
            x = x + K @ (y - C @ x)
            I_KH = np.eye(2) - K @ C
            P = I_KH @ P @ I_KH.T + K @ R @ K.T
        means.append(x.copy())
        covariances.append(P.copy())
        x = F @ x + Bd @ u
        P = F @ P @ F.T + Q
    return np.asarray(means), np.asarray(covariances)


def _linear_data(samples=60, seed=1):
    rng = np.random.default_rng(seed)
    us = np.sin(0.3 * np.arange(samples))[:, None]
    x = np.array([1.0, 0.0])
    F, Bd, Q = _discrete_model()
    ys = []
    for u in us:
        ys.append(C @ x + NOISE_STD * rng.standard_normal(1))
        x = F @ x + Bd @ u + np.linalg.cholesky(Q + 1e-18 * np.eye(2)) @ rng.standard_normal(2)
    return np.asarray(ys), us


@pytest.mark.parametrize("kind", [ExtendedKalmanFilter, UnscentedKalmanFilter])
def test_on_a_linear_plant_the_filters_are_the_exact_kalman_filter(kind):
    ys, us = _linear_data()
    ys[7] = np.nan  # a dropout: the exact filter skips the correction
    P0 = np.diag([4.0, 1.0])
    filter_ = kind(LinearPlant(), LinearSensor(), initial_std=[2.0, 1.0], plant_step=STEP, filter_period=SAMPLE)
    means, covariances = _drive(filter_, ys, us, filter_.guess(position=0.5))
    expected_means, expected_covariances = _kalman(ys, us, np.array([0.5, 0.0]), P0)
    tolerance = 1e-10 if kind is ExtendedKalmanFilter else 1e-8
    np.testing.assert_allclose(means, expected_means, rtol=0, atol=tolerance)
    np.testing.assert_allclose(covariances, expected_covariances, rtol=0, atol=tolerance)


def test_the_defaults_are_the_sensor_noise_and_the_steady_state_covariance():
    filter_ = ExtendedKalmanFilter(LinearPlant(), LinearSensor(), plant_step=STEP, filter_period=SAMPLE)
    np.testing.assert_allclose(np.asarray(filter_.measurement_covariance), [[NOISE_STD**2]], rtol=1e-14)
    # P_0 is the prior of the steady-state filter: a fixed point of predict after correct
    F, _, Q = _discrete_model()
    P = np.asarray(filter_.initial_covariance)
    R = NOISE_STD**2
    K = P @ C.T / (C @ P @ C.T + R)
    posterior = (np.eye(2) - K @ C) @ P
    np.testing.assert_allclose(F @ posterior @ F.T + Q, P, rtol=1e-9)


def test_a_sample_with_every_channel_missing_leaves_the_covariance_to_the_propagation():
    filter_ = ExtendedKalmanFilter(LinearPlant(), LinearSensor(), initial_std=[1.0, 1.0], plant_step=STEP, filter_period=SAMPLE)
    state = filter_.init(jnp.asarray([np.nan]), filter_.guess())
    corrected = filter_.update(state, 0.0, jnp.asarray([np.nan]))
    np.testing.assert_array_equal(np.asarray(corrected.covariance), np.asarray(state.covariance))
    np.testing.assert_array_equal(np.asarray(corrected.mean), np.asarray(state.mean))
    F, _, Q = _discrete_model()
    propagated = filter_.predict(corrected, 0.0, jnp.asarray([np.nan]), jnp.zeros(1), SAMPLE)
    np.testing.assert_allclose(np.asarray(propagated.covariance), F @ np.eye(2) @ F.T + Q, rtol=1e-12)


def test_a_held_sample_is_not_a_new_measurement():
    """A channel whose period is longer than the observer's is corrected on only when
    it is due: between its samples the engine holds the last value."""
    slow = LinearSensor(sample_period=(2 * SAMPLE,))
    filter_ = ExtendedKalmanFilter(LinearPlant(), slow, initial_std=[1.0, 1.0], plant_step=STEP, filter_period=SAMPLE)
    state = filter_.init(jnp.asarray([1.0]), filter_.guess())
    assert np.asarray(filter_.due(2 * SAMPLE)).all() and not np.asarray(filter_.due(SAMPLE)).any()
    held = filter_.update(state, SAMPLE, jnp.asarray([1.0]))
    np.testing.assert_array_equal(np.asarray(held.mean), np.asarray(state.mean))


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"measurement_noise": [0.0]}, "measurement_noise must be 1 finite standard deviations > 0"),
        ({"process_noise": [1.0, 2.0]}, "process_noise must have 1 entries (one per noise input of the plant), or be one number for all; got 2"),
        ({"initial_std": [1.0]}, "initial_std must have one entry per state entry (2)"),
        ({"initial_std": {"position": 1.0, "speed": 2.0}}, "initial_std: the plant's state has no part 'speed' (its parts: position, rate)"),
        ({"state_noise": [-1.0, 0.0]}, "state_noise must be finite and >= 0"),
        ({"plant_step": -0.1}, "plant_step"),
        ({"integrator": "rk45"}, "integrator must be one of rk4, euler"),
    ],
)
def test_bad_arguments_are_one_line_naming_them(changes, message):
    arguments = {"initial_std": [1.0, 1.0], "plant_step": STEP, "filter_period": SAMPLE, **changes}
    with pytest.raises(ValueError) as error:
        ExtendedKalmanFilter(LinearPlant(), LinearSensor(), **arguments)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_a_noiseless_sensor_needs_its_measurement_noise():
    quiet = _QuietSensor()
    with pytest.raises(ValueError, match="measurement_noise: the sensor's own noise is zero on measured_position"):
        ExtendedKalmanFilter(LinearPlant(), quiet, initial_std=[1.0, 1.0], plant_step=STEP, filter_period=SAMPLE)


class _QuietSensor(Sensor):
    measurement_layout: Layout = eqx.field(static=True, default=Layout((Signal("measured_position", "1", "measured position"),)))
    sample_period: tuple = eqx.field(static=True, default=(SAMPLE,))
    noise_size: int = eqx.field(static=True, default=1)

    def measure(self, x, normals):
        return jnp.asarray(C) @ x + 0.0 * normals

    def ideal(self, x):
        return jnp.asarray(C) @ x


# ------------------------------------------------------------------ the DP vessel against filterpy


def _vessel(heading=0.0, yaw_rate=0.0):
    """The DP vessel without waves (Northern Clipper, bias, 1 Hz fixes at a 0.5 s observer)."""
    document = {
        "simulation": {"plant_step": 0.25, "sample_period": 0.5, "duration": 60.0},
        "plant": {
            "kind": "dp-vessel",
            "vessel": {"kind": "northern-clipper"},
            "bias": {"kind": "gauss-markov", "time_constant": [1000.0, 1000.0, 1000.0], "std": [2000.0, 2000.0, 50000.0]},
            "waves": {"kind": "linear", "peak_frequency": 0.8, "damping_ratio": 0.1, "amplitude": [0.0, 0.0, 0.0]},
            "initial": {"eta": [0.0, 0.0, heading], "nu": [1.0, 0.2, yaw_rate], "bias": [1e4, 5e3, 1e5]},
        },
        "sensor": {"kind": "position-heading", "noise_std": [0.5, 0.5, 0.002], "sample_period": 1.0},
        "observer": {"kind": "passive"},
    }
    return compose(document).scenario


def _vessel_samples(scenario, samples, seed=3):
    from lookout.sim import keys_of_seeds, simulate

    trajectory = simulate(scenario, keys_of_seeds([seed])[0])
    return np.array(trajectory.measurement)[:samples], np.array(trajectory.applied)[:samples]


@pytest.mark.slow
def test_on_the_vessel_the_ekf_equals_filterpy_driven_with_the_same_model():
    import filterpy.kalman as filterpy  # a test extra (pyproject: dev): the test fails, not skips, without it

    scenario = _vessel(heading=0.3, yaw_rate=0.01)
    dt = scenario.sample_period
    std = {"eta": [5.0, 5.0, 0.05], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [1e-3] * 6}
    ekf = ExtendedKalmanFilter(scenario.plant, scenario.sensor, initial_std=std, plant_step=scenario.plant_step, filter_period=dt)
    ys, us = _vessel_samples(scenario, 50)
    ys[20:30] = np.nan  # a 5 s outage of every channel
    ys[41, 2] = np.nan  # one heading fix lost, the position kept
    guess = ekf.guess(eta=[1.0, -1.0, 0.25])
    means, covariances = _drive(ekf, ys, us, guess, dt)

    # the same model for filterpy: the step, its Jacobian, Q_d (separately computed), h and H
    model = jax.jit(lambda x, u: (ekf.step(x, 0.0, u, dt), jax.jacfwd(lambda z: ekf.step(z, 0.0, u, dt))(x), ekf.process_covariance(x, 0.0, u, dt)))
    observe = jax.jit(lambda x: (ekf.measurement(x), jax.jacfwd(lambda z: ekf.measurement(z))(x)))
    measure = lambda x: observe(x)[0]  # noqa: E731
    measure_jacobian = lambda x: observe(x)[1]  # noqa: E731
    R = np.asarray(ekf.measurement_covariance)
    n = means.shape[1]
    reference = filterpy.ExtendedKalmanFilter(dim_x=n, dim_z=3)
    reference.x = np.array(ekf._ravel(guess))
    reference.P = np.asarray(ekf.initial_covariance)
    expected = []
    for k, (y, u) in enumerate(zip(ys, us)):
        fresh = np.isfinite(y) & (k * dt % 1.0 < 1e-9)
        if fresh.any():
            rows = np.flatnonzero(fresh)
            residual = lambda a, b, rows=rows: np.where(rows == 2, (a - b + math.pi) % (2 * math.pi) - math.pi, a - b)
            reference.update(
                y[rows],
                lambda x, rows=rows: np.asarray(measure_jacobian(x))[rows],
                lambda x, rows=rows: np.asarray(measure(x))[rows],
                R=R[np.ix_(rows, rows)],
                residual=residual,
            )
            reference.x[2] = (reference.x[2] + math.pi) % (2 * math.pi) - math.pi
        expected.append((reference.x.copy(), reference.P.copy()))
        x = reference.x.copy()
        stepped, F, Q = (np.array(a) for a in model(x, u))
        reference.F, reference.Q = F, Q
        reference.P = reference.F @ reference.P @ reference.F.T + reference.Q
        reference.x = stepped
        reference.x[2] = (reference.x[2] + math.pi) % (2 * math.pi) - math.pi
    expected_means = np.asarray([m for m, _ in expected])
    expected_covariances = np.asarray([P for _, P in expected])
    scale = np.sqrt(np.diag(expected_covariances[-1]))
    np.testing.assert_allclose(means / scale, expected_means / scale, rtol=0, atol=1e-8)
    np.testing.assert_allclose(covariances / np.outer(scale, scale), expected_covariances / np.outer(scale, scale), rtol=0, atol=1e-8)
    # during the outage the covariance only grows
    position_variance = covariances[:, 0, 0]
    assert np.all(np.diff(position_variance[20:30]) > 0)


@pytest.mark.slow
def test_the_ukf_follows_a_heading_through_plus_minus_pi_without_a_jump():
    scenario = _vessel(heading=math.pi - 0.05, yaw_rate=0.01)
    # a heading guess 0.3 rad off with that uncertainty: the sigma points straddle +-pi
    std = {"eta": [2.0, 2.0, 0.3], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [1e-3] * 6}
    ukf = UnscentedKalmanFilter(
        scenario.plant, scenario.sensor, initial_std=std, plant_step=scenario.plant_step, filter_period=scenario.sample_period
    )
    from lookout.sim import Scenario, keys_of_seeds, simulate

    run = Scenario(
        plant=scenario.plant,
        sensor=scenario.sensor,
        observer=ukf,
        controller=scenario.controller,
        reference=scenario.reference,
        actuator=scenario.actuator,
        initial_state=scenario.initial_state,
        initial_estimate=ukf.guess(eta=[0.0, 0.0, math.pi - 0.35], nu=[1.0, 0.2, 0.01], bias=[1e4, 5e3, 1e5]),
        plant_step=scenario.plant_step,
        sample_period=scenario.sample_period,
        duration=20.0,
    )

    def worst_error(observer):
        ds = simulate(eqx.tree_at(lambda s: s.observer, run, observer), keys_of_seeds([0])[0]).to_xarray()
        heading, estimate = ds.heading.values, ds.heading_hat.values
        assert heading.min() < -math.pi + 0.3 and heading.max() > math.pi - 0.1  # the truth wrapped through +-pi
        return np.abs((estimate - heading + math.pi) % (2 * math.pi) - math.pi).max()

    assert worst_error(ukf) < 0.01
    # the same filter averaging headings as plain numbers loses the heading at the wrap
    naive = copy.copy(ukf)
    object.__setattr__(naive, "channel_angles", (False,) * 3)  # static fields: set on a copy
    object.__setattr__(naive, "state_angles", (False,) * len(ukf.state_angles))
    assert worst_error(naive) > 0.3  # measured 0.50 rad, and it stays


def test_a_composition_gives_the_filter_its_plant_steps_and_a_table_of_state_parts():
    from lookout.scenario._toml import read
    from lookout.scenario.composition import CompositionError

    document, _ = read("examples/dp-observer.toml")
    std = {"eta": [5.0, 5.0, 0.05], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [1.0, 1.0, 0.01, 1.0, 1.0, 0.01]}
    document["observer"] = {"kind": "ukf", "initial_std": std, "initial": {"bias": [1e4, 5e3, 1e5]}}
    composition = compose(document)
    ukf = composition.scenario.observer
    assert ukf.plant_step == document["simulation"]["plant_step"] and ukf.integrator == "rk4"
    np.testing.assert_allclose(np.sqrt(np.diag(np.asarray(ukf.initial_covariance)))[6:9], std["bias"])
    np.testing.assert_array_equal(np.asarray(composition.scenario.initial_estimate.bias), [1e4, 5e3, 1e5])
    document["observer"]["initial_std"] = {"eta": [5.0, 5.0, 0.05], "speed": [1.0]}
    with pytest.raises(
        CompositionError, match=r"observer.initial_std: .*the plant's state has no part 'speed' \(its parts: eta, nu, bias, wave_state\)"
    ):
        compose(document)


# ------------------------------------------------------------------ an unknown input disturbance


@pytest.mark.parametrize("kind", [ExtendedKalmanFilter, UnscentedKalmanFilter])
def test_an_input_disturbance_is_the_exact_kalman_filter_of_the_augmented_model(kind):
    """With ``input_disturbance`` the state is [x, d], x driven by u + d and d a random
    walk: the exact Kalman filter of that augmented discrete model (written here)."""
    intensity = 0.3
    F, Bd, Q = _discrete_model()
    Fa = np.block([[F, Bd], [np.zeros((1, 2)), np.eye(1)]])
    Qa = np.block([[Q, np.zeros((2, 1))], [np.zeros((1, 2)), intensity * SAMPLE * np.eye(1)]])
    Ca = np.hstack([C, np.zeros((1, 1))])
    R = np.array([[NOISE_STD**2]])
    ys, us = _linear_data()
    ys = ys + 0.5  # an offset the disturbance explains
    ys[7] = np.nan
    filter_ = kind(LinearPlant(), LinearSensor(), initial_std=[2.0, 1.0, 1.5], input_disturbance=[intensity], plant_step=STEP, filter_period=SAMPLE)
    means, covariances = _drive(filter_, ys, us, filter_.guess(position=0.5))
    x, P = np.array([0.5, 0.0, 0.0]), np.diag([4.0, 1.0, 2.25])
    expected_means, expected_covariances = [], []
    for y, u in zip(ys, us):
        if np.all(np.isfinite(y)):
            K = P @ Ca.T @ np.linalg.inv(Ca @ P @ Ca.T + R)
            x = x + K @ (y - Ca @ x)
            I_KH = np.eye(3) - K @ Ca
            P = I_KH @ P @ I_KH.T + K @ R @ K.T
        expected_means.append(x.copy())
        expected_covariances.append(P.copy())
        x = Fa @ x + np.concatenate([Bd @ u, [0.0]])
        P = Fa @ P @ Fa.T + Qa
    tolerance = 1e-10 if kind is ExtendedKalmanFilter else 1e-8
    np.testing.assert_allclose(means, expected_means, rtol=0, atol=tolerance)
    np.testing.assert_allclose(covariances, expected_covariances, rtol=0, atol=tolerance)
    # and it is recorded as the input's disturbance
    assert [s.name for s in filter_.extra_signals] == ["disturbance_force"]
    output = filter_.output(filter_.init(ys[0], filter_.guess()), ys[0])
    assert set(output) == {"state", "disturbance_force"}


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"input_disturbance": [-1.0]}, "input_disturbance must be 1 finite intensities >= 0"),
        ({"input_disturbance": [1.0, 1.0]}, "input_disturbance must be 1 finite intensities >= 0"),
        (
            {"initial_std": {"position": 1.0, "rate": 1.0, "input_disturbance": [1.0, 2.0]}},
            "initial_std: input_disturbance must have one entry per input entry (1)",
        ),
        (
            {"initial_std": {"position": 1.0, "wave": 1.0, "input_disturbance": 1.0}},
            "initial_std: the plant's state has no part 'wave' (its parts: position, rate, and input_disturbance)",
        ),
        ({"initial_std": [1.0, 1.0]}, "initial_std must have one entry per state entry (3: the plant's and the input disturbance's)"),
        ({"initial_std": {"position": 1.0, "rate": 1.0}}, "initial_std: give input_disturbance too"),
    ],
)
def test_bad_disturbance_arguments_are_one_line_naming_them(changes, message):
    arguments = {"initial_std": [1.0, 1.0, 1.0], "input_disturbance": [0.1], "plant_step": STEP, "filter_period": SAMPLE, **changes}
    with pytest.raises(ValueError) as error:
        ExtendedKalmanFilter(LinearPlant(), LinearSensor(), **arguments)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_a_filter_may_have_a_plant_model_of_its_own():
    """``[observer.plant]``: the filter's model differs from the truth (a model error),
    built from its table alone; the composition's plant is unchanged."""
    from lookout.scenario._toml import read
    from lookout.scenario.composition import CompositionError

    document, _ = read("examples/dp-observer.toml")
    model = copy.deepcopy(document["plant"])
    model.pop("initial")
    model["vessel"]["mass_scale"] = 1.2
    document["observer"] = {"kind": "ekf", "plant": model}
    composition = compose(document)
    scenario = composition.scenario
    np.testing.assert_array_equal(np.asarray(scenario.observer.model.vessel.mass_matrix), 1.2 * np.asarray(scenario.plant.vessel.mass_matrix))
    assert composition.document["observer"]["plant"]["vessel"]["mass_scale"] == 1.2
    document["observer"]["plant"]["vessel"]["mass_scale"] = -1.0
    with pytest.raises(CompositionError, match=r"^observer.plant.vessel.mass_scale: "):
        compose(document)
