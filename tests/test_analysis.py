import numpy as np
import pytest

from lookout import PassiveObserver, northern_clipper
from lookout.analysis import (
    Verdict,
    check_passive_observer,
    check_spr,
    check_tuning_rule,
    error_loop,
    fit_decay_rate,
    frequency_response,
    minimum_phase_in_band,
    settling_time,
    transfer_functions,
)


def _observer(kappa, lam, T=1000.0):
    return PassiveObserver.design(
        northern_clipper(),
        wave_frequency=0.8976,
        wave_damping=0.1,
        notch_damping=1.0,
        cutoff_frequency=1.1,
        velocity_injection_gain=kappa,
        bias_injection_gain=lam,
        bias_time_constant=T,
    )


def test_paper_gains_satisfy_tuning_rule_and_spr_with_verified_kyp(paper_observer):
    assert check_tuning_rule(paper_observer).holds
    for index, report in enumerate(check_spr(paper_observer)):
        assert report.holds and report.quantities["frequency_test"]
        assert report.key == f"spr_{['surge', 'sway', 'yaw'][index]}"
        certificate = report.quantities["certificate"]
        assert certificate["verified"]
        A, B, C = error_loop(paper_observer, index)
        P, Q = np.array(certificate["P"]), np.array(certificate["Q"])
        np.testing.assert_allclose(P, P.T, rtol=1e-12)
        np.testing.assert_allclose(P @ A + A.T @ P, -Q, rtol=1e-9, atol=1e-9 * np.abs(Q).max())
        np.testing.assert_allclose(B.T @ P, C, rtol=1e-9)
        assert np.all(np.linalg.eigvalsh(P) > 0)
        scale = 1 / np.sqrt(np.diag(Q))
        assert np.linalg.eigvalsh(scale[:, None] * Q * scale[None, :]).min() > 0


def test_in_band_phase_margin_is_reported_near_the_notch(paper_observer):
    """The paper's gains leave h within a degree of -90 deg just below w_o."""
    w = np.linspace(0.3, 0.9, 20001)
    phase = np.degrees(np.angle(transfer_functions(paper_observer, w)["h"][:, 0]))
    report = check_spr(paper_observer)[0]
    q = report.quantities
    assert q["min_phase_deg_in_band"] == pytest.approx(phase.min(), abs=0.05)
    assert 0.6 < q["min_phase_frequency_in_band"] < 0.8976
    assert -90.0 < q["min_phase_deg_in_band"] < -89.0
    (margin,) = report.informational  # the phase against -90 deg, not in the verdict
    assert margin.left == q["min_phase_deg_in_band"] and margin.right == -90.0 and 0.0 < margin.margin < 1.0


def test_transfer_function_matches_state_space_error_loop(paper_observer):
    w = np.logspace(-4, 2, 50)
    h = transfer_functions(paper_observer, w)["h"]
    for dof in range(3):
        A, B, C = error_loop(paper_observer, dof)
        direct = [(C @ np.linalg.solve(1j * wi * np.eye(4) - A, B)).item() for wi in w]
        np.testing.assert_allclose(h[:, dof], direct, rtol=1e-9)


def _failures(condition):
    return [item for item in condition.inequalities if item.verdict == "fails"]


def test_violated_tuning_rule_is_reported_with_its_margin_and_spr_fails():
    observer = _observer(kappa=1.0, lam=2.0)  # lambda/kappa = 2 > w_o
    report = check_tuning_rule(observer)
    assert report.verdict == Verdict.FAILS and not report.holds
    failures = _failures(report)
    assert {(item.name, item.relation) for item in failures} == {(dof, "lambda/kappa < w_o") for dof in ("surge", "sway", "yaw")}
    assert failures[0].factor == pytest.approx(0.8976 / 2.0) and failures[0].margin == pytest.approx(0.8976 - 2.0)
    assert failures[0].describe() == "surge: lambda/kappa < w_o: 2 < 0.8976 rad/s: fails, margin -1.1, factor 0.449"
    assert failures[0].source == "Fossen & Strand (1999), eq. (48)"
    spr = check_spr(observer)
    assert all(item.verdict == "fails" for item in spr)
    assert all(item.quantities["min_real_part"] < 0 for item in spr)


def test_much_less_than_is_checked_with_its_factor():
    observer = _observer(kappa=1.0, lam=0.005)  # lambda/kappa = 5/T: only 5x above 1/T
    failures = _failures(check_tuning_rule(observer))
    assert {item.relation for item in failures} == {"1/T << lambda/kappa, read as 10/T <= lambda/kappa"}
    assert failures[0].left == pytest.approx(10 / 1000.0) and failures[0].right == pytest.approx(0.005)
    assert check_tuning_rule(observer, much_less_factor=4.0).holds


def test_frequency_response_dataset(paper_observer):
    ds = frequency_response(paper_observer, [0.1, 0.8976, 10.0])
    assert ds.h0_magnitude.dims == ("frequency", "dof")
    # h0: velocity error (m/s) -> position error (m); hB: position error -> force; yaw in N m/rad
    assert ds.h0_magnitude.attrs["units"] == "s"
    assert ds.hB_magnitude_translation.attrs["units"] == "N/m" and ds.hB_magnitude_yaw.attrs["units"] == "N m/rad"
    assert ds.h_magnitude_translation.attrs["units"] == "N s/m" and ds.h_magnitude_yaw.attrs["units"] == "N m s/rad"
    np.testing.assert_allclose(ds.bias_filter_frequency, 1e-3)
    np.testing.assert_allclose(ds.wave_frequency, 0.8976)
    np.testing.assert_allclose(ds.cutoff_frequency, 1.1)
    np.testing.assert_allclose(
        ds.bias_gain_ratio, np.asarray(paper_observer.bias_injection_gain) / np.asarray(paper_observer.velocity_injection_gain)
    )
    # the default grid spans two decades either side of the loop's time scales
    default = frequency_response(paper_observer).frequency.values
    assert default[0] == pytest.approx(1e-5) and 100 < default[-1] < 200
    assert ds.h_phase_deg.sel(frequency=10.0).values.min() > -90.0
    with pytest.raises(ValueError, match="frequencies must be a 1-D array of positive finite values"):
        frequency_response(paper_observer, [0.0, 1.0])


def test_fit_decay_rate_recovers_an_exact_exponential():
    t = np.linspace(0, 100, 1001)
    fit = fit_decay_rate(t, 3.0 * np.exp(-0.25 * t))
    assert fit["rate"] == pytest.approx(0.25, rel=1e-9) and fit["r_squared"] > 0.999999


def test_settling_time_of_many_errors_at_once_equals_one_at_a_time():
    rng = np.random.default_rng(1)
    t = np.arange(0, 500.0, 0.5)
    errors = rng.normal(size=(4, 3, t.size)) + 20 * np.exp(-t / rng.uniform(10, 80, size=(4, 3, 1)))
    final = np.sqrt(np.mean(errors[..., t >= 250] ** 2, axis=-1))
    final[0, 0] = 1e-9  # never settles: NaN
    together = settling_time(errors, t, final)
    assert together.shape == (4, 3) and np.isnan(together[0, 0])
    for i in range(4):
        for j in range(3):
            np.testing.assert_equal(together[i, j], settling_time(errors[i, j], t, final[i, j]))


def test_settling_time_of_a_decaying_plus_stationary_error():
    t = np.arange(0, 2000.0, 0.1)
    rng = np.random.default_rng(0)
    noise = rng.normal(size=t.size)
    error = 100 * np.exp(-t / 50.0) + noise
    final = np.sqrt(np.mean(noise[t >= 1000] ** 2))
    settle = settling_time(error, t, final)
    assert 150 < settle < 400  # transient 100 e^{-t/50} must be well below the unit noise


def test_spr_is_not_claimed_without_a_verified_certificate():
    """A stiff loop (w_c = 1e6 rad/s) passes the frequency test, but no certificate is
    verified: the verdict is "unverified" with the reason, never "holds"."""
    observer = PassiveObserver.design(
        northern_clipper(),
        wave_frequency=0.8976,
        wave_damping=0.1,
        notch_damping=1.0,
        cutoff_frequency=1e6,
        velocity_injection_gain=5.91e4,
        bias_injection_gain=2121.0,
        bias_time_constant=1000.0,
    )
    for report in check_spr(observer):
        assert report.quantities["frequency_test"] and report.quantities["min_real_part"] > 0
        assert report.verdict == "unverified" and not report.holds and not report.quantities["certificate"]["verified"]
        assert "poles span 0.001 to 1e+06 rad/s" in report.reason
        assert report.to_dict()["verdict"] == "unverified"
        # the frequency conditions hold; the certificate's inequalities are undecided, none fails
        assert [item.verdict for item in report.inequalities[:3]] == ["holds"] * 3
        assert "unverified" in {item.verdict for item in report.inequalities[3:]} and "fails" not in {item.verdict for item in report.inequalities}


def test_passive_observer_report_has_the_tuning_rule_and_spr_per_dof(paper_observer):
    report = check_passive_observer(paper_observer)
    assert list(report.verdicts) == ["tuning_rule_48", "spr_surge", "spr_sway", "spr_yaw"]
    assert report.holds and [{item.name for item in report[key].inequalities} for key in ("spr_surge", "spr_sway", "spr_yaw")] == [
        {"surge"},
        {"sway"},
        {"yaw"},
    ]
    assert np.asarray(report.quantities["K2"]).diagonal() == pytest.approx([1.1] * 3)
    assert any(line.startswith("K1 = [diag(-2.206") for line in report.summary)


def test_in_band_minimum_ignores_the_high_frequency_asymptote():
    w = np.array([0.1, 1.0, 5.0, 20.0, 100.0])
    phase = np.array([-10.0, -60.0, -50.0, -89.0, -89.9])
    assert minimum_phase_in_band(w, phase, cutoff_frequency=1.0) == (-60.0, 1.0)
    assert minimum_phase_in_band(w, phase, cutoff_frequency=10.0) == (-89.9, 100.0)
    assert minimum_phase_in_band(w, phase, cutoff_frequency=1e-3) == (-89.9, 100.0)  # nothing in band: whole grid


# -- the vocabulary (lookout.analysis.conditions) ------------------------------------


def _inequality(left, comparison, right, **kwargs):
    from lookout.analysis import Inequality

    return Inequality.check("(1)", "a ? b", left, comparison, right, units="1/s", source="A paper (2000), eq. (1)", **kwargs)


@pytest.mark.parametrize(
    "left, comparison, right, verdict",
    [
        (2.0, ">", 1.0, "holds"),
        (1.0, ">", 2.0, "fails"),
        (1.0, "<", 2.0, "holds"),
        (1.0, ">", 1.0, "unverified"),  # equal: rounding decides a strict comparison
        (1.0, ">=", 1.0, "holds"),  # the same number meets a non-strict one
        (1.0, "<=", 1.0 + 1e-15, "unverified"),  # within the tolerance but not the same number
        (1.0 + 1e-9, ">", 1.0, "holds"),
        (float("nan"), ">", 1.0, "unverified"),
        (float("inf"), ">", 1e300, "holds"),
        (1.0, ">", float("inf"), "fails"),
        (float("inf"), ">", float("inf"), "unverified"),
    ],
)
def test_inequality_verdict(left, comparison, right, verdict):
    assert _inequality(left, comparison, right).verdict == verdict


def test_inequality_margin_factor_tolerance_and_a_search_that_fails_is_unverified():
    item = _inequality(3.0, "<", 12.0)
    assert (item.margin, item.factor, item.tolerance) == (9.0, 4.0, 12e-12)
    assert _inequality(0.0, ">", 1e-3, tolerance=1e-2).verdict == "unverified"
    assert _inequality(0.5, ">", 0.0).factor == float("inf") and np.isnan(_inequality(-1.0, ">", 2.0).factor)
    assert _inequality(-1.0, ">", 0.0, failure=Verdict.UNVERIFIED).verdict == "unverified"
    assert _inequality(1.0, ">", 0.0, failure=Verdict.UNVERIFIED).verdict == "holds"
    with pytest.raises(ValueError, match="comparison must be one of"):
        _inequality(1.0, "!=", 0.0)
    data = _inequality(1.0, ">", 0.0).to_dict()
    assert data["factor"] is None and data["verdict"] == "holds" and data["source"] == "A paper (2000), eq. (1)"
    assert set(data) == {"name", "relation", "left", "comparison", "right", "units", "source", "verdict", "margin", "factor", "tolerance"}


def test_condition_and_report_derive_their_verdicts_and_share_one_layout():
    import json

    from lookout.analysis import Condition, Report

    holds, fails, open_ = _inequality(2.0, ">", 1.0), _inequality(1.0, ">", 2.0), _inequality(1.0, ">", 1.0)
    assert Verdict.combine([]) == "unverified" and Verdict.combine(["holds", "unverified"]) == "unverified"
    a = Condition("a", "(1)", "first", "A paper (2000), eq. (1)", [holds, open_])
    b = Condition("b", "(2)", "second", "A paper (2000), eq. (2)", [holds, fails], informational=[fails])
    assert (a.verdict, b.verdict) == ("unverified", "fails")
    assert a.reason == "(1): a ? b is not decided numerically" and b.reason == "(1): a ? b fails"
    assert Condition("c", "(3)", "third", "A paper", [holds]).reason == "the inequality holds"
    report = Report("A paper (2000): two conditions", [a, b], {"gain": np.array([1.0, 2.0])}, ("gains: 1, 2",), ("a note",))
    assert report.verdict == "fails" and report.verdicts == {"a": "unverified", "b": "fails"} and report["b"] is b
    assert report.inequalities == (holds, open_, holds, fails)  # informational ones left out
    data = json.loads(json.dumps(report.to_dict(), allow_nan=False))
    # each inequality once, in its condition's block
    assert list(data) == ["title", "verdict", "holds", "verdicts", "a", "b", "quantities", "summary", "notes"]
    assert data["b"]["inequalities"][1]["verdict"] == "fails" and data["b"]["informational"][0]["name"] == "(1)"
    assert [item["verdict"] for key in data["verdicts"] for item in data[key]["inequalities"]] == ["holds", "unverified", "holds", "fails"]
    assert data["quantities"] == {"gain": [1.0, 2.0]}
    lines = report.lines()
    assert lines[:2] == ["A paper (2000): two conditions: fails", "  gains: 1, 2"]
    assert lines[2] == "(1) first [A paper (2000), eq. (1)]: unverified" and lines[-1] == "note: a note"
    assert "    (not in the verdict) (1): a ? b: 1 > 2 1/s: fails, margin -1, factor 0.5" in lines
    longer = report.extended(summary=["first line"], notes=["last"], quantities={"more": 1})
    assert longer.summary == ("first line", "gains: 1, 2") and longer.notes == ("a note", "last") and set(longer.quantities) == {"gain", "more"}
    with pytest.raises(ValueError, match="unique"):
        Report("t", [a, a])
    with pytest.raises(ValueError, match="must not be a report key"):
        Report("t", [Condition("inputs", "(1)", "x", "A paper", [holds])])
    with pytest.raises(ValueError, match="one line"):
        Condition("c", "(3)", "third", "A paper", [holds], reason="two\nlines")
