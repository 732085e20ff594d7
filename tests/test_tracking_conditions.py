"""Gain conditions of Wondergem et al. (2009): (25) and Proposition 3.1 on the printed design."""

import numpy as np
import pytest

from lookout.analysis.tracking import check_wondergem_2009, christoffel_bound, controller_p_matrix
from lookout.models.cybership import CYBERSHIP_M, cybership2
from lookout.papers.wondergem_2009.config import NATURAL_FREQUENCY, OBSERVER_POSITION_GAIN, OBSERVER_VELOCITY_GAIN

A, B = 3.5, 1.823  # the reproduction's ellipse: curvature a / b^2 at the start and at its largest
#: the printed gains of the observer (6) and the controller (20), the reproduction's
GAINS = dict(observer_gains=(OBSERVER_POSITION_GAIN, OBSERVER_VELOCITY_GAIN), natural_frequency=NATURAL_FREQUENCY)
PRINTED = dict(
    eta0=(3.8, -1.2, np.pi / 2),
    nu0=(0.0, 0.0, 0.0),
    eta_hat0=(4.0, -1.0, 2.94),
    velocity_hat0=(0.5, 0.5, -0.5),
    reference_position0=(A, 0.0, np.pi / 2),
    reference_velocity0=(0.05, 0.0, 0.05 * A / B**2),
    yaw_rate_max=0.2 * A / B**2,
)


def test_p_solves_the_lyapunov_equation_with_the_plus_sign():
    for w, lam in ((0.72, 1.0), (0.42, 1.0), (0.64, 0.7)):
        A_c = np.array([[0.0, 1.0], [-w * w, -2.0 * lam * w]])
        P = controller_p_matrix(w, lam)[np.ix_([0, 3], [0, 3])]
        np.testing.assert_allclose(A_c.T @ P + P @ A_c, -2.0 * w * w * np.eye(2), atol=1e-14)
        assert np.linalg.eigvalsh(P).min() > 0


def test_christoffel_bound_against_a_random_search():
    bound = christoffel_bound(CYBERSHIP_M)
    assert bound == pytest.approx(4.857, abs=1e-3)  # derivations-wondergem-2009.md, section 1
    ship = cybership2()
    rng = np.random.default_rng(0)
    x = rng.normal(size=(2000, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    norms = [np.linalg.norm(np.asarray(ship.christoffel_coriolis(rng.uniform(-3, 3), v)), 2) for v in x[:200]]
    assert max(norms) <= bound * (1 + 1e-9) and max(norms) > 0.9 * bound


def test_the_printed_design_meets_10_and_11_and_fails_13_14_and_25():
    report = check_wondergem_2009(cybership2(), **PRINTED, **GAINS)
    verdicts = {item.name: item.verdict for item in report.inequalities}
    assert verdicts == {"(25)": "fails", "(10a)": "holds", "(10b)": "holds", "(11)": "holds", "(13)": "fails", "(14)": "fails"}
    sides = {item.name: (item.left, item.right) for item in report.inequalities}
    q = report.quantities
    # derived by hand (derivations section 4): M_M = 0.3667, d_M1 = 0.891 + 73.26 V_M, k_n = 36.63
    assert q["M_M"] == pytest.approx(1 / 2.727, rel=1e-3) and q["k_n"] == pytest.approx(36.63, abs=0.01)
    assert q["d_M1"] == pytest.approx(0.891 + 2 * 36.628 * 0.3, abs=2e-3)
    assert q["lambda_P"] == pytest.approx([0.2316, 2.624], abs=1e-3) and q["x_e0_norm"] == pytest.approx(1.239, abs=1e-3)
    assert sides["(25)"][1] - sides["(25)"][0] == pytest.approx(4.03, abs=0.01)  # alpha_bar = -4.03
    assert sides["(11)"][1] == pytest.approx(2.36, abs=0.01)
    assert sides["(13)"][1] == pytest.approx(4150, rel=1e-3)
    assert not report.holds and "(13)" in report.text()
    assert report.verdicts == {"controller_25": "fails", "observer_3_1": "fails"}  # no reference bounds: no Prop. 3.3
    assert {item.source for item in report["observer_3_1"].inequalities} == {f"Wondergem et al. (2009), eq. ({n})" for n in (10, 11, 13, 14)}


def test_with_a_perfect_initial_estimate_13_needs_alpha11_plus_sqrt_gamma1():
    """eta_hat0 = eta0 removes gamma2 and (14); (13) becomes lmin(L1) > alpha11 + sqrt(gamma1)."""
    report = check_wondergem_2009(cybership2(), **GAINS, **{**PRINTED, "eta_hat0": PRINTED["eta0"], "velocity_hat0": (0.0, 0.0, 0.0)})
    names = [item.name for item in report.inequalities]
    assert "(14)" not in names
    q = report.quantities
    (bound,) = [item.right for item in report.inequalities if item.name == "(13)"]
    assert bound == pytest.approx(q["alpha11"] + np.sqrt(q["gamma1"]), rel=1e-12)
    assert q["gamma1"] == 0.0 and bound == pytest.approx(q["alpha11"])  # nu0 = 0 and v_hat0 = 0 too: 14.68


def test_bad_input_fails_with_one_line():
    with pytest.raises(ValueError, match=r"^observer_gains must be finite and positive"):
        check_wondergem_2009(cybership2(), **PRINTED, **{**GAINS, "observer_gains": (0.0, 50.0)})
    with pytest.raises(ValueError, match=r"^velocity_bound must be finite and >= 0"):
        check_wondergem_2009(cybership2(), **PRINTED, **GAINS, velocity_bound=-1.0)


# Proposition 3.3: the combined scheme --------------------------------------------------

BOUNDS = dict(reference_speed_max=0.2 * np.hypot(1.0, A / B**2), reference_acceleration_max=0.03)
MEASURED = {**PRINTED, "eta_hat0": PRINTED["eta0"], "velocity_hat0": (0.0, 0.0, 0.0)}


def _side(report, name):
    (item,) = [item for item in report.inequalities if item.name == name]
    return item


def test_27_is_zero_at_the_largest_eps3_and_the_eps3_bounds_fall_with_eps3():
    gains = dict(observer_gains=(3e5, 7e6), natural_frequency=1.6)
    best = check_wondergem_2009(cybership2(), **MEASURED, **BOUNDS, **gains)
    eps_max = best.quantities["combined"]["epsilon3_max"]
    assert eps_max > 0 and _side(best, "(27)").verdict == "holds"
    at_max = check_wondergem_2009(cybership2(), **MEASURED, **BOUNDS, **gains, epsilon3=eps_max)
    item = _side(at_max, "(27)")
    assert item.left == pytest.approx(item.right, rel=1e-12)  # alpha_bar_1 = 0 at eps3_max
    smaller = check_wondergem_2009(cybership2(), **MEASURED, **BOUNDS, **gains, epsilon3=0.5 * eps_max)
    assert _side(smaller, "(27)").verdict == "holds"
    for name in ("(30)", "(32)"):  # (30) and (34) carry eps3^-2: a smaller eps3 asks for more
        assert _side(smaller, name).right > _side(at_max, name).right
    # V0 (28) with eta_hat0 = eta0, v_hat0 = 0, nu0 = 0: lmax(P) ||x_e0||^2 alone
    q = best.quantities
    assert q["combined"]["V0"] == pytest.approx(q["lambda_P"][1] * q["x_e0_norm"] ** 2, rel=1e-12)


def test_the_printed_gains_leave_no_eps3_for_27():
    report = check_wondergem_2009(cybership2(), **PRINTED, **GAINS, **BOUNDS)
    item = _side(report, "(27)")
    assert item.verdict == "fails" and item.right == pytest.approx(24.07, abs=0.01)  # derivations section 4: 23.9 + r_max
    assert report.quantities["combined"]["epsilon3_max"] == 0.0
    assert not {"(30)", "(32)", "(33)"} & {item.name for item in report.inequalities}
    assert report.verdicts["combined_3_3"] == "fails" and "note: (30), (32), (33) need an eps3 that satisfies (27); none exists" in report.lines()
    measured = check_wondergem_2009(cybership2(), **MEASURED, **BOUNDS, **GAINS)
    assert _side(measured, "(27)").right == pytest.approx(4.382, abs=1e-3)  # V0 = lmax(P) ||x_e0||^2: 4.17 + r_max


def test_the_search_proposes_gains_that_meet_every_condition_and_no_less():
    from lookout.analysis.tracking import propose_wondergem_2009

    proposal = propose_wondergem_2009(cybership2(), **{k: v for k, v in MEASURED.items()}, **BOUNDS)
    assert proposal.found and proposal.report.holds
    names = {item.name for item in proposal.report.inequalities}
    assert {"(25)", "(10a)", "(10b)", "(11)", "(13)", "(27)", "(30)", "(32)"} <= names
    L1, L2 = proposal.observer_gains
    # the margin is 1.1 on the binding bound: 20 % less L1 fails (32)
    tighter = check_wondergem_2009(
        cybership2(),
        **MEASURED,
        **BOUNDS,
        observer_gains=(0.8 * L1, L2),
        natural_frequency=proposal.natural_frequency,
        epsilon3=proposal.epsilon3,
    )
    assert _side(tighter, "(32)").verdict == "fails"
    assert proposal.euler_step_max == pytest.approx(2.0 / max(abs(p) for p in np.roots([1.0, L1, L2])), rel=1e-12)
    assert proposal.search()["found"] is True and not hasattr(proposal, "to_dict")
    outcome = proposal.outcome()
    assert outcome.holds and outcome.summary[0].startswith("proposed: Omega = ") and outcome.quantities["proposal"]["found"] is True


def test_the_search_finds_nothing_from_the_printed_initial_estimate():
    from lookout.analysis.tracking import propose_wondergem_2009

    proposal = propose_wondergem_2009(cybership2(), **PRINTED, **BOUNDS)
    assert not proposal.found and proposal.report is None and "keep growing" in proposal.reason
    outcome = proposal.outcome()  # nothing to check: not established
    assert outcome.conditions == () and outcome.verdict == "unverified" and "keep growing" in outcome.summary[0]


def test_prop_3_3_bad_input():
    with pytest.raises(ValueError, match=r"^reference_speed_max and reference_acceleration_max must be given together"):
        check_wondergem_2009(cybership2(), **PRINTED, **GAINS, reference_speed_max=0.3)
    with pytest.raises(ValueError, match=r"^epsilon3 must be finite and positive"):
        check_wondergem_2009(cybership2(), **PRINTED, **GAINS, **BOUNDS, epsilon3=0.0)
    from lookout.analysis.tracking import propose_wondergem_2009

    with pytest.raises(ValueError, match=r"^margin must be finite and > 1"):
        propose_wondergem_2009(cybership2(), **MEASURED, **BOUNDS, margin=1.0)
