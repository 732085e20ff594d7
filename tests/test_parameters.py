"""Property 4.2 of Calugi (2002): the affine split of the dynamics in the unknown parameters."""

import jax.numpy as jnp
import numpy as np
import pytest

from lookout.models.manipulators import CartPendulum, FreePendulum, FurutaPendulum, TwoLinkArm
from lookout.models.parameters import ModelParameters, PendulumInertia

CASES = [
    ("pendulum m", lambda: ModelParameters(FreePendulum(1.0, 1.5, 0.1), ("mass",))),
    ("pendulum m, c", lambda: ModelParameters(FreePendulum(1.0, 1.5, 0.1), ("mass", "friction[0]"))),
    ("pendulum (m l^2, m l)", lambda: PendulumInertia(FreePendulum(1.0, 1.5, 0.1))),
    ("two-link m2", lambda: ModelParameters(TwoLinkArm((1.0, 1.5), (1.0, 1.0), (0.0, 0.0)), ("masses[1]",))),
    ("two-link m1, m2, f2", lambda: ModelParameters(TwoLinkArm(), ("masses[0]", "masses[1]", "friction[1]"))),
    ("cart-pendulum masses", lambda: ModelParameters(CartPendulum(), ("cart_mass", "pendulum_mass"))),
    ("furuta masses", lambda: ModelParameters(FurutaPendulum(), ("pillar_inertia", "arm_mass", "pendulum_mass", "tip_mass"))),
]


@pytest.mark.slow
@pytest.mark.parametrize("name, make", CASES, ids=[case[0] for case in CASES])
def test_the_split_reproduces_the_model_at_random_arguments(name, make):
    parameters = make()
    rng = np.random.default_rng(7)
    n = parameters.model(parameters.reference).size
    for _ in range(5):
        theta = jnp.asarray(np.asarray(parameters.reference) * rng.uniform(0.3, 3.0, parameters.size))
        q, xi, psi = (jnp.asarray(rng.normal(scale=2.0, size=n)) for _ in range(3))
        phi0, phi = parameters.split(q, xi, psi)
        assert phi.shape == (n, parameters.size)
        model = parameters.model(theta)  # the model itself, not the split's left side
        tau = model.mass_matrix(q) @ psi + model.coriolis_force(q, xi) + model.friction_force(xi) + model.gravity(q)
        np.testing.assert_allclose(phi0 + phi @ theta, tau, rtol=1e-11, atol=1e-11)


def test_pendulum_regressors_by_hand():
    """Ch. 3/4: theta = m gives phi = l^2 psi + g l sin q; theta = (m l^2, m l) gives [psi, g sin q]."""
    pendulum = FreePendulum(1.0, 1.5, 0.0)
    q, xi, psi = jnp.array([0.4]), jnp.array([-0.7]), jnp.array([1.3])
    phi0, phi = ModelParameters(pendulum, ("mass",)).split(q, xi, psi)
    np.testing.assert_allclose(phi, [[1.5**2 * 1.3 + 9.81 * 1.5 * np.sin(0.4)]], rtol=1e-14)
    np.testing.assert_allclose(phi0, [0.0], atol=1e-15)
    phi0, phi = PendulumInertia(pendulum).split(q, xi, psi)
    np.testing.assert_allclose(phi, [[1.3, 9.81 * np.sin(0.4)]], rtol=1e-12)
    np.testing.assert_allclose(phi0, [0.0], atol=1e-12)


def test_parameters_that_do_not_enter_affinely_are_refused():
    with pytest.raises(ValueError, match=r"^parameters lengths\[1\] must enter the dynamics affinely"):
        ModelParameters(TwoLinkArm(), ("lengths[1]",))
    with pytest.raises(ValueError, match=r"^field 'masses' of TwoLinkArm is a vector: name one element"):
        ModelParameters(TwoLinkArm(), ("masses",))
    with pytest.raises(ValueError, match=r"^TwoLinkArm has no parameter field 'mass'"):
        ModelParameters(TwoLinkArm(), ("mass",))
    with pytest.raises(ValueError, match=r"^field 'masses\[2\]': masses has shape \(2,\)"):
        ModelParameters(TwoLinkArm(), ("masses[2]",))
