"""Stability analysis of the sliding-mode observer of Kim (2002): (14), (17), eigenvalues.

Kim, M.-H. (2002), Section 3.2, read with the corrections of
``derivations-kim-calugi-2003.md`` (K1, K2). With x~ = x - x_hat the error dynamics
of the observer (6), for the model of (1)–(5) without noise and J = J(y) = R(psi)::

    xi~'  = (A_w - H1 C_w) xi~ - H1 eta~
    eta~' = J nu~ - H2 y~ - Kbar sat(y~ / eps)
    b~'   = -T^-1 b~ - H3 y~
    M nu~' = -D nu~ + J^T b~ - J^T H4 y~ + E_nu w_nu  =  -D nu~ - J^T z~ + E_nu w_nu
    y~ = C_w xi~ + eta~,      z~ = C x~ = H4 y~ - b~,      C = [H4 C_w, H4, -I]

(the printed (8)–(10) carry a spurious +tau, lack +J^T b~, and print C as
[C_w H1 -I]). This module gives

* :func:`error_system`: the 15x15 matrix of these dynamics for a fixed heading,
  with Kbar = 0 or with the switching term linearized inside its boundary layer
  (H2 -> H2 + Kbar/eps), and :func:`eigenvalue_report` for its modes;
* :func:`sigma2` and :func:`kyp_14`: Sigma_2 = (A, B, C) of (9)–(10) and the KYP
  conditions (14), P A + A^T P = -Q, B^T P = C, assembled from the per-DOF
  certificates of :mod:`lookout.analysis.passive` (the gains are diagonal, so
  (14) is equivalent to three scalar SPR conditions);
* :func:`switching_gain_required`: condition (17) made concrete, the switching gain
  that a bound on the unmodelled force E_nu w_nu requires, and the force bound that
  a given Kbar covers;
* :func:`check_kim_2002`: all of it for one observer, as a
  :class:`~lookout.analysis.conditions.Report`.

Findings for the printed gains (A.2)–(A.4) on the Northern Clipper (tested in
tests/test_sliding_mode_analysis.py): H3/H4 = 10 1/s > w_o breaks rule (48); the
loops' phase reaches -172.6 deg at 0.696 rad/s, so (14) has no solution; with
Kbar = 0 the error system has one unstable pair, +0.0156 +- 0.1235j 1/s (surge;
e-folding 64 s, period 51 s), while the coupled sway-yaw modes are stable (slowest
-0.0013 +- 0.1035j); inside the layer it is stable once Kbar/eps exceeds about
1.22 1/s (eps below about 8.2 m for Kbar = 10 m/s). Kbar = (10, 10, 0.01) covers,
one axis at a time, |f| up to 5.02e5 N in surge, 2.16e5 N in sway and 3.48e6 N m
in yaw (the last two limited by the yaw gain 0.01 rad/s).

Heading convention: the error system is linear only for J held constant (F&S
assumption: J(y) = J(psi), psi_w small); its eigenvalues do not depend on the
heading when the surge and sway gains and wave models are equal, as in Kim's (A.4).
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass
from typing import Any, TypeGuard

import numpy as np
import numpy.typing as npt
import scipy.integrate
import scipy.linalg
import scipy.optimize

from lookout import _validation as check
from lookout.analysis.conditions import Condition, Inequality, Report, Verdict, number, numbers
from lookout.analysis.passive import _normalized_min_eig, check_spr, check_tuning_rule, transfer_functions
from lookout.models.vessel import DOF, DPVessel
from lookout.observers.passive import PassiveObserver
from lookout.observers.sliding_mode import DEFAULT_BOUNDARY_LAYER, SlidingModeObserver

#: Names of the 15 error states, in the order of :func:`error_system`.
ERROR_STATES = (
    tuple(f"xi1_{d}" for d in DOF)
    + tuple(f"xi2_{d}" for d in DOF)
    + tuple(f"eta_{d}" for d in DOF)
    + tuple(f"b_{d}" for d in DOF)
    + tuple(f"nu_{d}" for d in DOF)
)
#: Units of Kbar, rho and the velocity disturbance bound per axis.
VELOCITY_UNITS = ("m/s", "m/s", "rad/s")
#: Units of the disturbance bound F per axis (body-fixed force, force, moment).
FORCE_UNITS = ("N", "N", "N m")

#: Where the checks of this module come from.
SOURCE_ERROR_SYSTEM = "Kim (2002), (8)-(10), corrected (derivations K1)"
SOURCE_14 = "Kim (2002), eq. (14)"
SOURCE_17 = "Kim (2002), eqs. (15)-(17), corrected (derivations K2)"


def _is_sliding_mode(observer: object) -> TypeGuard[SlidingModeObserver]:
    """A sliding-mode observer (:class:`lookout.observers.SlidingModeObserver`)."""
    return isinstance(observer, SlidingModeObserver)


def _parts(observer) -> tuple[PassiveObserver, np.ndarray, np.ndarray]:
    """(passive observer, Kbar, eps) of a sliding-mode or passive observer."""
    if _is_sliding_mode(observer):
        return observer.passive, np.asarray(observer.switching_gain, float), np.asarray(observer.boundary_layer, float)
    if isinstance(observer, PassiveObserver):
        return observer, np.zeros(3), np.ones(3)
    raise check.ParameterError("observer", f"observer must be a SlidingModeObserver or a PassiveObserver; got {type(observer).__name__}")


def _rotation(heading: float) -> np.ndarray:
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _model(passive: PassiveObserver, vessel: DPVessel) -> tuple[np.ndarray, np.ndarray]:
    """M, D of ``vessel``, which must be the observer's model (F&S A1–A4)."""
    M, D = np.asarray(vessel.mass_matrix, float), np.asarray(vessel.damping_matrix, float)
    if np.any(np.asarray(vessel.stiffness_matrix) != 0):
        raise ValueError(
            "the vessel has a mooring stiffness K, which the observer's model lacks: the error "
            "dynamics are then not a linear system in the error alone"
        )
    if not (
        np.allclose(M, np.asarray(passive.mass_matrix), rtol=1e-12, atol=0.0)
        and np.allclose(D, np.asarray(passive.damping_matrix), rtol=1e-12, atol=1e-12 * np.abs(D).max())
    ):
        raise ValueError(
            "the observer's model M, D differs from the vessel's: the error dynamics are then not "
            "a linear system in the error alone (they depend on the true state); build the observer "
            "for this vessel"
        )
    return M, D


def error_system(
    observer: SlidingModeObserver | PassiveObserver, vessel: DPVessel, *, heading: float = 0.0, inside_layer: bool = False
) -> np.ndarray:
    """The linear error dynamics d x~/dt = A_e x~ of the observer, J = R(heading) held.

    State ``x~ = [xi1~ (3), xi2~ (3), eta~ (3), b~ (3), nu~ (3)]`` (:data:`ERROR_STATES`),
    x~ = x - x_hat, without noise or unmodelled forces. From the corrected (8)::

        A_e = [[ A,                      B J       ],
               [ -(1/gamma) M^-1 J^T C,  -M^-1 D   ]]

    with A, B, C of Sigma_2 (:func:`sigma2`, Kim (10) with C = [H4 C_w, H4, -gamma I];
    gamma = 1 for Kim). The switching term is left out (Kbar = 0), or, with
    ``inside_layer=True``, linearized inside its boundary layer, where
    Kbar sat(y~/eps) = (Kbar/eps) y~ adds Kbar/eps to H2. Outside the layer its
    derivative is zero and the Kbar = 0 matrix applies.

    Parameters
    ----------
    observer : SlidingModeObserver or PassiveObserver
        A passive observer is the Kbar = 0 case.
    vessel : DPVessel
        The vessel; its M and D must be the observer's model.
    heading : float
        psi of J (rad), held constant.
    inside_layer : bool
        Linearize the switching term inside its boundary layer.

    Returns
    -------
    ndarray, shape (15, 15)
    """
    passive, kbar, eps = _parts(observer)
    M, D = _model(passive, vessel)
    A, B, C = sigma2(passive, extra_position_gain=kbar / eps if inside_layer else None)
    gamma = float(passive.lyapunov_weight)
    J = _rotation(float(heading))
    Minv = np.linalg.inv(M)
    top = np.hstack([A, B @ J])
    bottom = np.hstack([-Minv @ J.T @ C / gamma, -Minv @ D])
    return np.vstack([top, bottom])


def sigma2(
    observer: SlidingModeObserver | PassiveObserver, *, extra_position_gain: npt.ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sigma_2 of Kim (9)–(10), corrected: (A 12x12, B 12x3, C 3x12), x~ = [xi~, eta~, b~].

    ::

        A = [[A_w - H1 C_w, -H1,  0    ],      B = [0; I; 0]
             [-H2 C_w,      -H2,  0    ],      C = [H4 C_w, H4, -gamma I]
             [-H3 C_w,      -H3, -T^-1 ]]

    with A_w = [[0, I], [-W^2, -2 Z W]], C_w = [0, I], and H3, H4 as the
    implementation applies them (H3/gamma in A; gamma = 1 for Kim). Input
    eps_v = J nu~, output z~ = C x~ = H4 y~ - gamma b~ (F&S (33)). Per DOF this is
    the loop of :func:`lookout.analysis.passive.error_loop`, whose SPR
    :func:`lookout.analysis.passive.check_spr` checks.

    ``extra_position_gain`` (shape (3,), 1/s), if given, is added to H2, as the
    switching term does inside its boundary layer (Kbar/eps).
    """
    passive, _, _ = _parts(observer)
    extra = np.zeros(3) if extra_position_gain is None else np.asarray(extra_position_gain, float)
    gamma = float(passive.lyapunov_weight)
    w0 = np.broadcast_to(np.asarray(passive.wave_frequency, float), (3,))
    zeta = np.broadcast_to(np.asarray(passive.wave_damping, float), (3,))
    I, Z = np.eye(3), np.zeros((3, 3))
    Aw = np.block([[Z, I], [-np.diag(w0**2), -np.diag(2.0 * zeta * w0)]])
    Cw = np.hstack([Z, I])
    H1 = passive.wave_injection_matrix()
    H2 = passive.position_injection_matrix() + np.diag(extra)
    H3 = np.diag(np.asarray(passive.bias_injection_gain, float)) / gamma
    H4 = np.diag(np.asarray(passive.velocity_injection_gain, float))
    Tinv = np.diag(1.0 / np.asarray(passive.bias_time_constant, float))
    A = np.block(
        [
            [Aw - H1 @ Cw, -H1, np.zeros((6, 3))],
            [-H2 @ Cw, -H2, Z],
            [-H3 @ Cw, -H3, -Tinv],
        ]
    )
    B = np.vstack([np.zeros((6, 3)), I, Z])
    C = np.hstack([H4 @ Cw, H4, -gamma * I])
    return A, B, C


# -- eigenvalues ---------------------------------------------------------------------


@dataclass
class Mode:
    """One eigenvalue (or complex pair) of the error system."""

    real: float  # 1/s
    frequency: float  # rad/s, >= 0 (the imaginary part of the pair's upper member)
    period: float  # s, inf for a real eigenvalue
    e_folding_time: float  # s, 1/|real|: growth (real > 0) or decay time
    axis: str  # the DOF index (surge/sway/yaw) that carries most of the mode


@dataclass
class EigenvalueReport:
    """Eigenvalues of an error-system matrix and the stability inequality.

    ``stability`` is ``max Re lambda < 0`` with an absolute tolerance of
    ``1e-8 * max |lambda|``: ``holds`` (every real part below -tolerance), ``fails``
    (one above +tolerance) or ``unverified`` (the largest real part lies within the
    tolerance of zero, where rounding decides).
    """

    eigenvalues: np.ndarray
    stability: Inequality
    unstable: list[Mode]
    slowest: Mode

    @property
    def verdict(self) -> Verdict:
        """The stability inequality's verdict."""
        return self.stability.verdict

    def to_dict(self) -> dict:
        """The eigenvalues and modes (the verdict is the inequality's)."""
        return {
            "eigenvalues_real": [float(v.real) for v in self.eigenvalues],
            "eigenvalues_imag": [float(v.imag) for v in self.eigenvalues],
            "unstable": [asdict(m) for m in self.unstable],
            "slowest": asdict(self.slowest),
        }


def _axis_scaling(matrix: np.ndarray) -> np.ndarray:
    """Diagonal similarity that brings the bias errors to the scale of the others."""
    n = matrix.shape[0]
    scale = np.ones(n)
    if n == 15:
        # b~ enters nu~' through M^-1 J^T, y~ through M^-1 J^T H4: measure b~ in
        # units of the position error it balances (b~ / H4), as kyp_certificate does
        coupling = np.abs(matrix[12:15, 9:12]).max(axis=0)
        position = np.abs(matrix[12:15, 6:9]).max(axis=0)
        good = (coupling > 0) & (position > 0)
        scale[9:12][good] = position[good] / coupling[good]
    return scale


def eigenvalue_report(matrix: npt.ArrayLike, *, heading: float = 0.0, relative_tolerance: float = 1e-8) -> EigenvalueReport:
    """Eigenvalues of an error-system matrix, its unstable modes and the stability inequality.

    The matrix is first scaled (bias errors in units of position) and, for the
    15-state error system, its Earth-fixed states are rotated into body axes with
    J(heading)^T; the similarity changes no eigenvalue. Each mode is attributed to
    the DOF (surge, sway, yaw: index 0, 1, 2 of each block of three states) with
    the largest share of the transformed eigenvector's squared magnitude. Pass the
    ``heading`` that :func:`error_system` was built with.
    """
    matrix = np.asarray(matrix, float)
    n = matrix.shape[0]
    if matrix.shape != (n, n) or not np.isfinite(matrix).all():
        raise check.ParameterError("matrix", f"matrix must be square and finite; got shape {matrix.shape}")
    scale = _axis_scaling(matrix)
    scaled = matrix / scale[None, :] * scale[:, None]
    if n == 15:
        # Earth-fixed xi1~, xi2~, eta~, b~ in body axes: x_b = T x, T = diag(J^T x 4, I)
        J = _rotation(float(heading))
        T = scipy.linalg.block_diag(J.T, J.T, J.T, J.T, np.eye(3))
        scaled = T @ scaled @ T.T
    values, vectors = np.linalg.eig(scaled)
    order = np.lexsort((-values.imag, -values.real))
    values, vectors = values[order], vectors[:, order]
    tolerance = relative_tolerance * max(float(np.abs(values).max()), np.finfo(float).tiny)
    stability = Inequality.check(
        "max Re lambda",
        "max Re lambda(A_e) < 0",
        float(values.real.max()),
        "<",
        0.0,
        units="1/s",
        source=SOURCE_ERROR_SYSTEM,
        tolerance=tolerance,
    )

    def mode(k: int) -> Mode:
        lam = values[k]
        share = np.abs(vectors[:, k]) ** 2
        per_axis = [share[i::3].sum() for i in range(3)] if n % 3 == 0 else [1.0, 0.0, 0.0]
        frequency = abs(float(lam.imag))
        return Mode(
            real=float(lam.real),
            frequency=frequency,
            period=2.0 * math.pi / frequency if frequency > 0 else math.inf,
            e_folding_time=1.0 / abs(float(lam.real)) if lam.real != 0 else math.inf,
            axis=DOF[int(np.argmax(per_axis))],
        )

    unstable = [mode(k) for k in range(n) if values[k].real > tolerance and values[k].imag >= 0]
    return EigenvalueReport(eigenvalues=values, stability=stability, unstable=unstable, slowest=mode(int(np.argmax(values.real))))


# -- KYP (14) ------------------------------------------------------------------------


def kyp_14(observer: SlidingModeObserver | PassiveObserver, *, frequencies: npt.ArrayLike | None = None) -> Condition:
    """Check Kim's (14), P A + A^T P = -Q, B^T P = C with P, Q > 0, for Sigma_2.

    The gains are diagonal, so Sigma_2 splits into three SISO loops and (14) holds
    if and only if each loop is SPR (:func:`lookout.analysis.passive.check_spr`,
    which also builds and verifies each loop's certificate). When all three hold,
    the certificates are assembled block-wise into the 12x12 P and Q and (14) is
    verified again on the full matrices of :func:`sigma2`. The switching term does
    not enter (14): Kbar multiplies sat, not the linear part.

    Returns
    -------
    Condition
        ``kyp_14``: the per-DOF inequalities of the SPR checks and, when all hold, P > 0,
        Q > 0 and the residuals of (14) on the assembled matrices (``unverified``, not
        ``fails``, when these fail: the per-DOF certificates exist). ``quantities``: P, Q
        (None unless assembled), the residuals and per DOF the numbers of its SPR check.
    """
    passive, _, _ = _parts(observer)
    per_dof = check_spr(passive, frequencies=frequencies)
    inequalities = [item for r in per_dof for item in r.inequalities]
    informational = [item for r in per_dof for item in r.informational]
    quantities: dict[str, Any] = {
        "P": None,
        "Q": None,
        "residual_lyapunov": None,
        "residual_output": None,
        "per_dof": {
            dof: {k: v for k, v in r.quantities.items() if k != "certificate"} | {"verdict": r.verdict, "reason": r.reason}
            for dof, r in zip(DOF, per_dof)
        },
    }

    def condition(reason: str) -> Condition:
        return Condition(
            "kyp_14", "(14)", "KYP for Sigma_2: P A + A^T P = -Q, B^T P = C, P, Q > 0", SOURCE_14, inequalities, reason, informational, quantities
        )

    failing = [(dof, r) for dof, r in zip(DOF, per_dof) if r.verdict == Verdict.FAILS]
    if failing:
        return condition("not SPR, so no P, Q exist: " + "; ".join(f"{dof}: {r.reason}" for dof, r in failing))
    unverified = [(dof, r) for dof, r in zip(DOF, per_dof) if r.verdict != Verdict.HOLDS]
    if unverified:
        return condition("; ".join(f"{dof}: {r.reason}" for dof, r in unverified))
    A, B, C = sigma2(passive)
    P = np.zeros((12, 12))
    for i, report in enumerate(per_dof):
        index = [i, 3 + i, 6 + i, 9 + i]
        P[np.ix_(index, index)] = np.asarray(report.quantities["certificate"]["P"])
    P = 0.5 * (P + P.T)
    Q = -(P @ A + A.T @ P)
    Q = 0.5 * (Q + Q.T)
    residual_lyapunov = float(np.abs(P @ A + A.T @ P + Q).max() / np.abs(Q).max())
    residual_output = float(np.abs(B.T @ P - C).max() / np.abs(C).max())
    min_p, min_q = _normalized_min_eig(P), _normalized_min_eig(Q)
    quantities.update(P=P, Q=Q, residual_lyapunov=residual_lyapunov, residual_output=residual_output)
    check = functools.partial(Inequality.check, "Sigma_2", units="", source=SOURCE_14, failure=Verdict.UNVERIFIED)
    inequalities += [
        check("P > 0: lambda_min(S P S) > 0, S = diag(P)^-1/2", min_p, ">", 0.0),
        check("Q > 0: lambda_min(S Q S) > 0, S = diag(Q)^-1/2", min_q, ">", 0.0),
        check("B^T P = C: max|B^T P - C| / max|C| < 1e-8", residual_output, "<", 1e-8),
        check("P A + A^T P = -Q: max|P A + A^T P + Q| / max|Q| < 1e-8", residual_lyapunov, "<", 1e-8),
    ]
    if all(item.holds for item in inequalities):
        return condition("each DOF is SPR; the assembled P, Q satisfy (14) on the full Sigma_2")
    return condition(
        f"per-DOF certificates hold but the assembled ones do not verify (min eig P {min_p:.2g}, "
        f"Q {min_q:.2g}, B^T P - C residual {residual_output:.2g})"
    )


#: The parameter of :meth:`~lookout.observers.SlidingModeObserver.design` that each
#: inequality of the tuning rule (48) asks to change, by its relation's start.
_RULE_48_PARAMETERS = (
    ("1/T", "bias_time_constant", "larger"),
    ("lambda/kappa", "bias_injection_gain", "smaller"),
    ("w_o", "cutoff_frequency", "larger"),
)


def _loop_numbers(passive: PassiveObserver) -> tuple:
    """The numbers (14) depends on: the wave model, K1, K2, Kappa, Lambda, T, gamma."""
    fields = (
        "wave_frequency",
        "wave_damping",
        "wave_injection_gain",
        "position_injection_gain",
        "velocity_injection_gain",
        "bias_injection_gain",
        "bias_time_constant",
        "lyapunov_weight",
    )
    return tuple(tuple(np.ravel(np.asarray(getattr(passive, name), dtype=float)).tolist()) for name in fields)


#: :func:`_refusal` per set of gains (:func:`_loop_numbers`): a sweep builds the same observer many times.
_REFUSALS: dict[tuple, tuple[str, str]] = {}


def _refusal(passive: PassiveObserver) -> tuple[str, str]:
    """The parameter to change and the one-line refusal of :func:`require_kyp_14` for
    these gains (("", "") when (14) holds)."""
    condition = kyp_14(passive)
    if condition.holds:
        return "", ""
    per_dof = condition.quantities["per_dof"]
    dof, numbers_of_dof = next((d, q) for d, q in per_dof.items() if q["verdict"] != Verdict.HOLDS)
    index = DOF.index(dof)
    rule = check_tuning_rule(passive)
    broken = [item for item in rule.inequalities if item.name == dof and not item.holds]
    if broken:
        item = broken[0]
        parameter, advice = next((name, advice) for start, name, advice in _RULE_48_PARAMETERS if item.relation.startswith(start))
        why = f"Fossen & Strand's (48) fails: {item.relation}: {number(item.left, 4)} {item.comparison} {number(item.right, 4)} rad/s"
    else:
        # the factor of h = hB h0 that lags more where Re h is negative (where the phase
        # comes nearest -90 deg below 10 w_c, when no certificate was found) takes the blame
        negative = numbers_of_dof["min_real_part"] <= 0
        w = numbers_of_dof["min_real_part_frequency" if negative else "min_phase_frequency_in_band"]
        response = transfer_functions(passive, [w])
        lag_bias = float(np.degrees(np.angle(response["hB"][0, index])))
        lag_filter = float(np.degrees(np.angle(response["h0"][0, index])))
        parameter, advice = ("bias_injection_gain", "smaller") if lag_bias < lag_filter else ("cutoff_frequency", "larger")
        why = f"at w = {number(w, 4)} rad/s hB lags {lag_bias:.1f} deg and h0 {lag_filter:.1f} deg"
    return parameter, f"{parameter} must be {advice}: the gains violate Kim (2002)'s (14) ({dof}: {numbers_of_dof['reason']}; {why})"


def require_kyp_14(observer: SlidingModeObserver | PassiveObserver) -> None:
    """Refuse gains that violate Kim (2002)'s (14): a one-line ``ValueError`` naming the
    parameter of :meth:`~lookout.observers.SlidingModeObserver.design` to change.

    (14) is checked by :func:`kyp_14` (``holds`` only with verified P, Q; a loop that is
    SPR on the grid without a verified certificate is refused too). The parameter named
    is the one of the first inequality of the tuning rule (48) that fails in the first
    DOF where (14) does (:func:`lookout.analysis.passive.check_tuning_rule`: 1/T << H3/H4
    -> ``bias_time_constant``, H3/H4 < w_o -> ``bias_injection_gain``, w_o < w_c ->
    ``cutoff_frequency``); when (48) holds there, the factor of h = hB h0 that lags more
    where Re h is smallest (or, when Re h > 0 on the grid but no certificate verifies,
    where h's phase comes nearest -90 deg below 10 w_c): hB (``bias_injection_gain``)
    or h0 (``cutoff_frequency``). Observers built under ``jit`` (traced gains) are not checked.
    """
    import jax

    passive = observer.passive if _is_sliding_mode(observer) else observer
    if not isinstance(passive, PassiveObserver):
        raise check.ParameterError("observer", f"observer must be a SlidingModeObserver or a PassiveObserver; got {type(observer).__name__}")
    if not all(check.is_concrete(leaf) for leaf in jax.tree_util.tree_leaves(passive)):
        return  # built under jit or vmap: checked where the gains are concrete
    key = _loop_numbers(passive)
    if key not in _REFUSALS:
        if len(_REFUSALS) >= 256:
            _REFUSALS.clear()
        _REFUSALS[key] = _refusal(passive)
    parameter, refusal = _REFUSALS[key]
    if refusal:
        raise check.ParameterError(parameter, refusal)


# -- (17): the switching gain a bounded disturbance requires ------------------------


def _impulse_response(mass: np.ndarray, damping: np.ndarray):
    """g(t) = expm(-M^-1 D t) M^-1, vectorized over t, and the slowest and fastest
    decay rates. Evaluated in modal form when -M^-1 D has a well-conditioned
    eigenvector basis (distinct eigenvalues), else by expm."""
    Minv = np.linalg.inv(mass)
    A = -Minv @ damping
    values, vectors = np.linalg.eig(A)
    rates = -values.real
    if not rates.min() > 0:
        raise ValueError("M^-1 D must have eigenvalues with positive real parts (a damped vessel)")
    if np.linalg.cond(vectors) < 1e8:
        left = vectors
        right = np.linalg.solve(vectors, Minv.astype(complex))

        def g(t):
            t = np.atleast_1d(np.asarray(t, float))
            modal = np.exp(values[None, :] * t[:, None])
            out = np.einsum("ji,ti,ik->tjk", left, modal, right)
            return out.real
    else:

        def g(t):
            t = np.atleast_1d(np.asarray(t, float))
            return scipy.linalg.expm(A[None] * t[:, None, None]) @ Minv

    return g, float(rates.min()), float(rates.max())


def peak_to_peak_gains(
    mass: npt.ArrayLike, damping: npt.ArrayLike, *, method: str = "quad", decay_lengths: float = 60.0, steps_per_time_constant: float = 500.0
) -> np.ndarray:
    """||g_jk||_1 = int_0^inf |g_jk(t)| dt for the impulse response g of (M s + D)^-1.

    The peak-to-peak (L1) gain: a force bounded componentwise by |f_k(t)| <= F_k
    gives a velocity |nu_j(t)| <= sum_k ||g_jk||_1 F_k for all t (from rest; the
    bound is tight for the worst sign pattern of f). Units: s/kg (surge, sway),
    1/(kg m) and s/(kg m^2) for the yaw entries.

    Parameters
    ----------
    mass, damping : array_like, shape (3, 3)
    method : {"quad", "sum"}
        ``"quad"``: adaptive quadrature (scipy.integrate.quad) of |g_jk| between its
        sign changes (located on a grid, refined by brentq). ``"sum"``: the
        trapezoidal sum of |g_jk| on a uniform grid with ``steps_per_time_constant``
        steps per fastest time constant, g propagated exactly from step to step (an
        independent check; relative error of order (1/steps)^2).
    decay_lengths : float
        Horizon in units of the slowest time constant (the tail beyond is below
        e^-decay_lengths relative).

    Returns
    -------
    ndarray, shape (3, 3)
        For a first-order (decoupled) axis, ||g_jj||_1 = 1/d_jj exactly.
    """
    mass, damping = np.asarray(mass, float), np.asarray(damping, float)
    g, slow, fast = _impulse_response(mass, damping)
    horizon = decay_lengths / slow
    n = mass.shape[0]
    if method == "sum":
        # trapezoidal sum on t_m = m dt, g(t_m) by exact propagation: powers of
        # expm(A dt) in chunks of ``chunk`` steps, so the loop is over chunks
        dt = 1.0 / (steps_per_time_constant * fast)
        chunk = 1000
        chunks = int(math.ceil(horizon / (dt * chunk)))
        step = scipy.linalg.expm(-np.linalg.solve(mass, damping) * dt)
        powers = np.empty((chunk, n, n))
        powers[0] = np.eye(n)
        for m in range(1, chunk):
            powers[m] = step @ powers[m - 1]
        start = np.linalg.inv(mass)
        total = -0.5 * np.abs(start)  # trapezoid: half weight at t = 0
        for _ in range(chunks):
            block = powers @ start
            total += np.abs(block).sum(axis=0)
            start = step @ block[-1]
        return total * dt  # the end point's weight is below e^-decay_lengths
    if method != "quad":
        raise check.ParameterError("method", f"method must be 'quad' or 'sum'; got {method!r}")
    grid = np.concatenate([[0.0], np.geomspace(1e-3 / fast, horizon, 4000)])
    values = g(grid)
    negligible = 1e-13 * np.abs(values).max()
    out = np.zeros((n, n))
    for j in range(n):
        for k in range(n):
            sampled = values[:, j, k]
            if not np.abs(sampled).max() > negligible:
                continue  # a decoupled pair of axes: g_jk = 0 up to rounding

            def entry(t, j=j, k=k):
                return g(t)[0, j, k]

            cuts = [0.0]
            signs = np.sign(sampled)
            for crossing in np.flatnonzero(signs[:-1] * signs[1:] < 0):
                cuts.append(scipy.optimize.brentq(entry, grid[crossing], grid[crossing + 1], xtol=1e-14 * horizon))
            cuts.append(horizon)
            integral = 0.0
            for a, b in zip(cuts[:-1], cuts[1:]):
                value, _ = scipy.integrate.quad(entry, a, b, limit=200, epsabs=0.0, epsrel=1e-11)
                integral += abs(value)
            out[j, k] = integral
    return out


def _required(gains: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    velocity = gains @ bound
    planar = math.hypot(velocity[0], velocity[1])
    return velocity, np.array([planar, planar, velocity[2]])


def disturbance_coverage(vessel: DPVessel, switching_gain: npt.ArrayLike, *, gains: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
    """The largest force bound F_k (N, N, N m) that ``switching_gain`` covers in (17),
    per axis k with the other axes' forces zero, and which Kbar axis limits it.

    ``rho(F e_k) = F rho(e_k)`` is linear in F, so F_k = min_i Kbar_i / rho_i(e_k).
    """
    kbar = np.asarray(switching_gain, float).reshape(3)
    if gains is None:
        gains = peak_to_peak_gains(vessel.mass_matrix, vessel.damping_matrix)
    coverage, limited = np.zeros(3), []
    for k in range(3):
        _, per_unit = _required(gains, np.eye(3)[k])
        with np.errstate(divide="ignore"):
            ratios = np.where(per_unit > 0, kbar / np.where(per_unit > 0, per_unit, 1.0), np.inf)
        i = int(np.argmin(ratios))
        coverage[k] = ratios[i]
        limited.append(DOF[i] if math.isfinite(ratios[i]) else "none")
    return coverage, limited


def switching_gain_required(
    vessel: DPVessel, disturbance_bound: npt.ArrayLike, *, observer: SlidingModeObserver | PassiveObserver | None = None
) -> Condition:
    """The switching gain rho = diag(Kbar) that (17) requires for a bounded disturbance.

    Kim's (15)–(17), corrected (derivations K2): the velocity error splits as
    nu~ + nu~_d, where nu~_d is the response of (M s + D)^-1 to the unmodelled
    body-fixed force f = E_nu w_nu. In V' of (17) it enters as 2 z~^T J nu~_d, which
    the switching term -2 z~^T Theta sat(z~) dominates outside the layer when, for
    a componentwise sat,

        rho_i >= sup_t |(J nu~_d)_i|          (not "||Theta|| >= ||nu~_d||" as printed)

    For |f_k(t)| <= F_k, |nu~_d,j| <= b_j = sum_k ||g_jk||_1 F_k
    (:func:`peak_to_peak_gains`); J rotates the planar part, so over all headings
    |(J nu~_d)_1,2| <= sqrt(b_1^2 + b_2^2), and (J nu~_d)_3 = nu~_d,3. Hence
    rho_1 = rho_2 = sqrt(b_1^2 + b_2^2) and rho_3 = b_3. The bound is sufficient, and
    linear in F.

    Caveats, stated as the result is used: E_nu w_nu is read as a bounded force
    (Kim's white noise has no finite peak); the implementation uses sat (not sign)
    and the measured y~ (not z~ = H4 y~ - b~, which contains the unmeasured bias
    error), so even with rho large enough the result is ultimate boundedness (a
    layer of width of order eps, plus a term 2 sum rho_i |b~_i|), not the asymptotic
    stability claimed; and the argument presupposes the KYP conditions (14).

    Parameters
    ----------
    vessel : DPVessel
        M and D of the plant (= the observer's model).
    disturbance_bound : array_like, shape (3,)
        F (N, N, N m), >= 0.
    observer : SlidingModeObserver, optional
        When given, its Kbar is compared with rho: one inequality per axis,
        ``Kbar_i >= rho_i`` (m/s, m/s, rad/s). Without it there is nothing to compare
        and the verdict is ``unverified``.

    Returns
    -------
    Condition
        ``switching_gain_17``. ``quantities``: ``disturbance_bound`` F,
        ``peak_to_peak_gain`` ||g_jk||_1 of (M s + D)^-1, ``velocity_bound``
        b_j >= sup_t |nu~_d,j| (m/s, m/s, rad/s), ``required_gain`` rho and, with an
        observer, ``switching_gain`` Kbar.
    """
    bound = np.asarray(disturbance_bound, float)
    if bound.shape == ():
        bound = np.full(3, float(bound))
    if bound.shape != (3,) or not np.isfinite(bound).all() or np.any(bound < 0):
        raise check.ParameterError("disturbance_bound", f"disturbance_bound must be 3 finite values >= 0 (N, N, N m); got {disturbance_bound!r}")
    gains = peak_to_peak_gains(vessel.mass_matrix, vessel.damping_matrix)
    velocity, required = _required(gains, bound)
    quantities = {
        "disturbance_bound": bound,
        "disturbance_units": list(FORCE_UNITS),
        "peak_to_peak_gain": gains,
        "velocity_bound": velocity,
        "required_gain": required,
        "gain_units": list(VELOCITY_UNITS),
    }
    inequalities, reason = [], "no switching gain to compare with rho"
    if observer is not None:
        _, kbar, _ = _parts(observer)
        quantities["switching_gain"] = kbar
        relations = ("Kbar_1 >= rho_1 = sqrt(b_1^2 + b_2^2)", "Kbar_2 >= rho_2 = sqrt(b_1^2 + b_2^2)", "Kbar_3 >= rho_3 = b_3")
        inequalities = [
            Inequality.check(DOF[i], relations[i], kbar[i], ">=", required[i], units=VELOCITY_UNITS[i], source=SOURCE_17) for i in range(3)
        ]
        reason = f"for |f| <= F = ({', '.join(number(v, 3) for v in bound)}) N, N, N m"
    return Condition(
        "switching_gain_17", "(17)", "switching gain dominates a bounded disturbance", SOURCE_17, inequalities, reason, quantities=quantities
    )


# -- the whole check -----------------------------------------------------------------


def _stability(key: str, title: str, report: EigenvalueReport) -> Condition:
    """An error system's stability as a condition, its unstable modes in the reason."""
    if report.unstable:
        reason = "; ".join(
            f"{m.axis} {m.real:+.3g} +- {m.frequency:.4g}j 1/s: grows x e in {m.e_folding_time:.3g} s, period {number(m.period, 3)} s"
            for m in report.unstable
        )
    elif report.verdict == Verdict.HOLDS:
        m = report.slowest
        reason = f"slowest mode {m.real:+.3g} +- {m.frequency:.4g}j 1/s ({m.axis})"
    else:
        reason = "the largest real part lies within the tolerance of zero: rounding decides"
    return Condition(key, "(8)-(10)", title, SOURCE_ERROR_SYSTEM, (report.stability,), reason, quantities=report.to_dict())


def check_kim_2002(
    observer: SlidingModeObserver | PassiveObserver, vessel: DPVessel, *, disturbance_bound: npt.ArrayLike | None = None, heading: float = 0.0
) -> Report:
    """Check the conditions of Kim (2002), Section 3.2, for ``observer``.

    The conditions, by key:

    * ``tuning_rule_48``: Fossen & Strand's rule (48) for ``observer.passive``
      (:func:`lookout.analysis.passive.check_tuning_rule`);
    * ``kyp_14``: (14) for Sigma_2 (:func:`kyp_14`): "holds" only with verified P, Q;
    * ``error_system_stable_without_switching``: the 15-state error system with
      Kbar = 0 (:func:`error_system`, :func:`eigenvalue_report`);
    * ``error_system_stable_inside_layer``: the same with H2 + Kbar/eps;
    * ``switching_gain_17``: Kbar >= rho for ``disturbance_bound``
      (:func:`switching_gain_required`); not checked without a bound (a note says so).

    The report's ``quantities`` give the gains, eps, the heading and the forces that
    the observer's Kbar covers in (17), one axis at a time (``kbar_coverage``,
    :func:`disturbance_coverage`); its summary the gains, its notes the coverage.

    Parameters
    ----------
    observer : SlidingModeObserver (or PassiveObserver, the Kbar = 0 case)
    vessel : DPVessel
    disturbance_bound : array_like, shape (3,), optional
        Bound F on the unmodelled body-fixed force (N, N, N m).
    heading : float
        Heading of J for the error systems (rad).
    """
    passive, kbar, eps = _parts(observer)
    if _is_sliding_mode(observer):
        gains = observer.gains()
    else:
        gains = {
            "H1": passive.wave_injection_matrix(),
            "H2": passive.position_injection_matrix(),
            "H3": np.diag(np.asarray(passive.bias_injection_gain)),
            "H4": np.diag(np.asarray(passive.velocity_injection_gain)),
            "Kbar": np.zeros((3, 3)),
        }
    kyp = kyp_14(passive)
    conditions = [
        check_tuning_rule(passive),
        kyp,
        _stability(
            "error_system_stable_without_switching",
            "error system stable, Kbar = 0",
            eigenvalue_report(error_system(observer, vessel, heading=heading), heading=heading),
        ),
        _stability(
            "error_system_stable_inside_layer",
            "error system stable inside the layer, H2 + Kbar/eps",
            eigenvalue_report(error_system(observer, vessel, heading=heading, inside_layer=True), heading=heading),
        ),
    ]
    notes = []
    if disturbance_bound is None:
        notes.append("(17) not checked: no bound on the unmodelled force given")
    else:
        conditions.append(switching_gain_required(vessel, disturbance_bound, observer=observer))
    coverage, limited_by = disturbance_coverage(vessel, kbar)
    notes += [f"Kbar covers |f_{DOF[k]}| <= {number(coverage[k], 4)} {FORCE_UNITS[k]} alone (limited by the {limited_by[k]} gain)" for k in range(3)]
    if kyp.verdict != Verdict.HOLDS:
        notes.append("(17) presupposes (14): without P, Q it proves nothing")
    summary = [
        "gains (SI), diagonals per DOF surge, sway, yaw:",
        f"H1 xi1 {numbers(np.diag(gains['H1'][:3]))}",
        f"H1 xi2 {numbers(np.diag(gains['H1'][3:]))}",
        *(f"{name:<6} {numbers(np.diag(gains[name]))}" for name in ("H2", "H3", "H4", "Kbar")),
        f"eps    {numbers(eps)}  (m, m, rad)",
    ]
    quantities = {
        "gains": gains,
        "boundary_layer": eps,
        "heading": float(heading),
        "kbar_coverage": {"force_bound": coverage, "units": list(FORCE_UNITS), "limited_by": limited_by},
    }
    return Report("Kim (2002) sliding-mode observer: conditions of Section 3.2", conditions, quantities, summary, notes)


def kim_2002_observer(
    vessel: DPVessel,
    *,
    # a wave model (LinearWaveModel, JonswapWaves) or None; Any, since the registry takes a
    # part annotated with component classes as the first of them
    waves: Any = None,
    wave_frequency: npt.ArrayLike | None = None,
    wave_damping: npt.ArrayLike = 0.1,
    notch_damping: npt.ArrayLike = 1.0,
    cutoff_frequency: npt.ArrayLike | None = None,
    velocity_injection_gain: npt.ArrayLike | None = None,
    bias_injection_gain: npt.ArrayLike | None = None,
    bias_time_constant: npt.ArrayLike = 1000.0,
    velocity_bandwidth: npt.ArrayLike | None = None,
    switching_gain: npt.ArrayLike = 0.0,
    boundary_layer: npt.ArrayLike = DEFAULT_BOUNDARY_LAYER,
    steps_per_sample: int = 1,
    hold: str = "measurement",
) -> SlidingModeObserver:
    """The sliding-mode observer for ``vessel`` by Kim (2002)'s procedure (the rule
    ``kim-2002`` of the kind ``sliding-mode``): H1, H2 from Fossen & Strand's
    (45)–(47) (Kim's (A.3)), H4 = ``velocity_injection_gain`` and H3 =
    ``bias_injection_gain`` (SI; unless given, inside the tuning rule (48),
    :func:`lookout.observers.passive.tuning_rule_gains`), verified against (14).

    Kim's (14), P A + A^T P = -Q, B^T P = C with P, Q > 0 for Sigma_2 of (9)–(10), is
    what his Lyapunov argument (15)–(17) presupposes. With diagonal gains it holds if
    and only if each DOF's loop h = hB h0 is strictly positive real (Khalil 1996,
    Lemma 6.3), checked with a verified certificate by
    :func:`kyp_14`; gains for which it does not hold
    are refused (:func:`require_kyp_14`), in a
    ``ValueError`` that names the parameter to change.

    (14) is not guaranteed by construction. Re h(jw) > 0 needs the phases of
    hB(jw) = H4 + H3 / (jw + 1/T) and of h0(jw) of (42) to add up to more than
    -90 deg at every w. hB lags by up to 90 deg between its pole 1/T and its zero
    1/T + H3/H4, and below the notch h0 lags by about w (1/w_c + 2 (zeta_n - zeta) / w_o)
    (its first-order expansion at w << w_o with (45)–(47)): the sum stays above
    -90 deg only while hB's lag has died out before h0's builds up, which the rule
    (48), 1/T << H3/H4 < w_o < w_c, asks for without ensuring it. Kim's printed (A.4)
    (H3/H4 = 10 1/s > w_o) give -104.55 deg at 0.094 rad/s on the Northern Clipper;
    the default H3/H4 = sqrt(w_o / T) with T = 10 s gives -104.4 deg at 0.55 rad/s.

    Parameters
    ----------
    vessel : DPVessel
        The observer's vessel model (M, D); in a composition, the plant's unless given.
    waves : LinearWaveModel or JonswapWaves, optional
        The sea to tune for when wave_frequency is not given (in a composition, the plant's).
    wave_frequency : array_like, shape (3,), positive, optional
        The observer's wave frequencies w_oi (rad/s); default the dominating frequency of ``waves``.
    wave_damping : array_like, shape (3,), positive
        The observer's wave damping ratios zeta_i (1).
    notch_damping : array_like, shape (3,), positive
        zeta_ni of the notch filter, Fossen & Strand (45) (1).
    cutoff_frequency : array_like, shape (3,), positive, optional
        w_ci of the low-pass filter (45), above wave_frequency (rad/s); default as the passive observer's.
    velocity_injection_gain : array_like, shape (3,), positive, optional
        Diagonal of H4 (N/m, N/m, N m/rad); default from the tuning rule (48) of the passive observer.
    bias_injection_gain : array_like, shape (3,), positive, optional
        Diagonal of H3 (N/(m s), N/(m s), N m/(rad s)); default from the tuning rule (48).
    bias_time_constant : array_like, shape (3,), positive
        The observer's bias time constants T (s).
    velocity_bandwidth : array_like, shape (3,), positive, optional
        sqrt(H4_i / M_ii) of the default H4 (rad/s); default 0.1 w_o.
    switching_gain : array_like, shape (3,), non-negative
        Kbar = diag(rho_i) (m/s, m/s, rad/s); zero gives the passive observer.
    boundary_layer : array_like, shape (3,), positive
        eps_i (m, m, rad), the width of the saturation's linear zone; default 1 m, 1 m, 0.02 rad.
    steps_per_sample : int, positive
        RK4 steps of predict per sample period.
    hold : {"measurement", "innovation"}
        What predict holds over a sample (as the passive observer's).
    """
    passive = PassiveObserver.design(
        vessel,
        waves=waves,
        velocity_bandwidth=velocity_bandwidth,
        wave_frequency=wave_frequency,
        wave_damping=wave_damping,
        notch_damping=notch_damping,
        cutoff_frequency=cutoff_frequency,
        velocity_injection_gain=velocity_injection_gain,
        bias_injection_gain=bias_injection_gain,
        bias_time_constant=bias_time_constant,
        lyapunov_weight=1.0,
        steps_per_sample=steps_per_sample,
        hold=hold,
    )
    observer = SlidingModeObserver(passive, switching_gain, boundary_layer)
    require_kyp_14(observer)
    return observer
