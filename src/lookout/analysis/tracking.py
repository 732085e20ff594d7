"""The gain conditions of Wondergem et al. (2009) on concrete numbers: the controller's
(21)/(25) and the observer's Proposition 3.1, with every inequality's two sides.

Read as derived in ``derivations-wondergem-2009.md`` (sections 2 and 4; verified here
where stated):

Model constants (Assumption 1 and (4)), for a velocity bound ||eta'|| <= V_M:

* M_M = ||M^-1|| = 1 / lambda_min(M) (0.3667 for (39));
* C_M for the Christoffel factorization of M*(psi) (property (3), which the observer's
  proof uses; the printed C* violates it): the largest ||C_Gamma(psi, x)|| over unit x,
  rotation invariant, computed here over a fine grid of the unit sphere (4.857 for (39));
  the body-frame C(nu) has its own constant max(m11, sqrt(m22^2 + m23^2)) = 33.815;
* d_M1(V_M) = ||D|| + 2 k_n V_M and d_M2 = k_n, with k_n the norm of the quadratic
  damping coefficients of sway and yaw, sqrt(Y^2 + N^2) (36.63; X_|u|u = 1.33 is
  smaller), rotation invariant.

Controller (Prop. 3.2/3.3, (21)/(25)): per DOF
P_i = [[((2 l w)^2 + w^2 + w^4) / (2 l w), 1], [1, (1 + w^2) / (2 l w)]] (the printed
minus sign in the (2,2) block makes P indefinite; the plus sign solves
A_c^T P + P A_c = -Q, checked in the tests) and Q = diag(2 Omega^2, 2 Omega^2)::

    alpha_bar = lambda_min(Q) - r_ref_max - sqrt(lambda_max(P) / lambda_min(P)) ||x_e0|| > 0

with x_e0 = [eta_0 - eta_ref0; nu_0 - J^T(e_psi0) nu_ref0]. The proof's (81) drops a
term 2 r (p11,x - p11,y) z_x z_y when Omega_x != Omega_y; ``corrected=True`` multiplies
r_ref_max by kappa_r = (|dp| + sqrt(dp^2 + 4)) / 2, dp = p11,x - p11,y (1.546 for the
printed Omega).

Observer (Prop. 3.1), with alpha11 = 1/2 + 3 M_M C_M V_M + (3/2) M_M d_M1,
gamma = 3 M_M (C_M + d_M2), gamma1 = gamma^2 (lambda_max(L2) ||eta~0||^2 + ||eta~'0||^2),
gamma2 = gamma^2 ||eta~0||^2::

    (10) lambda_min(L1) > 1 and lambda_min(L2) >= 1
    (11) lambda_min(L2) > M_M C_M V_M / 2 + M_M d_M1 / 4
    (13) lambda_min(L1) > [(2 alpha11 + gamma2) + sqrt((2 alpha11 + gamma2)^2 - 4 (alpha11^2 - gamma1))] / 2
    (14) lambda_max(L1) <= [(lambda_min(L1) - alpha11)^2 - gamma1] / gamma2   (when gamma2 > 0)

Combined scheme, Prop. 3.3 ((27)–(37), from (93)–(95)), given sup ||nu_ref|| = N_r,
sup ||nu_ref'|| = A_r (the smooth part: the lap steps of the ellipse are outside the
proposition's bounded-derivative assumption) and eps3 of the completion of squares::

    V0 (28) = lmax(P) ||x_e0||^2 + (lmax(L1) + lmax(L2)) ||eta~0||^2 + ||eta~'0||^2,  s = sqrt(V0 / lmin(P))
    (27) alpha_bar_1 = lmin(Q) - r_max - eps3^2 lmax(P) B - (1 + eps3^2 lmax(P) C) s > 0
         B = M_M ||Kp|| + M_M ||Kd|| + 2 M_M ||D + Kd|| N_r + N_r + 2 C_M N_r + d_M3
         C = 2 C_M + 2 M_M ||Kp|| + 2 N_r + 2 A_r
    (29) = (10);  (31) lmax(L2) >= lmin(L2) (always true)
    (30) lmin(L2) > M_M C_M N_r / 2 + M_M d_M1 / 4 + 2 eps3^-2 lmax(P) M_M (||Kp|| + ||Kd|| + 2 ||D + Kd|| N_r)
                    + (M_M C_M / 2 + 2 eps3^-2 lmax(P) (2 M_M ||Kp|| + 2 N_r + 2 A_r)) s
    (32), (33) = (13), (14) with
         alpha11 (34) = 1/2 + 3 M_M C_M N_r + 3/2 M_M d_M1 + eps3^-2 lmax(P) (N_r + 2 C_M N_r + d_M3)
         gamma (35) = (2 C_M + 2 lmax(P) C_M + 2 lmax(P) d_M4) / sqrt(lmin(P)) + 3 M_M (C_M + d_M2)
         gamma1 (36) = gamma^2 (lmax(P) ||x_e0||^2 + lmax(L2) ||eta~0||^2 + ||eta~'0||^2),  gamma2 (37) = gamma^2 ||eta~0||^2

Read here (the paper defines neither d_M3, d_M4 nor Assumption 2): d_M1 = ||D|| + 2 k_n N_r
(Assumption 1 at the reference's speed), d_M3 = 2 k_n N_r, d_M4 = d_M2 = k_n; "lmax(K)" of
the non-symmetric Kp = M Omega^2, Kd is read as the spectral norm ||K||_2. (35) is grouped
as (94) prints it; (92) carries an extra M_M. (30) and (34) fall with eps3 and (27) rises,
so (27) is reported as the existence of an eps3 (its eps3 -> 0 limit, (97)) and (30),
(32), (33) at the largest admissible eps3, eps3_max^2 = (lmin(Q) - r_max - s) /
(lmax(P) (B + C s)), unless eps3 is given: when they fail there they fail for every eps3.

As printed the procedure is circular: V0 depends on L1 and L2, chosen after eps3.
:func:`propose_wondergem_2009` resolves it by a fixed-point iteration on (V0, L1, L2).
:func:`wondergem_2009_gains` is that search as the design rule ``wondergem-2009`` of the
observer (6) and the tracking controller (23) (one proposal for both, or a one-line
refusal naming the argument that leaves the procedure without gains).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from lookout import _validation as check
from lookout._json import json_safe
from lookout._math import rotate, rotate_transpose, ssa
from lookout.analysis.conditions import Condition, Inequality, Report
from lookout.models.cybership import Cybership
from lookout.observers.earth_fixed import EarthFixedObserver

PAPER = "Wondergem et al. (2009)"


def _check(name: str, relation: str, left: float, right: float, units: str, comparison: str = ">") -> Inequality:
    """An inequality of the paper, its source the equation that ``name`` numbers ((10a) is of (10))."""
    equation = name[:-2] + ")" if name[-2] in "ab" else name
    return Inequality.check(name, relation, left, comparison, right, units=units, source=f"{PAPER}, eq. {equation}")


def _unit_sphere(count: int = 181) -> np.ndarray:
    theta = np.linspace(0.0, np.pi, count)
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * count)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)


def christoffel_bound(mass_matrix: npt.ArrayLike) -> float:
    """C_M of (4) for the Christoffel factorization of M*(psi): max ||C_Gamma(psi, x)||_2 over
    unit x (psi drops out). C_Gamma(0, a) = 1/2 [a_3 K + (K a) e3^T - e3 (K a)^T], K = E M - M E,
    E = S(1); evaluated on a 181 x 362 grid of the unit sphere (relative error below 1e-4)."""
    M = np.asarray(mass_matrix, dtype=float)
    E = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    K = E @ M - M @ E
    a = _unit_sphere()
    Ka = a @ K.T
    e3 = np.array([0.0, 0.0, 1.0])
    C = 0.5 * (a[:, 2, None, None] * K + Ka[:, :, None] * e3[None, None, :] - e3[None, :, None] * Ka[:, None, :])
    return float(np.linalg.norm(C, ord=2, axis=(1, 2)).max())


def controller_p_matrix(natural_frequency: npt.ArrayLike, damping_ratio: npt.ArrayLike) -> np.ndarray:
    """P of (22)/(26) with the (2,2) sign corrected, ordered [z (3); z' (3)]."""
    w = np.asarray(natural_frequency, dtype=float) * np.ones(3)
    lam = np.asarray(damping_ratio, dtype=float) * np.ones(3)
    p11 = ((2 * lam * w) ** 2 + w**2 + w**4) / (2 * lam * w)
    p22 = (1.0 + w**2) / (2 * lam * w)
    return np.block([[np.diag(p11), np.eye(3)], [np.eye(3), np.diag(p22)]])


def _constants(ship) -> dict:
    """M_M, C_M (Christoffel), k_n and ||D|| of a Cybership (Assumption 1, (4))."""
    M = np.asarray(ship.mass_matrix, dtype=float)
    q = np.asarray(ship.quadratic_damping, dtype=float)
    return {
        "M": M,
        "D": np.asarray(ship.damping_matrix, dtype=float),
        "M_M": float(1.0 / np.linalg.eigvalsh(M).min()),
        "C_M": christoffel_bound(M),
        "k_n": float(np.hypot(q[1], q[2])),
        "norm_D": float(np.linalg.norm(np.asarray(ship.damping_matrix, dtype=float), 2)),
    }


def _controller(constants: dict, natural_frequency, damping_ratio) -> dict:
    """P, lmin(Q) and the gain norms of (24): Kp = M Omega^2, Kd = 2 M Lambda Omega - D."""
    w = np.asarray(natural_frequency, dtype=float) * np.ones(3)
    lam = np.asarray(damping_ratio, dtype=float) * np.ones(3)
    if not (np.all(np.isfinite(w)) and np.all(w > 0) and np.all(np.isfinite(lam)) and np.all(lam > 0)):
        raise check.ParameterError(
            "natural_frequency", f"natural_frequency and damping_ratio must be finite and positive; got {w.tolist()}, {lam.tolist()}"
        )
    P = controller_p_matrix(w, lam)
    eigenvalues = np.linalg.eigvalsh(P)
    M, D = constants["M"], constants["D"]
    Kp = M @ np.diag(w**2)
    DKd = 2.0 * M @ np.diag(lam * w)
    return {
        "P_min": float(eigenvalues.min()),
        "P_max": float(eigenvalues.max()),
        "Q_min": float(2.0 * np.min(w**2)),
        "p11": np.diag(P)[:3],
        "Kp": float(np.linalg.norm(Kp, 2)),
        "Kd": float(np.linalg.norm(DKd - D, 2)),
        "DKd": float(np.linalg.norm(DKd, 2)),
    }


def _start(eta0, nu0, eta_hat0, velocity_hat0, reference_position0, reference_velocity0) -> dict:
    """||x_e0||, ||eta~0||^2 and ||eta~'0||^2 at t_0 (25), (38)."""
    eta0, nu0 = np.asarray(eta0, dtype=float), np.asarray(nu0, dtype=float)
    e_eta0 = eta0 - np.asarray(reference_position0, dtype=float)
    e_eta0[2] = float(ssa(e_eta0[2]))
    rotated = np.asarray(rotate_transpose(e_eta0[2], np.asarray(reference_velocity0, dtype=float)))
    eta_tilde0 = eta0 - np.asarray(eta_hat0, dtype=float)
    eta_tilde0[2] = float(ssa(eta_tilde0[2]))
    eta_tilde_rate0 = np.asarray(rotate(eta0[2], nu0)) - np.asarray(velocity_hat0, dtype=float)
    return {
        "x_e0": float(np.linalg.norm(np.concatenate([e_eta0, nu0 - rotated]))),
        "eta_tilde0_sq": float(eta_tilde0 @ eta_tilde0),
        "eta_tilde_rate0_sq": float(eta_tilde_rate0 @ eta_tilde_rate0),
    }


def _l1_bound(alpha11: float, gamma1: float, gamma2: float) -> float:
    """The right side of (13)/(32)."""
    b = 2.0 * alpha11 + gamma2
    return (b + math.sqrt(max(b * b - 4.0 * (alpha11**2 - gamma1), 0.0))) / 2.0


def _combined(
    constants: dict, controller: dict, start: dict, L1_min, L1_max, L2_min, L2_max, yaw_rate_max, speed_max, acceleration_max, epsilon3=None
) -> dict:
    """The numbers of Prop. 3.3 (module docstring) at eps3 (default: the largest admissible)."""
    M_M, C_M, k_n = constants["M_M"], constants["C_M"], constants["k_n"]
    P_min, P_max = controller["P_min"], controller["P_max"]
    d_M1 = constants["norm_D"] + 2.0 * k_n * speed_max
    d_M3 = 2.0 * k_n * speed_max
    V0 = P_max * start["x_e0"] ** 2 + (L1_max + L2_max) * start["eta_tilde0_sq"] + start["eta_tilde_rate0_sq"]
    s = math.sqrt(V0 / P_min)
    B = M_M * controller["Kp"] + M_M * controller["Kd"] + 2.0 * M_M * controller["DKd"] * speed_max + speed_max + 2.0 * C_M * speed_max + d_M3
    C = 2.0 * C_M + 2.0 * M_M * controller["Kp"] + 2.0 * speed_max + 2.0 * acceleration_max
    free = controller["Q_min"] - yaw_rate_max - s
    eps_sq_max = free / (P_max * (B + C * s)) if free > 0 else 0.0
    eps_sq = eps_sq_max if epsilon3 is None else float(epsilon3) ** 2
    out = {"V0": V0, "s": s, "B": B, "C": C, "free": free, "epsilon3_max": math.sqrt(eps_sq_max), "d_M1": d_M1, "d_M3": d_M3}
    if eps_sq <= 0:
        return out
    inv = 1.0 / eps_sq
    out["epsilon3"] = math.sqrt(eps_sq)
    out["alpha_bar_1_loss"] = yaw_rate_max + eps_sq * P_max * B + (1.0 + eps_sq * P_max * C) * s
    out["L2_bound"] = (
        0.5 * M_M * C_M * speed_max
        + 0.25 * M_M * d_M1
        + 2.0 * inv * P_max * M_M * (controller["Kp"] + controller["Kd"] + 2.0 * controller["DKd"] * speed_max)
        + (0.5 * M_M * C_M + 2.0 * inv * P_max * (2.0 * M_M * controller["Kp"] + 2.0 * speed_max + 2.0 * acceleration_max)) * s
    )
    alpha11 = 0.5 + 3.0 * M_M * C_M * speed_max + 1.5 * M_M * d_M1 + inv * P_max * (speed_max + 2.0 * C_M * speed_max + d_M3)
    gamma = (2.0 * C_M + 2.0 * P_max * C_M + 2.0 * P_max * k_n) / math.sqrt(P_min) + 3.0 * M_M * (C_M + k_n)
    gamma1 = gamma**2 * (P_max * start["x_e0"] ** 2 + L2_max * start["eta_tilde0_sq"] + start["eta_tilde_rate0_sq"])
    gamma2 = gamma**2 * start["eta_tilde0_sq"]
    out.update(alpha11=alpha11, gamma=gamma, gamma1=gamma1, gamma2=gamma2, L1_bound=_l1_bound(alpha11, gamma1, gamma2))
    if gamma2 > 0:
        out["L1_max_bound"] = ((L1_min - alpha11) ** 2 - gamma1) / gamma2 if L1_min > alpha11 else -math.inf
    return out


def _observer(constants: dict, start: dict, L2_max, velocity_bound) -> dict:
    """alpha11, gamma, gamma1, gamma2 of Prop. 3.1 (15) and the bound of (11)."""
    M_M, C_M, k_n = constants["M_M"], constants["C_M"], constants["k_n"]
    d_M1 = constants["norm_D"] + 2.0 * k_n * velocity_bound
    alpha11 = 0.5 + 3.0 * M_M * C_M * velocity_bound + 1.5 * M_M * d_M1
    gamma = 3.0 * M_M * (C_M + k_n)
    gamma1 = gamma**2 * (L2_max * start["eta_tilde0_sq"] + start["eta_tilde_rate0_sq"])
    gamma2 = gamma**2 * start["eta_tilde0_sq"]
    return {
        "d_M1": d_M1,
        "alpha11": alpha11,
        "gamma": gamma,
        "gamma1": gamma1,
        "gamma2": gamma2,
        "L2_bound": 0.5 * M_M * C_M * velocity_bound + 0.25 * M_M * d_M1,
        "L1_bound": _l1_bound(alpha11, gamma1, gamma2),
    }


def check_wondergem_2009(
    ship: Cybership,
    *,
    observer_gains: tuple[npt.ArrayLike, npt.ArrayLike],
    natural_frequency: npt.ArrayLike,
    damping_ratio: npt.ArrayLike = 1.0,
    eta0: npt.ArrayLike,
    nu0: npt.ArrayLike,
    eta_hat0: npt.ArrayLike,
    velocity_hat0: npt.ArrayLike,
    reference_position0: npt.ArrayLike,
    reference_velocity0: npt.ArrayLike,
    yaw_rate_max: float,
    velocity_bound: float = 0.3,
    corrected: bool = False,
    reference_speed_max: float | None = None,
    reference_acceleration_max: float | None = None,
    epsilon3: float | None = None,
) -> Report:
    """The conditions for a :class:`~lookout.models.cybership.Cybership` (its M, D and
    quadratic damping), observer gains (L1, L2) (scalars or diagonals), Omega, Lambda, the
    initial state and estimates (v_hat(0) = ``velocity_hat0``, Earth frame), the reference
    at t_0 (eta_ref0, nu_ref0 body) and its largest yaw rate, and the velocity bound V_M
    of Prop. 3.1. With ``reference_speed_max`` (sup ||nu_ref||) and
    ``reference_acceleration_max`` (sup ||nu_ref'||) also Prop. 3.3 (27)–(33), at
    ``epsilon3`` or, by default, the largest eps3 that (27) admits.

    Returns a :class:`~lookout.analysis.conditions.Report` with the conditions
    ``controller_25`` ((25)), ``observer_3_1`` (Prop. 3.1: (10a), (10b), (11), (13) and,
    when gamma2 > 0, (14)) and, with the reference's bounds, ``combined_3_3``
    (Prop. 3.3: (27) and, when an eps3 satisfies it, (30), (32) and, when gamma2 > 0,
    (33); (29) is (10) and (31) always holds). ``quantities`` holds the model
    constants and the numbers of (15) and (28)-(37)."""
    for name, value in (
        ("yaw_rate_max", yaw_rate_max),
        ("velocity_bound", velocity_bound),
        ("reference_speed_max", reference_speed_max),
        ("reference_acceleration_max", reference_acceleration_max),
    ):
        if value is not None and not (math.isfinite(value) and value >= 0):
            raise check.ParameterError(check.key(name), f"{name} must be finite and >= 0; got {value!r}")
    if (reference_speed_max is None) != (reference_acceleration_max is None):
        raise check.ParameterError(
            "reference_speed_max", "reference_speed_max and reference_acceleration_max must be given together (Prop. 3.3 needs both)"
        )
    if epsilon3 is not None and not (math.isfinite(epsilon3) and epsilon3 > 0):
        raise check.ParameterError("epsilon3", f"epsilon3 must be finite and positive; got {epsilon3!r}")
    L1 = np.asarray(observer_gains[0], dtype=float) * np.ones(3)
    L2 = np.asarray(observer_gains[1], dtype=float) * np.ones(3)
    if np.any(L1 <= 0) or np.any(L2 <= 0) or not np.all(np.isfinite(np.concatenate([L1, L2]))):
        raise check.ParameterError("observer_gains", f"observer_gains must be finite and positive; got L1 = {L1.tolist()}, L2 = {L2.tolist()}")
    constants = _constants(ship)
    controller = _controller(constants, natural_frequency, damping_ratio)
    start = _start(eta0, nu0, eta_hat0, velocity_hat0, reference_position0, reference_velocity0)

    # controller (21)/(25)
    dp = abs(controller["p11"][0] - controller["p11"][1])
    kappa_r = (dp + math.sqrt(dp * dp + 4.0)) / 2.0 if corrected else 1.0
    ratio = math.sqrt(controller["P_max"] / controller["P_min"])
    controller_25 = [
        _check(
            "(25)",
            "lmin(Q) > r_max" + (" kappa_r" if corrected else "") + " + sqrt(lmax(P)/lmin(P)) |x_e0|",
            controller["Q_min"],
            kappa_r * yaw_rate_max + ratio * start["x_e0"],
            "1/s",
        ),
    ]

    # observer, Prop. 3.1
    observer = _observer(constants, start, L2.max(), velocity_bound)
    observer_3_1 = [
        _check("(10a)", "lmin(L1) > 1", L1.min(), 1.0, "1/s"),
        _check("(10b)", "lmin(L2) >= 1", L2.min(), 1.0, "1/s2", ">="),
        _check("(11)", "lmin(L2) > M_M C_M V_M / 2 + M_M d_M1 / 4", L2.min(), observer["L2_bound"], "1/s2"),
        _check("(13)", "lmin(L1) > [(2 a11 + g2) + sqrt((2 a11 + g2)^2 - 4 (a11^2 - g1))] / 2", L1.min(), observer["L1_bound"], "1/s"),
    ]
    if observer["gamma2"] > 0:
        observer_3_1.append(
            _check(
                "(14)",
                "[(lmin(L1) - a11)^2 - g1] / g2 >= lmax(L1)",
                ((L1.min() - observer["alpha11"]) ** 2 - observer["gamma1"]) / observer["gamma2"],
                L1.max(),
                "1/s",
                ">=",
            )
        )
    conditions = [
        Condition("controller_25", "(25)", "controller: alpha_bar > 0", f"{PAPER}, Proposition 3.2, eq. (25)", controller_25),
        Condition("observer_3_1", "Proposition 3.1", "observer: (10), (11), (13), (14)", f"{PAPER}, Proposition 3.1, eqs. (10)-(15)", observer_3_1),
    ]
    quantities = {
        "M_M": constants["M_M"],
        "C_M_christoffel": constants["C_M"],
        "C_M_body": float(max(constants["M"][0, 0], math.hypot(constants["M"][1, 1], constants["M"][1, 2]))),
        "k_n": constants["k_n"],
        "d_M1": observer["d_M1"],
        "d_M2": constants["k_n"],
        "velocity_bound": velocity_bound,
        "lambda_P": [controller["P_min"], controller["P_max"]],
        "lambda_min_Q": controller["Q_min"],
        "x_e0_norm": start["x_e0"],
        "kappa_r": kappa_r,
        "alpha11": observer["alpha11"],
        "gamma": observer["gamma"],
        "gamma1": float(observer["gamma1"]),
        "gamma2": float(observer["gamma2"]),
    }
    notes: list[str] = []

    # combined scheme, Prop. 3.3
    if reference_speed_max is not None:
        combined = _combined(
            constants,
            controller,
            start,
            L1.min(),
            L1.max(),
            L2.min(),
            L2.max(),
            yaw_rate_max,
            reference_speed_max,
            reference_acceleration_max,
            epsilon3,
        )
        if epsilon3 is None:
            combined_3_3 = [
                _check("(27)", "eps3 exists: lmin(Q) > r_max + sqrt(V0/lmin(P))", controller["Q_min"], yaw_rate_max + combined["s"], "1/s")
            ]
        else:
            combined_3_3 = [
                _check(
                    "(27)",
                    "lmin(Q) > r_max + eps3^2 lmax(P) (B + C s) + s, s = sqrt(V0/lmin(P))",
                    controller["Q_min"],
                    combined["alpha_bar_1_loss"],
                    "1/s",
                )
            ]
        if "epsilon3" in combined:
            combined_3_3 += [
                _check("(30)", "lmin(L2) > ... + 2 eps3^-2 lmax(P) (...) sqrt(V0/lmin(P))", L2.min(), combined["L2_bound"], "1/s2"),
                _check("(32)", "lmin(L1) > [(2 a11 + g2) + sqrt(...)] / 2 with (34)-(37)", L1.min(), combined["L1_bound"], "1/s"),
            ]
            if combined["gamma2"] > 0:
                combined_3_3.append(_check("(33)", "[(lmin(L1) - a11)^2 - g1] / g2 >= lmax(L1)", combined["L1_max_bound"], L1.max(), "1/s", ">="))
        else:
            notes.append("(30), (32), (33) need an eps3 that satisfies (27); none exists")
        conditions.append(
            Condition(
                "combined_3_3",
                "Proposition 3.3",
                "combined scheme: (27), (30), (32), (33)",
                f"{PAPER}, Proposition 3.3, eqs. (27)-(37)",
                combined_3_3,
            )
        )
        quantities["combined"] = {
            key: combined[key]
            for key in ("V0", "epsilon3_max", "epsilon3", "d_M1", "d_M3", "alpha11", "gamma", "gamma1", "gamma2")
            if key in combined
        }
        quantities["combined"].update(
            reference_speed_max=reference_speed_max,
            reference_acceleration_max=reference_acceleration_max,
            Kp_norm=controller["Kp"],
            Kd_norm=controller["Kd"],
            D_plus_Kd_norm=controller["DKd"],
        )
    return Report(f"{PAPER}: gain conditions", conditions, quantities, notes=notes)


@dataclass(frozen=True)
class GainProposal:
    """Gains from :func:`propose_wondergem_2009`: uniform Omega = omega I, isotropic L1, L2."""

    found: bool
    natural_frequency: float
    damping_ratio: float
    observer_gains: tuple[float, float]
    epsilon3: float
    iterations: int
    report: Report | None
    reason: str = ""

    @property
    def observer_poles(self) -> list[float]:
        """Roots of s^2 + L1 s + L2, the observer's linear part per DOF (1/s)."""
        return sorted(np.roots([1.0, self.observer_gains[0], self.observer_gains[1]]).real.tolist())

    @property
    def euler_step_max(self) -> float:
        """The largest forward-Euler step that keeps the linear part stable, 2 / |fastest pole| (s)."""
        return 2.0 / max(abs(p) for p in self.observer_poles)

    def search(self) -> dict:
        """The search's result, without the check of the gains: JSON-safe (what
        :meth:`outcome` puts in its ``quantities["proposal"]``)."""
        return json_safe(
            {
                "observer_poles": self.observer_poles if self.found else None,
                "euler_step_max_s": self.euler_step_max if self.found else None,
                "found": self.found,
                "natural_frequency": self.natural_frequency,
                "damping_ratio": self.damping_ratio,
                "observer_gains": {"L1": self.observer_gains[0], "L2": self.observer_gains[1]},
                "epsilon3": self.epsilon3,
                "iterations": self.iterations,
                "reason": self.reason,
            }
        )

    def summary(self) -> list[str]:
        """The proposed gains, or why there are none."""
        if not self.found:
            return [f"no gains found after {self.iterations} iterations: {self.reason}"]
        L1, L2 = self.observer_gains
        return [
            f"proposed: Omega = {self.natural_frequency:.4g} I rad/s, Lambda = {self.damping_ratio:g} I, "
            f"L1 = {L1:.4g} I 1/s, L2 = {L2:.4g} I 1/s2, eps3 = {self.epsilon3:.3g} ({self.iterations} iterations)",
            f"observer poles {', '.join(f'{p:.4g}' for p in self.observer_poles)} 1/s: forward Euler needs a step below {self.euler_step_max:.3g} s",
        ]

    def outcome(self) -> Report:
        """The proposal as a :class:`~lookout.analysis.conditions.Report`: the check of the
        proposed gains, with :meth:`summary` and :meth:`search` (``quantities["proposal"]``);
        when none were found, a report without conditions (verdict ``unverified``) that
        says why. Its :meth:`~lookout.analysis.conditions.Report.to_dict` is the JSON form."""
        report = self.report if self.report is not None else Report(f"{PAPER}: gain search", ())
        return report.extended(summary=self.summary(), quantities={"proposal": self.search()})


def propose_wondergem_2009(
    ship: Cybership,
    *,
    damping_ratio: float = 1.0,
    eta0: npt.ArrayLike,
    nu0: npt.ArrayLike,
    eta_hat0: npt.ArrayLike,
    velocity_hat0: npt.ArrayLike,
    reference_position0: npt.ArrayLike,
    reference_velocity0: npt.ArrayLike,
    yaw_rate_max: float,
    reference_speed_max: float,
    reference_acceleration_max: float,
    velocity_bound: float = 0.3,
    margin: float = 1.1,
    max_iterations: int = 200,
) -> GainProposal:
    """Gains that satisfy (25), Prop. 3.1 and Prop. 3.3 at the given start: the paper's
    procedure (steps 1–7 after Prop. 3.3) made explicit, with a search where it leaves a
    free choice:

    1. Lambda = ``damping_ratio`` I and Omega = omega I, uniform so that kappa_r = 1 and
       the gap in (81) does not arise;
    2.–3. omega on a 1 % grid over 0.05–100 rad/s where an eps3 satisfies (27) (this
       implies (25)), and eps3^2 = f eps3_max^2 with f in 0.1, 0.2, ..., 0.9 (alpha_bar_1
       keeps at least 10 % of its eps3 -> 0 value): the pair that needs the smallest L1;
    4.–7. L2 = ``margin`` x max(1, (11), (30)) and L1 = ``margin`` x max(1, (13), (32)),
       isotropic (lmax = lmin, so (31) holds and (33) reduces to (32)).

    V0 (28) depends on L1 and L2 when eta_hat0 != eta0, which makes the printed procedure
    circular; steps 2–4 are repeated with the new V0 until the gains stop growing (found)
    or grow past 1e12 / ``max_iterations`` (not found). With eta_hat0 = eta0 (eta is
    measured) the second pass confirms the first."""
    if not (math.isfinite(margin) and margin > 1.0):
        raise check.ParameterError("margin", f"margin must be finite and > 1; got {margin!r}")
    for name, value in (
        ("yaw_rate_max", yaw_rate_max),
        ("reference_speed_max", reference_speed_max),
        ("reference_acceleration_max", reference_acceleration_max),
        ("velocity_bound", velocity_bound),
    ):
        if not (math.isfinite(value) and value >= 0):
            raise check.ParameterError(check.key(name), f"{name} must be finite and >= 0; got {value!r}")
    if not (math.isfinite(damping_ratio) and damping_ratio > 0):
        raise check.ParameterError("damping_ratio", f"damping_ratio must be finite and positive; got {damping_ratio!r}")
    constants = _constants(ship)
    start = _start(eta0, nu0, eta_hat0, velocity_hat0, reference_position0, reference_velocity0)
    grid = np.geomspace(0.05, 100.0, 765)  # 1 % steps
    controllers = [_controller(constants, w, damping_ratio) for w in grid]
    fractions = np.arange(1, 10) / 10.0
    bounds = (yaw_rate_max, reference_speed_max, reference_acceleration_max)
    L1 = L2 = 1.0
    omega = eps3 = math.nan
    for iteration in range(1, max_iterations + 1):
        observer = _observer(constants, start, L2, velocity_bound)
        best = None
        for w, controller in zip(grid, controllers):
            eps_max = _combined(constants, controller, start, L1, L1, L2, L2, *bounds)["epsilon3_max"]
            if eps_max <= 0:
                continue
            for fraction in fractions:
                eps = eps_max * math.sqrt(fraction)
                combined = _combined(constants, controller, start, L1, L1, L2, L2, *bounds, eps)
                need = (max(1.0, combined["L1_bound"], observer["L1_bound"]), max(1.0, combined["L2_bound"], observer["L2_bound"]))
                if best is None or need < best[0]:
                    best = (need, w, eps)
        if best is None:
            return GainProposal(
                False,
                math.nan,
                damping_ratio,
                (L1, L2),
                math.nan,
                iteration,
                None,
                f"no omega up to {grid[-1]:g} rad/s leaves (27) an eps3 with L1 = {L1:.3g}, L2 = {L2:.3g}",
            )
        (need1, need2), omega, eps3 = best
        if need1 < L1 and need2 < L2:
            report = check_wondergem_2009(
                ship,
                observer_gains=(L1, L2),
                natural_frequency=omega,
                damping_ratio=damping_ratio,
                eta0=eta0,
                nu0=nu0,
                eta_hat0=eta_hat0,
                velocity_hat0=velocity_hat0,
                reference_position0=reference_position0,
                reference_velocity0=reference_velocity0,
                yaw_rate_max=yaw_rate_max,
                velocity_bound=velocity_bound,
                reference_speed_max=reference_speed_max,
                reference_acceleration_max=reference_acceleration_max,
                epsilon3=eps3,
            )
            return GainProposal(True, float(omega), damping_ratio, (float(L1), float(L2)), float(eps3), iteration, report)
        L1, L2 = max(L1, margin * need1), max(L2, margin * need2)
        if max(L1, L2) > 1e12:
            break
    return GainProposal(
        False,
        float(omega),
        damping_ratio,
        (float(L1), float(L2)),
        float(eps3),
        iteration,
        None,
        f"L1, L2 keep growing with V0 (L1 = {L1:.3g}, L2 = {L2:.3g}): the initial estimate error ||eta~0|| = "
        f"{math.sqrt(start['eta_tilde0_sq']):.3g} makes the procedure's fixed point run away; start the estimate at the measurement",
    )


def _vector(name: str, value) -> tuple[float, ...]:
    """``value`` as 3 finite floats (a scalar for all three), or a ValueError naming ``name``."""
    array = check.vector(name, value)
    check.finite(name, array)
    return tuple(float(v) for v in array)


def _bound(name: str, value, *, low: float = 0.0, strict: bool = False) -> float:
    """``value`` as a finite float >= ``low`` (> ``low`` with ``strict``), or a ValueError naming ``name``."""
    number = float(value)
    if not (math.isfinite(number) and (number > low if strict else number >= low)):
        raise check.ParameterError(check.key(name), f"{name} must be finite and {'>' if strict else '>='} {low:g}; got {value!r}")
    return number


@functools.lru_cache(maxsize=32)
def _cached_proposal(ship_numbers: tuple, start: tuple, bounds: tuple, damping_ratio: float, velocity_bound: float, margin: float) -> GainProposal:
    """:func:`propose_wondergem_2009` once per ship and inputs: the observer's rule and the
    controller's rule of one composition ask for the same proposal."""

    mass, damping, quadratic = (np.asarray(part) for part in ship_numbers)
    eta0, nu0, eta_hat0, velocity_hat0, reference_position0, reference_velocity0 = start
    yaw_rate_max, speed_max, acceleration_max = bounds
    return propose_wondergem_2009(
        Cybership(mass.reshape(3, 3), damping.reshape(3, 3), quadratic),
        damping_ratio=damping_ratio,
        eta0=eta0,
        nu0=nu0,
        eta_hat0=eta_hat0,
        velocity_hat0=velocity_hat0,
        reference_position0=reference_position0,
        reference_velocity0=reference_velocity0,
        yaw_rate_max=yaw_rate_max,
        reference_speed_max=speed_max,
        reference_acceleration_max=acceleration_max,
        velocity_bound=velocity_bound,
        margin=margin,
    )


def wondergem_2009_gains(
    ship: Cybership,
    *,
    reference_position: npt.ArrayLike,
    reference_velocity: npt.ArrayLike,
    reference_yaw_rate_max: float,
    reference_speed_max: float,
    reference_acceleration_max: float,
    start_position: npt.ArrayLike,
    start_velocity: npt.ArrayLike = 0.0,
    estimate_position: npt.ArrayLike | None = None,
    estimate_velocity: npt.ArrayLike = 0.0,
    damping_ratio: float = 1.0,
    velocity_bound: float = 0.3,
    margin: float = 1.1,
) -> GainProposal:
    """The gains of Wondergem et al. (2009)'s tuning procedure (steps 1–7 after Prop. 3.3)
    for ``ship``, a start and a reference: the design rule ``wondergem-2009`` of the
    observer (6) (:func:`wondergem_2009_observer`) and of the tracking
    scheme (23) (:meth:`lookout.controllers.TrackingController.design`), which take one
    proposal between them, L1, L2 and Omega, Lambda being chosen together.

    :func:`propose_wondergem_2009` with the arguments named for a composition's keys
    (``start_position`` is eta_0, ``estimate_position`` eta_hat_0, default eta_0: the
    estimate started at the measurement; ``estimate_velocity`` the Earth-frame v_hat(0)),
    computed once per ship and inputs. The returned proposal's gains satisfy (25),
    Prop. 3.1 ((10), (11), (13), (14)) and Prop. 3.3 ((27), (29)–(33)) at its eps3
    (:attr:`GainProposal.report`, from :func:`check_wondergem_2009`).

    Raises
    ------
    ValueError
        One line naming the argument: a value out of range, or the start from which the
        procedure finds no gains. With eta_hat_0 != eta_0, V0 (28) grows with L1 and L2
        and the fixed point can run away (``estimate_position``); from eta_hat_0 = eta_0
        the initial tracking error ||x_e0|| must leave (27) an eps3 for some
        omega <= 100 rad/s (``start_position``).
    """
    ship_numbers = tuple(
        tuple(np.asarray(getattr(ship, name), dtype=float).ravel().tolist()) for name in ("mass_matrix", "damping_matrix", "quadratic_damping")
    )
    position = _vector("start_position", start_position)
    start = (
        position,
        _vector("start_velocity", start_velocity),
        position if estimate_position is None else _vector("estimate_position", estimate_position),
        _vector("estimate_velocity", estimate_velocity),
        _vector("reference_position", reference_position),
        _vector("reference_velocity", reference_velocity),
    )
    bounds = (
        _bound("reference_yaw_rate_max", reference_yaw_rate_max),
        _bound("reference_speed_max", reference_speed_max),
        _bound("reference_acceleration_max", reference_acceleration_max),
    )
    ratio = _bound("damping_ratio", damping_ratio, strict=True)
    speed = _bound("velocity_bound", velocity_bound)
    factor = _bound("margin", margin, low=1.0, strict=True)
    proposal = _cached_proposal(ship_numbers, start, bounds, ratio, speed, factor)
    if proposal.found and proposal.report is not None and proposal.report.holds:
        return proposal
    estimate_error = math.sqrt(_start(*start)["eta_tilde0_sq"])
    if estimate_error > 0:
        L1, L2 = proposal.observer_gains
        raise check.ParameterError(
            "estimate_position",
            f"estimate_position is too far from the measurement for {PAPER}'s procedure: with ||eta_hat(0) - eta(0)|| = "
            f"{estimate_error:.3g} (m and rad in one norm) V0 (28) grows with L1 and L2 and their fixed point runs away "
            f"(L1 = {L1:.3g}, L2 = {L2:.3g} after {proposal.iterations} iterations); leave it out to start the estimate at the measurement",
        )
    raise check.ParameterError("start_position", f"start_position is too far from the reference for {PAPER}'s procedure: {proposal.reason}")


def wondergem_2009_observer(
    ship: Cybership,
    *,
    reference_position: npt.ArrayLike,
    reference_velocity: npt.ArrayLike,
    reference_yaw_rate_max: float,
    reference_speed_max: float,
    reference_acceleration_max: float,
    start_position: npt.ArrayLike,
    start_velocity: npt.ArrayLike = 0.0,
    estimate_position: npt.ArrayLike | None = None,
    estimate_velocity: npt.ArrayLike = 0.0,
    damping_ratio: float = 1.0,
    velocity_bound: float = 0.3,
    margin: float = 1.1,
    steps_per_sample: int = 1,
    method: str = "rk4",
    initial_velocity: str = "estimate",
) -> EarthFixedObserver:
    """The Earth-fixed observer (6) for ``ship`` (the rule ``wondergem-2009`` of the kind
    ``earth-fixed``) with L1 = l1 I, L2 = l2 I from Wondergem et al.
    (2009)'s gain tuning procedure (steps 1–7 after Prop. 3.3).

    The procedure chooses the controller's Omega, Lambda (24)–(26) and the observer's
    L1, L2 together: Omega = omega I on a 1 % grid where an eps3 satisfies (27) (which
    implies (25)), then L2 above (10b), (11), (30) and L1 above (10a), (13), (32) by
    ``margin``, isotropic so that (31) holds and (14), (33) reduce to (13), (32), with V0
    of (28) iterated to a fixed point
    (:func:`lookout.analysis.tracking.propose_wondergem_2009`). The gains satisfy (25),
    Prop. 3.1 ((10)–(15)) and Prop. 3.3 ((27)–(37)) at the given start; the tracking
    controller's rule of the same name, given the same reference and start, takes the
    Omega and Lambda of the same proposal
    (:func:`lookout.analysis.tracking.wondergem_2009_gains`).

    The conditions are sufficient and conservative: on Cybership II around the
    reproduction's ellipse L1 is about 2.5e5 1/s, so the observer's fastest pole
    -L1 needs an integration step below about 1e-5 s (forward Euler 2 / L1, RK4
    2.8 / L1).

    Parameters
    ----------
    ship : Cybership
        The observer's model (M, D and D_n); in a composition, the plant's unless given.
    reference_position : array_like, shape (3,)
        eta_ref(0): the reference's position north, east (m) and heading (rad) at t_0.
    reference_velocity : array_like, shape (3,)
        nu_ref(0): the reference's body-frame velocity surge, sway (m/s) and yaw rate (rad/s) at t_0.
    reference_yaw_rate_max : float, non-negative
        r_ref^max, the largest |r_ref| of the reference (rad/s).
    reference_speed_max : float, non-negative
        sup ||nu_ref|| of the reference (m/s and rad/s in one norm, as the paper's).
    reference_acceleration_max : float, non-negative
        sup ||nu_ref'|| of the reference (m/s^2 and rad/s^2 in one norm), its smooth part.
    start_position : array_like, shape (3,)
        eta(0): the ship's initial position north, east (m) and heading (rad).
    start_velocity : array_like, shape (3,)
        nu(0): the ship's initial body-frame velocity (m/s, m/s, rad/s).
    estimate_position : array_like, shape (3,), optional
        eta_hat(0), the observer's initial position estimate (m, m, rad); default
        ``start_position``, the estimate started at the measurement.
    estimate_velocity : array_like, shape (3,)
        v_hat(0) = eta_hat'(0), the initial Earth-frame velocity estimate (m/s, m/s, rad/s).
    damping_ratio : float, positive
        lambda of Lambda = lambda I, the relative damping of the error dynamics (19) (1).
    velocity_bound : float, non-negative
        V_M of Prop. 3.1, a bound on the ship's speed ||eta'|| (m/s).
    margin : float, in (1, inf)
        Factor by which L1 and L2 exceed their largest lower bound (1).
    steps_per_sample : int
        Integration steps of the observer's ``predict`` per sample.
    method : {"rk4", "euler"}
        How the observer's ``predict`` integrates (6) between samples.
    initial_velocity : {"estimate", "state"}
        Which of v_hat(0) or zeta(0) the guess's velocity is (module docstring).
    """
    proposal = wondergem_2009_gains(
        ship,
        reference_position=reference_position,
        reference_velocity=reference_velocity,
        reference_yaw_rate_max=reference_yaw_rate_max,
        reference_speed_max=reference_speed_max,
        reference_acceleration_max=reference_acceleration_max,
        start_position=start_position,
        start_velocity=start_velocity,
        estimate_position=estimate_position,
        estimate_velocity=estimate_velocity,
        damping_ratio=damping_ratio,
        velocity_bound=velocity_bound,
        margin=margin,
    )
    position_gain, velocity_gain = proposal.observer_gains
    return EarthFixedObserver(ship, position_gain, velocity_gain, steps_per_sample=steps_per_sample, method=method, initial_velocity=initial_velocity)


__all__ = [
    "GainProposal",
    "check_wondergem_2009",
    "wondergem_2009_observer",
    "christoffel_bound",
    "controller_p_matrix",
    "propose_wondergem_2009",
    "wondergem_2009_gains",
]
