"""Wondergem et al. (2009): the error index (43) and the reproduction's outputs."""

import json

import numpy as np
import pytest

from lookout.cli import main
from lookout.models.cybership import CYBERSHIP_THRUST_LIMIT
from lookout.papers import wondergem_2009 as w

from .roundtrip import assert_same_floats, run_written_case


def test_error_index_of_known_signals():
    time = np.linspace(0.0, 2.0 * np.pi, 20001)
    # constant errors: the mean square; a sine over whole periods: 1/2 (trapezoid is exact to rounding here)
    assert w.error_index(time, np.full_like(time, 0.1), np.full_like(time, -0.2), np.full_like(time, 0.3)) == pytest.approx(0.14, rel=1e-12)
    assert w.error_index(time, np.sin(time), 0 * time, 0 * time) == pytest.approx(0.5, rel=1e-9)
    # a window [t1, t2]: the error outside does not count
    step = np.where(time < np.pi, 1.0, 0.0)
    assert w.error_index(time, step, 0 * time, 0 * time, start=np.pi + 0.01) == 0.0
    with pytest.raises(ValueError, match="error_index needs start < end"):
        w.error_index(time, time, time, time, start=3.0, end=2.0)


def test_reproduce_wondergem_2009_writes_its_outputs_and_never_exceeds_the_thrust_limits(tmp_path, capsys):
    out = tmp_path / "w09"
    assert main(["reproduce", "wondergem-2009", "--out", str(out), "--duration", "20", "--condition", "basin-waves", "--no-sweep"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["conditions"]) == ["basin-waves"]
    values = summary["conditions"]["basin-waves"]
    assert values["table_1"] == 0.12686 and np.isfinite(values["error_index"][0])
    files = sorted(path.name for path in out.iterdir())
    assert files == summary["files"]
    # velocities: one figure per condition (overlaid, the conditions hid each other)
    assert {"track.png", "errors.png", "velocities_basin_waves.png", "thrust.png", "wondergem_2009_basin_waves.nc"} <= set(files)
    import xarray as xr

    ds = xr.open_dataset(out / "wondergem_2009_basin_waves.nc")
    applied = np.concatenate([ds.force_applied.values, ds.moment_applied.values[..., None]], axis=-1)
    commanded = np.concatenate([ds.force_commanded.values, ds.moment_commanded.values[..., None]], axis=-1)
    assert np.all(np.abs(applied) <= np.asarray(CYBERSHIP_THRUST_LIMIT))
    assert np.any(np.abs(commanded) > np.asarray(CYBERSHIP_THRUST_LIMIT))  # the transient saturates
    assert float(np.abs(ds.wave_position).max()) > 0  # the waves reach the measurement
    # the proposal is a report: the check of the gains found, the search's numbers in its quantities
    proposal = summary["gain_proposal"]
    assert proposal["verdict"] == "holds" and proposal["quantities"]["proposal"]["found"] is True
    assert summary["reference_thrust"]["feasible"] is True
    conditions = summary["gain_conditions"]
    assert {item["name"] for key in conditions["verdicts"] for item in conditions[key]["inequalities"]} >= {"(25)", "(13)", "(27)"}
    assert "Table 1" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--condition", "basin"], "--condition must be distinct names from simulation, basin-calm, basin-waves; got basin"),
        (["--duration", "5"], "--duration must be between 10 s and 3600 s; got 5"),
        (["--gains", "kyp"], "--gains: wondergem-2009 has no such setting (it belongs to kim-2002)"),
    ],
)
def test_bad_wondergem_options_exit_2_with_one_line(argv, message, capsys):
    assert main(["reproduce", "wondergem-2009", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_reference_thrust_on_a_circle_by_hand():
    """On a circle of radius R the reference is nu_ref = [U, 0, U/R], nu_ref' = 0, so
    tau_ref = C(nu_ref) nu_ref + D(nu_ref) nu_ref, written out from (39); the lap steps
    are Kd [dU, 0, dU/R]."""
    R = 2.0
    thrust = w.reference_thrust(w.Config(semi_axes=(R, R)))
    U, r = 0.2, 0.2 / R  # the fourth lap is the largest
    surge = 0.72 * U + 1.33 * U * U - 1.0115 * r * r  # -(m22 v + m23 r) r with v = 0
    sway = 25.8 * U * r - 0.11 * r
    yaw = 1.0115 * r * U + 0.5 * r
    np.testing.assert_allclose(thrust["steady_peak"], [abs(surge), abs(sway), abs(yaw)], rtol=1e-9)
    controller = w.scenario(w.Config(semi_axes=(R, R)), "simulation").controller
    step = np.abs(np.asarray(controller.damping_gain) @ np.array([0.05, 0.0, 0.05 / R]))
    np.testing.assert_allclose(thrust["lap_step_peak"], step, rtol=1e-9)
    assert thrust["feasible"] is True


def test_design_tracking_gains_checks_and_proposes(capsys):
    assert main(["design", "tracking-gains", "--json"]) == 1
    result = json.loads(capsys.readouterr().out)
    verdicts = {item["name"]: item["verdict"] for key in result["verdicts"] for item in result[key]["inequalities"]}
    assert result["holds"] is False and verdicts["(25)"] == "fails" and verdicts["(27)"] == "fails" and verdicts["(11)"] == "holds"
    # the defaults are the paper's printed gains and the reproduction's settings, from the paper's package
    assert result["inputs"]["gains"] == {
        "L1": [w.config.OBSERVER_POSITION_GAIN] * 3,
        "L2": [w.config.OBSERVER_VELOCITY_GAIN] * 3,
        "natural_frequency": list(w.config.NATURAL_FREQUENCY),
        "damping_ratio": [w.config.DAMPING_RATIO] * 3,
    }
    config = w.Config()
    assert (result["inputs"]["velocity_bound"], result["inputs"]["start_angle"], result["inputs"]["direction"]) == (
        w.config.VELOCITY_BOUND,
        config.start_angle,
        config.direction,
    )
    assert main(["design", "tracking-gains", "--propose", "--start", "measured"]) == 0
    text = capsys.readouterr().out
    assert "proposed: Omega = " in text and "(32)" in text and "verdict: passes (exit code 0)" in text


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--start", "exact"], "--start must be printed or measured; got 'exact'"),
        (["--l2", "-5"], "--l2 must be one finite positive number"),
        (["--omega", "1e13"], "--omega must lie within 1e-12..1e12"),
        (["--epsilon3", "nan"], "--epsilon3 must be a finite positive number"),
        (["--propose", "--lambda", "1,2,3"], "--lambda must be one number with --propose"),
    ],
)
def test_design_tracking_gains_bad_input_exits_2_with_one_line(argv, message, capsys):
    assert main(["design", "tracking-gains", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_the_10_hz_hold_makes_the_20_hz_command_alternate():
    """basin-calm without noise: with the 10 Hz measurement held over two 20 Hz steps the
    commanded surge force jumps every step (v_hat alternates); with 20 Hz measurements it
    is smooth."""
    rows = {row["case"]: row for row in w.hold_study(w.Config(duration=40.0))}
    assert set(rows) == {case[0] for case in w.HOLD_CASES}
    assert rows["10 Hz held"]["lap4_surge_error_m"] is None  # 40 s does not reach lap 4
    assert rows["10 Hz held, no limits"]["surge_command_step_N"] > 1.0
    assert rows["20 Hz"]["surge_command_step_N"] < 0.05


@pytest.mark.parametrize("case", w.REPRODUCTION.cases)
def test_a_case_written_as_a_scenario_file_gives_the_reproductions_numbers_exactly(case, tmp_path):
    """Each case's composition, saved as a scenario file and run by ``lookout run``, gives
    every float variable of the reproduction's own simulation of the case, bit for bit."""
    config = w.Config(duration=10.0, seed=3)
    ran = run_written_case(w.REPRODUCTION, config, case, tmp_path)
    reproduced = w.simulate_condition(config, case)
    compared = assert_same_floats(ran, reproduced, case)
    assert len(compared) >= 20 and list(ran.seed.values) == [3]
    assert (float(np.abs(ran.wave_position).max()) > 0) == (case == "basin-waves")  # the waves reach the measurement
