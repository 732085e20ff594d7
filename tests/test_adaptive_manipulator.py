"""Calugi (2002) ch. 4: the adaptive observer (4.34)–(4.35), resetting (4.45), Theorem 4.1."""

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lookout.analysis.adaptive_manipulator import check_theorem_4_1, injection_bound
from lookout.analysis.velocity import configuration_bounds
from lookout.models.manipulators import TwoLinkArm
from lookout.models.parameters import ModelParameters
from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver, mass_matrix_margin
from lookout.papers import calugi_2002_adaptive_observer as ch4

ARM = ModelParameters(TwoLinkArm((1.0, 1.5), (1.0, 1.0), (0.0, 0.0)), ("masses[1]",), units=("kg",))
ARM_OBSERVER = AdaptiveManipulatorObserver(ARM, 5.0, 0.1, sample_period=0.01, lower=0.5, upper=3.0, margin=0.2)


@pytest.mark.slow
def test_discrete_tends_to_continuous_at_first_order():
    study = ch4.order_study(ch4.Config(), duration=5.0)
    for key in ("theta", "velocity"):
        errors = study["max_error"][key]
        assert all(a > b for a, b in zip(errors[:-1], errors[1:]))
        assert all(0.85 < order < 1.25 for order in study["order"][key]), study["order"]


@settings(max_examples=60, deadline=None)
@given(
    theta=st.floats(0.5, 3.0),
    theta_hat=st.floats(-5.0, 10.0),
    gamma=st.floats(1e-3, 1e3),
)
def test_a_reset_never_increases_v_and_keeps_m_hat_positive_definite(theta, theta_hat, gamma):
    """V = 1/2 (x1~^T M x1~ + theta~^T Gamma^-1 theta~): a reset moves theta_hat only."""
    after, fired = ARM_OBSERVER.reset(jnp.array([theta_hat]))
    before_v = 0.5 * (theta - theta_hat) ** 2 / gamma
    after_v = 0.5 * (theta - float(after[0])) ** 2 / gamma
    assert after_v <= before_v * (1 + 1e-12)
    assert bool(fired[0]) == (theta_hat <= 0.3 or theta_hat >= 3.2)
    assert 0.3 < float(after[0]) < 3.2 or float(after[0]) in (0.5, 3.0)
    # inside [l - mu, h + mu] the estimated inertia is positive definite at every q tried
    for q2 in np.linspace(-np.pi, np.pi, 9):
        assert np.linalg.eigvalsh(np.asarray(ARM.model(after).mass_matrix(jnp.array([0.0, q2]))))[0] > 0


def test_the_margin_must_keep_m_hat_positive_definite():
    # M = m l^2 > 0 needs m > 0: l - mu = 0.05 - 0.06 < 0
    with pytest.raises(ValueError, match=r"^margin mu and the bounds must keep M\(q; theta_hat\) positive definite"):
        AdaptiveManipulatorObserver(ch4.parameters(), 20.0, 10.0, sample_period=0.01, lower=0.05, upper=5.0, margin=0.06)
    assert mass_matrix_margin(ch4.parameters(), [0.05], [5.0]) == pytest.approx(0.05 * 1.5**2)
    with pytest.raises(ValueError, match=r"^observer gain K must satisfy \|1 - Delta K\| < 1"):
        AdaptiveManipulatorObserver(ch4.parameters(), 250.0, 10.0, sample_period=0.01)
    with pytest.raises(ValueError, match=r"^lower must be below upper"):
        AdaptiveManipulatorObserver(ch4.parameters(), 20.0, 10.0, sample_period=0.01, lower=2.0, upper=1.0)


def test_a_missing_sample_is_a_model_prediction_and_leaves_theta_alone():
    observer = ch4.REPRODUCTION.scenario(ch4.Config(), "delta-0.01").observer
    state = observer.init(jnp.array([0.2]), observer.guess(0.5, 0.4))
    state = observer.update(state, 0.0, jnp.array([0.2]))
    tau = jnp.array([0.7])
    predicted = observer.predict(state, 0.0, jnp.array([0.2]), tau, 0.01)
    dropped = observer.update(predicted, 0.01, jnp.array([jnp.nan]))
    psi = observer.model_acceleration(state.theta, state.position, state.velocity, tau)
    np.testing.assert_allclose(dropped.velocity, state.velocity + 0.01 * psi, rtol=1e-14)
    np.testing.assert_allclose(dropped.theta, state.theta, rtol=1e-14)
    assert np.all(np.isfinite(np.asarray(dropped.position)))


def test_theorem_4_1_constants():
    """Pendulum: sigma = K m l^2 and C_M = 0 (global). Two-link: sigma = K lambda_min(M)."""
    report = check_theorem_4_1(ch4.parameters(), 20.0, 10.0, max_speed=1.2, initial_error=([1.0], [0.9]))
    assert report.quantities["sigma"] == pytest.approx(20.0 * 1.5**2)
    assert report.holds and report.notes == ("region (4.b) global: C_M = 0, it holds for every initial error",)
    assert [item.name for item in report.inequalities] == ["(4.a)"]  # no (4.b) to check
    sigma = injection_bound(ARM, 5.0)
    assert sigma == pytest.approx(5.0 * configuration_bounds(ARM.model(ARM.reference)).min_inertia, rel=1e-3)
    arm = check_theorem_4_1(ARM, 5.0, 0.1, max_speed=1.0, initial_error=([1.0, 1.0], [0.8]))
    names = {item.name: item for item in arm.inequalities}
    assert names["(4.a)"].right == pytest.approx(arm.quantities["C_M"] * 1.0)
    assert names["(4.b)"].right == pytest.approx(np.sqrt(1.0 + 1.0 + 0.8**2))
    assert arm.verdicts == {"theorem_4_1": "fails"} and names["(4.a)"].source == "Calugi (2002), Theorem 4.1"


def test_reproduce_calugi_2002_adaptive_observer_writes_its_outputs(tmp_path, capsys):
    import json

    from lookout.cli import main

    out = tmp_path / "ch4"
    assert main(["reproduce", "calugi-2002-adaptive-observer", "--out", str(out), "--duration", "20", "--no-sweep"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["sample_periods"]) == {"0.01", "0.001"}
    for values in summary["sample_periods"].values():
        assert values["theta_hat_at"]["1 s"] > 0.1 and values["resets"] == 0  # moved from 0.1 kg; stayed in the bounds
    assert sorted(p.name for p in out.iterdir()) == summary["files"]
    assert "Theorem 4.1" in capsys.readouterr().out
