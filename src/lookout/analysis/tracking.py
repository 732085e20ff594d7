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

The combined procedure of Prop. 3.3 ((27)–(34)) is not evaluated yet: its printed text
is cut, and as printed it is circular (V0 depends on L1, L2, chosen afterwards).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lookout._math import rotate, rotate_transpose, ssa
from lookout.analysis.adaptive_dp import Inequality, _inequality
from lookout.analysis._json import json_safe


def _unit_sphere(count: int = 181) -> np.ndarray:
    theta = np.linspace(0.0, np.pi, count)
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * count)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)


def christoffel_bound(mass_matrix) -> float:
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


def controller_p_matrix(natural_frequency, damping_ratio) -> np.ndarray:
    """P of (22)/(26) with the (2,2) sign corrected, ordered [z (3); z' (3)]."""
    w = np.asarray(natural_frequency, dtype=float) * np.ones(3)
    lam = np.asarray(damping_ratio, dtype=float) * np.ones(3)
    p11 = ((2 * lam * w) ** 2 + w**2 + w**4) / (2 * lam * w)
    p22 = (1.0 + w**2) / (2 * lam * w)
    return np.block([[np.diag(p11), np.eye(3)], [np.eye(3), np.diag(p22)]])


@dataclass
class TrackingGainReport:
    """Conditions (21)/(25) and (10), (11), (13), (14) for one gain set."""

    inequalities: list[Inequality]
    quantities: dict = field(default_factory=dict)

    @property
    def holds(self) -> bool:
        return all(item.verdict == "holds" for item in self.inequalities)

    def to_dict(self) -> dict:
        return json_safe({"holds": self.holds, "inequalities": [item.to_dict() for item in self.inequalities], "quantities": self.quantities})

    def text(self) -> str:
        lines = ["Wondergem et al. (2009): gain conditions"]
        for item in self.inequalities:
            lines += item.describe()
        return "\n".join(lines)


def check_wondergem_2009(
    ship,
    *,
    observer_gains=(15.0, 50.0),
    natural_frequency=(0.72, 0.42, 0.64),
    damping_ratio=1.0,
    eta0,
    nu0,
    eta_hat0,
    velocity_hat0,
    reference_position0,
    reference_velocity0,
    yaw_rate_max: float,
    velocity_bound: float = 0.3,
    corrected: bool = False,
) -> TrackingGainReport:
    """The conditions for a :class:`~lookout.models.cybership.Cybership` (its M, D and
    quadratic damping), observer gains (L1, L2) (scalars or diagonals), Omega, Lambda, the
    initial state and estimates (v_hat(0) = ``velocity_hat0``, Earth frame), the reference
    at t_0 (eta_ref0, nu_ref0 body) and its largest yaw rate, and the velocity bound V_M."""
    for name, value in (("yaw_rate_max", yaw_rate_max), ("velocity_bound", velocity_bound)):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0; got {value!r}")
    L1 = np.asarray(observer_gains[0], dtype=float) * np.ones(3)
    L2 = np.asarray(observer_gains[1], dtype=float) * np.ones(3)
    if np.any(L1 <= 0) or np.any(L2 <= 0) or not np.all(np.isfinite(np.concatenate([L1, L2]))):
        raise ValueError(f"observer_gains must be finite and positive; got L1 = {L1.tolist()}, L2 = {L2.tolist()}")
    M = np.asarray(ship.mass_matrix, dtype=float)
    D = np.asarray(ship.damping_matrix, dtype=float)
    q = np.asarray(ship.quadratic_damping, dtype=float)
    M_M = 1.0 / np.linalg.eigvalsh(M).min()
    C_M = christoffel_bound(M)
    k_n = float(np.hypot(q[1], q[2]))
    d_M1 = float(np.linalg.norm(D, 2) + 2.0 * k_n * velocity_bound)
    d_M2 = k_n

    # controller (21)/(25)
    P = controller_p_matrix(natural_frequency, damping_ratio)
    eigenvalues = np.linalg.eigvalsh(P)
    w = np.asarray(natural_frequency, dtype=float) * np.ones(3)
    q_min = float(2.0 * np.min(w**2))
    eta0, nu0 = np.asarray(eta0, dtype=float), np.asarray(nu0, dtype=float)
    eta_ref0 = np.asarray(reference_position0, dtype=float)
    e_eta0 = eta0 - eta_ref0
    e_eta0[2] = float(ssa(e_eta0[2]))
    rotated = np.asarray(rotate_transpose(e_eta0[2], np.asarray(reference_velocity0, dtype=float)))
    x_e0 = float(np.linalg.norm(np.concatenate([e_eta0, nu0 - rotated])))
    p11 = np.diag(P)[:3]
    dp = abs(p11[0] - p11[1])
    kappa_r = (dp + math.sqrt(dp * dp + 4.0)) / 2.0 if corrected else 1.0
    ratio = math.sqrt(eigenvalues.max() / eigenvalues.min())
    inequalities = [
        _inequality("(25)", "lmin(Q) > r_max" + (" kappa_r" if corrected else "") + " + sqrt(lmax(P)/lmin(P)) |x_e0|",
                    q_min, kappa_r * yaw_rate_max + ratio * x_e0, "1/s"),
    ]

    # observer, Prop. 3.1
    eta_tilde0 = eta0 - np.asarray(eta_hat0, dtype=float)
    eta_tilde0[2] = float(ssa(eta_tilde0[2]))
    eta_tilde_rate0 = np.asarray(rotate(eta0[2], nu0)) - np.asarray(velocity_hat0, dtype=float)
    alpha11 = 0.5 + 3.0 * M_M * C_M * velocity_bound + 1.5 * M_M * d_M1
    gamma = 3.0 * M_M * (C_M + d_M2)
    gamma1 = gamma**2 * (L2.max() * eta_tilde0 @ eta_tilde0 + eta_tilde_rate0 @ eta_tilde_rate0)
    gamma2 = gamma**2 * (eta_tilde0 @ eta_tilde0)
    b = 2.0 * alpha11 + gamma2
    bound13 = (b + math.sqrt(max(b * b - 4.0 * (alpha11**2 - gamma1), 0.0))) / 2.0
    inequalities += [
        _inequality("(10a)", "lmin(L1) > 1", L1.min(), 1.0, "1/s"),
        _inequality("(10b)", "lmin(L2) >= 1", L2.min() + 1e-300, 1.0, "1/s2"),
        _inequality("(11)", "lmin(L2) > M_M C_M V_M / 2 + M_M d_M1 / 4", L2.min(), 0.5 * M_M * C_M * velocity_bound + 0.25 * M_M * d_M1, "1/s2"),
        _inequality("(13)", "lmin(L1) > [(2 a11 + g2) + sqrt((2 a11 + g2)^2 - 4 (a11^2 - g1))] / 2", L1.min(), bound13, "1/s"),
    ]
    if gamma2 > 0:
        inequalities.append(_inequality("(14)", "[(lmin(L1) - a11)^2 - g1] / g2 >= lmax(L1)", ((L1.min() - alpha11) ** 2 - gamma1) / gamma2, L1.max(), "1/s"))
    quantities = {
        "M_M": M_M, "C_M_christoffel": C_M, "C_M_body": float(max(M[0, 0], math.hypot(M[1, 1], M[1, 2]))),
        "k_n": k_n, "d_M1": d_M1, "d_M2": d_M2, "velocity_bound": velocity_bound,
        "lambda_P": [float(eigenvalues.min()), float(eigenvalues.max())], "lambda_min_Q": q_min, "x_e0_norm": x_e0,
        "kappa_r": kappa_r, "alpha11": alpha11, "gamma": gamma, "gamma1": float(gamma1), "gamma2": float(gamma2),
    }
    return TrackingGainReport(inequalities, quantities)


__all__ = ["TrackingGainReport", "check_wondergem_2009", "christoffel_bound", "controller_p_matrix"]
