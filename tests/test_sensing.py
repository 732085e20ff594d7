"""Sensor suites (lookout.sensing) against references: lever arms against the geometry
p + R(psi) r, each failure mode against the same run without it, the IMU against the
plant's vector field at the applied input, one noise stream per instrument, vmapped
runs and a campaign over a failure's start, and every bad sensor table refused in one
line at its key."""

from __future__ import annotations

import copy
import tomllib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout.cli import main
from lookout.models.vessel import VesselState
from lookout.scenario import metrics as metric_module
from lookout.scenario.composition import CompositionError, compose
from lookout.scenario.file import from_document
from lookout.sensing.combining import WeightedMean
from lookout.sensing.failures import failure_from_table
from lookout.sensing.heading import Gyrocompass
from lookout.sensing.position import GnssReceiver, HydroacousticReference
from lookout.sensing.suite import SensorSuite
from lookout.sim import keys_of_seeds, simulate, simulate_batch
from lookout.sim.scenario import structure_key
from lookout.studies.campaign import campaign_from_document
from lookout.studies.execute import run_campaign
from lookout.studies.store import CampaignStore

DT = 0.1
KEY = keys_of_seeds([3])[0]
LEVER = np.array([30.0, 5.0])


def _rotate(heading: np.ndarray, arm: np.ndarray) -> np.ndarray:
    """R(psi) r per sample: (..., 2)."""
    c, s = np.cos(heading), np.sin(heading)
    return np.stack([c * arm[0] - s * arm[1], s * arm[0] + c * arm[1]], axis=-1)


def _document(sensors: dict, duration: float, controller: dict | None = None) -> dict:
    """A calm sea (no waves, no bias noise: the truth is deterministic), the vessel
    turning under an open-loop thrust, and the suite ``sensors``."""
    return {
        "simulation": {"duration": duration, "plant_step": DT, "sample_period": DT},
        "plant": {
            "kind": "dp-vessel",
            "bias": {"time_constant": 1000.0, "std": [0.0, 0.0, 0.0]},
            "waves": {"kind": "linear", "peak_frequency": 0.8976, "damping_ratio": 0.1, "amplitude": [0.0, 0.0, 0.0]},
            "initial": {"eta": [0.0, 0.0, 0.0], "nu": [0.5, 0.0, 0.03], "bias": [1e4, -2e4, 1e5]},
        },
        "controller": controller or {"kind": "sinusoidal", "amplitude": 0.0, "frequency": 0.0, "offset": [2e5, 1e5, 2e7]},
        "sensors": copy.deepcopy(sensors),
        "observer": {"kind": "passive"},
    }


def _dataset(trajectory):
    ds = trajectory.to_xarray()
    return ds.isel(run=0) if "run" in ds.dims else ds


def _values(ds, name: str) -> np.ndarray:
    return np.asarray(ds[name].values)


# ----------------------------------------------------------------------------------
# lever arms and the IMU: a vessel turning through more than 90 degrees

# the thrust varies from sample to sample, so that the input an IMU sample sees (the
# one applied over the interval before it) differs from the one applied after it
VARYING_THRUST = {"kind": "sinusoidal", "amplitude": [1e5, 1e5, 1e7], "frequency": 0.5, "offset": [2e5, 1e5, 2e7]}
IMU_BIAS, GYRO_BIAS = [0.01, -0.02], 0.001


def _turning_sensors(gnss_std: float, gyro_std: float, imu_std: float) -> dict:
    return {
        "dgnss1": {"kind": "gnss", "lever_arm": LEVER.tolist(), "noise_std": gnss_std, "sample_period": DT},
        "gyro1": {"kind": "gyrocompass", "noise_std": gyro_std},
        "imu": {
            "kind": "imu",
            "accelerometer_std": imu_std,
            "gyro_std": imu_std,
            "accelerometer_bias": IMU_BIAS,
            "gyro_bias": GYRO_BIAS,
        },
        "imu_bow": {"kind": "imu", "lever_arm": [10.0, -2.0], "accelerometer_std": imu_std, "gyro_std": imu_std},
    }


@pytest.fixture(scope="module")
def turning():
    """``(composition, noiseless dataset, noisy dataset)``: one program (the noise levels
    are arrays), two runs."""
    noiseless = compose(_document(_turning_sensors(0.0, 0.0, 0.0), 40.0, VARYING_THRUST))
    noisy = compose(_document(_turning_sensors(0.5, 0.002, 0.01), 40.0, VARYING_THRUST))
    return noiseless, _dataset(simulate(noiseless.scenario, KEY)), _dataset(simulate(noisy.scenario, KEY))


@pytest.mark.slow
def test_the_run_turns_through_more_than_90_degrees(turning):
    _, ds, _ = turning
    heading = _values(ds, "heading")
    assert np.ptp(np.unwrap(heading)) > np.pi / 2
    np.testing.assert_array_equal(_values(ds, "wave_position"), 0.0)  # the truth position is the total one


def test_a_gnss_measures_its_antenna_at_the_lever_arm(turning):
    """Noiseless: the raw fix minus the reference point is R(psi) r, to rounding."""
    _, ds, _ = turning
    error = _values(ds, "dgnss1.measured_position") - _values(ds, "position")
    np.testing.assert_allclose(error, _rotate(_values(ds, "heading"), LEVER), rtol=0, atol=1e-9)


def test_the_combined_position_takes_the_lever_arm_back(turning):
    """Noiseless: the combined position is the reference point, to rounding; noisy
    (GNSS 0.5 m, gyro 2 mrad): its mean error over N fixes is below 3 sigma / sqrt(N)
    per axis, sigma the fix's noise with the gyro's error times the lever arm, and its
    RMS error is that sigma within 10 %."""
    _, quiet, noisy = turning
    np.testing.assert_allclose(_values(quiet, "measured_position"), _values(quiet, "position"), rtol=0, atol=1e-9)
    np.testing.assert_allclose(_values(quiet, "measured_heading"), _values(quiet, "heading"), rtol=0, atol=1e-12)
    error = _values(noisy, "measured_position") - _values(noisy, "position")
    sigma = np.sqrt(0.5**2 + (0.002 * np.hypot(*LEVER)) ** 2 / 2)
    n = len(error)
    assert np.all(np.abs(error.mean(axis=0)) < 3 * sigma / np.sqrt(n)), (error.mean(axis=0), 3 * sigma / np.sqrt(n))
    np.testing.assert_allclose(np.sqrt(np.mean(error**2, axis=0)), sigma, rtol=0.1)


def _combined_as_if_at(arm, ds) -> np.ndarray:
    """The combining stage run over the recorded fixes and headings of ``ds`` with the
    GNSS declared at ``arm``: what a suite that believes the antenna is there computes."""
    instruments = (GnssReceiver(lever_arm=arm, noise_std=0.5, sample_period=DT), Gyrocompass(noise_std=0.002))
    fixes, headings = _values(ds, "dgnss1.measured_position"), _values(ds, "gyro1.measured_heading")

    def one(fix, heading):
        return WeightedMean().combine(instruments, [fix, heading[None]], jnp.asarray(0.0))[:2]

    return np.asarray(jax.vmap(one)(jnp.asarray(fixes), jnp.asarray(headings)))


def test_without_the_lever_arm_the_error_is_what_geometry_predicts(turning):
    """The same fixes combined by a stage that takes the antenna for the reference point
    (lever arm (0, 0)): the error is R(psi) r at every sample (noiseless, to rounding),
    and on the noisy run its mean departs from R(psi) r by less than 3 sigma / sqrt(N);
    the stage with the true lever arm gives back the recorded combined position."""
    _, quiet, noisy = turning
    predicted = _rotate(_values(quiet, "heading"), LEVER)
    error = _combined_as_if_at([0.0, 0.0], quiet) - _values(quiet, "position")
    np.testing.assert_allclose(error, predicted, rtol=0, atol=1e-9)
    assert np.abs(predicted).mean() > 10.0  # a bias of metres, not of rounding
    np.testing.assert_allclose(_combined_as_if_at(LEVER.tolist(), noisy), _values(noisy, "measured_position"), rtol=0, atol=1e-9)
    residual = _combined_as_if_at([0.0, 0.0], noisy) - _values(noisy, "position") - _rotate(_values(noisy, "heading"), LEVER)
    assert np.all(np.abs(residual.mean(axis=0)) < 3 * 0.51 / np.sqrt(len(residual))), residual.mean(axis=0)


def _accelerations(composition, ds) -> tuple[np.ndarray, np.ndarray]:
    """``(nu', nu)`` per sample: the plant's vector field at the recorded truth under the
    input applied over the interval before the sample (zero before the first)."""
    plant = composition.scenario.plant
    eta = np.column_stack([_values(ds, "position"), _values(ds, "heading")])
    nu = np.column_stack([_values(ds, "velocity"), _values(ds, "yaw_rate")])
    bias = np.column_stack([_values(ds, "bias_force"), _values(ds, "bias_moment")])
    applied = np.column_stack([_values(ds, "force_applied"), _values(ds, "moment_applied")])
    before = np.vstack([np.zeros((1, 3)), applied[:-1]])
    times = _values(ds, "time")

    def rate(t, eta, nu, bias, tau):
        state = VesselState(eta, nu, bias, jnp.zeros(6))
        return plant.vector_field(t, state, tau, jnp.zeros(plant.noise_size)).nu

    return np.asarray(jax.vmap(rate)(times, eta, nu, bias, before)), nu


def test_the_imu_feels_the_plants_acceleration_at_the_applied_input(turning):
    """Noiseless: specific force = nu'[:2] + r [-v, u] + bias (and at a lever arm
    r' [-y, x] - r^2 [x, y] more), yaw rate = r + bias, to rounding, with nu' the
    vector field at the input applied over [t_{k-1}, t_k]; the input applied after
    the sample would give another specific force."""
    composition, ds, _ = turning
    nu_rate, nu = _accelerations(composition, ds)
    u, v, r = nu.T
    reference_point = nu_rate[:, :2] + r[:, None] * np.column_stack([-v, u])
    force = _values(ds, "imu.measured_specific_force")
    scale = np.abs(reference_point).max()
    assert scale > 1e-3
    np.testing.assert_allclose(force, reference_point + np.asarray(IMU_BIAS), rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(_values(ds, "imu.measured_yaw_rate"), r + GYRO_BIAS, rtol=0, atol=1e-15)
    x, y = 10.0, -2.0
    bow = reference_point + nu_rate[:, 2:3] * np.array([-y, x]) - (r**2)[:, None] * np.array([x, y])
    np.testing.assert_allclose(_values(ds, "imu_bow.measured_specific_force"), bow, rtol=0, atol=1e-12 * scale)
    # against the input applied after the sample: a visible difference, so the check above tells the two apart
    plant = composition.scenario.plant
    eta = np.column_stack([_values(ds, "position"), _values(ds, "heading")])
    bias = np.column_stack([_values(ds, "bias_force"), _values(ds, "bias_moment")])
    after = np.column_stack([_values(ds, "force_applied"), _values(ds, "moment_applied")])
    later = jax.vmap(lambda e, n, b, tau: plant.vector_field(0.0, VesselState(e, n, b, jnp.zeros(6)), tau, jnp.zeros(plant.noise_size)).nu)(
        eta, nu, bias, after
    )
    assert np.abs(np.asarray(later)[1:, :2] - nu_rate[1:, :2]).max() > 1e-5


# ----------------------------------------------------------------------------------
# failures: the suite with its failures against the same suite with every window moved
# past the end (one program: a failure's start is an array), same key

FAILING_DURATION = 30.0
FAILING_SENSORS = {
    "gyro": {"kind": "gyrocompass", "noise_std": 0.002},
    "a_drop": {"kind": "gnss", "noise_std": 0.5, "failures": [{"mode": "dropout", "start": 5.05, "duration": 3.0}]},
    "a_freeze": {"kind": "imu", "failures": [{"mode": "freeze", "signal": "measured_specific_force", "start": 4.05, "duration": 4.0}]},
    "a_jump": {
        "kind": "gnss",
        "noise_std": 0.5,
        "sample_period": 0.5,
        "failures": [{"mode": "jump", "size": [3.0, -2.0], "start": 10.25, "duration": 5.0}],
    },
    "a_drift": {"kind": "gnss", "noise_std": 0.5, "failures": [{"mode": "drift", "rate": [0.05, -0.02], "start": 3.5, "duration": 10.0}]},
    "a_noise": {
        "kind": "gnss",
        "lever_arm": LEVER.tolist(),
        "noise_std": 0.5,
        "sample_period": DT,
        "failures": [{"mode": "noise", "factor": 3.0, "start": 12.05, "duration": 6.0}],
    },
    "a_wild": {
        "kind": "gnss",
        "noise_std": 0.5,
        "sample_period": DT,
        "failures": [{"mode": "wild", "probability": 0.3, "size": 20.0, "start": 1.05}],
    },
    "a_late": {
        "kind": "gnss",
        "noise_std": 0.5,
        "sample_period": 0.5,
        "failures": [{"mode": "latency", "delay": 1.5, "start": 20.25, "duration": 5.0}],
    },
}
#: sensor -> (flag, instrument period)
FAILED = {
    "a_drop": ("dropout", 1.0),
    "a_freeze": ("freeze", DT),
    "a_jump": ("jump", 0.5),
    "a_drift": ("drift", 1.0),
    "a_noise": ("noise", DT),
    "a_wild": ("wild", DT),
    "a_late": ("latency", 0.5),
}
MEASURED = {"a_freeze": ("measured_specific_force", "measured_yaw_rate")}


def _without_failures(scenario):
    """The scenario with every failure's window starting at infinity: never active."""
    where = [(i, j) for i, listed in enumerate(scenario.sensor.failures) for j in range(len(listed))]
    return eqx.tree_at(lambda s: [s.sensor.failures[i][j].start for i, j in where], scenario, [jnp.asarray(np.inf)] * len(where))


@pytest.fixture(scope="module")
def failing():
    """``(composition, dataset with the failures, dataset without)``."""
    composition = compose(_document(FAILING_SENSORS, FAILING_DURATION))
    failed = _dataset(simulate(composition.scenario, KEY))
    clean = _dataset(simulate(_without_failures(composition.scenario), KEY))
    return composition, failed, clean


def _window(ds, sensor: str) -> np.ndarray:
    """Per record: whether the failure of ``sensor`` is active at the instrument's last
    sample (the flag and the measurement hold between samples)."""
    table = FAILING_SENSORS[sensor]["failures"][0]
    steps = round(FAILED[sensor][1] / DT)
    index = np.arange(ds.sizes["time"])
    sampled = _values(ds, "time")[(index // steps) * steps]
    return (sampled >= table["start"]) & (sampled < table["start"] + table.get("duration", np.inf))


def _channels(ds, sensor: str) -> np.ndarray:
    """The instrument's channels side by side: (time, channels)."""
    names = MEASURED.get(sensor, ("measured_position",))
    return np.column_stack([_values(ds, f"{sensor}.{name}").reshape(ds.sizes["time"], -1) for name in names])


@pytest.mark.slow
@pytest.mark.parametrize("sensor", sorted(FAILED))
def test_a_failure_acts_over_its_window_only_and_its_flag_says_when(failing, sensor):
    """The flag is 1 exactly over the window (at the instrument's samples, held between;
    for wild points, at the outliers only, which lie in the window), and wherever it is 0
    the measurement is the failure-free one, bit for bit."""
    _, failed, clean = failing
    mode = FAILED[sensor][0]
    flag = _values(failed, f"{sensor}.{mode}_failure")
    window = _window(failed, sensor)
    assert window.any() and not window.all()
    if mode == "wild":
        assert set(np.unique(flag)) == {0.0, 1.0} and not np.any(flag[~window])
    else:
        np.testing.assert_array_equal(flag, window.astype(float))
    np.testing.assert_array_equal(_values(clean, f"{sensor}.{mode}_failure"), 0.0)
    quiet = flag == 0
    np.testing.assert_array_equal(_channels(failed, sensor)[quiet], _channels(clean, sensor)[quiet])
    assert not np.array_equal(_channels(failed, sensor), _channels(clean, sensor), equal_nan=True)
    # the truth does not see a sensor's failure
    np.testing.assert_array_equal(_values(failed, "position"), _values(clean, "position"))


def test_a_dropout_is_nan_over_its_window(failing):
    _, failed, _ = failing
    fixes = _channels(failed, "a_drop")
    window = _window(failed, "a_drop")
    assert np.isnan(fixes[window]).all() and np.isfinite(fixes[~window]).all()
    assert np.isfinite(_values(failed, "measured_position")).all()  # the other references carry the combined fix


def test_a_freeze_holds_the_last_sample_before_it_bit_for_bit(failing):
    """Only the signal it names: the specific force holds, the yaw rate goes on."""
    _, failed, clean = failing
    window = _window(failed, "a_freeze")
    first = int(np.argmax(window))
    force, yaw_rate = _values(failed, "a_freeze.measured_specific_force"), _values(failed, "a_freeze.measured_yaw_rate")
    np.testing.assert_array_equal(force[window], np.broadcast_to(_values(clean, "a_freeze.measured_specific_force")[first - 1], force[window].shape))
    np.testing.assert_array_equal(yaw_rate, _values(clean, "a_freeze.measured_yaw_rate"))
    assert len(np.unique(_values(clean, "a_freeze.measured_specific_force")[window][:, 0])) == window.sum()  # it would have moved


def test_a_jump_adds_its_step(failing):
    _, failed, clean = failing
    window = _window(failed, "a_jump")
    np.testing.assert_array_equal(_channels(failed, "a_jump")[window], _channels(clean, "a_jump")[window] + np.array([3.0, -2.0]))


def test_a_drift_adds_its_ramp_from_the_start(failing):
    _, failed, clean = failing
    window = _window(failed, "a_drift")
    steps = round(1.0 / DT)
    index = np.arange(failed.sizes["time"])
    sampled = _values(failed, "time")[(index // steps) * steps]
    ramp = np.outer(sampled - 3.5, [0.05, -0.02])
    np.testing.assert_allclose(_channels(failed, "a_drift")[window], _channels(clean, "a_drift")[window] + ramp[window], rtol=0, atol=1e-12)


def test_a_noise_failure_scales_the_white_noise_by_its_factor(failing):
    """The deviation from the noise-free fix p + R(psi) r is 3 times the failure-free one."""
    _, failed, clean = failing
    window = _window(failed, "a_noise")
    exact = _values(failed, "position") + _rotate(_values(failed, "heading"), LEVER)
    deviation = _channels(failed, "a_noise") - exact
    np.testing.assert_allclose(deviation[window], 3.0 * (_channels(clean, "a_noise") - exact)[window], rtol=0, atol=1e-9)
    assert np.abs(deviation[window]).max() > 1.0


def test_wild_points_come_at_their_rate_with_their_spread(failing):
    """Outliers where the flag is 1, and there only; over N samples their frequency is
    within 4 standard errors of the probability, and (outlier - clean) / size is a
    standard normal within its sampling spread."""
    _, failed, clean = failing
    window = _window(failed, "a_wild")
    flag = _values(failed, "a_wild.wild_failure").astype(bool)
    jumps = (_channels(failed, "a_wild") - _channels(clean, "a_wild"))[flag]
    assert np.all(jumps != 0)
    n, p = window.sum(), 0.3
    assert abs(flag.sum() / n - p) < 4 * np.sqrt(p * (1 - p) / n), (flag.sum(), n)
    spread = jumps.ravel() / 20.0
    assert abs(spread.mean()) < 4 / np.sqrt(spread.size) and abs(spread.std() - 1.0) < 4 / np.sqrt(2 * spread.size)


def test_a_latency_gives_the_sample_taken_its_delay_earlier(failing):
    _, failed, clean = failing
    window = _window(failed, "a_late")
    delay = round(1.5 / DT)
    index = np.flatnonzero(window)
    np.testing.assert_array_equal(_channels(failed, "a_late")[index], _channels(clean, "a_late")[index - delay])


@pytest.mark.slow
def test_adding_or_reordering_sensors_never_changes_another_ones_draws(failing):
    """A suite of three of the instruments, in another order, with a new one first: their
    channels and flags are those of the full suite, bit for bit (each instrument draws
    from a stream numbered from its name)."""
    _, failed, _ = failing
    kept = ("a_wild", "gyro", "a_noise")
    sensors = {"extra": {"kind": "hydroacoustic", "transponder": [50.0, -20.0]}, **{name: FAILING_SENSORS[name] for name in kept}}
    composition = compose(_document(sensors, FAILING_DURATION))
    assert composition.scenario.sensor.names == ("extra", *kept)
    fewer = _dataset(simulate(composition.scenario, KEY))
    for name in ("a_wild.measured_position", "a_wild.wild_failure", "gyro.measured_heading", "a_noise.measured_position", "a_noise.noise_failure"):
        np.testing.assert_array_equal(_values(fewer, name), _values(failed, name), err_msg=name)
    assert np.isfinite(_values(fewer, "extra.measured_position")).all()


@pytest.mark.slow
def test_the_combined_channels_do_not_depend_on_the_order_of_the_sensors():
    """Three references and two gyros in two orders, read at 256 random kinematics with
    the same noise per instrument: the combined position and heading agree bit for bit
    (a campaign's spec holds the tables sorted by name, a file in its own order)."""
    instruments = {
        "dgnss1": GnssReceiver(lever_arm=[30.0, 5.0], noise_std=0.5),
        "dgnss2": GnssReceiver(lever_arm=[-20.0, -4.0], noise_std=0.7),
        "hpr": HydroacousticReference(lever_arm=[5.0, 1.0], transponder=[40.0, 10.0]),
        "gyro1": Gyrocompass(noise_std=0.002),
        "gyro2": Gyrocompass(noise_std=0.003),
    }
    forward = SensorSuite(instruments, combining=WeightedMean())
    backward = SensorSuite(dict(reversed(instruments.items())), combining=WeightedMean())
    rng = np.random.default_rng(0)
    n = 256
    kinematics = {
        "position": rng.normal(0, 50, (n, 2)),
        "heading": rng.uniform(-np.pi, np.pi, n),
        "velocity": rng.normal(0, 1, (n, 2)),
        "yaw_rate": rng.normal(0, 0.05, n),
        "acceleration": rng.normal(0, 0.1, (n, 2)),
        "yaw_acceleration": rng.normal(0, 0.01, n),
    }
    normals = {name: rng.normal(size=(n, each.noise_count)) for name, each in instruments.items()}

    def read(suite):
        size = suite.measurement_layout.size
        drawn = np.concatenate([normals[name] for name in suite.names], axis=1)

        def one(k, z):
            memory = suite.initial_memory(k)
            return suite.read(memory, 0.0, k, z, jnp.ones(size, dtype=bool), jnp.zeros(size))[1][-3:]

        return np.asarray(jax.vmap(one)(kinematics, drawn))

    combined = read(forward)
    assert np.isfinite(combined).all()
    np.testing.assert_array_equal(combined, read(backward))


# ----------------------------------------------------------------------------------
# batches and campaigns

SEEDS = [3, 4]


@pytest.fixture(scope="module")
def failing_batch(failing):
    composition, _, _ = failing
    return simulate_batch(composition.scenario, keys_of_seeds(SEEDS))


@pytest.mark.slow
def test_vmapped_runs_equal_single_runs_with_failures(failing, failing_batch):
    """The failure flags (wild points included) of a vmapped batch are those of the runs
    one by one, bit for bit; the measurements and the estimates to rounding (as every
    observer's, tests/test_conformance.py): each device steps its runs as a batch of its
    own, which XLA compiles apart from the single run, so the truth the measurements
    sample can differ in the last bit (docs/reproductions.md)."""
    composition, failed, _ = failing
    batch = failing_batch.to_xarray()
    second = _dataset(simulate(composition.scenario, keys_of_seeds(SEEDS)[1]))
    for run, single in enumerate((failed, second)):
        for name in composition.scenario.sensor.measurement_layout.names:
            if name.endswith("_failure"):
                np.testing.assert_array_equal(batch[name].values[run], _values(single, name), err_msg=f"run {run}: {name}")
            else:
                np.testing.assert_allclose(batch[name].values[run], _values(single, name), rtol=1e-13, atol=1e-12, err_msg=f"run {run}: {name}")
        for name in ("position_hat", "heading_hat", "velocity_hat"):
            np.testing.assert_allclose(batch[name].values[run], _values(single, name), rtol=0, atol=1e-11, err_msg=f"run {run}: {name}")
    assert not np.array_equal(batch["a_wild.wild_failure"].values[0], batch["a_wild.wild_failure"].values[1])


@pytest.mark.slow
def test_a_campaign_sweeps_a_failures_start(failing, failing_batch, tmp_path):
    """An axis on a key inside an array of tables (sensors.a_drift.failures[0].start):
    the points share one program, each flag is 1 over its window, the fixes differ
    over the two windows only, and the first point's metrics and kept
    fixes are those of the composition run as a batch, bit for bit (the campaign's
    spec holds the sensors sorted by name, which changes no bit of the combined fix)."""
    composition, _, _ = failing
    path = "sensors.a_drift.failures[0].start"
    document = {
        "scenario": _document(FAILING_SENSORS, FAILING_DURATION),
        "seed": SEEDS[0],
        "seeds_per_point": len(SEEDS),
        "chunk_runs": len(SEEDS),
        "metrics": ["rms_error:position"],
        "trajectories": {"signals": ["a_drift.measured_position", "a_drift.drift_failure"], "every": 1},
        "sweep": {"axes": [{"field": path, "values": [3.5, 8.5], "name": "drift_start"}]},
    }
    campaign = campaign_from_document(document, "<drift>")
    assert campaign.changes(1) == {path: 8.5}
    scenarios = [campaign.point_spec(point).build() for point in (0, 1)]
    starts = [float(s.sensor.failures[s.sensor.names.index("a_drift")][0].start) for s in scenarios]
    assert starts == [3.5, 8.5] and structure_key(scenarios[0]) == structure_key(scenarios[1])
    store = tmp_path / "drift.zarr"
    run_campaign(campaign, store, workers=0, say=lambda text: None)
    ds = CampaignStore(store).open().load()
    times = ds.kept_time.values
    flags = ds["trajectory__a_drift.drift_failure"].values
    fixes = ds["trajectory__a_drift.measured_position"].values
    sampled = times[(np.arange(times.size) // 10) * 10]  # the 1 Hz receiver's last sample
    windows = [(sampled >= start) & (sampled < start + 10.0) for start in starts]
    for point, first in enumerate((40, 90)):  # its first sample from the start
        assert np.argmax(windows[point]) == first
        np.testing.assert_array_equal(flags[point], np.broadcast_to(windows[point], flags[point].shape))
    either = windows[0] | windows[1]
    np.testing.assert_array_equal(fixes[0][:, ~either], fixes[1][:, ~either])
    assert np.all(fixes[0][:, either] != fixes[1][:, either])
    batch = failing_batch.to_xarray()
    np.testing.assert_array_equal(fixes[0], batch["a_drift.measured_position"].values)
    metrics = metric_module.resolve(["rms_error:position"], composition.scenario)
    expected = metric_module.reduce(failing_batch, metrics, after=None, divergence=None)
    np.testing.assert_array_equal(ds.rms_error__position.values[0], expected["rms_error__position"])


# ----------------------------------------------------------------------------------
# bad sensor tables: one line at the key, nothing written

SUITE = """\
[simulation]
duration = 20.0
plant_step = 0.1
sample_period = 0.1

[plant]
kind = "dp-vessel"
[plant.bias]
time_constant = 1000.0
std = [2000.0, 2000.0, 50000.0]
[plant.waves]
kind = "linear"
peak_frequency = 0.8976
damping_ratio = 0.1
amplitude = [1.0, 1.0, 0.0017]
[plant.initial]
eta = [0.0, 0.0, 0.0]
nu = [0.5, 0.0, 0.01]

[sensors.dgnss1]
kind = "gnss"
lever_arm = [30.0, 5.0]
noise_std = 0.5

[sensors.dgnss2]
kind = "gnss"
lever_arm = [-20.0, -4.0]
noise_std = 0.7
[[sensors.dgnss2.failures]]
mode = "dropout"
start = 2.0
duration = 3.0
[[sensors.dgnss2.failures]]
mode = "drift"
start = 10.0
rate = [0.05, 0.0]

[sensors.gyro1]
kind = "gyrocompass"
noise_std = 0.002

[sensors.imu]
kind = "imu"

[observer]
kind = "passive"
"""


def test_the_suite_file_composes_with_the_sensors_in_its_order():
    composition = from_document(tomllib.loads(SUITE)).composition
    suite = composition.scenario.sensor
    assert composition.kinds["sensor"] == "suite" and suite.names == ("dgnss1", "dgnss2", "gyro1", "imu")
    assert [f.mode for f in suite.failures[1]] == ["dropout", "drift"]
    assert "dgnss2.dropout_failure" in suite.measurement_layout.names and composition.document["references"] == {"kind": "weighted-mean"}


#: (replaced, replacement, the key blamed, the message, the line it points to: its text)
BAD_TABLES = [
    ('kind = "gyrocompass"', 'kind = "gyro"', "sensors.gyro1.kind", "no instrument kind 'gyro' (one of gnss, ", 'kind = "gyro"'),
    (
        "lever_arm = [30.0, 5.0]",
        "lever_arm = [30.0, 5.0, 1.0]",
        "sensors.dgnss1.lever_arm",
        "must have 2 entries; got 3 entries",
        "lever_arm = [30.0, 5.0, 1.0]",
    ),
    ("noise_std = 0.7", "noise_std = -0.7", "sensors.dgnss2.noise_std", "must be non-negative; got -0.7", "noise_std = -0.7"),
    ("start = 10.0", "start = 20.0", "sensors.dgnss2.failures[1].start", "start (20 s) must be before the run's end (duration 20 s)", "start = 20.0"),
    (
        'mode = "drift"',
        'mode = "melt"',
        "sensors.dgnss2.failures[1].mode",
        "mode must be one of dropout, freeze, jump, drift, noise, wild, latency; got 'melt'",
        'mode = "melt"',
    ),
    (
        'mode = "drift"',
        'mode = "jump"',
        "sensors.dgnss2.failures[1].rate",
        "unknown key (a jump failure takes mode, start, duration, signal, size)",
        "rate = [0.05, 0.0]",
    ),
    (
        'mode = "dropout"',
        'mode = "jump"',
        "sensors.dgnss2.failures[0].size",
        "missing key (a jump failure needs start, size)",
        "[[sensors.dgnss2.failures]]",
    ),
    (
        "duration = 3.0",
        "duration = 0.0",
        "sensors.dgnss2.failures[0].duration",
        "duration must be a number > 0 (inf: to the run's end); got 0.0",
        "duration = 0.0",
    ),
    (
        "duration = 3.0",
        'signal = "measured_heading"',
        "sensors.dgnss2.failures[0].signal",
        "the sensor measures no 'measured_heading'",
        'signal = "measured_heading"',
    ),
    (
        "rate = [0.05, 0.0]",
        "rate = [0.05, 0.0, 0.0]",
        "sensors.dgnss2.failures[1].rate",
        "must be one finite number or 2 (one per channel)",
        "rate = [0.05, 0.0, 0.0]",
    ),
    (
        "noise_std = 0.5",
        "noise_std = 0.5\nsample_period = 0.25",
        "sensors.dgnss1.sample_period",
        "must be an integer multiple of the simulation's",
        "sample_period = 0.25",
    ),
    (
        "noise_std = 0.5",
        "noise_std = 0.5\nnoise = 1.0",
        "sensors.dgnss1.noise",
        "unknown key (instrument gnss takes: lever_arm, noise_std,",
        "noise = 1.0",
    ),
    (
        "[observer]",
        '[sensor]\nkind = "position-heading"\n\n[observer]',
        "sensors",
        "give one [sensor] table or named [sensors.NAME] tables, not both",
        None,
    ),
]


@pytest.mark.parametrize(
    ("old", "new", "key", "message", "at"), BAD_TABLES, ids=[f"{case[2]}={case[1].splitlines()[-1][:24]}" for case in BAD_TABLES]
)
def test_a_bad_sensor_table_is_one_line_at_its_key_and_nothing_is_written(old, new, key, message, at, tmp_path, capsys):
    """compose blames the key; ``lookout run`` says it in one line with the key's line of
    the file, exits with 2 and creates no output folder."""
    assert SUITE.count(old) == 1
    text = SUITE.replace(old, new)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(CompositionError) as raised:
        compose(tomllib.loads(text))
    assert str(raised.value).startswith(f"{key}: ") and message in str(raised.value)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    where = key if at is None else f"{key} (line {text.splitlines().index(at) + 1})"
    assert err.startswith(f"error: {path}: {where}: ") and message in err, err
    assert not out.exists()


def test_two_sensors_of_one_name_are_a_toml_error_in_one_line(tmp_path, capsys):
    path = tmp_path / "twice.toml"
    path.write_text(SUITE.replace("[sensors.imu]", "[sensors.gyro1]"))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}: ") and "not valid TOML" in err and err.count("\n") == 1, err
    assert not out.exists()


# ----------------------------------------------------------------------------------
# one sample of a suite, read directly: what is taken when


def _kinematics(heading: float = 0.3, position=(10.0, -4.0)) -> dict:
    return {
        "position": jnp.asarray(position),
        "heading": jnp.asarray(heading),
        "velocity": jnp.zeros(2),
        "yaw_rate": jnp.asarray(0.0),
        "acceleration": jnp.zeros(2),
        "yaw_acceleration": jnp.asarray(0.0),
    }


def test_the_combined_position_is_taken_when_a_reference_has_a_new_fix_not_at_the_gyros_rate():
    """A fix every second and a gyro every 0.1 s: at a gyro-only sample the combined
    heading is new and the combined position is the held one, bit for bit; at a fix the
    position is new. The combined position's period is the references' (1 s)."""
    suite = SensorSuite(
        {"dgnss": GnssReceiver(lever_arm=LEVER, noise_std=0.5), "gyro": Gyrocompass(noise_std=0.0, sample_period=DT)}, combining=WeightedMean()
    )
    layout = suite.measurement_layout
    assert layout.names == ("dgnss.measured_position", "gyro.measured_heading", "measured_position", "measured_heading")
    assert suite.sample_period == (1.0, 1.0, DT, 1.0, 1.0, DT)
    k = _kinematics()
    memory = suite.initial_memory(k)
    normals = jnp.asarray(np.random.default_rng(1).normal(size=suite.noise_size))
    held = jnp.asarray([1.0, 2.0, 0.1, 7.0, 8.0, 0.2])
    gyro_only = jnp.asarray([False, False, True, False, False, True])
    _, y = suite.read(memory, 0.0, k, normals, gyro_only, held)
    np.testing.assert_array_equal(np.asarray(y[:2]), [1.0, 2.0])
    np.testing.assert_array_equal(np.asarray(y[3:5]), [7.0, 8.0])  # the held combined position
    assert float(y[5]) == pytest.approx(0.3, abs=1e-15) and float(y[2]) == pytest.approx(0.3, abs=1e-15)
    _, y = suite.read(memory, 0.0, k, normals, jnp.ones(6, dtype=bool), held)
    fix = np.asarray(y[:2])
    np.testing.assert_allclose(np.asarray(y[3:5]), fix - _rotate(np.asarray(0.3), LEVER), rtol=0, atol=1e-12)


def test_a_freeze_from_the_start_holds_the_first_sample():
    """A freeze with no sample before it holds the first one it sees, bit for bit, and
    lets go at its window's end."""
    signals = GnssReceiver().signals
    freeze = failure_from_table({"mode": "freeze", "start": 0.0, "duration": 2.0}, signals, 1.0)
    memory = freeze.initial_memory(2)
    held = jnp.full(2, jnp.nan)
    out = []
    for t, value in ((0.0, [1.0, 2.0]), (1.0, [3.0, 4.0]), (2.0, [5.0, 6.0])):
        memory, y, flag = freeze.apply(memory, t, jnp.asarray(value), jnp.zeros(2), held, jnp.zeros(0), jnp.asarray(True))
        out.append((np.asarray(y), float(flag)))
        held = y
    assert [flag for _, flag in out] == [1.0, 1.0, 0.0]
    np.testing.assert_array_equal(np.stack([y for y, _ in out]), [[1.0, 2.0], [1.0, 2.0], [5.0, 6.0]])


def test_a_gnss_latency_gives_the_fix_of_its_age_and_the_resting_position_before():
    """``latency = 2`` s at 1 s fixes: the fix given at sample n is of sample n - 2; the
    first two are of the initial position (the vessel rested there before the run)."""
    receiver = GnssReceiver(noise_std=0.0, latency=2.0)
    track = [_kinematics(position=(float(n), 2.0 * n)) for n in range(5)]
    memory = receiver.initial_memory(track[0])
    given = []
    for k in track:
        memory, value, _ = receiver.emit(memory, k, jnp.zeros(receiver.noise_count))
        given.append(np.asarray(value))
    np.testing.assert_array_equal(np.stack(given), [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 2.0], [2.0, 4.0]])
    with pytest.raises(ValueError, match=r"latency must be a whole number of the sample period \(1 s\), >= 0; got 1.5"):
        GnssReceiver(latency=1.5)
    with pytest.raises(ValueError, match=r"latency must be a whole number"):
        GnssReceiver(latency=-1.0)


def test_a_files_sensors_replace_a_presets_sensor():
    """``preset`` with ``[sensors.NAME]``: the suite replaces the reproduction's sensor."""
    document = tomllib.loads(SUITE)
    document["preset"] = "fossen-strand-1999"
    composition = compose(document)
    assert composition.scenario.sensor.names == ("dgnss1", "dgnss2", "gyro1", "imu")


def test_an_observer_the_suite_does_not_fit_is_refused_naming_the_suite():
    document = tomllib.loads(SUITE)
    document["sensors"] = {name: table for name, table in document["sensors"].items() if name != "gyro1"}
    with pytest.raises(
        CompositionError, match=r"which the sensor suite \(dgnss1, dgnss2, imu\) does not measure \(it measures dgnss1.measured_position"
    ):
        compose(document)


def test_a_hydroacoustic_reference_states_each_fix_at_its_own_slant_range():
    """Its noise grows with the slant range (sigma = sigma_0 + f rho), so the spread it
    states for a fix is at that fix's range from the transponder, which a combining stage
    tests and weights it by; a GNSS receiver states the same for every fix; a missing fix
    gets the spread at the transponder (weight_std)."""
    hpr = HydroacousticReference(transponder=[40.0, 10.0], depth=100.0, noise_std=0.5, range_fraction=0.005)
    fix = jnp.asarray([40.0 + 120.0, 10.0 - 160.0])  # 200 m off horizontally
    assert float(hpr.std_at(fix)) == pytest.approx(0.5 + 0.005 * np.hypot(100.0, 200.0), rel=1e-14)
    assert float(hpr.std_at(jnp.asarray([40.0, 10.0]))) == pytest.approx(float(hpr.weight_std()), rel=1e-14) == 1.0
    assert float(hpr.std_at(jnp.asarray([np.nan, np.nan]))) == float(hpr.weight_std())
    gnss = GnssReceiver(noise_std=0.7)
    assert float(gnss.std_at(fix)) == float(gnss.weight_std()) == pytest.approx(0.7)


def test_gnss_velocity_at_rest_has_a_finite_gradient():
    """At rest the speed over ground is 0 and the course 0, each with a finite (zero)
    gradient: a Kalman filter linearizes the instrument there at a DP vessel's start
    (atan2's gradient at the origin is NaN, and gave every estimate NaN from t = 0)."""
    from lookout.sensing.motion import GnssVelocity

    velocity = GnssVelocity(lever_arm=[30.0, 5.0])

    def expected(v):
        return velocity.expected({**_kinematics(), "velocity": v})

    jacobian = jax.jacfwd(expected)(jnp.zeros(2))
    np.testing.assert_array_equal(expected(jnp.zeros(2)), [0.0, 0.0])
    assert np.isfinite(np.asarray(jacobian)).all()
    # away from rest the course is the velocity's direction over ground, as before
    moving = expected(jnp.array([1.0, 0.0]))
    np.testing.assert_allclose(moving, [1.0, 0.3], rtol=1e-12)
