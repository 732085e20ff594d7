"""Campaign specs: a base scenario, sweep axes, seeds per point, metrics; and their chunks.

A campaign spec is a TOML file::

    scenario = "dp-observer.toml"     # a scenario file, relative to this file
    seeds_per_point = 32              # runs at every sweep point: seeds seed .. seed + 31
    seed = 0                          # the same seeds at every point (common random numbers)
    chunk_runs = 16                   # runs per chunk: one vmapped batch, one dask task
    metrics = ["rms_error:position", "max_excursion:position", "rms_input:force"]
    after = 1500.0                    # metrics over t >= after (default: half the run)

    [divergence]                      # optional: a run whose error of `signal` exceeds
    signal = "position"               # `limit` at any time counts as diverged (default:
    limit = 50.0                      # the scenario's [simulation] divergence)

    [sweep]
    kind = "grid"                     # or "latin-hypercube" (then `points` and `seed`)

    [[sweep.axes]]                    # a key of the scenario's composition; several keys take
    name = "wave_frequency"           # the same value (the sea and the observer tuned to it)
    field = ["plant.waves.peak_frequency", "observer.wave_frequency"]
    values = [0.6, 0.9, 1.2]

    [[sweep.axes]]
    field = ["plant.bias.std[0]", "plant.bias.std[1]", "plant.bias.std[2]"]
    values = [0.5, 1.0, 2.0]
    scale = true                      # multiply the base values instead of replacing them

    [trajectories]                    # optional: keep these recorded signals, decimated
    signals = ["position", "position_hat"]
    every = 10

A grid axis gives ``values``, or ``range = [low, high]`` with ``steps``; a
Latin-hypercube axis gives ``range``. A grid axis may instead give ``cases``: one
table of key paths per value, each setting several keys at once (a gain set, a
model error of one kind at a time), named by ``labels``::

    [[sweep.axes]]
    name = "model_error"
    labels = ["none", "mass +25 %", "damping +25 %"]
    cases = [{}, {"plant.vessel.mass_scale" = 1.25}, {"plant.vessel.damping_scale" = 1.25}]
 An axis whose field is a whole table
(``field = "observer"``) and whose values are tables replaces that component at each
point (several observers on the same runs). The points of a grid are the Cartesian product
of the axes (the last axis varies fastest); a Latin hypercube draws ``points`` points
with one point in each of ``points`` equal strata of every axis.

The work is split into chunks: one sweep point times one block of ``chunk_runs``
seeds. :func:`compute_chunk` simulates a chunk as one vmapped batch and returns only
its metrics (and decimated trajectories if asked): that is all that leaves a worker.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from lookout.scenario._toml import FileError, read
from lookout.scenario.composition import get_path
from lookout.scenario.file import CompositionSpec, describe, from_document, located, read_spec
from lookout.scenario.settings import positive_count, validate_strictly

if TYPE_CHECKING:
    from lookout.sim import Scenario

#: The largest batch a chunk defaults to.
DEFAULT_CHUNK_RUNS = 64


class Axis(BaseModel):
    """One sweep axis: the settings it sets, and its values or range."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    field: str | tuple[str, ...] | None = Field(
        default=None, description="key path(s) of the scenario's composition (plant.waves.peak_frequency, observer), set to the same value"
    )
    values: tuple[Any, ...] | None = Field(default=None, description="the values (grid)")
    cases: tuple[dict[str, Any], ...] | None = Field(
        default=None, description="instead of field and values: per value, key path -> value of the keys it sets (grid)"
    )
    labels: tuple[str | float, ...] | None = Field(
        default=None, description="the cases' names in the store and report (default: what each case sets)"
    )
    range: tuple[float, float] | None = Field(default=None, description="[low, high]: steps values (grid) or strata (latin-hypercube)")
    steps: int | None = Field(default=None, description="number of evenly spaced values over range (grid)")
    scale: bool = Field(default=False, description="multiply each field's base value by the axis value instead of setting it")
    name: str | None = Field(default=None, description="the axis's name in the store and report (default: from field)")

    @field_validator("values", "cases")
    @classmethod
    def _some_values(cls, value):
        if value is not None and len(value) == 0:
            raise ValueError("must hold at least one value")
        return value

    @model_validator(mode="after")
    def _field_or_cases(self):
        if self.cases is None:
            if self.field is None:
                raise ValueError("an axis needs field (with values, or range and steps), or cases")
            if self.labels is not None:
                raise ValueError("labels name the cases of a cases axis; an axis with field is labelled by its values")
            return self
        others = [name for name in ("field", "values", "range", "steps") if getattr(self, name) is not None] + (["scale"] if self.scale else [])
        if others:
            raise ValueError(f"an axis with cases sets its keys per case: drop {others[0]}")
        if self.name is None:
            raise ValueError("an axis with cases needs a name")
        if self.labels is not None:
            if len(self.labels) != len(self.cases):
                raise ValueError(f"labels must name each of the {len(self.cases)} cases; got {len(self.labels)} label(s)")
            if len(set(self.labels)) != len(self.labels):
                raise ValueError(f"labels repeat: {list(self.labels)}")
        elif len(set(self.case_labels)) != len(self.cases):
            raise ValueError("two cases set the same keys to the same values; drop one")
        return self

    @property
    def case_labels(self) -> tuple:
        """Each case's name: its label, or what it sets (``base`` for an empty case)."""
        if self.labels is not None:
            return self.labels
        assert self.cases is not None, "case labels are a cases axis's"
        return tuple(", ".join(f"{key}={json.dumps(value)}" for key, value in case.items()) or "base" for case in self.cases)

    def case_changes(self, label: str | float) -> dict[str, Any]:
        """Key path -> value of the case named ``label``."""
        assert self.cases is not None, "case changes are a cases axis's"
        return dict(self.cases[self.case_labels.index(label)])

    @field_validator("range")
    @classmethod
    def _ordered(cls, value):
        if value is not None and not (math.isfinite(value[0]) and math.isfinite(value[1]) and value[0] < value[1]):
            raise ValueError(f"must be [low, high] with finite low < high; got {list(value)}")
        return value

    @field_validator("steps")
    @classmethod
    def _two_or_more(cls, value):
        if value is not None and value < 2:
            raise ValueError(f"must be at least 2; got {value}")
        return value

    @property
    def fields(self) -> tuple[str, ...]:
        """The key paths it sets (for cases: every key any case sets, in order)."""
        if self.cases is not None:
            return tuple(dict.fromkeys(key for case in self.cases for key in case))
        assert self.field is not None  # an axis without cases has a field (checked on validation)
        return (self.field,) if isinstance(self.field, str) else tuple(self.field)

    def value_label(self, value: Any) -> Any:
        """A value as the store and the report show it: a replaced component by its kind
        (numbered in the axis's order when two values share one); a case by its label."""
        if self.cases is not None or not isinstance(value, dict):
            return value
        assert self.values is not None  # a component value (a table) is one of the axis's values
        kinds = [v.get("kind", "?") if isinstance(v, dict) else str(v) for v in self.values or ()]
        index = next(i for i, v in enumerate(self.values) if v == value)
        kind = kinds[index]
        return kind if kinds.count(kind) == 1 else f"{kind} {kinds[: index + 1].count(kind)}"

    @property
    def label(self) -> str:
        if self.name:
            return self.name
        first = self.fields[0]
        return first if len(self.fields) == 1 else first.split("[")[0] + ("_scale" if self.scale else "")


#: Names the store uses itself: an axis may not take them.
RESERVED_NAMES = frozenset({"point", "seed", "diverged", "kept_time"})
#: Settings a campaign sets itself (its seeds): no axis may sweep them.
SEED_FIELDS = frozenset({"seed", "runs"})


class Sweep(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: Literal["grid", "latin-hypercube"] = "grid"
    points: int | None = Field(default=None, description="latin-hypercube: number of points")
    seed: int = Field(default=0, description="latin-hypercube: seed of the draw")
    axes: tuple[Axis, ...] = ()

    @model_validator(mode="after")
    def _consistent(self):
        for index, axis in enumerate(self.axes):
            if self.kind == "grid" and axis.cases is None and (axis.values is None) == (axis.range is None or axis.steps is None):
                raise ValueError(f"axes[{index}] of a grid needs values, or range and steps")
            if self.kind == "latin-hypercube" and axis.cases is not None:
                raise ValueError(f"axes[{index}]: cases are for a grid; a latin-hypercube axis needs range")
            if self.kind == "latin-hypercube" and (axis.range is None or axis.values is not None):
                raise ValueError(f"axes[{index}] of a latin-hypercube needs range (and no values)")
        if self.kind == "latin-hypercube" and (self.points is None or self.points < 1):
            raise ValueError("a latin-hypercube needs points >= 1")
        if self.kind == "grid" and self.points is not None:
            raise ValueError("points is for a latin-hypercube; a grid's points are the product of its axes' values")
        for index, axis in enumerate(self.axes):
            swept = sorted(set(axis.fields) & SEED_FIELDS)
            if swept:
                raise ValueError(f"axes[{index}]: a campaign runs seeds_per_point seeds from seed at every point; {swept[0]!r} cannot be swept")
        labels = [axis.label for axis in self.axes]
        if len(set(labels)) != len(labels):
            raise ValueError(f"axis names repeat: {labels}; give each axis a distinct name")
        reserved = sorted({label for label in labels if label in RESERVED_NAMES or "__" in label})
        if reserved:
            raise ValueError(
                f"axis name {reserved[0]!r} is taken by the store (point, seed, diverged, and metric names with '__'); give the axis another name"
            )
        return self


class Divergence(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    signal: str
    limit: float

    @field_validator("limit")
    @classmethod
    def _positive(cls, value):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"must be a finite positive number; got {value:g}")
        return value


class Trajectories(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    signals: tuple[str, ...]
    every: int = Field(default=10, description="keep one record in this many")

    @field_validator("every")
    @classmethod
    def _positive(cls, value):
        return positive_count(value)


class CampaignSettings(BaseModel):
    """The validated top level of a campaign spec (the scenario is resolved apart)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    scenario: str | dict
    seeds_per_point: int = 8
    seed: int = 0
    chunk_runs: int | None = None
    metrics: tuple[str, ...] = ()
    after: float | None = None
    divergence: Divergence | None = None
    sweep: Sweep = Sweep()
    trajectories: Trajectories | None = None

    @field_validator("seeds_per_point")
    @classmethod
    def _positive_count(cls, value):
        return positive_count(value)

    @field_validator("seed")
    @classmethod
    def _seed(cls, value, info):
        from lookout.scenario.settings import seed_for_runs

        return seed_for_runs(value, info.data.get("seeds_per_point", 1))

    @field_validator("chunk_runs")
    @classmethod
    def _divides(cls, value, info):
        seeds = info.data.get("seeds_per_point")
        if value is not None and (value < 1 or (seeds and seeds % value)):
            raise ValueError(f"must be a positive divisor of seeds_per_point ({seeds}) so every chunk is the same batch; got {value}")
        return value

    @field_validator("after")
    @classmethod
    def _after(cls, value):
        if value is not None and not (math.isfinite(value) and value >= 0):
            raise ValueError(f"must be a finite number of seconds >= 0; got {value:g}")
        return value


@dataclass(frozen=True)
class Chunk:
    """One sweep point times one block of seeds: one vmapped batch, one task."""

    index: int
    point: int
    block: int
    seeds: tuple[int, ...]

    @property
    def key(self) -> str:
        return f"chunk-{self.index:06d}"


@dataclass(frozen=True)
class Campaign:
    """A validated campaign: its settings, base scenario, sweep points and metrics."""

    settings: CampaignSettings
    base: CompositionSpec
    points: tuple[dict[str, Any], ...]  # axis label -> value, per point
    metric_names: tuple[str, ...]
    source: str
    #: the most records a run of any swept value has (the base and each axis value
    #: were built to validate them): what sizes a chunk's memory
    records: int = 0

    @property
    def axes(self) -> tuple[Axis, ...]:
        return self.settings.sweep.axes

    @property
    def chunk_runs(self) -> int:
        return chunk_runs_of(self.settings)

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(range(self.settings.seed, self.settings.seed + self.settings.seeds_per_point))

    def divergence_at(self, point: int) -> tuple[str, float] | None:
        """When a run at ``point`` has failed (signal, limit): the spec's
        ``[divergence]``, else its scenario's (``[simulation] divergence``, else the plant
        kind's: :attr:`lookout.scenario.composition.Composition.divergence`)."""
        if self.settings.divergence is not None:
            return (self.settings.divergence.signal, self.settings.divergence.limit)
        bound = self.point_spec(point).composition.divergence
        return None if bound is None else (bound.signal, bound.limit)

    @property
    def blocks(self) -> int:
        return self.settings.seeds_per_point // self.chunk_runs

    def chunks(self) -> list[Chunk]:
        size = self.chunk_runs
        return [
            Chunk(point * self.blocks + block, point, block, self.seeds[block * size : (block + 1) * size])
            for point in range(len(self.points))
            for block in range(self.blocks)
        ]

    def document(self) -> dict:
        """The campaign as one self-contained document: the scenario inlined."""
        settings = self.settings.model_dump(mode="json", exclude_none=True)
        settings["scenario"] = self.base.document()
        settings["metrics"] = list(self.metric_names)
        return settings

    def canonical(self) -> str:
        return canonical_json(self.document())

    def fingerprint(self) -> str:
        return fingerprint_of(self.document())

    def point_spec(self, point: int) -> CompositionSpec:
        """The scenario of sweep point ``point``."""
        return _point_spec(self.canonical(), point)

    def changes(self, point: int) -> dict[str, Any]:
        """Key path -> value at ``point``."""
        base = self.base.values()
        result = {}
        for axis in self.axes:
            result.update(_axis_changes(axis, base, self.points[point][axis.label]))
        return result


def canonical_json(document: dict) -> str:
    """The campaign document as the one JSON text that resume compares and workers receive."""
    return json.dumps(document, sort_keys=True, separators=(",", ":"))


def fingerprint_of(document: dict) -> str:
    """A short hash of :func:`canonical_json`, shown by the store and its report."""
    return hashlib.sha256(canonical_json(document).encode()).hexdigest()[:16]


@functools.lru_cache(maxsize=8)
def _campaign(canonical: str) -> Campaign:
    return campaign_from_document(json.loads(canonical), "<campaign>")


def _with_changes(base: CompositionSpec, changes: dict[str, Any], source: str) -> CompositionSpec:
    """``base`` with the keys at ``changes``' paths set (a path may name a whole table)."""
    return base.with_settings(dict(changes), source=source)


@functools.lru_cache(maxsize=256)
def _point_spec(canonical: str, point: int) -> CompositionSpec:
    campaign = _campaign(canonical)
    return _with_changes(campaign.base, campaign.changes(point), f"{campaign.source} (point {point})")


@functools.lru_cache(maxsize=64)
def _point_scenario(canonical: str, point: int):
    """The built scenario of a point, once per process (building checks the components'
    fit with ``jax.eval_shape``, which costs more than simulating a short chunk)."""
    return _point_spec(canonical, point).build()


def _axis_changes(axis: Axis, base: dict, value) -> dict[str, Any]:
    """Key path -> value that ``axis`` sets at its value ``value`` (a case's label, for cases)."""
    if axis.cases is not None:
        return axis.case_changes(value)
    return {path: (get_path(base, path) * value if axis.scale else value) for path in axis.fields}


def _axis_range(axis: Axis) -> list[float]:
    """``[low, high]`` of an axis that has a range (a latin-hypercube's, or a grid's without values)."""
    assert axis.range is not None  # Sweep checks that every such axis has one
    return list(axis.range)


def _grid_values(axis: Axis) -> list:
    if axis.cases is not None:
        return list(axis.case_labels)
    if axis.values is not None:
        return list(axis.values)
    assert axis.range is not None and axis.steps is not None  # Sweep: a grid axis has values, or range and steps
    return np.linspace(axis.range[0], axis.range[1], axis.steps).tolist()


def _latin_hypercube(axes: tuple[Axis, ...], points: int, seed: int) -> list[dict]:
    """One point in each of ``points`` equal strata of every axis, strata paired at random."""
    rng = np.random.default_rng(seed)
    columns = []
    for axis in axes:
        unit = (rng.permutation(points) + rng.random(points)) / points
        low, high = _axis_range(axis)
        columns.append(low + unit * (high - low))
    return [{axis.label: float(column[i]) for axis, column in zip(axes, columns)} for i in range(points)]


def campaign_from_document(document: dict, source: str, text: str | None = None, folder: Path | None = None) -> Campaign:
    """Validate a parsed campaign spec: its keys, its scenario, that every swept field
    exists and takes the axis's values, and that every metric applies."""
    from lookout.scenario import metrics as metric_module

    if "scenario" not in document and ({"preset", "plant", "observer"} & set(document)):
        name = Path(source).name
        raise FileError(
            f"{source}: a scenario file, not a campaign spec: run it with lookout run {source}, or sweep it from a spec "
            f'that names it (scenario = "{name}", with [sweep] axes; docs/studies.md)'
        )
    try:
        settings = validate_strictly(CampaignSettings, document)
    except ValidationError as error:
        raise FileError(describe(error, source, text)) from None
    scenario = settings.scenario
    if isinstance(scenario, str):
        scenario_path = Path(scenario)
        if not scenario_path.is_absolute() and folder is not None:
            scenario_path = folder / scenario_path
        base = read_spec(scenario_path)[0]
    else:
        base = from_document(scenario, f"{source} [scenario]", None)
    axes = settings.sweep.axes
    scenario_object = base.build()
    # sizes first: nothing that grows with the points or seeds exists before this check
    try:
        check_driver_memory(settings, scenario_object)
    except ValueError as error:
        key = ("sweep",) if point_count(settings) > settings.seeds_per_point else ("seeds_per_point",)
        raise located(source, text, key, str(error)) from None
    _check_window(settings, scenario_object, source, text, ("after",), None)
    if settings.sweep.kind == "grid":
        grids = [_grid_values(axis) for axis in axes]
        points = tuple({axis.label: value for axis, value in zip(axes, combo)} for combo in itertools.product(*grids)) if axes else ({},)
    else:
        assert settings.sweep.points is not None  # Sweep: a latin-hypercube has points
        points = tuple(_latin_hypercube(axes, settings.sweep.points, settings.sweep.seed))
    base_values = base.values()
    variants = [scenario_object]  # the base and every swept component: each metric must apply to each
    records = [scenario_object.n_records]
    for index, axis in enumerate(axes):
        location = ("sweep", "axes", index, "cases" if axis.cases is not None else "field")
        for path in axis.fields:
            try:
                current = get_path(base_values, path) if _exists(base_values, path) else None
                # a whole table may be given where the base takes a part from elsewhere (an
                # observer's own vessel model): its building checks its keys
                table = axis.cases is not None and all(isinstance(case.get(path, {}), dict) for case in axis.cases)
                if not _exists(base_values, path) and not (table and _exists(base_values, path.rpartition(".")[0])):
                    raise FileError(f"the scenario has no setting {path!r}")
                if axis.scale and not isinstance(current, (int, float)):
                    raise FileError(f"scale = true needs a number at {path!r}; it holds {current!r}")
            except FileError as error:
                raise located(source, text, location, str(error)) from None
        # every value of the axis must make a valid scenario (checked on the base)
        for value in _grid_values(axis) if settings.sweep.kind == "grid" else _axis_range(axis):
            changes = _axis_changes(axis, base_values, value)
            where = ("sweep", "axes", index, "cases" if axis.cases is not None else "values" if axis.values is not None else "range")
            word = "case" if axis.cases is not None else "value"
            try:
                changed = _with_changes(base, changes, source)
            except FileError as error:
                detail = str(error).split(": ", 1)[-1]
                raise located(source, text, where, f"{word} {value!r}: {detail}") from None
            try:
                built = changed.build()
            except ValueError as error:
                raise located(source, text, where, f"{word} {value!r} makes no scenario: {error}") from None
            if any(isinstance(v, dict) for v in changes.values()):  # a whole component replaced
                variants.append(built)
            records.append(built.n_records)
            _check_window(settings, built, source, text, where, value)
    names = settings.metrics or ()
    if not names:
        raise located(source, text, ("metrics",), "name at least one metric (KIND:SIGNAL, see lookout.scenario.metrics)")
    try:
        for built in variants:  # every metric applies to every swept component
            metric_module.resolve(list(names), built)
        if settings.divergence is not None:
            signal = settings.divergence.signal
            if signal not in {s.name for s in scenario_object.record_signals.truth}:
                raise ValueError(f"the plant has no variable {signal!r}")
    except ValueError as error:
        raise located(
            source, text, ("metrics",) if settings.divergence is None or "variable" not in str(error) else ("divergence", "signal"), str(error)
        ) from None
    if settings.trajectories is not None:
        recorded = {name for _, name, _ in scenario_object.record_signals.variables()}
        for signal in settings.trajectories.signals:
            if signal not in recorded:
                raise located(source, text, ("trajectories", "signals"), f"no recorded signal {signal!r} (recorded: {', '.join(sorted(recorded))})")
    return Campaign(settings, base, points, tuple(names), source, records=max(records))


def _check_window(settings: CampaignSettings, scenario, source: str, text: str | None, where: tuple, value) -> None:
    """Refuse ``after`` past the last record of ``scenario`` (a point's horizon)."""
    after = settings.after
    if after is None:
        return
    last = float(scenario.record_times[-1])
    if after > last + 1e-9 * max(1.0, abs(after)):
        if value is None:
            raise located(source, text, ("after",), f"{after:g} s is past the end of the run ({last:g} s): the metrics would have no record")
        raise located(
            source, text, where, f"value {value!r}: after ({after:g} s) is past the end of that run ({last:g} s): the metrics would have no record"
        )


#: What the driver holds per run (the seed as a Python int in the seed tuples, its
#: slot in the chunks' tuples and the store's seed coordinate, and one float per
#: metric, divergence flag and kept value when the store is read back), per chunk (the
#: chunk, its key, its task and its completion record) and per sweep point.
DRIVER_BYTES_PER_RUN = 56
DRIVER_BYTES_PER_CHUNK = 2000
DRIVER_BYTES_PER_POINT = 500


def point_count(settings: CampaignSettings) -> int:
    """The number of sweep points, from the axes alone (without making them)."""
    if settings.sweep.kind == "latin-hypercube":
        assert settings.sweep.points is not None  # Sweep: a latin-hypercube has points
        return int(settings.sweep.points)
    return math.prod(len(_grid_values(axis)) if axis.steps is None else int(axis.steps) for axis in settings.sweep.axes)


def kept_values(settings: CampaignSettings, scenario: Scenario) -> int:
    """Numbers a run keeps in the store: one per metric and the divergence flag, and
    its kept trajectories."""
    values = len(settings.metrics) + 1
    kept = settings.trajectories
    if kept is not None:
        sizes = {name: signal.size for _, name, signal in scenario.record_signals.variables()}
        values += -(-scenario.n_records // kept.every) * sum(sizes.get(name, 1) for name in kept.signals)
    return values


def chunk_runs_of(settings: CampaignSettings) -> int:
    """Runs per chunk: ``chunk_runs``, or the largest divisor of ``seeds_per_point`` up
    to :data:`DEFAULT_CHUNK_RUNS`."""
    if settings.chunk_runs is not None:
        return settings.chunk_runs
    seeds = settings.seeds_per_point
    if seeds <= DEFAULT_CHUNK_RUNS:
        return seeds
    return max(d for d in range(1, DEFAULT_CHUNK_RUNS + 1) if seeds % d == 0)


def driver_memory(settings: CampaignSettings, scenario: Scenario) -> tuple[float, int, int]:
    """(bytes, points, chunks) the driver holds for the campaign: see
    :data:`DRIVER_BYTES_PER_RUN` and the two after it."""
    points = point_count(settings)
    runs = points * settings.seeds_per_point
    chunks = points * (settings.seeds_per_point // chunk_runs_of(settings))
    need = runs * (DRIVER_BYTES_PER_RUN + 8 * kept_values(settings, scenario)) + chunks * DRIVER_BYTES_PER_CHUNK + points * DRIVER_BYTES_PER_POINT
    return need, points, chunks


def check_driver_memory(settings: CampaignSettings, scenario: Scenario, available: float | None = None) -> None:
    """Refuse (ValueError) a campaign whose points, seeds and chunks would not fit in
    this process's memory, before any of them is made."""
    from lookout._resources import refuse_unless_it_fits

    need, points, chunks = driver_memory(settings, scenario)
    refuse_unless_it_fits(
        need,
        f"{points} point(s) x {settings.seeds_per_point} seeds in {chunks} chunks",
        "use fewer seeds_per_point or fewer sweep points (or split the study into several campaigns)",
        available=available,
    )


def _exists(values: dict, path: str) -> bool:
    try:
        get_path(values, path)
        return True
    except (KeyError, IndexError, TypeError, ValueError):
        return False


def load_campaign(path: str | Path) -> Campaign:
    """Read and validate the campaign spec at ``path``."""
    document, text = read(path)
    return campaign_from_document(document, str(path), text, Path(path).parent)


# ----------------------------------------------------------------------------------
# computing one chunk (runs on a worker)


#: (campaign, scenario structure, batch size) of the chunks this process has computed:
#: a later one with the same key runs compiled (points that differ in numbers only,
#: share one program).
_COMPUTED: set[tuple] = set()


def compute_chunk(canonical: str, point: int, seeds: tuple[int, ...]) -> dict[str, np.ndarray]:
    """Simulate one chunk as a vmapped batch and reduce it to its metrics: in the
    engine's scan (:func:`lookout.scenario.metrics.summarize`), or from the recorded
    batch when trajectories are kept.

    Returns metric variable -> ``(runs,)`` array, ``diverged``, and ``trajectory__NAME``
    -> ``(runs, kept records, ...)`` for the kept signals; plus ``seconds`` (wall time)
    and ``compiled`` (1.0 when this process had computed a chunk of the campaign before,
    so the time is a compiled chunk's, 0.0 when it includes compilation).
    Built scenarios are cached per process, so a worker compiles once per shape.
    """
    import time

    from lookout.scenario import metrics as metric_module
    from lookout.sim import keys_of_seeds, simulate_batch
    from lookout.sim.scenario import structure_key

    start = time.perf_counter()
    campaign = _campaign(canonical)
    scenario = _point_scenario(canonical, point)
    shape = (canonical, structure_key(scenario), len(seeds))
    compiled = shape in _COMPUTED
    keys = keys_of_seeds(list(seeds))
    metrics = metric_module.resolve(list(campaign.metric_names), scenario)
    options: dict[str, Any] = {
        "after": campaign.settings.after,
        "divergence": campaign.divergence_at(point),
        "outage": metric_module.outage_of(scenario),
    }
    kept = campaign.settings.trajectories
    if kept is None:  # the metrics accumulate as the runs go; no records are held
        out = metric_module.summarize(scenario, keys, metrics, **options)
    else:
        trajectory = simulate_batch(scenario, keys)
        out = metric_module.reduce(trajectory, metrics, **options)
        recorded = {**trajectory.truth, **{f"{k}_hat": v for k, v in trajectory.estimate.items()}}
        ds = None
        for name in kept.signals:
            if name in recorded:
                out[f"trajectory__{name}"] = np.asarray(recorded[name])[:, :: kept.every]
            else:  # measurements, references, inputs: through the labelled view
                ds = trajectory.to_xarray() if ds is None else ds
                out[f"trajectory__{name}"] = np.asarray(ds[name].values[:, :: kept.every])
    _COMPUTED.add(shape)
    out["seconds"] = np.asarray(time.perf_counter() - start)
    out["compiled"] = np.asarray(float(compiled))
    return out
