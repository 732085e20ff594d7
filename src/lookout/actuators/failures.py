"""The ways a thruster fails, as data: stop, stuck and reduced, each over a window of time.

A failure acts on one thruster of a :class:`~lookout.actuators.layout.ThrusterLayout`
(``[[actuator.failures]]``, the thruster by name or index), from ``start`` for
``duration`` seconds (to the end of the run when not given; ``start = inf``: never, a
failure a campaign's axis switches on). ``start``, ``duration``
and ``fraction`` are arrays, so a campaign sweeps them (a worst-single-failure
analysis: which thruster, and when) without compiling again; the mode and the thruster
are the structure. While a failure is active the thrusters record a flag of 1
(``THRUSTER.MODE_failure``, the name's characters other than letters, digits and
``_`` as ``_``: ``port_azimuth.stop_failure``).

========  ==================================================================
stop      no thrust: the thruster delivers 0 and the allocation commands it 0
stuck     the thruster holds the thrust and angle it had when the failure began
reduced   its thrust limits (and an azimuth's thrust circle) times ``fraction``
========  ==================================================================

The allocation re-solves with the thrusters that remain (Johansen & Fossen, "Control
allocation - a survey", Automatica 49(5), 2013: reconfiguration after an
actuator failure by changing the constraints of the allocation problem, not the
controller; Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2011,
Section 12.3): a stopped thruster's variables are held at 0, a stuck one's at its held
force (which is so subtracted from the demand the others produce), a reduced one's
limits scaled (:meth:`lookout.actuators.allocation.Allocator.allocate`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import Signal

#: The failure modes and the keys each takes besides thruster, mode, start and duration.
MODES: dict[str, tuple[str, ...]] = {"stop": (), "stuck": (), "reduced": ("fraction",)}
COMMON_KEYS = ("thruster", "mode", "start", "duration")


class ThrusterFailure(eqx.Module):
    """One failure of one thruster.

    Attributes
    ----------
    mode : str
        One of :data:`MODES` (static).
    thruster : int
        The thruster's index in the layout (static).
    start, duration : Array
        The window ``[start, start + duration)`` (s); an infinite duration lasts to the end.
    fraction : Array
        A reduced thruster's share of its thrust range, in (0, 1) (1 for the other modes).
    """

    mode: str = eqx.field(static=True)
    thruster: int = eqx.field(static=True)
    start: Array
    duration: Array
    fraction: Array

    def __init__(self, mode: str, thruster: int, start: ArrayLike, duration: ArrayLike = math.inf, fraction: ArrayLike = 1.0):
        if mode not in MODES:
            raise check.ParameterError("mode", f"mode must be one of {', '.join(MODES)}; got {check.short(mode)}")
        self.mode, self.thruster = mode, int(thruster)
        self.start = jnp.asarray(start, dtype=float)
        self.duration = jnp.asarray(duration, dtype=float)
        self.fraction = jnp.asarray(fraction, dtype=float)

    def active(self, t: ArrayLike) -> Array:
        """Whether the window holds ``t``."""
        return jnp.asarray((t >= self.start) & (t < self.start + self.duration))


_number = check.table_number


def _thruster(location: tuple, value: Any, names: Sequence[str]) -> int:
    listed = ", ".join(names[:8]) + (", ..." if len(names) > 8 else "")
    if isinstance(value, str):
        if value not in names:
            raise check.ParameterError(location, f"the layout has no thruster {check.short(value)} (it has {listed})")
        return list(names).index(value)
    if isinstance(value, int) and not isinstance(value, bool):
        if not 0 <= value < len(names):
            raise check.ParameterError(location, f"thruster index {value} is outside the layout's 0 .. {len(names) - 1} ({listed})")
        return value
    raise check.ParameterError(location, f"thruster must be a thruster's name or its index in the layout; got {check.short(value)}")


def failure_from_table(table: Any, names: Sequence[str], location: tuple = (), *, run_duration: float | None = None) -> ThrusterFailure:
    """The :class:`ThrusterFailure` an ``[[actuator.failures]]`` table describes, for a
    layout of thrusters ``names`` (``run_duration``: the run's, which the start must
    precede); every refusal is a one-line :class:`~lookout._validation.ParameterError`
    whose location is ``location`` and the key.

    Parameters
    ----------
    table : dict
        ``thruster`` (a name or an index), ``mode``, ``start`` (s), optionally
        ``duration`` (s; to the run's end when not given) and, for ``reduced``, ``fraction``.
    names : sequence of str
        The layout's thruster names.
    location : tuple
        Where the table is (``("actuator", "failures", 0)``).
    run_duration : float, optional
        The run's duration.

    Returns
    -------
    ThrusterFailure
    """
    if not isinstance(table, dict):
        raise check.ParameterError(location, f"must be a table with a thruster, a mode and a start; got {check.short(table)}")
    mode = table.get("mode")
    if mode not in MODES:
        raise check.ParameterError(location + ("mode",), f"mode must be one of {', '.join(MODES)}; got {check.short(mode)}")
    allowed = COMMON_KEYS + MODES[mode]
    for key in table:
        if key not in allowed:
            raise check.ParameterError(location + (key,), f"unknown key (a {mode} failure takes {', '.join(allowed)})")
    needed = ("thruster", "start") + MODES[mode]
    for key in needed:
        if key not in table:
            raise check.ParameterError(location + (key,), f"missing key (a {mode} failure needs {', '.join(needed)})")
    thruster = _thruster(location + ("thruster",), table["thruster"], names)
    # inf: never (a failure that a campaign's axis switches on, lookout failures)
    start = _number(location + ("start",), table["start"], allow_inf=True, inf_means="never")
    if run_duration is not None and math.isfinite(start) and start >= run_duration:
        raise check.ParameterError(
            location + ("start",), f"start ({start:g} s) must be before the run's end (duration {run_duration:g} s) for the failure to happen"
        )
    length = _number(location + ("duration",), table.get("duration", math.inf), positive=True, allow_inf=True)
    fraction = 1.0
    if mode == "reduced":
        fraction = _number(location + ("fraction",), table["fraction"])
        if not 0.0 < fraction < 1.0:
            raise check.ParameterError(
                location + ("fraction",), f"fraction must be in (0, 1) (0 is mode 'stop', 1 no failure); got {table['fraction']}"
            )
    return ThrusterFailure(mode, thruster, start, length, fraction)


def flag_prefix(thruster: str) -> str:
    """A thruster's name made an identifier, the part of its failure flags' names before
    the dot (``port-azimuth`` -> ``port_azimuth``)."""
    name = re.sub(r"\W", "_", thruster)  # a signal's name is an identifier
    return name if name.isidentifier() else f"thruster_{name}"


def flag_signal(thruster: str, mode: str, index: int, modes: Sequence[str]) -> Signal:
    """The recorded flag of failure ``index`` of a thruster (``modes``: that thruster's
    failures in order): ``THRUSTER.MODE_failure``, the thruster's name made an identifier
    (``port_azimuth.stop_failure``), with the index when it has two of a mode."""
    suffix = f"{mode}_failure" if list(modes).count(mode) == 1 else f"{mode}{index + 1}_failure"
    return Signal(
        f"{flag_prefix(thruster)}.{suffix}", "1", f"thruster {thruster}: {mode} failure active (1) or not (0), the truth of the injected failure"
    )
