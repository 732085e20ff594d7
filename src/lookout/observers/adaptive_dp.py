"""Adaptive observer for dynamic positioning with unknown model parameters.

Calugi, F., Robertsson, A. and Johansson, R. (2003), "An adaptive observer for
dynamical ship position control using vectorial observer backstepping", Proc. 42nd
IEEE CDC, 3262–3267. Model (1)–(2) with the parametrization (8)::

    eta' = J(psi) nu,     M nu' + D nu + K eta = tau                       (1)-(2)
    M xi + D nu_hat + K eta_hat  linear in the unknown entries theta        (8)

and the observer (13)–(15), eta~ = eta - eta_hat, nu~ = nu - nu_hat::

    eta_hat'   = J(psi) nu_hat + K1 eta~                                    (13)
    nu_hat'    = xi + K2 nu~,   xi = M_hat^-1 (tau - D_hat nu_hat - K_hat eta_hat)   (14)
    theta_hat' = -Gamma phi^T(xi, nu_hat, eta_hat) nu~                      (15)

(15) needs the unmeasured nu (Remark 2). Appendix A integrates it with
``nu dt = J^T(psi) d eta`` and gives the implementable discrete form (65)–(67),
with (65) corrected to K1 eta~ (NOTES.md; thesis B.27), Delta the sample period,
delta_eta(i) = eta(i) - eta(i-1)::

    eta_hat(i)   = eta_hat(i-1) + Delta [J(i-1) nu_hat(i-1) + K1 eta~(i-1)]            (65)
    nu_hat(i)    = (I - Delta K2) nu_hat(i-1) + Delta xi(i-1) + K2 J^T(i-1) delta_eta(i)  (66)
    theta_hat(i) = theta_hat(i-1) + Gamma phi^T(i-1) [Delta nu_hat(i-1) - J^T(i-1) delta_eta(i)]  (67)

where J(i-1) = J(psi(i-1)) of the *measured* heading, and xi(i-1), phi(i-1) use
tau(i-1), nu_hat(i-1), eta_hat(i-1), theta_hat(i-1) (derivations C3).

Checked here (derivations-kim-calugi-2003.md, C1–C3, verified):

* Regressor. With M_hat = M(theta_hat) etc. the model is affine in theta, so
  ``M~ xi + D~ nu_hat + K~ eta_hat = phi theta~`` with one column of phi per
  unknown entry: E xi (mass), E nu_hat (damping), E eta_hat (stiffness), E the
  0/1 matrix of the entry (both (i, j) and (j, i) for an off-diagonal one). For
  theta = m11, phi = [xi_1, 0, 0]^T (C1).
* Error dynamics, corrected (16) (thesis B.14, C2)::

      M nu~' = -M~ xi - D~ nu_hat - K~ eta_hat - D nu~ - K eta~ - M K2 nu~

  so nu~^T M nu~' contains -nu~^T phi theta~, and with V of (17) the bracket of (19)
  is -theta~^T (phi^T nu~ + Gamma^-1 theta_hat'), which vanishes for
  theta_hat' = -Gamma phi^T nu~: **the sign of (15) is right** as printed (C1).
  Sanity check: theta~ > 0 (mass underestimated) gives u~ of the sign of -xi_1,
  so theta_hat grows.
* (66)–(67) are left-rectangle integrations of (62)–(64); the discrete form tends
  to (13)–(15) at first order in Delta (tested: tests/test_adaptive_observer.py).

Choices (where the paper is silent)
-----------------------------------
* Known model. The observer's model is a :class:`~lookout.models.vessel.DPVessel`
  (M, D, K) whose unknown entries are replaced by theta_hat; its other entries are
  taken as exact. There is no bias estimate: the model (2) has none, so a plant
  bias J^T b acts as an unmodelled force. The stiffness term uses the heading
  through ``ssa`` (as :class:`~lookout.models.vessel.DPVessel` does).
* Time indices in the engine (:mod:`lookout.sim.loop`): ``predict(S, t_{i-1},
  y_{i-1}, tau_{i-1}, Delta)`` computes every term of (65)–(67) that uses (i-1)
  values (eta_hat(i); (I - Delta K2) nu_hat + Delta xi; Gamma phi^T Delta nu_hat)
  and stores eta(i-1) (whose heading gives J(i-1)) and phi(i-1); ``update(S, t_i,
  y_i)`` adds K2 J^T(i-1) delta_eta and -Gamma phi^T J^T(i-1) delta_eta with
  delta_eta = y_i - eta(i-1), heading difference through ``ssa`` (C3: the true
  increment |r| Delta << pi is recovered exactly), then projects theta_hat. The
  controller sees the estimate at t_i (Remark 3). Delta is the engine's sample
  period (the ``dt`` of predict).
* First sample. ``init(y0, guess)`` stores eta(0) = y0; the engine's first
  ``update`` at t_0 then has delta_eta = 0 and changes nothing, so the estimate at
  t_0 is the guess.
* Projection. theta_hat is kept in the box [lower, upper] of the parametrization
  (the paper's "bounds for the unknown parameters", (9)–(11)). Discrete form: the
  complete (67) step is clipped to the box in ``update``. Continuous form: the
  standard projection (theta_hat'_j set to 0 where theta_hat_j is at or beyond a
  bound and the rate points outward) in :meth:`AdaptiveObserver.vector_field`,
  AND a clip after every integration step (``predict``, ``normalize``), so rounding
  never leaves the box; the vector field evaluates M_hat, xi and phi at the clipped
  theta_hat, since an RK4 stage may step outside the box. The componentwise
  projection keeps V' <= 0 for a diagonal Gamma; with a non-diagonal Gamma it
  still keeps the bounds, but the Lyapunov argument needs the Gamma-weighted
  projection, which is not implemented.
* Missing samples (NaN). Discrete form: a missing channel of eta(i) is replaced by
  the prediction ``eta(i-1) + Delta J(i-1) nu_hat(i-1)`` (stored by ``predict``),
  so the next difference spans one sample; with every channel missing, (66)
  reduces to nu_hat(i) = nu_hat(i-1) + Delta xi(i-1) (the model alone) and (67)
  to theta_hat(i) = theta_hat(i-1) (no adaptation). The K1 eta~ injection of (65)
  is zero on a missing channel. Continuous form: the injections K1 eta~ and K2
  nu~ (and the adaptation through nu~) are zero on missing channels, and J is
  built from eta_hat's heading when the heading is missing.
* Slower sensor channels. The discrete form expects every position/heading
  channel sampled at the observer's period: a channel held over several samples
  gives delta_eta = 0 on the held samples and the whole increment on the fresh
  one (the increments still sum to the displacement, but the estimate is rough).
* Continuous form. Needs the true nu: it reads it from the ORACLE
  :class:`~lookout.sensors.PositionHeadingVelocitySensor` (simulation only). In
  ``observer_mode="continuous"`` the engine integrates :meth:`vector_field` with
  the plant; in sampled mode ``predict`` integrates it by ``steps_per_sample`` RK4
  steps with y and tau held over the sample (like the passive observer).
* Gains in SI: K1, K2 in 1/s (diagonals); Gamma maps phi^T nu~ to theta_hat'
  (units of theta per second over units of phi^T nu~): kg s2 m-2 for theta = m11
  (phi = xi_1 in m/s2, nu~ in m/s). Gamma = 0 is allowed
  (theta known: the observer is then (13)–(14) with M_hat = M(theta_hat(0))).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Sequence
from typing import Any, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec, rotate, rotate_transpose, solve, ssa
from lookout.components import ContinuousObserver, Layout, Signal
from lookout.declare import Part, Value, component, initial_values
from lookout.models.vessel import VESSEL_INPUT, VESSEL_SIGNALS, DPVessel
from lookout.observers.start import from_first_measurement
from lookout.sensors import POSITION_HEADING, POSITION_HEADING_VELOCITY
from lookout.sim.integrators import integrate_sample

#: Kinds of unknown model entries and the letter of their names (m11, d23, k33).
KINDS = {"mass": "m", "damping": "d", "stiffness": "k"}
#: SI units of an entry by kind and by how many of (row, col) are the yaw axis:
#: surge/sway entries, surge/sway-yaw couplings, the yaw-yaw entry. Angles (rad) are
#: dimensionless: damping kg/s = N s/m, kg m/s = N s (= N m s/m), kg m2/s = N m s;
#: stiffness kg s-2 = N/m, kg m s-2 = N (per rad, or N m per m), kg m2 s-2 = N m (per rad).
UNITS = {
    "mass": ("kg", "kg m", "kg m2"),
    "damping": ("kg s-1", "kg m s-1", "kg m2 s-1"),
    "stiffness": ("kg s-2", "kg m s-2", "kg m2 s-2"),
}
FORMS = ("discrete", "continuous")

#: The estimate: low-frequency position, heading and velocities of the vessel.
ESTIMATE_SIGNALS = tuple(s for s in VESSEL_SIGNALS if s.name in ("position", "heading", "velocity", "yaw_rate"))
#: eta - eta_hat at the sample (heading through ssa; 0 on a missing channel).
INNOVATION_SIGNALS = tuple(
    s.renamed(s.name.replace("measured_", "innovation_"), "position innovation eta - eta_hat (eq. 13), " + s.name.split("_", 1)[1])
    for s in POSITION_HEADING.signals
)

#: One unknown entry as given: a paper-style name ("m11", 1-based) or (kind, row, col), 0-based.
_Unknown = str | tuple[str, int, int] | list[str | int]

_NAME = re.compile(r"^([mdk])([123])([123])$")


def _parse_unknown(entry) -> tuple[str, int, int]:
    """("mass"|"damping"|"stiffness", row, col) with 0-based row <= col, from a tuple
    (0-based) or a paper-style name "m11" (1-based)."""
    if isinstance(entry, str):
        match = _NAME.match(entry)
        if match is None:
            raise check.ParameterError("unknowns", f"unknowns: a name must read like 'm11', 'd23' or 'k33' (1-based, as in the paper); got {entry!r}")
        kind = {letter: name for name, letter in KINDS.items()}[match.group(1)]
        row, col = int(match.group(2)) - 1, int(match.group(3)) - 1
    else:
        if not (isinstance(entry, (tuple, list)) and len(entry) == 3):
            raise check.ParameterError("unknowns", f"unknowns: each entry must be (kind, row, col) or a name like 'm11'; got {entry!r}")
        kind, row, col = entry
        if kind not in KINDS:
            raise check.ParameterError("unknowns", f"unknowns: kind must be one of {', '.join(map(repr, KINDS))}; got {kind!r}")
        for index in (row, col):
            if not (isinstance(index, (int, np.integer)) and not isinstance(index, bool) and 0 <= index <= 2):
                raise check.ParameterError("unknowns", f"unknowns: row and col must be integers 0, 1 or 2 (0-based); got {entry!r}")
    return kind, min(int(row), int(col)), max(int(row), int(col))


@component(
    "parametrization",
    "inertia-entries",
    summary="The observer's model with some entries of M, D, K unknown: theta of eq. (8).",
    parameters=(
        Part("model", role="vessel", doc="The known model (M, D, K)."),
        Value(
            "unknowns",
            "strings",
            'The unknown entries, each (kind, row, col) with kind "mass", "damping" or "stiffness" and **0-based** row, col, or a paper-style name ("m11" = ("mass", 0, 0), 1-based).',
        ),
        Value("lower", "array", "Bounds of theta (the paper's (9)–(11)), in the SI units of units.", shape="(p,)"),
        Value("upper", "array", "Bounds of theta (the paper's (9)–(11)), in the SI units of units.", shape="(p,)"),
    ),
)
@final
class InertiaParametrization(eqx.Module):
    """The observer's model with some entries of M, D, K unknown: theta of eq. (8).

    Parameters
    ----------
    model : DPVessel
        The known model (M, D, K). Its values at the unknown entries are ignored:
        :meth:`matrices` replaces them by theta.
    unknowns : sequence of str
        The unknown entries, each ``(kind, row, col)`` with kind ``"mass"``,
        ``"damping"`` or ``"stiffness"`` and **0-based** row, col, or a paper-style
        name (``"m11"`` = ``("mass", 0, 0)``, 1-based). An off-diagonal entry stands
        for the symmetric pair (i, j) and (j, i), one parameter.
    lower, upper : array_like, shape (p,)
        Bounds of theta (the paper's (9)–(11)), in the SI units of :attr:`units`.

    Notes
    -----
    Checks (each a one-line ValueError naming the parameter): ``model`` is a
    DPVessel; every entry is valid and none repeats (a pair counts once); the bounds
    are finite with lower < upper; a diagonal mass entry has lower > 0; and M_hat is
    symmetric positive definite at every vertex of the box of the mass unknowns. M_hat
    is affine in theta and the SPD matrices form a convex cone, so the vertices
    suffice: M_hat is then SPD (invertible) everywhere in the box, in particular at
    both bounds of each diagonal entry. D_hat and K_hat are not required to be
    definite (the paper's D > 0 is a property of the vessel, not of the bounds).
    """

    model: DPVessel
    lower: Array
    upper: Array
    unknowns: tuple[tuple[str, int, int], ...] = eqx.field(static=True)

    def __init__(self, model: DPVessel, unknowns: _Unknown | Sequence[_Unknown], lower: npt.ArrayLike, upper: npt.ArrayLike):
        if not isinstance(model, DPVessel):
            raise check.ParameterError("model", f"model must be a DPVessel; got {type(model).__name__}")
        entries: Sequence[object] = unknowns  # the entries, each checked by _parse_unknown
        if isinstance(unknowns, (str, tuple)) and len(unknowns) == 3 and unknowns and unknowns[0] in KINDS:
            entries = (unknowns,)  # one entry given bare
        if isinstance(entries, str):
            entries = (entries,)
        parsed = tuple(_parse_unknown(entry) for entry in entries)
        if not parsed:
            raise check.ParameterError("unknowns", "unknowns must name at least one entry of M, D or K")
        if len(set(parsed)) != len(parsed):
            raise check.ParameterError(
                "unknowns", f"unknowns must be distinct (an off-diagonal entry counts for its symmetric pair); got {list(parsed)}"
            )
        self.model = model
        self.unknowns = parsed
        p = len(parsed)
        self.lower = jnp.asarray(check.vector("theta lower bound", lower, p))
        self.upper = jnp.asarray(check.vector("theta upper bound", upper, p))

    def __check_init__(self):
        check.finite("theta lower bound", self.lower)
        check.finite("theta upper bound", self.upper)
        if not (check.is_concrete(self.lower) and check.is_concrete(self.upper)):
            return
        lower, upper = np.asarray(self.lower), np.asarray(self.upper)
        for name, lo, hi in zip(self.names, lower, upper):
            if not lo < hi:
                raise check.ParameterError("theta", f"theta bounds of {name}: lower must be below upper; got lower {lo:.6g}, upper {hi:.6g}")
        for (kind, row, col), name, lo in zip(self.unknowns, self.names, lower):
            if kind == "mass" and row == col and not lo > 0:
                raise check.ParameterError("theta", f"theta lower bound of {name} must be positive (a diagonal mass entry); got {lo:.6g}")
        if not check.is_concrete(self.model.mass_matrix):
            return
        mass = [k for k, (kind, _, _) in enumerate(self.unknowns) if kind == "mass"]
        for corner in itertools.product((0, 1), repeat=len(mass)):
            theta = lower.copy()
            for k, high in zip(mass, corner):
                theta[k] = upper[k] if high else lower[k]
            m_hat = np.asarray(self.matrices(jnp.asarray(theta))[0])
            smallest = np.linalg.eigvalsh(0.5 * (m_hat + m_hat.T)).min()
            if not smallest > 0:
                where = ", ".join(f"{self.names[k]} = {theta[k]:.6g}" for k in mass)
                raise check.ParameterError(
                    "theta", f"theta bounds: M_hat must be positive definite in the whole box; at {where} its smallest eigenvalue is {smallest:.3g}"
                )

    @property
    def size(self) -> int:
        """p, the number of unknown parameters."""
        return len(self.unknowns)

    @property
    def names(self) -> tuple[str, ...]:
        """Paper-style names, 1-based: ``("m11",)``, ``("m11", "d23")``."""
        return tuple(f"{KINDS[kind]}{row + 1}{col + 1}" for kind, row, col in self.unknowns)

    @property
    def units(self) -> tuple[str, ...]:
        """SI units of each parameter (see :data:`UNITS`): e.g. kg for m11, kg m2 for m33."""
        return tuple(UNITS[kind][(row == 2) + (col == 2)] for kind, row, col in self.unknowns)

    @property
    def signals(self) -> tuple[Signal, ...]:
        """One scalar Signal ``theta_<name>`` per unknown, in its units."""
        return tuple(
            Signal(f"theta_{name}", units, f"estimate of the unknown {kind} entry {name} (theta_hat, eqs. 15, 67)")
            for name, units, (kind, _, _) in zip(self.names, self.units, self.unknowns)
        )

    def values(self, vessel: DPVessel) -> Array:
        """The entries of ``vessel`` that theta stands for (the true theta of a plant's vessel)."""
        matrices = {"mass": vessel.mass_matrix, "damping": vessel.damping_matrix, "stiffness": vessel.stiffness_matrix}
        return jnp.stack([jnp.asarray(matrices[kind][row, col], dtype=float) for kind, row, col in self.unknowns])

    def project(self, theta: Array) -> Array:
        """theta clipped to [lower, upper] (the projection onto the box)."""
        return jnp.clip(theta, self.lower, self.upper)

    def matrices(self, theta: Array) -> tuple[Array, Array, Array]:
        """(M_hat, D_hat, K_hat): the known model with the unknown entries set to theta
        (both entries of a symmetric pair)."""
        out = {"mass": self.model.mass_matrix, "damping": self.model.damping_matrix, "stiffness": self.model.stiffness_matrix}
        for k, (kind, row, col) in enumerate(self.unknowns):
            out[kind] = out[kind].at[row, col].set(theta[k]).at[col, row].set(theta[k])
        return out["mass"], out["damping"], out["stiffness"]

    def regressor(self, xi: Array, nu_hat: Array, eta_hat: Array) -> Array:
        """phi (3 x p) with ``M~ xi + D~ nu_hat + K~ eta_hat = phi theta~`` (eq. 8, C1).

        Column k is E_k v with E_k the 0/1 matrix of entry k (both (i, j) and
        (j, i) if off-diagonal) and v = xi (mass), nu_hat (damping) or eta_hat with
        its heading through ``ssa`` (stiffness, as the model's K eta). For
        theta = m11: phi = [xi_1, 0, 0]^T.
        """
        vectors = {"mass": xi, "damping": nu_hat, "stiffness": eta_hat.at[2].set(ssa(eta_hat[2]))}
        columns = []
        for kind, row, col in self.unknowns:
            v = vectors[kind]
            column = jnp.zeros(3, dtype=v.dtype).at[row].add(v[col])
            if row != col:
                column = column.at[col].add(v[row])
            columns.append(column)
        return jnp.stack(columns, axis=1)


class AdaptiveEstimate(eqx.Module):
    """An initial estimate for :meth:`AdaptiveObserver.init` (see :meth:`AdaptiveObserver.guess`).

    Attributes
    ----------
    eta : Array, shape (3,)
        eta_hat(0) = [x, y, psi] (m, m, rad).
    nu : Array, shape (3,)
        nu_hat(0) = [u, v, r] (m/s, m/s, rad/s).
    theta : Array, shape (p,)
        theta_hat(0), in the parametrization's units.
    """

    eta: Array
    nu: Array
    theta: Array


class AdaptiveObserverState(eqx.Module):
    """Internal state of :class:`AdaptiveObserver` (the same layout for both forms).

    Attributes
    ----------
    eta : Array, shape (3,)
        eta_hat (m, m, rad; heading wrapped to [-pi, pi) after each sample).
    nu : Array, shape (3,)
        nu_hat (m/s, m/s, rad/s).
    theta : Array, shape (p,)
        theta_hat. Discrete form: inside the bounds after ``update``; between
        ``predict`` and ``update`` it holds the partial step of (67).
    measured : Array, shape (3,)
        Discrete form: eta(i-1), the measurement (or its stand-in, when missing)
        that delta_eta is taken from and whose heading gives J(i-1). Continuous
        form: unused (the first sample, kept).
    expected : Array, shape (3,)
        Discrete form: eta(i-1) + Delta J(i-1) nu_hat(i-1), the stand-in for a
        missing channel of eta(i). Continuous form: unused.
    regressor : Array, shape (3, p)
        Discrete form: phi(i-1) of (67). Continuous form: unused (zeros).
    """

    eta: Array
    nu: Array
    theta: Array
    measured: Array
    expected: Array
    regressor: Array


def _angle_difference(a: Array, b: Array) -> Array:
    """a - b for [x, y, psi] vectors, heading through ssa."""
    d = a - b
    return d.at[2].set(ssa(d[2]))


@component(
    "observer",
    "adaptive-dp",
    summary="Adaptive observer of Calugi, Robertsson & Johansson (2003), eqs. (13)–(15) and (65)–(67).",
    family="lookout.tuning.families.adaptive_dp:AdaptiveDPFamily",
    parameters=(
        Part("parametrization", "The known model, the unknown entries and their bounds."),
        Value("position_gain", "array", "Diagonal of K1 (1/s), > 0.", shape="(3,)"),
        Value("velocity_gain", "array", "Diagonal of K2 (1/s), > 0.", shape="(3,)"),
        Value(
            "adaptation_gain",
            "array",
            "Gamma: a scalar (Gamma I), a diagonal, or a symmetric matrix; positive definite as in the paper, or 0 (semidefinite allowed) to switch adaptation off.",
            shape="(p,) or (p, p)",
        ),
        Value("form", "str", "(65)–(67) at the engine's sample period, or (13)–(15).", choices=("discrete", "continuous")),
        Value("initial_theta", "array", "theta_hat(0) used by guess when no theta is given; by default the midpoint of the bounds.", shape="(p,)"),
        Value("steps_per_sample", "int", "RK4 steps of the continuous form's predict per sample period."),
    ),
)
@final
class AdaptiveObserver(ContinuousObserver):
    """Adaptive observer of Calugi, Robertsson & Johansson (2003), eqs. (13)–(15) and (65)–(67).

    Estimates eta, nu and the unknown model entries theta from position and heading
    measurements (``form="discrete"``, implementable, Appendix A), or from eta and
    the true nu of the ORACLE :class:`~lookout.sensors.PositionHeadingVelocitySensor`
    (``form="continuous"``, eqs. (13)–(15), for analysis in simulation only). See
    the module docstring for time indices, projection and missing samples.

    Outputs: ``position``, ``heading``, ``velocity``, ``yaw_rate`` (estimates of
    the plant's variables, :data:`~lookout.models.vessel.VESSEL_SIGNALS`);
    ``theta_<name>`` per unknown (e.g. ``theta_m11`` in kg); ``innovation_position``
    and ``innovation_heading`` = eta - eta_hat at the sample.

    Parameters
    ----------
    parametrization : InertiaParametrization
        The known model, the unknown entries and their bounds.
    position_gain : float or array_like, shape (3,)
        Diagonal of K1 (1/s), > 0.
    velocity_gain : float or array_like, shape (3,)
        Diagonal of K2 (1/s), > 0.
    adaptation_gain : float, array_like (p,) or (p, p)
        Gamma: a scalar (Gamma I), a diagonal, or a symmetric matrix; positive
        definite as in the paper, or 0 (semidefinite allowed) to switch adaptation
        off.
    form : {"discrete", "continuous"}
        (65)–(67) at the engine's sample period, or (13)–(15).
    initial_theta : array_like, shape (p,), optional
        theta_hat(0) used by :meth:`guess` when no theta is given; by default the
        midpoint of the bounds. Must lie in the bounds.
    steps_per_sample : int
        RK4 steps of the continuous form's :meth:`predict` per sample period.
    """

    parametrization: InertiaParametrization
    position_gain: Array
    velocity_gain: Array
    adaptation_gain: Array
    initial_theta: Array
    form: str = eqx.field(static=True)
    steps_per_sample: int = eqx.field(static=True)
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    #: position and heading (discrete form), and nu as well (continuous form)
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    #: (65)-(67) are written for any sample interval Delta: the step the engine gives
    sample_period: None = eqx.field(static=True)

    def __init__(
        self,
        parametrization: InertiaParametrization,
        position_gain: npt.ArrayLike,
        velocity_gain: npt.ArrayLike,
        adaptation_gain: npt.ArrayLike,
        *,
        form: str = "discrete",
        initial_theta: npt.ArrayLike | None = None,
        steps_per_sample: int = 1,
    ):
        if not isinstance(parametrization, InertiaParametrization):
            raise check.ParameterError("parametrization", f"parametrization must be an InertiaParametrization; got {type(parametrization).__name__}")
        if form not in FORMS:
            raise check.ParameterError("form", f"form must be one of {', '.join(map(repr, FORMS))}; got {form!r}")
        if not (isinstance(steps_per_sample, int) and steps_per_sample >= 1):
            raise check.ParameterError("steps_per_sample", f"steps_per_sample must be a positive integer; got {steps_per_sample!r}")
        p = parametrization.size
        self.parametrization = parametrization
        self.position_gain = jnp.asarray(check.vector("position_gain (K1)", position_gain))
        self.velocity_gain = jnp.asarray(check.vector("velocity_gain (K2)", velocity_gain))
        gamma = jnp.asarray(adaptation_gain, dtype=float)
        if gamma.ndim == 0:
            gamma = gamma * jnp.eye(p)
        elif gamma.shape == (p,):
            gamma = jnp.diag(gamma)
        elif gamma.shape != (p, p):
            raise check.ParameterError(
                "adaptation_gain", f"adaptation_gain (Gamma) must be a scalar, a diagonal of {p} or a {p}x{p} matrix; got shape {gamma.shape}"
            )
        self.adaptation_gain = gamma
        if initial_theta is None:
            initial_theta = 0.5 * (parametrization.lower + parametrization.upper)
        self.initial_theta = jnp.asarray(check.vector("initial_theta", initial_theta, p))
        self.form = form
        self.steps_per_sample = steps_per_sample
        self.estimate_signals = ESTIMATE_SIGNALS
        self.extra_signals = parametrization.signals + INNOVATION_SIGNALS
        self.measurement_layout = POSITION_HEADING if form == "discrete" else POSITION_HEADING_VELOCITY
        self.input_layout, self.sample_period = VESSEL_INPUT, None

    def __check_init__(self):
        check.positive("position_gain (K1)", self.position_gain)
        check.positive("velocity_gain (K2)", self.velocity_gain)
        if check.is_concrete(self.adaptation_gain):
            gamma = np.asarray(self.adaptation_gain, dtype=float)
            check.finite("adaptation_gain (Gamma)", gamma)
            if np.abs(gamma - gamma.T).max() > 1e-12 * max(np.abs(gamma).max(), 1e-300):
                raise check.ParameterError("adaptation_gain", "adaptation_gain (Gamma) must be symmetric")
            smallest = np.linalg.eigvalsh(gamma).min()
            if smallest < -1e-12 * max(np.abs(gamma).max(), 1e-300):
                raise check.ParameterError(
                    "adaptation_gain",
                    f"adaptation_gain (Gamma) must be positive definite (or semidefinite, 0 = no adaptation); its smallest eigenvalue is {smallest:.3g}",
                )
        if check.is_concrete(self.initial_theta) and check.is_concrete(self.parametrization.lower):
            theta = np.asarray(self.initial_theta)
            lower, upper = np.asarray(self.parametrization.lower), np.asarray(self.parametrization.upper)
            check.finite("initial_theta", theta)
            if np.any(theta < lower) or np.any(theta > upper):
                raise check.ParameterError(
                    "initial_theta", f"initial_theta must lie in the theta bounds [{check._fmt(lower)}, {check._fmt(upper)}]; got {check._fmt(theta)}"
                )

    @classmethod
    def calugi_2003(
        cls, vessel: DPVessel, theta_bounds: Sequence[float] | None = None, initial_theta: npt.ArrayLike | None = None, **options: Any
    ) -> AdaptiveObserver:
        """The printed setting of Section V: theta = m11, K1 = K2 = 1e-3 I (1/s), Gamma = 1e3.

        The paper gives neither bounds nor a starting value for theta_hat. Chosen
        defaults: ``theta_bounds = (0.5 m11, 2 m11)`` and ``initial_theta =
        0.8 m11``, with m11 of ``vessel`` (the known model; for eq. (59) use
        :func:`~lookout.models.vessel.northern_clipper`, whose M is (59)'s and whose
        D differs from (59) by rounding: 5.0242e4 vs 5.024e4, -4.3933e6 vs
        -4.399e6). ``options``: ``form``, ``steps_per_sample``. Note Gamma = 1e3 is
        very slow in SI (derivations C1: a time constant of hours).
        """
        m11 = float(np.asarray(vessel.mass_matrix)[0, 0])
        lower, upper = theta_bounds if theta_bounds is not None else (0.5 * m11, 2.0 * m11)
        parametrization = InertiaParametrization(vessel, ("m11",), [lower], [upper])
        start = 0.8 * m11 if initial_theta is None else initial_theta
        return cls(parametrization, 1e-3, 1e-3, 1e3, initial_theta=start, **options)

    # Building blocks --------------------------------------------------------------
    @property
    def discrete(self) -> bool:
        return self.form == "discrete"

    @initial_values(
        Value("eta", "array", "Position north, east (m) and heading (rad); default the first measurement.", shape="(3,)"),
        Value("nu", "array", "Velocity surge, sway (m/s) and yaw rate (rad/s).", shape="(3,)"),
        Value("theta", "array", "theta_hat(0) (SI); default the observer's initial_theta.", shape="(p,)"),
    )
    def guess(self, eta: npt.ArrayLike | None = None, nu: npt.ArrayLike = 0.0, theta: npt.ArrayLike | None = None) -> AdaptiveEstimate:
        """An initial estimate (eta the first measurement unless given; nu zero unless
        given; theta :attr:`initial_theta` unless given), to pass to :meth:`init` through
        the Scenario.

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            Position north, east (m) and heading (rad); default the first measurement.
        nu : array_like, shape (3,)
            Velocity surge, sway (m/s) and yaw rate (rad/s).
        theta : array_like, shape (p,), optional
            theta_hat(0) (SI); default the observer's initial_theta.
        """
        theta = self.initial_theta if theta is None else theta
        return AdaptiveEstimate(
            jnp.asarray(check.vector("eta", eta)),
            jnp.asarray(check.vector("nu", nu)),
            jnp.asarray(check.vector("theta", theta, self.parametrization.size)),
        )

    def model_acceleration(self, theta: Array, eta_hat: Array, nu_hat: Array, tau: Array) -> Array:
        """xi = M_hat^-1 (tau - D_hat nu_hat - K_hat eta_hat) (eq. 14), heading of eta_hat through ssa."""
        m_hat, d_hat, k_hat = self.parametrization.matrices(theta)
        eta_wrapped = eta_hat.at[2].set(ssa(eta_hat[2]))
        return solve(m_hat, tau - matvec(d_hat, nu_hat) - matvec(k_hat, eta_wrapped))

    def _adapt(self, regressor: Array, velocity: Array) -> Array:
        """Gamma phi^T v."""
        return self.adaptation_gain @ (regressor.T @ velocity)

    def _check_measurement(self, y: Array) -> None:
        if not self.discrete and y.shape[-1] < 6:
            raise ValueError(
                f"form='continuous' needs position, heading AND velocity measurements (the oracle PositionHeadingVelocitySensor, 6 channels); got {y.shape[-1]} channels"
            )

    # The Observer contract -----------------------------------------------------------
    def init(self, y0: Array, guess: AdaptiveEstimate) -> AdaptiveObserverState:
        """The estimate at t_0 is the guess (theta_hat clipped to the bounds), eta_hat(0)
        = y0 where the guess leaves eta to the first measurement
        (:mod:`lookout.observers.start`); eta(0) = y0 is stored as the base of the first
        difference (a NaN channel of y0 is replaced by eta_hat(0))."""
        if not isinstance(guess, AdaptiveEstimate):
            raise ValueError(
                f"the initial estimate of an AdaptiveObserver must be an AdaptiveEstimate (observer.guess(...)); got {type(guess).__name__}"
            )
        y = jnp.asarray(y0, dtype=float)[:3]
        eta = from_first_measurement(jnp.asarray(guess.eta, dtype=float), y, angles=(2,))
        measured = jnp.where(jnp.isfinite(y), y, eta)
        measured = measured.at[2].set(ssa(measured[2]))
        p = self.parametrization.size
        return AdaptiveObserverState(
            eta=eta.at[2].set(ssa(eta[2])),
            nu=jnp.asarray(guess.nu, dtype=float),
            theta=self.parametrization.project(jnp.asarray(guess.theta, dtype=float)),
            measured=measured,
            expected=measured,
            regressor=jnp.zeros((3, p)),
        )

    def update(self, state: AdaptiveObserverState, t: ArrayLike, y: Array) -> AdaptiveObserverState:
        """Discrete form: the delta_eta terms of (66)–(67) and the projection of theta_hat.

        delta_eta = eta(i) - eta(i-1) (heading through ssa), with a missing channel
        of eta(i) replaced by ``state.expected``; then
        nu_hat += K2 J^T(i-1) delta_eta and theta_hat = proj(theta_hat - Gamma
        phi^T(i-1) J^T(i-1) delta_eta). Continuous form: the identity.
        """
        del t
        self._check_measurement(y)
        if not self.discrete:
            return state
        y = y[:3]
        eta_i = jnp.where(jnp.isfinite(y), y, state.expected)
        eta_i = eta_i.at[2].set(ssa(eta_i[2]))
        delta = _angle_difference(eta_i, state.measured)
        body = rotate_transpose(state.measured[2], delta)  # J^T(i-1) delta_eta(i)
        nu = state.nu + self.velocity_gain * body  # eq. (66), last term
        theta = self.parametrization.project(state.theta - self._adapt(state.regressor, body))  # eq. (67), last term
        return AdaptiveObserverState(state.eta, nu, theta, eta_i, eta_i, state.regressor)

    def innovation(self, state: AdaptiveObserverState, y: Array) -> Array:
        """eta - eta_hat at the sample (heading through ssa); 0 on missing channels."""
        y = y[:3]
        return jnp.where(jnp.isfinite(y), _angle_difference(y, state.eta), 0.0)

    def output(self, state: AdaptiveObserverState, y: Array) -> dict[str, Array]:
        """position, heading, velocity, yaw_rate, theta_<name> and the innovation."""
        self._check_measurement(y)
        innovation = self.innovation(state, y)
        out = {
            "position": state.eta[:2],
            "heading": state.eta[2],
            "velocity": state.nu[:2],
            "yaw_rate": state.nu[2],
            "innovation_position": innovation[:2],
            "innovation_heading": innovation[2],
        }
        for k, name in enumerate(self.parametrization.names):
            out[f"theta_{name}"] = state.theta[k]
        return out

    def predict(self, state: AdaptiveObserverState, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> AdaptiveObserverState:
        """From t_{i-1} to t_i with tau_{i-1} = ``u`` held; dt = Delta.

        Discrete form: the (i-1) terms of (65)–(67)::

            eta_hat   <- eta_hat + Delta [J(psi(i-1)) nu_hat + K1 eta~(i-1)]   (65), eta~ = 0 on missing channels
            nu_hat    <- (I - Delta K2) nu_hat + Delta xi(i-1)                 (66), first terms
            theta_hat <- theta_hat + Gamma phi^T(i-1) Delta nu_hat(i-1)         (67), first term

        storing phi(i-1) and the stand-in eta(i-1) + Delta J(i-1) nu_hat(i-1)
        (eta(i-1) is ``state.measured``, set by ``update``). Continuous form:
        ``steps_per_sample`` RK4 steps of :meth:`vector_field` with y and u held,
        heading wrapped and theta_hat clipped after each step.
        """
        self._check_measurement(y)
        if not self.discrete:
            field = lambda time, s: self.vector_field(time, s, y, u)
            return integrate_sample(field, t, state, dt, self.steps_per_sample, normalize=self.normalize, normalize_each_step=True)
        valid = jnp.isfinite(y[:3])
        eta_prev = state.measured  # eta(i-1), a stand-in on missing channels
        psi = eta_prev[2]
        eta_tilde = jnp.where(valid, _angle_difference(eta_prev, state.eta), 0.0)
        xi = self.model_acceleration(state.theta, state.eta, state.nu, u)
        phi = self.parametrization.regressor(xi, state.nu, state.eta)
        moved = rotate(psi, state.nu)  # J(i-1) nu_hat(i-1)
        eta = state.eta + dt * (moved + self.position_gain * eta_tilde)  # eq. (65), corrected to K1 eta~
        nu = state.nu + dt * (xi - self.velocity_gain * state.nu)  # eq. (66), first terms
        theta = state.theta + dt * self._adapt(phi, state.nu)  # eq. (67), first term
        expected = eta_prev + dt * moved
        return AdaptiveObserverState(
            eta=eta.at[2].set(ssa(eta[2])),
            nu=nu,
            theta=theta,
            measured=eta_prev,
            expected=expected.at[2].set(ssa(expected[2])),
            regressor=phi,
        )

    def vector_field(self, t: ArrayLike, state: AdaptiveObserverState, y: Array, u: Array) -> AdaptiveObserverState:
        """Eqs. (13)–(15) with y = [eta, nu] from the oracle sensor and tau = ``u``.

        theta_hat' is projected: set to 0 componentwise where theta_hat is at (or
        beyond) a bound and the rate points out of the box; M_hat, xi and phi are
        evaluated at theta_hat clipped to the box (an RK4 stage may step outside
        it, where M_hat need not be invertible). Missing channels give
        zero injection; J uses eta_hat's heading when the heading is missing.
        Only the continuous form has a vector field.
        """
        del t
        if self.discrete:
            raise ValueError(
                "form='discrete' has no vector field: simulate it with observer_mode='sampled', or build the observer with form='continuous'"
            )
        self._check_measurement(y)
        eta, nu = y[:3], y[3:6]
        eta_tilde = jnp.where(jnp.isfinite(eta), _angle_difference(eta, state.eta), 0.0)
        nu_tilde = jnp.where(jnp.isfinite(nu), nu - state.nu, 0.0)
        psi = jnp.where(jnp.isfinite(eta[2]), eta[2], state.eta[2])
        # the model at the clipped theta_hat: an RK4 stage may step outside the box,
        # where M_hat need not be invertible
        xi = self.model_acceleration(self.parametrization.project(state.theta), state.eta, state.nu, u)
        phi = self.parametrization.regressor(xi, state.nu, state.eta)
        eta_rate = rotate(psi, state.nu) + self.position_gain * eta_tilde  # eq. (13)
        nu_rate = xi + self.velocity_gain * nu_tilde  # eq. (14)
        theta_rate = -self._adapt(phi, nu_tilde)  # eq. (15)
        lower, upper = self.parametrization.lower, self.parametrization.upper
        outward = ((state.theta >= upper) & (theta_rate > 0)) | ((state.theta <= lower) & (theta_rate < 0))
        theta_rate = jnp.where(outward, 0.0, theta_rate)
        zero = jnp.zeros_like
        return AdaptiveObserverState(eta_rate, nu_rate, theta_rate, zero(state.measured), zero(state.expected), zero(state.regressor))

    def normalize(self, state: AdaptiveObserverState) -> AdaptiveObserverState:
        """Heading of eta_hat wrapped to [-pi, pi) and theta_hat clipped to the bounds."""
        return eqx.tree_at(lambda s: (s.eta, s.theta), state, (state.eta.at[2].set(ssa(state.eta[2])), self.parametrization.project(state.theta)))
