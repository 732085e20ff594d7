"""The nonlinear PID for dynamic positioning (lookout.controllers.pid) against references:
the loop's poles from the code's own Jacobian against the design polynomial's roots at
several headings, the sampled loop against its exact zero-order-hold model, the steady
state under a constant force (exactly zero with the integral, exactly F / Kp without),
the rotation into the body frame by hand, the feed-forward against finite differences,
the anti-windup's bound, the EKF and the UKF holding the Northern Clipper in waves, its
tuning family, and bad values refused in one line naming the key."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path
from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm

from lookout._math import rotate, rotate_transpose
from lookout.components import Layout, Observer, Signal
from lookout.controllers.pid import PidController
from lookout.models.vessel import VESSEL_INPUT, VESSEL_SIGNALS, DPVessel, VesselPlant, VesselState
from lookout.sensors import POSITION_HEADING_VELOCITY, PositionHeadingVelocitySensor
from lookout.sim import Scenario, simulate

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "ekf-pid-dp.toml"
#: The Northern Clipper's M and D without their sway-yaw coupling (Fossen & Strand 1999, (56)-(57)):
#: the per-DOF design is then exact.
MASS = np.diag([5.3122e6, 8.2831e6, 3.7454e9])
DAMPING = np.diag([5.0242e4, 2.7229e5, 4.1894e8])
PERIOD = 0.1


def _rotation(psi: float) -> np.ndarray:
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _estimate(eta, nu) -> dict:
    return {"position": jnp.asarray(eta[:2]), "heading": jnp.asarray(eta[2]), "velocity": jnp.asarray(nu[:2]), "yaw_rate": jnp.asarray(nu[2])}


def _setpoint(eta) -> dict:
    return {"position_desired": jnp.asarray(eta[:2]), "heading_desired": jnp.asarray(eta[2])}


@final
class _Oracle(Observer):
    """Perfect estimates: position, heading, velocity and yaw rate as the noise-free oracle
    sensor measures them (a plant without waves), so that the loop is the controller's alone."""

    estimate_signals: tuple[Signal, ...] = eqx.field(
        static=True, default=tuple(s for s in VESSEL_SIGNALS if s.name in ("position", "heading", "velocity", "yaw_rate"))
    )
    extra_signals: tuple[Signal, ...] = eqx.field(static=True, default=())
    measurement_layout: Layout = eqx.field(static=True, default=POSITION_HEADING_VELOCITY)
    input_layout: Layout = eqx.field(static=True, default=VESSEL_INPUT)
    sample_period: None = eqx.field(static=True, default=None)

    def guess(self):
        return jnp.zeros(6)

    def init(self, y0, guess):
        return y0

    def update(self, state, t, y):
        return y

    def output(self, state, y):
        parts = self.measurement_layout.split(state)
        return {
            "position": parts["measured_position"],
            "heading": parts["measured_heading"],
            "velocity": parts["measured_velocity"],
            "yaw_rate": parts["measured_yaw_rate"],
        }

    def predict(self, state, t, y, u, dt):
        return state


def _oracle_loop(controller, start: VesselState, setpoint, *, duration, disturbance=None, actuator=None, bandwidth=0.1, times=(0.0,)):
    """The controller on the diagonal vessel without waves or bias, perfect estimates, a
    reference filter over the setpoints (resting at the first: no feed-forward until it moves)."""
    from lookout.actuators import IdealActuator
    from lookout.environment import GaussMarkovBias, LinearWaveModel
    from lookout.reference import ReferenceFilter

    plant = VesselPlant(DPVessel(MASS, DAMPING), GaussMarkovBias(1000.0, 0.0), LinearWaveModel(0.8976, 0.1, 0.0), disturbance)
    return Scenario(
        plant,
        PositionHeadingVelocitySensor(0.0, PERIOD),
        _Oracle(),
        controller,
        start,
        jnp.zeros(6),
        plant_step=PERIOD,
        sample_period=PERIOD,
        duration=duration,
        reference=ReferenceFilter.vessel(bandwidth, list(times), setpoint),
        actuator=actuator or IdealActuator(),
    )


def test_the_loop_linearized_from_the_code_has_the_designed_poles_at_every_heading():
    """jax.jacfwd of the vessel driven by the controller's own step (perfect estimates, about
    a setpoint) against the roots of s^3 + 2 zeta w s^2 + w^2 s + r w^3 per DOF (numpy): the
    same poles at every heading, surge and sway designed apart (their gains differ, so an
    Earth-frame gain would move the poles with the heading)."""
    vessel = DPVessel(MASS, DAMPING)
    w, zeta, ratio = np.array([0.08, 0.1, 0.12]), np.array([0.9, 1.0, 1.2]), np.array([0.1, 0.05, 0.2])
    pid = PidController.design(vessel, natural_frequency=w, damping_ratio=zeta, integral_ratio=ratio)
    designed = np.sort_complex(np.concatenate([np.roots([1.0, 2 * zeta[i] * w[i], w[i] ** 2, ratio[i] * w[i] ** 3]) for i in range(3)]))

    def field(x, setpoint):
        eta, nu, z = x[:3], x[3:6], x[6:]
        z_next, tau = pid.step(z, 0.0, None, _estimate(eta, nu), _setpoint(setpoint), PERIOD)
        return jnp.concatenate([rotate(eta[2], nu), jnp.linalg.solve(MASS, tau - DAMPING @ nu), (z_next - z) / PERIOD])

    linearize = jax.jit(jax.jacfwd(field))
    for heading in (0.0, 0.7, 2.5, -3.0):
        setpoint = jnp.asarray([12.0, -4.0, heading])
        jacobian = np.asarray(linearize(jnp.concatenate([setpoint, jnp.zeros(6)]), setpoint))
        poles = np.sort_complex(np.linalg.eigvals(jacobian))
        np.testing.assert_allclose(poles, designed, rtol=1e-8, atol=1e-12, err_msg=f"heading {heading}")
        np.testing.assert_allclose(np.sort_complex(pid.closed_loop_poles(heading)), designed, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(pid.design_poles(), designed, rtol=1e-8, atol=1e-12)


def test_the_northern_clippers_coupled_loop_is_stable_and_differs_from_the_per_dof_design():
    """The sway-yaw coupling of D is not cancelled: the coupled poles are the surge design's
    and six others, all stable, and the sampled loop at 10 Hz is stable."""
    from lookout.models.vessel import northern_clipper

    pid = PidController.design(northern_clipper())
    coupled = np.sort_complex(pid.closed_loop_poles())
    surge = np.sort_complex(np.roots([1.0, 0.2, 0.01, 0.0001]))
    assert all(np.min(np.abs(coupled - pole)) < 1e-9 for pole in surge)
    assert np.max(coupled.real) < 0 and not np.allclose(coupled, pid.design_poles())
    assert pid.sampled_spectral_radius(PERIOD) < 1.0


def test_the_sampled_loop_follows_its_exact_zero_order_hold_model():
    """The engine's run (RK4 at the sample period, tau held, the integral by forward Euler)
    against the loop written here in numpy with the plant's exact zero-order-hold step
    (expm): at a constant heading of 0.6 rad the loop is linear, and the two agree to RK4's
    error (1e-9 m over 200 s)."""
    pid = PidController.design(DPVessel(MASS, DAMPING), natural_frequency=[0.1, 0.15, 0.1])
    heading = 0.6
    start = VesselState.build(eta=[3.0, -2.0, heading], nu=[0.1, -0.05, 0.0])
    ds = simulate(_oracle_loop(pid, start, [[0.0, 0.0, heading]], duration=200.0), jax.random.key(0)).to_xarray()
    # numpy: e (2), nu (2) Earth/body, z (2); R constant
    rotation = _rotation(heading)[:2, :2]
    mass, damping = MASS[:2, :2], DAMPING[:2, :2]
    continuous = np.zeros((6, 6))
    continuous[:2, 2:4] = rotation
    continuous[2:4, 2:4] = -np.linalg.solve(mass, damping)
    continuous[2:4, 4:6] = np.linalg.inv(mass)
    step = expm(continuous * PERIOD)
    kp, kd, ki = (np.diag(np.asarray(g)[:2]) for g in (pid.proportional_gain, pid.derivative_gain, pid.integral_gain))
    e, nu, z = np.array([3.0, -2.0]), np.array([0.1, -0.05]), np.zeros(2)
    positions = []
    for _ in range(ds.time.size):
        positions.append(e.copy())
        tau = -kp @ rotation.T @ e - kd @ nu - ki @ rotation.T @ z
        z = z + PERIOD * e
        state = step @ np.concatenate([e, nu, tau])
        e, nu = state[:2], state[2:4]
    np.testing.assert_allclose(ds.position.values[0], np.asarray(positions), rtol=0, atol=1e-9)
    np.testing.assert_allclose(ds.heading.values[0], heading, rtol=0, atol=1e-15)


def test_the_integral_removes_a_constant_force_exactly_and_a_pd_leaves_r_f_over_kp():
    """A constant body-fixed force F (and moment) on the vessel: with the integral the
    setpoint is held exactly; without it (integral_ratio = 0) the vessel settles where
    Kp R^T(psi) e = F, i.e. e_psi = F_3 / kp_3 and e_xy = R(psi_d + e_psi) (F_1 / kp_1, F_2 / kp_2)."""
    from lookout.environment import BodyDisturbance

    force = np.array([3.0e4, -2.0e4, 2.0e6])
    setpoint = np.array([5.0, -3.0, 0.6])
    start = VesselState.build(eta=setpoint)
    kwargs = dict(duration=1000.0, disturbance=BodyDisturbance(constant=force))
    vessel = DPVessel(MASS, DAMPING)
    pid = PidController.design(vessel, natural_frequency=0.2)
    pd = PidController.design(vessel, natural_frequency=0.2, integral_ratio=0.0)
    with_integral = simulate(_oracle_loop(pid, start, [setpoint], **kwargs), jax.random.key(0)).to_xarray()
    without = simulate(_oracle_loop(pd, start, [setpoint], **kwargs), jax.random.key(0)).to_xarray()
    np.testing.assert_allclose(with_integral.position.values[0, -1], setpoint[:2], rtol=0, atol=1e-7)
    np.testing.assert_allclose(with_integral.heading.values[0, -1], setpoint[2], rtol=0, atol=1e-10)
    kp = np.asarray(pd.proportional_gain)
    heading_offset = force[2] / kp[2]
    offset = _rotation(setpoint[2] + heading_offset)[:2, :2] @ (force[:2] / kp[:2])
    np.testing.assert_allclose(without.heading.values[0, -1] - setpoint[2], heading_offset, rtol=1e-7)
    np.testing.assert_allclose(without.position.values[0, -1] - setpoint[:2], offset, rtol=1e-7)
    assert np.linalg.norm(offset) > 0.1  # the PD's offset is there to be removed


def test_the_error_is_rotated_into_the_body_frame():
    """By hand, at heading 90 deg (bow east, starboard south): a vessel 1 m north of its
    setpoint is pushed south, to starboard (+sway); 1 m south, to port (-sway); 1 m east,
    ahead of it, astern (-surge); a surge speed is damped in surge."""
    pid = PidController(DPVessel(MASS, DAMPING), [1.0e5, 2.0e5, 3.0e8], [1.0e6, 2.0e6, 1.0e9], [0.0, 0.0, 0.0])
    east = np.pi / 2

    command = jax.jit(lambda eta, nu, setpoint: pid.step(pid.init(), 0.0, None, _estimate(eta, nu), _setpoint(setpoint), PERIOD)[1])

    def tau(eta, nu=(0.0, 0.0, 0.0)):
        return np.asarray(command(jnp.asarray(eta), jnp.asarray(nu), jnp.array([0.0, 0.0, east])))

    np.testing.assert_allclose(tau([1.0, 0.0, east]), [0.0, 2.0e5, 0.0], atol=1e-9)
    np.testing.assert_allclose(tau([-1.0, 0.0, east]), [0.0, -2.0e5, 0.0], atol=1e-9)
    np.testing.assert_allclose(tau([0.0, 1.0, east]), [-1.0e5, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(tau([0.0, 0.0, east], [0.5, 0.0, 0.0]), [-5.0e5, 0.0, 0.0], atol=1e-9)
    rng = np.random.default_rng(0)
    for _ in range(20):  # any heading and error: -Kp R^T e with numpy's rotation
        psi, error = rng.uniform(-np.pi, np.pi), rng.normal(size=3) * [10.0, 10.0, 0.1]
        eta = np.array([error[0], error[1], psi + error[2]])
        pid_at = command(jnp.asarray(eta), jnp.zeros(3), jnp.array([0.0, 0.0, psi]))
        np.testing.assert_allclose(np.asarray(pid_at), -np.asarray(pid.proportional_gain) * (_rotation(eta[2]).T @ error), rtol=1e-12, atol=1e-6)


def test_the_reference_feed_forward_is_m_nu_d_rate_plus_d_nu_d():
    """Along a turning trajectory given in closed form: M nu_d' + D nu_d with
    nu_d = R^T(psi_d) eta_d' and nu_d' by central differences (numpy); on the reference
    with perfect estimates the command is that feed-forward alone; a setpoint-only
    reference, or one at rest, gives none."""
    from lookout.models.vessel import northern_clipper

    vessel = northern_clipper()
    pid = PidController.design(vessel)

    def trajectory(t):
        eta = np.array([40.0 * np.sin(0.01 * t), 25.0 * (1.0 - np.cos(0.01 * t)), 0.3 + 0.2 * np.sin(0.02 * t)])
        rate = np.array([0.4 * np.cos(0.01 * t), 0.25 * np.sin(0.01 * t), 0.004 * np.cos(0.02 * t)])
        acceleration = np.array([-0.004 * np.sin(0.01 * t), 0.0025 * np.cos(0.01 * t), -8e-5 * np.sin(0.02 * t)])
        return eta, rate, acceleration

    def nu_d(t):
        eta, rate, _ = trajectory(t)
        return _rotation(eta[2]).T @ rate

    for t in (0.0, 37.0, 180.0):
        eta, rate, acceleration = trajectory(t)
        reference = {
            **_setpoint(eta),
            "position_desired_rate": jnp.asarray(rate[:2]),
            "heading_desired_rate": jnp.asarray(rate[2]),
            "position_desired_acceleration": jnp.asarray(acceleration[:2]),
            "heading_desired_acceleration": jnp.asarray(acceleration[2]),
        }
        h = 1e-3
        expected = np.asarray(vessel.mass_matrix) @ ((nu_d(t + h) - nu_d(t - h)) / (2 * h)) + np.asarray(vessel.damping_matrix) @ nu_d(t)
        np.testing.assert_allclose(np.asarray(pid.feedforward({}, reference)), expected, rtol=1e-7)
        _, on_reference = pid.step(pid.init(), t, None, _estimate(jnp.asarray(eta), jnp.asarray(nu_d(t))), reference, PERIOD)
        np.testing.assert_allclose(np.asarray(on_reference), expected, rtol=1e-7)
        assert np.abs(expected).max() > 1e3  # a feed-forward to get right
    np.testing.assert_array_equal(np.asarray(pid.feedforward({}, _setpoint(jnp.array([1.0, 2.0, 0.3])))), np.zeros(3))
    resting = {
        **_setpoint(jnp.array([1.0, 2.0, 0.3])),
        "position_desired_rate": jnp.zeros(2),
        "heading_desired_rate": jnp.asarray(0.0),
        "position_desired_acceleration": jnp.zeros(2),
        "heading_desired_acceleration": jnp.asarray(0.0),
    }
    np.testing.assert_array_equal(np.asarray(pid.feedforward({}, resting)), np.zeros(3))


def test_the_bias_feed_forward_cancels_the_observers_estimate():
    """ "bias": tau = -R^T(psi_hat) b_hat, the Earth-fixed bias of the DP model rotated to
    the body (at heading 90 deg, north becomes -sway); "disturbance": tau = -d_hat, a Kalman
    filter's body-fixed input disturbance. Each reads what it needs, nothing else."""
    vessel = DPVessel(MASS, DAMPING)
    estimate = {
        **_estimate(jnp.array([0.0, 0.0, np.pi / 2]), jnp.zeros(3)),
        "bias_force": jnp.array([1.0e4, 5.0e3]),
        "bias_moment": jnp.asarray(1.0e5),
        "disturbance_force": jnp.array([2.0e3, -1.0e3]),
        "disturbance_moment": jnp.asarray(3.0e4),
    }
    setpoint = _setpoint(jnp.array([0.0, 0.0, np.pi / 2]))
    expected = {"none": [0.0, 0.0, 0.0], "bias": [-5.0e3, 1.0e4, -1.0e5], "disturbance": [-2.0e3, 1.0e3, -3.0e4]}
    for setting, force in expected.items():
        pid = PidController.design(vessel, bias_feedforward=setting)
        np.testing.assert_allclose(np.asarray(pid.step(pid.init(), 0.0, None, estimate, setpoint, PERIOD)[1]), force, atol=1e-9)
    assert PidController.design(vessel, bias_feedforward="bias").estimate_needs == (
        "position",
        "heading",
        "velocity",
        "yaw_rate",
        "bias_force",
        "bias_moment",
    )
    assert PidController.design(vessel).estimate_needs == ("position", "heading", "velocity", "yaw_rate")


def test_the_anti_windup_bounds_the_integral_force():
    """A constant error at heading 0.7 rad for 2000 samples: the integral's body-frame force
    Ki R^T z never exceeds integral_limit (and reaches it); without a limit it grows past it."""
    vessel = DPVessel(MASS, DAMPING)
    limit = np.array([1.0e4, 2.0e4, 1.0e6])
    estimate = _estimate(jnp.array([30.0, -20.0, 0.8]), jnp.zeros(3))
    setpoint = _setpoint(jnp.array([0.0, 0.0, 0.7]))

    def integral_forces(pid):
        def body(z, _):
            z, _ = pid.step(z, 0.0, None, estimate, setpoint, PERIOD)
            return z, pid.integral_gain * rotate_transpose(0.8, z)  # Ki R^T z at the estimate's heading

        return np.asarray(jax.lax.scan(body, pid.init(), None, length=2000)[1])

    clamped = integral_forces(PidController.design(vessel, integral_limit=limit))
    free = integral_forces(PidController.design(vessel))
    assert np.all(np.abs(clamped) <= limit * (1 + 1e-12))
    np.testing.assert_allclose(np.abs(clamped[-1]), limit, rtol=1e-12)
    assert np.all(np.abs(free[-1]) > 3 * limit)


@pytest.mark.slow
def test_the_anti_windup_cuts_the_overshoot_of_a_move_at_the_thrust_limits():
    """A 60 m move through thrust limits of 20 kN: the unclamped integral winds up during
    the saturated transit and overshoots; clamped at the limits, the overshoot is a
    fraction (measured: 64 m against 4.3 m)."""
    from lookout.actuators import SaturatingActuator

    vessel = DPVessel(MASS, DAMPING)
    limits = [2.0e4, 2.0e4, 2.0e6]
    start = VesselState.build()
    overshoot = {}
    for name, limit in (("free", None), ("clamped", limits)):
        pid = PidController.design(vessel, integral_limit=limit)
        scenario = _oracle_loop(
            pid, start, [[0.0, 0.0, 0.0], [60.0, 0.0, 0.0]], duration=600.0, times=(0.0, 10.0), bandwidth=1.0, actuator=SaturatingActuator(limits)
        )
        ds = simulate(scenario, jax.random.key(0)).to_xarray()
        overshoot[name] = float(ds.position.values[0, :, 0].max() - 60.0)
    assert overshoot["free"] > 5.0 and overshoot["clamped"] < 0.25 * overshoot["free"], overshoot


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_the_kalman_filters_hold_the_northern_clipper_in_waves(kind):
    """The example (Fossen & Strand's sea: waves of up to 10 m, a drifting bias, 1 Hz
    fixes) with each filter, seeds 0 and 1, 900 s: from 300 s on the vessel stays within
    1.5 m and 0.5 deg of the reference, through the move at 600 s (measured: 0.71 m and
    0.15 deg at most, both filters)."""
    from lookout.scenario.composition import compose
    from lookout.scenario.composition import simulate as run

    document = tomllib.loads(EXAMPLE.read_text())
    document["simulation"].update(duration=900.0, runs=2)
    document["observer"]["kind"] = kind
    ds = run(compose(document)).to_xarray()
    window = ds.time.values >= 300.0
    distance = np.linalg.norm(ds.position.values - ds.position_desired.values, axis=-1)[:, window]
    heading = np.abs(ds.heading.values - ds.heading_desired.values)[:, window]
    assert ds.status.values.tolist() == ["finite", "finite"]
    assert distance.max() < 1.5 and np.degrees(heading.max()) < 0.5, (distance.max(), np.degrees(heading.max()))


# ------------------------------------------------------------------ composition, CLI, tuning


def test_kind_pid_alone_composes_on_both_vessel_plants():
    """Its pole-placement defaults for the plant's own M and D (Cybership II's as a DP
    vessel): stable, the sampled loop too, at each plant's sample period."""
    from lookout.scenario.composition import compose

    reference = {
        "kind": "reference-filter",
        "signals": ["position", "heading"],
        "bandwidth": 0.1,
        "schedule_times": [0.0],
        "setpoints": [[0.0, 0.0, 0.0]],
    }
    for document in ({"preset": "fossen-strand-1999:paper"}, {"preset": "wondergem-2009"}):
        composed = compose({**document, "controller": {"kind": "pid"}, "reference": reference})
        pid = composed.scenario.controller
        assert isinstance(pid, PidController) and composed.document["controller"]["design"] == "pole-placement"
        np.testing.assert_array_equal(np.asarray(pid.vessel.mass_matrix), np.asarray(composed.scenario.plant.models()[-1].mass_matrix))
        assert np.max(pid.closed_loop_poles().real) < 0 and pid.sampled_spectral_radius(composed.scenario.sample_period) < 1


@pytest.mark.slow
@pytest.mark.parametrize("plant", ["dp-vessel", "cybership-ii"])
def test_every_observer_of_the_shipped_benchmarks_drives_it(plant):
    """The closed-loop condition of each shipped benchmark composes with each of its
    observers (passive, sliding-mode, adaptive-dp, earth-fixed, ekf, ukf, model-free on the DP vessel):
    each gives the estimate the PID reads, checked by the scenario's fit check."""
    from lookout.scenario.composition import compose
    from lookout.studies import benchmark as bench

    loaded = bench.load_benchmark(bench.shipped_spec(plant))
    (closed,) = [c for c in loaded.spec.conditions if c.name == "closed loop, PID"]
    for name, table in loaded.spec.observers.items():
        document = bench.base_document(loaded, loaded.spec.quick, table)
        document.update(copy.deepcopy(closed.changes))
        scenario = compose(document).scenario
        assert isinstance(scenario.controller, PidController), name
    assert plant != "dp-vessel" or set(loaded.spec.observers) == {"passive", "sliding-mode", "adaptive-dp", "earth-fixed", "ekf", "ukf", "model-free"}


def test_tuned_gains_written_to_a_pole_placement_table_are_the_gains_built():
    """lookout tune writes controller.proportional_gain etc. into the file's table, whose
    design rule is pole-placement: given gains win over the rule's."""
    from lookout.scenario.composition import compose

    document = tomllib.loads(EXAMPLE.read_text())
    gains = {"proportional_gain": [6.0e4, 9.0e4, 4.0e7], "derivative_gain": [1.1e6, 1.5e6, 3.5e8], "integral_gain": [500.0, 800.0, 3.0e5]}
    document["controller"].update(gains)
    pid = compose(document).scenario.controller
    for name, value in gains.items():
        np.testing.assert_array_equal(np.asarray(getattr(pid, name)), value)


def _family_scenario(duration=200.0):
    from lookout.environment import BodyDisturbance

    pid = PidController.design(DPVessel(MASS, DAMPING))
    disturbance = BodyDisturbance(constant=[1.0e4, -5.0e3, 5.0e5], amplitude=[5.0e3, 5.0e3, 2.0e5], period=120.0)
    return _oracle_loop(
        pid,
        VesselState.build(eta=[2.0, -1.0, 0.05]),
        [[0.0, 0.0, 0.0], [10.0, 5.0, 0.1]],
        duration=duration,
        times=(0.0, 50.0),
        disturbance=disturbance,
        bandwidth=0.05,
    )


def test_the_tuning_family_round_trips_stays_inside_routh_hurwitz_and_is_checked():
    from lookout.tuning.families import family_of
    from lookout.tuning.families.pid import PidFamily

    scenario = _family_scenario()
    family, start, _ = family_of(scenario)
    assert isinstance(family, PidFamily) and family.check(scenario).holds
    for given, back in zip(start, family.gains(jnp.asarray(family.theta(start)))):
        np.testing.assert_allclose(np.asarray(back), given, rtol=1e-12)
    rng = np.random.default_rng(0)
    for theta in rng.normal(scale=5.0, size=(50, 9)):
        kp, kd, ki = (np.asarray(g) for g in family.gains(jnp.asarray(theta)))
        loop = np.diag(DAMPING) + kd
        assert np.all(kp > 0) and np.all(loop > 0) and np.all((ki > 0) & (ki < loop * kp / np.diag(MASS)))
        # diagonal M, D: the per-DOF conditions are the loop's, so the coupled check holds too
        assert max(np.roots([np.diag(MASS)[i], loop[i], kp[i], ki[i]]).real.max() for i in range(3)) < 0
    pd = eqx.tree_at(lambda s: s.controller.integral_gain, scenario, jnp.asarray([0.0, 1.0, 1.0]))
    assert PidFamily.of(pd).theta(PidFamily.of(pd).current(pd)).size == 8  # a zero Ki stays zero: not tuned
    unstable = eqx.tree_at(lambda s: s.controller.integral_gain, scenario, jnp.asarray([1.0e6, 1.0, 1.0]))
    assert family.check(unstable).verdicts["routh_hurwitz"] == "fails" and family.check(unstable).verdicts["coupled_loop"] == "fails"


@pytest.mark.slow
def test_the_tuning_gradient_matches_central_differences():
    """Through 200 s of the loop with perfect estimates, a slow sinusoidal force and a move."""
    from tuning_checks import gradient_and_central_differences

    from lookout.sim import keys_of_seeds
    from lookout.tuning.families import family_of
    from lookout.tuning.tune import _objective_function, parse_objective

    scenario = _family_scenario()
    family, start, _ = family_of(scenario)
    objective, metrics = parse_objective("rms_tracking:position + 1e-5*rms_input:force", scenario)
    value = _objective_function(scenario, family, objective, metrics, None)
    theta = jnp.asarray(family.theta(start))
    gradient, central = gradient_and_central_differences(value, family, theta, keys_of_seeds([0]), 1e-5)
    np.testing.assert_allclose(gradient, central, rtol=1e-5, atol=1e-7 * np.abs(central).max())
    assert np.abs(gradient).min() > 0


def _write(tmp_path, change) -> Path:
    from lookout.scenario._toml import write

    document = tomllib.loads(EXAMPLE.read_text())
    document["simulation"]["duration"] = 20.0
    change(document)
    path = tmp_path / "bad.toml"
    write(path, document)
    return path


def _set(table: str, **values):
    def change(document):
        document[table] = {**document.get(table, {}), **values}

    return change


def _replace(table: str, **values):
    def change(document):
        document[table] = dict(values)

    return change


BAD = [
    # (the change, the key the line names, a fragment of its reason)
    (_set("controller", natural_frequency=-0.1), "controller.natural_frequency", "must be positive; got -0.1"),
    (
        _set("controller", natural_frequency=[0.1, 0.1, 0.1, 0.1]),
        "controller.natural_frequency",
        "must be one number or have 3 entries; got 4 entries",
    ),
    (_set("controller", damping_ratio=0.0), "controller.damping_ratio", "must be positive; got 0.0"),
    (_set("controller", integral_ratio=2.5), "controller.integral_ratio", "integral_ratio must be below 2 damping_ratio"),
    (_set("controller", integral_limit=[0.0, 1.0, 1.0]), "controller.integral_limit", "must be positive"),
    (_set("controller", bias_feedforward="wind"), "controller.bias_feedforward", "'none', 'bias' or 'disturbance'"),
    (
        _set("controller", derivative_gain=[-1.0e6, 1.0e6, 1.0e9]),
        "controller.derivative_gain",
        "must leave the closed loop's damping d + Kd positive in surge",
    ),
    (_set("controller", integral_gain=[1.0e5, 800.0, 3.0e5]), "controller.integral_gain", "must be below (d + Kd) Kp / m = 1.062e+04 in surge"),
    (
        _replace("controller", kind="pid", design="gains", proportional_gain=[5.0e4, 8.0e4, 4.0e7], derivative_gain=[1.0e6, 1.4e6, 3.3e8]),
        "controller",
        "missing key integral_gain",
    ),
    (
        _replace("controller", kind="pid", vessel={"kind": "northern-clipper", "mass_scale": -1.0}),
        "controller.vessel.mass_scale",
        "must be non-negative",
    ),
    (_replace("reference", kind="none"), "controller", "controller pid needs reference position_desired, which reference none does not provide"),
    (
        lambda d: d["controller"].update(bias_feedforward="disturbance"),
        "controller",
        "controller pid needs estimate disturbance_force, which observer ekf does not provide",
    ),
]


@pytest.mark.parametrize("change, key, reason", BAD, ids=[f"{key} {i}" for i, (_, key, _) in enumerate(BAD)])
def test_bad_values_in_a_scenario_file_are_one_line_naming_the_key(tmp_path, capsys, change, key, reason):
    from lookout.cli import main

    path = _write(tmp_path, change)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and f"{path}: {key} (line " in lines[0] and reason in lines[0], captured.err
    assert "Traceback" not in captured.err + captured.out
    assert not out.exists()


def test_a_long_array_is_refused_by_its_shape_not_printed(tmp_path, capsys):
    from lookout.cli import main

    path = _write(tmp_path, _set("controller", proportional_gain=[1.0e5] * 100_000))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    line = capsys.readouterr().err.strip()
    assert "controller.proportional_gain" in line and "got 100000 entries" in line and len(line) < 300, line[:300]


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda v: PidController.design(v, natural_frequency=[0.1, -0.1, 0.1]), "natural_frequency must be positive"),
        (lambda v: PidController.design(v, damping_ratio=0.5, integral_ratio=1.0), "integral_ratio must be below 2 damping_ratio"),
        (lambda v: PidController.design(v, integral_limit=[1.0, float("nan"), 1.0]), "integral_limit must be positive"),
        (lambda v: PidController.design(v, bias_feedforward="wind"), "bias_feedforward must be one of"),
        (lambda v: PidController(v, [1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]), "integral_gain must be non-negative"),
        (lambda v: PidController(v, [1.0e5, 1.0e5, 1.0e8], [1.0e6, 1.0e6, 1.0e9], [1.0e6, 0.0, 0.0]), "integral_gain must be below"),
        (lambda v: PidController(v, [0.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]), "proportional_gain must be positive"),
        (lambda v: PidController(v, [1.0, 1.0, 1.0], [np.inf, 0.0, 0.0], [0.0, 0.0, 0.0]), "derivative_gain must be finite"),
        (lambda v: PidController("vessel", [1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]), "vessel must be a DPVessel"),
    ],
)
def test_bad_arguments_are_a_value_error_naming_them(build, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        build(DPVessel(MASS, DAMPING))
