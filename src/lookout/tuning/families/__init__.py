"""Tunable families: the gains a tuner may change, parametrized so that every value of the
parameters satisfies the paper's conditions by construction, and the conditions
checked by the analysis the ``lookout design`` commands use.

A family maps unconstrained parameters theta (any real vector, what the optimizer
moves) to gains of the scenario's components, and back; every theta gives gains inside
the conditions that can be written as a parametrization; the conditions that can only
be checked are checked on each accepted step (:meth:`Family.check`), and the tuner
backtracks until they hold.

A family acts on a whole scenario (:meth:`Family.apply`): some conditions couple the
observer and the controller (Wondergem et al. 2009), others need the observer's
vessel model (Kim 2002). The families, one file each, are named by the component
kinds' declarations (``family=``, :func:`families`); a scenario whose
observer and controller both have one is tuned over both (:class:`Joint`).
"""

from __future__ import annotations

import abc
import importlib
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from jax import Array
from jax.typing import ArrayLike

if TYPE_CHECKING:
    from lookout.analysis.conditions import Condition, Report
    from lookout.sim import Scenario


#: observer kind -> "module:class" of its family (the class's ``of(scenario)`` builds it).
def families(role: str) -> dict[str, str]:
    """kind -> ``"module:Family"`` of the registered kinds of ``role`` (``"observer"`` or
    ``"controller"``) that declare a tuning family (``family=`` in their declaration)."""
    from lookout.scenario.registry import kinds

    return {each.name: each.family for each in kinds(role) if each.family}


class Family(abc.ABC):
    """Gains of a scenario's components, parametrized inside their conditions."""

    name: str
    #: the composition's key of each tuned gain (``observer.velocity_injection_gain``)
    keys: tuple[str, ...]
    #: the command that checks the same conditions and says why one fails
    design: str = "lookout design"

    @abc.abstractmethod
    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        """The gains of ``theta`` (traceable), in the order of :attr:`keys`."""

    @abc.abstractmethod
    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        """The parameters of ``gains`` (which must satisfy the conditions)."""

    @abc.abstractmethod
    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        """``scenario`` with ``gains`` (traceable: ``eqx.tree_at``)."""

    @abc.abstractmethod
    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        """The scenario's own gains, in the order of :attr:`keys`."""

    @abc.abstractmethod
    def check(self, scenario: Scenario) -> Report:
        """The conditions, as the ``lookout design`` command checks them: a
        :class:`~lookout.analysis.conditions.Report`."""

    def candidates(self, scenario: Scenario) -> Iterator[tuple[np.ndarray, ...]]:
        """Gain sets inside the conditions written as a parametrization, nearest the
        scenario's own first, for a start when the scenario's own gains are outside
        (:func:`start`); none by default."""
        return iter(())


_Component = TypeVar("_Component")


def component_as(component: object, kind: type[_Component], role: str) -> _Component:
    """``component``, a scenario's ``role`` (``"observer"``, ``"controller"``), as ``kind``,
    the class whose declaration names the family (:func:`families`); a TypeError names
    ``role`` when it is of another class."""
    if not isinstance(component, kind):
        raise TypeError(f"{role} is a {type(component).__name__}, not the {kind.__name__} its tuning family reads")
    return component


def build(family: Family, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
    """``scenario`` with ``gains``, and its controller following the observer's gains it
    copies (:meth:`lookout.components.Controller.follow`): traceable."""
    import equinox as eqx

    tuned = family.apply(scenario, gains)
    return eqx.tree_at(lambda s: s.controller, tuned, tuned.controller.follow(tuned.observer))


def start(family: Family, scenario: Scenario) -> tuple[np.ndarray, ...]:
    """Where tuning starts: the scenario's own gains when every condition of ``family``
    holds for them; else the first of :meth:`Family.candidates` for which they hold; else
    a ValueError naming the conditions that fail and the command that says why."""
    own = family.current(scenario)
    report = family.check(build(family, scenario, own))
    if report.holds:
        return own
    for gains in family.candidates(scenario):
        if family.check(build(family, scenario, gains)).holds:
            return gains
    failing = [key for key, verdict in report.verdicts.items() if verdict != "holds"]
    raise ValueError(
        f"the starting gains do not satisfy {', '.join(failing)} ({family.design} shows why), and no nearby gains inside "
        "the parametrized conditions satisfy them; start from gains that do"
    )


class Joint(Family):
    """Several families tuned together (an observer's and its controller's): theta laid
    end to end, the gains in the order of the parts, every part's conditions checked."""

    def __init__(self, parts: list[Family], starts: list[tuple[np.ndarray, ...]]):
        self.parts = tuple(parts)
        self.sizes = tuple(int(np.size(part.theta(gains))) for part, gains in zip(parts, starts))
        self.name = "; ".join(part.name for part in parts)
        self.keys = tuple(key for part in parts for key in part.keys)
        self.design = " and ".join(dict.fromkeys(part.design for part in parts))

    def _split(self, values, counts):
        out, start = [], 0
        for count in counts:
            out.append(values[start : start + count])
            start += count
        return out

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        return tuple(g for part, t in zip(self.parts, self._split(theta, self.sizes)) for g in part.gains(t))

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        groups = self._split(tuple(gains), [len(part.keys) for part in self.parts])
        return np.concatenate([part.theta(g) for part, g in zip(self.parts, groups)])

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        for part, group in zip(self.parts, self._split(tuple(gains), [len(part.keys) for part in self.parts])):
            scenario = part.apply(scenario, group)
        return scenario

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        return tuple(g for part in self.parts for g in part.current(scenario))

    def check(self, scenario: Scenario) -> Report:
        from lookout.analysis.conditions import Report

        reports = [part.check(scenario) for part in self.parts]
        return Report(
            "; ".join(r.title for r in reports),
            [c for r in reports for c in r.conditions],
            {k: v for r in reports for k, v in r.quantities.items()},
            [line for r in reports for line in r.summary],
            [note for r in reports for note in r.notes],
        )


def _load(path: str):
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


#: The largest h |lambda| on the negative real axis that each integration method keeps
#: stable (RK4: the real root of 1 - x + x^2/2 - x^3/6 + x^4/24 = 1, x = 2.785; Euler: 2).
STABLE_STEP = {"rk4": 2.785, "euler": 2.0}


def integration_stable(step: float, fastest: float, method: str, gains: str, source: str) -> Condition:
    """The condition that a sampled observer integrates its fastest error pole, near
    -``fastest`` (1/s), stably: ``step * fastest < STABLE_STEP[method]``; ``gains`` names
    the gains in the relation (``"L1"``, ``"K1, K2"``)."""
    from lookout.analysis.conditions import Condition, Inequality

    bound = STABLE_STEP[method]
    return Condition(
        "integration_stable",
        f"h {gains} < x_stable",
        "the sampled observer integrates the error poles stably",
        source,
        (Inequality.check(f"h max {gains}", f"h max({gains}) < {bound} ({method})", step * fastest, "<", bound, units="1", source=source),),
    )


#: The components a tuning may change.
COMPONENTS = ("observer", "controller")


def family_of(scenario: Scenario, components: tuple[str, ...] | None = None) -> tuple[Family, tuple[np.ndarray, ...], list[str]]:
    """The tunable family of ``scenario``, where it starts (:func:`start`) and notes.

    ``components`` (default: each that has a family) chooses among the observer and the
    controller. A component chosen by default whose conditions cannot be met at its
    start is left as it is, with a note saying why; one asked for by name is refused
    (ValueError). A ValueError lists the kinds that have a family when none is left."""
    from lookout.scenario.registry import kind_of

    kinds = {"observer": (kind_of(scenario.observer), families("observer")), "controller": (kind_of(scenario.controller), families("controller"))}
    asked = components is not None
    for name in components or ():
        if name not in COMPONENTS:
            raise ValueError(f"--tune: {name!r} is not a component; use {' or '.join(COMPONENTS)}")
    parts, starts, notes, errors = [], [], [], []
    for role in components or COMPONENTS:
        kind, registry = kinds[role]
        if kind not in registry:
            if asked:
                raise ValueError(f"--tune: {role} {kind} has no tunable family (tunable {role}s: {', '.join(registry) or 'none'})")
            continue
        try:
            part = _load(registry[kind]).of(scenario)
            gains = start(part, scenario)
        except ValueError as error:
            if asked:
                raise ValueError(f"{role} {kind}: {error}") from None
            errors.append(f"{role} {kind}: {error}")
            notes.append(f"{role} {kind} left as it is: {error}")
            continue
        if any(not np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-12, atol=0.0) for a, b in zip(gains, part.current(scenario))):
            notes.append(f"{role} {kind}: its own gains are outside the conditions; tuning starts from the nearest inside them")
        parts.append(part)
        starts.append(gains)
    if not parts:
        if errors:
            raise ValueError(errors[0])
        raise ValueError(
            f"neither observer {kinds['observer'][0]} nor controller {kinds['controller'][0]} has a tunable family yet (tunable "
            f"observers: {', '.join(kinds['observer'][1])}; controllers: {', '.join(kinds['controller'][1]) or 'none'})"
        )
    if len(parts) == 1:
        return parts[0], starts[0], notes
    return Joint(parts, starts), tuple(g for gains in starts for g in gains), notes


__all__ = ["COMPONENTS", "Family", "Joint", "build", "component_as", "families", "family_of", "start"]
