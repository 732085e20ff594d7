"""A vessel's thrusters as data: kind, position, limits and response of each.

Three kinds of thruster (Fossen, *Handbook of Marine Craft Hydrodynamics and Motion
Control*, 2011, Section 12.3, actuator models and the extended thrust formulation):

``tunnel``
    Thrust T along a fixed direction (``direction``, 90 deg for a sideways tunnel),
    ``min_thrust <= T <= max_thrust``.
``azimuth``
    Thrust 0 <= T <= ``max_thrust`` along the thruster's angle alpha, which turns at
    most ``turn_rate`` (rad/s).
``main``
    A main propeller with a rudder behind it: thrust T along ``direction`` (0 deg:
    ahead), ``min_thrust`` (astern, <= 0) to ``max_thrust``, and the rudder's lift
    L = ``rudder_lift`` * delta * max(T, 0) across it (a slipstream model: lift grows
    with the rudder angle delta and the propeller's thrust, and vanishes astern; drag
    neglected), |delta| <= ``max_rudder``, turning at most ``turn_rate``.

Every thruster's thrust follows its command as a first-order lag of ``time_constant``
(s) and changes at most ``thrust_rate`` (N/s). A thruster at body-fixed position
(x, y) whose force is (F_x, F_y) gives the generalized force
(F_x, F_y, x F_y - y F_x) in surge, sway and yaw.

For allocation each thruster has "extended" variables whose map to the generalized
force is linear: a tunnel's T; an azimuth's force components (F_x, F_y) (Fossen
(2011), eq. (12.247)); a main propeller's T and rudder lift L. :attr:`B` is that map.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.declare import Value, register

#: The kinds of thruster.
THRUSTER_KINDS = ("tunnel", "azimuth", "main")
KIND_PLURALS = {"tunnel": "tunnels", "azimuth": "azimuths", "main": "main propellers"}
#: The columns that apply to some kinds only: one number is theirs; given per thruster,
#: the other kinds' entries must be 0 (an entry that would be ignored is refused).
APPLIES_TO = {"min_thrust": ("tunnel", "main"), "turn_rate": ("azimuth", "main"), "max_rudder": ("main",), "rudder_lift": ("main",)}
#: Their defaults (the value of a layout that does not give them).
DEFAULTS = {"min_thrust": 0.0, "turn_rate": math.inf, "max_rudder": 0.6, "rudder_lift": 0.0}
#: The columns one number cannot stand for: every thruster has a position of its own
#: (one x for all would put them on one line across the hull).
PER_THRUSTER = ("x", "y")
NOT_APPLICABLE = {
    "min_thrust": "an azimuth pushes one way and turns to push the other",
    "turn_rate": "a tunnel does not turn",
    "max_rudder": "only a main propeller has a rudder",
    "rudder_lift": "only a main propeller has a rudder",
}


def _short(text: str, limit: int = 40) -> str:
    """A name cut to ``limit`` characters for a message."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _listed(items: list[str], shown: int = 3) -> str:
    """The first ``shown`` items, and how many more."""
    return ", ".join(items[:shown]) + (f" and {len(items) - shown} more" if len(items) > shown else "")


def magnitude(x: Array | np.ndarray, y: Array | np.ndarray) -> Array:
    """sqrt(x^2 + y^2) with a finite derivative at the origin (0 there, not NaN)."""
    square = x**2 + y**2
    return jnp.where(square > 0, jnp.sqrt(jnp.where(square > 0, square, 1.0)), 0.0)


def direction_of(x: Array | np.ndarray, y: Array | np.ndarray, fallback: Array | np.ndarray) -> Array:
    """atan2(y, x), and ``fallback`` where (x, y) is the origin (finite derivatives both ways)."""
    zero = (x == 0) & (y == 0)
    return jnp.where(zero, fallback, jnp.arctan2(jnp.where(zero, 0.0, y), jnp.where(zero, 1.0, x)))


#: Sea water's density (kg/m^3), and a hull's displaced volume as a fraction of its
#: length cubed: 0.7 (block coefficient) x 1/5 (beam) x 1/14 (draught), the proportions
#: of a supply vessel (the Northern Clipper: 5.3e6 kg in surge, about 80 m by this rule).
SEA_WATER_DENSITY = 1025.0
HULL_VOLUME_RATIO = 0.7 / 5 / 14


def hull_length(mass: float) -> float:
    """The length (m) of a hull of the proportions of :data:`HULL_VOLUME_RATIO` that
    displaces ``mass`` (kg) of sea water: a vessel's size from its mass alone."""
    return (mass / SEA_WATER_DENSITY / HULL_VOLUME_RATIO) ** (1 / 3)


@final
class ThrusterLayout(eqx.Module):
    """A vessel's thrusters: one entry per thruster in every column.

    Parameters
    ----------
    names : sequence of str
        A distinct name per thruster (the labels of its records).
    kinds : sequence of str
        ``"tunnel"``, ``"azimuth"`` or ``"main"`` (a main propeller with a rudder).
    x, y : array_like, shape (n,)
        Position of each thruster, body-fixed, forward and starboard of the origin (m).
        One entry per thruster (n of them): one number is not spread over them.
    direction : array_like
        A tunnel's thrust direction and a main propeller's (rad from the bow,
        clockwise seen from above; pi/2 pushes to starboard); an azimuth's bias
        direction, where it points when idle (azimuths pointing against each other
        bias each other; :mod:`lookout.actuators.allocation`).
    max_thrust : array_like
        Largest thrust (N); positive.
    min_thrust : array_like
        Smallest thrust (N, negative: astern or to port) of a tunnel or a main
        propeller; between -max_thrust and 0. An azimuth pushes one way only (it turns
        to push the other): one number is the tunnels' and main propellers', and a list
        gives 0 for each azimuth.
    thrust_rate : array_like, optional
        Largest change of thrust per second (N/s); positive. None: no limit.
    time_constant : array_like
        Time constant of the first-order response of thrust to its command (s);
        non-negative, 0 for an instant response.
    turn_rate : array_like, optional
        Largest turning rate of an azimuth or a rudder (rad/s); positive. None: no
        limit. One number is the azimuths' and rudders'; a list gives 0 for each tunnel.
    max_rudder : array_like
        A main propeller's largest rudder angle (rad); positive, below pi/2. One number
        is the main propellers'; a list gives 0 for each other thruster.
    rudder_lift : array_like
        A main propeller's rudder lift per radian of rudder angle per newton of thrust
        (1/rad); non-negative. One number is the main propellers'; a list gives 0 for
        each other thruster.
    weight : array_like
        Allocation weight of each thruster's squared thrust relative to its largest
        (1); positive. A larger weight spares the thruster.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    kinds: tuple[str, ...] = eqx.field(static=True)
    x: np.ndarray
    y: np.ndarray
    direction: np.ndarray
    max_thrust: np.ndarray
    min_thrust: np.ndarray
    thrust_rate: np.ndarray
    time_constant: np.ndarray
    turn_rate: np.ndarray
    max_rudder: np.ndarray
    rudder_lift: np.ndarray
    weight: np.ndarray

    def __init__(
        self,
        names: Sequence[str],
        kinds: Sequence[str],
        x: npt.ArrayLike,
        y: npt.ArrayLike,
        direction: npt.ArrayLike,
        max_thrust: npt.ArrayLike,
        min_thrust: npt.ArrayLike = 0.0,
        thrust_rate: npt.ArrayLike | None = None,
        time_constant: npt.ArrayLike = 0.0,
        turn_rate: npt.ArrayLike | None = None,
        max_rudder: npt.ArrayLike = 0.6,
        rudder_lift: npt.ArrayLike = 0.0,
        weight: npt.ArrayLike = 1.0,
    ):
        thrust_rate = math.inf if thrust_rate is None else thrust_rate
        turn_rate = math.inf if turn_rate is None else turn_rate
        if isinstance(names, str) or isinstance(kinds, str):
            raise check.ParameterError("names", "names and kinds must be lists of strings, one per thruster")
        self.names = tuple(str(n) for n in names)
        self.kinds = tuple(str(k) for k in kinds)
        count = len(self.names)
        if count == 0:
            raise check.ParameterError("names", "names must name at least one thruster")
        if len(self.kinds) != count:
            raise check.ParameterError("kinds", f"kinds must have one entry per thruster ({count}); got {len(self.kinds)}")
        unknown = [kind for kind in dict.fromkeys(self.kinds) if kind not in THRUSTER_KINDS]
        if unknown:
            raise check.ParameterError("kinds", f"kinds must be among {', '.join(THRUSTER_KINDS)}; got {_listed([repr(_short(k)) for k in unknown])}")
        seen: dict[str, int] = {}
        for name in self.names:
            seen[name] = seen.get(name, 0) + 1
            if seen[name] == 2:
                raise check.ParameterError("names", f"names must be distinct; {_short(name)!r} is given more than once")
        # Any: a column is a number or one per thruster, which np.ndim tells apart below
        columns: dict[str, Any] = dict(
            x=x,
            y=y,
            direction=direction,
            max_thrust=max_thrust,
            min_thrust=min_thrust,
            thrust_rate=thrust_rate,
            time_constant=time_constant,
            turn_rate=turn_rate,
            max_rudder=max_rudder,
            rudder_lift=rudder_lift,
            weight=weight,
        )
        kind_array = np.asarray(self.kinds)
        for name, value in columns.items():
            if name in PER_THRUSTER and check.is_concrete(value) and np.shape(value) != (count,):
                got = ", not one number for all; got one number" if np.ndim(value) == 0 else f"; got shape {np.shape(value)}"
                raise check.ParameterError(name, f"{name} must have one entry per thruster ({count}){got}")
            array = check.vector(name, value, count)
            self._refuse(name, np.isnan(array), array, "must not be NaN")
            kinds_it_applies_to = APPLIES_TO.get(name)
            if kinds_it_applies_to is not None:
                other = ~np.isin(kind_array, kinds_it_applies_to)
                if np.all(other) and np.ndim(value) == 0 and float(value) != DEFAULTS[name]:
                    raise check.ParameterError(
                        name,
                        f"{name} applies to {' and '.join(KIND_PLURALS[k] for k in kinds_it_applies_to)} only, and this layout has none: "
                        f"leave {name} out; got {float(value):g}",
                    )
                if np.ndim(value) > 0:  # given per thruster: the others' entries say "none"
                    wrong = other & (array != 0)
                    if np.any(wrong):
                        first = int(np.argmax(wrong))
                        raise check.ParameterError(
                            name,
                            f"{name} of {self.kinds[first]} {_short(self.names[first])!r} must be 0: {NOT_APPLICABLE[name]} "
                            f"(give 0 for each {' and '.join(sorted(set(kind_array[other])))}, or one number for the {' and '.join(KIND_PLURALS[k] for k in kinds_it_applies_to)}); "
                            f"got {array[first]:g}",
                        )
                array = np.where(other, 0.0, array)
            setattr(self, name, array)
        self._check()

    def _refuse(self, name: str, bad: np.ndarray, values: np.ndarray, condition: str) -> None:
        """Fail, naming ``name``, the first thrusters where ``bad`` and their values, when any is."""
        if not np.any(bad):
            return
        where = np.flatnonzero(bad)
        shown = ", ".join(f"{values[i]:g} for {_short(self.names[i])!r}" for i in where[:3])
        more = f" and {where.size - 3} more" if where.size > 3 else ""
        raise check.ParameterError(check.key(name), f"{name} {condition}; got {shown}{more}")

    def _check(self):
        for name in ("x", "y", "direction", "max_thrust", "min_thrust", "max_rudder", "rudder_lift", "weight"):
            values = getattr(self, name)
            self._refuse(name, ~np.isfinite(values), values, "must be finite")
        for name in ("max_thrust", "thrust_rate", "weight"):
            self._refuse(name, getattr(self, name) <= 0, getattr(self, name), "must be positive")
        self._refuse("time_constant", self.time_constant < 0, self.time_constant, "must be non-negative")
        turning = self.is_kind("azimuth") | self.is_kind("main")
        self._refuse("turn_rate", turning & (self.turn_rate <= 0), self.turn_rate, "must be positive for an azimuth or a rudder")
        self._refuse("min_thrust", (self.min_thrust > 0) | (self.min_thrust < -self.max_thrust), self.min_thrust, "must be in [-max_thrust, 0]")
        main = self.is_kind("main")
        self._refuse(
            "max_rudder",
            main & ((self.max_rudder <= 0) | (self.max_rudder >= math.pi / 2)),
            self.max_rudder,
            "must be in (0, pi/2) for a main propeller",
        )
        self._refuse("rudder_lift", self.rudder_lift < 0, self.rudder_lift, "must be non-negative")
        rank = np.linalg.matrix_rank(self.B)
        if rank < 3:
            raise ValueError(
                f"the thrusters ({_listed([repr(_short(n)) for n in self.names])}) span only {rank} of surge, sway and yaw: "
                "a layout must be able to push in every direction and turn (check x, y, direction and rudder_lift)"
            )

    def hull_refusal(self, mass: float) -> str | None:
        """Why these thrusters cannot be those of a vessel of ``mass`` (kg, its surge
        mass), or None when they can: a thruster farther from the origin than a hull of
        that mass is long (:func:`hull_length`) lies outside the vessel, so the layout
        is another vessel's (a 76 m supply vessel's on a 1.3 m model ship)."""
        if not (math.isfinite(mass) and mass > 0):
            return None
        reach = float(np.max(np.hypot(self.x, self.y)))
        length = hull_length(mass)
        if reach <= length:
            return None
        return (
            f"its thrusters reach {reach:.3g} m from the origin, and a vessel of {mass:.3g} kg is a hull of about {length:.2g} m: "
            "the layout is another vessel's; give [actuator.layout] this vessel's thrusters"
        )

    # -- structure -------------------------------------------------------------------------

    @property
    def size(self) -> int:
        """Number of thrusters."""
        return len(self.names)

    def is_kind(self, kind: str) -> np.ndarray:
        """Boolean mask of the thrusters of ``kind``."""
        return np.asarray(self.kinds) == kind

    @property
    def variables(self) -> tuple[tuple[int, str], ...]:
        """The extended variables, in order: (thruster index, part), part one of
        ``"thrust"`` (a tunnel's or a main propeller's T), ``"x"``, ``"y"`` (an
        azimuth's force components) and ``"lift"`` (a main propeller's rudder lift)."""
        parts = {"tunnel": ("thrust",), "azimuth": ("x", "y"), "main": ("thrust", "lift")}
        return tuple((i, part) for i, kind in enumerate(self.kinds) for part in parts[kind])

    def _variable_direction(self, i: int, part: str) -> float:
        if part == "x":
            return 0.0
        if part == "y":
            return math.pi / 2
        return float(self.direction[i]) + (math.pi / 2 if part == "lift" else 0.0)

    @property
    def B(self) -> np.ndarray:
        """The (3, n_variables) map from the extended variables to (X, Y, N)."""
        columns = []
        for i, part in self.variables:
            angle = self._variable_direction(i, part)
            fx, fy = math.cos(angle), math.sin(angle)
            columns.append([fx, fy, self.x[i] * fy - self.y[i] * fx])
        return np.asarray(columns, dtype=float).T

    @property
    def variable_scale(self) -> np.ndarray:
        """Each extended variable's largest magnitude (N): the thruster's largest
        thrust; for a rudder's lift, rudder_lift * max_rudder * max_thrust (at least
        a millionth of the thrust, so that a lift-less rudder still scales)."""
        scale = []
        for i, part in self.variables:
            value = float(self.max_thrust[i])
            if part == "lift":
                value = max(value * float(self.rudder_lift[i] * self.max_rudder[i]), 1e-6 * value)
            scale.append(value)
        return np.asarray(scale)

    @property
    def force_scale(self) -> np.ndarray:
        """(X, Y, N) scale: what every variable at its largest magnitude adds up to per axis."""
        return np.abs(self.B) @ self.variable_scale

    # -- the thrusters' forces --------------------------------------------------------------

    def forces(self, thrust: ArrayLike, angle: ArrayLike) -> Array:
        """Generalized force (X, Y, N) of the thrusters at ``thrust`` (n,) and ``angle`` (n,).

        ``angle`` is an azimuth's angle and a main propeller's rudder angle (a tunnel's
        is not read).
        """
        thrust, angle = jnp.asarray(thrust), jnp.asarray(angle)
        azimuth = jnp.asarray(self.is_kind("azimuth"))
        main = jnp.asarray(self.is_kind("main"))
        heading = jnp.where(azimuth, angle, jnp.asarray(self.direction))
        along = thrust
        across = jnp.where(main, jnp.asarray(self.rudder_lift) * angle * jnp.maximum(thrust, 0.0), 0.0)
        c, s = jnp.cos(heading), jnp.sin(heading)
        fx = along * c - across * s
        fy = along * s + across * c
        moment = jnp.asarray(self.x) * fy - jnp.asarray(self.y) * fx
        return jnp.stack([fx.sum(-1), fy.sum(-1), moment.sum(-1)], axis=-1)

    # -- shipped layouts --------------------------------------------------------------------

    @classmethod
    def cybership_ii(cls, time_constant: float = 0.2) -> ThrusterLayout:
        """Cybership II, the 1:70 model supply ship of Wondergem et al. (2009), Section 5:
        two screw-rudder pairs at the stern and a tunnel thruster in the bow.

        The paper gives the layout in words and the largest generalized force (surge
        2 N, sway 1.5 N, yaw 1.5 N m), not the thrusters' numbers; these are chosen
        (a documented guess) on the 1.255 m hull so that the layout's reach stays within
        those bounds: screws 1.0 N ahead and 0.5 N astern each at x = -0.55 m,
        y = +-0.08 m, rudders +-35 deg at 1.5 rad/s with a lift of 0.6 per radian
        (0.37 N of lift per rudder at full thrust); the bow tunnel +-0.75 N at
        x = +0.47 m. Thrust changes at most 5 N/s (the paper: "the growth rate of the
        actuated forces is limited", no number).

        Parameters
        ----------
        time_constant : float
            Thrust response time constant of every thruster (s); non-negative.
        """
        return cls(
            names=("port-main", "starboard-main", "bow-tunnel"),
            kinds=("main", "main", "tunnel"),
            x=(-0.55, -0.55, 0.47),
            y=(-0.08, 0.08, 0.0),
            direction=(0.0, 0.0, math.pi / 2),
            max_thrust=(1.0, 1.0, 0.75),
            min_thrust=(-0.5, -0.5, -0.75),
            thrust_rate=5.0,
            time_constant=time_constant,
            turn_rate=1.5,
            max_rudder=math.radians(35.0),
            rudder_lift=0.6,
        )

    @classmethod
    def supply_vessel(cls, time_constant: float = 2.0) -> ThrusterLayout:
        """A 76 m platform supply vessel the size of the Northern Clipper of Fossen &
        Strand (1999): two bow tunnel thrusters and two azimuth thrusters aft.

        Neither paper gives a thruster layout; this one is a plausible, documented guess
        in the proportions of supply vessels of that length: bow tunnels of 130 kN
        (about 1 MW each) at x = +30 and +27 m, azimuths of 300 kN (about 2.5 MW)
        at x = -33 m, y = -+6 m turning at 10 deg/s, the port one ahead and the
        starboard one astern (their bias directions: they push against each other when
        idle; :mod:`lookout.actuators.allocation`). Thrust changes at most 40 kN/s per
        tunnel and 60 kN/s per azimuth; thrust follows its command with a time
        constant of ``time_constant``.

        Parameters
        ----------
        time_constant : float
            Thrust response time constant of every thruster (s); non-negative.
        """
        return cls(
            names=("bow-tunnel-1", "bow-tunnel-2", "port-azimuth", "starboard-azimuth"),
            kinds=("tunnel", "tunnel", "azimuth", "azimuth"),
            x=(30.0, 27.0, -33.0, -33.0),
            y=(0.0, 0.0, -6.0, 6.0),
            direction=(math.pi / 2, math.pi / 2, 0.0, math.pi),
            max_thrust=(1.3e5, 1.3e5, 3.0e5, 3.0e5),
            min_thrust=(-1.3e5, -1.3e5, 0.0, 0.0),
            thrust_rate=(4.0e4, 4.0e4, 6.0e4, 6.0e4),
            time_constant=time_constant,
            turn_rate=math.radians(10.0),
        )


register(
    "layout",
    "supply-vessel",
    ThrusterLayout,
    summary="A vessel's thrusters: one entry per thruster in every column.",
    build="supply_vessel",
    parameters=(Value("time_constant", "float", "Thrust response time constant of every thruster (s); non-negative."),),
)


register(
    "layout",
    "cybership-ii",
    ThrusterLayout,
    summary="A vessel's thrusters: one entry per thruster in every column.",
    build="cybership_ii",
    parameters=(Value("time_constant", "float", "Thrust response time constant of every thruster (s); non-negative."),),
)


register(
    "layout",
    "custom",
    ThrusterLayout,
    summary="A vessel's thrusters: one entry per thruster in every column.",
    parameters=(
        Value("names", "strings", "A distinct name per thruster (the labels of its records)."),
        Value("kinds", "strings", '"tunnel", "azimuth" or "main" (a main propeller with a rudder).'),
        Value(
            "x",
            "array",
            "Position of each thruster, body-fixed, forward and starboard of the origin (m).",
            shape="(n,)",
            broadcast="x" not in PER_THRUSTER,
        ),
        Value(
            "y",
            "array",
            "Position of each thruster, body-fixed, forward and starboard of the origin (m).",
            shape="(n,)",
            broadcast="y" not in PER_THRUSTER,
        ),
        Value(
            "direction",
            "array",
            "A tunnel's thrust direction and a main propeller's (rad from the bow, clockwise seen from above; pi/2 pushes to starboard); an azimuth's bias direction, where it points when idle (azimuths pointing against each other bias each other; lookout.actuators.allocation).",
        ),
        Value("max_thrust", "array", "Largest thrust (N); positive."),
        Value("min_thrust", "array", "Smallest thrust (N, negative: astern or to port) of a tunnel or a main propeller; between -max_thrust and 0."),
        Value("thrust_rate", "array", "Largest change of thrust per second (N/s); positive."),
        Value(
            "time_constant",
            "array",
            "Time constant of the first-order response of thrust to its command (s); non-negative, 0 for an instant response.",
        ),
        Value("turn_rate", "array", "Largest turning rate of an azimuth or a rudder (rad/s); positive."),
        Value("max_rudder", "array", "A main propeller's largest rudder angle (rad); positive, below pi/2."),
        Value("rudder_lift", "array", "A main propeller's rudder lift per radian of rudder angle per newton of thrust (1/rad); non-negative."),
        Value("weight", "array", "Allocation weight of each thruster's squared thrust relative to its largest (1); positive."),
    ),
)
