"""Manipulator models of Calugi (2002), chapter 2: properties, printed matrices, energy,
the plant's signals and the joint encoder."""

import math
from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lookout.models.manipulators import (
    JOINT_POSITION,
    CartPendulum,
    FreePendulum,
    FurutaPendulum,
    JointState,
    ManipulatorModel,
    ManipulatorPlant,
    TwoLinkArm,
    joint_layout,
)
from lookout.sensors import JointEncoder
from lookout.sim.integrators import rk4_step

G = 9.81
MODELS = {"pendulum": FreePendulum(), "two_link": TwoLinkArm(), "cart": CartPendulum(), "furuta": FurutaPendulum()}
NAMES = list(MODELS)

# --- the C(q, q') matrices as printed in Section 2.3, friction included, with the printed numbers


def printed_c_pendulum(q, v):
    return np.array([[0.1]])


def printed_c_two_link(q, v):
    m2, l1, l2, c1, c2 = 0.7, 1.0, 1.5, 0.5, 0.1
    h = m2 * l1 * l2 * np.sin(q[1])
    return np.array([[c1 - 2 * h * v[1], -h * v[1]], [h * v[0], c2]])


def printed_c_cart(q, v):
    m2, l, c1, c2 = 0.2, 0.5, 0.4, 0.1
    return np.array([[c1, -m2 * l * np.sin(q[1]) * v[1]], [0.0, c2]])


def printed_c_furuta(q, v):
    m2, m3, l1, l2, c1, c2 = 0.1, 0.5, 0.7, 0.5, 0.4, 0.2
    beta, gamma = (m3 + m2 / 3) * l2**2, (m3 + m2 / 2) * l1 * l2
    s, c = np.sin(q[1]), np.cos(q[1])
    return np.array([[c1 + beta * c * s * v[1], beta * c * s * v[0] - gamma * s * v[1]], [-beta * c * s * v[0], c2]])


PRINTED_C = {"pendulum": printed_c_pendulum, "two_link": printed_c_two_link, "cart": printed_c_cart, "furuta": printed_c_furuta}


@eqx.filter_jit
def _mass(model, q):
    return model.mass_matrix(q)


@eqx.filter_jit
def _coriolis(model, q, v):
    return model.coriolis_matrix(q, v)


@eqx.filter_jit
def _mass_rate(model, q, v):
    return jax.jvp(model.mass_matrix, (q,), (v,))[1]


@eqx.filter_jit
def _measure_many(encoder, x, normals):
    return jax.vmap(lambda n: encoder.measure(x, n))(normals)


@eqx.filter_jit
def _potential_gradient(model, q):
    return model.gravity(q), jax.grad(model.potential_energy)(q)


def _vectors(data, n, count, bound=10.0):
    element = st.floats(-bound, bound, allow_nan=False)
    return [np.array(data.draw(st.lists(element, min_size=n, max_size=n))) for _ in range(count)]


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=30)
@given(data=st.data())
def test_mass_matrix_is_symmetric_positive_definite(name, data):
    """Property 2.1 at random configurations."""
    model = MODELS[name]
    (q,) = _vectors(data, model.size, 1, bound=20.0)
    M = np.asarray(_mass(model, jnp.asarray(q)))
    np.testing.assert_allclose(M, M.T, rtol=0, atol=1e-15)
    assert np.linalg.eigvalsh(M).min() > 0


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=30)
@given(data=st.data())
def test_mdot_minus_2c_is_skew_symmetric(name, data):
    """For the Christoffel C: M' - 2C skew, with M' = dM/dq q' by jax.jvp."""
    model = MODELS[name]
    q, v = (jnp.asarray(x) for x in _vectors(data, model.size, 2))
    N = np.asarray(_mass_rate(model, q, v) - 2.0 * _coriolis(model, q, v))
    np.testing.assert_allclose(N + N.T, 0.0, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=30)
@given(data=st.data())
def test_christoffel_c_satisfies_property_2_2(name, data):
    """C(q, a) b = C(q, b) a, used by the thesis in (2.9)."""
    model = MODELS[name]
    q, a, b = (jnp.asarray(x) for x in _vectors(data, model.size, 3))
    np.testing.assert_allclose(_coriolis(model, q, a) @ b, _coriolis(model, q, b) @ a, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=30)
@given(data=st.data())
def test_printed_c_gives_the_christoffel_forces_plus_friction(name, data):
    """The printed C(q, q') q' (friction inside) equals Christoffel C(q, q') q' + F q'."""
    model = MODELS[name]
    q, v = _vectors(data, model.size, 2)
    printed = PRINTED_C[name](q, v) @ v
    ours = np.asarray(_coriolis(model, jnp.asarray(q), jnp.asarray(v)) @ v + model.friction * v)
    np.testing.assert_allclose(ours, printed, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", ["pendulum", "cart", "furuta"])
def test_printed_c_matrices_of_pendulum_cart_and_furuta_are_christoffel_plus_friction(name):
    """As matrices, not only as products: only the two-link arm's printed C is another factorization."""
    model = MODELS[name]
    rng = np.random.default_rng(7)
    for _ in range(5):
        q, v = rng.uniform(-3, 3, (2, model.size))
        ours = np.asarray(_coriolis(model, jnp.asarray(q), jnp.asarray(v))) + np.diag(np.asarray(model.friction))
        np.testing.assert_allclose(ours, PRINTED_C[name](q, v), atol=1e-12)


def test_printed_two_link_c_violates_property_2_2_and_christoffel_c_is_the_closed_form():
    """NOTES.md: Property 2.2 fails for the printed two-link C; the code's C is the
    textbook Christoffel form C = h [[-q2', -(q1' + q2')], [q1', 0]], h = m2 l1 l2 sin q2."""
    q, a, b = np.array([0.3, 1.1]), np.array([1.0, 0.0]), np.array([0.0, 1.0])
    friction = np.diag([0.5, 0.1])
    printed_ab = (printed_c_two_link(q, a) - friction) @ b
    printed_ba = (printed_c_two_link(q, b) - friction) @ a
    assert np.abs(printed_ab - printed_ba).max() > 0.5  # -h vs -2h in the first row
    model = MODELS["two_link"]
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, v = rng.uniform(-3, 3, (2, 2))
        h = 0.7 * 1.0 * 1.5 * np.sin(q[1])
        closed = h * np.array([[-v[1], -(v[0] + v[1])], [v[0], 0.0]])
        np.testing.assert_allclose(np.asarray(_coriolis(model, jnp.asarray(q), jnp.asarray(v))), closed, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=30)
@given(data=st.data())
def test_gravity_is_the_gradient_of_the_potential_energy(name, data):
    """G(q) as printed equals dV/dq of the geometric potential energy."""
    model = MODELS[name]
    (q,) = _vectors(data, model.size, 1, bound=20.0)
    gravity, gradient = _potential_gradient(model, jnp.asarray(q))
    np.testing.assert_allclose(gravity, gradient, rtol=1e-12, atol=1e-12)


def test_printed_gravity_and_inertia_values():
    """Spot values from the printed formulas (n = g = 9.81)."""
    np.testing.assert_allclose(MODELS["pendulum"].gravity(jnp.array([0.5])), [0.5 * G * 0.5 * math.sin(0.5)])
    q = jnp.array([0.2, -0.4])
    np.testing.assert_allclose(
        MODELS["two_link"].gravity(q),
        [0.7 * 1.5 * G * math.cos(-0.2) + 1.2 * 1.0 * G * math.cos(0.2), 0.7 * 1.5 * G * math.cos(-0.2)],
    )
    alpha, beta, gamma, delta = MODELS["furuta"].inertia_constants()
    np.testing.assert_allclose([alpha, beta, gamma, delta], [1 + (0.5 + 0.4 / 3 + 0.1) * 0.49, (0.5 + 0.1 / 3) * 0.25, 0.55 * 0.35, 0.55 * G * 0.5])
    np.testing.assert_allclose(MODELS["cart"].mass_matrix(jnp.array([7.0, 0.0])), [[2.2, 0.1], [0.1, 0.05]])


def _frictionless(name):
    model = MODELS[name]
    return eqx.tree_at(lambda m: m.friction, model, jnp.zeros(model.size))


@eqx.filter_jit
def _energy_drift(model, q0, v0, step, steps, stride):
    """max over the coarse grid of |E(t) - E(0)|, unforced frictionless motion by RK4.

    Step, step count and stride are traced (a while loop), so one compilation serves
    every step size.
    """
    tau = jnp.zeros_like(q0)
    initial = model.energy(q0, v0)

    def field(t, x):
        return (x[1], model.acceleration(x[0], x[1], tau))

    def body(i, carry):
        x, worst = carry
        x = rk4_step(field, 0.0, x, step)
        error = jnp.abs(model.energy(*x) - initial)
        return x, jnp.where((i + 1) % stride == 0, jnp.maximum(worst, error), worst)

    _, worst = jax.lax.fori_loop(0, steps, body, ((q0, v0), jnp.zeros(())))
    return worst


ENERGY_START = {
    "pendulum": ([2.0], [0.5]),
    "two_link": ([-0.8, 0.6], [1.0, -0.5]),
    "cart": ([0.0, 2.5], [0.3, -1.0]),
    "furuta": ([1.0, -1.0], [0.5, 1.0]),
}


@pytest.mark.parametrize("name", NAMES)
def test_rk4_conserves_energy_to_fourth_order(name):
    """Frictionless, unforced: the largest energy error over 2 s shrinks by ~2^4 per halving of the step."""
    model = _frictionless(name)
    q0, v0 = (jnp.asarray(x, dtype=float) for x in ENERGY_START[name])
    horizon, coarse = 2.0, 0.01
    errors = []
    for refinement in (1, 2, 4):
        steps = int(round(horizon / coarse)) * refinement
        errors.append(float(_energy_drift(model, q0, v0, jnp.asarray(coarse / refinement), jnp.asarray(steps), jnp.asarray(refinement))))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    print(f"{name}: energy errors {errors}, observed orders {orders}")
    assert errors[-1] > 1e-13  # above round-off, so the order is measurable
    assert abs(orders[-1] - 4.0) < 0.5


def test_models_build_under_jit_and_vmap_and_differentiate():
    q, v, tau = jnp.array([0.4, -0.3]), jnp.array([0.2, 1.0]), jnp.array([1.0, 0.0])
    masses = jnp.array([0.5, 1.0, 2.0])
    acceleration = jax.jit(lambda m: CartPendulum(pendulum_mass=m).acceleration(q, v, tau))
    batch = jax.jit(jax.vmap(acceleration))(masses)
    one = [acceleration(m) for m in masses]
    np.testing.assert_allclose(batch, np.stack(one), rtol=1e-14)
    jitted = jax.jit(lambda l: FurutaPendulum(pendulum_length=l).energy(q, v))
    np.testing.assert_allclose(jitted(0.5), jitted(jnp.asarray(0.5, dtype=float)))
    np.testing.assert_allclose(
        jitted(0.5), 0.5 * v @ np.asarray(FurutaPendulum().mass_matrix(q)) @ v + FurutaPendulum().inertia_constants()[3] * np.cos(q[1])
    )
    # d(kinetic energy)/d(m2) of the two-link arm: T is linear in the masses
    kinetic = jax.jit(lambda m: TwoLinkArm(masses=m).kinetic_energy(q, v))
    grad = jax.jit(jax.grad(kinetic))(jnp.array([0.5, 0.7]))
    finite = kinetic(jnp.array([0.5, 1.7])) - kinetic(jnp.array([0.5, 0.7]))
    np.testing.assert_allclose(grad[1], finite, rtol=1e-12)


def test_plant_signals_input_layout_and_state_derivative():
    plant = ManipulatorPlant(CartPendulum())
    x = plant.state([-1.0, 1.0], [0.5, -2.0])
    signals = {s.name: s for s in plant.variable_signals}
    assert list(signals) == ["joint_position", "joint_angle", "joint_speed", "joint_rate"]
    assert (signals["joint_position"].units, signals["joint_position"].dim, signals["joint_position"].labels) == ("m", "prismatic_joint", ("cart",))
    assert (signals["joint_angle"].units, signals["joint_angle"].dim, signals["joint_angle"].labels) == ("rad", "revolute_joint", ("pendulum",))
    assert (signals["joint_speed"].units, signals["joint_rate"].units) == ("m/s", "rad/s")
    assert signals["joint_angle"].angle and not signals["joint_rate"].angle
    assert all(s.frame == "joint space" for s in plant.variable_signals)
    variables = plant.variables(x)
    np.testing.assert_array_equal(variables["joint_position"], [-1.0])
    np.testing.assert_array_equal(variables["joint_rate"], [-2.0])
    inputs = plant.input_layout
    assert [(s.name, s.units, s.labels) for s in inputs.signals] == [("joint_force", "N", ("cart",)), ("joint_torque", "N m", ("pendulum",))]
    u = jnp.array([3.0, 0.5])
    field = eqx.filter_jit(lambda p, w: p.vector_field(0.0, x, u, w))
    derivative = field(plant, jnp.zeros(2))
    np.testing.assert_array_equal(derivative.q, x.qdot)
    expected = eqx.filter_jit(lambda tau: CartPendulum().acceleration(x.q, x.qdot, tau))
    np.testing.assert_allclose(derivative.qdot, expected(u))
    assert plant.normalize(JointState(jnp.array([0.0, 7.0]), x.qdot)).q[1] == 7.0  # not wrapped
    noisy = ManipulatorPlant(CartPendulum(), force_noise=[2.0, 0.0])
    np.testing.assert_allclose(field(noisy, jnp.array([1.0, 5.0])).qdot, expected(u + jnp.array([2.0, 0.0])))
    arm = ManipulatorPlant(TwoLinkArm())
    assert [(s.name, s.labels) for s in arm.variable_signals] == [("joint_angle", ("shoulder", "elbow")), ("joint_rate", ("shoulder", "elbow"))]
    assert arm.noise_size == 2 and arm.realize(jax.random.key(1)) is arm


def test_joint_layout_refuses_non_contiguous_joint_kinds():
    with pytest.raises(ValueError, match="the revolute joints must be contiguous"):
        joint_layout(("a", "b", "c"), ("revolute", "prismatic", "revolute"), JOINT_POSITION)
    with pytest.raises(ValueError, match="joint_kinds must be 'revolute' or 'prismatic'"):
        joint_layout(("a",), ("spherical",), JOINT_POSITION)

    @final
    class Scara(ManipulatorModel):
        friction: jax.Array
        joint_names: ClassVar[tuple[str, ...]] = ("shoulder", "lift", "wrist")
        joint_kinds: ClassVar[tuple[str, ...]] = ("revolute", "prismatic", "revolute")

        def mass_matrix(self, q):
            return jnp.eye(3)

        def gravity(self, q):
            return jnp.zeros(3)

        def potential_energy(self, q):
            return 0.0

    with pytest.raises(ValueError, match="contiguous"):
        ManipulatorPlant(Scara(jnp.zeros(3)))


def test_encoder_layout_matches_the_plant_labels():
    plant = ManipulatorPlant(CartPendulum())
    encoder = JointEncoder(plant, sample_period=[0.01, 0.02])
    signals = encoder.measurement_layout.signals
    assert [(s.name, s.units, s.dim, s.labels) for s in signals] == [
        ("measured_joint_position", "m", "prismatic_joint", ("cart",)),
        ("measured_joint_angle", "rad", "revolute_joint", ("pendulum",)),
    ]
    assert encoder.noise_size == 4 and encoder.sample_period == (0.01, 0.02)
    x = plant.state([0.3, 0.7])
    np.testing.assert_array_equal(encoder.ideal(x), x.q)


NORMALS = np.random.default_rng(0).standard_normal((20000, 4))


def test_encoder_quantizes_to_the_nearest_step_and_adds_noise():
    x = JointState(jnp.array([0.12345, -0.0361]), jnp.zeros(2))
    never_dropped = NORMALS.copy()
    never_dropped[:, 2:] = np.abs(never_dropped[:, 2:])
    silent = np.zeros_like(NORMALS)
    encoder = JointEncoder(TwoLinkArm(), sample_period=0.01, quantization=[0.01, 0.0])
    np.testing.assert_allclose(_measure_many(encoder, x, silent)[0], [0.12, -0.0361], atol=1e-15)
    encoder = JointEncoder(TwoLinkArm(), sample_period=0.01, quantization=[0.0, 0.01])
    np.testing.assert_allclose(_measure_many(encoder, x, silent)[0], [0.12345, -0.04], atol=1e-15)
    # noise: std per joint, applied before the quantizer
    noisy = JointEncoder(TwoLinkArm(), sample_period=0.01, noise_std=[0.1, 0.001])
    samples = np.asarray(_measure_many(noisy, x, never_dropped))
    np.testing.assert_allclose(samples.std(axis=0), [0.1, 0.001], rtol=0.03)
    np.testing.assert_allclose(samples.mean(axis=0), x.q, atol=3e-3)
    coarse = JointEncoder(TwoLinkArm(), sample_period=0.01, noise_std=0.1, quantization=0.25)
    grid = np.asarray(_measure_many(coarse, x, never_dropped))
    np.testing.assert_allclose(grid / 0.25, np.round(grid / 0.25), atol=1e-12)
    assert len(np.unique(grid[:, 0])) > 2  # the noise moves samples across steps


def test_encoder_dropouts_are_nan_at_the_requested_rate():
    encoder = JointEncoder(TwoLinkArm(), sample_period=0.01, dropout_probability=0.25)
    x = JointState(jnp.array([1.0, 2.0]), jnp.zeros(2))
    samples = np.asarray(_measure_many(encoder, x, NORMALS))
    assert abs(np.isnan(samples).mean() - 0.25) < 0.015
    np.testing.assert_array_equal(np.where(np.isnan(samples), x.q, samples), np.broadcast_to(x.q, samples.shape))


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: FreePendulum(mass=-0.5), "pendulum mass must be positive"),
        (lambda: FreePendulum(length=[0.5, 0.5]), "pendulum length must be a scalar"),
        (lambda: TwoLinkArm(lengths=(1.0, -1.5)), "two-link lengths must be positive"),
        (lambda: TwoLinkArm(masses=(0.5, 0.7, 0.1)), "two-link masses must be a scalar or have 2 entries"),
        (lambda: CartPendulum(friction=(0.4, -0.1)), "cart-pendulum friction must be non-negative"),
        (lambda: CartPendulum(cart_mass=0.0), "cart_mass must be positive"),
        (lambda: FurutaPendulum(pillar_inertia=-1.0), "pillar_inertia must be positive"),
        (lambda: FurutaPendulum(friction=(0.4, 0.2, 0.0)), "Furuta friction must be a scalar or have 2 entries"),
        (lambda: FurutaPendulum(gravity_acceleration=float("nan")), "gravity_acceleration must be finite"),
        (lambda: ManipulatorPlant(TwoLinkArm(), force_noise=[-1.0, 0.0]), "force_noise must be non-negative"),
        (lambda: ManipulatorPlant(TwoLinkArm(), force_noise=[1.0, 0.0, 0.0]), "force_noise must be a scalar or have 2 entries"),
        (lambda: JointEncoder(TwoLinkArm(), sample_period=0.01, quantization=-0.1), "encoder quantization must be non-negative"),
        (lambda: JointEncoder(TwoLinkArm(), sample_period=[0.01, 0.0]), "encoder sample_period must be positive"),
        (lambda: JointEncoder(TwoLinkArm(), sample_period=0.01, noise_std=[0.1, 0.1, 0.1]), "encoder noise_std must be a scalar or have 2 entries"),
        (lambda: JointEncoder(TwoLinkArm(), sample_period=0.01, dropout_probability=1.0), r"encoder dropout_probability must be in \[0, 1\)"),
        (lambda: ManipulatorPlant(TwoLinkArm()).state([0.0, 0.0, 0.0]), "q must be a scalar or have 2 entries"),
    ],
)
def test_bad_parameters_raise_value_errors_that_name_the_parameter(build, message):
    with pytest.raises(ValueError, match=message):
        build()
