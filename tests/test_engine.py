"""The engine: integrators, the sample order, scenario checks, records and NetCDF.

Properties every observer must have in the engine (vmap, chunks, decimation, traces,
dropouts, exactness) are in tests/test_conformance.py.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
import scipy.signal
import xarray as xr

import lookout
from lookout import DPVessel, GaussMarkovBias, LinearWaveModel, PositionHeadingSensor, SinusoidalInput, VesselPlant, VesselState
from lookout.components import Controller
from lookout.papers import fossen_strand_1999 as fs
from lookout.sim import Scenario, euler_step, rk4_step, simulate


def _linear_error(integrator, step: float, A: np.ndarray, x0: np.ndarray, horizon: float) -> float:
    field = lambda t, x: jnp.asarray(A) @ x
    x = jnp.asarray(x0)
    for i in range(int(round(horizon / step))):
        x = integrator(field, i * step, x, step)
    return float(np.linalg.norm(np.asarray(x) - scipy.linalg.expm(A * horizon) @ x0))


@pytest.mark.parametrize("integrator, order, steps", [(rk4_step, 4.0, (0.04, 0.02, 0.01)), (euler_step, 1.0, (0.004, 0.002, 0.001))])
def test_integrators_converge_with_their_order_against_expm(integrator, order, steps):
    A = np.array([[0.0, 1.0], [-4.0, -0.4]])
    x0 = np.array([1.0, 0.0])
    errors = [_linear_error(integrator, h, A, x0, 4.0) for h in steps]  # asymptotic range
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - order) < 0.15), orders


def quiet_scenario(**overrides) -> Scenario:
    """Paper scenario with no noise, no waves and no bias unless overridden."""
    config = fs.Config(
        duration=overrides.pop("duration", 20.0),
        noise_std=(0, 0, 0),
        bias_std=(0, 0, 0),
        wave_amplitude=(0, 0, 0),
        bias_initial=(0, 0, 0),
        measurement_period=overrides.pop("measurement_period", 0.1),
    )
    scenario = fs.build(config)
    for name, value in overrides.items():
        scenario = eqx.tree_at(lambda s: getattr(s, name), scenario, value)
    return scenario


@pytest.mark.parametrize("integrator", ["rk4", "euler"])
@pytest.mark.slow
def test_one_sample_of_a_linear_plant_equals_zero_order_hold_discretization(integrator):
    mass, damping = np.diag([5.0e6, 8.0e6, 3.7e9]), np.diag([5.0e4, 2.7e5, 4.2e8])
    plant = VesselPlant(DPVessel(mass, damping), GaussMarkovBias(1000.0), LinearWaveModel(0.9, 0.1))
    tau = np.array([3e4, -2e4, 0.0])  # no yaw moment: psi stays 0 and the plant is linear
    x0 = VesselState.build(eta=[1.0, -2.0, 0.0], nu=[0.3, -0.1, 0.0])
    observer = quiet_scenario().observer
    step = 0.1 if integrator == "rk4" else 1e-4
    scenario = Scenario(
        plant,
        PositionHeadingSensor(0.0, 1.0),
        observer,
        SinusoidalInput.constant(tau),
        x0,
        observer.guess(),
        plant_step=step,
        sample_period=1.0,
        duration=2.0,
        integrator=integrator,
    )
    trajectory = simulate(scenario, jax.random.key(0))
    for axis in (0, 1):
        A = np.array([[0.0, 1.0], [0.0, -damping[axis, axis] / mass[axis, axis]]])
        B = np.array([[0.0], [1.0 / mass[axis, axis]]])
        Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), 1.0, method="zoh")
        expected = Ad @ np.array([x0.eta[axis], x0.nu[axis]]) + Bd[:, 0] * tau[axis]
        got = np.array([trajectory.truth["position"][1, axis], trajectory.truth["velocity"][1, axis]])
        # RK4 is exact to rounding here; Euler's error is O(step) = 1e-4 of the motion
        np.testing.assert_allclose(got, expected, rtol=1e-10 if integrator == "rk4" else 2e-4, atol=1e-12)
    np.testing.assert_allclose(trajectory.command[0], tau, rtol=1e-12)
    np.testing.assert_allclose(trajectory.applied[0], tau, rtol=1e-12)


class EchoController(Controller):
    """Commands what it saw: the measurement (source="y") or the estimate (source="estimate")."""

    source: str = eqx.field(static=True)

    @property
    def estimate_needs(self):
        return () if self.source == "y" else ("position", "heading")

    measurement_needs = reference_needs = property(lambda self: ())

    def init(self):
        return ()

    def step(self, state, t, y, estimate, reference, dt):
        if self.source == "y":
            u = jnp.nan_to_num(y)
        else:
            u = jnp.concatenate([estimate["position"], estimate["heading"][None]])
        return state, 1e-9 * u  # tiny: the plant hardly moves, the bookkeeping is what is tested


@pytest.mark.parametrize("source", ["y", "estimate"])
@pytest.mark.slow
def test_the_controller_acts_on_the_measurement_and_estimate_of_the_same_sample(source):
    """DESIGN.md sample order: measure -> update -> output -> controller, so u_k is a
    function of y_k and of the estimate at t_k, not of the previous sample's."""
    scenario = fs.build(fs.Config(duration=20.0, measurement_period=0.1))
    scenario = eqx.tree_at(lambda s: s.controller, scenario, EchoController(source))
    trajectory = simulate(scenario, jax.random.key(4))
    if source == "y":
        expected = np.nan_to_num(np.asarray(trajectory.measurement))
    else:
        expected = np.column_stack([trajectory.estimate["position"], trajectory.estimate["heading"]])
    np.testing.assert_allclose(np.asarray(trajectory.command) / 1e-9, expected, rtol=1e-12, atol=1e-15)
    # and the measurement of sample k is of the plant state at t_k (noise-free channels would equal it)


def test_the_first_estimate_is_the_guess_and_the_first_sample_is_of_the_initial_state():
    scenario = quiet_scenario(duration=2.0)
    guess = scenario.observer.guess(eta=[3.0, -1.0, 0.2])
    start = VesselState.build(eta=[1.0, 2.0, 0.1])
    scenario = eqx.tree_at(lambda s: (s.initial_state, s.initial_estimate), scenario, (start, guess))
    trajectory = simulate(scenario, jax.random.key(0))
    np.testing.assert_array_equal(trajectory.estimate["position"][0], [3.0, -1.0])
    np.testing.assert_allclose(trajectory.measurement[0], [1.0, 2.0, 0.1], rtol=1e-15)


def _heading_run(psi0: float):
    start = VesselState.build(eta=[0.0, 0.0, psi0], nu=[0.0, 0.0, 0.01])
    scenario = quiet_scenario(duration=40.0, initial_state=start)
    scenario = eqx.tree_at(lambda s: s.initial_estimate, scenario, start)
    return simulate(scenario, jax.random.key(0)).to_xarray().isel(run=0)


def test_heading_wraps_across_pi_in_plant_measurement_and_observer():
    ds = _heading_run(np.pi - 0.05)
    heading = ds.heading.values
    assert heading.max() > 3.1 and heading.min() < -3.1, "the run must cross +-pi"
    for values in (heading, ds.heading_hat.values, ds.measured_heading.values):
        assert np.all(values >= -np.pi) and np.all(values < np.pi)
    # The yaw dynamics do not depend on absolute heading, so the heading error of a
    # run that crosses +-pi equals that of the same run started far from the wrap.
    far = _heading_run(-0.05)
    error = np.angle(np.exp(1j * (heading - ds.heading_hat.values)))
    np.testing.assert_allclose(error, far.heading.values - far.heading_hat.values, atol=1e-12)
    np.testing.assert_allclose(ds.velocity_hat.values, far.velocity_hat.values, atol=1e-12)


def test_all_channels_dropped_means_pure_prediction(paper_observer):
    estimate = paper_observer.guess(eta=[1.0, 2.0, 0.1], nu=[0.1, 0.0, 0.0])
    missing = jnp.full(3, jnp.nan)
    assert np.all(np.asarray(paper_observer.innovation(estimate, missing)) == 0.0)
    stepped = paper_observer.predict(estimate, 0.0, missing, jnp.zeros(3), 0.1)
    assert all(np.all(np.isfinite(np.asarray(leaf))) for leaf in jax.tree.leaves(stepped))


def test_missing_heading_holds_the_predicted_heading_over_the_sample(paper_observer):
    """J(y) is held over the sample like y: with the heading missing, the predicted
    heading at t stands in for it in every RK4 stage; with it present, the measured one."""
    estimate = paper_observer.guess(eta=[1.0, 2.0, 0.3], nu=[0.5, -0.2, 0.05], bias=[1e3, -2e3, 1e4])
    tau = jnp.asarray([1e4, -5e3, 2e5])
    for measurement, heading in (
        (jnp.asarray([1.5, 2.5, jnp.nan]), 0.3),  # psi_hat + psi_hat_w at t
        (jnp.asarray([1.5, 2.5, 0.35]), 0.35),
    ):
        stepped = paper_observer.predict(estimate, 0.0, measurement, tau, 0.1)
        field = lambda t, x: paper_observer.vector_field(t, x, measurement, tau, jnp.asarray(heading))
        expected = rk4_step(field, 0.0, estimate, 0.1).wrapped()
        for a, b in zip(jax.tree.leaves(stepped), jax.tree.leaves(expected)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-14, atol=1e-15)
    # the default heading of the vector field is the per-stage prediction (continuous mode)
    missing = jnp.asarray([1.5, 2.5, jnp.nan])
    moved = paper_observer.guess(eta=[1.0, 2.0, 0.9], nu=[0.5, -0.2, 0.05], bias=[1e3, -2e3, 1e4])
    default = paper_observer.vector_field(0.0, moved, missing, tau)
    explicit = paper_observer.vector_field(0.0, moved, missing, tau, jnp.asarray(0.9))
    np.testing.assert_array_equal(np.asarray(default.nu), np.asarray(explicit.nu))


def _rebuild(base: Scenario, **changes) -> Scenario:
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
    fields.update(changes)
    return Scenario(**fields)


@pytest.mark.parametrize(
    "changes, message",
    [
        (
            {"plant_step": 0.1, "sample_period": 0.15, "duration": 3.0},
            r"sample_period \(0.15 s\) must be an integer multiple of plant_step \(0.1 s\)",
        ),
        ({"plant_step": 0.1, "sample_period": 0.1, "duration": 3.05}, r"duration \(3.05 s\) must be an integer multiple"),
        ({"plant_step": -0.1}, "plant_step must be positive"),
        ({"integrator": "midpoint"}, r"integrator must be one of \['euler', 'rk4'\]; got 'midpoint'"),
        (
            {"sensor": PositionHeadingSensor(0.0, [0.25, 1.0, 1.0])},
            r"sensor sample_period\[0\] \(0.25 s\) must be an integer multiple of sample_period",
        ),
        # the process noise of a sample is one draw of at most 65536 numbers: a step so short it cannot be is refused, not run for days
        (
            {"plant_step": 1e-9},
            r"^plant_step \(1e-09 s\) makes 100000000 plant steps per sample of 0.1 s; at most 10922 \(6 process noise inputs each\): a plant_step of at least 9.16e-06 s$",
        ),
        # an outage that would silence nothing is no outage
        (
            {"sensor": PositionHeadingSensor(0.0, 1.0, outage_signals=["measured_position"], outage_start=10.0, outage_duration=5.0)},
            r"^sensor outage_start \(10 s\) must be before the run's end \(duration 10 s\)",
        ),
    ],
)
def test_scenario_rejects_inconsistent_rates(changes, message):
    base = fs.build(fs.Config(duration=10.0))
    with pytest.raises(ValueError, match=message):
        _rebuild(base, **changes)


def test_scenario_names_the_two_parts_that_do_not_fit():
    base = fs.build(fs.Config(duration=10.0))
    cases = [
        ({"plant": "not a plant"}, "^plant must be a lookout Plant; got str$"),
        (
            {"controller": SinusoidalInput(1.0, 0.1, size=2)},
            r"^controller and plant disagree: the controller's input has shape \(2,\), the plant takes \(3,\)$",
        ),
        (
            {"initial_state": VesselState.build().__class__(jnp.zeros(2), jnp.zeros(3), jnp.zeros(3), jnp.zeros(6))},
            "^plant and initial_state do not fit: ",
        ),
        ({"initial_estimate": jnp.zeros(4)}, "^observer and (initial_estimate|sensor) do not fit: "),
    ]
    for changes, message in cases:
        with pytest.raises(ValueError, match=message) as raised:
            _rebuild(base, **changes)
        assert "\n" not in str(raised.value)


def test_continuous_mode_needs_a_continuous_observer():
    from lookout.components import Layout, Observer
    from lookout.models.vessel import VESSEL_INPUT
    from lookout.sensors import POSITION_HEADING

    class Frozen(Observer):
        estimate_signals: tuple = eqx.field(static=True, default=(), kw_only=True)
        extra_signals: tuple = eqx.field(static=True, default=(), kw_only=True)
        measurement_layout: Layout = eqx.field(static=True, default=POSITION_HEADING, kw_only=True)
        input_layout: Layout = eqx.field(static=True, default=VESSEL_INPUT, kw_only=True)
        sample_period: None = eqx.field(static=True, default=None, kw_only=True)

        def guess(self):
            return None

        def init(self, y0, guess):
            return ()

        def update(self, state, t, y):
            return state

        def output(self, state, y):
            return {}

        def predict(self, state, t, y, u, dt):
            return state

    base = fs.build(fs.Config(duration=10.0))
    with pytest.raises(ValueError, match="observer_mode 'continuous' needs a ContinuousObserver; observer Frozen is not one"):
        _rebuild(base, observer=Frozen(), initial_estimate=None, observer_mode="continuous")
    # the same observer runs in sampled mode: an estimate of nothing
    ds = simulate(_rebuild(base, observer=Frozen(), initial_estimate=None), jax.random.key(0)).to_xarray()
    assert "position" in ds and "position_hat" not in ds


def test_netcdf_is_cf_compressed_and_round_trips(tmp_path):
    trajectory = simulate(fs.build(fs.Config(duration=20.0)), jax.random.key(0))
    path = trajectory.to_netcdf(tmp_path / "run.nc")
    loaded = xr.load_dataset(path)
    assert loaded.attrs["Conventions"] == "CF-1.10" and "lookout" in loaded.attrs["history"] and loaded.attrs["lookout_version"]
    assert {"run", "time", "earth_axis", "body_axis"} <= set(loaded.dims)
    assert loaded.earth_axis.values.tolist() == ["north", "east"] and loaded.body_axis.values.tolist() == ["surge", "sway"]
    units = {
        name: loaded[name].attrs["units"] for name in ("position", "heading", "velocity", "yaw_rate", "bias_force", "bias_moment", "force_applied")
    }
    assert units == {
        "position": "m",
        "heading": "rad",
        "velocity": "m/s",
        "yaw_rate": "rad/s",
        "bias_force": "N",
        "bias_moment": "N m",
        "force_applied": "N",
    }
    assert loaded.position.attrs["frame"] == "Earth-fixed" and loaded.velocity.attrs["frame"] == "body-fixed"
    assert loaded.heading.attrs["angle"] == 1 and loaded.position.attrs["angle"] == 0
    with xr.open_dataset(path, engine="netcdf4") as raw:
        assert raw.position.encoding["zlib"] and raw.position.encoding["complevel"] == 4
    np.testing.assert_allclose(loaded.velocity_hat.values, trajectory.to_xarray().velocity_hat.values)


def test_dropout_decision_matches_the_normal_cdf():
    """A channel drops when Phi(n) < p (SciPy's ndtr), computed as n < Phi^-1(p)."""
    from scipy.special import ndtr

    sensor = PositionHeadingSensor([0.5, 0.5, 0.002], 1.0, dropout_probability=0.3)
    normals = np.random.default_rng(3).standard_normal((20_000, 6))
    y = jax.vmap(lambda n: sensor.measure(VesselState.zeros(), n))(jnp.asarray(normals))
    np.testing.assert_array_equal(np.isnan(np.asarray(y)), ndtr(normals[:, 3:]) < 0.3)
    assert abs(np.isnan(np.asarray(y)).mean() - 0.3) < 0.01


def test_a_manipulator_scenario_refuses_an_observer_or_sensor_of_another_arm():
    """A 1-DOF observer on a 2-DOF plant, and a 1-channel encoder on it: one line each."""
    from lookout.controllers import SinusoidalInput
    from lookout.models.manipulators import FreePendulum, ManipulatorPlant, TwoLinkArm
    from lookout.observers import VelocityObserver
    from lookout.sensors import JointEncoder

    arm, pendulum = TwoLinkArm(), FreePendulum()
    plant = ManipulatorPlant(arm)
    parts = dict(
        plant=plant,
        sensor=JointEncoder(arm, sample_period=0.01),
        observer=VelocityObserver(arm, 5.0),
        controller=SinusoidalInput.constant([2.0, 1.0]),
        initial_state=plant.state([0.1, 0.2]),
        initial_estimate=jnp.zeros(2),
        plant_step=0.01,
        sample_period=0.01,
        duration=1.0,
    )
    Scenario(**parts)  # the arm's own parts fit
    with pytest.raises(
        ValueError, match=r"^observer and plant disagree: the estimate 'joint_rate' is \(1,\) in rad/s over \('pendulum',\), the plant's is \(2,\)"
    ) as raised:
        Scenario(**parts | {"observer": VelocityObserver(pendulum, 1.2), "initial_estimate": jnp.zeros(1)})
    assert "\n" not in str(raised.value)
    with pytest.raises(ValueError, match=r"^sensor and plant do not fit: ") as raised:
        Scenario(**parts | {"sensor": JointEncoder(pendulum, sample_period=0.01)})
    assert "\n" not in str(raised.value)


@pytest.mark.slow
def test_keys_of_seeds_and_stacked_scenarios_give_the_single_runs():
    from lookout.papers import fossen_strand_1999 as fs
    from lookout.sim import keys_of_seeds, seed_keys, simulate, simulate_batch, stack_scenarios

    keys = keys_of_seeds([3, 5])
    assert jax.random.key_data(keys[1]).tolist() == jax.random.key_data(seed_keys(5, 1)[0]).tolist()
    base = fs.build(fs.Config(duration=20.0))
    other = dataclasses.replace(base, initial_state=base.plant.state(eta=[5.0, 0.0, 0.0]))
    batch = simulate_batch(stack_scenarios([base, other]), keys, batched_scenario=True)
    for i, scenario in enumerate((base, other)):
        single = simulate(scenario, keys[i])
        np.testing.assert_allclose(np.asarray(batch.truth["position"])[i], np.asarray(single.truth["position"]), rtol=1e-12, atol=1e-12)


def test_sizes_from_the_caller_are_checked_against_memory_before_anything_is_allocated(monkeypatch):
    from lookout import _resources
    from lookout.sim import check_batch_memory, keys_of_seeds, seed_keys, simulate_batch, stack_scenarios

    with pytest.raises(
        ValueError, match=r"^runs: 1000000000000 keys x 16 B would need about 16 TB of memory, and .* are available: make fewer keys at a time$"
    ):
        seed_keys(0, 10**12)
    with pytest.raises(ValueError, match=r"^seeds: 1000000000000 keys x 52 B would need about 52 TB of memory"):
        keys_of_seeds(range(10**12))
    scenario = fs.build(fs.Config(duration=100.0))
    # 1000 records x (1000 runs x 296 B, twice, + 32 B): 592 MB
    with pytest.raises(
        ValueError,
        match=r"^keys: 1000 run\(s\) x 1000 records x 296 B \(x2 at the peak, \+ 32 B per record\) would need about 592 MB of memory, and 100 MB are available",
    ):
        check_batch_memory(scenario, 1000, available=100e6)
    monkeypatch.setattr(_resources, "available_memory", lambda: 1_000_000)
    with pytest.raises(
        ValueError,
        match=r"^keys: 4 run\(s\) x 1000 records x 296 B \(x2 at the peak, \+ 32 B per record\) would need about 2.4 MB of memory, and 1 MB are available",
    ):
        simulate_batch(scenario, jax.random.split(jax.random.key(0), 4))
    monkeypatch.setattr(_resources, "available_memory", lambda: 500_000)
    with pytest.raises(
        ValueError,
        match=r"^scenario: 1 run\(s\) x 1000 records x 296 B \(x2 at the peak, \+ 32 B per record\) would need about 624 kB of memory, and 500 kB are available",
    ):
        simulate(scenario, jax.random.key(0))
    with pytest.raises(ValueError, match=r"^scenarios: 10000 stacked x \d+ B of arrays would need about"):
        stack_scenarios([scenario] * 10000)


def test_the_memory_check_counts_what_a_run_holds_while_it_takes_a_sample():
    """An EKF linearizes through every plant step of a sample: 64 of them on the DP vessel
    hold a Jacobian over 402 columns. The batch check adds that to the records, and a
    filter with more steps than it takes is refused naming plant_step."""
    from lookout.observers.kalman import working_nbytes as kalman_bytes
    from lookout.scenario.composition import CompositionError, compose
    from lookout.scenario.registry import preset
    from lookout.sim import check_batch_memory, record_nbytes, working_nbytes

    document = preset("fossen-strand-1999", "paper")
    document["simulation"].update(duration=10.0, plant_step=0.1 / 64)
    document["observer"] = {"kind": "ekf"}
    scenario = compose(document).scenario
    working = working_nbytes(scenario)
    assert working == 64 * 6 * 8 + kalman_bytes(scenario.observer.state_size, 64, 6)
    runs = 1000
    records = scenario.n_records * (2 * runs * record_nbytes(scenario) + 32)
    check_batch_memory(scenario, runs, available=records + 1.01 * runs * working)
    with pytest.raises(
        ValueError,
        match=r"^keys: 1000 run\(s\) x 100 records x \d+ B \(x2 at the peak, \+ 32 B per record\) \+ 1000 x [\d.]+ MB while a sample is taken would need",
    ):
        check_batch_memory(scenario, runs, available=records + 0.99 * runs * working)
    document["simulation"]["plant_step"] = 0.1 / 128
    with pytest.raises(
        CompositionError,
        match=r"plant_step \(0.00078125 s\) makes 128 propagation steps per sample of 0.1 s, .*: at most 64; give the filter a plant_step of its own of at least 0.00156 s",
    ):
        compose(document)


@pytest.mark.parametrize(
    "call, message",
    [
        (
            lambda sc: simulate(sc, lookout.seed_keys(0, 1)),
            r"^key must be one JAX PRNG key .*got an array of shape \(1,\) and dtype key<fry>: a batch of keys goes to simulate_batch$",
        ),
        (lambda sc: simulate(sc, 0), r"^key must be one JAX PRNG key .*got int$"),
        (lambda sc: simulate(None, jax.random.key(0)), r"^scenario must be a lookout Scenario .*got NoneType$"),
        (
            lambda sc: lookout.simulate_batch(sc, lookout.seed_keys(0, 1)[0]),
            r"^keys must be a 1-D batch of JAX PRNG keys, one per run .*got an array of shape \(\)",
        ),
        (lambda sc: lookout.simulate_batch(sc, [0, 1, 2]), r"^keys must be a 1-D batch .*got list$"),
        (
            lambda sc: lookout.simulate_batch(lookout.stack_scenarios([sc] * 4), lookout.seed_keys(0, 3), batched_scenario=True),
            r"^scenario: with batched_scenario=True every array of the scenario needs a leading run axis of 3 \(one per key\); its arrays lead with 4$",
        ),
        (
            lambda sc: lookout.simulate_batch(lookout.stack_scenarios([sc] * 5), lookout.seed_keys(0, 5)),
            r"^scenario: plant and initial_state disagree: .*; a scenario stacked per run \(stack_scenarios\) needs batched_scenario=True$",
        ),
        (
            lambda sc: lookout.stack_scenarios([sc, fs.build(fs.Config(duration=30.0))]),
            r"^scenarios\[1\] differs from scenarios\[0\] in its structure",
        ),
        (lambda sc: lookout.stack_scenarios([]), r"^scenarios must be a non-empty list of Scenarios; got \[\]$"),
        (lambda sc: lookout.stack_scenarios([sc, "x"]), r"^scenarios\[1\] must be a lookout Scenario; got str$"),
        (lambda sc: lookout.seed_keys(0, True), r"^runs must be a positive integer; got True$"),
    ],
    ids=lambda value: "" if callable(value) else value[:30],
)
def test_the_simulation_api_refuses_what_it_cannot_run_in_one_line(call, message):
    with pytest.raises(ValueError, match=message) as raised:
        call(fs.build(fs.Config(duration=20.0)))
    assert "\n" not in str(raised.value)
