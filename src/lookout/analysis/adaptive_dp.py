"""Stability conditions of Calugi, Robertsson & Johansson (2003): (22), (57), (58).

The adaptive observer (13)–(15) and the vectorial observer backstepping controller
(24)–(40) for the DP model (1)–(2), ``M nu' + D nu + K eta = tau``, with theta the
unknown entries of M, D, K (theta = m11 in Section V). This module evaluates the
paper's sufficient conditions on concrete numbers, read as derived (and checked
against ``derivations-kim-calugi-2003.md``, C5):

Observer, V = 1/2 (eta~'eta~ + nu~'M nu~ + theta~'Gamma^-1 theta~) (17)::

    V' = -eta~'K1 eta~ - nu~'(M K2 + D) nu~ + eta~'(J - K') nu~        (19)
       <= -sigma1 |eta~|^2 - (sigma2 + D_min) |nu~|^2 + (1 + K_max) |eta~||nu~|

    sigma1 = lambda_min(sym K1),  sigma2 = lambda_min(sym(M K2))      (20)
    D_min <= lambda_min(sym D),    K_max >= ||K||_2  (||J|| = 1)

(sym X = (X + X')/2; x'Xx = x' sym(X) x is what the proof bounds). The 2x2 form
[[sigma1, -(1+K_max)/2], [-(1+K_max)/2, sigma2 + D_min]] is positive definite iff
sigma1 > (1 + K_max)^2 / (4 (sigma2 + D_min)) with sigma2 + D_min > 0; the paper
prints the second part as sigma2 > 0 (22), sufficient since D_min > 0 (10).

Closed loop, V of (47): completing the squares of Appendix B (69) gives
``-z'D_z z + z'W1 eta~ + z'W2 nu~ <= (g1 |eta~|^2 + g2 |nu~|^2) / 4`` with
g1 = sum_1..6 1/d_i, g2 = sum_4..6 1/d_i (53) (with the controller's coupling
weight P1 = diag(p_i), V = 1/2 (z1'P1 z1 + |z2|^2), the first three terms of g1
become p_i/d_i; P1 = 1 as printed), hence

    (57) sigma1 > g1/4 + (1 + K_max)^2 / (4 (sigma2 + D_min - g2/4))
    (58) sigma2 > max(0, g2/4 - D_min)

The model bounds (9)–(11) are read as the quantities the proof uses
(:func:`model_bounds`): the printed ``D_min < ||D||`` is not a lower bound on
nu~'D nu~ (the induced norm of the Calugi D is 4.19e8, its lambda_min(sym D) is
5.024e4). M is unknown (theta), so sigma2 and D_min are taken in the worst case
over the theta box: each is lambda_min of a matrix affine in theta, a concave
function of theta, so its minimum over the box is attained at a vertex (for one
unknown: an end point of [lower, upper]); M_max, D_max, K_max (convex norms) are
maxima at vertices too. The vertices are enumerated exactly.

Findings for the printed parameters (59) with theta = m11 known (tested in
tests/test_adaptive_dp_conditions.py): sigma1 = 1e-3 1/s, sigma2 = 1e-3 m11 =
5312.2 kg/s, D_min = 5.024e4 kg/s, K_max = 0, g1 = 60, g2 = 30 1/s. (22) holds
(1e-3 > 4.50e-6, factor 222), (58) holds (5312 > max(0, 7.5 - 50240) = 0), (57)
fails: 1e-3 > 15 + 4.50e-6 is false by a factor 6.67e-5 (the right side is 1.5e4
times the left); the failure is g1/4 = 15 1/s against sigma1 = 1e-3 1/s, the
same units, so no D_min reading in [0, lambda_min(sym D)] changes it.

Weights and units. V adds eta~'eta~ (m^2) to nu~'M nu~ (J) and z'z (m^2 and
m^2/s^2): the conditions carry implicit unit weights (1 kg/s^2, 1 kg), and their
SI numbers depend on that choice; the margins of (22) and (58) are largely an
artefact of M ~ 1e6 kg in SI. In (57), the d1..3 terms of g1 (D1 = d_i |k_i|^2,
so d_i in s) compare 1/s with 1/s and alone give 7.5 1/s against 1e-3 1/s: no
change of units rescues (57) as printed (the d4..6 terms carry mixed units, as
Omega2 mixes m/s and 1/s). The relative weight of z'z and eta~'eta~ is, however,
a free dimensionless choice: weighting z'z in V (47) by
w_z > 0 (a valid Lyapunov function for the same closed loop: the observer error
terms of V' do not depend on z, and z'Ez = 0 for any scalar weight) multiplies
g1 and g2 by w_z, so (57)–(58) hold for every w_z below a bound
(:func:`z_weight_bound`) whenever (22) holds strictly: the printed gains are
outside the region that (47) proves, not outside every quadratic proof
(w_z < 6.6e-5 proves them). The report gives both.

Gains that satisfy (57)–(58) as printed (:func:`satisfying_gains`): with K1 kept,
d4..6 > 3/(4 sigma1) = 750 s, so D2 >= 750 v_hat^2 (210 1/s at 0.5 m/s, not
realizable with a 0.1 s controller); at a design speed of 0.5 m/s the chosen set
is K1 = 0.05 I, d = (320, 320, 320, 18, 18, 18) s ((57) by a factor 1.14, fastest
loop rate 4.6 1/s); at 0.05 m/s K1 = 1e-3 I is kept.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.optimize

from lookout import _validation as check
from lookout._json import json_safe as _json_safe
from lookout.analysis.conditions import TOLERANCE, Condition, Inequality, Report, Verdict, number, numbers
from lookout.models.vessel import DPVessel

#: The unknown parameter of Section V: theta = m11.
M11 = (("M", 0, 0),)

#: Unknown entries of M, D, K: (matrix, row, column), 0-based.
_Entries = Iterable[tuple[str, int, int]]

#: The paper, as each check cites it.
PAPER = "Calugi et al. (2003)"


# -- inputs ----------------------------------------------------------------------------


def _sym(matrix: np.ndarray) -> np.ndarray:
    return 0.5 * (matrix + matrix.T)


def _gain_matrix(name: str, value) -> np.ndarray:
    """A 3x3 gain from a scalar, a 3-vector (the diagonal) or a 3x3 matrix."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = np.full(3, float(array))
    if array.shape == (3,):
        array = np.diag(array)
    if array.shape != (3, 3):
        raise check.ParameterError(check.key(name), f"{name} must be a scalar, a 3-vector (diagonal) or a 3x3 matrix; got shape {array.shape}")
    if not np.isfinite(array).all():
        raise check.ParameterError(check.key(name), f"{name} must be finite; got {array.tolist()}")
    return array


def _k1(value) -> np.ndarray:
    K1 = _gain_matrix("K1", value)
    smallest = float(np.linalg.eigvalsh(_sym(K1))[0])
    if not smallest > 0:
        raise ValueError(f"K1 must be positive definite; lambda_min(sym K1) = {smallest:.3g} 1/s")
    return K1


def _weights(value) -> np.ndarray:
    d = np.asarray(value, dtype=float)
    if d.ndim == 0:
        d = np.full(6, float(d))
    if d.shape != (6,) or not np.isfinite(d).all() or np.any(d <= 0):
        shown = d.tolist() if d.size <= 6 else f"shape {d.shape}"
        raise check.ParameterError("d", f"d must be 6 positive finite values d1..d6 (s); got {shown}")
    return d


def _positive3(name: str, value) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = np.full(3, float(array))
    if array.shape != (3,) or not np.isfinite(array).all() or np.any(array <= 0):
        raise check.ParameterError(check.key(name), f"{name} must be a positive scalar or 3 positive values; got {np.ravel(array).tolist()}")
    return array


def _unknown(unknown) -> tuple[tuple[str, int, int], ...]:
    out = []
    for item in unknown:
        try:
            name, i, j = item
            i, j = int(i), int(j)
        except (TypeError, ValueError):
            raise check.ParameterError("unknown", f"unknown must be entries (matrix, row, column); got {item!r}") from None
        if name not in ("M", "D", "K") or not (0 <= i < 3 and 0 <= j < 3):
            raise check.ParameterError("unknown", f"unknown entries must be ('M'|'D'|'K', row 0..2, column 0..2); got {item!r}")
        out.append((name, i, j))
    return tuple(out)


def _model(vessel: DPVessel) -> dict[str, np.ndarray]:
    if not isinstance(vessel, DPVessel):
        raise check.ParameterError("vessel", f"vessel must be a DPVessel; got {type(vessel).__name__}")
    return {
        "M": np.array(vessel.mass_matrix, dtype=float),
        "D": np.array(vessel.damping_matrix, dtype=float),
        "K": np.array(vessel.stiffness_matrix, dtype=float),
    }


def _entry_name(entry: tuple[str, int, int]) -> str:
    name, i, j = entry
    return f"{name.lower()}{i + 1}{j + 1}"


def _set(matrices: dict[str, np.ndarray], entry: tuple[str, int, int], value: float) -> None:
    name, i, j = entry
    matrices[name][i, j] = value
    if name == "M":  # a mass matrix stays symmetric: m_ij and m_ji are one parameter
        matrices[name][j, i] = value


def _vertices(vessel: DPVessel, theta_bounds, unknown) -> tuple[list[tuple[np.ndarray, dict]], np.ndarray | None, np.ndarray]:
    """The model at each vertex of the theta box: [(theta, {M, D, K})], the box, theta_true."""
    base = _model(vessel)
    unknown = _unknown(unknown)
    true = np.array([base[n][i, j] for n, i, j in unknown])
    if theta_bounds is None:
        return [(true, base)], None, true
    box = np.asarray(theta_bounds, dtype=float)
    if box.shape == (2,) and len(unknown) == 1:
        box = box[None, :]
    if box.shape != (len(unknown), 2) or not np.isfinite(box).all() or np.any(box[:, 0] > box[:, 1]):
        raise check.ParameterError(
            "theta_bounds",
            f"theta_bounds must be [lower, upper] per unknown entry ({len(unknown)}), finite, "
            f"lower <= upper; got {np.asarray(theta_bounds).tolist()}",
        )
    outside = [(_entry_name(e), t) for e, t, (lo, hi) in zip(unknown, true, box) if not lo <= t <= hi]
    if outside:
        names = ", ".join(f"{n} = {t:.6g}" for n, t in outside)
        raise check.ParameterError("theta_bounds", f"theta_bounds must contain the vessel's (true) value: {names} is outside")
    if len(unknown) > 12:
        raise check.ParameterError("theta_bounds", f"theta_bounds: at most 12 unknown entries (2^n vertices); got {len(unknown)}")
    out = []
    for corner in itertools.product(*box):
        theta = np.array(corner, dtype=float)
        matrices = {k: v.copy() for k, v in base.items()}
        for entry, value in zip(unknown, theta):
            _set(matrices, entry, value)
        smallest = float(np.linalg.eigvalsh(_sym(matrices["M"]))[0])
        if not smallest > 0:
            raise check.ParameterError(
                "theta_bounds", f"theta_bounds: M is not positive definite at theta = {theta.tolist()} (lambda_min {smallest:.3g}); narrow the bounds"
            )
        out.append((theta, matrices))
    return out, box, true


# -- (9)-(11) --------------------------------------------------------------------------


@dataclass(frozen=True)
class ModelBounds:
    """The constants of (9)–(11) as the proofs use them, worst case over the theta box.

    Attributes (SI; yaw entries mix in m and rad as the paper's norms do)
    ----------
    mass_min : float
        M_min = min_theta lambda_min(M) (kg): nu~'M nu~ >= M_min |nu~|^2, so V of
        (17)/(47) is positive definite (needs > 0, (9)). Not in (22), (57), (58).
    mass_max : float
        M_max = max_theta lambda_max(M) = ||M||_2 (kg): V is decrescent.
    damping_min : float
        D_min = min_theta lambda_min(sym D) (kg/s): the largest constant with
        nu~'D nu~ >= D_min |nu~|^2 for all nu~, the step from (19) to (20) and from
        (55) to (56). The printed "D_min < ||D||" is not that property; the induced
        norm (or, for non-symmetric D, even sigma_min(D)) can exceed it.
    damping_max : float
        D_max = max_theta ||D||_2 (kg/s): printed in (10), used by no step.
    stiffness_max : float
        K_max = max_theta ||K||_2 (N/m): |eta~'(J - K')nu~| <= (1 + K_max)|eta~||nu~|.
    theta_bounds : list or None
        [[lower, upper], ...] per unknown entry; None: M, D, K known (the vessel's).
    unknown : list of str
        The unknown entries, e.g. ["m11"] (for M, m_ij and m_ji together).
    theta_true : list of float
        The vessel's values of the unknown entries.
    worst_theta : dict
        The theta (vertex) at which each bound is attained.
    assumptions : tuple of Inequality
        (9) M_min > 0, (10) D_min > 0, (11) K_max < inf. The printed lower bound
        0 < ||K|| fails for K = 0 but is used by no step, so it is not checked.
    """

    mass_min: float
    mass_max: float
    damping_min: float
    damping_max: float
    stiffness_max: float
    theta_bounds: list | None
    unknown: list[str]
    theta_true: list[float]
    worst_theta: dict[str, list[float]]
    assumptions: tuple[Inequality, ...]

    def to_dict(self) -> dict:
        """JSON-safe form (non-finite numbers are None)."""
        return _json_safe(
            {
                "mass_min": self.mass_min,
                "mass_max": self.mass_max,
                "damping_min": self.damping_min,
                "damping_max": self.damping_max,
                "stiffness_max": self.stiffness_max,
                "units": {"mass": "kg", "damping": "kg/s", "stiffness": "N/m"},
                "theta_bounds": self.theta_bounds,
                "unknown": list(self.unknown),
                "theta_true": list(self.theta_true),
                "worst_theta": dict(self.worst_theta),
                "assumptions": [item.to_dict() for item in self.assumptions],
            }
        )


def _extreme(vertices, function, pick) -> tuple[float, list[float]]:
    values = [function(m) for _, m in vertices]
    k = int(pick(values))
    return float(values[k]), vertices[k][0].tolist()


def model_bounds(vessel: DPVessel, theta_bounds: npt.ArrayLike | None = None, *, unknown: _Entries = M11) -> ModelBounds:
    """M_min, M_max, D_min, D_max, K_max of (9)–(11) for ``vessel``.

    Parameters
    ----------
    vessel : DPVessel
        The true model (M, D, K); for the paper, :func:`lookout.papers.calugi_2003.paper_vessel`.
    theta_bounds : array_like, optional
        [lower, upper] of each unknown entry (shape (2,) for one, (p, 2) for p);
        None: the model is known. Must contain the vessel's values.
    unknown : sequence of (matrix, row, column)
        The unknown entries, 0-based; default theta = m11 (("M", 0, 0),). Each
        enters its matrix affinely, so every bound is attained at a vertex of the
        box (lambda_min is concave, lambda_max and ||.||_2 convex in theta).

    Returns
    -------
    ModelBounds
    """
    vertices, box, true = _vertices(vessel, theta_bounds, unknown)
    mass_min, at_mass_min = _extreme(vertices, lambda m: np.linalg.eigvalsh(_sym(m["M"]))[0], np.argmin)
    mass_max, at_mass_max = _extreme(vertices, lambda m: np.linalg.eigvalsh(_sym(m["M"]))[-1], np.argmax)
    damping_min, at_damping_min = _extreme(vertices, lambda m: np.linalg.eigvalsh(_sym(m["D"]))[0], np.argmin)
    damping_max, at_damping_max = _extreme(vertices, lambda m: np.linalg.norm(m["D"], 2), np.argmax)
    stiffness_max, at_stiffness_max = _extreme(vertices, lambda m: np.linalg.norm(m["K"], 2), np.argmax)
    return ModelBounds(
        mass_min=mass_min,
        mass_max=mass_max,
        damping_min=damping_min,
        damping_max=damping_max,
        stiffness_max=stiffness_max,
        theta_bounds=None if box is None else box.tolist(),
        unknown=[_entry_name(e) for e in _unknown(unknown)],
        theta_true=true.tolist(),
        worst_theta={
            "mass_min": at_mass_min,
            "mass_max": at_mass_max,
            "damping_min": at_damping_min,
            "damping_max": at_damping_max,
            "stiffness_max": at_stiffness_max,
        },
        assumptions=(
            Inequality.check("(9)", "M_min > 0", mass_min, ">", 0.0, units="kg", source=f"{PAPER}, eq. (9)"),
            Inequality.check("(10)", "D_min > 0", damping_min, ">", 0.0, units="kg/s", source=f"{PAPER}, eq. (10)"),
            Inequality.check("(11)", "K_max < inf", stiffness_max, "<", math.inf, units="N/m", source=f"{PAPER}, eq. (11)"),
        ),
    )


# -- inequalities ----------------------------------------------------------------------


def _greater(name: str, relation: str, left: float, right: float, units: str, equation: str) -> Inequality:
    """``left > right``, an inequality of the paper's ``equation``."""
    return Inequality.check(name, relation, left, ">", right, units=units, source=f"{PAPER}, eq. {equation}")


def _observer_quantities(vessel, K2, theta_bounds, unknown, d_min) -> dict[str, float]:
    """sigma2, D_min, K_max and lambda_min(sym(M K2 + D)), worst case over the box."""
    K2 = _gain_matrix("K2", K2)
    vertices, _, _ = _vertices(vessel, theta_bounds, unknown)
    bounds = model_bounds(vessel, theta_bounds, unknown=unknown)
    sigma2 = min(float(np.linalg.eigvalsh(_sym(m["M"] @ K2))[0]) for _, m in vertices)
    combined = min(float(np.linalg.eigvalsh(_sym(m["M"] @ K2 + m["D"]))[0]) for _, m in vertices)
    damping = bounds.damping_min
    if d_min is not None:
        d_min = float(d_min)
        if not (math.isfinite(d_min) and d_min <= damping + TOLERANCE * abs(damping)):
            raise check.ParameterError(
                "d_min",
                f"d_min must be finite and <= lambda_min(sym D) = {damping:.6g} kg/s (the proof uses nu~'D nu~ >= D_min |nu~|^2); got {d_min!r}",
            )
        damping = d_min
    return {
        "sigma2": sigma2,
        "damping_min": damping,
        "damping_min_model": bounds.damping_min,
        "stiffness_max": bounds.stiffness_max,
        "combined": combined,
    }


#: Units of the sides, with the implicit SI weights the printed V's carry.
UNITS_22A = "1/s vs 1/s (implicit weight 1 kg/s^2 on eta~'eta~ in V (17))"
UNITS_SIGMA2 = "kg/s (surge, sway; yaw kg m^2/s)"
UNITS_57 = "1/s vs 1/s (g1/4) + 1/s (with the implicit 1 kg/s^2)"
UNITS_58 = "kg/s vs 1/s x (implicit 1 kg: z'z added to nu~'M nu~)"


def observer_condition_22(
    vessel: DPVessel,
    *,
    K1: npt.ArrayLike,
    K2: npt.ArrayLike,
    theta_bounds: npt.ArrayLike | None = None,
    unknown: _Entries = M11,
    d_min: float | None = None,
) -> Condition:
    """Condition (22) of the adaptive observer, with both sides of each inequality.

    ``(22a) sigma1 > (1 + K_max)^2 / (4 (sigma2 + D_min))`` and ``(22b) sigma2 > 0``
    (as printed; the proof itself needs sigma2 + D_min > 0), with
    sigma1 = lambda_min(sym K1), sigma2 = min_theta lambda_min(sym(M(theta) K2)),
    D_min = min_theta lambda_min(sym D) (or ``d_min``, any value <= it) and
    K_max = max_theta ||K||_2 (:func:`model_bounds`).

    Parameters
    ----------
    vessel : DPVessel
    K1, K2 : scalar, 3-vector (diagonal) or 3x3
        Observer gains (1/s); K1 must be positive definite.
    theta_bounds, unknown
        As for :func:`model_bounds`.
    d_min : float, optional
        A D_min reading to use instead of lambda_min(sym D) (e.g. 0); must not
        exceed it.

    Returns
    -------
    Condition
        ``observer_22`` with (22a), (22b); ``quantities`` the numbers it was built from
        (SI). Informational (not in the verdict): (22a*), (22a) with
        lambda_min(sym(M K2 + D)) in place of sigma2 + D_min, valid (Weyl:
        lambda_min(A + B) >= lambda_min(A) + lambda_min(B)) and never weaker.
    """
    K1 = _k1(K1)
    sigma1 = float(np.linalg.eigvalsh(_sym(K1))[0])
    q = _observer_quantities(vessel, K2, theta_bounds, unknown, d_min)
    coupling = (1.0 + q["stiffness_max"]) ** 2
    c = q["sigma2"] + q["damping_min"]
    right = coupling / (4.0 * c) if c > 0 else math.inf
    first = _greater("(22a)", "sigma1 > (1+K_max)^2/(4(sigma2+D_min))", sigma1, right, UNITS_22A, "(22)")
    second = _greater("(22b)", "sigma2 > 0", q["sigma2"], 0.0, UNITS_SIGMA2, "(22)")
    tight_right = coupling / (4.0 * q["combined"]) if q["combined"] > 0 else math.inf
    tighter = _greater(
        "(22a*)", "sigma1 > (1+K_max)^2/(4 lmin(sym(MK2+D)))", sigma1, tight_right, UNITS_22A, "(22), read with lmin(sym(MK2+D)) for sigma2+D_min"
    )
    quantities = {"sigma1": sigma1} | q
    return Condition(
        "observer_22", "(22)", "adaptive observer", f"{PAPER}, eq. (22)", [first, second], informational=[tighter], quantities=quantities
    )


def _g(d: np.ndarray, coupling_gain: np.ndarray) -> tuple[float, float]:
    """g1, g2 of (53); the first three terms of g1 weighted by P1 (1 as printed)."""
    g2 = float(np.sum(1.0 / d[3:]))
    return float(np.sum(coupling_gain / d[:3])) + g2, g2


def closed_loop_conditions_57_58(
    vessel: DPVessel,
    *,
    K1: npt.ArrayLike,
    K2: npt.ArrayLike,
    d: npt.ArrayLike,
    theta_bounds: npt.ArrayLike | None = None,
    unknown: _Entries = M11,
    d_min: float | None = None,
    coupling_gain: npt.ArrayLike = 1.0,
) -> tuple[Condition, Condition]:
    """Conditions (57) and (58) of the closed loop, with both sides.

    ``(57) sigma1 > g1/4 + (1 + K_max)^2 / (4 (sigma2 + D_min - g2/4))``
    (the right side is inf when sigma2 + D_min <= g2/4) and
    ``(58) sigma2 > max(0, g2/4 - D_min)``, with g1 = sum_1..6 1/d_i,
    g2 = sum_4..6 1/d_i (53) and the quantities of :func:`observer_condition_22`.

    Parameters
    ----------
    d : array_like, shape (6,)
        The damping weights d1..d6 (s), > 0.
    coupling_gain : scalar or 3-vector
        P1 of :class:`~lookout.controllers.backstepping.VectorialBackstepping`
        (1/s^2; 1 as printed). With V = 1/2 (z1'P1 z1 + |z2|^2) the z1-eta~ squares
        of (69) carry p_i, so g1 = sum_1..3 p_i/d_i + sum_4..6 1/d_i.

    Returns
    -------
    (Condition, Condition)
        ``closed_loop_57`` and ``closed_loop_58``, each with its tighter variant
        ((57*), (58*), lambda_min(sym(M K2 + D)) for sigma2 + D_min) as informational.
    """
    K1 = _k1(K1)
    d = _weights(d)
    coupling_gain = _positive3("coupling_gain", coupling_gain)
    sigma1 = float(np.linalg.eigvalsh(_sym(K1))[0])
    q = _observer_quantities(vessel, K2, theta_bounds, unknown, d_min)
    g1, g2 = _g(d, coupling_gain)
    coupling = (1.0 + q["stiffness_max"]) ** 2
    c = q["sigma2"] + q["damping_min"] - g2 / 4.0
    right = g1 / 4.0 + (coupling / (4.0 * c) if c > 0 else math.inf)
    first = _greater("(57)", "sigma1 > g1/4 + (1+K_max)^2/(4(sigma2+D_min-g2/4))", sigma1, right, UNITS_57, "(57)")
    c_tight = q["combined"] - g2 / 4.0
    tight = g1 / 4.0 + (coupling / (4.0 * c_tight) if c_tight > 0 else math.inf)
    tighter = _greater(
        "(57*)", "sigma1 > g1/4 + (1+K_max)^2/(4(lmin(..)-g2/4))", sigma1, tight, UNITS_57, "(57), read with lmin(sym(MK2+D)) for sigma2+D_min"
    )
    quantities = {"sigma1": sigma1, "g1": g1, "g2": g2} | q
    c57 = Condition("closed_loop_57", "(57)", "closed loop", f"{PAPER}, eq. (57)", [first], informational=[tighter], quantities=quantities)
    second = _greater("(58)", "sigma2 > max(0, g2/4 - D_min)", q["sigma2"], max(0.0, g2 / 4.0 - q["damping_min"]), UNITS_58, "(58)")
    tight58 = _greater("(58*)", "lmin(sym(MK2+D)) > g2/4", q["combined"], g2 / 4.0, UNITS_58, "(58), read with lmin(sym(MK2+D)) for sigma2+D_min")
    c58 = Condition("closed_loop_58", "(58)", "closed loop", f"{PAPER}, eq. (58)", [second], informational=[tight58], quantities=dict(quantities))
    return c57, c58


def z_weight_bound(sigma1: float, sigma2: float, damping_min: float, stiffness_max: float, g1: float, g2: float) -> float:
    """The supremum of w_z > 0 for which V = 1/2 (w_z z'z + eta~'eta~ + nu~'M nu~ + ...)
    proves the closed loop, i.e. (57)–(58) hold with g1, g2 replaced by w_z g1, w_z g2.

    With a = sigma1, c = sigma2 + D_min, k = (1 + K_max)^2 / 4 the form is positive
    definite iff a - w g1/4 > 0, c - w g2/4 > 0 and (a - w g1/4)(c - w g2/4) > k;
    the left sides fall with w, so the set is (0, w*), w* the smaller root of the
    quadratic. Returns 0 when (22) fails (no weight helps), inf when g1 = g2 = 0.
    The paper's V (47) is w_z = 1: (57)–(58) as printed hold iff w* > 1 (up to
    (58)'s extra sigma2 > 0).
    """
    a, c, k = float(sigma1), float(sigma2) + float(damping_min), (1.0 + float(stiffness_max)) ** 2 / 4.0
    p, r = g1 / 4.0, g2 / 4.0
    if not (a > 0 and c > 0 and a * c > k):
        return 0.0
    # f(w) = (a - p w)(c - r w) - k = p r w^2 - (a r + c p) w + (a c - k), f(0) > 0
    quad, lin, const = p * r, -(a * r + c * p), a * c - k
    caps = [a / p if p > 0 else math.inf, c / r if r > 0 else math.inf]
    if quad > 0:
        disc = lin * lin - 4.0 * quad * const
        root = 2.0 * const / (-lin + math.sqrt(max(disc, 0.0)))  # the smaller root, stably
    elif lin < 0:
        root = -const / lin
    else:
        root = math.inf
    return float(min([root] + caps))


def noise_drift_rate(
    *,
    K1: npt.ArrayLike,
    K2: npt.ArrayLike,
    d: npt.ArrayLike,
    gamma: float,
    noise_std: float,
    interval: float,
    C1: npt.ArrayLike = 0.1,
    C2: npt.ArrayLike = 0.1,
) -> float:
    """Expected rate of theta_hat (kg/s) that white position noise alone causes in the
    discrete update (67) for theta = m11, with the controller (36) and the vessel at
    rest at heading 0 (derived here; not in the paper).

    The same noisy sample enters the regressor and the prediction error of (67).
    With eta(i) = eta_true(i) + n(i), n white with std ``noise_std`` per axis:

    * (66) puts K2 J^T delta_eta(i-1), hence k2 n_u(i-1), into nu_hat(i-1);
    * (36) has d tau_u / d u_hat = d11 - m11_hat g with g = (C1 + D1 + C2 + D2)_u
      (z2 = J nu_hat + ..., D1 of (28), D2 of (40) at rest), so
      phi(i-1) = xi_u(i-1) = (tau_u - d11 u_hat) / m11_hat carries -g k2 n_u(i-1);
    * the bracket Delta nu_hat(i-1) - J^T delta_eta(i) carries (1 + Delta k2) n_u(i-1).

    So each sample adds E[d theta_hat] = -Gamma g k2 (1 + Delta k2) sigma^2 (kg) and
    the rate is that over Delta: negative (the mass is driven toward its lower bound),
    proportional to Gamma like the restoring term of a parameter error, so the
    equilibrium bias does not depend on Gamma, and growing as 1/Delta for a fixed
    per-sample std. Valid while the loop's own response to the noise is negligible (the
    printed gains: g = 0.2 1/s); a loop that moves the ship with the noise (large K1)
    adds correlations this leaves out. Measured against simulation in
    :func:`lookout.papers.calugi_2003.noise_drift`.
    """
    K1, K2, d = _k1(K1), _gain_matrix("K2", K2), _weights(d)
    C1, C2 = _positive3("C1", C1), _positive3("C2", C2)
    for name, value in (("gamma", gamma), ("noise_std", noise_std)):
        if not (math.isfinite(value) and value >= 0):
            raise check.ParameterError(check.key(name), f"{name} must be finite and >= 0; got {value!r}")
    if not (math.isfinite(interval) and interval > 0):
        raise check.ParameterError("interval", f"interval must be finite and > 0 (s); got {interval!r}")
    D1 = d[:3] * np.sum(K1**2, axis=1)
    omega1_u = np.sum(((C1 + D1)[0] * K1[0]) ** 2)
    D2_u = d[3] * (omega1_u + np.sum(K2[0] ** 2))  # row 1 of Omega2 = J (T(0) + K2) at psi = 0, rest
    g = C1[0] + D1[0] + C2[0] + D2_u
    k2 = K2[0, 0]
    return float(-gamma * g * k2 * (1.0 + interval * k2) * noise_std**2 / interval)


# -- the report ------------------------------------------------------------------------


def _calugi_summary(bounds: ModelBounds, gains: dict, quantities: Mapping) -> list[str]:
    """The model's worst-case constants and the gains, as lines under the report's title."""
    if bounds.theta_bounds is None:
        theta = f"{', '.join(bounds.unknown)} known"
    else:
        theta = "; ".join(f"{n} in [{lo:.5g}, {hi:.5g}]" for n, (lo, hi) in zip(bounds.unknown, bounds.theta_bounds))
    lines = [
        f"model (worst case, {theta}):",
        f"  M_min {number(bounds.mass_min, 3)}  M_max {number(bounds.mass_max, 3)} kg (9, lambda of M)",
        f"  D_min {number(bounds.damping_min, 3)} kg/s (lambda_min sym D)  D_max {number(bounds.damping_max, 3)}",
        f"  K_max {number(bounds.stiffness_max, 3)} N/m (||K||_2)",
        "gains:",
    ]
    for name in ("K1", "K2"):
        matrix = np.asarray(gains[name])
        diagonal = np.allclose(matrix, np.diag(np.diag(matrix)))
        lines.append(f"  {name} {'diag ' + numbers(np.diag(matrix)) if diagonal else '(full 3x3, see the JSON)'} 1/s")
    lines.append(f"  d  {numbers(gains['d'])} s")
    if not np.allclose(gains["coupling_gain"], 1.0):
        lines.append(f"  P1 {numbers(gains['coupling_gain'])} 1/s^2")
    q = quantities
    lines.append(f"  sigma1 {number(q['sigma1'], 3)} 1/s, sigma2 {number(q['sigma2'], 3)} kg/s, g1 {number(q['g1'], 3)}, g2 {number(q['g2'], 3)} 1/s")
    if q["damping_min"] != q["damping_min_model"]:
        lines.append(f"  D_min read as {number(q['damping_min'], 3)} kg/s")
    return lines


def check_calugi_2003(
    vessel: DPVessel,
    *,
    K1: npt.ArrayLike,
    K2: npt.ArrayLike,
    d: npt.ArrayLike,
    theta_bounds: npt.ArrayLike | None = None,
    unknown: _Entries = M11,
    d_min: float | None = None,
    coupling_gain: npt.ArrayLike = 1.0,
) -> Report:
    """Check (22), (57) and (58) of Calugi et al. (2003) for a vessel and gain set.

    Parameters
    ----------
    vessel : DPVessel
        The true model; for the paper :func:`lookout.papers.calugi_2003.paper_vessel` ((59)'s numbers).
    K1, K2 : scalar, 3-vector (diagonal) or 3x3
        Observer gains (1/s); K1 positive definite.
    d : array_like, shape (6,)
        Damping weights d1..d6 (s), > 0.
    theta_bounds : array_like, optional
        Bounds on the unknown entries (default: known model); sigma2 and D_min are
        taken in the worst case over them (:func:`model_bounds`).
    unknown : sequence of (matrix, row, column)
        Default theta = m11.
    d_min : float, optional
        A D_min reading below lambda_min(sym D) to use instead (e.g. 0).
    coupling_gain : scalar or 3-vector
        P1 (1/s^2), 1 as printed.

    Returns
    -------
    Report
        Conditions ``observer_22``, ``closed_loop_57``, ``closed_loop_58``
        (:func:`observer_condition_22`, :func:`closed_loop_conditions_57_58`).
        ``quantities``: ``gains`` and their units, ``model_bounds``
        (:meth:`ModelBounds.to_dict`) and ``z_weight_bound`` (:func:`z_weight_bound`):
        the closed loop is proven by V with z'z weighted by any w_z below it (the
        printed (47) is w_z = 1).
    """
    K1m, K2m = _k1(K1), _gain_matrix("K2", K2)
    d = _weights(d)
    coupling_gain = _positive3("coupling_gain", coupling_gain)
    bounds = model_bounds(vessel, theta_bounds, unknown=unknown)
    c22 = observer_condition_22(vessel, K1=K1m, K2=K2m, theta_bounds=theta_bounds, unknown=unknown, d_min=d_min)
    c57, c58 = closed_loop_conditions_57_58(
        vessel, K1=K1m, K2=K2m, d=d, theta_bounds=theta_bounds, unknown=unknown, d_min=d_min, coupling_gain=coupling_gain
    )
    q = c57.quantities
    w = z_weight_bound(q["sigma1"], q["sigma2"], q["damping_min"], q["stiffness_max"], q["g1"], q["g2"])
    gains = {"K1": K1m, "K2": K2m, "d": d, "coupling_gain": coupling_gain}
    if math.isfinite(w) and w > 0:
        weight = f"with z'z weighted by w_z in V (47): proven for w_z < {w:.3g}"
    elif w > 0:
        weight = "with z'z weighted by w_z in V (47): proven for every w_z"
    else:
        weight = "no weight w_z on z'z proves it: (22) does not hold"
    return Report(
        f"{PAPER}: conditions (22), (57), (58)",
        (c22, c57, c58),
        quantities={
            "gains": gains,
            "gain_units": {"K1": "1/s", "K2": "1/s", "d": "s", "coupling_gain": "1/s^2"},
            "model_bounds": bounds.to_dict(),
            "z_weight_bound": w,
        },
        summary=_calugi_summary(bounds, gains, q),
        notes=(weight,),
    )


# -- gains that satisfy (57)-(58) ------------------------------------------------------


def loop_rates(
    K1: npt.ArrayLike,
    K2: npt.ArrayLike,
    d: npt.ArrayLike,
    *,
    C1: npt.ArrayLike = 0.1,
    C2: npt.ArrayLike = 0.1,
    coupling_gain: npt.ArrayLike = 1.0,
    speed: float = 0.5,
) -> dict[str, np.ndarray]:
    """The controller's rates at a planar speed bound, per axis (1/s).

    D1 = diag(d_i |k_i|^2) (28), Omega1 = (C1 + D1) K1 (38) and the largest
    D2 = diag(d_{i+3} (|row_i Omega1|^2 + |row_i Omega2|^2)) (40) over all headings
    and |(u_hat, v_hat)| <= ``speed``: row i of Omega2 = J (T(nu_hat) + K2) (39)
    has |.|^2 <= max(k2_u^2, k2_v^2) + speed^2 for surge and sway (exact for
    diagonal K2; (sigma_max(K2[:2]) + speed)^2 otherwise) and |row_3 K2|^2 for
    yaw. ``loop`` is, per axis, the largest of C1 + D1, C2 + D2 and the spectral
    radius of the linear z-loop [[-(C1 + D1), 1], [-P1, -(C2 + D2)]] ((29), (37)):
    the fastest rate the sampled controller has to realize.
    """
    K1, K2, d = _k1(K1), _gain_matrix("K2", K2), _weights(d)
    C1, C2 = _positive3("C1", C1), _positive3("C2", C2)
    P1 = _positive3("coupling_gain", coupling_gain)
    if not (math.isfinite(speed) and speed >= 0):
        raise check.ParameterError("speed", f"speed must be finite and >= 0 (m/s); got {speed!r}")
    return _rates(K1, K2, d, C1, C2, P1, float(speed))


def _rates(K1, K2, d, C1, C2, P1, speed) -> dict[str, np.ndarray]:
    """:func:`loop_rates` on validated arrays."""
    D1 = d[:3] * np.sum(K1**2, axis=1)
    omega1 = np.sum(((C1 + D1)[:, None] * K1) ** 2, axis=1)
    if np.allclose(K2, np.diag(np.diag(K2)), rtol=0.0, atol=0.0):
        planar = max(K2[0, 0] ** 2, K2[1, 1] ** 2) + speed**2
    else:
        planar = (np.linalg.norm(K2[:2], 2) + speed) ** 2
    omega2 = np.array([planar, planar, float(np.sum(K2[2] ** 2))])
    D2 = d[3:] * (omega1 + omega2)
    # eigenvalues of [[-a, 1], [-p, -c]]: (-(a + c) +- sqrt((a - c)^2 - 4 p)) / 2
    a, c = C1 + D1, C2 + D2
    root = np.sqrt((a - c) ** 2 - 4.0 * P1 + 0j)
    radius = np.maximum(np.abs(-(a + c) + root), np.abs(-(a + c) - root)) / 2.0
    loop = np.maximum(radius, np.maximum(a, c))
    return {"D1": D1, "D2": D2, "loop": loop}


@dataclass(frozen=True, eq=False)
class GainRoute:
    """One way to satisfy (57)–(58), and what it costs.

    ``K1`` (3x3), ``d`` (6); ``factor_57`` left/right of (57); ``D1`` and ``D2`` at
    the design speed (1/s); ``fastest_rate`` max of the z-loop spectral radii and
    ||K1||, ||K2|| (1/s); ``step_gain`` = step x fastest_rate; ``usable`` when
    step_gain <= max_step_gain; ``feasible`` False when the route cannot satisfy
    the conditions (then the numbers are those of the given gains).
    """

    name: str
    K1: np.ndarray
    d: np.ndarray
    feasible: bool
    factor_57: float
    D1: np.ndarray
    D2: np.ndarray
    fastest_rate: float
    step_gain: float
    usable: bool
    verdicts: dict[str, Verdict]
    note: str

    def to_dict(self) -> dict:
        return _json_safe(
            {
                "name": self.name,
                "K1": self.K1,
                "d": self.d,
                "feasible": self.feasible,
                "factor_57": self.factor_57,
                "D1": self.D1,
                "D2": self.D2,
                "fastest_rate": self.fastest_rate,
                "step_gain": self.step_gain,
                "usable": self.usable,
                "verdicts": dict(self.verdicts),
                "note": self.note,
            }
        )


@dataclass(frozen=True, eq=False)
class GainProposal:
    """The gain set :func:`satisfying_gains` chose, why, and every route it weighed.

    ``K1``, ``K2`` (3x3, 1/s), ``d`` (6, s) are the chosen set; ``report`` its
    :func:`check_calugi_2003` report; ``route`` the chosen route's name; ``reason`` one
    line; ``routes`` all routes; ``design`` the step (s), speed (m/s),
    max_step_gain and margin it was built for.
    """

    K1: np.ndarray
    K2: np.ndarray
    d: np.ndarray
    route: str
    reason: str
    report: Report
    routes: list[GainRoute]
    design: dict[str, float]

    def to_dict(self) -> dict:
        return _json_safe(
            {
                "K1": self.K1,
                "K2": self.K2,
                "d": self.d,
                "route": self.route,
                "reason": self.reason,
                "design": dict(self.design),
                "verdicts": dict(self.report.verdicts),
                "routes": [r.to_dict() for r in self.routes],
                "report": self.report.to_dict(),
            }
        )

    def text(self) -> str:
        """The chosen set and the routes, at most 80 columns."""
        lines = [f"Gains satisfying (57)-(58): route {self.route}", f"  {self.reason}"]
        lines.append(f"  K1 diag {numbers(np.diag(self.K1))} 1/s")
        lines.append(f"  d       {numbers(self.d)} s")
        dz = self.design
        lines.append(f"Routes (|v| <= {dz['speed']:g} m/s, step {dz['step']:g} s, usable if step x rate <= {dz['max_step_gain']:g}):")
        lines.append(f"  {'route':<11}{'K1':>8}{'d1..3':>9}{'d4..6':>9}{'max D2':>9}{'rate':>9}{'(57) x':>9}  usable")
        for r in self.routes:
            if not r.feasible:
                lines.append(f"  {r.name:<11} infeasible: {r.note}"[:80])
                continue
            lines.append(
                f"  {r.name:<11}{number(np.diag(r.K1).max(), 3):>8}{number(r.d[:3].max(), 3):>9}"
                f"{number(r.d[3:].max(), 3):>9}{number(r.D2.max(), 3):>9}{number(r.fastest_rate, 3):>9}"
                f"{number(r.factor_57, 3):>9}  {'yes' if r.usable else 'no'}"
            )
        return "\n".join(line[:80] for line in lines)


def _round_up(value: float, digits: int = 2) -> float:
    """``value`` rounded up to ``digits`` significant digits."""
    if not (math.isfinite(value) and value > 0):
        return value
    exponent = math.floor(math.log10(value)) - digits + 1
    scaled = value / 10.0**exponent
    return float(math.ceil(scaled - 1e-9) * 10.0**exponent)


#: Scale factors tried for K1 (the 1-1.5-2-3-4-5-7 series, 1 to 1e4).
K1_FACTORS = tuple(m * 10.0**e for e in range(5) for m in (1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 7.0))


def satisfying_gains(
    vessel: DPVessel,
    *,
    K1: npt.ArrayLike,
    K2: npt.ArrayLike,
    d: npt.ArrayLike,
    C1: npt.ArrayLike,
    C2: npt.ArrayLike,
    theta_bounds: npt.ArrayLike | None = None,
    unknown: _Entries = M11,
    coupling_gain: npt.ArrayLike = 1.0,
    step: float = 0.1,
    speed: float = 0.5,
    max_step_gain: float = 0.5,
    margin: float = 1.1,
) -> GainProposal:
    """A gain set that satisfies (57)–(58), found from the given one (the paper's: the
    Calugi 2003 reproduction's ``PRINTED_GAINS``).

    (57) needs g1/4 = sum 1/(4 d_i) below sigma1 (the second term is ~4.5e-6 1/s
    here), so there are two levers, and the routes weighed are:

    * ``d_uniform``: all d_i raised to one value, K1 kept (the derivation's reading:
      d_i >~ 1.5e3 s for K1 = 1e-3 I; then D2 ~ 1.5e3 v_hat^2 1/s, about 375 1/s at
      0.5 m/s, beyond what a 0.1 s sampled controller can realize).
    * ``d_split``: K1 kept; d1..3 = a and d4..6 = b chosen to minimize the fastest
      loop rate at the design speed, with b the smallest that satisfies (57)–(58)
      for that a. D1 = a |k_i|^2 is cheap for a small K1, but d4..6 alone must
      give 3/(4b) < sigma1, so b > 750 s and D2 >= 750 v_hat^2 whatever a is.
    * ``K1_only``: d kept, K1 scaled until sigma1 > g1/4 + ...: K1 > 15 I for
      d = 0.1, which ends the position filtering (K1 is its bandwidth) and makes
      D1 = d K1^2 and Omega1 huge.
    * ``K1_and_d``: K1 scaled by the smallest factor in :data:`K1_FACTORS` for which
      the ``d_split`` design at that K1 is usable: sigma1 grows linearly, so b can
      shrink as 1/K1 and D2 with it; the filter bandwidth K1 grows by that factor.

    Choice (deterministic): the given set if it already satisfies (57)–(58) with
    ``margin``; else ``d_split`` if usable (K1, the observer's filtering, kept);
    else ``K1_and_d`` (the smallest K1 increase that is usable); else the route
    with the smallest step gain, said so in ``reason``. "Usable" means
    step x fastest rate <= ``max_step_gain``, the fastest rate being the largest
    spectral radius of the linear z-loops (:func:`loop_rates`, D2 at
    |(u_hat, v_hat)| = ``speed``) and of K1, K2; 0.5 is a quarter of forward
    Euler's stability limit 2 at the sample time, room for D2 changing with
    nu_hat between samples. Every route keeps K2, C1, C2, P1, never lowers a d_i
    or K1, satisfies (57) and (58) by ``margin`` (left/right >= margin, before
    rounding d and the K1 factor up to two significant digits) and is verified
    with :func:`check_calugi_2003`.

    Parameters
    ----------
    vessel, K1, K2, d, theta_bounds, unknown, coupling_gain
        As for :func:`check_calugi_2003`; defaults are the printed gains.
    C1, C2 : scalar or 3-vector
        Controller gains (1/s), for the loop rates.
    step : float
        Sample time of the controller (s).
    speed : float
        Design bound on |(u_hat, v_hat)| (m/s) at which D2 is evaluated. A
        filtered step of A metres through (60) peaks at 0.027 A m/s.
    max_step_gain : float
        Largest acceptable step x rate.
    margin : float
        Required factor left/right of (57) and (58), >= 1.

    Returns
    -------
    GainProposal
    """
    K1m, K2m, d0 = _k1(K1), _gain_matrix("K2", K2), _weights(d)
    C1v, C2v = _positive3("C1", C1), _positive3("C2", C2)
    P1 = _positive3("coupling_gain", coupling_gain)
    for name, value in (("step", step), ("max_step_gain", max_step_gain)):
        if not (math.isfinite(value) and value > 0):
            raise check.ParameterError(check.key(name), f"{name} must be positive and finite; got {value!r}")
    if not (math.isfinite(speed) and speed >= 0):
        raise check.ParameterError("speed", f"speed must be finite and >= 0 (m/s); got {speed!r}")
    if not (math.isfinite(margin) and margin >= 1):
        raise check.ParameterError("margin", f"margin must be >= 1; got {margin!r}")
    q = _observer_quantities(vessel, K2m, theta_bounds, unknown, None)
    sigma1_0 = float(np.linalg.eigvalsh(_sym(K1m))[0])
    k = (1.0 + q["stiffness_max"]) ** 2 / 4.0
    c0, sigma2, dmin = q["sigma2"] + q["damping_min"], q["sigma2"], q["damping_min"]
    design = {"step": float(step), "speed": float(speed), "max_step_gain": float(max_step_gain), "margin": float(margin)}

    def conditions_at(K1x, dx) -> Report:
        return check_calugi_2003(vessel, K1=K1x, K2=K2m, d=dx, theta_bounds=theta_bounds, unknown=unknown, coupling_gain=P1)

    def route(name: str, K1x, dx, note: str, feasible: bool = True) -> GainRoute:
        report = conditions_at(K1x, dx)
        rates = loop_rates(K1x, K2m, dx, C1=C1v, C2=C2v, coupling_gain=P1, speed=speed)
        fastest = float(max(rates["loop"].max(), np.linalg.norm(K1x, 2), np.linalg.norm(K2m, 2)))
        return GainRoute(
            name,
            np.asarray(K1x, float),
            np.asarray(dx, float),
            feasible,
            report["closed_loop_57"].inequalities[0].factor,
            rates["D1"],
            rates["D2"],
            fastest,
            step * fastest,
            feasible and step * fastest <= max_step_gain,
            dict(report.verdicts),
            note,
        )

    def x_max(sigma1: float, first: float) -> float:
        """The largest x = g2/4 (d4..6 common) with (57)-(58) holding by ``margin``,
        given sigma1 and the d1..3 part ``first`` of g1/4; <= 0 when none."""
        s = sigma1 / margin - first
        if not (s > 0 and s * c0 > k):
            return 0.0
        root = 2.0 * (s * c0 - k) / ((s + c0) + math.sqrt((s - c0) ** 2 + 4.0 * k))
        return min(root, dmin + sigma2 / margin) if sigma2 > 0 else 0.0

    def split(K1x) -> tuple[np.ndarray | None, str]:
        """d for K1x: a (d1..3) minimizing the fastest rate, b the smallest that
        satisfies (57)-(58); both rounded up to two significant digits."""
        sigma1 = float(np.linalg.eigvalsh(_sym(K1x))[0])
        a_low, b_low = float(d0[:3].max()), float(d0[3:].max())
        p = P1

        def b_of(a: float) -> float:
            x = x_max(sigma1, float(np.sum(p / a)) / 4.0)
            return max(b_low, 3.0 / (4.0 * x)) if x > 0 else math.inf

        def cost(log_a: float) -> float:
            a = math.exp(log_a)
            b = b_of(a)
            if not math.isfinite(b):
                return math.inf
            dx = np.array([a] * 3 + [b] * 3)
            return float(_rates(K1x, K2m, dx, C1v, C2v, P1, speed)["loop"].max())

        grid = np.log(a_low) + np.linspace(0.0, np.log(1e10), 121)
        costs = np.array([cost(v) for v in grid])
        if not np.isfinite(costs).any():
            return None, "sigma1 too small for any d (the d4..6 terms alone exceed it)"
        best = int(np.argmin(costs))
        log_a, lowest = float(grid[best]), float(costs[best])
        lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
        if hi > lo:
            result = scipy.optimize.minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
            if result.fun < lowest:
                log_a, lowest = float(result.x), float(result.fun)
        # the cost is often flat in a (D2 set by the speed term): take the smallest a
        # within 1 % of the lowest rate, the least change to d1..3
        near = np.flatnonzero(costs <= 1.01 * lowest)
        if near.size and grid[near[0]] < log_a:
            log_a = float(grid[near[0]])
        a = _round_up(max(math.exp(log_a), a_low))
        b = _round_up(b_of(a))
        return np.array([a] * 3 + [b] * 3), ""

    routes: list[GainRoute] = []
    given = route("given", K1m, d0, "the gains as given")
    if given.verdicts["closed_loop_57"] == Verdict.HOLDS and given.verdicts["closed_loop_58"] == Verdict.HOLDS and given.factor_57 >= margin:
        report = conditions_at(K1m, d0)
        return GainProposal(K1m, K2m, d0, "given", "the given gains already satisfy (57)-(58)", report, [given], design)

    # d_uniform: all six equal, K1 kept; x = 3/(4 d) gives g1/4 = 2x (times p for d1..3), g2/4 = x
    weight = (float(np.sum(P1)) + 3.0) / 3.0
    s = sigma1_0 / margin
    # (s - weight x)(c0 - x) >= k: the smaller root of weight x^2 - (s + weight c0) x + (s c0 - k)
    if s * c0 > k:
        lin = s + weight * c0
        root = 2.0 * (s * c0 - k) / (lin + math.sqrt(max(lin * lin - 4.0 * weight * (s * c0 - k), 0.0)))
        x = min(root, dmin + sigma2 / margin) if sigma2 > 0 else 0.0
    else:
        x = 0.0
    if x > 0:
        value = _round_up(max(3.0 / (4.0 * x), float(d0.max())))
        routes.append(route("d_uniform", K1m, np.full(6, value), "all d_i equal, K1 kept"))
    else:
        routes.append(route("d_uniform", K1m, d0, "sigma1 too small for any d", feasible=False))

    d_split, why = split(K1m)
    if d_split is None:
        routes.append(route("d_split", K1m, d0, why, feasible=False))
    else:
        routes.append(route("d_split", K1m, d_split, "d1..3 and d4..6 raised, K1 kept"))

    start = conditions_at(K1m, d0)
    needed = float(start["closed_loop_57"].inequalities[0].right)
    c58 = start["closed_loop_58"].inequalities[0]
    if math.isfinite(needed) and c58.factor >= margin:
        factor = _round_up(max(1.0, margin * needed / sigma1_0))
        routes.append(route("K1_only", factor * K1m, d0, f"K1 x {factor:.3g}, d kept"))
    else:
        routes.append(route("K1_only", K1m, d0, "(58) or (57)'s second term fails for the given d", feasible=False))

    mixed = None
    for factor in K1_FACTORS[1:]:
        K1x = factor * K1m
        dx, _ = split(K1x)
        if dx is None:
            continue
        candidate = route("K1_and_d", K1x, dx, f"K1 x {factor:g}, d1..3 and d4..6 raised")
        if candidate.usable:
            mixed = candidate
            break
    if mixed is None:
        routes.append(route("K1_and_d", K1m, d0, "no K1 factor up to 1e4 gives a usable set", feasible=False))
    else:
        routes.append(mixed)

    by_name = {r.name: r for r in routes}
    satisfied = [r for r in routes if r.feasible and all(v == Verdict.HOLDS for v in r.verdicts.values())]
    names = {r.name for r in satisfied}
    if "d_split" in names and by_name["d_split"].usable:
        chosen = by_name["d_split"]
        reason = f"K1 kept; d raised: fastest rate {chosen.fastest_rate:.3g} 1/s at {speed:g} m/s (step x rate {chosen.step_gain:.2g})"
    elif mixed is not None and "K1_and_d" in names:
        chosen = mixed
        ratio = float(np.linalg.eigvalsh(_sym(chosen.K1))[0]) / sigma1_0
        reason = (
            f"K1 kept needs D2 ~ {by_name['d_split'].D2.max():.3g} 1/s at {speed:g} m/s; "
            f"K1 x {ratio:g} and d raised: rate {chosen.fastest_rate:.3g} 1/s"
        )
    elif satisfied:
        chosen = min(satisfied, key=lambda r: r.step_gain)
        reason = f"no route is usable at {speed:g} m/s; {chosen.name} has the smallest step x rate ({chosen.step_gain:.3g})"
    else:
        raise ValueError("no gain route satisfies (57)-(58) for this vessel and K2 (check (22) and (58))")
    report = conditions_at(chosen.K1, chosen.d)
    return GainProposal(chosen.K1, K2m, chosen.d, chosen.name, reason, report, [given] + routes, design)


__all__ = [
    "GainProposal",
    "GainRoute",
    "ModelBounds",
    "check_calugi_2003",
    "closed_loop_conditions_57_58",
    "loop_rates",
    "model_bounds",
    "noise_drift_rate",
    "observer_condition_22",
    "satisfying_gains",
    "z_weight_bound",
]
