"""Observer backstepping with integral action, Kim (2002) eqs. (18)–(26), in closed loop."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout.actuators import SaturatingActuator
from lookout.controllers import ObserverBackstepping
from lookout.environment import BodyDisturbance, GaussMarkovBias, LinearWaveModel
from lookout.models.vessel import VesselPlant, VesselState, northern_clipper
from lookout.observers import PassiveObserver
from lookout.papers import kim_2002
from lookout.reference import ReferenceFilter
from lookout.sensors import PositionHeadingSensor
from lookout.sim import Scenario, simulate

GAINS = {"integral_gain": 0.01, "position_gain": 0.1, "velocity_gain": 0.1, "coupling_gain": 0.01, "damping_weights": [1e-3] * 3 + [1e-2] * 3}
BIAS = (1e4, 5e3, 1e5)


def _observer(**kwargs):
    return kim_2002.printed_observer(northern_clipper(), boundary_layer=(5.0, 5.0, 0.02), hold="innovation", **kim_2002.gain_sets()["kyp"], **kwargs)


def _noise_free_loop(observer, duration=800.0, coupling_gain=0.01):
    """Exact model, no noise or waves, the bias known (the observer starts at the truth),
    the vessel 5 m, 3 m and 3 deg off the reference's start, and a setpoint step at 10 s."""
    plant = VesselPlant(northern_clipper(), GaussMarkovBias((1000.0, 1000.0, 10000.0)), LinearWaveModel(0.8976, 0.1, 0.0))
    start = VesselState.build(eta=[5.0, -3.0, 0.05], bias=BIAS)
    controller = ObserverBackstepping.for_observer(observer, **{**GAINS, "coupling_gain": coupling_gain})
    return Scenario(
        plant,
        PositionHeadingSensor(0.0, 0.1),
        observer,
        controller,
        start,
        start,
        plant_step=0.1,
        sample_period=0.1,
        duration=duration,
        reference=ReferenceFilter.vessel(0.05, [0.0, 10.0], [[0.0, 0.0, 0.0], [10.0, 5.0, 0.1]]),
    )


def _lyapunov_along(scenario, trajectory):
    """V_con of (29) at every sample, the integral state rebuilt as the controller advances it."""
    controller = scenario.controller
    time_major = jax.tree.map(lambda a: jnp.asarray(a), (trajectory.measurement, trajectory.estimate, trajectory.reference))
    y, estimate, reference = time_major
    errors = jax.vmap(lambda yk, ek, rk: controller.errors(jnp.zeros(3), yk, ek, rk)["e"])(y, estimate, reference)
    integral = jnp.concatenate([jnp.zeros((1, 3)), jnp.cumsum(scenario.sample_period * errors, axis=0)[:-1]])
    return np.asarray(jax.vmap(controller.lyapunov)(integral, y, estimate, reference))


@pytest.mark.slow
def test_noise_free_closed_loop_tracks_the_setpoint_and_v_does_not_increase():
    scenario = _noise_free_loop(_observer())
    trajectory = simulate(scenario, jax.random.key(0))
    ds = trajectory.to_xarray().isel(run=0)
    # the observer stays exact (perfect start, no noise, innovation hold) so V_obs = 0
    assert float(np.abs(ds.position - ds.position_hat).max()) < 1e-9
    # integral action: the tracking error goes to zero against the bias
    final = ds.isel(time=-1)
    assert float(np.abs(final.position - final.position_desired).max()) < 1e-3
    assert abs(float(final.heading - final.heading_desired)) < 1e-5
    # V of (29) is non-increasing along the sampled loop (ZOH control): allowed 1e-9 of its peak for rounding
    v = _lyapunov_along(scenario, jax.tree.map(lambda a: a, trajectory))
    increase = np.diff(v)
    assert v[0] > 0.1 and v[-1] < 1e-6 * v.max()
    assert increase.max() <= 1e-9 * v.max(), increase.max() / v.max()  # measured: strictly decreasing


def test_the_same_controller_closes_the_loop_on_the_passive_observer():
    sliding = _observer()
    scenario = _noise_free_loop(sliding.passive, duration=400.0)
    assert isinstance(scenario.observer, PassiveObserver)
    ds = simulate(scenario, jax.random.key(0)).to_xarray().isel(run=0)
    final = ds.isel(time=-1)
    assert float(np.abs(final.position - final.position_desired).max()) < 0.05


def test_kims_printed_coupling_puts_the_loop_at_one_radian_per_second():
    """P1 = 1 (Kim's law as printed): the z-loop rings at sqrt(1 + C1 C2) = 1.005 rad/s."""
    scenario = _noise_free_loop(_observer(), duration=100.0, coupling_gain=1.0)
    ds = simulate(scenario, jax.random.key(0)).to_xarray().isel(run=0)
    error = (ds.position - ds.position_desired).sel(earth_axis="north").values
    crossings = np.flatnonzero(np.diff(np.sign(error[100:])) != 0)
    period = 2 * np.mean(np.diff(crossings)) * scenario.sample_period
    assert 2 * np.pi / period == pytest.approx(np.sqrt(1 + 0.1 * 0.1), rel=0.05)


def test_saturation_bounds_the_applied_thrust_and_the_command_is_recorded():
    scenario = dataclasses.replace(_noise_free_loop(_observer(), duration=200.0), actuator=SaturatingActuator([2e4, 2e4, 1e6]))
    ds = simulate(scenario, jax.random.key(0)).to_xarray()
    assert float(np.abs(ds.force_applied).max()) <= 2e4
    assert float(np.abs(ds.moment_applied).max()) <= 1e6
    assert float(np.abs(ds.force_commanded).max()) > 2e4


def test_for_observer_rejects_other_observers():
    from lookout.models.manipulators import TwoLinkArm
    from lookout.observers import VelocityObserver

    with pytest.raises(ValueError, match=r"observer must be a wave-filtering observer \(passive, sliding-mode\); got VelocityObserver"):
        ObserverBackstepping.for_observer(VelocityObserver(TwoLinkArm(), 5.0), **GAINS)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"position_gain": 0.0}, "position_gain \\(C1\\) must be positive"),
        ({"coupling_gain": -1.0}, "coupling_gain \\(P1\\) must be positive"),
        ({"damping_weights": [1.0] * 5}, "damping_weights \\(d1..d6\\) must be a scalar or have 6 entries"),
        ({"integral_gain": float("nan")}, "integral_gain must be"),
    ],
)
def test_bad_controller_gains_fail_with_one_line(change, message):
    with pytest.raises(ValueError, match=message):
        ObserverBackstepping.for_observer(_observer(), **{**GAINS, **change})


def test_an_unmodelled_constant_surge_force_gives_the_open_loop_terminal_speed_f_over_d():
    """BodyDisturbance: u' = (F - d11 u) / m11 from rest, exactly integrated by RK4 to its order."""
    vessel = northern_clipper()
    force = 5e3
    plant = VesselPlant(vessel, GaussMarkovBias(1000.0), LinearWaveModel(0.8976, 0.1, 0.0), BodyDisturbance(constant=[force, 0.0, 0.0]))
    observer = _observer()
    from lookout.controllers import NoControl

    scenario = Scenario(
        plant,
        PositionHeadingSensor(0.5, 1.0),
        observer,
        NoControl(3),
        VesselState.build(),
        observer.guess(),
        plant_step=0.1,
        sample_period=0.1,
        duration=300.0,
    )
    ds = simulate(scenario, jax.random.key(0)).to_xarray().isel(run=0)
    m, d = float(vessel.mass_matrix[0, 0]), float(vessel.damping_matrix[0, 0])
    t = ds.time.values
    expected = force / d * (1 - np.exp(-d * t / m))
    np.testing.assert_allclose(ds.velocity.sel(body_axis="surge").values, expected, rtol=1e-7, atol=1e-12)
    assert plant.noise_size == 6
    assert VesselPlant(vessel, GaussMarkovBias(1000.0), LinearWaveModel(0.8976, 0.1, 0.0), BodyDisturbance(white_std=1.0)).noise_size == 9


def test_scaled_vessel_multiplies_entry_by_entry_and_rejects_negative_factors():
    vessel = northern_clipper()
    scaled = vessel.scaled(1.2, 1.5)
    np.testing.assert_allclose(np.asarray(scaled.mass_matrix), 1.2 * np.asarray(vessel.mass_matrix))
    np.testing.assert_allclose(np.asarray(scaled.damping_matrix), 1.5 * np.asarray(vessel.damping_matrix))
    with pytest.raises(ValueError, match="mass_scale must be finite and non-negative"):
        vessel.scaled(-0.1)
