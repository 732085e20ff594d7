"""Thrust allocation: the thrusters' commands that produce a generalized force tau.

Two methods over a :class:`~lookout.actuators.layout.ThrusterLayout`'s extended
variables u (tau = B u: a tunnel's thrust, an azimuth's force components, a main
propeller's thrust and rudder lift), after Fossen, *Handbook of Marine Craft
Hydrodynamics and Motion Control* (Wiley, 2011), Section 12.3 (control allocation),
and Johansen, Fossen & Berge, "Constrained nonlinear control allocation with
singularity avoidance using sequential quadratic programming", IEEE TCST 12(1), 2004
(a QP per sample with thrust, rate and turning limits and a slack on tau):

``"pseudo-inverse"``
    The weighted least-squares solution u = W^-1 B^T (B W^-1 B^T)^-1 tau, the
    least-weighted u that produces tau exactly (W: each thruster's weight over its
    largest thrust squared), then each thruster saturated on its own (force and rate
    limits; an azimuth told the direction of its force, which it turns to at its
    rate while pushing): the classical unconstrained allocation. Its azimuths follow
    every turn of tau, noise included.
``"qp"``
    The azimuths are *steered* (below): each turns slowly, if at all, and at each
    sample the QP allocates the thrust along the steered angles,

        minimize  (u - u_b)^T W (u - u_b) + s^T Q s   subject to  B u = tau + s,  u in the limits

    with u_b the azimuths' bias (below; 0 without one) and the slack s weighted by
    Q = ``slack_weight`` (tau scaled per axis): when tau cannot be produced, the
    thrusters produce the tau closest to it in the Q-weighted norm. The QP's target
    is tau moved by Q^-1 (B W^-1 B^T)^-1 tau (a part in ``slack_weight`` of tau),
    which makes its unconstrained optimum u_b + W^-1 B^T (B W^-1 B^T)^-1 tau exactly
    (the biased least-squares solution, which produces tau): where that solution
    meets every limit it is the allocation, and the allocation is continuous where it
    passes to the QP's. The limits, all linear and all met by a start point built
    from the previous command (so :func:`lookout.actuators.qp.active_set` can start
    there):

    - a tunnel's and a main propeller's thrust in [min_thrust, max_thrust] (a main
      propeller ahead after ahead, so that its rudder's lift stays convex) and within
      thrust_rate dt of its previous command;
    - a rudder's lift within the rudder angles reachable in dt, |delta| <= max_rudder,
      ahead only (L = rudder_lift delta T);
    - an azimuth's force along its steered angle (none across it), its thrust in
      [0, max_thrust] (the thrust circle, exactly) and within thrust_rate dt of its
      previous command.

    Whatever the QP commands is delivered after one sample, up to the thrust lag.

Azimuth steering and bias (``"qp"``)
    Sørdalen, "Optimal thrust allocation for marine vessels", Control Eng. Practice
    5(9), 1997, filters the azimuths' directions so that they align with the
    direction where most force is required instead of following every change of the
    command, to spare the thrusters' wear and tear (Fossen, 2011, Section 12.3;
    Johansen & Fossen, "Control allocation - a survey", Automatica 49(5), 2013, count
    such turning among the costs an allocation should keep low); DP systems also
    *bias* azimuths, pushing them against each other so that a small force of either
    sign is a change of thrust, not a turn. lookout's form of both (the filter, the
    rules and the null-space bias are lookout's choices, not equations of the papers):

    1. the bias u_b is the part of ``steering_bias`` max_thrust along each azimuth's
       ``direction`` that produces no force: s projected onto the null space of B,
       u_b = s - W^-1 B^T (B W^-1 B^T)^-1 B s (so azimuths whose directions oppose
       bias each other, and the tunnels take up the moment of the pair; azimuths
       pointing the same way have no bias);
    2. the demand d is tau through a first-order low-pass of time constant
       ``steering_time_constant``: d_k = d_k-1 + (1 - exp(-dt / T_s)) (tau_k - d_k-1);
    3. azimuth i wants the direction of its force f_i in u_b + W^-1 B^T (B W^-1 B^T)^-1 d,
       under a load |f_i| / max_thrust_i;
    4. it holds its angle unless its load exceeds ``steering_load`` and it points
       more than ``steering_deadband`` away from that direction; then it turns toward
       it at its turning rate until it points there (a turn once begun is finished
       unless the load falls below ``steering_load``).

    So an idle or lightly loaded azimuth holds its angle, force at the wave frequency
    or noise in tau hardly moves d, and a turn begins only when the steady demand has
    turned by the deadband; the fast part of tau is thrust along the held angles.

Variables, tau and slack are scaled (each variable by its largest magnitude, each
axis of tau by :attr:`ThrusterLayout.force_scale`) so the QP is equally well
conditioned for a model ship and a supply vessel.

What the allocation reports per sample: ``shortfall``, the largest part of tau it
left unproduced, |tau - B u| on an axis as a fraction of that axis's reach
(:attr:`Allocator.axis_reach`); ``saturated``, a shortfall above :data:`SATURATED`:
the limits (force, rate, turning) kept the allocation from producing tau.
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple, cast, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa
from lookout._resources import refuse_unless_it_fits
from lookout.actuators.box_qp import FREE, MOST_VARIABLES, box_qp
from lookout.actuators.layout import ThrusterLayout, direction_of, magnitude
from lookout.actuators.qp import active_set

ALLOCATION_METHODS = ("qp", "pseudo-inverse")
QP_SOLVERS = ("active-set", "active-set-general", "qpax")
#: A scaled force below this is no direction (an idle thruster's rounding).
IDLE = 1e-3
#: A sample is saturated when the allocation leaves more than this fraction of an
#: axis's reach unproduced (6 kN of the supply vessel's 600 kN in surge): a
#: shortfall visible on the thrusters' figure. A QP whose limits bind but still
#: produce tau leaves about 1 / slack_weight (1e-6 by default) for the slack.
SATURATED = 1e-2
#: The QP's defaults, and why:
#: slack_weight: tau is produced to about a millionth of its scale whenever the limits allow it.
DEFAULT_SLACK_WEIGHT = 1e6
#: steering_time_constant (s): longer than a DP sea state's wave periods (about 5 to
#: 12 s), so the filter passes a wave-frequency force at a fifth of its amplitude or
#: less (1 / sqrt(1 + (2 pi 10 / 12)^2) = 0.19 at 12 s), and short enough that the
#: filtered demand reaches 95 % of a step (a setpoint move, a change of the weather)
#: in 30 s.
DEFAULT_STEERING_TIME_CONSTANT = 10.0
#: steering_deadband (rad), 10 deg: an azimuth held up to 10 deg off the wanted
#: direction still gives cos(10 deg) = 98.5 % of its thrust along it, and the
#: 17 % across it is a force the other thrusters absorb.
DEFAULT_STEERING_DEADBAND = math.radians(10.0)
#: steering_load: below 5 % of its largest thrust (1 % of its power, |T|^1.5) an
#: azimuth's steady demand is not worth a turn; its direction is then mostly noise
#: left by the filter.
DEFAULT_STEERING_LOAD = 0.05
#: steering_bias: 30 % of an azimuth's largest thrust (16 % of its power), so that a
#: pair pushing against each other answers a force of either sign up to 60 % of one
#: azimuth's thrust along their line with a change of thrust at the thrust rate, not
#: a turn of 180 degrees at the turning rate (measured against 20 % on
#: examples/thrusters-dp.toml: half the turning for a tenth more power; docs/thrusters.md).
DEFAULT_STEERING_BIAS = 0.3
#: A layout of at most this many thrusters keeps the weighted pseudo-inverse over every
#: subset of them (2^8 = 256 of n x 3 at most), so that a failed thruster costs a look-up,
#: not a singular value decomposition, at each sample.
SUBSET_TABLE_THRUSTERS = 8


class _QPTerms(NamedTuple):
    """The arrays of allocation ``"qp"`` (see :class:`Allocator`), none of them None."""

    slack_weights: Array | np.ndarray
    P: Array | np.ndarray
    target_matrix: Array | np.ndarray
    steering_time_constant: Array | np.ndarray
    steering_deadband: Array | np.ndarray
    steering_load: Array | np.ndarray
    bias: Array | np.ndarray


class _Indices(NamedTuple):
    """Static index arrays of the extended variables, by kind of thruster."""

    tunnel: np.ndarray  # thruster indices
    tunnel_thrust: np.ndarray  # variable indices
    main: np.ndarray
    main_thrust: np.ndarray
    main_lift: np.ndarray
    azimuth: np.ndarray
    azimuth_x: np.ndarray
    azimuth_y: np.ndarray


def _indices(layout: ThrusterLayout) -> _Indices:
    position = {variable: j for j, variable in enumerate(layout.variables)}
    kinds = np.asarray(layout.kinds)

    def of(kind, part=None):
        thrusters = np.flatnonzero(kinds == kind)
        if part is None:
            return thrusters
        return np.asarray([position[(int(i), part)] for i in thrusters], dtype=int)

    return _Indices(
        of("tunnel"),
        of("tunnel", "thrust"),
        of("main"),
        of("main", "thrust"),
        of("main", "lift"),
        of("azimuth"),
        of("azimuth", "x"),
        of("azimuth", "y"),
    )


def limit_rows(layout: ThrusterLayout) -> int:
    """Rows of the QP's limits: 2 per tunnel (thrust), 4 per main propeller (thrust
    and lift), 4 per azimuth (thrust, and none across its angle).

    Parameters
    ----------
    layout : ThrusterLayout
        The thrusters.

    Returns
    -------
    int
        The number of rows of :meth:`Allocator.constraints`.
    """
    count = {kind: int(np.sum(layout.is_kind(kind))) for kind in ("tunnel", "main", "azimuth")}
    return 2 * count["tunnel"] + 4 * count["main"] + 4 * count["azimuth"]


def working_nbytes(layout: ThrusterLayout, method: str = "qp") -> int:
    """Bytes one allocation holds, float64, with n variables and m limit rows: its
    matrices (B and the pseudo-inverse, 3 x n each; the QP's P and its inverse, n x n; with at most
    :data:`SUBSET_TABLE_THRUSTERS` thrusters T, the 2^T pseudo-inverses and biases over subsets of them) and one sample's
    work: the limits G (m x n) and the QP's solves, bounded by KKT systems of (2n x 2n)
    each with their LU factors, for the warm start's solve, the iterations' and the
    final one (six such matrices at most live at once; the range-space solves the
    active-set method takes with P's inverse hold n x n ones; :mod:`lookout.actuators.qp`),
    and vectors of n and m. The pseudo-inverse holds the 3 x n matrices and vectors only. The reach is in
    closed form (:meth:`Allocator._reach`, O(n)): there is no linear program to hold.

    Computed from the layout's size alone, before anything of that size is allocated
    (:class:`Allocator` refuses a layout whose allocation does not fit the memory
    available).

    Parameters
    ----------
    layout : ThrusterLayout
        The thrusters.
    method : {"qp", "pseudo-inverse"}
        The allocation method.

    Returns
    -------
    int
        Bytes.
    """
    n, m = len(layout.variables), limit_rows(layout)
    floats = 8 * n + 16 * (n + m) + 64
    if layout.size <= SUBSET_TABLE_THRUSTERS:
        floats += 2**layout.size * 4 * n  # the tables of the pseudo-inverse and bias over subsets of thrusters
    if method == "qp":
        floats += 2 * n * n + m * n + 6 * (2 * n) ** 2
    return 8 * floats


@final
class Allocator(eqx.Module):
    """Thrust allocation for one layout (see the module docstring for the methods).

    Parameters
    ----------
    layout : ThrusterLayout
        The thrusters.
    method : {"qp", "pseudo-inverse"}
        The allocation method.
    slack_weight : float or array_like, shape (3,), optional
        ``"qp"`` only. Weight of the squared scaled slack (surge, sway, yaw) against
        the squared scaled thrust; positive (default :data:`DEFAULT_SLACK_WEIGHT`).
        Large: tau is produced whenever the limits allow it (within about
        1/slack_weight of its scale); unequal: the axis with the larger weight is
        kept first when tau cannot be produced.
    clip_to_reach : bool
        Clip each axis of tau to what the thrusters can produce on that axis alone
        (:attr:`reach`) before allocating, as a per-axis saturation would: a command
        far beyond the thrusters' reach on one axis then does not take the thrust
        another axis needs. False allocates tau as it comes.
    solver : {"active-set", "active-set-general", "qpax"}, optional
        ``"qp"`` only. The QP's solver: lookout's active-set method (exact, and cheap
        when few limits change from sample to sample; the default), in its bounds-only
        form (:mod:`lookout.actuators.box_qp`, each azimuth's force one variable along
        its steered angle) for a layout of tunnels and azimuths
        (:attr:`bounds_only`), in its general form (:mod:`lookout.actuators.qp`) for
        one with main propellers; ``"active-set-general"``, the general form whatever
        the layout (the same allocation, slower: for comparison); or qpax's primal-dual
        interior-point method (Tracy & Manchester, 2024; the ``qpax`` package,
        installed with lookout's ``dev`` extra), for comparison.
    steering_time_constant : float, optional
        ``"qp"`` only. Time constant of the low-pass filter on tau whose allocation
        the azimuths turn toward (s); non-negative, 0 for none (default
        :data:`DEFAULT_STEERING_TIME_CONSTANT`).
    steering_deadband : float, optional
        ``"qp"`` only. Angle an azimuth may point away from its filtered direction
        before it turns (rad); in [0, pi] (default :data:`DEFAULT_STEERING_DEADBAND`).
    steering_load : float, optional
        ``"qp"`` only. Filtered load (a fraction of the azimuth's largest thrust) below
        which an azimuth holds its angle; in [0, 1] (default
        :data:`DEFAULT_STEERING_LOAD`).
    steering_bias : float, optional
        ``"qp"`` only. Thrust (a fraction of its largest) each azimuth puts along its
        layout ``direction``, of which the part that produces no force is its bias
        u_b; in [0, 1) (default :data:`DEFAULT_STEERING_BIAS`; 0 for none).
    """

    layout: ThrusterLayout
    # NumPy arrays when built, JAX arrays once traced
    B: Array | np.ndarray  # scaled: tau / force_scale = B (u / scale)
    scale: Array | np.ndarray  # each variable's largest magnitude (N)
    force_scale: Array | np.ndarray
    weights: Array | np.ndarray
    pseudo_inverse_matrix: Array | np.ndarray
    reach: Array | np.ndarray  # (2, 3) scaled: the smallest and largest of each axis alone
    slack_weights: Array | np.ndarray | None
    P: Array | np.ndarray | None
    P_inverse: Array | np.ndarray | None  # for the active-set method's range-space solves
    target_matrix: Array | np.ndarray | None  # the QP's target from the scaled tau (see the module docstring)
    steering_time_constant: Array | np.ndarray | None
    steering_deadband: Array | np.ndarray | None
    steering_load: Array | np.ndarray | None
    bias: Array | np.ndarray | None  # u_b, scaled
    # with at most SUBSET_TABLE_THRUSTERS thrusters: per subset of them left (a bit per thruster),
    # the weighted pseudo-inverse over it and the bias's part that produces no force with it
    subset_pseudo_inverse: Array | np.ndarray | None
    subset_bias: Array | np.ndarray | None
    method: str = eqx.field(static=True)
    clip_to_reach: bool = eqx.field(static=True)
    solver: str | None = eqx.field(static=True)

    def __init__(
        self,
        layout: ThrusterLayout,
        method: Literal["qp", "pseudo-inverse"] = "qp",
        slack_weight: npt.ArrayLike | None = None,
        clip_to_reach: bool = True,
        solver: Literal["active-set", "active-set-general", "qpax"] | None = None,
        steering_time_constant: float | None = None,
        steering_deadband: float | None = None,
        steering_load: float | None = None,
        steering_bias: float | None = None,
    ):
        if not isinstance(layout, ThrusterLayout):
            raise check.ParameterError("layout", f"layout must be a ThrusterLayout; got {type(layout).__name__}")
        if method not in ALLOCATION_METHODS:
            raise check.ParameterError("allocation", f"allocation must be one of {', '.join(ALLOCATION_METHODS)}; got {method!r}")
        qp_options = dict(
            slack_weight=slack_weight,
            solver=solver,
            steering_time_constant=steering_time_constant,
            steering_deadband=steering_deadband,
            steering_load=steering_load,
            steering_bias=steering_bias,
        )
        if method != "qp":
            for name, value in qp_options.items():
                if value is not None:
                    raise check.ParameterError(
                        check.key(name),
                        f"{name} applies to allocation 'qp' only, and this allocation is {method!r}: leave {name} out, or allocate by 'qp'",
                    )
        self.method, self.clip_to_reach = method, bool(clip_to_reach)
        variables, rows = len(layout.variables), limit_rows(layout)
        refuse_unless_it_fits(
            working_nbytes(layout, method),
            f"the allocation of {layout.size} thrusters ({variables} variables, {rows} limits)",
            "use fewer thrusters (the QP's matrices grow as the square of the variables: one per tunnel, two per azimuth or main propeller)",
        )
        self.layout = layout
        self.scale, self.force_scale = layout.variable_scale, layout.force_scale
        self.B = layout.B * self.scale[None, :] / self.force_scale[:, None]
        self.weights = np.array([layout.weight[i] for i, _ in layout.variables])
        inverse_weighted = self.B.T / self.weights[:, None]  # W^-1 B^T, without the n x n W^-1
        gram = self.B @ inverse_weighted
        self.pseudo_inverse_matrix = inverse_weighted @ np.linalg.inv(gram)
        self.reach = self._reach()
        if method != "qp":
            self.solver = None
            self.slack_weights = self.P = self.P_inverse = self.target_matrix = None
            self.steering_time_constant = self.steering_deadband = self.steering_load = self.bias = None
            self.subset_pseudo_inverse, self.subset_bias = self._subset_tables()
            return
        solver = "active-set" if solver is None else solver
        if solver not in QP_SOLVERS:
            raise check.ParameterError("solver", f"solver must be one of {', '.join(QP_SOLVERS)}; got {solver!r}")
        if solver == "qpax":
            try:
                import qpax  # noqa: F401
            except ImportError:
                raise check.ParameterError("solver", "solver 'qpax' needs the qpax package (pip install qpax, or lookout's dev extra)") from None
        self.solver = solver
        slack_weight = DEFAULT_SLACK_WEIGHT if slack_weight is None else slack_weight
        try:
            slack = np.broadcast_to(np.asarray(slack_weight, dtype=float), (3,)).copy()
        except (TypeError, ValueError):
            slack = np.full(3, np.nan)
        if not np.all(np.isfinite(slack)) or np.any(slack <= 0):
            raise check.ParameterError(
                "slack_weight", f"slack_weight must be a positive number or three of them (surge, sway, yaw); got {_brief(slack_weight)}"
            )
        self.slack_weights = slack
        # (u - u_b)^T W (u - u_b) + (B u - t')^T Q (B u - t') = u^T P u - 2 (W u_b + B^T Q t')^T u + const
        self.P = np.diag(self.weights) + self.B.T @ np.diag(slack) @ self.B
        self.P_inverse = np.linalg.inv(self.P)
        # stationarity W (u - u_b) + B^T Q (B u - t') = 0 holds at u = u_b + W^-1 B^T lam,
        # lam = (B W^-1 B^T)^-1 t (B u_b = 0, so B u = t), for t' = t + Q^-1 lam: the penalty
        # QP's unconstrained optimum is the biased least-squares one
        self.target_matrix = np.eye(3) + np.diag(1.0 / slack) @ np.linalg.inv(gram)
        self.steering_time_constant = _option("steering_time_constant", steering_time_constant, DEFAULT_STEERING_TIME_CONSTANT, 0.0, math.inf)
        self.steering_deadband = _option("steering_deadband", steering_deadband, DEFAULT_STEERING_DEADBAND, 0.0, math.pi)
        self.steering_load = _option("steering_load", steering_load, DEFAULT_STEERING_LOAD, 0.0, 1.0)
        bias = float(_option("steering_bias", steering_bias, DEFAULT_STEERING_BIAS, 0.0, 1.0, high_included=False))
        index = self.indices
        wanted = np.zeros(variables)
        wanted[index.azimuth_x] = bias * np.cos(layout.direction[index.azimuth])
        wanted[index.azimuth_y] = bias * np.sin(layout.direction[index.azimuth])
        self.bias = wanted - self.pseudo_inverse_matrix @ (self.B @ wanted)  # its part in the null space of B
        self.subset_pseudo_inverse, self.subset_bias = self._subset_tables()

    @property
    def size(self) -> int:
        """Number of extended variables."""
        return self.B.shape[1]

    @property
    def indices(self) -> _Indices:
        """The extended variables' indices by kind of thruster (static NumPy arrays)."""
        return _indices(self.layout)

    def _qp_terms(self) -> _QPTerms:
        """The arrays that allocation ``"qp"`` sets (``"pseudo-inverse"`` leaves them None)."""
        slack, P, target_matrix, bias = self.slack_weights, self.P, self.target_matrix, self.bias
        time_constant, deadband, load = self.steering_time_constant, self.steering_deadband, self.steering_load
        if slack is None or P is None or target_matrix is None or bias is None or time_constant is None or deadband is None or load is None:
            raise check.ParameterError(
                "allocation", f"the QP's terms and the azimuth steering belong to allocation 'qp'; this allocation is {self.method!r}"
            )
        return _QPTerms(slack, P, target_matrix, time_constant, deadband, load, bias)

    @property
    def working_nbytes(self) -> int:
        """Bytes one run's allocation holds while stepping (:func:`working_nbytes`)."""
        return working_nbytes(self.layout, self.method)

    def target(self, tau: Array) -> tuple[Array, Array]:
        """``(wanted, target)``: tau scaled per axis, and clipped to :attr:`reach` with
        ``clip_to_reach``."""
        wanted = jnp.asarray(tau) / self.force_scale
        return wanted, (jnp.clip(wanted, self.reach[0], self.reach[1]) if self.clip_to_reach else wanted)

    # -- azimuth steering ---------------------------------------------------------------------

    def steer(
        self,
        demand: Array,
        angle: Array,
        turning: Array,
        tau: Array,
        dt: ArrayLike,
        fraction: Array | None = None,
        frozen: Array | None = None,
        held: Array | None = None,
    ) -> tuple[Array, Array, Array]:
        """One sample of the azimuth steering (module docstring): ``(demand, angle,
        turning)`` after tau arrives, from the scaled filtered ``demand`` (3,), the
        thrusters' ``angle`` (n,) and whether each azimuth is ``turning`` (n,).

        The returned angle is each azimuth's angle at the end of the sample (within
        turn_rate dt of ``angle``); the other thrusters' entries are ``angle``'s. A
        non-finite tau leaves the demand as it was. With failed thrusters (``fraction``,
        ``frozen`` and the stuck ones' ``held`` scaled force, as :meth:`allocate` takes
        them) the wanted directions are those of the thrusters that remain, for the
        demand less the stuck ones' force, and a failed azimuth does not turn."""
        layout, index, qp = self.layout, self.indices, self._qp_terms()
        _, target = self.target(tau)
        time_constant = qp.steering_time_constant
        gain = jnp.where(time_constant > 0, -jnp.expm1(-jnp.asarray(dt) / jnp.where(time_constant > 0, time_constant, 1.0)), 1.0)
        demand = jnp.where(jnp.all(jnp.isfinite(target)), demand + gain * (target - demand), demand)
        if index.azimuth.size == 0:
            return demand, angle, turning
        wished = self.pseudo_inverse_matrix @ demand + qp.bias  # scaled: an azimuth's force as a fraction of its largest
        failed = jnp.zeros(index.azimuth.size, dtype=bool)
        if fraction is not None and frozen is not None:
            owner = np.asarray([i for i, _ in layout.variables], dtype=int)
            available, pseudo_inverse, remaining = self._available(fraction, frozen)
            pinned = jnp.where(frozen[owner] & (fraction[owner] > 0.0), jnp.zeros(self.size) if held is None else held, 0.0)
            wished = jnp.where(jnp.any(~available), pseudo_inverse @ (demand - jnp.asarray(self.B) @ pinned) + remaining, wished)
            failed = (fraction == 0.0)[index.azimuth] | frozen[index.azimuth]
        fx, fy = wished[index.azimuth_x], wished[index.azimuth_y]
        current = angle[index.azimuth]
        error = ssa(direction_of(fx, fy, current) - current)
        reachable = jnp.asarray(layout.turn_rate[index.azimuth]) * dt
        turn = (magnitude(fx, fy) > qp.steering_load) & (turning[index.azimuth] | (jnp.abs(error) > qp.steering_deadband)) & ~failed
        steered = jnp.where(turn, ssa(current + jnp.clip(error, -reachable, reachable)), current)
        return demand, angle.at[index.azimuth].set(steered), turning.at[index.azimuth].set(turn & (jnp.abs(error) > reachable))

    # -- the limits --------------------------------------------------------------------------

    def constraints(
        self, previous: Array, angle: Array, dt: ArrayLike, fraction: Array | None = None, frozen: Array | None = None
    ) -> tuple[Array, Array, Array]:
        """``(G, h, start)``: the limits G u <= h on the scaled command after the scaled
        ``previous`` command, with the azimuths at their steered ``angle`` and the rudders
        at theirs, over a step ``dt``, and a scaled command that meets them all (see the
        module docstring). Rows: each tunnel's and main propeller's thrust (upper, then
        lower), each main propeller's lift (upper, lower), each azimuth's thrust
        (upper, lower) and its force across its angle (<= 0, >= 0).

        Failed thrusters (:mod:`lookout.actuators.failures`): ``fraction`` (n_thrusters,)
        scales each thruster's force limits (0: stopped, its variables held at 0; 1:
        intact) and its previous command into them; a ``frozen`` (stuck) thruster
        neither changes its thrust nor turns, so its variables are held at ``previous``
        (its held force, which the caller gives there). Both None: every thruster intact."""
        layout, index, n = self.layout, self.indices, self.size
        previous = jnp.asarray(previous, dtype=float)
        failed = fraction is not None or frozen is not None
        fraction = jnp.ones(layout.size) if fraction is None else jnp.asarray(fraction, dtype=float)
        frozen = jnp.zeros(layout.size, dtype=bool) if frozen is None else jnp.asarray(frozen)
        if failed and (index.tunnel.size or index.main.size):
            # a reduced or stopped thruster's previous thrust into its new limits (as a where,
            # so an intact one's is its own bits)
            thrusters = np.concatenate([index.tunnel, index.main])
            variables = np.concatenate([index.tunnel_thrust, index.main_thrust])
            share = fraction[thrusters]
            clipped = jnp.clip(
                previous[variables],
                share * layout.min_thrust[thrusters] / self.scale[variables],
                share * layout.max_thrust[thrusters] / self.scale[variables],
            )
            previous = previous.at[variables].set(jnp.where(share < 1.0, clipped, previous[variables]))
        start = previous
        rows, columns, entries, bounds = [], [], [], []
        count = 0

        def add(column_values, bound):
            # one row per entry of ``bound``; column_values: [(variable indices, values), ...]
            nonlocal count
            size = len(bound)
            for variables, values in column_values:
                rows.append(np.arange(count, count + size))
                columns.append(np.asarray(variables))
                entries.append(jnp.broadcast_to(jnp.asarray(values, dtype=float), (size,)))
            bounds.append(bound)
            count += size

        # thrust of tunnels and main propellers: the force and rate limits
        thrusters = np.concatenate([index.tunnel, index.main])
        variables = np.concatenate([index.tunnel_thrust, index.main_thrust])
        if thrusters.size:
            step = jnp.asarray(layout.thrust_rate[thrusters]) * dt / self.scale[variables]
            smallest, largest = layout.min_thrust[thrusters] / self.scale[variables], layout.max_thrust[thrusters] / self.scale[variables]
            if failed:
                step = jnp.where(frozen[thrusters], 0.0, step)
                smallest, largest = fraction[thrusters] * smallest, fraction[thrusters] * largest
            low = jnp.maximum(smallest, previous[variables] - step)
            main = np.asarray(layout.is_kind("main"))[thrusters]
            low = jnp.where(main & (previous[variables] > 0), jnp.maximum(low, 0.0), low)
            high = jnp.minimum(largest, previous[variables] + step)
            add([(variables, 1.0)], high)
            add([(variables, -1.0)], -low)
        # a rudder's lift L / (k d_max T_max) between (delta -+ turn) / d_max times T / T_max; astern L = 0
        if index.main.size:
            jt, jl, i = index.main_thrust, index.main_lift, index.main
            reachable = jnp.asarray(layout.turn_rate[i]) * dt
            if failed:
                reachable = jnp.where(frozen[i], 0.0, reachable)
            ahead = previous[jt] > 0
            largest = jnp.asarray(layout.max_rudder[i])
            high = jnp.where(ahead, jnp.minimum(angle[i] + reachable, largest) / largest, 0.0)
            low = jnp.where(ahead, jnp.maximum(angle[i] - reachable, -largest) / largest, 0.0)
            add([(jl, 1.0), (jt, -high)], jnp.zeros(i.size))
            add([(jl, -1.0), (jt, low)], jnp.zeros(i.size))
            start = start.at[jl].set(angle[i] / largest * jnp.maximum(previous[jt], 0.0))
        # an azimuth's force along its steered angle, its thrust within its circle and rate
        if index.azimuth.size:
            jx, jy, i = index.azimuth_x, index.azimuth_y, index.azimuth
            c, s = jnp.cos(angle[i]), jnp.sin(angle[i])
            along0 = jnp.minimum(magnitude(previous[jx], previous[jy]), 1.0)
            step = jnp.asarray(layout.thrust_rate[i]) * dt / self.scale[jx]
            circle = jnp.ones(i.size)
            if failed:
                circle = fraction[i]
                along0 = jnp.where(circle < 1.0, jnp.minimum(along0, circle), along0)
                step = jnp.where(frozen[i], 0.0, step)
            add([(jx, c), (jy, s)], jnp.minimum(along0 + step, circle))
            add([(jx, -c), (jy, -s)], -jnp.maximum(along0 - step, 0.0))
            add([(jx, -s), (jy, c)], jnp.zeros(i.size))
            add([(jx, s), (jy, -c)], jnp.zeros(i.size))
            start = start.at[jx].set(along0 * c).at[jy].set(along0 * s)
        G = jnp.zeros((count, n)).at[np.concatenate(rows), np.concatenate(columns)].set(jnp.concatenate(entries))
        return G, jnp.concatenate(bounds), start

    def _reach(self) -> np.ndarray:
        """(2, 3): the smallest and largest of each axis of the scaled tau that the force
        limits allow, each axis alone. With the other axes free, each thruster adds its
        own extreme (the limits are per thruster), in closed form: a tunnel at either
        limit; an azimuth's thrust circle, max_thrust |(B_x, B_y)|; a main propeller
        ahead with its rudder (|L| <= rudder_lift max_rudder T) or astern without lift,
        whichever reaches further."""
        layout, index = self.layout, self.indices
        B = layout.B  # newtons
        low, high = np.zeros(3), np.zeros(3)
        i, j = index.tunnel, index.tunnel_thrust
        ends = np.stack([B[:, j] * layout.min_thrust[i], B[:, j] * layout.max_thrust[i]])
        low, high = low + ends.min(axis=0).sum(axis=-1), high + ends.max(axis=0).sum(axis=-1)
        i = index.azimuth
        circle = np.hypot(B[:, index.azimuth_x], B[:, index.azimuth_y]) * layout.max_thrust[i]
        low, high = low - circle.sum(axis=-1), high + circle.sum(axis=-1)
        i, jt, jl = index.main, index.main_thrust, index.main_lift
        lift = np.abs(B[:, jl]) * layout.rudder_lift[i] * layout.max_rudder[i]  # largest |L| per newton of thrust, on each axis
        ahead_high, ahead_low = np.maximum((B[:, jt] + lift) * layout.max_thrust[i], 0.0), np.minimum((B[:, jt] - lift) * layout.max_thrust[i], 0.0)
        astern = B[:, jt] * layout.min_thrust[i]
        low = low + np.minimum(ahead_low, np.minimum(astern, 0.0)).sum(axis=-1)
        high = high + np.maximum(ahead_high, np.maximum(astern, 0.0)).sum(axis=-1)
        return np.stack([low, high]) / self.force_scale

    @property
    def axis_reach(self) -> Array:
        """(3,) scaled: each axis's reach, the larger of its two directions (the
        shortfall's unit)."""
        return jnp.maximum(-self.reach[0], self.reach[1])

    # -- allocation --------------------------------------------------------------------------

    def allocate(
        self,
        tau: Array,
        previous: Array,
        angle: Array,
        dt: ArrayLike,
        working: Array | None = None,
        fraction: Array | None = None,
        frozen: Array | None = None,
    ) -> tuple[Array, dict]:
        """The scaled command for ``tau`` (N, N, N m) after the scaled ``previous``
        command, with the thrusters at ``angle`` (an azimuth's steered angle, a
        rudder's angle); ``working`` is the previous sample's active set
        (``info["working"]``), tried first.

        Failed thrusters (:mod:`lookout.actuators.failures`; both None: none):
        ``fraction`` (n_thrusters,) scales each thruster's force limits (0: stopped, 1:
        intact) and ``frozen`` marks the stuck ones, whose variables ``previous`` holds
        at their held force. The rest re-solve (Johansen & Fossen, "Control allocation -
        a survey", Automatica 49(5), 2013: reconfiguration by the allocation's
        constraints): with ``"qp"`` the failed thrusters' variables are pinned by their
        limits (:meth:`constraints`), so a stuck thruster's force is subtracted from what
        the others produce; with ``"pseudo-inverse"`` the weighted least-squares
        solution is taken over the available thrusters' columns of B only, for tau less
        the stuck thrusters' force. A stopped thruster's command is 0, exactly.

        Returns ``(u, info)``; ``info`` has ``unconstrained`` (the scaled weighted
        least-squares solution, biased with ``"qp"``), ``constrained`` (it broke a limit, so the QP was
        solved), ``shortfall`` (largest |tau - B u| over the axes, as a fraction of each
        axis's reach), ``residual`` (tau - B u in N, N, N m: the demanded force the
        thrusters were not commanded to produce), ``saturated`` (shortfall above
        :data:`SATURATED`), and the QP's ``iterations``, ``converged`` and ``working``
        (its active set; empty when not constrained). A non-finite ``tau`` gives a NaN
        command.
        """
        wanted, target = self.target(tau)
        failed = fraction is not None or frozen is not None
        owner = np.asarray([i for i, _ in self.layout.variables], dtype=int)
        if failed:
            fraction = jnp.ones(self.layout.size) if fraction is None else jnp.asarray(fraction, dtype=float)
            frozen = jnp.zeros(self.layout.size, dtype=bool) if frozen is None else jnp.asarray(frozen)
        # an Array: a NumPy matrix defers to the Array's __rmatmul__ (numpy's stubs say ndarray)
        unconstrained = cast(Array, self.pseudo_inverse_matrix @ target)
        qp = self._qp_terms() if self.method == "qp" else None
        if qp is not None:
            unconstrained = unconstrained + qp.bias
        elif fraction is not None and frozen is not None:
            unconstrained = self._without_failed(unconstrained, target, previous, fraction, frozen, owner)
        active = jnp.full(self.size, -1)
        if qp is None:
            u = self._saturate(unconstrained, previous, dt, fraction, frozen)
            constrained = jnp.any(jnp.abs(u - unconstrained) > 1e-12)
            iterations, converged = jnp.asarray(0), jnp.asarray(True)
        else:
            bias = qp.bias
            if fraction is not None and frozen is not None:
                available, _, remaining = self._available(fraction, frozen)
                bias = jnp.where(jnp.any(~available), remaining, bias)
            q = -(self.B.T @ (qp.slack_weights * (qp.target_matrix @ target))) - self.weights * bias
            if self.bounds_only:
                solved, active, iterations, converged, constrained = self._box(
                    jnp.asarray(q), unconstrained, previous, angle, dt, working, fraction, frozen
                )
                active = jnp.where(constrained, active, FREE)
            else:
                G, h, start = self.constraints(previous, angle, dt, fraction, frozen)
                constrained = ~jnp.all(G @ unconstrained <= h + 1e-12)
                if self.solver == "qpax":
                    solved, iterations, converged = _qpax(qp.P, q, G, h, self.indices.azimuth.size)
                else:
                    solved, found, iterations, converged = active_set(
                        qp.P,
                        q,
                        G,
                        h,
                        start,
                        max_iterations=G.shape[0] + self.size,
                        needed=constrained,
                        warm=working,
                        P_inverse=self.P_inverse,
                    )
                    active = jnp.where(constrained, found, active)
            u = jnp.where(constrained, solved, unconstrained)
            converged = converged | ~constrained
        if fraction is not None:
            u = jnp.where(fraction[owner] == 0.0, 0.0, u)  # never a stopped thruster, not even the solver's rounding
        u = jnp.where(jnp.all(jnp.isfinite(target)), u, jnp.nan)
        residual = wanted - self.B @ u
        shortfall = jnp.max(jnp.abs(residual) / self.axis_reach)
        return u, {
            "unconstrained": unconstrained,
            "constrained": constrained,
            "saturated": shortfall > SATURATED,
            "shortfall": shortfall,
            "residual": residual * self.force_scale,
            "iterations": iterations,
            "converged": converged,
            "working": active,
        }

    @property
    def bounds_only(self) -> bool:
        """Whether the QP, with each azimuth's force one variable along its steered angle,
        has bounds only (a layout of tunnels and azimuths, no main propeller's rudder),
        so that lookout's active-set solver takes its bounds-only form
        (:mod:`lookout.actuators.box_qp`), whose arithmetic is unrolled over the
        variables: up to :data:`~lookout.actuators.box_qp.MOST_VARIABLES` of them."""
        index = self.indices
        reduced = index.tunnel.size + index.azimuth.size
        return self.method == "qp" and self.solver == "active-set" and index.main.size == 0 and reduced <= MOST_VARIABLES

    def _box(
        self,
        q: Array,
        unconstrained: Array,
        previous: Array,
        angle: Array,
        dt: ArrayLike,
        working: Array | None,
        fraction: Array | None,
        frozen: Array | None,
    ) -> tuple[Array, Array, Array, Array, Array]:
        """The QP of :meth:`constraints` in its reduced variables, solved by
        :func:`lookout.actuators.box_qp.box_qp`: a tunnel's thrust, and an azimuth's
        force along its steered angle (the rows that hold its force across the angle at
        0 make the other component 0), each between the bounds those limits give it.
        The objective u^T P u / 2 + q^T u with u = T x is x^T (T^T P T) x / 2 + (T^T q)^T x.
        Returns ``(u, working, iterations, converged, constrained)``: the scaled command,
        the reduced variables' working set (tunnels first, then azimuths; padded to
        :attr:`size` with free entries), and whether the ``unconstrained`` solution
        breaks a limit (as :meth:`allocate` asks of :meth:`constraints`' rows)."""
        layout, index, n = self.layout, self.indices, self.size
        qp = self._qp_terms()
        failed = fraction is not None and frozen is not None
        step_of = jnp.asarray(layout.thrust_rate) * dt
        columns: list[list[tuple[int, Array | float]]] = []
        lower: list[Array] = []
        upper: list[Array] = []
        broken = jnp.zeros((), dtype=bool)
        for i, j in zip(index.tunnel.tolist(), index.tunnel_thrust.tolist(), strict=True):
            scale = self.scale[j]
            step = step_of[i] / scale
            smallest, largest, before = layout.min_thrust[i] / scale, layout.max_thrust[i] / scale, previous[j]
            if failed:
                assert fraction is not None and frozen is not None
                step = jnp.where(frozen[i], 0.0, step)
                smallest, largest = fraction[i] * smallest, fraction[i] * largest
                before = jnp.where(fraction[i] < 1.0, jnp.clip(before, smallest, largest), before)
            lower.append(jnp.maximum(smallest, before - step))
            upper.append(jnp.minimum(largest, before + step))
            columns.append([(j, 1.0)])
            broken = broken | (unconstrained[j] > upper[-1] + 1e-12) | (unconstrained[j] < lower[-1] - 1e-12)
        for i, jx, jy in zip(index.azimuth.tolist(), index.azimuth_x.tolist(), index.azimuth_y.tolist(), strict=True):
            c, s = jnp.cos(angle[i]), jnp.sin(angle[i])
            along = jnp.minimum(magnitude(previous[jx], previous[jy]), 1.0)
            step, circle = step_of[i] / self.scale[jx], jnp.asarray(1.0)
            if failed:
                assert fraction is not None and frozen is not None
                circle = fraction[i]
                along = jnp.where(circle < 1.0, jnp.minimum(along, circle), along)
                step = jnp.where(frozen[i], 0.0, step)
            lower.append(jnp.maximum(along - step, 0.0))
            upper.append(jnp.minimum(along + step, circle))
            columns.append([(jx, c), (jy, s)])
            wished, across = c * unconstrained[jx] + s * unconstrained[jy], c * unconstrained[jy] - s * unconstrained[jx]
            broken = broken | (wished > upper[-1] + 1e-12) | (wished < lower[-1] - 1e-12) | (jnp.abs(across) > 1e-12)
        P = jnp.asarray(qp.P)
        H = [[sum((a * P[ja, jb] * b for ja, a in first for jb, b in second), jnp.zeros(())) for second in columns] for first in columns]
        f = [sum((a * q[ja] for ja, a in column), jnp.zeros(())) for column in columns]
        r = len(columns)
        warm = None if working is None else working[:r]
        x, state, iterations, converged = box_qp(jnp.stack([jnp.stack(row) for row in H]), jnp.stack(f), jnp.stack(lower), jnp.stack(upper), warm)
        u = [jnp.zeros(())] * n
        for k, column in enumerate(columns):
            for j, a in column:
                u[j] = a * x[k]
        return jnp.stack(u), jnp.concatenate([state, jnp.full(n - r, FREE)]), iterations, converged, broken

    def _subset_tables(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """:meth:`_available`'s pseudo-inverse and bias for every subset of the thrusters
        (index: a bit per thruster left), computed once here for a layout of at most
        :data:`SUBSET_TABLE_THRUSTERS` thrusters, ``(None, None)`` for a larger one. The
        pseudo-inverse's cutoff is JAX's (singular values below 10 max(m, n) eps of the
        largest count as zero)."""
        count = self.layout.size
        if count > SUBSET_TABLE_THRUSTERS:
            return None, None
        owner = np.asarray([i for i, _ in self.layout.variables], dtype=int)
        bias = np.zeros(self.size) if self.bias is None else np.asarray(self.bias)
        inverses, biases = [], []
        for subset in range(2**count):
            left = ((subset >> owner) & 1).astype(bool)
            inverse_weighted = np.where(left[:, None], self.B.T / self.weights[:, None], 0.0)
            pseudo_inverse = inverse_weighted @ np.linalg.pinv(self.B @ inverse_weighted, rcond=30 * np.finfo(float).eps)
            kept = np.where(left, bias, 0.0)
            inverses.append(pseudo_inverse)
            biases.append(kept - pseudo_inverse @ (self.B @ kept))
        return np.stack(inverses), np.stack(biases)

    def _available(self, fraction: Array, frozen: Array) -> tuple[Array, Array, Array]:
        """``(available, pseudo_inverse, bias)`` over the thrusters that remain: whether
        each variable's thruster is neither stopped nor stuck, the weighted pseudo-inverse
        with the others' columns of B out (a pseudo-inverse of the gram, which is
        singular when the thrusters left span fewer than three axes), and the bias's
        part that produces no force with them (0 without a bias). From the tables of
        :meth:`_subset_tables` where the layout has them (no factorization per sample)."""
        owner = np.asarray([i for i, _ in self.layout.variables], dtype=int)
        left = ~((fraction == 0.0) | frozen)
        available = left[owner]
        if self.subset_pseudo_inverse is not None and self.subset_bias is not None:
            subset = jnp.sum(jnp.where(left, 2 ** np.arange(self.layout.size), 0))
            return available, jnp.asarray(self.subset_pseudo_inverse)[subset], jnp.asarray(self.subset_bias)[subset]
        B = jnp.asarray(self.B)
        inverse_weighted = jnp.where(available[:, None], B.T / jnp.asarray(self.weights)[:, None], 0.0)
        pseudo_inverse = inverse_weighted @ jnp.linalg.pinv(B @ inverse_weighted)
        bias = jnp.zeros(self.size) if self.bias is None else jnp.where(available, jnp.asarray(self.bias), 0.0)
        return available, pseudo_inverse, bias - pseudo_inverse @ (B @ bias)

    def _without_failed(self, intact: Array, target: Array, held: Array, fraction: Array, frozen: Array, owner: np.ndarray) -> Array:
        """The weighted least-squares solution over the available thrusters only (the
        stopped and stuck ones' columns of B out) for ``target`` less the stuck ones'
        ``held`` force, the stuck ones at it and the stopped ones at 0; ``intact`` while
        no thruster is failed (the same bits as without failures)."""
        available, pseudo_inverse, _ = self._available(fraction, frozen)
        pinned = jnp.where(frozen[owner] & (fraction[owner] > 0.0), held, 0.0)  # a stopped thruster holds nothing
        solution = pseudo_inverse @ (target - jnp.asarray(self.B) @ pinned) + pinned
        return jnp.where(jnp.any(~available), solution, intact)

    def _saturate(self, u: Array, previous: Array, dt, fraction: Array | None = None, frozen: Array | None = None) -> Array:
        """Each thruster limited on its own: a thrust into its force and rate limits, an
        azimuth's force scaled into its circle with its magnitude rate-limited, a
        rudder's lift into its angle limits (failed thrusters: see :meth:`allocate`)."""
        layout, index = self.layout, self.indices
        failed = fraction is not None and frozen is not None
        share = jnp.ones(layout.size) if fraction is None else fraction
        still = jnp.zeros(layout.size, dtype=bool) if frozen is None else frozen
        out = u
        if index.azimuth.size:
            jx, jy, i = index.azimuth_x, index.azimuth_y, index.azimuth
            step = jnp.asarray(layout.thrust_rate[i]) * dt / self.scale[jx]
            norm = magnitude(u[jx], u[jy])
            old = magnitude(previous[jx], previous[jy])
            largest = jnp.ones(i.size)
            if failed:
                step = jnp.where(still[i], 0.0, step)
                largest = share[i]
                old = jnp.where(largest < 1.0, jnp.minimum(old, largest), old)
            wanted = jnp.clip(jnp.minimum(norm, largest), old - step, old + step)
            factor = jnp.where(norm > 0, wanted / jnp.where(norm > 0, norm, 1.0), 0.0)
            out = out.at[jx].set(u[jx] * factor).at[jy].set(u[jy] * factor)
        thrusters = np.concatenate([index.tunnel, index.main])
        if thrusters.size:
            j = np.concatenate([index.tunnel_thrust, index.main_thrust])
            step = jnp.asarray(layout.thrust_rate[thrusters]) * dt / self.scale[j]
            smallest, largest_thrust = layout.min_thrust[thrusters] / self.scale[j], layout.max_thrust[thrusters] / self.scale[j]
            before = previous[j]
            if failed:
                step = jnp.where(still[thrusters], 0.0, step)
                smallest, largest_thrust = share[thrusters] * smallest, share[thrusters] * largest_thrust
                before = jnp.where(share[thrusters] < 1.0, jnp.clip(before, smallest, largest_thrust), before)
            low = jnp.maximum(smallest, before - step)
            high = jnp.minimum(largest_thrust, before + step)
            out = out.at[j].set(jnp.clip(u[j], low, high))
        if index.main.size:
            thrust = out[index.main_thrust]
            out = out.at[index.main_lift].set(jnp.clip(u[index.main_lift], -jnp.maximum(thrust, 0.0), jnp.maximum(thrust, 0.0)))
        return out


def _brief(value) -> str:
    """A value for a one-line message: short, never an array dump."""
    text = repr(value.tolist() if isinstance(value, np.ndarray) else value)
    return text if len(text) <= 60 else f"{text[:50]}... ({np.size(value)} entries)"


def _option(name: str, value, default: float, low: float, high: float, high_included: bool = True) -> np.ndarray:
    """A scalar option in [low, high] (or [low, high)), its default when None, as a
    float64 array (a gain: changing it does not trace again)."""
    value = default if value is None else value
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise check.ParameterError(check.key(name), f"{name} must be a number; got {_brief(value)}") from None
    if not (low <= number and (number <= high if high_included else number < high)) or math.isnan(number):
        interval = f"[{low:g}, {'pi' if high == math.pi else f'{high:g}'}{']' if high_included else ')'}"
        raise check.ParameterError(check.key(name), f"{name} must be in {interval}; got {number:g}")
    return np.asarray(number)


def _qpax(P, q, G, h, azimuths: int):
    """The QP by qpax's interior-point method (differentiable by its own rule): the same
    scaling of P as :func:`lookout.actuators.qp.active_set`. The last 2 ``azimuths``
    rows of :meth:`Allocator.constraints` hold each azimuth's force across its angle
    at <= 0 and >= 0: an equality, which an interior-point method needs as one (the
    pair has no interior)."""
    import qpax

    size = jnp.max(jnp.abs(P))
    m = G.shape[0]
    equal = slice(m - 2 * azimuths, m - azimuths)
    x = qpax.solve_qp_primal(P / size, q / size, G[equal], h[equal], G[: m - 2 * azimuths], h[: m - 2 * azimuths], solver_tol=1e-10, max_iter=50)
    return x, jnp.asarray(-1), jnp.all(jnp.isfinite(x))
