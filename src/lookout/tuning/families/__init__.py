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
vessel model (Kim 2002). The families, one file each, are registered by component
kind in :data:`OBSERVER_FAMILIES` and :data:`CONTROLLER_FAMILIES`; a scenario whose
observer and controller both have one is tuned over both (:class:`Joint`).
"""

from __future__ import annotations

import abc
import importlib

import numpy as np

#: observer kind -> "module:class" of its family (the class's ``of(scenario)`` builds it).
OBSERVER_FAMILIES = {
    "passive": "lookout.tuning.families.passive:PassiveFamily",
}
#: controller kind -> "module:class" of its family.
CONTROLLER_FAMILIES: dict[str, str] = {}


class Family(abc.ABC):
    """Gains of a scenario's components, parametrized inside their conditions."""

    name: str
    #: the composition's key of each tuned gain (``observer.velocity_injection_gain``)
    keys: tuple[str, ...]
    #: the command that checks the same conditions and says why one fails
    design: str = "lookout design"

    @abc.abstractmethod
    def gains(self, theta) -> tuple:
        """The gains of ``theta`` (traceable), in the order of :attr:`keys`."""

    @abc.abstractmethod
    def theta(self, gains) -> np.ndarray:
        """The parameters of ``gains`` (which must satisfy the conditions)."""

    @abc.abstractmethod
    def apply(self, scenario, gains):
        """``scenario`` with ``gains`` (traceable: ``eqx.tree_at``)."""

    @abc.abstractmethod
    def current(self, scenario) -> tuple:
        """The scenario's own gains, in the order of :attr:`keys`."""

    @abc.abstractmethod
    def check(self, scenario):
        """The conditions, as the ``lookout design`` command checks them: a
        :class:`~lookout.analysis.conditions.Report`."""

    def size(self, scenario) -> int:
        """The length of theta."""
        return int(np.size(self.theta(self.current(scenario))))


class Joint(Family):
    """Several families tuned together (an observer's and its controller's): theta laid
    end to end, the gains in the order of the parts, every part's conditions checked."""

    def __init__(self, parts: list[Family], scenario):
        self.parts = tuple(parts)
        self.sizes = tuple(part.size(scenario) for part in parts)
        self.name = "; ".join(part.name for part in parts)
        self.keys = tuple(key for part in parts for key in part.keys)
        self.design = " and ".join(dict.fromkeys(part.design for part in parts))

    def _split(self, values, counts):
        out, start = [], 0
        for count in counts:
            out.append(values[start:start + count])
            start += count
        return out

    def gains(self, theta):
        return tuple(g for part, t in zip(self.parts, self._split(theta, self.sizes)) for g in part.gains(t))

    def theta(self, gains) -> np.ndarray:
        groups = self._split(tuple(gains), [len(part.keys) for part in self.parts])
        return np.concatenate([part.theta(g) for part, g in zip(self.parts, groups)])

    def apply(self, scenario, gains):
        for part, group in zip(self.parts, self._split(tuple(gains), [len(part.keys) for part in self.parts])):
            scenario = part.apply(scenario, group)
        return scenario

    def current(self, scenario) -> tuple:
        return tuple(g for part in self.parts for g in part.current(scenario))

    def check(self, scenario):
        from lookout.analysis.conditions import Report

        reports = [part.check(scenario) for part in self.parts]
        return Report("; ".join(r.title for r in reports), [c for r in reports for c in r.conditions],
                      {k: v for r in reports for k, v in r.quantities.items()}, [line for r in reports for line in r.summary],
                      [note for r in reports for note in r.notes])


def _load(path: str):
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


def family_of(scenario) -> Family:
    """The tunable family of ``scenario``: its observer's, joined with its controller's
    where that has one; a ValueError lists the kinds that have one."""
    from lookout.registry import kind_of

    observer, controller = kind_of(scenario.observer), kind_of(scenario.controller)
    parts = []
    if observer in OBSERVER_FAMILIES:
        parts.append(_load(OBSERVER_FAMILIES[observer]).of(scenario))
    if controller in CONTROLLER_FAMILIES:
        parts.append(_load(CONTROLLER_FAMILIES[controller]).of(scenario))
    if not parts:
        raise ValueError(f"neither observer {observer} nor controller {controller} has a tunable family yet (tunable observers: "
                         f"{', '.join(OBSERVER_FAMILIES)}; controllers: {', '.join(CONTROLLER_FAMILIES) or 'none'})")
    return parts[0] if len(parts) == 1 else Joint(parts, scenario)


__all__ = ["CONTROLLER_FAMILIES", "OBSERVER_FAMILIES", "Family", "Joint", "family_of"]
