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
    rate while pushing): the classical unconstrained allocation.
``"qp"``
    The same solution when it respects every limit (it is then optimal), else

        minimize  u^T W u + s^T Q s   subject to  B u = tau + s,  u in the limits

    with the slack s weighted by Q = ``slack_weight`` (tau scaled per axis): when
    tau cannot be produced, the thrusters produce the tau closest to it in the
    Q-weighted norm. The QP's target is tau moved by Q^-1 (B W^-1 B^T)^-1 tau (a
    part in ``slack_weight`` of tau), which makes the QP's unconstrained optimum the
    weighted least-squares solution exactly: the allocation is then continuous where
    it passes from that solution to the QP's (a penalty QP on tau itself would jump
    by a part in ``slack_weight`` there). The limits, all linear and all met by a start point built from
    the previous command (so :func:`lookout.actuators.qp.active_set` can start there):

    - force: a tunnel's and a main propeller's thrust in [min_thrust, max_thrust]
      (a main propeller ahead after ahead, so that its rudder's lift stays convex);
      an azimuth's |F| <= max_thrust as the inscribed polygon of ``polygon_sides``
      sides, so a command never exceeds it;
    - rate: a thrust within thrust_rate dt of its previous command; an azimuth's
      force within thrust_rate dt of its previous thrust along and across its
      current direction;
    - turning: an azimuth's force within turn_rate dt of its current angle (a
      sector, when turn_rate dt < pi), and a rudder's lift within the rudder angles
      reachable in dt, |delta| <= max_rudder, ahead only (L = rudder_lift delta T):
      whatever the QP commands is delivered after one sample. An azimuth the QP
      leaves idle turns toward the direction the unconstrained solution wants (a
      sector QP alone would never turn a thruster that points the wrong way).

Variables, tau and slack are scaled (each variable by its largest magnitude, each
axis of tau by :attr:`ThrusterLayout.force_scale`) so the QP is equally well
conditioned for a model ship and a supply vessel.
"""

from __future__ import annotations

import math
from typing import Literal, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout.actuators.layout import ThrusterLayout, magnitude
from lookout.actuators.qp import active_set

#: h of a row that never binds.
NEVER = 1e30
ALLOCATION_METHODS = ("qp", "pseudo-inverse")
QP_SOLVERS = ("active-set", "qpax")
#: An azimuth's turning sector is capped at this half-width (rad) below pi (a wider
#: sector is not convex); at turn_rate dt >= pi there is no sector.
LARGEST_SECTOR = 1.5
#: A scaled force below this is no direction (an idle thruster's rounding).
IDLE = 1e-3


def _unit(angle):
    return jnp.cos(angle), jnp.sin(angle)


@final
class Allocator(eqx.Module):
    """Thrust allocation for one layout (see the module docstring for the methods).

    Parameters
    ----------
    layout : ThrusterLayout
        The thrusters.
    method : {"qp", "pseudo-inverse"}
        The allocation method.
    slack_weight : float or array_like, shape (3,)
        Weight of the squared scaled slack (surge, sway, yaw) against the squared
        scaled thrust in the QP; positive. Large: tau is produced whenever the limits
        allow it (within about 1/slack_weight of its scale); unequal: the axis with the
        larger weight is kept first when tau cannot be produced.
    polygon_sides : int
        Sides of the polygon inside an azimuth's thrust circle; at least 4.
    clip_to_reach : bool
        Clip each axis of tau to what the thrusters can produce on that axis alone
        (:attr:`reach`) before allocating, as a per-axis saturation would: a command
        far beyond the thrusters' reach on one axis then does not take the thrust
        another axis needs. False allocates tau as it comes.
    solver : {"active-set", "qpax"}
        The QP's solver: lookout's active-set method (:mod:`lookout.actuators.qp`;
        exact, and cheap when few limits change from sample to sample), or qpax's
        primal-dual interior-point method (Tracy & Manchester, 2024; the ``qpax``
        package, installed with lookout's ``dev`` extra), for comparison.
    """

    layout: ThrusterLayout
    B: Array          # scaled: tau / force_scale = B (u / scale)
    scale: Array      # each variable's largest magnitude (N)
    force_scale: Array
    weights: Array
    slack_weights: Array
    pseudo_inverse_matrix: Array
    P: Array
    target_matrix: Array  # the QP's target from the scaled tau (see the module docstring)
    reach: Array      # (2, 3) scaled: the smallest and largest of each axis alone
    method: str = eqx.field(static=True)
    polygon_sides: int = eqx.field(static=True)
    clip_to_reach: bool = eqx.field(static=True)
    solver: str = eqx.field(static=True)

    def __init__(self, layout: ThrusterLayout, method: Literal["qp", "pseudo-inverse"] = "qp", slack_weight=1e6, polygon_sides: int = 16,
                 clip_to_reach: bool = True, solver: Literal["active-set", "qpax"] = "active-set"):
        if method not in ALLOCATION_METHODS:
            raise ValueError(f"allocation must be one of {', '.join(ALLOCATION_METHODS)}; got {method!r}")
        if solver not in QP_SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(QP_SOLVERS)}; got {solver!r}")
        if solver == "qpax":
            try:
                import qpax  # noqa: F401
            except ImportError:
                raise ValueError("solver 'qpax' needs the qpax package (pip install qpax, or lookout's dev extra)") from None
        self.solver = solver
        try:
            slack = np.broadcast_to(np.asarray(slack_weight, dtype=float), (3,)).copy()
        except (TypeError, ValueError):
            slack = np.full(3, np.nan)
        if not np.all(np.isfinite(slack)) or np.any(slack <= 0):
            raise ValueError(f"slack_weight must be a positive number or three of them (surge, sway, yaw); got {slack_weight!r}")
        if not isinstance(polygon_sides, int) or isinstance(polygon_sides, bool) or polygon_sides < 4:
            raise ValueError(f"polygon_sides must be an integer of at least 4; got {polygon_sides!r}")
        self.layout, self.method, self.polygon_sides, self.clip_to_reach = layout, method, polygon_sides, bool(clip_to_reach)
        self.scale, self.force_scale = layout.variable_scale, layout.force_scale
        self.B = layout.B * self.scale[None, :] / self.force_scale[:, None]
        self.weights = np.array([layout.weight[i] for i, _ in layout.variables])
        self.slack_weights = slack
        inverse = np.diag(1.0 / self.weights)
        self.pseudo_inverse_matrix = inverse @ self.B.T @ np.linalg.inv(self.B @ inverse @ self.B.T)
        # u^T W u + (B u - tau)^T Q (B u - tau) = u^T P u - 2 tau^T Q B u + const
        self.P = np.diag(self.weights) + self.B.T @ np.diag(slack) @ self.B
        # stationarity W u + B^T Q (B u - t') = 0 holds at u = W^-1 B^T lam, lam = (B W^-1 B^T)^-1 t,
        # for t' = t + Q^-1 lam: the penalty QP's unconstrained optimum is the least-squares one
        self.target_matrix = np.eye(3) + np.diag(1.0 / slack) @ np.linalg.inv(self.B @ inverse @ self.B.T)
        self.reach = self._reach()

    @property
    def size(self) -> int:
        """Number of extended variables."""
        return self.B.shape[1]

    def _index(self, i: int, part: str) -> int:
        return self.layout.variables.index((i, part))

    # -- the limits --------------------------------------------------------------------------

    def constraints(self, previous: Array, angle: Array, dt, preferred: Array | None = None) -> tuple[Array, Array, Array]:
        """``(G, h, start)``: the limits G u <= h on the scaled command after the scaled
        ``previous`` command, with the thrusters at ``angle`` (an azimuth's, a rudder's)
        and a step ``dt``, and a scaled command that meets them all (see the module
        docstring). With the ``preferred`` (unconstrained) allocation, an azimuth's
        thrust is capped at cos(its angle from the preferred direction) of its largest
        (0 beyond 90 degrees), lowered no faster than its rate allows."""
        layout, n = self.layout, self.size
        rows, bounds = [], []
        start = jnp.asarray(previous, dtype=float)

        def row(entries, bound):
            g = jnp.zeros(n)
            for j, value in entries:
                g = g.at[j].set(value)
            rows.append(g)
            bounds.append(jnp.asarray(bound, dtype=float))

        for i, kind in enumerate(layout.kinds):
            if kind in ("tunnel", "main"):
                j = self._index(i, "thrust")
                step = layout.thrust_rate[i] * dt / self.scale[j]
                low = jnp.maximum(layout.min_thrust[i] / self.scale[j], previous[j] - step)
                if kind == "main":
                    low = jnp.where(previous[j] > 0, jnp.maximum(low, 0.0), low)
                row([(j, 1.0)], jnp.minimum(layout.max_thrust[i] / self.scale[j], previous[j] + step))
                row([(j, -1.0)], -low)
            if kind == "main":
                jt, jl = self._index(i, "thrust"), self._index(i, "lift")
                reachable = layout.turn_rate[i] * dt
                ahead = previous[jt] > 0
                # L / (k d_max T_max) between (delta -+ turn) / d_max times T / T_max; astern L = 0
                high = jnp.where(ahead, jnp.minimum(angle[i] + reachable, layout.max_rudder[i]) / layout.max_rudder[i], 0.0)
                low = jnp.where(ahead, jnp.maximum(angle[i] - reachable, -layout.max_rudder[i]) / layout.max_rudder[i], 0.0)
                row([(jl, 1.0), (jt, -high)], 0.0)
                row([(jl, -1.0), (jt, low)], 0.0)
                start = start.at[jl].set(angle[i] / layout.max_rudder[i] * jnp.maximum(previous[jt], 0.0))
            if kind == "azimuth":
                jx, jy = self._index(i, "x"), self._index(i, "y")
                apothem = math.cos(math.pi / self.polygon_sides)
                along0 = jnp.minimum(magnitude(previous[jx], previous[jy]), apothem)
                c, s = _unit(angle[i])
                step = layout.thrust_rate[i] * dt / self.scale[jx]
                high = along0 + step
                if preferred is not None:  # pointing away from where it is wanted: thrust down, so it turns
                    wanted = magnitude(preferred[jx], preferred[jy]) > IDLE
                    alignment = jnp.where(wanted, (preferred[jx] * c + preferred[jy] * s) / jnp.maximum(magnitude(preferred[jx], preferred[jy]), IDLE), 1.0)
                    high = jnp.maximum(jnp.minimum(high, apothem * jnp.maximum(alignment, 0.0)), along0 - step)
                along_start = jnp.minimum(along0, high)
                start = start.at[jx].set(along_start * c).at[jy].set(along_start * s)
                row([(jx, c), (jy, s)], high)
                row([(jx, -c), (jy, -s)], -(along0 - step))
                row([(jx, -s), (jy, c)], step)
                row([(jx, s), (jy, -c)], step)
                reachable = layout.turn_rate[i] * dt
                width = jnp.minimum(reachable, LARGEST_SECTOR)
                sector = jnp.where(reachable < math.pi, 0.0, NEVER)
                right_c, right_s = _unit(angle[i] - width)
                left_c, left_s = _unit(angle[i] + width)
                row([(jx, right_s), (jy, -right_c)], sector)
                row([(jx, -left_s), (jy, left_c)], sector)
                for k in range(self.polygon_sides):
                    normal = (2 * k + 1) * math.pi / self.polygon_sides
                    row([(jx, math.cos(normal)), (jy, math.sin(normal))], apothem)
        return jnp.stack(rows), jnp.stack(bounds), start

    def _reach(self) -> np.ndarray:
        """(2, 3): the smallest and largest of each axis of the scaled tau that the force
        limits allow, each axis alone (linear programs; a main propeller either ahead
        with its rudder or astern without lift, whichever reaches further)."""
        from scipy.optimize import linprog

        layout, n = self.layout, self.size
        mains = [i for i, kind in enumerate(layout.kinds) if kind == "main"]
        reach = np.zeros((2, 3))
        for axis in range(3):
            for side, sign in ((0, 1.0), (1, -1.0)):  # minimize sign * tau_axis
                best = math.inf
                for astern in range(2 ** len(mains)):
                    rows, bounds, limits = [], [], [(None, None)] * n
                    for i, kind in enumerate(layout.kinds):
                        if kind in ("tunnel", "main"):
                            j = self._index(i, "thrust")
                            limits[j] = (layout.min_thrust[i] / self.scale[j], layout.max_thrust[i] / self.scale[j])
                        if kind == "main":
                            jt, jl = self._index(i, "thrust"), self._index(i, "lift")
                            if astern >> mains.index(i) & 1:
                                limits[jt], limits[jl] = (limits[jt][0], 0.0), (0.0, 0.0)
                            else:
                                limits[jt] = (0.0, limits[jt][1])
                                for sign_l in (1.0, -1.0):
                                    g = np.zeros(n)
                                    g[jl], g[jt] = sign_l, -1.0
                                    rows.append(g)
                                    bounds.append(0.0)
                        if kind == "azimuth":
                            jx, jy = self._index(i, "x"), self._index(i, "y")
                            for k in range(self.polygon_sides):
                                normal = (2 * k + 1) * math.pi / self.polygon_sides
                                g = np.zeros(n)
                                g[jx], g[jy] = math.cos(normal), math.sin(normal)
                                rows.append(g)
                                bounds.append(math.cos(math.pi / self.polygon_sides))
                    result = linprog(
                        sign * self.B[axis], A_ub=np.asarray(rows) if rows else None, b_ub=np.asarray(bounds) if rows else None,
                        bounds=limits, method="highs",
                    )
                    if result.status == 0:
                        best = min(best, result.fun)
                reach[side, axis] = sign * best
        return reach

    # -- allocation --------------------------------------------------------------------------

    def allocate(self, tau: Array, previous: Array, angle: Array, dt, working: Array | None = None) -> tuple[Array, dict]:
        """The scaled command for ``tau`` (N, N, N m) after the scaled ``previous``
        command, with the thrusters at ``angle``; ``working`` is the previous sample's
        active set (``info["working"]``), tried first.

        Returns ``(u, info)``; ``info`` has ``unconstrained`` (the scaled weighted
        least-squares solution, which idle azimuths turn toward), ``saturated`` (it
        broke a limit), ``shortfall`` (largest |tau - B u| over the axes, as a fraction
        of each axis's :attr:`force_scale`), and the QP's ``iterations``, ``converged``
        and ``working`` (its active set; empty when unsaturated). A non-finite ``tau``
        gives a NaN command.
        """
        wanted = jnp.asarray(tau) / self.force_scale
        target = jnp.clip(wanted, self.reach[0], self.reach[1]) if self.clip_to_reach else wanted
        unconstrained = self.pseudo_inverse_matrix @ target
        G, h, start = self.constraints(previous, angle, dt, unconstrained)
        saturated = ~jnp.all(G @ unconstrained <= h + 1e-12)
        active = jnp.full(self.size, -1)
        if self.method == "pseudo-inverse":
            u = self._saturate(unconstrained, previous, dt)
            iterations, converged = jnp.asarray(0), jnp.asarray(True)
        else:
            q = -(self.B.T @ (self.slack_weights * (self.target_matrix @ target)))
            if self.solver == "qpax":
                solved, iterations, converged = _qpax(self.P, q, G, h)
            else:
                solved, found, iterations, converged = active_set(
                    self.P, q, G, h, start, max_iterations=G.shape[0] + self.size, needed=saturated, warm=working
                )
                active = jnp.where(saturated, found, active)
            u = jnp.where(saturated, solved, unconstrained)
            converged = converged | ~saturated
        u = jnp.where(jnp.all(jnp.isfinite(target)), u, jnp.nan)
        shortfall = jnp.max(jnp.abs(wanted - self.B @ u))
        return u, {"unconstrained": unconstrained, "saturated": saturated, "shortfall": shortfall, "iterations": iterations, "converged": converged,
                   "working": active}

    def _saturate(self, u: Array, previous: Array, dt) -> Array:
        """Each thruster limited on its own: a thrust into its force and rate limits, an
        azimuth's force scaled into its circle with its magnitude rate-limited, a
        rudder's lift into its angle limits."""
        layout = self.layout
        out = u
        for i, kind in enumerate(layout.kinds):
            if kind == "azimuth":
                jx, jy = self._index(i, "x"), self._index(i, "y")
                step = layout.thrust_rate[i] * dt / self.scale[jx]
                norm = magnitude(u[jx], u[jy])
                old = magnitude(previous[jx], previous[jy])
                wanted = jnp.clip(jnp.minimum(norm, 1.0), old - step, old + step)
                factor = jnp.where(norm > 0, wanted / jnp.where(norm > 0, norm, 1.0), 0.0)
                out = out.at[jx].set(u[jx] * factor).at[jy].set(u[jy] * factor)
                continue
            j = self._index(i, "thrust")
            step = layout.thrust_rate[i] * dt / self.scale[j]
            low = jnp.maximum(layout.min_thrust[i] / self.scale[j], previous[j] - step)
            high = jnp.minimum(layout.max_thrust[i] / self.scale[j], previous[j] + step)
            thrust = jnp.clip(u[j], low, high)
            out = out.at[j].set(thrust)
            if kind == "main":
                jl = self._index(i, "lift")
                out = out.at[jl].set(jnp.clip(u[jl], -jnp.maximum(thrust, 0.0), jnp.maximum(thrust, 0.0)))
        return out


def _qpax(P, q, G, h):
    """The QP by qpax's interior-point method (differentiable by its own rule): the same
    scaling of P as :func:`lookout.actuators.qp.active_set`, rows that never bind left out."""
    import qpax

    size = jnp.max(jnp.abs(P))
    bind = h < NEVER
    n = P.shape[0]
    x = qpax.solve_qp_primal(P / size, q / size, jnp.zeros((0, n)), jnp.zeros(0), jnp.where(bind[:, None], G, 0.0), jnp.where(bind, h, 1.0),
                             solver_tol=1e-10, max_iter=50)
    return x, jnp.asarray(-1), jnp.all(jnp.isfinite(x))
