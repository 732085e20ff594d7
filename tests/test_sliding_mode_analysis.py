"""Analysis of Kim's (2002) sliding-mode observer: error system, KYP (14), switching gain (17)."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout.analysis import check_spr, error_loop
from lookout.analysis.sliding_mode import (
    check_kim_2002,
    disturbance_coverage,
    eigenvalue_report,
    error_system,
    kyp_14,
    peak_to_peak_gains,
    sigma2,
    switching_gain_required,
)
from lookout.environment import GaussMarkovBias, LinearWaveModel
from lookout.models.vessel import DPVessel, VesselPlant, VesselState, northern_clipper
from lookout.observers.sliding_mode import SlidingModeObserver
from lookout.papers import kim_2002

VESSEL = northern_clipper()
M = np.asarray(VESSEL.mass_matrix)
D = np.asarray(VESSEL.damping_matrix)
LAYER = (1.0, 1.0, 0.001)  # eps (m, m, rad): Kbar/eps = 10 1/s in every axis


def printed(**overrides):
    return kim_2002.printed_observer(VESSEL, boundary_layer=LAYER, **overrides)


def swapped():
    """H3 = 1e5 diag(0.1, 0.1, 100), H4 = 1e6 diag(0.1, 0.1, 100): ratio 0.1 1/s."""
    return printed(bias_injection_gain=(1e4, 1e4, 1e7), velocity_injection_gain=(1e5, 1e5, 1e8))


# -- the error system is the linearization of the implementation --------------------


def _flat(state: VesselState):
    return jnp.concatenate([state.wave_state, state.eta, state.bias, state.nu])


def _state(x):
    return VesselState(eta=x[6:9], nu=x[12:15], bias=x[9:12], wave_state=x[:6])


def _error_rate(observer, truth: VesselState, *, hold_heading: bool):
    """x~ -> d x~/dt = plant rate (noise-free) - observer rate at x_hat = x - x~."""
    passive = observer.passive
    plant = VesselPlant(
        VESSEL,
        GaussMarkovBias(passive.bias_time_constant, 0.0),
        LinearWaveModel(passive.wave_frequency, passive.wave_damping, 0.0),
    )
    tau = jnp.array([1e5, -2e5, 3e7])
    y = truth.eta + truth.wave
    plant_rate = _flat(plant.vector_field(0.0, truth, tau, jnp.zeros(6)))
    # J held at R(psi): passed explicitly, or J(y) = R(psi) because psi_w = 0
    heading = truth.eta[2] if hold_heading else None

    def rate(x_tilde):
        estimate = _state(_flat(truth) - x_tilde)
        return plant_rate - _flat(observer.vector_field(0.0, estimate, y, tau, heading=heading))

    return jax.jit(rate)


TRUTHS = {
    "heading 0, psi_w = 0": (
        VesselState.build(eta=[10.0, -5.0, 0.0], nu=[0.3, -0.1, 0.002], bias=[1e5, 2e4, 1e6], wave_state=[0.1, -0.2, 0.01, 0.5, 0.3, 0.0]),
        False,
    ),
    "heading 2.3, J held": (
        VesselState.build(eta=[-40.0, 25.0, 2.3], nu=[-0.2, 0.4, -0.003], bias=[-3e4, 5e4, -2e6], wave_state=[0.2, 0.1, -0.004, -0.6, 0.2, 0.01]),
        True,
    ),
}


@pytest.mark.parametrize("case", list(TRUTHS))
def test_error_system_is_the_jacobian_of_the_implementation(case):
    truth, hold = TRUTHS[case]
    heading = float(truth.eta[2])
    observer = printed()
    rate = _error_rate(observer, truth, hold_heading=hold)
    zero = jnp.zeros(15)
    np.testing.assert_allclose(np.asarray(rate(zero)), 0.0, atol=1e-12)
    # at x~ = 0 the switching term is inside its layer: H2 -> H2 + Kbar/eps
    inside = error_system(observer, VESSEL, heading=heading, inside_layer=True)
    jacobian = np.asarray(jax.jit(jax.jacobian(rate))(zero))
    np.testing.assert_allclose(jacobian, inside, rtol=1e-12, atol=1e-12 * np.abs(inside).max())
    # far outside the layer (|y~| >> eps) sat is constant: the Kbar = 0 system
    outside_point = jnp.zeros(15).at[6:9].set(jnp.array([50.0, -50.0, 0.5]))
    without = error_system(observer, VESSEL, heading=heading)
    jacobian = np.asarray(jax.jit(jax.jacobian(rate))(outside_point))
    np.testing.assert_allclose(jacobian, without, rtol=1e-12, atol=1e-12 * np.abs(without).max())
    # with Kbar = 0 the error dynamics are exactly linear: rate(x~) = A x~
    passive_only = printed(switching_gain=(0.0, 0.0, 0.0))
    rate = _error_rate(passive_only, truth, hold_heading=hold)
    x_tilde = np.array([0.3, -0.2, 0.01, 0.4, 0.5, -0.02, 2.0, -1.0, 0.05, 3e4, -2e4, 4e5, 0.1, -0.05, 0.001])
    np.testing.assert_allclose(np.asarray(rate(jnp.asarray(x_tilde))), without @ x_tilde, rtol=1e-9, atol=1e-12 * np.abs(without @ x_tilde).max())


def test_sigma2_per_dof_is_the_passive_error_loop_and_error_system_has_its_blocks():
    for observer in (printed(), swapped()):
        A, B, C = sigma2(observer)
        for i in range(3):
            index = [i, 3 + i, 6 + i, 9 + i]
            a, b, c = error_loop(observer.passive, i)
            np.testing.assert_array_equal(A[np.ix_(index, index)], a)
            np.testing.assert_array_equal(B[index, i], b[:, 0])
            np.testing.assert_array_equal(C[i, index], c[0])
        full = error_system(observer, VESSEL, heading=0.4)
        np.testing.assert_array_equal(full[:12, :12], A)
        np.testing.assert_allclose(full[12:, 12:], -np.linalg.solve(M, D), rtol=1e-12)


def test_error_system_rejects_a_vessel_that_is_not_the_observers_model():
    other = DPVessel(M, 1.5 * D)
    with pytest.raises(ValueError, match="model"):
        error_system(printed(), other)
    moored = DPVessel(M, D, np.diag([1e4, 1e4, 1e7]))
    with pytest.raises(ValueError, match="stiffness"):
        error_system(printed(), moored)


# -- the printed gains -----------------------------------------------------------------


def test_printed_gains_break_rule_48_and_kyp_14_with_phase_near_minus_172_6_deg():
    report = check_kim_2002(printed(), VESSEL)
    assert report.verdicts["tuning_rule_48"] == "fails"
    failing = {(item.name, item.relation) for item in report["tuning_rule_48"].inequalities if item.verdict == "fails"}
    assert failing == {(dof, "lambda/kappa < w_o") for dof in ("surge", "sway", "yaw")}
    kyp = report["kyp_14"]
    assert kyp.verdict == "fails" and kyp.reason.startswith("not SPR, so no P, Q exist")
    assert kyp.quantities["P"] is None
    for values in kyp.quantities["per_dof"].values():
        assert values["verdict"] == "fails"
        assert -173.0 < values["min_phase_deg_in_band"] < -172.5
        assert values["min_phase_frequency_in_band"] == pytest.approx(0.696, abs=0.01)
    assert [item.left for item in kyp.informational] == [kyp.quantities["per_dof"][dof]["min_phase_deg_in_band"] for dof in ("surge", "sway", "yaw")]


def test_printed_gains_without_switching_are_unstable_in_surge_only():
    """Found: one unstable pair, +0.0156 +- 0.1235j (e-folding 64 s, period 51 s),
    carried by surge. The sway-yaw pair is stable (about -0.0013 +- 0.1035j)."""
    for heading in (0.0, 1.1):
        report = eigenvalue_report(error_system(printed(), VESSEL, heading=heading), heading=heading)
        assert report.verdict == "fails" and report.stability.left > report.stability.tolerance > 0
        assert [m.axis for m in report.unstable] == ["surge"]
        mode = report.unstable[0]
        assert mode.real == pytest.approx(0.015615, rel=1e-4)
        assert mode.frequency == pytest.approx(0.12351, rel=1e-4)
        assert mode.e_folding_time == pytest.approx(64.04, rel=1e-3)
        assert mode.period == pytest.approx(50.87, rel=1e-3)
        second = sorted(report.eigenvalues.real)[-3]  # after the unstable pair
        assert second == pytest.approx(-0.0012707, rel=1e-3)


def test_printed_gains_are_stable_inside_a_narrow_enough_layer():
    inside = eigenvalue_report(error_system(printed(), VESSEL, inside_layer=True))  # Kbar/eps = 10 1/s
    assert inside.verdict == "holds"
    wide = kim_2002.printed_observer(VESSEL, boundary_layer=(20.0, 20.0, 0.02))  # Kbar/eps = 0.5 1/s
    assert eigenvalue_report(error_system(wide, VESSEL, inside_layer=True)).verdict == "fails"


def test_swapped_multipliers_are_stable_but_not_spr():
    observer = swapped()
    report = eigenvalue_report(error_system(observer, VESSEL))
    assert report.verdict == "holds"
    assert report.stability.left == pytest.approx(-0.0116, abs=5e-5)
    kyp = kyp_14(observer)
    assert kyp.verdict == "fails"
    for values in kyp.quantities["per_dof"].values():
        assert values["min_phase_deg_in_band"] == pytest.approx(-94.85, abs=0.05)


def test_fossen_strand_paper_gains_pass_kyp_14_with_verified_p_and_q(paper_observer):
    observer = SlidingModeObserver(paper_observer, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    kyp = kyp_14(observer)
    assert kyp.verdict == "holds"
    assert [item.name for item in kyp.inequalities[-4:]] == ["Sigma_2"] * 4  # (14) on the assembled P, Q
    A, B, C = sigma2(observer)
    P, Q = kyp.quantities["P"], kyp.quantities["Q"]
    np.testing.assert_allclose(P, P.T, rtol=0, atol=0)
    np.testing.assert_allclose(P @ A + A.T @ P, -Q, atol=1e-9 * np.abs(Q).max())
    np.testing.assert_allclose(B.T @ P, C, rtol=1e-9, atol=1e-9 * np.abs(C).max())
    for matrix in (P, Q):
        scale = 1.0 / np.sqrt(np.diag(matrix))
        assert np.linalg.eigvalsh(scale[:, None] * matrix * scale[None, :]).min() > 0
    report = check_kim_2002(observer, VESSEL)
    assert report.verdicts["tuning_rule_48"] == "holds"
    assert report.verdicts["error_system_stable_without_switching"] == "holds"
    data = json.loads(json.dumps(report.to_dict(), allow_nan=False))
    assert data["verdicts"]["kyp_14"] == "holds"
    np.testing.assert_allclose(np.array(data["kyp_14"]["quantities"]["P"]), P, rtol=1e-15)
    assert [r.verdict for r in check_spr(paper_observer)] == ["holds"] * 3


# -- (17): switching gain --------------------------------------------------------------


def test_surge_peak_to_peak_gain_is_one_over_d11():
    gains = peak_to_peak_gains(M, D)
    assert gains[0, 0] == pytest.approx(1.0 / D[0, 0], rel=1e-10)
    assert np.all(gains[0, 1:] == 0) and np.all(gains[1:, 0] == 0)


def test_sway_yaw_peak_to_peak_gains_by_quadrature_and_by_time_step_sum_agree():
    quad = peak_to_peak_gains(M, D)
    summed = peak_to_peak_gains(M, D, method="sum")
    np.testing.assert_allclose(summed[1:, 1:], quad[1:, 1:], rtol=1e-5)
    # an L1 norm is at least the DC gain; the Northern Clipper's responses keep one
    # sign, so here it equals |D^-1|
    dc = np.abs(np.linalg.inv(D))
    assert np.all(quad >= dc * (1 - 1e-9))
    np.testing.assert_allclose(quad, dc, rtol=1e-8, atol=1e-20)


def test_peak_to_peak_gain_of_an_oscillating_response_exceeds_its_dc_gain():
    """A lightly damped coupled block changes sign: the quadrature splits at the zeros."""
    mass = np.diag([1.0, 1.0, 1.0])
    damping = np.array([[1.0, 0.0, 0.0], [0.0, 0.2, 1.0], [0.0, -1.0, 0.2]])
    quad = peak_to_peak_gains(mass, damping)
    summed = peak_to_peak_gains(mass, damping, method="sum")
    np.testing.assert_allclose(quad, summed, rtol=1e-5, atol=1e-12)
    assert quad[1, 1] > 1.5 * abs(np.linalg.inv(damping)[1, 1])


def test_switching_gain_required_scales_linearly_with_the_bound():
    bound = np.array([1e5, 5e4, 2e6])
    one = switching_gain_required(VESSEL, bound).quantities
    three = switching_gain_required(VESSEL, 3.0 * bound).quantities
    np.testing.assert_allclose(three["required_gain"], 3.0 * one["required_gain"], rtol=1e-12)
    np.testing.assert_allclose(three["velocity_bound"], 3.0 * one["velocity_bound"], rtol=1e-12)
    assert one["required_gain"][0] == one["required_gain"][1] == pytest.approx(np.hypot(*one["velocity_bound"][:2]))
    # without an observer there is no Kbar to compare: nothing decides the condition
    assert switching_gain_required(VESSEL, bound).verdict == "unverified"


def test_printed_kbar_covers_about_5e5_n_in_surge_and_2e5_n_in_sway():
    observer = printed()
    coverage, limited = disturbance_coverage(VESSEL, observer.switching_gain)
    assert coverage[0] == pytest.approx(10.0 * D[0, 0], rel=1e-9)  # 5.0242e5 N
    assert limited == ["surge", "yaw", "yaw"]
    gains = peak_to_peak_gains(M, D)
    assert coverage[1] == pytest.approx(0.01 / gains[2, 1], rel=1e-12)  # about 2.16e5 N
    assert coverage[2] == pytest.approx(0.01 / gains[2, 2], rel=1e-12)  # about 3.48e6 N m
    for k in range(3):
        at_limit = switching_gain_required(VESSEL, coverage[k] * np.eye(3)[k], observer=observer)
        assert min(item.factor for item in at_limit.inequalities) == pytest.approx(1.0, rel=1e-9)
        assert at_limit.verdict != "fails"  # equal within rounding: holds or unverified
        within = switching_gain_required(VESSEL, 0.99 * coverage[k] * np.eye(3)[k], observer=observer)
        assert within.verdict == "holds"
        beyond = switching_gain_required(VESSEL, 1.01 * coverage[k] * np.eye(3)[k], observer=observer)
        assert beyond.verdict == "fails"


# -- the report ----------------------------------------------------------------------


def test_report_verdicts_json_and_text():
    report = check_kim_2002(printed(), VESSEL, disturbance_bound=[1e5, 1e5, 1e6])
    assert report.verdicts == {
        "tuning_rule_48": "fails",
        "kyp_14": "fails",
        "error_system_stable_without_switching": "fails",
        "error_system_stable_inside_layer": "holds",
        "switching_gain_17": "holds",
    }
    data = report.to_dict()
    text = json.dumps(data, allow_nan=False)
    assert json.loads(text)["verdicts"] == report.verdicts
    assert data["quantities"]["kbar_coverage"]["force_bound"][0] == pytest.approx(5.0242e5)
    assert data["switching_gain_17"]["quantities"]["required_gain"][0] == pytest.approx(2.05, rel=1e-2)
    assert [item["verdict"] for item in data["switching_gain_17"]["inequalities"]] == ["holds"] * 3
    assert data["kyp_14"]["quantities"]["P"] is None  # not SPR: no certificate exists
    lines = report.text().splitlines()
    assert "note: Kbar covers |f_surge| <= 5.024e+05 N alone (limited by the surge gain)" in lines
    assert "  surge +0.0156 +- 0.1235j 1/s: grows x e in 64 s, period 50.9 s" in lines
    assert "note: (17) presupposes (14): without P, Q it proves nothing" in lines


def test_switching_gain_is_not_checked_without_a_bound_and_fails_for_a_large_one():
    report = check_kim_2002(printed(), VESSEL)
    assert "switching_gain_17" not in report.verdicts
    assert "(17) not checked: no bound on the unmodelled force given" in report.notes
    assert report.quantities["kbar_coverage"]["force_bound"][0] == pytest.approx(10.0 * D[0, 0])
    json.dumps(report.to_dict(), allow_nan=False)
    large = switching_gain_required(VESSEL, [1e6, 0.0, 0.0], observer=printed())
    assert [item.verdict for item in large.inequalities] == ["fails", "fails", "holds"]  # yaw: rho_3 = 0 <= Kbar_3
    assert large.verdict == "fails"
