"""Design from a scenario: the conditions of every component in a scenario file that has
any, checked for the file's own plant, gains and sea (``lookout design FILE``), and gains
proposed inside them (``--propose``).

A kind's conditions are what its declaration names: ``checks`` (``"module:function"``,
called with the built :class:`~lookout.scenario.composition.Composition`, returning a
:class:`~lookout.analysis.conditions.Report`), else its tuning ``family``'s
:meth:`~lookout.tuning.families.Family.check` (the conditions ``lookout tune`` keeps).
The family's gains nearest the file's own that satisfy them are the proposal
(:func:`lookout.tuning.families.start`). Observers do not import this module, nor the
analysis it calls.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lookout.analysis.conditions import Condition, Report
from lookout.scenario import registry
from lookout.scenario.composition import Composition

#: The roles whose kinds may declare conditions, in the order they are checked.
CHECKED_ROLES = ("observer", "controller")


@dataclass(frozen=True)
class ComponentDesign:
    """One component's conditions: its role and kind, the report at the file's own
    gains, and (with a proposal) the gains proposed, file key -> value, with the report
    at those gains (``proposal``)."""

    role: str
    kind: str
    report: Report
    proposed: dict | None = None
    proposal: Report | None = None


def component_designs(composition: Composition, *, propose: bool = False) -> list[ComponentDesign]:
    """The conditions of each component of ``composition`` whose kind declares any (see
    the module docstring); with ``propose``, the gains a family proposes and the
    conditions at them. A component whose family has no gains inside its conditions is
    reported with the reason as a note. ``report`` is always the file's own gains';
    the proposal's conditions are ``proposal``, apart."""
    from lookout.tuning.families import build, start

    scenario = composition.scenario
    found = []
    for role in CHECKED_ROLES:
        kind = registry.kind(role, composition.kinds[role])
        if kind.checks is not None:
            found.append(ComponentDesign(role, kind.name, registry.resolve(kind.checks)(composition)))
            continue
        if kind.family is None:
            continue
        family = registry.resolve(kind.family).of(scenario)
        report = family.check(build(family, scenario, family.current(scenario)))
        if not propose:
            found.append(ComponentDesign(role, kind.name, report))
            continue
        try:
            gains = start(family, scenario)
        except ValueError as error:
            found.append(ComponentDesign(role, kind.name, report.extended(notes=[f"no gains proposed: {error}"]), {}))
            continue
        proposed = {key: _plain(value) for key, value in zip(family.keys, gains)}
        found.append(ComponentDesign(role, kind.name, report, proposed, family.check(build(family, scenario, gains))))
    return found


def combined(designs: list[ComponentDesign], source: str) -> Report:
    """The designs at the file's own gains as one report (each condition keyed by its
    component), for the file's verdict."""
    if not designs:
        return Report(f"{source}: no component with conditions", [])
    return _joined([(each, each.report) for each in designs], f" in {source}")


def combined_proposal(designs: list[ComponentDesign], source: str) -> Report | None:
    """The conditions with the proposed gains in place of the file's (a component without
    a proposal keeps its file's report) as one report, or None when nothing was proposed."""
    if not any(each.proposed for each in designs):
        return None
    report = _joined([(each, _proposal(each) if each.proposed else each.report) for each in designs], f" in {source} with the proposed gains")
    notes = [
        f"{each.role} {each.kind} proposed: " + "; ".join(f"{key} = {value}" for key, value in each.proposed.items())
        for each in designs
        if each.proposed
    ]
    return report.extended(notes=notes)


def _proposal(design: ComponentDesign) -> Report:
    assert design.proposal is not None  # a design with proposed gains has their report
    return design.proposal


def _joined(reports: list[tuple[ComponentDesign, Report]], where: str) -> Report:
    conditions: list[Condition] = []
    quantities: dict[str, Any] = {}
    summary: list[str] = []
    notes: list[str] = []
    for each, report in reports:
        summary.append(f"{each.role} {each.kind}: {report.title}")
        conditions.extend(report.conditions)
        quantities[each.role] = report.quantities
        summary.extend(report.summary)
        notes.extend(report.notes)
    return Report("; ".join(f"{each.role} {each.kind}" for each, _ in reports) + where, conditions, quantities, summary, notes)


def _plain(value):
    """A gain as file data, to 12 significant digits (what a file written by hand holds)."""
    array = np.asarray(value, dtype=float)
    rounded = np.vectorize(lambda x: float(f"{x:.12g}"), otypes=[float])(array) if array.size else array
    return float(rounded) if array.ndim == 0 else rounded.tolist()


__all__ = ["CHECKED_ROLES", "ComponentDesign", "combined", "combined_proposal", "component_designs"]
