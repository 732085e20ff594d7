"""The ``lookout components`` command: the registered kinds, their parameters, and what
each needs and provides (registered by :mod:`lookout.cli`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.markup import escape
from rich.table import Table

from lookout._commandline import console
from lookout._json import json_safe
from lookout._validation import InputError, one_line

if TYPE_CHECKING:
    from lookout.scenario.composition import Composition
    from lookout.scenario.registry import Kind


def example(each: Kind) -> Composition | None:
    """A built composition with a component of kind ``each`` in it: the first
    reproduction case that uses the kind, else the first case in which the kind, put in
    place of that case's component with its defaults, composes. None if there is none."""
    from lookout.scenario import registry
    from lookout.scenario.composition import CompositionError, compose

    documents = [registry.preset(name, case) for name, case in registry.presets()]
    for document in documents:
        table = _find_table(document, each.role)
        if isinstance(table, dict) and table.get("kind") == each.name:
            return compose(document)
    for document in documents:
        if each.role not in registry.COMPONENT_ROLES:
            break
        try:
            return compose({**document, each.role: {"kind": each.name}})
        except (CompositionError, ValueError):
            continue
    return None


def _find_table(document: dict, role: str):
    """The first table of ``role`` in a composition: a component's, or a part's."""
    if role in document:
        return document[role]
    for value in document.values():
        if isinstance(value, dict):
            found = _find_table(value, role)
            if found is not None:
                return found
    return None


def signals_of(role: str, component: Any) -> dict[str, list[str]]:
    """What a built component provides and needs, by signal name."""
    names = lambda signals: [s.name for s in signals]  # noqa: E731
    if role == "plant":
        return {"provides": names(component.variable_signals), "needs": [f"input {n}" for n in component.input_layout.names]}
    if role == "sensor":
        return {"provides": [f"measurement {n}" for n in component.measurement_layout.names], "needs": []}
    if role == "observer":
        return {
            "provides": [f"estimate {n}" for n in names(component.estimate_signals)] + [f"extra {n}" for n in names(component.extra_signals)],
            "needs": [f"measurement {n}" for n in component.measurement_layout.names] + [f"input {n}" for n in component.input_layout.names],
        }
    if role == "controller":
        return {
            "provides": ["input"],
            "needs": [f"estimate {n}" for n in component.estimate_needs]
            + [f"measurement {n}" for n in component.measurement_needs]
            + [f"reference {n}" for n in component.reference_needs],
        }
    if role == "reference":
        return {"provides": [f"reference {n}" for n in names(component.reference_signals)], "needs": []}
    return {"provides": [], "needs": []}


def _matching(name: str | None):
    from lookout.scenario import registry

    if name is None:
        return registry.kinds()
    if name in registry.ROLES:
        return registry.kinds(name)
    found = [each for each in registry.kinds() if each.name == name]
    if not found:
        known = sorted({each.name for each in registry.kinds()})
        raise InputError(f"KIND: no role or kind {name!r} (roles: {', '.join(registry.ROLES)}; kinds: {', '.join(known)})")
    return found


def _describe(each, design) -> dict:
    from lookout.scenario import registry

    entry = registry.describe_kind(each, design)
    composition = example(each) if each.role in registry.COMPONENT_ROLES else None
    if composition is not None:
        built = getattr(composition.scenario, each.role)
        entry.update(signals_of(each.role, built))
    return entry


def _plant_part_default(role: str) -> str:
    """What a plant takes for a required part its file leaves out: its role's first kind
    with that kind's defaults, where the kind has a default for every value."""
    from lookout.scenario import registry

    name = registry.default_kind(role)
    if name is None:
        raise ValueError(f"no {role} kind is the default of its role: a plant's {role} part has no default to show")
    first = registry.kind(role, name)
    missing = [p.name for p in first.parameters() if p.sort == "value" and p.required]
    if missing:
        return f"required: a {role} table ({first.name} needs {', '.join(missing)})"
    return f"a {role} table; else {first.name} with its defaults"


def components(
    kind: Annotated[str | None, typer.Argument(metavar="[KIND]", help="A role (observer, plant, ...) or a kind (passive, dp-vessel, ...).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of tables.")] = False,
    plugin: Annotated[
        list[str] | None,
        typer.Option(
            "--plugin", metavar="FILE", help="A Python file (or module) that registers kinds of its own, listed with lookout's; repeat for several."
        ),
    ] = None,
) -> None:
    """List the registered components: kinds by role, or one kind's parameters (name,
    default, type and range, description with units) and what it needs and provides.

    A scenario file has one table per component ([plant], [sensor], [observer],
    [controller], [reference], [actuator]) with `kind` and these parameters; its
    `plugins` (and --plugin here) add kinds of your own, as do installed packages
    under the entry-point group lookout.components (LOOKOUT_ENTRY_POINTS=0 leaves
    those out).
    """
    from lookout.scenario import registry

    for each in plugin or []:
        try:
            registry.load_plugin(each, Path.cwd())
        except ValueError as error:
            raise InputError(f"--plugin {each}: {one_line(error)}") from None
    try:
        registry.load_entry_points()  # a listing shows installed packages' kinds too
    except ValueError as error:
        raise InputError(one_line(error)) from None
    found = _matching(kind)
    detail = kind is not None and all(each.name == kind for each in found)
    if as_json:
        entries = []
        for each in found:
            for design in each.designs or [None]:
                entry = (
                    _describe(each, design)
                    if detail
                    else {"role": each.role, "kind": each.name, "designs": list(each.designs), "description": each.description}
                )
                entries.append(entry)
                if not detail:
                    break
        print(json.dumps(json_safe(entries), indent=2))
        return
    if not detail:
        table = Table(title="lookout components (`lookout components KIND` for one kind's parameters)", title_justify="left", box=box.SIMPLE_HEAD)
        for column in ("role", "kind", "design rules", "description"):
            table.add_column(column, justify="left")
        for each in found:
            table.add_row(each.role, each.name, ", ".join(each.designs), escape(each.description))
        console.print(table)
        return
    for each in found:
        for design in each.designs or [None]:
            entry = _describe(each, design)
            title = escape(f"{each.role} {each.name}" + (f", design {design!r}" if design else "") + f": {entry['description']}")
            table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD)
            for column in ("parameter", "default", "type", "description"):
                table.add_column(column, justify="left")
            for p in entry["parameters"]:
                if p["sort"] == "value":
                    default = "required" if p["required"] else json.dumps(p["default"])
                elif p["sort"] == "part" and p["role"] in ("observer", "controller", "sensor", "reference"):
                    default = f"the composition's {p['role']}"
                elif p["sort"] == "part" and each.role == "plant" and p["from_plant"]:  # a plant's required part: its table or its role's first kind
                    default = _plant_part_default(p["role"])
                elif p["sort"] == "part":
                    default = f"a {p['role']} table" + ("; else the plant's" if p["from_plant"] else "")
                else:
                    default = "from the composition"
                table.add_row(p["name"], escape(default), escape(p["type"]), escape(p["description"]))
            console.print(table)
            for what in ("provides", "needs"):
                if entry.get(what):
                    console.print(f"  {what}: {', '.join(entry[what])}", highlight=False)
            console.print()


def register(app: typer.Typer) -> None:
    """Add ``lookout components`` to the main command."""
    app.command("components")(components)
