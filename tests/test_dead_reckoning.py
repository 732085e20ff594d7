"""The dead-reckoning benchmark's measurements (lookout.studies.dead_reckoning) on errors
whose drift and recovery are known, its documents, and its command's refusals."""

from __future__ import annotations

import numpy as np
import pytest

from lookout.cli import main
from lookout.studies import dead_reckoning as dr


def _errors():
    """Two runs on a 0.1 s grid: a level of 0.5 m (run 0) and 1 m (run 1) before the loss;
    during it the error grows as 0.01 t (run 0) and 0.02 t (run 1) metres, t seconds into the
    loss; after it, run 0 is back at its level at once and run 1 holds 4 m for 30 s first."""
    times = np.arange(0.0, dr.LOSS_START + dr.LOSS_DURATION + dr.RECOVERY, 0.1)
    error = np.empty((2, times.size))
    into = times - dr.LOSS_START
    for run, (level, rate) in enumerate([(0.5, 0.01), (1.0, 0.02)]):
        error[run] = np.where(into < 0, level, rate * into)
        error[run, into >= dr.LOSS_DURATION] = level
    error[1, (into >= dr.LOSS_DURATION) & (into < dr.LOSS_DURATION + 30.0)] = 4.0
    return times, error


def test_the_drift_is_taken_before_each_time_and_the_recovery_when_the_level_is_back():
    times, error = _errors()
    level, drift, recovery = dr.measure(times, error)
    np.testing.assert_allclose(level, [0.5, 1.0])
    # the last sample before 60, 300, 600 s into the loss: 59.9 s, 299.9 s, 599.9 s
    for seconds in dr.DRIFT_TIMES:
        np.testing.assert_allclose(drift[seconds], [0.01 * (seconds - 0.1), 0.02 * (seconds - 0.1)], rtol=1e-9)
    assert recovery[0] == pytest.approx(0.0, abs=1e-9)
    # run 1: the 60 s window's RMS is within 1.25 of 1 m once at most (1.25^2 - 1) / 15 of it is the 4 m part
    window = dr.RECOVERY_WINDOW
    allowed = (dr.RECOVERED**2 - 1.0) / (4.0**2 - 1.0) * window
    assert recovery[1] == pytest.approx(30.0 - allowed, abs=0.11)


def test_a_run_that_does_not_recover_is_said_so_in_the_table():
    times, error = _errors()
    error[1, times >= dr.LOSS_START + dr.LOSS_DURATION] = 10.0
    level, drift, recovery = dr.measure(times, error)
    assert np.isnan(recovery[1])
    row = dr.Row("x", "hull model 25 % off", level, drift, recovery, 0)
    table = dr.table([row])
    assert "1 of 2 recover" in table and "| x | hull model 25 % off |" in table


@pytest.mark.slow
def test_every_entry_composes_and_loses_both_receivers_over_the_stated_window():
    from lookout.scenario.composition import compose

    for entry in dr.ENTRIES:
        document = dr.document(entry, 1)
        assert document["sensors"]["dgnss1"]["failures"] == [{"mode": "dropout", "start": dr.LOSS_START, "duration": dr.LOSS_DURATION}]
        assert ("imu" in document["sensors"]) == entry.imu
        compose(document)


def test_the_hull_model_error_reaches_the_vessel_and_not_the_observers_models():
    """Under the model error the plant's vessel is 25 % heavier and more damped; the passive
    observer's vessel and the extended Kalman filter's plant stay the paper's."""
    from lookout.scenario.composition import compose

    error = "hull model 25 % off"
    passive, ekf = (dr.document(entry, 1, error) for entry in dr.ENTRIES[:2])
    for document in (passive, ekf):
        assert document["plant"]["vessel"] == {"kind": "northern-clipper", "mass_scale": 1.25, "damping_scale": 1.25}
    assert passive["observer"]["vessel"] == {"kind": "northern-clipper", "mass_scale": 1.0, "damping_scale": 1.0}
    assert ekf["observer"]["plant"]["vessel"] == {"kind": "northern-clipper", "mass_scale": 1.0, "damping_scale": 1.0}
    composed = compose(passive).scenario
    mass = float(composed.plant.vessel.mass_matrix[0, 0])
    assert float(composed.observer.mass_matrix[0, 0]) * 1.25 == pytest.approx(mass, rel=1e-12)


@pytest.mark.slow
def test_the_changing_environment_reaches_the_vessel_and_not_the_observers_models():
    from lookout.scenario.composition import compose

    passive, ekf = (dr.document(entry, 1, "environment changing") for entry in dr.ENTRIES[:2])
    assert passive["plant"]["disturbance"] == {"kind": "body-force", "amplitude": [2000.0, 2000.0, 50000.0], "period": 2400.0}
    assert "disturbance" not in ekf["observer"]["plant"]
    assert compose(passive).scenario.plant.disturbance is not None and compose(ekf).scenario.observer.model.disturbance is None


@pytest.mark.parametrize("out", ["", "README.md"])
def test_the_command_refuses_an_output_that_is_no_folder(out, capsys):
    assert main(["benchmark", "dead-reckoning", "--out", out]) == 2
    captured = capsys.readouterr()
    assert "--out" in captured.err + captured.out and "Traceback" not in captured.err


@pytest.mark.slow
def test_the_model_free_observer_leaves_a_suites_imu_out():
    """The model without a hull has no acceleration: the same suite with and without an IMU
    gives it the same estimates, to rounding (the IMU's masked rows change the sizes of the
    matrices the correction multiplies, not what it takes: measured 1.3e-15 relative)."""
    from lookout.scenario.composition import compose, simulate

    document = dr.document(dr.Entry("model-free", {"kind": "model-free"}, imu=False), 1)
    document["simulation"]["duration"] = 20.0
    for table in document["sensors"].values():
        table.pop("failures", None)
    without = simulate(compose(document))
    document["sensors"]["imu"] = {"kind": "imu", "grade": "industrial", "lever_arm": [10.0, 0.0], "sample_period": 0.1}
    with_imu = simulate(compose(document))
    np.testing.assert_allclose(np.asarray(with_imu.estimate["position"]), np.asarray(without.estimate["position"]), rtol=1e-12, atol=1e-12)


# ----------------------------------------------------------------------------------
# the claims of docs/choosing-an-observer.md, measured on seeds 0 and 1 (the exact hull
# model; two minutes after the return)


@pytest.fixture(scope="module")
def measured() -> dict[str, dr.Row]:
    entries = {entry.name: entry for entry in dr.ENTRIES}
    return {name: dr.run_entry(entries[name], 2, after=120.0) for name in ("passive", "ins, tactical", "ins, navigation")}


@pytest.mark.slow
def test_with_references_the_imu_aided_observer_is_no_worse_than_the_passive_one(measured):
    """The low-frequency position error's RMS over the 300 s before the loss, per seed:
    measured 0.53 and 0.46 m (tactical) against 1.0 and 1.0 m (passive)."""
    passive = measured["passive"].before
    for grade in ("ins, tactical", "ins, navigation"):
        assert np.all(measured[grade].before <= passive), (grade, measured[grade].before, passive)


@pytest.mark.slow
def test_after_ten_minutes_the_navigation_grade_drifts_less_than_the_passive_observer_and_the_tactical_grade_more(measured):
    """The drift 600 s into the loss, per seed: navigation grade 4.6 and 4.0 m, passive 27
    and 6.5 m, tactical grade 40 and 36 m. The tactical grade's in-run accelerometer
    bias (0.1 mg, a tenth of the HG1700's 1 mg) is what it cannot learn before the
    loss; the passive observer dead reckons on a hull model that is exact here and on a
    bias estimate of an environment that changes slowly (docs/choosing-an-observer.md)."""
    passive, tactical, navigation = (measured[name].drift[dr.LOSS_DURATION] for name in ("passive", "ins, tactical", "ins, navigation"))
    assert np.all(navigation < passive) and np.all(tactical > passive), (navigation, passive, tactical)
    assert all(row.diverged == 0 for row in measured.values())


@pytest.mark.slow
def test_the_imu_aided_observer_recovers_within_thirty_seconds_of_the_return(measured):
    """Recovery: the error's RMS over the next 60 s back within 1.25 times its level
    before the loss; measured 2.8 to 3.2 s."""
    for grade in ("ins, tactical", "ins, navigation"):
        recovery = measured[grade].recovery
        assert np.all(np.isfinite(recovery)) and np.all(recovery <= 30.0), (grade, recovery)
