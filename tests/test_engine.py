import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from lookout import DPVessel, GaussMarkovBias, LinearWaveModel, PositionHeadingSensor, SinusoidalThrust, VesselPlant, VesselState
from lookout.papers import fossen_strand_1999 as fs
from lookout.sim import Scenario, rk4_step, simulate, simulate_batch


def _linear_rk4_error(step: float, A: np.ndarray, x0: np.ndarray, horizon: float) -> float:
    field = lambda t, x: jnp.asarray(A) @ x
    x = jnp.asarray(x0)
    for i in range(int(round(horizon / step))):
        x = rk4_step(field, i * step, x, step)
    return float(np.linalg.norm(np.asarray(x) - scipy.linalg.expm(A * horizon) @ x0))


def test_rk4_converges_with_order_four_against_expm():
    A = np.array([[0.0, 1.0], [-4.0, -0.4]])
    x0 = np.array([1.0, 0.0])
    errors = [_linear_rk4_error(h, A, x0, 4.0) for h in (0.04, 0.02, 0.01)]  # asymptotic range
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 4.0) < 0.15), orders


def _quiet_scenario(**overrides) -> Scenario:
    """Paper scenario with no noise, no waves and no bias unless overridden."""
    config = fs.Config(duration=overrides.pop("duration", 20.0), noise_std=(0, 0, 0), bias_std=(0, 0, 0), wave_amplitude=(0, 0, 0), bias_initial=(0, 0, 0), measurement_period=overrides.pop("measurement_period", 0.1))
    scenario = fs.build(config)
    for name, value in overrides.items():
        scenario = eqx.tree_at(lambda s: getattr(s, name), scenario, value)
    return scenario


def test_one_sample_of_a_linear_plant_equals_zero_order_hold_discretization():
    mass, damping = np.diag([5.0e6, 8.0e6, 3.7e9]), np.diag([5.0e4, 2.7e5, 4.2e8])
    vessel = DPVessel(mass, damping)
    plant = VesselPlant(vessel, GaussMarkovBias(1000.0), LinearWaveModel(0.9, 0.1))
    tau = np.array([3e4, -2e4, 0.0])  # no yaw moment: psi stays 0 and the plant is linear
    thrust = SinusoidalThrust(tau, 0.0, np.pi / 2)  # constant tau
    x0 = VesselState.build(eta=[1.0, -2.0, 0.0], nu=[0.3, -0.1, 0.0])
    observer = _quiet_scenario().observer
    scenario = Scenario(plant, PositionHeadingSensor(0.0, 1.0), observer, thrust, x0, observer.init(), plant_step=0.1, sample_period=1.0, duration=2.0)
    trajectory = simulate(scenario, jax.random.key(0))
    for axis in (0, 1):
        A = np.array([[0.0, 1.0], [0.0, -damping[axis, axis] / mass[axis, axis]]])
        B = np.array([[0.0], [1.0 / mass[axis, axis]]])
        Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), 1.0, method="zoh")
        expected = Ad @ np.array([x0.eta[axis], x0.nu[axis]]) + Bd[:, 0] * tau[axis]
        got = np.array([trajectory.state.eta[1, axis], trajectory.state.nu[1, axis]])
        np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(trajectory.control[0], tau, rtol=1e-12)


def test_vmapped_runs_equal_the_same_runs_one_by_one():
    scenario = fs.build(fs.Config(duration=60.0))
    if jax.default_backend() == "cpu":
        assert len(jax.devices()) == 2, "conftest exposes two host devices, so the batch below is sharded"
    keys = jax.random.split(jax.random.key(7), 4)
    batch = simulate_batch(scenario, keys)
    for i in range(4):
        single = simulate(scenario, keys[i])
        for name in ("eta", "nu", "bias", "wave_state"):
            np.testing.assert_allclose(getattr(batch.estimate, name)[i], getattr(single.estimate, name), rtol=1e-11, atol=1e-9)
            np.testing.assert_allclose(getattr(batch.state, name)[i], getattr(single.state, name), rtol=1e-11, atol=1e-9)
    ds = batch.to_xarray()
    assert ds.sizes["run"] == 4 and list(ds.status.values) == ["finite"] * 4


def test_batched_scenario_maps_over_initial_conditions():
    base = fs.build(fs.Config(duration=30.0))
    starts = [VesselState.build(eta=[0.0, 0.0, 0.0]), VesselState.build(eta=[5.0, -3.0, 1.0])]
    scenarios = [eqx.tree_at(lambda s: s.initial_state, base, start) for start in starts]
    stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves), *scenarios)
    keys = jax.random.split(jax.random.key(3), 2)
    batch = simulate_batch(stacked, keys, batched_scenario=True)
    for i, scenario in enumerate(scenarios):
        single = simulate(scenario, keys[i])
        np.testing.assert_allclose(batch.state.eta[i], single.state.eta, rtol=1e-11, atol=1e-9)


def test_progress_segments_give_the_same_run():
    scenario = fs.build(fs.Config(duration=50.0))
    calls = []
    chunked = simulate(scenario, jax.random.key(1), progress=lambda done, total: calls.append((done, total)), chunks=3)
    whole = simulate(scenario, jax.random.key(1))
    np.testing.assert_allclose(chunked.estimate.eta, whole.estimate.eta, rtol=1e-12, atol=1e-12)
    assert calls[-1] == (500, 500) and len(calls) >= 3


def _heading_run(psi0: float):
    start = VesselState.build(eta=[0.0, 0.0, psi0], nu=[0.0, 0.0, 0.01])
    scenario = _quiet_scenario(duration=40.0, initial_state=start)
    scenario = eqx.tree_at(lambda s: s.initial_estimate, scenario, start)
    return simulate(scenario, jax.random.key(0)).to_xarray().isel(run=0)


def test_heading_wraps_across_pi_in_plant_measurement_and_observer():
    ds = _heading_run(np.pi - 0.05)
    heading = ds.eta.sel(dof="yaw").values
    assert heading.max() > 3.1 and heading.min() < -3.1, "the run must cross +-pi"
    for values in (heading, ds.eta_hat.sel(dof="yaw").values, ds.measurement.sel(dof="yaw").values):
        assert np.all(values >= -np.pi) and np.all(values < np.pi)
    # The yaw dynamics do not depend on absolute heading, so the heading error of a
    # run that crosses +-pi equals that of the same run started far from the wrap.
    far = _heading_run(-0.05)
    error = np.angle(np.exp(1j * (heading - ds.eta_hat.sel(dof="yaw").values)))
    error_far = far.eta.sel(dof="yaw").values - far.eta_hat.sel(dof="yaw").values
    np.testing.assert_allclose(error, error_far, atol=1e-12)
    np.testing.assert_allclose(ds.nu_hat.values, far.nu_hat.values, atol=1e-12)


def test_dropouts_leave_estimates_finite():
    scenario = fs.build(fs.Config(duration=200.0))
    scenario = eqx.tree_at(lambda s: s.sensor, scenario, PositionHeadingSensor([0.5, 0.5, 0.002], 1.0, dropout_probability=0.5))
    ds = simulate(scenario, jax.random.key(2)).to_xarray()
    assert np.isnan(ds.measurement.values).any()
    for name in ("eta_hat", "nu_hat", "bias_hat", "wave_hat"):
        assert np.all(np.isfinite(ds[name].values))
    assert ds.status.values.tolist() == ["finite"]


def test_all_channels_dropped_means_pure_prediction(paper_observer):
    estimate = paper_observer.init(eta=[1.0, 2.0, 0.1], nu=[0.1, 0.0, 0.0])
    missing = jnp.full(3, jnp.nan)
    assert np.all(np.asarray(paper_observer.innovation(estimate, missing)) == 0.0)
    stepped, _ = paper_observer.step(estimate, 0.0, missing, jnp.zeros(3), 0.1)
    assert all(np.all(np.isfinite(np.asarray(leaf))) for leaf in jax.tree.leaves(stepped))


def test_missing_heading_holds_the_predicted_heading_over_the_sample(paper_observer):
    """J(y) is held over the sample like y: with the heading missing, the predicted
    heading at t stands in for it in every RK4 stage; with it present, the measured one."""
    from lookout.sim.integrators import rk4_step

    estimate = paper_observer.init(eta=[1.0, 2.0, 0.3], nu=[0.5, -0.2, 0.05], bias=[1e3, -2e3, 1e4])
    tau = jnp.asarray([1e4, -5e3, 2e5])
    for measurement, heading in (
        (jnp.asarray([1.5, 2.5, jnp.nan]), 0.3),  # psi_hat + psi_hat_w at t
        (jnp.asarray([1.5, 2.5, 0.35]), 0.35),
    ):
        stepped, _ = paper_observer.step(estimate, 0.0, measurement, tau, 0.1)
        field = lambda t, x: paper_observer.vector_field(t, x, measurement, tau, jnp.asarray(heading))
        expected = rk4_step(field, 0.0, estimate, 0.1).wrapped()
        for a, b in zip(jax.tree.leaves(stepped), jax.tree.leaves(expected)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-14, atol=1e-15)
    # the default heading of the vector field is the per-stage prediction (continuous mode)
    missing = jnp.asarray([1.5, 2.5, jnp.nan])
    moved = paper_observer.init(eta=[1.0, 2.0, 0.9], nu=[0.5, -0.2, 0.05], bias=[1e3, -2e3, 1e4])
    default = paper_observer.vector_field(0.0, moved, missing, tau)
    explicit = paper_observer.vector_field(0.0, moved, missing, tau, jnp.asarray(0.9))
    np.testing.assert_array_equal(np.asarray(default.nu), np.asarray(explicit.nu))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"plant_step": 0.1, "sample_period": 0.15, "duration": 3.0}, r"sample_period \(0.15 s\) must be an integer multiple of plant_step \(0.1 s\)"),
        ({"plant_step": 0.1, "sample_period": 0.1, "duration": 3.05}, r"duration \(3.05 s\) must be an integer multiple"),
        ({"plant_step": -0.1, "sample_period": 0.1, "duration": 3.0}, "plant_step must be positive"),
    ],
)
def test_scenario_rejects_inconsistent_rates(kwargs, message):
    base = fs.build(fs.Config(duration=10.0))
    with pytest.raises(ValueError, match=message):
        Scenario(base.plant, base.sensor, base.observer, base.control, base.initial_state, base.initial_estimate, **kwargs)


def test_sensor_period_must_be_multiple_of_sample_period():
    base = fs.build(fs.Config(duration=10.0))
    with pytest.raises(ValueError, match=r"sensor sample_period\[0\] \(0.25 s\) must be an integer multiple of sample_period"):
        Scenario(base.plant, PositionHeadingSensor(0.0, [0.25, 1.0, 1.0]), base.observer, base.control, base.initial_state, base.initial_estimate, plant_step=0.1, sample_period=0.1, duration=10.0)


def test_netcdf_round_trip(tmp_path):
    import xarray as xr

    trajectory = simulate(fs.build(fs.Config(duration=20.0)), jax.random.key(0))
    path = trajectory.to_netcdf(tmp_path / "run.nc")
    loaded = xr.load_dataset(path)
    assert set(loaded.dims) == {"run", "time", "dof"}
    assert loaded.eta.attrs["units"] == "surge: m, sway: m, yaw: rad"
    np.testing.assert_allclose(loaded.nu_hat.values, trajectory.to_xarray().nu_hat.values)


def test_repeated_runs_with_new_gains_do_not_recompile():
    from lookout.sim.engine import _initial_carry, _segment

    base = fs.build(fs.Config(duration=10.0))
    counted = eqx.debug.assert_max_traces(_segment, max_traces=1)
    run = eqx.filter_jit(counted)
    carry = _initial_carry(base)
    for gain in (1.0, 2.0, 3.0):
        scenario = eqx.tree_at(lambda s: s.observer.position_injection_gain, base, jnp.full(3, gain))
        run(scenario, jax.random.key(0), carry, jnp.asarray(0), 100)


def test_dropout_decision_matches_the_normal_cdf():
    """A channel drops when Phi(n) < p (SciPy's ndtr), computed as n < Phi^-1(p)."""
    from scipy.special import ndtr

    from lookout.models import VesselState

    sensor = PositionHeadingSensor([0.5, 0.5, 0.002], 1.0, dropout_probability=0.3)
    normals = np.random.default_rng(3).standard_normal((20_000, 6))
    y = jax.vmap(lambda n: sensor.measure(VesselState.zeros(), n))(jnp.asarray(normals))
    np.testing.assert_array_equal(np.isnan(np.asarray(y)), ndtr(normals[:, 3:]) < 0.3)
    assert abs(np.isnan(np.asarray(y)).mean() - 0.3) < 0.01


@pytest.mark.parametrize("every", [3, 10])
def test_decimated_records_are_every_nth_sample_of_the_full_run(every):
    """record_every only thins the records: the noise of sample k depends on (key, k) alone.

    The two programs are compiled apart, and XLA may fuse (and so round) them
    differently: agreement is to a few ulp, where a shifted noise stream would differ
    at the size of the signal.
    """
    import dataclasses

    full = fs.build(fs.Config(duration=30.0))
    thin = dataclasses.replace(full, record_every=every)
    key = jax.random.key(5)
    a, b = simulate(full, key), simulate(thin, key)
    np.testing.assert_array_equal(b.time, a.time[::every])
    for name in ("state", "estimate"):
        for x, y in zip(jax.tree.leaves(getattr(a, name)), jax.tree.leaves(getattr(b, name))):
            np.testing.assert_allclose(np.asarray(y), np.asarray(x)[::every], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(b.measurement), np.asarray(a.measurement)[::every], rtol=1e-12, atol=1e-15)
