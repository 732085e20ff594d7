"""Cybership II (Wondergem et al. 2009, eq. 39), its Earth-fixed form, the observer (6),
the tracking controller (18)/(23) and the ellipse reference."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lookout._math import rotate
from lookout.controllers import TrackingController
from lookout.models.cybership import CYBERSHIP_M, Cybership, CybershipPlant, cybership2
from lookout.observers import EarthFixedObserver
from lookout.papers.wondergem_2009.config import DAMPING_RATIO, NATURAL_FREQUENCY, OBSERVER_POSITION_GAIN, OBSERVER_VELOCITY_GAIN
from lookout.reference import EllipseReference

SHIP = cybership2()
speeds = st.floats(-2.0, 2.0, allow_nan=False, allow_subnormal=False)


@settings(max_examples=50)
@given(speeds, speeds, speeds)
def test_coriolis_is_skew_for_every_velocity(u, v, r):
    C = np.asarray(SHIP.coriolis(jnp.array([u, v, r])))
    np.testing.assert_allclose(C, -C.T, atol=0.0)


def test_the_printed_numbers_of_39():
    nu = jnp.array([0.3, -0.1, 0.2])
    u, v, r = 0.3, -0.1, 0.2
    expected = np.array([[0, 0, -33.8 * v - 1.0115 * r], [0, 0, 25.8 * u], [33.8 * v + 1.0115 * r, -25.8 * u, 0]])
    np.testing.assert_allclose(SHIP.coriolis(nu), expected, rtol=1e-15)
    damping = np.array([[0.72 + 1.33 * abs(u), 0, 0], [0, 0.86 + 36.28 * abs(v), -0.11], [0, -0.11 - 5.04 * abs(v), 0.5]])
    np.testing.assert_allclose(SHIP.damping_force(nu), damping @ np.array([u, v, r]), rtol=1e-14)
    assert np.linalg.eigvalsh(CYBERSHIP_M).min() == pytest.approx(2.727, abs=1e-3)  # M_M = 1/2.727 = 0.3667


def test_christoffel_factorization_has_property_3_and_the_same_product():
    rng = np.random.default_rng(0)
    for _ in range(5):
        psi = rng.uniform(-np.pi, np.pi)
        x, y = (jnp.asarray(rng.normal(size=3)) for _ in range(2))
        C_gamma = SHIP.christoffel_coriolis(psi, x)
        np.testing.assert_allclose(C_gamma @ x, SHIP.earth_coriolis(psi, x) @ x, atol=1e-12)
        np.testing.assert_allclose(C_gamma @ y, SHIP.christoffel_coriolis(psi, y) @ x, atol=1e-12)
        # M*' - 2 C_Gamma skew, with M*' = dM*/dpsi psi' and psi' = x_3
        _, mass_rate = jax.jvp(SHIP.earth_mass, (jnp.asarray(psi),), (x[2],))
        N = np.asarray(mass_rate - 2.0 * C_gamma)
        np.testing.assert_allclose(N, -N.T, atol=1e-12)
        # the printed C* does not have property (3)
        assert np.abs(np.asarray(SHIP.earth_coriolis(psi, x) @ y - SHIP.earth_coriolis(psi, y) @ x)).max() > 1e-3


def test_earth_fixed_form_integrated_alongside_gives_the_same_trajectory():
    """eta'' of (1)-(2) against eta' = J nu, nu' of (16), under the same time-varying tau."""

    def tau(t):
        return jnp.array([1.5 * jnp.sin(0.3 * t), 0.8 * jnp.cos(0.2 * t), 0.3 * jnp.sin(0.5 * t + 1.0)])

    def body(t, state):
        eta, nu = state
        return rotate(eta[2], nu), SHIP.acceleration(nu, tau(t))

    def earth(t, state):
        eta, rate = state
        return rate, SHIP.earth_acceleration(eta[2], rate, tau(t))

    def rk4(field, state, h, n):
        def step(i, s):
            t = i * h
            k1 = field(t, s)
            k2 = field(t + h / 2, jax.tree.map(lambda a, b: a + h / 2 * b, s, k1))
            k3 = field(t + h / 2, jax.tree.map(lambda a, b: a + h / 2 * b, s, k2))
            k4 = field(t + h, jax.tree.map(lambda a, b: a + h * b, s, k3))
            return jax.tree.map(lambda a, b1, b2, b3, b4: a + h / 6 * (b1 + 2 * b2 + 2 * b3 + b4), s, k1, k2, k3, k4)

        return jax.lax.fori_loop(0, n, step, state)

    eta0, nu0 = jnp.array([1.0, -2.0, 0.4]), jnp.array([0.2, -0.05, 0.1])
    eta_b, nu_b = rk4(body, (eta0, nu0), 0.01, 4000)
    eta_e, rate_e = rk4(earth, (eta0, rotate(eta0[2], nu0)), 0.01, 4000)
    assert float(jnp.abs(eta_b[:2] - eta0[:2]).max()) > 1.0  # the ship moved
    np.testing.assert_allclose(eta_e, eta_b, atol=1e-9)
    np.testing.assert_allclose(rate_e, rotate(eta_b[2], nu_b), atol=1e-10)


def test_gains_20_and_the_closed_loop_19_per_dof():
    controller = TrackingController(SHIP, NATURAL_FREQUENCY, DAMPING_RATIO)
    Kp, Kd = (np.asarray(v) for v in controller.gains_table().values())
    # derivations-wondergem-2009.md, section 3 (printed Omega, Lambda = I)
    np.testing.assert_allclose(Kp, [[13.375, 0, 0], [0, 5.962, 0.414], [0, 0.178, 1.131]], atol=6e-4)
    np.testing.assert_allclose(Kd, [[36.432, 0, 0], [0, 27.532, 1.405], [0, 0.960, 3.033]], atol=6e-4)
    M_inv = np.linalg.inv(CYBERSHIP_M)
    omega = np.array([0.72, 0.42, 0.64])
    np.testing.assert_allclose(M_inv @ Kp, np.diag(omega**2), atol=1e-14)
    np.testing.assert_allclose(M_inv @ (np.asarray(SHIP.damping_matrix) + Kd), np.diag(2 * omega), atol=1e-14)


def _reference_derivative(reference, theta, name, of):
    """d/dt of reference output ``of`` at theta, by forward mode along theta' = U / rho."""
    rate = reference.speed(theta) / reference._rho(theta)
    return jax.jacfwd(lambda th: reference.sample(th)[of])(theta) * rate, reference.sample(theta)[name]


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.slow
def test_ellipse_reference_derivatives_speed_and_heading(direction):
    reference = EllipseReference((3.5, 1.823), (0.05, 0.1, 0.15, 0.2), centre=(0.5, -0.2), start_angle=0.3, direction=direction)
    for theta in (0.4, 2.0, 3.5, 5.9, 7.0, 13.0, 20.0):
        theta = jnp.asarray(theta)
        for name, of in (
            ("position_desired_rate", "position_desired"),
            ("heading_desired_rate", "heading_desired"),
            ("position_desired_acceleration", "position_desired_rate"),
            ("heading_desired_acceleration", "heading_desired_rate"),
        ):
            derivative, value = _reference_derivative(reference, theta, name, of)
            np.testing.assert_allclose(value, derivative, rtol=1e-10, atol=1e-14)
        sample = reference.sample(theta)
        lap = int((float(theta) - 0.3) // (2 * np.pi))
        assert float(jnp.linalg.norm(sample["position_desired_rate"])) == pytest.approx((0.05, 0.1, 0.15, 0.2)[min(lap, 3)], rel=1e-12)
        rate = sample["position_desired_rate"]
        assert float(sample["heading_desired"]) == pytest.approx(float(jnp.arctan2(rate[1], rate[0])), abs=1e-12)
    # four laps of the chosen ellipse take 714.2 s (Table 1's horizon)
    assert reference.perimeter() * sum(1 / u for u in (0.05, 0.1, 0.15, 0.2)) == pytest.approx(714.2, abs=0.05)


def test_ellipse_reference_and_observer_reject_bad_input():
    for kwargs, message in (
        ({"semi_axes": (0.0, 1.0)}, "semi_axes must be positive"),
        ({"lap_speeds": (0.1, -0.1)}, "lap_speeds must be positive"),
        ({"direction": 2}, "direction must be 1 or -1"),
        ({"substeps": 0}, "substeps must be a positive integer"),
    ):
        arguments = {"semi_axes": (3.0, 2.0), "lap_speeds": (0.1,)} | kwargs
        with pytest.raises(ValueError, match=message):
            EllipseReference(**arguments)
    with pytest.raises(ValueError, match=r"position_gain \(L1\) must be positive"):
        EarthFixedObserver(SHIP, -1.0, 50.0)
    with pytest.raises(ValueError, match="method must be one of 'rk4', 'euler'"):
        EarthFixedObserver(SHIP, OBSERVER_POSITION_GAIN, OBSERVER_VELOCITY_GAIN, method="heun")
    with pytest.raises(ValueError, match="mass_matrix must have m12 = m13 = 0"):
        Cybership(np.array([[25.8, 1.0, 0.0], [1.0, 33.8, 1.0115], [0.0, 1.0115, 2.76]]))
    with pytest.raises(ValueError, match="wave_ramp must be positive"):
        CybershipPlant(SHIP, wave_ramp=0.0)


def test_a_dp_vessel_as_a_ship_model_differs_from_it_by_c_nu_alone():
    """The Northern Clipper's M and D in the form (16): its acceleration is the DP model's
    (3) less M^-1 C(nu) nu, the term the DP model neglects; a mooring K or a surge coupled
    to sway or yaw (m12, m13) is refused."""
    from lookout.models.vessel import DPVessel, northern_clipper

    vessel = northern_clipper()
    ship = Cybership.from_dp_vessel(vessel)
    nu, tau = jnp.array([1.2, -0.3, 0.01]), jnp.array([2.0e5, -5.0e4, 3.0e6])
    dp = vessel.acceleration(jnp.zeros(3), nu, tau, jnp.zeros(3))
    coriolis = np.linalg.solve(np.asarray(vessel.mass_matrix), np.asarray(ship.coriolis(nu) @ nu))
    assert np.abs(coriolis).max() > 1e-3 * np.abs(np.asarray(dp)).max()  # at 1.2 m/s the term is not negligible
    np.testing.assert_allclose(ship.acceleration(nu, tau), np.asarray(dp) - coriolis, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(ship.quadratic_damping, np.zeros(3))
    with pytest.raises(ValueError, match="vessel has a mooring stiffness K"):
        Cybership.from_dp_vessel(DPVessel(vessel.mass_matrix, vessel.damping_matrix, np.diag([1e4, 1e4, 1e6])))
    with pytest.raises(ValueError, match="mass_matrix must have m12 = m13 = 0"):
        Cybership.from_dp_vessel(DPVessel(np.array([[5e6, 1e5, 0.0], [1e5, 8e6, 0.0], [0.0, 0.0, 4e9]]), vessel.damping_matrix))


@pytest.mark.slow
def test_matched_scheme_converges_and_tracks_to_the_sampling_error():
    """Matched model, no noise: the observer error decays exponentially to rounding, and
    the tracking error after the transient is the controller's zero-order hold alone:
    first order in the control period (the continuous scheme (23) converges to zero)."""
    from lookout.analysis import fit_decay_rate
    from lookout.papers import wondergem_2009 as w
    from lookout.sim import simulate

    config = w.Config(duration=80.0, sweep=False)
    tails = []
    for period in (0.01, 0.002):
        scenario = w.scenario(
            config,
            "simulation",
            {
                "reference.lap_speeds": [0.1],
                "simulation.sample_period": period,
                "simulation.plant_step": period,
                "simulation.record_every": int(round(0.1 / period)),
            },
        )
        ds = simulate(scenario, jax.random.key(0)).to_xarray().isel(run=0)
        observer_error = np.hypot(*(ds.position - ds.position_hat).values.T)
        if period == 0.01:
            fit = fit_decay_rate(ds.time.values, observer_error, upper=1e-2, lower=1e-10)
            # linear part (s + 5)(s + 10) of L1 = 15, L2 = 50: the slow pole 5 1/s, slowed by the model terms
            assert 2.0 < fit["rate"] < 6.0, fit
            assert observer_error[ds.time.values > 40.0].max() < 1e-11
        errors = w.tracking_errors(ds).where(ds.time > 60.0)
        tails.append(max(float(np.abs(errors[name]).max()) for name in errors))
    assert tails[1] < 1e-5
    assert tails[0] / tails[1] == pytest.approx(5.0, rel=0.05)  # first order in the period
