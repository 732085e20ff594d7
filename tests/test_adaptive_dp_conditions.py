"""Conditions (22), (57), (58) of Calugi, Robertsson & Johansson (2003) on concrete numbers."""

import json

import numpy as np
import pytest

from lookout.analysis.adaptive_dp import (
    check_calugi_2003,
    closed_loop_conditions_57_58,
    loop_rates,
    model_bounds,
    observer_condition_22,
    satisfying_gains,
    z_weight_bound,
)
from lookout.models.vessel import NORTHERN_CLIPPER_D, DPVessel
from lookout.papers.calugi_2003 import CALUGI_2003_D, CALUGI_2003_M, PRINTED_GAINS
from lookout.papers.calugi_2003 import paper_vessel as calugi_2003_vessel

VESSEL = calugi_2003_vessel()
M, D = CALUGI_2003_M, CALUGI_2003_D
M11 = M[0, 0]
PRINTED = {"K1": PRINTED_GAINS["K1"], "K2": PRINTED_GAINS["K2"], "d": PRINTED_GAINS["d"]}
#: the gains satisfying_gains starts its search from: the printed ones
PRINTED_START = {name: PRINTED_GAINS[name] for name in ("K1", "K2", "d", "C1", "C2")}


def lmin(matrix):
    return np.linalg.eigvalsh(0.5 * (matrix + matrix.T))[0]


@pytest.fixture(scope="module")
def printed():
    return check_calugi_2003(VESSEL, **PRINTED)


@pytest.fixture(scope="module")
def proposal():
    return satisfying_gains(VESSEL, **PRINTED_START)


# -- the printed parameters (59) ------------------------------------------------------


def test_vessel_is_59_not_fossen_strand():
    assert np.allclose(np.asarray(VESSEL.mass_matrix), M)
    assert D[0, 0] == 5.024e4 and D[1, 2] == D[2, 1] == -4.399e6
    assert NORTHERN_CLIPPER_D[0, 0] == 5.0242e4 and NORTHERN_CLIPPER_D[1, 2] == -4.3933e6
    assert not np.any(np.asarray(VESSEL.stiffness_matrix))


def test_model_bounds_are_the_quantities_the_proof_uses():
    b = model_bounds(VESSEL)
    assert b.mass_min == pytest.approx(M11, rel=1e-12)
    assert b.mass_max == pytest.approx(3.7454e9, rel=1e-12)
    # D_min = lambda_min(sym D): the decoupled surge damping; not ||D|| = 4.19e8
    assert b.damping_min == pytest.approx(lmin(D), rel=1e-12)
    assert b.damping_min == pytest.approx(5.024e4, rel=1e-12)
    assert b.damping_max == pytest.approx(np.linalg.norm(D, 2), rel=1e-12)
    assert b.damping_max == pytest.approx(4.19e8, rel=1e-3)
    assert b.stiffness_max == 0.0
    assert [(item.name, item.verdict) for item in b.assumptions] == [("(9)", "holds"), ("(10)", "holds"), ("(11)", "holds")]
    assert b.assumptions[1].left == b.damping_min and b.assumptions[1].source == "Calugi et al. (2003), eq. (10)"


def test_printed_gains_numbers(printed):
    q = printed["closed_loop_57"].quantities
    K2 = 1e-3 * np.eye(3)
    assert q["sigma1"] == pytest.approx(np.linalg.eigvalsh(1e-3 * np.eye(3))[0], rel=1e-12)
    # (20): sigma2 = lambda_min(K2^T M^T + M K2) / 2
    assert q["sigma2"] == pytest.approx(0.5 * np.linalg.eigvalsh(K2.T @ M.T + M @ K2)[0], rel=1e-12)
    assert q["sigma2"] == pytest.approx(1e-3 * M11, rel=1e-12)  # 5312.2 kg/s
    assert q["damping_min"] == pytest.approx(5.024e4, rel=1e-12)
    assert q["stiffness_max"] == 0.0
    assert q["g1"] == pytest.approx(60.0, rel=1e-12)
    assert q["g2"] == pytest.approx(30.0, rel=1e-12)
    assert printed.verdicts == {"observer_22": "holds", "closed_loop_57": "fails", "closed_loop_58": "holds"}


def test_printed_gains_inequalities(printed):
    s2, dmin = 1e-3 * M11, 5.024e4
    a, b = printed["observer_22"].inequalities
    assert a.left == pytest.approx(1e-3) and a.right == pytest.approx(1.0 / (4.0 * (s2 + dmin)), rel=1e-12)
    assert a.right == pytest.approx(4.5003e-6, rel=1e-4)
    assert a.factor == pytest.approx(1e-3 * 4.0 * (s2 + dmin), rel=1e-12)  # 222.2
    assert (b.left, b.right, b.verdict) == (pytest.approx(s2), 0.0, "holds")
    (c57,) = printed["closed_loop_57"].inequalities
    right = 60.0 / 4.0 + 1.0 / (4.0 * (s2 + dmin - 30.0 / 4.0))
    assert c57.right == pytest.approx(right, rel=1e-12)  # 15 + 4.5e-6
    assert c57.verdict == "fails"
    assert c57.factor == pytest.approx(1e-3 / right, rel=1e-12)  # 6.667e-5: the right side is 1.5e4 x the left
    assert 1.0 / c57.factor == pytest.approx(1.5e4, rel=1e-5)
    (c58,) = printed["closed_loop_58"].inequalities
    assert (c58.left, c58.right, c58.verdict) == (pytest.approx(s2), 0.0, "holds")


def test_tighter_combined_bound_is_valid_and_equal_here(printed):
    # lambda_min(sym(M K2 + D)) >= sigma2 + D_min (Weyl); for (59) both are the surge value
    q = printed["observer_22"].quantities
    assert q["combined"] == pytest.approx(lmin(1e-3 * M + D), rel=1e-12)
    assert q["combined"] == pytest.approx(q["sigma2"] + q["damping_min"], rel=1e-12)
    (tighter,) = printed["observer_22"].informational
    assert tighter.name == "(22a*)" and tighter.verdict == "holds"
    rng = np.random.default_rng(3)
    for _ in range(20):
        A = rng.standard_normal((3, 3))
        Mr = A @ A.T + 3 * np.eye(3)
        # a damping matrix dissipates (DPVessel refuses one that does not): a positive
        # semi-definite symmetric part and any skew part
        B, W = rng.standard_normal((3, 3)), rng.standard_normal((3, 3))
        Dr = B @ B.T + (W - W.T)
        K2 = rng.standard_normal((3, 3)) + 3 * np.eye(3)
        vessel = DPVessel(Mr, Dr)
        c22 = observer_condition_22(vessel, K1=1.0, K2=K2)
        q = c22.quantities
        assert q["combined"] >= q["sigma2"] + q["damping_min"] - 1e-12


def test_verdicts_do_not_depend_on_the_d_min_reading(printed):
    for reading in (0.0, 1.0, 5312.2, 2.5e4, 5.024e4):
        report = check_calugi_2003(VESSEL, **PRINTED, d_min=reading)
        assert report.verdicts == printed.verdicts
    report = check_calugi_2003(VESSEL, **PRINTED, d_min=0.0)
    a, _ = report["observer_22"].inequalities
    assert a.right == pytest.approx(1.0 / (4.0 * 1e-3 * M11), rel=1e-12)  # 4.71e-5
    (c58,) = report["closed_loop_58"].inequalities
    assert c58.right == pytest.approx(7.5)
    with pytest.raises(ValueError, match=r"^d_min must be .* <= lambda_min\(sym D\)"):
        check_calugi_2003(VESSEL, **PRINTED, d_min=4.19e8)  # the induced-norm reading is not a lower bound


def test_northern_clipper_numbers_change_no_verdict(printed):
    clipper = DPVessel(M, NORTHERN_CLIPPER_D)
    assert check_calugi_2003(clipper, **PRINTED).verdicts == printed.verdicts


# -- the derivation itself -----------------------------------------------------------------


def _rotation(psi):
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("seed", range(5))
def test_appendix_b_completing_squares_gives_g1_g2(seed):
    """-z'D_z z + z'W1 eta~ + z'W2 nu~ - (g1|eta~|^2 + g2|nu~|^2)/4 = -(sum of squares) <= 0,
    built from (28), (38)-(40), (46) with random gains, state and weights."""
    rng = np.random.default_rng(seed)
    k1, k2 = rng.uniform(0.01, 2.0, 3), rng.uniform(0.01, 2.0, 3)
    K1, K2 = np.diag(k1), np.diag(k2)
    C1 = np.diag(rng.uniform(0.05, 1.0, 3))
    d = rng.uniform(0.05, 5.0, 6)
    p = rng.uniform(0.2, 3.0, 3)  # coupling weight P1 (1 as printed)
    psi, u, v = rng.uniform(-np.pi, np.pi), *rng.normal(size=2)
    D1 = np.diag(d[:3] * np.sum(K1**2, axis=1))
    Omega1 = (C1 + D1) @ K1
    T = np.array([[0.0, 0.0, -v], [0.0, 0.0, u], [0.0, 0.0, 0.0]])
    Omega2 = _rotation(psi) @ (T + K2)
    D2 = np.diag(d[3:] * (np.sum(Omega1**2, axis=1) + np.sum(Omega2**2, axis=1)))
    z1, z2, eta, nu = (rng.normal(size=3) for _ in range(4))
    P1 = np.diag(p)
    # V = 1/2 (z1'P1 z1 + |z2|^2): the z1 terms carry P1
    form = -z1 @ P1 @ D1 @ z1 - z2 @ D2 @ z2 + z1 @ P1 @ K1 @ eta + z2 @ Omega1 @ eta + z2 @ Omega2 @ nu
    _, c = closed_loop_conditions_57_58(VESSEL, K1=k1, K2=k2, d=d, coupling_gain=p)
    g1, g2 = c.quantities["g1"], c.quantities["g2"]
    assert g1 == pytest.approx(np.sum(p / d[:3]) + np.sum(1.0 / d[3:]))
    assert g2 == pytest.approx(np.sum(1.0 / d[3:]))
    Q = form - 0.25 * (g1 * eta @ eta + g2 * nu @ nu)
    squares = sum(
        p[i] * d[i] * np.sum((z1[i] * K1[i] - eta / (2 * d[i])) ** 2)
        + d[i + 3] * np.sum((z2[i] * Omega1[i] - eta / (2 * d[i + 3])) ** 2)
        + d[i + 3] * np.sum((z2[i] * Omega2[i] - nu / (2 * d[i + 3])) ** 2)
        for i in range(3)
    )
    assert Q == pytest.approx(-squares, rel=1e-9, abs=1e-12)
    assert Q <= 1e-12


def test_worst_case_over_theta_is_at_an_end_point():
    low, high = 0.5 * M11, 2.0 * M11
    report = check_calugi_2003(VESSEL, **PRINTED, theta_bounds=[low, high])
    assert report["observer_22"].quantities["sigma2"] == pytest.approx(1e-3 * low, rel=1e-12)
    bounds = report.quantities["model_bounds"]
    assert bounds["mass_min"] == pytest.approx(low, rel=1e-12)
    assert bounds["worst_theta"]["mass_min"] == [low]
    assert report.verdicts == {"observer_22": "holds", "closed_loop_57": "fails", "closed_loop_58": "holds"}
    # lambda_min(sym(M(theta) K2)) is concave in theta: also for a full K2 the box minimum
    # is at an end point; check on a dense grid
    rng = np.random.default_rng(7)
    for _ in range(5):
        K2 = 1e-3 * (np.eye(3) + 0.3 * rng.standard_normal((3, 3)))
        q = observer_condition_22(VESSEL, K1=1e-3, K2=K2, theta_bounds=[low, high]).quantities
        grid = []
        for theta in np.linspace(low, high, 401):
            Mt = M.copy()
            Mt[0, 0] = theta
            grid.append(lmin(Mt @ K2))
        assert q["sigma2"] == pytest.approx(min(grid[0], grid[-1]), rel=1e-12)
        assert min(grid) >= q["sigma2"] - 1e-9 * abs(q["sigma2"])


def test_z_weight_bound_is_where_the_reweighted_form_stops_being_definite(printed):
    q = printed["closed_loop_57"].quantities
    w = printed.quantities["z_weight_bound"]
    assert w == pytest.approx(6.64e-5, rel=1e-2)
    assert 0.0 < w < 1.0  # the paper's V (47) is w = 1: (57) fails

    def smallest(weight):
        a = q["sigma1"] - weight * q["g1"] / 4
        c = q["sigma2"] + q["damping_min"] - weight * q["g2"] / 4
        return np.linalg.eigvalsh(np.array([[a, -0.5], [-0.5, c]]))[0]

    assert smallest(0.999 * w) > 0 > smallest(1.001 * w)
    assert z_weight_bound(1e-3, 0.0, 0.0, 0.0, 60.0, 30.0) == 0.0  # (22) fails: no weight helps


# -- gains that satisfy (57)-(58) -----------------------------------------------------------


def test_satisfying_gains_all_hold(proposal):
    assert proposal.report.verdicts == {"observer_22": "holds", "closed_loop_57": "holds", "closed_loop_58": "holds"}
    again = check_calugi_2003(VESSEL, K1=proposal.K1, K2=proposal.K2, d=proposal.d)
    assert again.holds
    assert again["closed_loop_57"].inequalities[0].factor >= 1.1
    assert np.all(proposal.d >= 0.1) and np.all(np.diag(proposal.K1) >= 1e-3)
    chosen = {r.name: r for r in proposal.routes}[proposal.route]
    assert chosen.usable and chosen.step_gain <= 0.5
    assert "\n" not in proposal.reason


def test_satisfying_gains_default_choice_and_costs(proposal):
    routes = {r.name: r for r in proposal.routes}
    # K1 kept needs d4..6 > 3 / (4 sigma1) = 750 s, and D2 >= 750 v^2
    assert routes["d_split"].d[3] > 750.0
    assert routes["d_split"].D2.max() > 750.0 * 0.5**2
    assert routes["d_uniform"].d[0] > 1.5e3
    assert routes["K1_only"].K1[0, 0] > 15.0
    # at 0.5 m/s only a K1 increase is usable
    assert proposal.route == "K1_and_d"
    assert np.allclose(proposal.K1, 0.05 * np.eye(3))
    assert np.allclose(proposal.d, [320.0] * 3 + [18.0] * 3)
    assert satisfying_gains(VESSEL, **PRINTED_START).to_dict() == proposal.to_dict()  # deterministic


def test_satisfying_gains_keeps_K1_at_low_speed():
    slow = satisfying_gains(VESSEL, speed=0.05, **PRINTED_START)
    assert slow.route == "d_split"
    assert np.allclose(slow.K1, 1e-3 * np.eye(3))
    assert slow.report.holds
    rates = loop_rates(slow.K1, slow.K2, slow.d, speed=0.05)
    assert 0.1 * rates["loop"].max() <= 0.5


# -- output forms and inputs ---------------------------------------------------------------


def test_to_dict_is_strict_json_and_text(printed, proposal):
    for obj in (printed, proposal):
        json.dumps(obj.to_dict(), allow_nan=False)
    assert all(len(line) <= 80 for line in proposal.text().splitlines())
    data = printed.to_dict()
    assert data["closed_loop_58"]["inequalities"][0]["factor"] is None  # inf -> None
    assert data["verdicts"]["closed_loop_57"] == "fails"
    assert data["quantities"]["z_weight_bound"] == pytest.approx(6.64e-5, rel=1e-2)
    text = printed.text()
    assert "(57) closed loop [Calugi et al. (2003), eq. (57)]: fails" in text
    assert "note: with z'z weighted by w_z in V (47): proven for w_z < 6.64e-05" in text
    json.dumps(model_bounds(VESSEL, [0.9 * M11, 1.1 * M11]).to_dict(), allow_nan=False)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"d": [0.1] * 5 + [0.0]}, r"^d must be 6 positive"),
        ({"d": [0.1] * 5}, r"^d must be 6 positive"),
        ({"K1": [1e-3, -1e-3, 1e-3]}, r"^K1 must be positive definite"),
        ({"K1": [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]}, r"^K1 must be positive definite"),
        ({"K2": np.ones((2, 2))}, r"^K2 must be"),
        ({"theta_bounds": [0.5 * M11, 0.9 * M11]}, r"^theta_bounds must contain"),
        ({"theta_bounds": [2 * M11, M11]}, r"^theta_bounds must be"),
        ({"coupling_gain": 0.0}, r"^coupling_gain must be"),
    ],
)
def test_bad_inputs_fail_with_one_line(kwargs, pattern):
    args = dict(PRINTED) | kwargs
    with pytest.raises(ValueError, match=pattern) as info:
        check_calugi_2003(VESSEL, **args)
    assert "\n" not in str(info.value)


def test_bad_design_inputs():
    for kwargs, pattern in (({"speed": -1.0}, "^speed"), ({"margin": 0.5}, "^margin"), ({"step": 0.0}, "^step")):
        with pytest.raises(ValueError, match=pattern):
            satisfying_gains(VESSEL, **{**PRINTED_START, **kwargs})


def test_stiffness_enters_through_its_norm():
    K = np.diag([1e4, 2e4, 3e6])
    vessel = DPVessel(M, D, K)
    assert model_bounds(vessel).stiffness_max == pytest.approx(3e6)
    a, _ = observer_condition_22(vessel, K1=1e-3, K2=1e-3).inequalities
    assert a.right == pytest.approx((1 + 3e6) ** 2 / (4 * (1e-3 * M11 + 5.024e4)))
    assert a.verdict == "fails"


def test_noise_drift_rate_of_the_printed_gains_and_its_scaling():
    from lookout.analysis.adaptive_dp import noise_drift_rate

    printed = dict(K1=PRINTED_GAINS["K1"], K2=PRINTED_GAINS["K2"], d=PRINTED_GAINS["d"])
    # g = C1 + D1 + C2 + D2 = 0.1 + 1e-7 + 0.1 + 0.1 (1e-8 + 1e-6) at rest: -1e8 g 1e-3 (1 + 1e-4) / 0.1
    g = 0.2 + 1e-7 + 0.1 * (1e-8 + 1e-6)
    assert noise_drift_rate(**printed, gamma=1e8, noise_std=1.0, interval=0.1) == pytest.approx(-1e6 * g * (1 + 1e-4), rel=1e-12)
    base = noise_drift_rate(**printed, gamma=1e3, noise_std=1.0, interval=0.1)
    assert noise_drift_rate(**printed, gamma=2e3, noise_std=3.0, interval=0.1) == pytest.approx(18 * base, rel=1e-12)
    assert noise_drift_rate(**printed, gamma=1e3, noise_std=0.0, interval=0.1) == 0.0
    with pytest.raises(ValueError, match=r"^interval must be finite and > 0 \(s\); got 0"):
        noise_drift_rate(**printed, gamma=1e3, noise_std=1.0, interval=0)
    with pytest.raises(ValueError, match=r"^noise_std must be finite and >= 0; got -1"):
        noise_drift_rate(**printed, gamma=1e3, noise_std=-1.0, interval=0.1)
