"""The IMU-aided observer (lookout.observers.ins) and its strapdown model
(lookout.models.strapdown): the propagation against the plant, the biases estimated,
refusals and the design conditions."""

from __future__ import annotations

import copy
import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout._math import rotate
from lookout.scenario.composition import compose, simulate

# one worker runs the file: the runs below are shared by its tests
pytestmark = pytest.mark.xdist_group("ins")

#: The filter's R when the suite is noise-free (GNSS north, east; gyrocompass; the IMU's, unused).
FILTER_NOISE = [0.5, 0.5, 0.0017, 1.0, 1.0, 1.0]


def _document(period: float = 0.1, *, duration: float = 60.0, imu: dict | None = None, noise: bool = False, runs: int = 1) -> dict:
    """The Northern Clipper in calm water under a sinusoidal thrust, moving from the start;
    a GNSS receiver, a gyrocompass and an IMU at the reference point."""
    return {
        "simulation": {"plant_step": period, "sample_period": period, "duration": duration, "runs": runs},
        "plant": {
            "kind": "dp-vessel",
            "vessel": {"kind": "northern-clipper"},
            "bias": {"kind": "gauss-markov", "time_constant": 1000.0, "std": [0.0, 0.0, 0.0]},
            "waves": {"kind": "linear", "peak_frequency": 0.8976, "damping_ratio": 0.1, "amplitude": [0.0, 0.0, 0.0]},
            "initial": {"nu": [1.0, 0.2, 0.01]},
        },
        "sensors": {
            "gnss": {"kind": "gnss", "noise_std": 0.5 if noise else 0.0, "sample_period": 1.0},
            "gyro": {"kind": "gyrocompass", "noise_std": 0.0017 if noise else 0.0, "sample_period": period},
            "imu": {
                "kind": "imu",
                "accelerometer_std": 0.01 if noise else 0.0,
                "gyro_std": 0.001 if noise else 0.0,
                "sample_period": period,
                **(imu or {}),
            },
        },
        "observer": {"kind": "ins"} if noise else {"kind": "ins", "measurement_noise": FILTER_NOISE},
        "controller": {"kind": "sinusoidal", "amplitude": [2e5, 1e5, 2e6], "frequency": 0.05, "offset": [0.0, 0.0, 0.0]},
    }


def _dead_reckoned(period: float) -> tuple[float, float]:
    """(position error (m), heading error (rad)) after 60 s of the filter's own propagation
    (its model's discretization, no correction) from the true start, on the noise-free
    IMU's readings of a simulated run."""
    composition = compose(_document(period))
    trajectory = simulate(composition)
    observer, start = composition.scenario.observer, composition.scenario.initial_state
    measured = trajectory.signals.measurement.split(np.asarray(trajectory.measurement))
    readings = np.concatenate([measured["imu.measured_specific_force"], measured["imu.measured_yaw_rate"][:, None]], axis=1)
    mean = observer.augmented(observer.model.state(start.eta, rotate(start.eta[2], start.nu)[:2]))
    times = np.asarray(trajectory.time)

    def step(mean, sample):
        t, reading = sample
        return observer.step(mean, t, reading, period), None

    mean, _ = jax.lax.scan(step, mean, (jnp.asarray(times[:-1]), jnp.asarray(readings[:-1])))
    position = float(np.hypot(*(np.asarray(mean[:2]) - np.asarray(trajectory.truth["position"])[-1])))
    return position, abs(float(mean[2] - np.asarray(trajectory.truth["heading"])[-1]))


@pytest.mark.slow
def test_the_strapdown_propagation_follows_the_plant_to_first_order():
    """Noise-free IMU at the reference point, exact start: the strapdown propagation of the
    IMU's readings follows the simulated vessel, its error first order in the sample
    period (the reading held over each sample): halving the period halves the error
    after 60 s of a turning, accelerating vessel (measured 0.1462 m and 0.0731 m, ratio
    2.00; heading 2.0e-4 and 1.0e-4 rad)."""
    coarse, fine = _dead_reckoned(0.1), _dead_reckoned(0.05)
    assert fine[0] < 0.1
    assert 1.8 < coarse[0] / fine[0] < 2.2
    assert 1.8 < coarse[1] / fine[1] < 2.2


@functools.cache
def _biased_runs():
    document = _document(duration=600.0, imu={"accelerometer_bias": [0.02, -0.015], "gyro_bias": 0.002}, noise=True, runs=4)
    return simulate(compose(document))


@pytest.mark.slow
def test_a_constant_bias_is_estimated():
    """An IMU with 0.02 and -0.015 m/s2 of accelerometer bias and 0.002 rad/s (413 deg/h)
    of gyro bias, white noise 0.01 m/s2 and 0.001 rad/s, aided by a 1 Hz GNSS of 0.5 m
    and a 10 Hz gyrocompass of 0.1 deg, seeds 0 to 3: after 600 s the filter's biases
    are within 1e-3 m/s2 and 5e-5 rad/s of the truth on every seed (measured 2.7e-4 and
    1.1e-5) and closer than at 100 s (8.9e-4 and 5.1e-5)."""
    trajectory = _biased_runs()
    accelerometer = np.asarray(trajectory.estimate["accelerometer_bias"]) - np.array([0.02, -0.015])
    gyro = np.asarray(trajectory.estimate["gyro_bias"]) - 0.002
    times = np.asarray(trajectory.time)
    early = np.searchsorted(times, 100.0)
    assert np.abs(accelerometer[:, -1]).max() < 1e-3
    assert np.abs(gyro[:, -1]).max() < 5e-5
    assert np.abs(accelerometer[:, -1]).max() < np.abs(accelerometer[:, early]).max()
    assert np.abs(gyro[:, -1]).max() < np.abs(gyro[:, early]).max()


def _refused(document: dict) -> ValueError:
    """The one-line error composing ``document`` gives (a scenario file's: it names the
    table and the parameter)."""
    with pytest.raises(ValueError) as caught:
        compose(document)
    assert "\n" not in str(caught.value)
    return caught.value


@pytest.mark.parametrize(
    ("change", "named", "words"),
    [
        (lambda d: d["sensors"].pop("imu"), "imu", "the suite has none"),
        (lambda d: d["sensors"].update(imu2=copy.deepcopy(d["sensors"]["imu"])), "imu", "2 (imu, imu2)"),
        (lambda d: d["observer"].update(imu="gnss"), "imu", "no IMU named 'gnss'"),
        (lambda d: d["sensors"].pop("gyro"), "sensor", "a position reference and a heading"),
        (lambda d: d["observer"].update(wave_period=7.0), "wave_period", "go together"),
        (lambda d: d["observer"].update(bias_time_constant=-1.0), "bias_time_constant", "positive"),
        (lambda d: d["observer"].update(initial_bias_std=[0.0, 0.1, 0.1]), "initial_bias_std", "positive"),
        (lambda d: d["observer"].update(accelerometer_noise=float("nan")), "accelerometer_noise", "finite"),
    ],
)
def test_bad_input_is_refused_naming_the_parameter(change, named, words):
    document = _document()
    change(document)
    error = _refused(document)
    assert named in str(error) and words in str(error)


def test_a_sensor_that_is_not_a_suite_is_refused():
    document = _document()
    del document["sensors"]
    document["sensor"] = {"kind": "position-heading"}
    error = _refused(document)
    assert "sensor suite with an IMU" in str(error)


@pytest.mark.slow
def test_the_design_conditions_hold_on_the_example_and_fail_where_they_should():
    """examples/imu-dp.toml satisfies the observer's conditions; an IMU at 5 Hz under a
    10 Hz filter fails the rate condition; without the gyrocompass's row the model is not
    observable (the gyro bias is not seen), which the margin shows."""
    from pathlib import Path

    from lookout.analysis.ins import RANK_TOLERANCE, check_ins, observability_margin
    from lookout.scenario.file import load

    example = load(Path(__file__).resolve().parent.parent / "examples" / "imu-dp.toml", runs=1).composition
    report = check_ins(example)
    assert all(condition.holds for condition in report.conditions), [c.lines() for c in report.conditions]

    slow = _document()
    slow["sensors"]["imu"]["sample_period"] = 0.2
    report = check_ins(compose(slow))
    verdicts = {condition.key: condition.holds for condition in report.conditions}
    assert verdicts["imu_rate"] is False and verdicts["observable"] is True

    observer = compose(_document()).scenario.observer
    assert observability_margin(observer) > 1e3 * RANK_TOLERANCE
    assert observability_margin(observer, aiding=(True, True, False, False, False, False)) < RANK_TOLERANCE


#: The extended Kalman filter's prior on the test document (its plant has no noise of its
#: own on the bias and waves, so no steady state to start from).
EKF_INITIAL_STD = {
    "eta": [5.0, 5.0, 0.05],
    "nu": [0.5, 0.5, 0.005],
    "bias": [5e3, 5e3, 1e5],
    "wave_state": [1e-3] * 6,
    "imu_bias": [0.05, 0.05, 0.005],
}


@pytest.mark.slow
def test_acceleration_feedback_estimates_the_imus_biases():
    """The second way to use the IMU: the extended Kalman filter on the vessel's own model
    reads the IMU's specific force as a measurement of the model's acceleration, with the
    IMU's biases as states (imu_bias). The IMU of the constant-bias test above, seeds 0 and
    1, a 1 Hz GNSS of 0.5 m 30 m ahead and a 10 Hz gyrocompass: after 600 s the biases are
    within 2e-3 m/s2 and 1e-4 rad/s (measured 6.5e-4 and 1.6e-5)."""
    document = _document(duration=600.0, imu={"accelerometer_bias": [0.02, -0.015], "gyro_bias": 0.002}, noise=True, runs=2)
    document["sensors"]["gnss"]["lever_arm"] = [30.0, 5.0]
    document["observer"] = {"kind": "ekf", "imu_bias": [1e-4, 1e-4, 1e-6], "initial_std": EKF_INITIAL_STD}
    trajectory = simulate(compose(document))
    accelerometer = np.asarray(trajectory.estimate["accelerometer_bias"])[:, -1] - np.array([0.02, -0.015])
    gyro = np.asarray(trajectory.estimate["gyro_bias"])[:, -1] - 0.002
    assert np.abs(accelerometer).max() < 2e-3
    assert np.abs(gyro).max() < 1e-4


def test_the_imu_biases_initial_guess_is_a_key_of_observer_initial():
    """[observer.initial] takes imu_bias beside the plant's keys (the wrapped plant's
    state and the biases); a wrong size is refused at its key."""
    document = _document(noise=True)
    document["observer"] = {
        "kind": "ekf",
        "imu_bias": [1e-4, 1e-4, 1e-6],
        "initial_std": EKF_INITIAL_STD,
        "initial": {"imu_bias": [0.02, -0.015, 0.002]},
    }
    composition = compose(document)
    np.testing.assert_array_equal(np.asarray(composition.scenario.initial_estimate.bias), [0.02, -0.015, 0.002])
    assert composition.document["observer"]["initial"]["imu_bias"] == (0.02, -0.015, 0.002)
    document["observer"]["initial"] = {"imu_bias": [0.02, -0.015]}
    assert str(_refused(document)).startswith("observer.initial.imu_bias: must be one number or have 3 entries")


def test_imu_biases_need_an_imu():
    document = _document()
    document["sensors"].pop("imu")
    document["observer"] = {"kind": "ekf", "imu_bias": [1e-4, 1e-4, 1e-6], "initial_std": EKF_INITIAL_STD}
    error = _refused(document)
    assert "imu_bias" in str(error) and "no IMU" in str(error)
