"""Scenario files: everything one simulation needs, in a TOML file a user can edit.

A scenario file names a **template** (a family of scenarios lookout can build: each
reproduction is one), a **case** of it (which of the template's scenarios) and its
**settings**: every value the template's builder takes (plant, vessel matrices,
environment, sensors and dropouts, observer gains, controller, reference, actuator
limits, horizon and steps, runs and seed), validated by the template's pydantic model::

    template = "fossen-strand-1999"
    case = "paper"

    [settings]
    duration = 3000.0
    noise_std = [0.5, 0.5, 0.0017453292519943296]

    [settings.vessel]
    model = "custom"
    mass_matrix = [[5.3e6, 0, 0], [0, 8.3e6, 0], [0, 0, 3.7e9]]
    damping_matrix = [[5.0e4, 0, 0], [0, 2.7e5, -4.4e6], [0, -4.4e6, 4.2e8]]

A key left out takes the template's default. ``lookout reproduce NAME
--write-scenario FILE`` writes a reproduction's scenario with every setting spelled out,
and :func:`simulate_file` on that file simulates the same runs with the same keys, so
it gives the reproduction's numbers.

Errors are one line: the file, the key (``settings.vessel.mass_matrix``), its line in
the file when it can be found, and the condition.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from pydantic import BaseModel, ValidationError

from lookout import registry
from lookout._validation import one_line
from lookout.composition import Composition, CompositionError, SimulationSettings, compose
from lookout.settings import explain
from lookout.studies._toml import FileError, key_line, read, write

#: Top-level keys of a scenario file.
TOP_KEYS = ("template", "case", "settings")


@dataclass(frozen=True)
class Template:
    """A family of scenarios: a settings model and a builder per case."""

    name: str
    title: str
    settings: type[BaseModel]
    cases: tuple[str, ...]
    build: Callable[[BaseModel, str], Any]
    #: Whether the reproduction vmaps its runs over a scenario stacked per run
    #: (``batched_scenario=True``) rather than one shared scenario; the two agree to
    #: rounding, and a scenario file batches as its reproduction does, to give the
    #: same numbers to the last bit.
    stacked: bool = False


def templates() -> dict[str, Template]:
    """The templates by name: one per reproduction (its Config and :data:`CASES`)."""
    from lookout.papers import REPRODUCTIONS

    return {
        name: Template(name, module.TITLE, module.Config, module.CASES, module.case_scenario, getattr(module, "STACKED_BATCHES", False))
        for name, module in REPRODUCTIONS.items()
        if not hasattr(module, "cases")  # issue 23: a Reproduction's files are compositions; the template form goes with the last
    }


@dataclass(frozen=True)
class ScenarioSpec:
    """A validated scenario file: the template, the case and the settings."""

    template: Template
    case: str
    settings: BaseModel
    source: str = field(default="<scenario>")

    def build(self):
        """The :class:`~lookout.sim.Scenario`."""
        return self.template.build(self.settings, self.case)

    @property
    def seeds(self) -> list[int]:
        return list(self.settings.seeds)

    @property
    def runs(self) -> int:
        return self.settings.runs

    @property
    def title(self) -> str:
        return f"{self.template.name}, case {self.case}"

    @property
    def stacked(self) -> bool:
        return self.template.stacked

    @property
    def runs_key(self) -> str:
        return "settings.runs"

    @property
    def cases(self) -> tuple[str, ...]:
        return self.template.cases

    def values(self) -> dict:
        """The settings as plain data, for the paths a campaign sweeps."""
        return self.settings.model_dump(mode="python")

    def with_case(self, case: str) -> "ScenarioSpec":
        return ScenarioSpec(self.template, case, self.settings, self.source)

    def document(self) -> dict:
        """The file's content as a dict: every setting spelled out."""
        return {"template": self.template.name, "case": self.case, "settings": self.settings.model_dump(mode="json")}

    def with_settings(self, changes: dict[str, Any], source: str | None = None) -> "ScenarioSpec":
        """This scenario with ``changes`` (dotted paths such as ``noise_std[0]`` or
        ``vessel.mass``, relative to ``settings``) applied and validated again."""
        values = self.settings.model_dump(mode="python")
        for path, value in changes.items():
            set_path(values, path, value, self.settings)
        return ScenarioSpec(self.template, self.case, _validate(self.template.settings, values, source or self.source, None, ("settings",)), source or self.source)


@dataclass(frozen=True)
class CompositionSpec:
    """A scenario file that is a composition (:mod:`lookout.composition`): its tables
    validated and built."""

    composition: Composition
    source: str = field(default="<scenario>")

    def build(self):
        """The :class:`~lookout.sim.Scenario` (built when the file was read)."""
        return self.composition.scenario

    @property
    def seeds(self) -> list[int]:
        return self.composition.seeds

    @property
    def runs(self) -> int:
        return self.composition.simulation.runs

    @property
    def stacked(self) -> bool:
        return self.composition.simulation.batch == "stacked"

    @property
    def runs_key(self) -> str:
        return "simulation.runs"

    #: a composition has no cases (a campaign sweeps its keys)
    cases: tuple = ()
    case = None

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

    def with_settings(self, changes: dict[str, Any], source: str | None = None) -> "CompositionSpec":
        """This composition with ``changes`` (key paths from the file's root) applied."""
        try:
            return CompositionSpec(self.composition.with_changes(changes), source or self.source)
        except CompositionError as error:
            raise FileError(f"{source or self.source}: {error}") from None


def composition_comments(document: dict) -> dict[str, str]:
    """Every key of a full composition with its description (for the written file)."""
    comments = {"simulation": "the time grid, the integrator, runs and seeds"}
    for name, info in SimulationSettings.model_fields.items():
        comments[f"simulation.{name}"] = info.description
    for role in registry.COMPONENT_ROLES:
        table = document.get(role)
        if isinstance(table, dict):
            _table_comments(role, table, role, comments)
    return comments


def _table_comments(role: str, table: dict, prefix: str, comments: dict) -> None:
    try:
        kind = registry.kind(role, table["kind"])
    except (ValueError, KeyError):
        return
    comments[prefix] = f"{role}: {kind.description}"
    comments[f"{prefix}.kind"] = f"one of {', '.join(registry.KINDS[role])} (`lookout components {role}`)"
    if kind.designs:
        comments[f"{prefix}.design"] = f"gain-synthesis rule: one of {', '.join(kind.designs)}"
    parameters = kind.parameters(table.get("design"))
    for p in parameters:
        if p.sort == "part" and isinstance(table.get(p.name), dict):
            _table_comments(p.role, table[p.name], f"{prefix}.{p.name}", comments)
        elif p.description:
            comments[f"{prefix}.{p.name}"] = p.description + ("" if p.sort != "part" or p.name in table else " (the plant's, unless given)")
    if isinstance(table.get("initial"), dict):
        comments[f"{prefix}.initial"] = "the initial state (zeros where left out)" if role == "plant" else "the initial guess (its defaults where left out)"
        method = {"plant": "state", "observer": "guess"}.get(role)
        owner = kind.component_class
        if method and hasattr(owner, method):
            function = getattr(owner, method)
            target = f"{function.__module__}:{function.__qualname__}"
            for p in registry._parameters(target, values_only=True):
                if p.description:
                    comments[f"{prefix}.initial.{p.name}"] = p.description


def _changed_paths(values: dict, defaults: dict, prefix: tuple = ()) -> list[tuple]:
    """Paths (tuples of keys) where ``values`` differs from ``defaults``: nested tables
    are followed, a vector counts as one value."""
    paths = []
    for key, value in values.items():
        default = defaults.get(key) if isinstance(defaults, dict) else None
        if isinstance(value, dict) and isinstance(default, dict):
            paths += _changed_paths(value, default, prefix + (key,))
        elif value != default:
            paths.append(prefix + (key,))
    return paths


def blame(spec: "ScenarioSpec") -> tuple | None:
    """The settings key whose value keeps ``spec`` from making a scenario: the first
    key set away from the template's default whose default, put back alone, lets the
    scenario be built (None when no single key does)."""
    values = spec.settings.model_dump(mode="json")
    defaults = spec.template.settings().model_dump(mode="json")
    for path in _changed_paths(values, defaults)[:MAX_BLAMED_KEYS]:
        trial = json.loads(json.dumps(values))
        target, source = trial, defaults
        for key in path[:-1]:
            target, source = target[key], source[key]
        target[path[-1]] = source[path[-1]]
        try:
            spec.template.build(validate_strictly(spec.template.settings, trial), spec.case)
        except (ValueError, ValidationError):
            continue
        return path
    return None


#: At most this many changed keys are tried back at their defaults to find the one a
#: failed build comes from (each try builds the scenario).
MAX_BLAMED_KEYS = 24


def build_located(spec: "ScenarioSpec", text: str | None = None):
    """``spec.build()``; a ``ValueError`` from the components becomes a
    :class:`FileError` naming the file's key that causes it (:func:`blame`), its line
    and value, with the component's reason after it."""
    if isinstance(spec, CompositionSpec):
        return spec.build()
    try:
        return spec.build()
    except ValueError as error:
        reason = one_line(error)
        path = blame(spec)
        if path is None:
            raise FileError(f"{spec.source}: settings: they make no scenario together ({spec.template.name}, case {spec.case}): {reason}") from None
        value = spec.settings.model_dump(mode="json")
        for key in path:
            value = value[key]
        raise located(spec.source, text, ("settings", *path), f"{json.dumps(value)} makes no scenario with the other settings: {reason}") from None


def _location_text(location: tuple) -> str:
    text = ""
    for part in location:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def located(source: str, text: str | None, location: tuple, message: str) -> FileError:
    """The one-line error for the key at ``location``: file, key, its line in ``text``
    when it can be found, and ``message``."""
    line = key_line(text, location) if text else None
    where = f" (line {line})" if line else ""
    return FileError(f"{source}: {_location_text(location)}{where}: {message}")


def validate_strictly(model: type[BaseModel], values: dict) -> BaseModel:
    """``model`` validated from a file's ``values`` in pydantic's strict mode: a number
    must be a number (an integer is one), a boolean a boolean and a string a string
    (``duration = true`` and ``duration = "100"`` are refused, not read as 1 s and
    100 s). The values go through JSON, whose strict mode takes arrays for tuples; a
    TOML date or time becomes a string, which no number or boolean accepts."""
    text = json.dumps(values, allow_nan=True, default=lambda value: f"<a TOML {type(value).__name__}: {value}>")
    return model.model_validate_json(text, strict=True)


def _validate(model: type[BaseModel], values: dict, source: str, text: str | None, prefix: tuple) -> BaseModel:
    try:
        return validate_strictly(model, values)
    except ValidationError as error:
        raise FileError(describe(error, source, text, prefix)) from None


def describe(error: ValidationError, source: str, text: str | None, prefix: tuple = ()) -> str:
    """One line for the first error of a pydantic validation: file, key, line, condition."""
    location, message = explain(error)
    return str(located(source, text, prefix + location, message))


def _path_parts(path: str) -> list:
    """``"vessel.mass_matrix[0][1]"`` -> ``["vessel", "mass_matrix", 0, 1]``."""
    import re

    parts: list = []
    for name in path.split("."):
        match = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)", name)
        if not match:
            raise FileError(f"{path!r} is not a settings path (names joined by '.', indices as [i])")
        parts.append(match.group(1))
        parts += [int(i) for i in re.findall(r"\[(\d+)\]", match.group(2))]
    return parts


def set_path(values: dict, path: str, value: Any, settings: BaseModel | None = None) -> None:
    """Set ``values`` at the settings path ``path`` (the path must exist)."""
    parts = _path_parts(path)
    target: Any = values
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        here = _location_text(tuple(parts[: depth + 1]))
        if isinstance(part, int):
            if not isinstance(target, (list, tuple)) or part >= len(target):
                size = len(target) if isinstance(target, (list, tuple)) else "no"
                raise FileError(f"settings.{path}: {here} does not exist ({_location_text(tuple(parts[:depth]))} has {size} entries)")
        elif not isinstance(target, dict) or part not in target:
            known = ", ".join(sorted(target)) if isinstance(target, dict) else "none"
            raise FileError(f"settings.{path}: no setting {here!r} (known here: {known})")
        if last:
            if isinstance(target, tuple):
                raise FileError(f"settings.{path}: internal: a tuple was not converted")
            target[part] = value
        else:
            child = target[part]
            if isinstance(child, tuple):
                child = list(child)
                target[part] = child
            target = child


def get_path(values: dict, path: str) -> Any:
    """The value of ``values`` at the settings path ``path``."""
    target: Any = values
    for part in _path_parts(path):
        target = target[part]
    return target


def from_document(document: dict, source: str = "<scenario>", text: str | None = None) -> "ScenarioSpec | CompositionSpec":
    """Validate a parsed scenario file (see the module docstring): a composition, or a
    template's settings."""
    if "template" not in document:
        try:
            return CompositionSpec(compose(document), source)
        except CompositionError as error:
            raise located(source, text, error.location, error.reason) if error.location else FileError(f"{source}: {error.reason}") from None
    unknown = [key for key in document if key not in TOP_KEYS]
    if unknown:
        raise located(source, text, (unknown[0],), f"unknown key (a scenario file has {', '.join(TOP_KEYS)})")
    known = templates()
    name = document.get("template")
    if name is None:
        raise FileError(f"{source}: template: missing key (one of {', '.join(known)})")
    if name not in known:
        raise located(source, text, ("template",), f"unknown template {name!r} (one of {', '.join(known)})")
    template = known[name]
    case = document.get("case", template.cases[0])
    if case not in template.cases:
        raise located(source, text, ("case",), f"{template.name} has no case {case!r} (one of {', '.join(template.cases)})")
    settings = document.get("settings", {})
    if not isinstance(settings, dict):
        raise FileError(f"{source}: settings: must be a table; got {type(settings).__name__}")
    return ScenarioSpec(template, case, _validate(template.settings, settings, source, text, ("settings",)), source)


def read_spec(path: str | Path, *, runs: int | None = None, seed: int | None = None) -> tuple[ScenarioSpec, str]:
    """:func:`load`, and the file's text (for :func:`build_located`)."""
    document, text = read(path)
    return _load_document(document, text, path, runs, seed), text


def load(path: str | Path, *, runs: int | None = None, seed: int | None = None) -> ScenarioSpec:
    """Read and validate the scenario file at ``path``; ``runs`` and ``seed`` override its own."""
    return read_spec(path, runs=runs, seed=seed)[0]


def _load_document(document: dict, text: str, path, runs: int | None, seed: int | None) -> ScenarioSpec:
    if "template" not in document:
        simulation = document.get("simulation", {})
        if isinstance(simulation, dict):
            given = {"runs": runs, "seed": seed}
            document = {**document, "simulation": {**simulation, **{k: v for k, v in given.items() if v is not None}}}
        return from_document(document, str(path), text)
    settings = dict(document.get("settings", {})) if isinstance(document.get("settings", {}), dict) else document.get("settings")
    if isinstance(settings, dict):
        if runs is not None:
            settings["runs"] = runs
        if seed is not None:
            settings["seed"] = seed
        document = {**document, "settings": settings}
    return from_document(document, str(path), text)


def _comments(model: type[BaseModel], prefix: str = "settings.") -> dict[str, str]:
    comments = {}
    for name, info in model.model_fields.items():
        if info.description:
            comments[f"{prefix}{name}"] = info.description
        annotation = info.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            comments.update(_comments(annotation, f"{prefix}{name}."))
    return comments


def save(spec: ScenarioSpec, path: str | Path, *, header: str | None = None) -> Path:
    """Write ``spec`` as a scenario file with every setting and its description."""
    if isinstance(spec, CompositionSpec):
        header = header or f"lookout scenario: {spec.title}.\nRun it with: lookout run {Path(path).name} --out DIR"
        return write(path, spec.document(), composition_comments(spec.document()), header)
    header = header or (
        f"lookout scenario: {spec.template.title}, case {spec.case!r}.\n"
        f"Run it with: lookout run {Path(path).name} --out DIR"
    )
    comments = {"settings": "Every setting of the template; a key left out takes its default.", **_comments(spec.template.settings)}
    comments["case"] = f"one of {', '.join(spec.template.cases)}"
    return write(path, spec.document(), comments, header)


def simulate_trajectory(spec: ScenarioSpec, *, progress=None, scenario=None):
    """Simulate the scenario for its seeds: a :class:`~lookout.Trajectory` (batched
    when there are several runs).

    One run is :func:`~lookout.sim.simulate`, several a vmapped
    :func:`~lookout.sim.simulate_batch`, batched as the template's reproduction
    batches them (:attr:`Template.stacked`): run i uses ``jax.random.key(seed + i)``.
    """
    from lookout.sim import keys_of_seeds, simulate, simulate_batch, stack_scenarios

    scenario = spec.build() if scenario is None else scenario
    seeds = spec.seeds
    if len(seeds) == 1:
        return simulate(scenario, keys_of_seeds(seeds)[0], progress=progress)
    if spec.stacked:
        return simulate_batch(stack_scenarios([scenario] * len(seeds)), keys_of_seeds(seeds), batched_scenario=True, progress=progress)
    return simulate_batch(scenario, keys_of_seeds(seeds), progress=progress)


def to_dataset(spec: ScenarioSpec, trajectory):
    """The trajectory as an :class:`xarray.Dataset` with ``seed`` along ``run`` and the
    scenario (template, case, settings) in its attributes."""
    ds = trajectory.to_xarray().assign_coords(seed=("run", np.asarray(spec.seeds, dtype=np.int64), {"long_name": "PRNG seed of the run"}))
    if isinstance(spec, CompositionSpec):
        ds.attrs.update({"composition": json.dumps(spec.document())})
    else:
        ds.attrs.update({"template": spec.template.name, "case": spec.case, "settings": spec.settings.model_dump_json()})
    return ds


def simulate_spec(spec: ScenarioSpec, *, progress=None, scenario=None):
    """:func:`simulate_trajectory` as :func:`to_dataset`."""
    return to_dataset(spec, simulate_trajectory(spec, progress=progress, scenario=scenario))
