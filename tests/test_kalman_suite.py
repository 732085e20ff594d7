"""The extended and unscented Kalman filters on a sensor suite (lookout.observers.kalman):
every instrument channel a measurement with its own R, its lever arm in h, masked when
missing; the input an IMU feels carried in the filter's state.

The vessel is the Northern Clipper without waves, turned by a constant yaw moment of
2e6 N m (its heading swings through 1.7 rad in 300 s), the GNSS receivers 1 m (per
axis, 1 Hz) at lever arms A = (30, 5) m and B = (-20, -4) m, a gyrocompass of 2 mrad
at 1 Hz; the filters estimate every state of their own model (the plant's)."""

from __future__ import annotations

import copy
import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout.observers.kalman import KalmanState
from lookout.scenario.composition import compose, simulate

# one worker runs the file: its simulated runs (functools.cache below) are shared by its tests
pytestmark = pytest.mark.xdist_group("kalman_suite")

A = {"kind": "gnss", "noise_std": 1.0, "lever_arm": [30.0, 5.0]}
B = {"kind": "gnss", "noise_std": 1.0, "lever_arm": [-20.0, -4.0]}
GYRO = {"kind": "gyrocompass", "noise_std": 0.002, "sample_period": 1.0}
INITIAL_STD = {"eta": [5.0, 5.0, 0.05], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [1e-3] * 6}
#: Seeds 0 to 7; each suite sees the same truth (the process noise is its own stream)
#: and a GNSS named ``gnss`` the same noise in every suite (an instrument's stream is
#: numbered from its name), so the suites are compared run by run.
RUNS, DURATION = 8, 300.0
#: The errors are taken once the filters have settled from the unknown bias.
SETTLED = 150.0


def _document(sensors: dict | None = None, observer: str = "ekf", *, sensor: dict | None = None, runs: int = RUNS) -> dict:
    document = {
        "simulation": {"plant_step": 0.25, "sample_period": 0.5, "duration": DURATION, "runs": runs},
        "plant": {
            "kind": "dp-vessel",
            "vessel": {"kind": "northern-clipper"},
            "bias": {"kind": "gauss-markov", "time_constant": [1000.0, 1000.0, 1000.0], "std": [2000.0, 2000.0, 50000.0]},
            "waves": {"kind": "linear", "peak_frequency": 0.8, "damping_ratio": 0.1, "amplitude": [0.0, 0.0, 0.0]},
            "initial": {"bias": [1e4, 5e3, 1e5]},
        },
        "observer": {"kind": observer, "initial_std": INITIAL_STD},
        "controller": {"kind": "sinusoidal", "amplitude": [0.0, 0.0, 0.0], "frequency": 0.0, "offset": [0.0, 0.0, 2e6]},
    }
    if sensor is not None:
        document["sensor"] = sensor
    else:
        document["sensors"] = copy.deepcopy({**(sensors or {}), "gyro": GYRO})
    return document


# ------------------------------------------------------------------ offline: the same samples


def _drive(observer, ys, us, dt=0.5):
    """Posterior means and covariances of ``observer`` through samples ``ys`` (each row
    held between its channels' samples, as the engine holds them) and inputs ``us``."""
    update = eqx.filter_jit(lambda f, s, t, y: f.update(s, t, y))
    predict = eqx.filter_jit(lambda f, s, t, y, u: f.predict(s, t, y, u, dt))
    state = observer.init(jnp.asarray(ys[0]), observer.guess())
    means, covariances = [], []
    for k, (y, u) in enumerate(zip(ys, us)):
        t = jnp.asarray(k * dt)
        state = update(observer, state, t, jnp.asarray(y))
        means.append(np.asarray(state.mean))
        covariances.append(np.asarray(state.covariance))
        state = predict(observer, state, t, jnp.asarray(y), jnp.asarray(u))
    return np.asarray(means), np.asarray(covariances)


def _samples(count=80, seed=5):
    """Position (m) and heading (rad, through +-pi) fixes of 1 m and 2 mrad with a few
    lost, and inputs of about 1e5 N and 1e6 N m."""
    rng = np.random.default_rng(seed)
    k = np.arange(count)
    position = np.stack([0.05 * k, -0.02 * k], axis=1) + rng.standard_normal((count, 2))
    heading = (np.pi - 0.05 + 0.002 * k + 0.002 * rng.standard_normal(count) + np.pi) % (2 * np.pi) - np.pi
    ys = np.concatenate([position, heading[:, None]], axis=1)
    ys[[12, 13, 40]] = np.nan  # fixes lost
    ys[25, :2] = np.nan  # a position lost, the heading kept
    inputs = rng.standard_normal((count, 3)) * np.array([1e5, 1e5, 1e6])
    return ys, inputs


def _scaled(values, covariances):
    scale = np.sqrt(np.diag(covariances[-1]))
    return values / (scale if values.ndim == 2 else np.outer(scale, scale))


@pytest.mark.slow
def test_the_ekf_on_one_gnss_and_a_gyrocompass_is_the_ekf_on_the_position_heading_sensor():
    """A suite of a GNSS at the reference point (lever arm 0) and a gyrocompass measures
    what the position-heading sensor does, with the same noise: the two filters given the
    same samples agree to rounding (1e-9 of each state's standard deviation; measured:
    bit for bit)."""
    suite = compose(_document({"gnss": {**A, "lever_arm": [0.0, 0.0]}}, runs=1)).scenario.observer
    plain = compose(_document(sensor={"kind": "position-heading", "noise_std": [1.0, 1.0, 0.002], "sample_period": 1.0}, runs=1)).scenario.observer
    assert suite.measurement_layout.names == ("gnss.measured_position", "gyro.measured_heading")
    np.testing.assert_array_equal(np.asarray(suite.measurement_covariance), np.asarray(plain.measurement_covariance))
    assert suite.channel_periods == plain.channel_periods == (1.0, 1.0, 1.0)
    ys, us = _samples()
    means, covariances = _drive(suite, ys, us)
    expected_means, expected_covariances = _drive(plain, ys, us)
    np.testing.assert_allclose(_scaled(means, expected_covariances), _scaled(expected_means, expected_covariances), rtol=0, atol=1e-9)
    np.testing.assert_allclose(_scaled(covariances, expected_covariances), _scaled(expected_covariances, expected_covariances), rtol=0, atol=1e-9)


@pytest.mark.slow
def test_a_missing_reference_is_masked_exactly():
    """Two GNSS receivers of which the second never has a fix: the filter is the one on
    the first receiver alone, to rounding (its gain columns are exactly zero)."""
    both = compose(_document({"gnss": A, "gnss2": B}, runs=1)).scenario.observer
    one = compose(_document({"gnss": A}, runs=1)).scenario.observer
    ys, us = _samples()
    lost = np.full((len(ys), 2), np.nan)
    means, covariances = _drive(both, np.concatenate([ys[:, :2], lost, ys[:, 2:]], axis=1), us)
    expected_means, expected_covariances = _drive(one, ys, us)
    np.testing.assert_allclose(_scaled(means, expected_covariances), _scaled(expected_means, expected_covariances), rtol=0, atol=1e-9)
    np.testing.assert_allclose(_scaled(covariances, expected_covariances), _scaled(expected_covariances, expected_covariances), rtol=0, atol=1e-9)


def test_the_filter_reads_the_instrument_channels_with_their_noise_and_periods():
    imu = {"kind": "imu", "sample_period": 0.5, "accelerometer_std": 0.01, "gyro_std": 0.001}
    observer = compose(_document({"gnss": A, "imu": imu}, runs=1)).scenario.observer
    assert observer.measurement_layout.names == (
        "gnss.measured_position",
        "imu.measured_specific_force",
        "imu.measured_yaw_rate",
        "gyro.measured_heading",
    )
    np.testing.assert_allclose(np.diag(np.asarray(observer.measurement_covariance)), [1.0, 1.0, 1e-4, 1e-4, 1e-6, 4e-6], rtol=1e-14)
    assert observer.channel_periods == (1.0, 1.0, 0.5, 0.5, 0.5, 1.0)
    assert observer.channel_angles == (False,) * 5 + (True,)


def test_due_every_makes_every_channel_due_at_every_step_and_changes_nothing_else():
    """A live session's filter (each reading taken when it comes): every channel due at
    each multiple of the step, an ignored channel still never; the original untouched."""
    imu = {"kind": "imu", "sample_period": 0.5, "accelerometer_std": 0.01, "gyro_std": 0.001}
    observer = compose(_document({"gnss": A, "imu": imu}, runs=1)).scenario.observer
    object.__setattr__(observer, "ignored_channels", (False, False, True, True, True, False))  # as the IMU-aided observer marks its IMU
    live = observer.due_every(0.1)
    assert live.channel_periods == (0.1,) * 6 and observer.channel_periods == (1.0, 1.0, 0.5, 0.5, 0.5, 1.0)
    for t in (0.1, 0.3, 0.7, 1.0):
        np.testing.assert_array_equal(live.due(t), [True, True, False, False, False, True])
    np.testing.assert_array_equal(observer.due(0.3), [False] * 6)
    leaves = [jax.tree_util.tree_leaves(eqx.filter(each, eqx.is_array)) for each in (live, observer)]
    assert len(leaves[0]) == len(leaves[1]) > 0 and all(a is b for a, b in zip(*leaves))  # the same arrays: a copy, the periods apart
    with pytest.raises(ValueError, match="period"):
        observer.due_every(0.0)


@pytest.mark.slow
def test_an_imu_is_read_under_the_input_applied_before_the_sample():
    """The specific force an IMU measures at t_k depends on the input applied over
    [t_(k-1), t_k]: predict keeps it in the state, and the correction at t_k reads h there."""
    imu = {"kind": "imu", "sample_period": 0.5}
    observer = compose(_document({"gnss": A, "imu": imu}, runs=1)).scenario.observer
    state = observer.init(jnp.asarray([1.0, 2.0, 0.0, 0.0, 0.0, 0.1]), observer.guess())
    assert isinstance(state, KalmanState)
    np.testing.assert_array_equal(np.asarray(state.applied), np.zeros(3))
    u = jnp.asarray([2e5, -1e5, 3e6])
    state = observer.predict(state, 0.0, jnp.zeros(6), u, 0.5)
    np.testing.assert_array_equal(np.asarray(state.applied), np.asarray(u))
    assert float(state.time) == 0.5
    plant, x = observer.model, observer._unravel(state.mean)
    force = observer.sensor.expected(plant.kinematics(0.5, x, u))[2:4]
    predicted = observer.measurement(state.mean, state.applied, 0.5)
    np.testing.assert_array_equal(np.asarray(predicted[2:4]), np.asarray(force))
    # a thrust of 2e5 N on the Northern Clipper: about 0.04 m/s2, what the IMU feels
    assert 0.01 < float(predicted[2]) < 0.1
    innovation, _ = observer.innovation_statistics(state, predicted)
    np.testing.assert_allclose(np.asarray(innovation), 0.0, atol=1e-12)
    # at 0.5 s only the IMU is due: a sample that is h under the carried input moves
    # nothing, one read as if no thrust had been applied would (0.04 m/s2 against 0.01)
    corrected = observer.update(state, 0.5, predicted)
    np.testing.assert_allclose(np.asarray(corrected.mean), np.asarray(state.mean), rtol=0, atol=1e-9)
    unthrusted = observer.measurement(state.mean, jnp.zeros(3), 0.5)
    moved = observer.update(state, 0.5, unthrusted)
    assert np.abs(np.asarray(moved.mean) - np.asarray(state.mean)).max() > 1e-3


# ------------------------------------------------------------------ simulated: the engine's samples


#: The second receiver's dropout from 150 s to 250 s; the runs without it are the same
#: program with the window moved past the end (a failure's start is an array), so that
#: the two compile once.
B_LOST = {**B, "failures": [{"mode": "dropout", "start": 150.0, "duration": 100.0}]}


def _never(composition):
    """``composition`` with its one failure's window starting at infinity: never active."""
    scenario = eqx.tree_at(lambda s: s.sensor.failures[1][0].start, composition.scenario, jnp.asarray(np.inf))
    return dataclasses.replace(composition, scenario=scenario)


@functools.cache
def _run(name: str):
    documents = {
        "A": lambda: compose(_document({"gnss": A})),
        "B": lambda: compose(_document({"gnss": B})),  # A's program: only the lever arm differs
        "A+B": lambda: _never(compose(_document({"gnss": A, "gnss2": B_LOST}))),
        "A+B, B lost": lambda: compose(_document({"gnss": A, "gnss2": B_LOST})),
        "A+B ukf": lambda: _never(compose(_document({"gnss": A, "gnss2": B_LOST}, "ukf"))),
    }
    return simulate(documents[name]())


def _error(trajectory):
    return np.asarray(trajectory.truth["position"]) - np.asarray(trajectory.estimate["position"])


def _rms(error, times, start=SETTLED, end=DURATION):
    """Per run: the RMS over [start, end) of the position error's norm (m)."""
    window = (times >= start) & (times < end)
    return np.sqrt(np.mean(np.sum(error[:, window] ** 2, axis=-1), axis=-1))


@pytest.mark.slow
def test_two_references_estimate_the_position_better_than_either_alone():
    """Two references of 1 m each halve R of the position: the filter's position error
    RMS (seeds 0 to 7, 150 s to 300 s) is 0.70 of either single reference's (measured
    0.697 and 0.698; 1/sqrt(2) = 0.707 for an error all measurement noise); asserted
    below 0.8, and below each single reference's on every seed."""
    times = np.asarray(_run("A").time)
    single_a, single_b, both = (_rms(_error(_run(name)), times) for name in ("A", "B", "A+B"))
    assert np.all(both < single_a) and np.all(both < single_b)
    assert both.mean() < 0.8 * single_a.mean() and both.mean() < 0.8 * single_b.mean()
    assert 0.15 < both.mean() < 0.25  # about 0.19 m: what the test is about, not a filter that fails


@pytest.mark.slow
def test_a_lever_arm_is_compensated_in_h():
    """A GNSS antenna 30 m forward and 5 m to starboard while the heading turns through
    1.7 rad: the position estimate of the reference point is unbiased. Its mean error
    over seeds 0 to 7 and 150 s to 300 s is under 15 cm per axis, three standard errors
    of the eight runs' means (4 and 5 cm; measured 0.7 and 1.2 cm), where the same filter
    with the lever arm left out of its model is 6.5 m and 31 m off."""
    run = _run("A")
    times = np.asarray(run.time)
    heading = np.asarray(run.truth["heading"])
    assert heading.max() - heading.min() > 1.5
    settled = times >= SETTLED
    assert np.all(np.abs(_error(run)[:, settled].mean(axis=(0, 1))) < 0.15)
    from lookout.sim import keys_of_seeds, simulate_batch

    scenario = compose(_document({"gnss": A})).scenario
    unaware = eqx.tree_at(lambda s: s.observer.sensor.instruments[0].lever_arm, scenario, jnp.zeros(2))
    wrong = simulate_batch(unaware, keys_of_seeds(list(range(RUNS))))
    assert np.linalg.norm(_error(wrong)[:, settled].mean(axis=(0, 1))) > 10.0


@pytest.mark.slow
def test_the_filter_rides_through_a_dropped_reference():
    """The second receiver drops out from 150 s to 250 s (a dropout failure: its channels
    NaN, its flag 1): the filter goes on with the first alone, its position error RMS
    over the dropout no more than the single reference's (measured 0.25 m against
    0.28 m), and takes the second back after it (from 270 s: 0.14 m against the single
    reference's 0.20 m and 0.12 m of the filter that never lost it)."""
    lost = _run("A+B, B lost")
    times = np.asarray(lost.time)
    measured = lost.signals.measurement.split(np.asarray(lost.measurement))
    during = (times >= 150.0) & (times < 250.0)
    assert np.all(np.isnan(measured["gnss2.measured_position"][:, during]))
    assert np.all(measured["gnss2.dropout_failure"][:, during] == 1.0)
    assert np.all(np.isfinite(np.asarray(lost.estimate["position"])))
    assert _rms(_error(lost), times, 150.0, 250.0).mean() <= _rms(_error(_run("A")), times, 150.0, 250.0).mean()
    # afterwards both again: better than either alone
    assert _rms(_error(lost), times, 270.0).mean() < 0.85 * _rms(_error(_run("A")), times, 270.0).mean()


@pytest.mark.slow
def test_the_ukf_on_the_suite_agrees_with_the_ekf():
    """The unscented filter on the two references and the gyrocompass: its position
    estimate within 1 mm of the extended filter's from 150 s on (measured at most
    0.08 mm: the measurement is nearly linear over the spread of the sigma points)."""
    times = np.asarray(_run("A+B").time)
    settled = times >= SETTLED
    difference = np.asarray(_run("A+B ukf").estimate["position"]) - np.asarray(_run("A+B").estimate["position"])
    assert np.abs(difference[:, settled]).max() < 1e-3
    heading = np.asarray(_run("A+B ukf").estimate["heading"]) - np.asarray(_run("A+B").estimate["heading"])
    assert np.abs((heading[:, settled] + np.pi) % (2 * np.pi) - np.pi).max() < 1e-4


def test_a_noiseless_instrument_needs_a_measurement_noise():
    """R is the instruments' white noise; a channel of none is refused, naming it, until
    ``measurement_noise`` gives R."""
    document = _document({"gnss": {**A, "noise_std": 0.0}}, runs=1)
    with pytest.raises(ValueError, match="measurement_noise: the sensor's own noise is zero on gnss.measured_position"):
        compose(document)
    document["observer"]["measurement_noise"] = [0.5, 0.5, 0.002]
    observer = compose(document).scenario.observer
    np.testing.assert_allclose(np.diag(np.asarray(observer.measurement_covariance)), [0.25, 0.25, 4e-6], rtol=1e-14)


SCENARIO_FILE = """
[simulation]
plant_step = 0.25
sample_period = 0.5
duration = 60.0

[plant]
kind = "dp-vessel"
vessel = { kind = "northern-clipper" }
bias = { kind = "gauss-markov", time_constant = [1000.0, 1000.0, 1000.0], std = [2000.0, 2000.0, 50000.0] }
waves = { kind = "linear", peak_frequency = 0.8, damping_ratio = 0.1, amplitude = [1.0, 1.0, 0.01] }

[sensors.dgnss1]
kind = "gnss"
lever_arm = [30.0, 5.0]

[sensors.dgnss2]
kind = "gnss"
lever_arm = [-20.0, -4.0]

[[sensors.dgnss2.failures]]
mode = "dropout"
start = 20.0
duration = 10.0

[sensors.gyro]
kind = "gyrocompass"
sample_period = 1.0

[sensors.imu]
kind = "imu"
sample_period = 0.5

[observer]
kind = "ekf"
"""


@pytest.mark.slow
def test_a_scenario_file_of_named_sensors_builds_the_filter_on_their_channels(tmp_path, capsys):
    """``[observer] kind = "ekf"`` with ``[sensors.NAME]`` tables: the filter on the suite's
    instrument channels, with the steady-state P_0 of its own R, and ``lookout design``
    checks its noise model."""
    from lookout.cli import main
    from lookout.scenario.file import load

    path = tmp_path / "suite.toml"
    path.write_text(SCENARIO_FILE)
    scenario = load(path, runs=1).composition.scenario
    observer = scenario.observer
    assert observer.measurement_layout.names == (
        "dgnss1.measured_position",
        "dgnss2.measured_position",
        "gyro.measured_heading",
        "imu.measured_specific_force",
        "imu.measured_yaw_rate",
    )
    assert observer.sensor is scenario.sensor
    # the engine hands the filter those channels of the suite's measurement, by name
    names = scenario.sensor.measurement_layout.names
    assert "dgnss2.dropout_failure" in names and "measured_position" in names
    assert scenario.observer_channels == tuple(range(8))
    covariance = np.asarray(observer.initial_covariance)
    assert np.all(np.isfinite(covariance)) and np.all(np.diag(covariance) >= 0)
    assert main(["design", str(path)]) == 0
    assert "R > 0" in capsys.readouterr().out


def test_the_default_r_adds_each_slow_errors_stationary_variance_to_the_white_noise():
    """R on a suite: sqrt(noise_std^2 + error_std^2) for a GNSS receiver and a
    gyrocompass with a Gauss-Markov error, the white noise alone where there is none,
    and the hydroacoustic reference's spread at the transponder's horizontal position."""
    from lookout.observers.kalman import suite_measurement_std
    from lookout.sensing.heading import Gyrocompass
    from lookout.sensing.position import GnssReceiver, HydroacousticReference
    from lookout.sensing.suite import SensorSuite

    suite = SensorSuite(
        {
            "dgnss1": GnssReceiver(noise_std=0.7, error_std=0.5),
            "dgnss2": GnssReceiver(noise_std=0.7),
            "hpr": HydroacousticReference(depth=100.0, noise_std=0.5, range_fraction=0.005),
            "gyro1": Gyrocompass(noise_std=0.002, error_std=0.001),
        }
    )
    np.testing.assert_allclose(suite_measurement_std(suite), [np.hypot(0.7, 0.5)] * 2 + [0.7] * 2 + [1.0] * 2 + [np.hypot(0.002, 0.001)], rtol=1e-15)
