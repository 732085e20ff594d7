"""DP capability: the largest environmental force a thruster layout can balance, per
direction, intact and with thrusters out of service (``lookout capability``).

The environment pushes the vessel with a force F from direction beta (body-fixed, the
direction it comes from: 0 from ahead, 90 deg from starboard) and a yaw moment
``moment_arm * F``; the thrusters balance it when their generalized force is
``F [cos beta, sin beta, moment_arm]`` (they push into the weather). The capability at
beta is the largest such F within every thruster's force limits, a linear program in
the layout's extended variables (:attr:`~lookout.actuators.layout.ThrusterLayout.B`;
Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2011, Section
12.3): maximize F subject to ``B u = F d``,

- a tunnel's thrust within ``[min_thrust, max_thrust]``;
- an azimuth's force (F_x, F_y) within its thrust circle, taken as the inscribed
  regular polygon of ``sides`` sides (at most ``1 - cos(pi / sides)`` of the circle
  lost: 3.8e-5 at 360 sides), so the capability is never overstated;
- a main propeller ahead, ``0 <= T <= max_thrust`` with its rudder's lift
  ``|L| <= rudder_lift * max_rudder * T``, or astern, ``min_thrust <= T <= 0`` without
  lift: the larger of the two programs (every combination, for several mains).

It is the quasi-static capability of DNV's standard for DP capability (DNV-ST-0111,
level 1: thrust against the static environment, no dynamics and no reserve), with the
environment's moment stated as an arm instead of a model of wind, current and waves. A
thruster out of service contributes nothing (its variables pinned at 0), as a stopped
thruster does in :mod:`lookout.actuators.failures`. The rates of thrust and turning do
not enter: it is what the layout can hold, not how fast it gets there.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from lookout import _validation as check
from lookout.actuators.layout import ThrusterLayout

#: Sides of the polygon inscribed in an azimuth's thrust circle.
SIDES = 360


def _program(layout: ThrusterLayout, out: Sequence[int], sides: int, astern: dict[int, bool]):
    """The inequality rows, rhs and variable bounds of the layout's force limits (the
    extended variables in :attr:`ThrusterLayout.variables` order)."""
    variables = layout.variables
    n = len(variables)
    bounds: list[tuple[float | None, float | None]] = [(None, None)] * n
    rows: list[np.ndarray] = []
    rhs: list[float] = []
    angles = 2 * np.pi * np.arange(sides) / sides
    for i, kind in enumerate(layout.kinds):
        if i in out:
            for j, (owner, _) in enumerate(variables):
                if owner == i:
                    bounds[j] = (0.0, 0.0)
            continue
        if kind == "tunnel":
            j = variables.index((i, "thrust"))
            bounds[j] = (float(layout.min_thrust[i]), float(layout.max_thrust[i]))
        elif kind == "azimuth":
            jx, jy = variables.index((i, "x")), variables.index((i, "y"))
            for angle in angles:
                row = np.zeros(n)
                row[jx], row[jy] = math.cos(angle), math.sin(angle)
                rows.append(row)
                rhs.append(float(layout.max_thrust[i]) * math.cos(math.pi / sides))
        else:
            jt, jl = variables.index((i, "thrust")), variables.index((i, "lift"))
            if astern[i]:
                bounds[jt], bounds[jl] = (float(layout.min_thrust[i]), 0.0), (0.0, 0.0)
            else:
                bounds[jt] = (0.0, float(layout.max_thrust[i]))
                slope = float(layout.rudder_lift[i] * layout.max_rudder[i])
                for sign in (1.0, -1.0):
                    row = np.zeros(n)
                    row[jl], row[jt] = sign, -slope
                    rows.append(row)
                    rhs.append(0.0)
    return rows, rhs, bounds


def largest_force(
    layout: ThrusterLayout, direction: npt.ArrayLike, *, out: Sequence[int] = (), free: Sequence[int] = (), sides: int = SIDES
) -> float:
    """The largest F with the thrusters' generalized force equal to ``F * direction`` (3,)
    on every axis not in ``free`` (those are left to whatever the thrusters give), the
    thrusters in ``out`` out of service; 0 when the layout cannot push that way at all."""
    from scipy.optimize import linprog

    d = np.asarray(direction, dtype=float)
    B = np.asarray(layout.B, dtype=float)
    n = B.shape[1]
    held = [axis for axis in range(3) if axis not in free]
    mains = [i for i, kind in enumerate(layout.kinds) if kind == "main" and i not in out]
    best = 0.0
    for combination in itertools.product((False, True), repeat=len(mains)):
        rows, rhs, bounds = _program(layout, out, sides, dict(zip(mains, combination)))
        # variables: u (n), then F >= 0; maximize F
        a_eq = np.hstack([B[held], -d[held, None]])
        a_ub = np.hstack([np.asarray(rows).reshape(-1, n), np.zeros((len(rows), 1))]) if rows else None
        cost = np.zeros(n + 1)
        cost[-1] = -1.0
        result = linprog(
            cost, A_ub=a_ub, b_ub=rhs if rows else None, A_eq=a_eq, b_eq=np.zeros(len(held)), bounds=bounds + [(0.0, None)], method="highs"
        )
        if result.status == 0:
            best = max(best, float(result.x[-1]))
        elif result.status == 3:  # unbounded: only with no limit at all, which a layout does not have
            return math.inf
    return best


def capability(
    layout: ThrusterLayout, directions: npt.ArrayLike, *, moment_arm: float = 0.0, out: Sequence[int] = (), sides: int = SIDES
) -> np.ndarray:
    """The capability (N) at each direction of ``directions`` (rad, the direction the
    environment comes from), with a yaw moment of ``moment_arm`` (m) times the force,
    the thrusters in ``out`` (indices) out of service."""
    betas = np.asarray(directions, dtype=float)
    if betas.ndim != 1 or not np.all(np.isfinite(betas)):
        raise check.ParameterError("directions", f"directions must be a 1-D array of finite angles (rad); got shape {betas.shape}")
    if isinstance(moment_arm, bool) or not math.isfinite(float(moment_arm)):
        raise check.ParameterError("moment_arm", f"moment_arm must be a finite number of metres; got {moment_arm}")
    if isinstance(sides, bool) or not isinstance(sides, int) or sides < 8:
        raise check.ParameterError("sides", f"sides must be a whole number >= 8; got {sides}")
    for i in out:
        if not (isinstance(i, (int, np.integer)) and 0 <= i < layout.size):
            raise check.ParameterError("out", f"out must name thrusters by index, 0 to {layout.size - 1}; got {i}")
    return np.asarray([largest_force(layout, [math.cos(b), math.sin(b), float(moment_arm)], out=out, sides=sides) for b in betas])


def single_failure_capability(
    layout: ThrusterLayout, directions: npt.ArrayLike, *, moment_arm: float = 0.0, sides: int = SIDES
) -> dict[str, np.ndarray]:
    """The capability intact (key ``intact``) and with each thruster out of service
    (its name), at ``directions``."""
    found = {"intact": capability(layout, directions, moment_arm=moment_arm, sides=sides)}
    for i, name in enumerate(layout.names):
        found[name] = capability(layout, directions, moment_arm=moment_arm, out=(i,), sides=sides)
    return found


__all__ = ["SIDES", "capability", "largest_force", "single_failure_capability"]
