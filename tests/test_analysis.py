import numpy as np
import pytest

from lookout import PassiveObserver, northern_clipper
from lookout.analysis import (
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
        northern_clipper(), wave_frequency=0.8976, wave_damping=0.1, notch_damping=1.0, cutoff_frequency=1.1,
        velocity_injection_gain=kappa, bias_injection_gain=lam, bias_time_constant=T,
    )


def test_paper_gains_satisfy_tuning_rule_and_spr_with_verified_kyp(paper_observer):
    assert check_tuning_rule(paper_observer).holds
    for report in check_spr(paper_observer):
        assert report.hurwitz and report.spr
        certificate = report.certificate
        assert certificate["verified"]
        A, B, C = error_loop(paper_observer, ["surge", "sway", "yaw"].index(report.dof))
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
    assert report.min_phase_deg_in_band == pytest.approx(phase.min(), abs=0.05)
    assert 0.6 < report.min_phase_frequency_in_band < 0.8976
    assert -90.0 < report.min_phase_deg_in_band < -89.0


def test_transfer_function_matches_state_space_error_loop(paper_observer):
    w = np.logspace(-4, 2, 50)
    h = transfer_functions(paper_observer, w)["h"]
    for dof in range(3):
        A, B, C = error_loop(paper_observer, dof)
        direct = [(C @ np.linalg.solve(1j * wi * np.eye(4) - A, B)).item() for wi in w]
        np.testing.assert_allclose(h[:, dof], direct, rtol=1e-9)


def test_violated_tuning_rule_is_reported_with_its_margin_and_spr_fails():
    observer = _observer(kappa=1.0, lam=2.0)  # lambda/kappa = 2 > w_o
    report = check_tuning_rule(observer)
    assert not report.holds
    failures = {(item.dof, item.relation) for item in report.failures}
    assert failures == {(dof, "lambda/kappa < w_o") for dof in ("surge", "sway", "yaw")}
    assert report.failures[0].margin == pytest.approx(0.8976 / 2.0)
    assert "FAILS (ratio 0.449" in report.failures[0].describe()
    spr = check_spr(observer)
    assert not any(item.spr for item in spr)
    assert all(item.min_real_part < 0 for item in spr)


def test_much_less_than_is_checked_with_its_factor():
    observer = _observer(kappa=1.0, lam=0.005)  # lambda/kappa = 5/T: only 5x above 1/T
    failures = check_tuning_rule(observer).failures
    assert {item.relation for item in failures} == {"1/T << lambda/kappa"}
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
    np.testing.assert_allclose(ds.bias_gain_ratio, np.asarray(paper_observer.bias_injection_gain) / np.asarray(paper_observer.velocity_injection_gain))
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
        northern_clipper(), wave_frequency=0.8976, wave_damping=0.1, notch_damping=1.0, cutoff_frequency=1e6,
        velocity_injection_gain=5.91e4, bias_injection_gain=2121.0, bias_time_constant=1000.0,
    )
    for report in check_spr(observer):
        assert report.frequency_test and report.min_real_part > 0
        assert report.verdict == "unverified" and not report.spr and not report.certificate["verified"]
        assert "poles span 0.001 to 1e+06 rad/s" in report.reason
        assert report.to_dict()["spr"] is False


def test_in_band_minimum_ignores_the_high_frequency_asymptote():
    w = np.array([0.1, 1.0, 5.0, 20.0, 100.0])
    phase = np.array([-10.0, -60.0, -50.0, -89.0, -89.9])
    assert minimum_phase_in_band(w, phase, cutoff_frequency=1.0) == (-60.0, 1.0)
    assert minimum_phase_in_band(w, phase, cutoff_frequency=10.0) == (-89.9, 100.0)
    assert minimum_phase_in_band(w, phase, cutoff_frequency=1e-3) == (-89.9, 100.0)  # nothing in band: whole grid
