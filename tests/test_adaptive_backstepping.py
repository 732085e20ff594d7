"""Calugi (2002) ch. 5: adaptive observer backstepping (5.9)–(5.12), the (5.37) erratum, (5.28)."""

import json

import jax.numpy as jnp
import numpy as np
import pytest

from lookout.analysis.adaptive_manipulator import check_5_28
from lookout.cli import main
from lookout.controllers.adaptive_backstepping import AdaptiveObserverBackstepping
from lookout.papers import calugi_2002_backstepping as ch5


def test_the_observer_sees_psi_equal_to_minus_v():
    """With tau of (5.9), psi = M_hat^-1 (tau - C_hat x1_hat - F_hat x1_hat - G_hat) = -v,
    for any theta_hat (the control law and the observer share M(q; theta_hat))."""
    parameters = ch5.parameters()
    controller = AdaptiveObserverBackstepping(parameters, 5.0, 2.0, 3.0, [1.0, 0.5, 2.0, 1.5])
    observer = ch5.build(ch5.Config()).observer
    rng = np.random.default_rng(3)
    for _ in range(4):
        q, velocity = jnp.asarray(rng.normal(size=2)), jnp.asarray(rng.normal(size=2))
        theta = jnp.asarray([rng.uniform(0.5, 3.0)])
        reference = {
            "joint_angle_desired": jnp.asarray(rng.normal(size=2)),
            "joint_angle_desired_rate": jnp.asarray(rng.normal(size=2)),
            "joint_angle_desired_acceleration": jnp.asarray(rng.normal(size=2)),
        }
        tau = controller.law(q, velocity, theta, reference)
        z1, z2, q_d_accel = controller.errors(q, velocity, reference)
        first, second = controller.gains()
        v = -(first**2) * z1 + first * z2 - q_d_accel + second * z2 + z1
        np.testing.assert_allclose(observer.model_acceleration(theta, q, velocity, tau), -v, rtol=1e-10, atol=1e-10)
    # D2 = diag(d_{n+i} |omega_i|^2), Omega = C1 + D1 + K: 2 + 1 + 5 = 8 -> 2 + 64 for the printed gains
    np.testing.assert_allclose(ch5.build(ch5.Config()).controller.gains()[1], [66.0, 66.0])


def test_5_28_fails_at_rest_for_the_printed_gains():
    report = check_5_28(ch5.parameters(), 5.0, 1.0, max_speed=0.0)
    at_rest = report.inequalities[0]
    assert at_rest.verdict == "fails" and at_rest.right == pytest.approx(1.0)  # p/4 with p = 2n = 4
    assert at_rest.left == pytest.approx(0.90, abs=0.01)  # 5 lambda_min(M) at q2 = 0 (derivations: 0.90)
    assert report.quantities["C_M"] == pytest.approx(2.47, abs=0.01)


@pytest.mark.slow
def test_reproduce_calugi_2002_backstepping_corrected_tracks_and_printed_is_reported_diverged(tmp_path, capsys):
    out = tmp_path / "ch5"
    assert main(["reproduce", "calugi-2002-backstepping", "--out", str(out), "--duration", "20"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    corrected, printed = summary["variants"]["corrected"], summary["variants"]["printed"]
    assert corrected["status"] == "finite"
    # just before the square wave switches at 20 s the transient of the 10 s switch has decayed
    assert max(corrected["tracking_error_final"]) < 1e-4
    assert abs(corrected["theta_hat_final"] - 1.5) < 1e-3
    assert corrected["theta_hat_min"] < 0  # the first samples: tau(0) = (-335, -138) N m drives theta_hat below zero
    assert printed["status"] != "finite" and printed["finite_until_s"] < 5.0  # reported, not crashed
    assert printed["m_hat_indefinite_from_s"] is not None
    assert sorted(p.name for p in out.iterdir()) == summary["files"]
    assert "(5.28)" in capsys.readouterr().out


def test_design_adaptive_arm_checks_theorem_4_1_and_5_28(capsys):
    assert main(["design", "adaptive-arm", "--arm", "pendulum"]) == 0  # C_M = 0: global
    assert "verdict: passes (exit code 0)" in capsys.readouterr().out
    assert main(["design", "adaptive-arm", "--json"]) == 1  # the two-link arm's printed gains
    result = json.loads(capsys.readouterr().out)
    assert result["holds"] is False and "passed" not in result
    (at_rest,) = [item for item in result["condition_5_28"]["inequalities"] if item["name"] == "(5.28) at rest"]
    assert at_rest["verdict"] == "fails" and at_rest["right"] == 1.0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--arm", "robot"], "--arm must be pendulum or two-link; got 'robot'"),
        (["--k", "0"], "--k must be one finite positive number or 2 separated by commas"),
        (["--d", "1,2,3"], "--d must be one finite positive number or 4 separated by commas"),
        (["--max-speed", "nan"], "--max-speed must be finite and >= 0"),
    ],
)
def test_design_adaptive_arm_bad_input_exits_2_with_one_line(argv, message, capsys):
    assert main(["design", "adaptive-arm", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
