"""Calugi (2002) ch. 6: the Furuta pendulum model, its stick-slip plant, the quantized encoders,
the pendulum-angle law (6.9)–(6.11) and the four experiments."""

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout.controllers.furuta import FurutaPendulumBackstepping
from lookout.models.furuta import FurutaConstants, FurutaPlant
from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver
from lookout.papers import REPRODUCTIONS
from lookout.papers import calugi_2002_furuta as ch6
from lookout.sensors import JointEncoder
from lookout.sim.integrators import rk4_step

MODEL = FurutaConstants()
PLANT = FurutaPlant(MODEL)
STEP = 2.5e-4


@jax.jit
def _hold(x, tau):
    """The plant alone from x with (tau, 0) held, 0.1 s of RK4 at 0.25 ms."""
    u = jnp.stack([tau, 0.0])

    def body(state, k):
        return rk4_step(lambda t, z: PLANT.vector_field(t, z, u, jnp.zeros(0)), k * STEP, state, STEP), None

    return jax.lax.scan(body, x, jnp.arange(400))[0]


def test_the_derived_christoffel_c_is_the_printed_c_and_the_stick_condition_is_the_notes():
    rng = np.random.default_rng(0)
    a, b, g, d = 0.00354, 0.00384, 0.00258, 0.103
    for _ in range(5):
        q, v = jnp.asarray(rng.normal(size=2) * 2), jnp.asarray(rng.normal(size=2) * 2)
        np.testing.assert_allclose(MODEL.coriolis_matrix(q, v), MODEL.printed_coriolis_matrix(q, v), atol=1e-15)
        # the torque that holds the arm at rest (phi' = 0) is tau_u - gamma cos th th''_s + gamma sin th th'^2, th''_s = delta sin th / beta
        theta, theta_rate, tau = float(q[1]), float(v[1]), float(rng.normal() * 0.05)
        f, _ = PLANT.friction_torque(q, jnp.array([0.0, theta_rate]), jnp.array([tau, 0.0]))
        held = tau - g * math.cos(theta) * d * math.sin(theta) / b + g * math.sin(theta) * theta_rate**2
        assert float(f) == pytest.approx(float(np.clip(held, -0.028, 0.028)), rel=1e-9, abs=1e-12)
    assert float(MODEL.determinant(jnp.array([0.0, math.pi]))) == pytest.approx(a * b - g**2)


@pytest.mark.slow
def test_the_arm_sticks_below_tau_c_and_slips_above():
    hanging = PLANT.state([0.0, math.pi])
    for tau in (0.0, 0.02, -0.027):
        x = _hold(hanging, tau)
        assert abs(float(x.q[0])) < 1e-15 and abs(float(x.qdot[0])) < 1e-15, tau  # not a creep: at rest (to rounding)
        assert float(x.stuck_time) == pytest.approx(0.1)
    for tau in (0.029, 0.04, -0.04):
        x = _hold(hanging, tau)
        assert np.sign(float(x.qdot[0])) == np.sign(tau) and abs(float(x.q[0])) > 1e-3 and float(x.stuck_time) == 0.0
    # breakaway at theta = pi, at rest: phi'' = (tau_u - tau_C) [M^-1]_11 at first; 10 ms in, phi' is within 1 %
    rate = np.linalg.inv(np.asarray(MODEL.mass_matrix(jnp.array([0.0, math.pi]))))[0, 0] * (0.04 - 0.028)
    u = jnp.array([0.04, 0.0])
    x = hanging
    for k in range(40):
        x = rk4_step(lambda t, z: PLANT.vector_field(t, z, u, jnp.zeros(0)), k * STEP, x, STEP)
    assert float(x.qdot[0]) == pytest.approx(rate * 0.01, rel=0.01)
    # a slipping arm under a torque within tau_C comes to rest and stays there
    moving = PLANT.state([0.0, math.pi], [0.3, 0.0])
    x = _hold(moving, 0.01)
    assert abs(float(x.qdot[0])) < 1e-9 and float(x.stuck_time) > 0.0
    with pytest.raises(ValueError, match="coulomb_friction\\[1\\]"):
        FurutaPlant(FurutaConstants(coulomb_friction=(0.028, 0.01)))
    with pytest.raises(ValueError, match="alpha must exceed gamma"):
        FurutaConstants(alpha=1e-4)
    with pytest.raises(ValueError, match="stick_band"):
        FurutaPlant(MODEL, stick_band=0.0)


def test_the_encoders_quantize_onto_their_grids():
    encoder = JointEncoder(MODEL, sample_period=ch6.SAMPLE_PERIOD, quantization=ch6.QUANTIZATION)
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = rng.normal(size=2) * 3
        y = np.asarray(encoder.measure(PLANT.state(q), jnp.zeros(4)))
        steps = y / np.asarray(ch6.QUANTIZATION)
        np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
        assert np.all(np.abs(y - q) <= np.asarray(ch6.QUANTIZATION) / 2 + 1e-12)


@pytest.mark.parametrize("unknowns", [("coulomb_friction[0]",), ("coulomb_friction[0]", "alpha")])
def test_with_exact_estimates_the_pendulum_channel_is_z2_dot_equal_minus_c2_d2_z2_minus_z1(unknowns):
    """(6.8) with x1~ = 0: theta'' = v, so z2' = -(c2 + d2) z2 - z1, on the model with the
    Coulomb friction tau_C sgn(phi') (sgn x1_hat_1 = sgn phi' with exact estimates)."""
    parameters = ch6.parameters(unknowns)
    controller = FurutaPendulumBackstepping(parameters, 10.0, 1.0, 10.0, 2.0)
    rng = np.random.default_rng(2)
    for _ in range(5):
        q = jnp.asarray([rng.normal(), rng.choice([0.0, math.pi]) + rng.normal() * 0.5])
        qdot = jnp.asarray(rng.normal(size=2))
        reference = {
            "pendulum_angle_desired": q[1] + rng.normal() * 0.2,
            "pendulum_angle_desired_rate": rng.normal(),
            "pendulum_angle_desired_acceleration": rng.normal(),
        }
        tau = controller.law(q, qdot, parameters.reference, reference)
        accel = MODEL.acceleration(q, qdot, jnp.array([tau, 0.0]))
        z1, z2 = controller.errors(q, qdot, reference)
        z2_dot = accel[1] - reference["pendulum_angle_desired_acceleration"] + 11.0 * (qdot[1] - reference["pendulum_angle_desired_rate"])
        assert float(z2_dot) == pytest.approx(float(-12.0 * z2 - z1), rel=1e-9, abs=1e-9)
        # the printed split tau_u = tau_C_hat sgn(x1_hat_1) + tau_net
        inverse = np.linalg.inv(np.asarray(MODEL.mass_matrix(q)))
        rest = inverse @ -np.asarray(MODEL.coriolis_force(q, qdot) + MODEL.gravity(q))
        tau_net = (float(controller.virtual_acceleration(q, qdot, reference)) - rest[1]) / inverse[1, 0]
        assert float(tau) == pytest.approx(0.028 * np.sign(float(qdot[0])) + tau_net, rel=1e-9)
    with pytest.raises(ValueError, match="velocity_damping d2"):
        FurutaPendulumBackstepping(parameters, 10.0, 1.0, 10.0, 0.0)


def test_exp_iii_printed_bounds_make_m_hat_indefinite():
    experiment = ch6.EXPERIMENTS["III"]
    with pytest.raises(ValueError, match="positive definite"):
        AdaptiveManipulatorObserver(
            ch6.parameters(experiment.unknowns),
            5.0,
            experiment.adaptation_gain,
            sample_period=ch6.SAMPLE_PERIOD,
            lower=experiment.lower,
            upper=experiment.upper,
            margin=experiment.margin,
        )
    assert ch6.ALPHA_MINIMUM == pytest.approx(0.00173, abs=1e-5) and experiment.initial[1] < ch6.ALPHA_MINIMUM


@pytest.mark.slow
def test_every_experiment_runs_to_its_end_or_reports_why_not(tmp_path):
    assert REPRODUCTIONS[ch6.NAME] is ch6.REPRODUCTION
    config = ch6.Config(duration=2.4)
    summary = ch6.run(config, tmp_path)
    experiments = summary["experiments"]
    assert list(experiments) == list(ch6.EXPERIMENTS)
    for name, result in experiments.items():
        assert result["status"] in ("finite", "fell", "diverged"), name
        if result["status"] == "finite":
            assert result["finite_until_s"] == pytest.approx(result["duration_s"] - ch6.SAMPLE_PERIOD)
        else:
            assert result["pendulum_left_half_plane_at_s"] is not None or result["finite_until_s"] < result["duration_s"]
    # the hanging experiments and the fixed upright one hold; the printed upright one (tau_C_hat(0) = 0.001) falls within 2.4 s
    for name in ("I", "II", "III", "III-fixed", "IV-fixed"):
        assert experiments[name]["status"] == "finite", name
        assert experiments[name]["max_abs_tau_u"] < 0.1, name
    assert experiments["IV"]["status"] != "finite"
    assert experiments["III"]["det_m_hat_nonpositive_s"] > 0 and experiments["III-fixed"]["det_m_hat_nonpositive_s"] == 0
    assert experiments["I"]["final_estimates"]["coulomb_friction[0]"] == 0.028  # Gamma = 0 freezes it
    assert sorted(p.name for p in tmp_path.iterdir()) == summary["files"]
    assert json.loads((tmp_path / "summary.json").read_text())["reproduction"] == ch6.NAME
    assert ch6.tables(summary)[0].columns[1:] == tuple(ch6.EXPERIMENTS)


def test_config_refuses_bad_settings():
    with pytest.raises(ValueError, match="7.5 ms"):
        ch6.Config(duration=1.0)
    with pytest.raises(ValueError, match="must be 1"):
        ch6.Config(runs=2)
    with pytest.raises(ValueError, match="distinct names"):
        ch6.Config(experiments=("V",))
    with pytest.raises(ValueError, match="0.25 ms"):
        ch6.Config(plant_step=5e-4)
