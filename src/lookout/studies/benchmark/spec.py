"""A benchmark spec: its settings (validated), the shipped specs, and the composition of
its base scenario with an observer.

A spec file is read into a :class:`Benchmark` by :func:`spec_benchmark` (a scenario
file is made one by :mod:`lookout.studies.benchmark.from_scenario`; either is loaded by
:func:`lookout.studies.benchmark.load.load_benchmark`). What the spec would accept and
ignore is refused by :func:`check_spec`, one line at the key.
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from lookout.scenario._toml import FileError, read
from lookout.scenario.composition import TOP_KEYS, CompositionError, load_plugins, merge, preset_document
from lookout.scenario.file import CAMPAIGN_ONLY, SPEC_ONLY, describe, located  # the keys only a campaign spec, or a benchmark spec, has
from lookout.scenario.settings import PositiveCount, PositiveFloat, validate_strictly
from lookout.studies.campaign import Divergence

#: The folder of the shipped benchmark specs (``<plant>.toml``).
SHIPPED = "benchmarks"
#: The sizes a spec defines.
SIZES = ("full", "quick")
#: Settings of ``[simulation]`` the benchmark sets itself (from the size and the spec).
BENCHMARK_SIMULATION = {
    "duration": "full.duration and quick.duration",
    "seed": "the spec's seed",
    "runs": "full.seeds and quick.seeds",
    "record_every": "the benchmark records every sample",
    "observer_mode": "the benchmark samples every observer",
}
#: Settings of the sensor the benchmark sets itself (the outage of an outage condition).
BENCHMARK_SENSOR = ("outage_signals", "outage_start", "outage_duration")


class Condition(BaseModel):
    """One condition: a name and what it changes from the base."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(description="the condition's name in the tables and figures")
    changes: dict[str, Any] = Field(default_factory=dict, description="key path -> value, for the whole composition (the observers are told)")
    truth_only: dict[str, Any] = Field(default_factory=dict, description="key path -> value, for the plant alone (a model error)")

    @field_validator("name")
    @classmethod
    def _named(cls, value):
        if not value.strip():
            raise ValueError("must not be empty")
        return value

    @field_validator("changes")
    @classmethod
    def _not_the_benchmarks(cls, value):
        for path in value:
            key = path.removeprefix("simulation.")
            if path.startswith("simulation.") and key in BENCHMARK_SIMULATION:
                raise ValueError(f"{path!r}: the benchmark sets it ({BENCHMARK_SIMULATION[key]}); a condition cannot change it")
        return value

    @field_validator("truth_only")
    @classmethod
    def _plant_only(cls, value):
        for path in value:
            if not path.startswith("plant."):
                raise ValueError(f"{path!r}: a model error changes the plant (keys plant.*); put other changes under changes")
        return value

    @property
    def replaces_a_table(self) -> bool:
        """Whether it gives a whole component table (a controller and its reference:
        a closed loop), which some observers may not fit."""
        return any(isinstance(value, dict) for value in self.changes.values())


class Size(BaseModel):
    """How long and how many: the ``full`` or the ``quick`` benchmark."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    duration: PositiveFloat = Field(description="simulated time of each run (s)")
    seeds: PositiveCount = Field(description="runs per observer and condition (seeds seed .. seed + seeds - 1)")
    after: float | None = Field(default=None, description="the metrics over t >= after (s); default half the run")
    outage_start: float | None = Field(default=None, description="when an outage condition's outage begins (s)")


class BenchmarkSpec(BaseModel):
    """A validated benchmark spec (the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    title: str
    plugins: tuple[str, ...] = Field(default=(), description="Python files (relative to the spec) or modules that register kinds of their own")
    scenario: str | dict = Field(description="a scenario file (relative to the spec) or an inline composition (may hold a preset)")
    seed: int = 0
    metrics: tuple[str, ...]
    recommend_by: tuple[str, ...] = Field(
        default=(), description="the metrics that lead the recommendation, in order (default: benchmark_report.lead_metrics)"
    )
    divergence: Divergence | None = None
    outage_signals: tuple[str, ...] = Field(default=(), description="the measured signals an outage condition silences")
    full: Size
    quick: Size
    observers: dict[str, dict] = Field(description="name -> an [observer] table")
    conditions: tuple[Condition, ...]

    @field_validator("title")
    @classmethod
    def _titled(cls, value):
        if not value.strip():
            raise ValueError("must not be empty")
        return value

    @field_validator("observers")
    @classmethod
    def _some_observers(cls, value):
        if not value:
            raise ValueError("name at least one observer")
        for name, table in value.items():
            if not isinstance(table, dict) or "kind" not in table:
                raise ValueError(f"{name}: must be an [observer] table with a kind")
            if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_+-]*", name):
                raise ValueError(f"{name!r}: an observer's name names its store (NAME.zarr): letters, digits, -, _ and + only")
        return value

    @field_validator("conditions")
    @classmethod
    def _distinct(cls, value):
        names = [c.name for c in value]
        if not names:
            raise ValueError("name at least one condition (the base: a condition that changes nothing)")
        if len(set(names)) != len(names):
            raise ValueError(f"condition names repeat: {names}")
        return value


# ------------------------------------------------------------------ loading


def shipped_plants() -> list[str]:
    """The plants of the shipped benchmark specs."""
    folder = resources.files("lookout.studies") / SHIPPED
    return sorted(entry.name[: -len(".toml")] for entry in folder.iterdir() if entry.name.endswith(".toml"))


def shipped_spec(plant: str) -> Path:
    """The path of the shipped spec of ``plant`` (a ValueError lists them)."""
    plants = shipped_plants()
    if plant not in plants:
        raise ValueError(f"--plant: no benchmark for {plant!r} (one of {', '.join(plants)}; or give your own with --spec)")
    return Path(str(resources.files("lookout.studies") / SHIPPED / f"{plant}.toml"))


@dataclass(frozen=True)
class Benchmark:
    """A loaded spec: its settings, where it came from, and its base scenario.

    ``notes`` are what loading it decided that the user should read (a scenario file's
    observers that do not fit, its keys the benchmark does not use), one line each;
    ``lenient``: a condition an observer does not fit skips that observer there (a
    benchmark made from a scenario file) instead of refusing the spec.
    """

    spec: BenchmarkSpec
    name: str
    source: str
    text: str | None
    base: dict  # the scenario, a preset expanded, without its observer
    notes: tuple[str, ...] = ()
    lenient: bool = False

    def located(self, location: tuple, message: str) -> FileError:
        return located(self.source, self.text, location, message)


def file_form(document: dict) -> str:
    """What a file given to ``--spec`` is: ``"spec"`` (a benchmark spec), ``"scenario"``
    (a scenario file) or ``"campaign"`` (a campaign spec); a FileError-worthy
    ValueError when it mixes a spec's keys with a scenario's tables, or is neither."""
    keys = set(document)
    spec, scenario, campaign = keys & SPEC_ONLY, keys & (set(TOP_KEYS) - {"plugins"}), keys & CAMPAIGN_ONLY
    if spec and scenario:
        raise ValueError(
            f"mixes a benchmark spec's keys ({', '.join(sorted(spec))}) with a scenario's tables ({', '.join(sorted(scenario))}): "
            "put the scenario under [scenario], or give the scenario file alone"
        )
    if scenario:
        return "scenario"
    if campaign and not spec:
        return "campaign"
    if spec or "scenario" in keys:
        return "spec"
    raise ValueError(
        "is neither a benchmark spec (title, scenario, observers, conditions, full, quick, metrics) "
        "nor a scenario file ([plant], [sensor], [observer], ...)"
    )


def spec_benchmark(path: Path, document: dict, text: str | None) -> Benchmark:
    """The benchmark of the benchmark spec ``document``, read from ``path`` (its
    ``text``): validated, its plugins loaded, its scenario read (a file, relative to
    the spec) or taken inline, a preset expanded (one-line FileError on bad input)."""
    try:
        spec = validate_strictly(BenchmarkSpec, document)
    except ValidationError as error:
        raise FileError(describe(error, str(path), text)) from None
    source = str(path)
    try:
        load_plugins(list(spec.plugins))
    except CompositionError as error:
        raise located(source, text, error.location, error.reason) from None
    scenario = spec.scenario
    notes: list[str] = []
    if isinstance(scenario, str):
        scenario_path = Path(scenario) if Path(scenario).is_absolute() else path.parent / scenario
        try:
            scenario, _ = read(scenario_path)
        except FileError as error:
            raise located(source, text, ("scenario",), str(error)) from None
        notes += _unused_scenario_keys(scenario, str(scenario_path))
    else:
        _refuse_overridden_keys(scenario, source, text)
    try:
        base = merge(preset_document(scenario["preset"]), scenario) if "preset" in scenario else copy.deepcopy(scenario)
    except CompositionError as error:
        raise located(source, text, ("scenario",) + error.location, error.reason) from None
    base.pop("observer", None)
    if spec.plugins:
        base["plugins"] = list(dict.fromkeys([*spec.plugins, *base.get("plugins", [])]))
    benchmark = Benchmark(spec, path.stem, source, text, base, tuple(notes))
    check_spec(benchmark)
    return benchmark


def shipped_benchmark(plant: str) -> Benchmark:
    """The shipped benchmark of ``plant``, loaded (a ValueError lists the plants)."""
    path = shipped_spec(plant)
    document, text = read(path)
    return spec_benchmark(path, document, text)


def _overridden_keys(scenario: dict) -> list[tuple[tuple, str]]:
    """(location, what sets it) of each key of a scenario that the benchmark replaces."""
    found: list[tuple[tuple, str]] = []
    simulation = scenario.get("simulation")
    if isinstance(simulation, dict):
        found += [(("simulation", key), BENCHMARK_SIMULATION[key]) for key in simulation if key in BENCHMARK_SIMULATION]
    sensor = scenario.get("sensor")
    if isinstance(sensor, dict):
        found += [(("sensor", key), "outage_signals, full.outage_start and the conditions") for key in sensor if key in BENCHMARK_SENSOR]
    if "observer" in scenario:
        found.append((("observer",), "the [observers.NAME] tables"))
    return found


def _refuse_overridden_keys(scenario: dict, source: str, text: str | None) -> None:
    """An inline scenario may not set what the benchmark sets: it would be ignored."""
    for location, setter in _overridden_keys(scenario):
        raise located(source, text, ("scenario",) + location, f"the benchmark sets it ({setter}); drop it here")


def _unused_scenario_keys(scenario: dict, source: str) -> list[str]:
    """A referenced scenario file's keys that the benchmark replaces, in one line."""
    found = [f"{'.'.join(location)} ({setter})" for location, setter in _overridden_keys(scenario)]
    return [f"{source}: not used here: {'; '.join(found)}"] if found else []


def check_spec(benchmark: Benchmark) -> None:
    """Refuse (one line, at the key) what a spec would accept and ignore: a size's
    ``after`` or ``outage_start`` outside its run, an outage start without an outage, an
    outage that no condition has, ``recommend_by`` outside the metrics. The outages'
    timing against the sensor is checked per observer (:func:`check_outages`)."""
    from lookout.scenario.settings import seed_for_runs

    spec = benchmark.spec
    try:
        seed_for_runs(spec.seed, max(spec.full.seeds, spec.quick.seeds))
    except ValueError as error:
        raise benchmark.located(("seed",), str(error)) from None
    for size_name in SIZES:
        size = getattr(spec, size_name)
        if size.after is not None and not (math.isfinite(size.after) and 0.0 <= size.after < size.duration):
            raise benchmark.located(
                (size_name, "after"), f"must be in [0, duration = {size.duration:g} s): the metrics need records after it; got {size.after:g}"
            )
        if size.outage_start is None:
            if spec.outage_signals:
                raise benchmark.located((size_name, "outage_start"), "give it (outage_signals names an outage)")
            continue
        if not spec.outage_signals:
            raise benchmark.located(
                (size_name, "outage_start"), "no outage starts: outage_signals names none (name the signals an outage silences, or drop outage_start)"
            )
        if not (math.isfinite(size.outage_start) and 0.0 <= size.outage_start < size.duration):
            raise benchmark.located((size_name, "outage_start"), f"must be in [0, duration = {size.duration:g} s); got {size.outage_start:g}")
    for index, condition in enumerate(spec.conditions):
        if "sensor.outage_start" in condition.changes and _number(condition.changes.get("sensor.outage_duration", 0.0)) <= 0:
            raise benchmark.located(
                ("conditions", index), f'{condition.name}: sets sensor.outage_start, but the condition has no outage ("sensor.outage_duration" > 0)'
            )
    outages = [c for c in spec.conditions if _number(c.changes.get("sensor.outage_duration", 0.0)) > 0]
    if spec.outage_signals and not outages:
        raise benchmark.located(
            ("outage_signals",),
            'no condition has an outage (changes with "sensor.outage_duration" > 0): '
            "the outage would measure nothing; add one, or drop outage_signals and outage_start",
        )
    for name in spec.recommend_by:
        if name not in spec.metrics:
            raise benchmark.located(("recommend_by",), f"{name!r} is not one of the metrics ({', '.join(spec.metrics)})")


def _number(value) -> float:
    """A condition's number (NaN if it is not one: the composition refuses it later)."""
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan


# ------------------------------------------------------------------ the base composition


def base_document(benchmark: Benchmark, size: Size, observer: dict, *, open_loop: bool = False) -> dict:
    """The composition of the base condition with ``observer``: the spec's scenario with
    the size's duration, the spec's seed, every sample recorded, the observer sampled on
    the sensor's measurements, and the outage's structure (of 0 s) on the sensor.
    ``open_loop``: without the scenario's controller and reference (a probe of whether
    the observer fits the plant and the sensor)."""
    document = copy.deepcopy(benchmark.base)
    simulation = document.setdefault("simulation", {})
    simulation.update(duration=size.duration, seed=benchmark.spec.seed, runs=1, record_every=1, observer_mode="sampled")
    if benchmark.spec.outage_signals:
        document.setdefault("sensor", {}).update(
            outage_signals=list(benchmark.spec.outage_signals), outage_start=size.outage_start, outage_duration=0.0
        )
    document["observer"] = copy.deepcopy(observer)
    if open_loop:
        document["controller"], document["reference"] = {"kind": "none"}, {"kind": "none"}
    return document
