"""Scenario files: everything one simulation needs, in a TOML file a user can edit.

A scenario file is a composition (:mod:`lookout.scenario.composition`): one table per component
(``[plant]``, ``[sensor]``, ``[observer]``, ``[controller]``, ``[reference]``,
``[actuator]``), each with ``kind`` and its parameters, nested tables for parts, and
``[simulation]``; ``preset = "NAME:CASE"`` starts from a reproduction's case::

    preset = "fossen-strand-1999"

    [simulation]
    duration = 3000.0

    [plant.vessel]
    kind = "custom"
    mass_matrix = [[5.3e6, 0, 0], [0, 8.3e6, 0], [0, 0, 3.7e9]]
    damping_matrix = [[5.0e4, 0, 0], [0, 2.7e5, -4.4e6], [0, -4.4e6, 4.2e8]]

A key left out takes its kind's default. ``lookout reproduce NAME --write-scenario
FILE`` writes a reproduction's case with every key spelled out and described, and
:func:`simulate_trajectory` on that file simulates the same runs with the same keys, so
it gives the reproduction's numbers.

Errors are one line: the file, the key (``plant.vessel.mass_matrix``), its line in the
file when it can be found, and the condition.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import ValidationError

from lookout.scenario import registry
from lookout.scenario._toml import FileError, key_line, read, write
from lookout.scenario.composition import TOP_KEYS, Composition, CompositionError, SimulationSettings, compose, key_text, state_parameters
from lookout.scenario.settings import explain

if TYPE_CHECKING:
    import xarray as xr

    from lookout.results import Trajectory


@dataclass(frozen=True)
class CompositionSpec:
    """A scenario file that is a composition (:mod:`lookout.scenario.composition`): its tables
    validated and built."""

    composition: Composition
    source: str = field(default="<scenario>")

    # a Scenario, returned as Any: typed Scenario, lookout.studies.store indexes by a
    # record signal's dim (str | None) without narrowing it, which mypy refuses
    def build(self) -> Any:
        """The :class:`~lookout.sim.Scenario` (built when the file was read)."""
        return self.composition.scenario

    @property
    def seeds(self) -> list[int]:
        return self.composition.seeds

    @property
    def runs(self) -> int:
        return self.composition.simulation.runs

    @property
    def runs_key(self) -> str:
        return "simulation.runs"

    def values(self) -> dict:
        """The full composition, for the paths a campaign sweeps."""
        return self.composition.document

    @property
    def title(self) -> str:
        kinds = self.composition.kinds
        return ", ".join(f"{role} {kinds[role]}" for role in ("plant", "observer", "controller") if kinds[role] != "none")

    def document(self) -> dict:
        """The full composition: every key spelled out."""
        return self.composition.document

    def with_settings(self, changes: dict[str, Any], source: str | None = None) -> CompositionSpec:
        """This composition with ``changes`` (key paths from the file's root) applied."""
        try:
            return CompositionSpec(self.composition.with_changes(changes), source or self.source)
        except CompositionError as error:
            raise FileError(f"{source or self.source}: {error}") from None


def composition_comments(document: dict) -> dict[str, str]:
    """Every key of a full composition with its description (for the written file)."""
    comments = {"simulation": "the time grid, the integrator, runs and seeds"}
    for name, info in SimulationSettings.model_fields.items():
        if info.description is not None:
            comments[f"simulation.{name}"] = info.description
    for role in registry.COMPONENT_ROLES:
        table = document.get(role)
        if isinstance(table, dict):
            _table_comments(role, table, role, comments)
    sensors = document.get("sensors")
    if isinstance(sensors, dict):
        comments["sensors"] = "the sensor suite: one table per sensor, [sensors.NAME], its channels recorded as NAME.signal"
        for name, table in sensors.items():
            if isinstance(table, dict):
                _table_comments("instrument", table, f"sensors.{name}", comments)
                comments[f"sensors.{name}"] = f"sensor {name}: {comments.get(f'sensors.{name}', 'an instrument').partition(': ')[2]}"
                if "failures" in table:
                    comments[f"sensors.{name}.failures"] = "its failures: mode, start, duration and the mode's keys (docs/sensors.md)"
    if isinstance(document.get("references"), dict):
        _table_comments("references", document["references"], "references", comments)
        comments["references"] = "the stage that combines the references into the measured_position and measured_heading the observer reads"
    return comments


def _table_comments(role: str, table: dict, prefix: str, comments: dict) -> None:
    try:
        kind = registry.kind(role, table["kind"])
    except (ValueError, KeyError):
        return
    comments[prefix] = f"{role}: {kind.description}"
    comments[f"{prefix}.kind"] = f"one of {', '.join(registry.names(role))} (`lookout components {role}`)"
    if kind.designs:
        comments[f"{prefix}.design"] = f"gain-synthesis rule: one of {', '.join(kind.designs)}"
    parameters = kind.parameters(table.get("design"))
    for p in parameters:
        if p.sort == "part" and p.role is not None and isinstance(table.get(p.name), dict):  # a part's role is always set
            _table_comments(p.role, table[p.name], f"{prefix}.{p.name}", comments)
        elif p.description:
            comments[f"{prefix}.{p.name}"] = p.description + ("" if p.sort != "part" or p.name in table else " (the plant's, unless given)")
    if isinstance(table.get("initial"), dict):
        comments[f"{prefix}.initial"] = (
            "the initial state (zeros where left out)" if role == "plant" else "the initial guess (its defaults where left out)"
        )
        method = {"plant": "state", "observer": "guess"}.get(role)
        owner = kind.component_class
        if method and hasattr(owner, method):
            for p in state_parameters(getattr(owner, method)):
                if p.description:
                    comments[f"{prefix}.initial.{p.name}"] = p.description


#: Keys only a campaign spec has (``lookout campaign run``), and keys only a benchmark
#: spec has (``lookout benchmark observers --spec``); a scenario file has neither.
CAMPAIGN_ONLY = frozenset({"seeds_per_point", "sweep", "chunk_runs", "trajectories", "after"})
SPEC_ONLY = frozenset({"title", "observers", "conditions", "full", "quick", "outage_signals", "recommend_by"})


def other_form(document: dict, source: str) -> str | None:
    """Why ``document`` is not a scenario file when it is a campaign spec or a benchmark
    spec (it has no table of a scenario, and a spec's keys), with the command that
    runs it; None otherwise."""
    keys = set(document)
    if keys & (set(TOP_KEYS) - {"plugins"}):
        return None
    scenario = document.get("scenario")
    named = f" (its scenario is {scenario})" if isinstance(scenario, str) else ""
    if keys & SPEC_ONLY:
        return f"a benchmark spec, not a scenario file: run it with lookout benchmark observers --spec {source}{named}"
    if keys & CAMPAIGN_ONLY or "scenario" in keys:
        return f"a campaign spec, not a scenario file: run it with lookout campaign run {source}{named}"
    return None


def from_document(document: dict, source: str = "<scenario>", text: str | None = None) -> CompositionSpec:
    """Validate and build a parsed scenario file (see the module docstring); a campaign
    spec or a benchmark spec is refused in one line that names the command for it."""
    if not isinstance(document, dict):
        raise FileError(f"{source}: a scenario file is a table of tables")
    other = other_form(document, source)
    if other is not None:
        raise FileError(f"{source}: {other}")
    try:
        return CompositionSpec(compose(document), source)
    except CompositionError as error:
        raise (located(source, text, error.location, error.reason) if error.location else FileError(f"{source}: {error.reason}")) from None


def read_spec(path: str | Path, *, runs: int | None = None, seed: int | None = None) -> tuple[CompositionSpec, str]:
    """:func:`load`, and the file's text."""
    document, text = read(path)
    other = other_form(document, str(path))
    if other is not None:  # before runs and seed add a [simulation] table of their own
        raise FileError(f"{path}: {other}")
    simulation = document.get("simulation", {})
    if isinstance(simulation, dict) and (runs is not None or seed is not None):
        given = {"runs": runs, "seed": seed}
        document = {**document, "simulation": {**simulation, **{k: v for k, v in given.items() if v is not None}}}
    return from_document(document, str(path), text), text


def load(path: str | Path, *, runs: int | None = None, seed: int | None = None) -> CompositionSpec:
    """Read, validate and build the scenario file at ``path``; ``runs`` and ``seed``
    override its own."""
    return read_spec(path, runs=runs, seed=seed)[0]


def save(spec: CompositionSpec, path: str | Path, *, header: str | None = None) -> Path:
    """Write ``spec`` as a scenario file with every key and its description."""
    header = header or f"lookout scenario: {spec.title}.\nRun it with: lookout run {Path(path).name} --out DIR"
    return write(path, spec.document(), composition_comments(spec.document()), header)


def located(source: str, text: str | None, location: tuple, message: str) -> FileError:
    """The one-line error for the key at ``location``: file, key, its line in ``text``
    when it can be found, and ``message``."""
    line = key_line(text, location) if text else None
    where = f" (line {line})" if line else ""
    return FileError(f"{source}: {key_text(location)}{where}: {message}" if location else f"{source}: {message}")


def describe(error: ValidationError, source: str, text: str | None, prefix: tuple = ()) -> str:
    """One line for the first error of a pydantic validation: file, key, line, condition."""
    location, message = explain(error)
    return str(located(source, text, prefix + location, message))


def simulate_trajectory(spec: CompositionSpec, *, progress: Callable[[int, int], object] | None = None) -> Trajectory:
    """Simulate the scenario for its seeds: a :class:`~lookout.Trajectory`, batched as
    :func:`lookout.scenario.composition.simulate` batches it (run i uses ``jax.random.key(seed + i)``)."""
    from lookout.scenario.composition import simulate

    return simulate(spec.composition, progress=progress)


def to_dataset(spec: CompositionSpec, trajectory: Trajectory) -> xr.Dataset:
    """The trajectory as an :class:`xarray.Dataset` with ``seed`` along ``run`` and the
    composition (JSON) in its attributes."""
    ds = trajectory.to_xarray().assign_coords(seed=("run", np.asarray(spec.seeds, dtype=np.int64), {"long_name": "PRNG seed of the run"}))
    ds.attrs.update({"composition": json.dumps(spec.document())})
    return ds


def simulate_spec(spec: CompositionSpec, *, progress: Callable[[int, int], object] | None = None) -> xr.Dataset:
    """:func:`simulate_trajectory` as :func:`to_dataset`."""
    return to_dataset(spec, simulate_trajectory(spec, progress=progress))
