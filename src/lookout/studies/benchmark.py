"""The observer benchmark: every observer that fits a plant, on identical scenarios.

Which observer, for my vessel and my sea, at what cost? A **benchmark spec** (TOML; the
shipped ones are in ``lookout/studies/benchmarks/``, one per plant) names

- a base scenario (a composition, or a reproduction's case as a preset), run open loop
  with its own input, so that what the sensor measures does not depend on the observer;
- the observers to compare, each an ``[observer]`` table of the composition (a kind, its
  design rule and gains; the models it leaves out are the plant's);
- the conditions, each one change from the base: ``changes`` reach the whole
  composition (a calmer sea, lost fixes, an outage: the observers that take the sea
  from the plant are told; a whole table, such as ``controller = { kind = "pid" }`` with
  a ``reference`` table, closes the loop), ``truth_only`` reaches the plant alone (a
  model error: the observers keep the nominal model);
- the metrics (those of :mod:`lookout.scenario.metrics`; each observer is measured on
  the signals it estimates, a tracking metric where the condition has a reference), a
  divergence rule, and two sizes, ``full`` and ``quick`` (duration, seeds, when the
  outage starts);
- optionally ``recommend_by``: the metrics that lead the recommendation, in order
  (:mod:`lookout.studies.benchmark_report` states the rule).

A **scenario file** (``[plant]``, ``[sensor]``, ...; what ``lookout run`` takes) is a
benchmark too (:func:`scenario_benchmark`): its plant, sensor and sea, every registered
observer kind that composes on them, its own observer as given, and the conditions of
the shipped benchmark of its plant kind (model errors relative to its own model), or
generic ones.

Each observer's benchmark is one campaign (:mod:`lookout.studies.campaign`): the base
scenario with that observer, and one sweep axis, ``condition``, with a case per
condition. A condition at which other metrics apply (a closed loop, whose tracking error
is measured) is a campaign of its own. Every campaign runs the same seeds at every
condition, so every observer sees the same plant, the same sea and the same
measurements, bit for bit, and the chunks run on dask as any campaign's, into a Zarr
store per campaign that a killed benchmark resumes.

A model error must not reach the observer's model: for a ``truth_only`` condition, the
benchmark gives the observer, explicitly, each model it would otherwise take from the
plant (``observer.vessel`` = the plant's nominal ``vessel`` table, a Kalman filter's
``observer.plant`` = the nominal plant) before it changes the plant (:func:`model_pins`).

Besides the campaigns, each observer's **cost** is measured in the same run: the
observer alone (``observer.update``, ``output``, ``predict``) stepped over the
baseline's recorded measurements and inputs of one run, compiled, as
:func:`lookout.filter` runs it: microseconds per sample, the best of a few repeats.
"""

from __future__ import annotations

import copy
import functools
import json
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from lookout.scenario import registry
from lookout.scenario._toml import FileError, read
from lookout.scenario.composition import (
    MODEL_ROLES,
    TOP_KEYS,
    CompositionError,
    SimulationSettings,
    compose,
    get_path,
    key_text,
    load_plugins,
    merge,
    preset_document,
    set_path,
)
from lookout.scenario.file import CAMPAIGN_ONLY, SPEC_ONLY, describe, located  # the keys only a campaign spec, or a benchmark spec, has
from lookout.scenario.settings import PositiveCount, PositiveFloat, validate_strictly
from lookout.studies.campaign import Campaign, Divergence, campaign_from_document

#: The folder of the shipped benchmark specs (``<plant>.toml``).
SHIPPED = "benchmarks"
#: The sizes a spec defines.
SIZES = ("full", "quick")
#: Repeats of the timed observer-only pass; the best is reported.
COST_REPEATS = 3
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
#: A scenario file's benchmark without a shipped spec of its plant kind: seeds of each size.
GENERIC_SEEDS = {"full": 16, "quick": 4}
#: ... a model error of this fraction up and down, on each mass, damping, inertia or
#: friction the plant's model has.
GENERIC_MODEL_ERROR = 0.25
#: ... the outage starts at this fraction of the run and lasts this fraction of it
#: (the shipped specs: 1500 s of 2400, 60 s; 7 s of 10, 0.5 s).
GENERIC_OUTAGE = (2.0 / 3.0, 1.0 / 24.0)
#: Model parameters a generic model error changes (by name).
MODEL_ERROR_NAMES = re.compile(r"mass|damping|inertia|friction")
#: Controller kinds that never read an estimate (an input, not a loop).
OPEN_LOOP_CONTROLLERS = ("none", "sinusoidal")


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
    after: float | None = Field(None, description="the metrics over t >= after (s); default half the run")
    outage_start: float | None = Field(None, description="when an outage condition's outage begins (s)")


class BenchmarkSpec(BaseModel):
    """A validated benchmark spec (the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    title: str
    plugins: tuple[str, ...] = Field((), description="Python files (relative to the spec) or modules that register kinds of their own")
    scenario: str | dict = Field(description="a scenario file (relative to the spec) or an inline composition (may hold a preset)")
    seed: int = 0
    metrics: tuple[str, ...]
    recommend_by: tuple[str, ...] = Field(
        (), description="the metrics that lead the recommendation, in order (default: benchmark_report.lead_metrics)"
    )
    divergence: Divergence | None = None
    outage_signals: tuple[str, ...] = Field((), description="the measured signals an outage condition silences")
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


def load_benchmark(path: str | Path) -> Benchmark:
    """Read and validate the benchmark spec, or the scenario file, at ``path`` (one-line
    FileError on bad input)."""
    path = Path(path)
    document, text = read(path)
    try:
        form = file_form(document)
    except ValueError as error:
        raise FileError(f"{path}: {error}") from None
    if form == "campaign":
        raise FileError(
            f"{path}: is a campaign spec ({', '.join(sorted(set(document) & CAMPAIGN_ONLY))}): run it with lookout campaign run {path}; "
            "--spec takes a benchmark spec or a scenario file"
        )
    if form == "scenario":
        return scenario_benchmark(path, document, text)
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


def _overridden_keys(scenario: dict) -> list[tuple[tuple, str]]:
    """(location, what sets it) of each key of a scenario that the benchmark replaces."""
    found = []
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


# ------------------------------------------------------------------ a scenario file as a benchmark


@functools.lru_cache(maxsize=1)
def _first_cases() -> dict[str, dict]:
    """Observer kind -> the observer table of the first reproduction case that uses it."""
    found: dict[str, dict] = {}
    for name, case in registry.presets():
        table = registry.preset(name, case).get("observer")
        if isinstance(table, dict) and table.get("kind") not in found:
            found[table["kind"]] = copy.deepcopy(table)
    return found


def required_table(kind: str, given: dict | None) -> dict:
    """The table of observer ``kind`` with only what the kind requires taken from
    ``given`` (a shipped spec's table of that kind, or the kind's first reproduction
    case): its required values, its required parts that are no model (unknown
    parameters and their bounds), and a required model given by its kind alone (a form
    of the plant's own model, such as the Earth-fixed observer's ``ship = { kind =
    "dp-vessel" }``). A model with numbers of its own is another plant's and is left
    out, as are the gains: the kind's design rule and defaults make them for the plant
    at hand."""
    given = given if given is not None else _first_cases().get(kind, {"kind": kind})
    table = {"kind": kind}
    design = given.get("design")
    if design is not None:
        table["design"] = design
    for parameter in registry.kind("observer", kind).parameters(design):
        if not parameter.required or parameter.name not in given:
            continue
        value = given[parameter.name]
        if parameter.sort == "part" and _is_model_role(parameter.role) and not (isinstance(value, dict) and set(value) <= {"kind", "design"}):
            continue
        if parameter.sort in ("value", "part"):
            table[parameter.name] = copy.deepcopy(value)
    return table


def _is_model_role(role: str | None) -> bool:
    """Roles of the models a plant offers (an observer takes them from the plant)."""
    return role in ("vessel", "ship", "model") or role in MODEL_ROLES


def _model_parts(plant_table: dict) -> dict:
    """The model parts (vessel, ship, model) of a spelled-out plant table."""
    kind = registry.kind("plant", plant_table["kind"])
    return {p.name: plant_table[p.name] for p in kind.parameters() if p.sort == "part" and _is_model_role(p.role) and p.name in plant_table}


def _on_grid(value: float, period: float) -> float:
    """``value`` rounded to a whole number (at least one) of ``period``."""
    return max(1, round(value / period)) * period


def _relative_error(shipped: Any, shipped_base: Any, user_base: Any):
    """A shipped model error (``shipped`` where the shipped plant has ``shipped_base``)
    as the same factor on the user's value; None when it is no uniform factor that the
    user's value can take."""
    try:
        value, base, user = (np.asarray(v, dtype=float) for v in (shipped, shipped_base, user_base))
    except (TypeError, ValueError):
        return None
    if value.shape != base.shape:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(base != 0, value / base, np.where(value == 0, 1.0, np.nan))
    if not np.isfinite(factor).all():
        return None
    if np.allclose(factor, factor.flat[0], rtol=1e-9, atol=0.0):
        result = user * float(factor.flat[0])
    elif factor.shape == user.shape:
        result = user * factor
    else:
        return None
    result = np.vectorize(lambda x: float(f"{x:.12g}"))(result)  # 1.2 x 0.75 is 0.9, not 0.8999999999999999
    return result.tolist() if result.ndim else float(result)


def _exists(document: dict, path: str) -> bool:
    try:
        get_path(document, path)
        return True
    except (KeyError, IndexError, TypeError, ValueError):
        return False


def scenario_benchmark(path: Path, document: dict, text: str | None) -> Benchmark:
    """The benchmark of a scenario file (what ``--spec FILE`` makes of one).

    - its plant, sensor and sea, its time grid (plant_step, sample_period, integrator)
      and its actuator; its controller when it is an input (it reads no estimate); a
      controller that closes the loop on the observer's estimate becomes the condition
      ``closed loop (KIND)`` (with its reference), and the other conditions run open loop
      with the shipped benchmark's input of the plant kind (or none);
    - every registered observer kind that composes on them: each with the table the
      shipped benchmark of the plant kind gives it when the plant's model is the shipped
      one, else with only what the kind requires from that table (or from the kind's
      first reproduction case), its design rule and defaults doing the rest; those that
      do not compose are skipped, each in a note with the reason; the file's own
      observer as given (``KIND-as-given``), unless it is one of them exactly;
    - the shipped benchmark's sizes, metrics, divergence rule and conditions, where the
      file's scenario has their keys, model errors as the same factor on the file's own
      model; a plant kind without a shipped benchmark gets generic ones: runs of the
      file's duration (quick: half), a baseline, 10 % and 50 % lost samples, an outage of
      the first measured signal (from 2/3 of the run, for 1/24 of it), and
      ±25 % on each mass, damping, inertia and friction of the plant's model.
    """
    source = str(path)

    def fail(location: tuple, message: str) -> FileError:
        return located(source, text, location, message)

    try:
        merged = merge(preset_document(document["preset"]), document) if "preset" in document else copy.deepcopy(document)
    except CompositionError as error:
        raise fail(error.location, error.reason) from None
    for role in ("plant", "sensor"):
        if not isinstance(merged.get(role), dict):
            raise fail((role,), f"missing table (a scenario needs a plant and a sensor; `lookout components {role}` lists the kinds)")
    own = None
    if "observer" in merged:
        try:
            own = compose(merged)  # the file as `lookout run` takes it
        except CompositionError as error:
            raise fail(error.location, error.reason) from None
    try:
        simulation = validate_strictly(SimulationSettings, merged.get("simulation", {}))
    except ValidationError as error:
        raise FileError(describe(error, source, text, ("simulation",))) from None
    plant_kind = merged["plant"].get("kind")
    shipped = load_benchmark(shipped_spec(plant_kind)) if plant_kind in shipped_plants() else None
    period = simulation.sample_period
    notes: list[str] = []

    base = {key: copy.deepcopy(value) for key, value in merged.items() if key not in ("observer", "preset")}
    base["simulation"] = {key: value for key, value in base.get("simulation", {}).items() if key not in BENCHMARK_SIMULATION}
    base["sensor"] = {key: value for key, value in base["sensor"].items() if key not in BENCHMARK_SENSOR}
    own_controller = copy.deepcopy(merged.get("controller", {"kind": "none"}))
    own_reference = copy.deepcopy(merged.get("reference", {"kind": "none"}))
    if shipped is not None:
        sizes = {name: getattr(shipped.spec, name) for name in SIZES}
        sizes = {
            name: size.model_copy(
                update={
                    "duration": _on_grid(size.duration, period),
                    "outage_start": None if size.outage_start is None else _on_grid(size.outage_start, period),
                }
            )
            for name, size in sizes.items()
        }
    else:
        sizes = {}
        for name, fraction in (("full", 1.0), ("quick", 0.5)):
            duration = _on_grid(simulation.duration * fraction, period)
            sizes[name] = Size(duration=duration, seeds=GENERIC_SEEDS[name], outage_start=_on_grid(duration * GENERIC_OUTAGE[0], period))

    # what base_document needs of a spec, before the spec exists: the probes' benchmark
    probe = Benchmark(BenchmarkSpec.model_construct(seed=simulation.seed, outage_signals=()), path.stem, source, text, base, (), True)

    # ---- the observers: every registered kind that composes on the file's plant and sensor
    # (of plugin files, those the file names)
    same_model = False
    if shipped is not None:
        shipped_first = next(iter(shipped.spec.observers.values()))
        shipped_plant = compose(base_document(shipped, shipped.spec.quick, shipped_first)).document["plant"]
    tables: dict[str, dict] = {}
    registry.load_entry_points()  # every observer kind means installed packages' too (a listing)
    for each in registry.kinds("observer", plugins=base.get("plugins", [])):
        given = next((t for t in shipped.spec.observers.values() if t["kind"] == each.name), None) if shipped is not None else None
        tables[each.name] = required_table(each.name, given)

    def trial(table: dict):
        try:
            return compose(base_document(probe, sizes["quick"], table, open_loop=True))
        except CompositionError as error:
            if error.location[:1] in (("plant",), ("sensor",), ("simulation",), ("actuator",)):
                raise fail(error.location, error.reason) from None
            return error

    first = next((result for result in map(trial, tables.values()) if not isinstance(result, CompositionError)), None)
    if first is None and own is None:
        reasons = "; ".join(f"{kind}: {trial(table)}" for kind, table in list(tables.items())[:2])
        raise fail((), f"no registered observer composes on its plant and sensor ({reasons}; ...)")
    reference_document = (first or own).document
    if shipped is not None:
        same_model = _model_parts(reference_document["plant"]) == _model_parts(shipped_plant)
        if same_model:  # the shipped tables were chosen for this very model: take them whole
            for table in reversed(list(shipped.spec.observers.values())):
                tables[table["kind"]] = copy.deepcopy(table)
    observers: dict[str, dict] = {}
    built: dict[str, Any] = {}
    skipped: list[str] = []
    if own is not None:
        own_table = copy.deepcopy(merged["observer"])
        own_kind = own_table["kind"]
        trial_own = trial(own_table)
        if isinstance(trial_own, CompositionError):
            notes.append(f"your observer ({own_kind}) does not compose open loop here: {trial_own}")
        # beside the kind's own table, unless it is that table exactly (equal at the base is not
        # enough: a table that sets the wave frequency is not retuned to a condition's sea)
        elif own_table != tables[own_kind]:
            observers[f"{own_kind}-as-given"], built[f"{own_kind}-as-given"] = own_table, trial_own
    for kind, table in tables.items():
        result = trial(table)
        if isinstance(result, CompositionError):
            skipped.append(f"skipped {kind}: {result}")
            continue
        observers[kind], built[kind] = table, result
    if not observers:
        raise fail(("observer",), f"no observer composes on its plant and sensor ({skipped[0] if skipped else 'none registered'})")

    # ---- the controller: an input stays; a loop on the estimate becomes a condition
    controller_kind = own_controller.get("kind", "none")
    if own is not None:
        closes_loop = bool(tuple(own.scenario.controller.estimate_needs))
    else:
        closes_loop = controller_kind not in OPEN_LOOP_CONTROLLERS
    tracked: list[str] = []
    if closes_loop:
        for name in observers:  # the loop's reference: what it tracks (from a composition that closes it)
            try:
                loop = compose({**base_document(probe, sizes["quick"], observers[name]), "controller": own_controller, "reference": own_reference})
            except CompositionError:
                continue
            truths = {s.name for s in loop.scenario.record_signals.truth}
            tracked = [
                s.name.removesuffix("_desired")
                for s in loop.scenario.record_signals.reference
                if s.name.endswith("_desired") and s.name.removesuffix("_desired") in truths
            ]
            break
        open_input = copy.deepcopy(shipped.base.get("controller", {"kind": "none"})) if shipped is not None else {"kind": "none"}
        base["controller"], base["reference"] = open_input, {"kind": "none"}
        notes.append(
            f"your controller ({controller_kind}) reads the observer's estimate: the benchmark runs open loop "
            f"({'the shipped ' + plant_kind + ' benchmark input, ' + open_input['kind'] if shipped is not None else 'no input'}), "
            f"and your loop is the condition 'closed loop ({controller_kind})'"
        )

    # ---- the conditions
    user = reference_document
    measured = [s.name for s in (first or own).scenario.sensor.measurement_layout.signals]
    truths = [s.name for s in (first or own).scenario.record_signals.truth]
    conditions: list[Condition] = []
    if shipped is not None:
        outage_signals = tuple(shipped.spec.outage_signals) if set(shipped.spec.outage_signals) <= set(measured) else ()
        if shipped.spec.outage_signals and not outage_signals:
            notes.append(f"no outage: your sensor measures no {', '.join(shipped.spec.outage_signals)}")
        shipped_document = compose(base_document(shipped, shipped.spec.quick, next(iter(shipped.spec.observers.values())))).document
        for condition in shipped.spec.conditions:
            missing = [p for p in {**condition.changes, **condition.truth_only} if not _exists(user, p)]
            if "sensor.outage_duration" in condition.changes and not outage_signals:
                missing = missing or ["sensor.outage_signals"]
            if missing:
                notes.append(f"left out condition '{condition.name}': your scenario has no setting {missing[0]!r}")
                continue
            truth_only = {}
            for key, value in condition.truth_only.items():
                truth_only[key] = value if same_model else _relative_error(value, get_path(shipped_document, key), get_path(user, key))
            if any(value is None for value in truth_only.values()):
                notes.append(f"left out condition '{condition.name}': its model error is no factor that your model can take")
                continue
            conditions.append(condition.model_copy(update={"truth_only": truth_only}))
        metrics = list(shipped.spec.metrics)
        divergence = shipped.spec.divergence
    else:
        outage_signals = tuple(measured[:1])
        conditions.append(Condition(name="baseline"))
        if "dropout_probability" in user["sensor"]:
            conditions += [Condition(name=f"{p} % lost samples", changes={"sensor.dropout_probability": p / 100}) for p in (10, 50)]
        sensor_periods = np.atleast_1d(np.asarray((first or own).scenario.sensor.sample_period, dtype=float))
        length = max(float(sensor_periods.max()), _on_grid(sizes["full"].duration * GENERIC_OUTAGE[1], period))
        if outage_signals:
            conditions.append(
                Condition(
                    name=f"{length:g} s {outage_signals[0].removeprefix('measured_').replace('_', ' ')} outage",
                    changes={"sensor.outage_duration": length},
                )
            )
        for part, table in _model_parts(user["plant"]).items():
            for key, value in table.items():
                try:
                    array = np.asarray(value, dtype=float)
                except (TypeError, ValueError):
                    continue
                if not MODEL_ERROR_NAMES.search(key) or not np.any(array != 0) or not np.isfinite(array).all():
                    continue
                for sign in (1, -1):
                    changed = array * (1 + sign * GENERIC_MODEL_ERROR)
                    conditions.append(
                        Condition(
                            name=f"{key.replace('_', ' ')} {'+' if sign > 0 else '-'}{GENERIC_MODEL_ERROR:.0%}".replace("%", " %"),
                            truth_only={f"plant.{part}.{key}": changed.tolist() if changed.ndim else float(changed)},
                        )
                    )
        estimated = {s.name for result in built.values() for s in result.scenario.record_signals.estimate}
        metrics = [f"rms_error:{name}" for name in truths if name in estimated]
        unmeasured = [name for name in truths if name in estimated and f"measured_{name}" not in measured]
        if unmeasured:
            metrics.append(f"settling_time:{unmeasured[0]}")
        outage_variable = outage_signals[0].removeprefix("measured_") if outage_signals else None
        if outage_variable in estimated and outage_variable in truths:
            metrics += [f"outage_drift:{outage_variable}", f"recovery_time:{outage_variable}"]
        divergence = None
    if not outage_signals:
        sizes = {name: size.model_copy(update={"outage_start": None}) for name, size in sizes.items()}
        metrics = [m for m in metrics if m.partition(":")[0] not in ("outage_drift", "recovery_time")]
    if closes_loop:
        conditions.append(Condition(name=f"closed loop ({controller_kind})", changes={"controller": own_controller, "reference": own_reference}))
        metrics += [f"rms_tracking:{name}" for name in tracked if f"rms_tracking:{name}" not in metrics]
    # what the file sets that the benchmark sets otherwise (a preset's keys are not the file's)
    benchmark_values = {"duration": sizes["full"].duration, "runs": 1, "seed": simulation.seed, "record_every": 1, "observer_mode": "sampled"}
    own_simulation = document.get("simulation", {}) if isinstance(document.get("simulation"), dict) else {}
    unused = [
        f"simulation.{key} = {json.dumps(value)}"
        for key, value in own_simulation.items()
        if key in benchmark_values and value != benchmark_values[key]
    ]
    unused += [f"sensor.{key}" for key in document.get("sensor", {}) if key in BENCHMARK_SENSOR]
    origin = f"the shipped {plant_kind} benchmark's" if shipped is not None else "generic"
    notes.insert(
        0,
        f"{source}: a scenario file: its plant ({plant_kind}), sensor and sea; {len(observers)} observers that compose on them; "
        f"{origin} conditions and sizes ({sizes['full'].duration:g} s x {sizes['full'].seeds} seeds, quick {sizes['quick'].duration:g} s x "
        f"{sizes['quick'].seeds})" + (f"; not used: {', '.join(unused)}" if unused else ""),
    )
    notes += skipped
    spec = BenchmarkSpec.model_validate(
        {
            "title": f"{path.name}: {plant_kind}, every observer that composes on it",
            "scenario": base,
            "seed": simulation.seed,
            "metrics": tuple(metrics),
            "divergence": divergence,
            "outage_signals": outage_signals,
            "full": sizes["full"],
            "quick": sizes["quick"],
            "observers": observers,
            "conditions": tuple(conditions),
        }
    )
    benchmark = Benchmark(spec, path.stem, source, text, base, tuple(notes), True)
    check_spec(benchmark)
    return benchmark


# ------------------------------------------------------------------ the campaigns


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


def _plant_part(plant: dict, role: str) -> tuple[str, dict] | None:
    """(key, table) of the plant's part of ``role`` (its ``vessel`` for a vessel model)."""
    for parameter in registry.kind("plant", plant["kind"]).parameters():
        if parameter.sort == "part" and parameter.role == role and isinstance(plant.get(parameter.name), dict):
            return parameter.name, plant[parameter.name]
    return None


def model_pins(document: dict) -> dict[str, dict]:
    """Key path -> table: each model the observer of ``document`` (a composition with every
    key spelled out) takes from the plant or the sensor, given explicitly as the table it
    is taken from, so that a change to the plant afterwards (a model error) does not reach
    it. A model the plant derives from another part (a ship's DP-vessel form) has no
    table to pin: a ValueError asks for it in the observer's table."""
    pins = _models_taken(document)
    for here, table in pins.items():
        if table is None:
            raise ValueError(
                f"{here}: the observer takes its {here.rpartition('.')[2]} from plant {document['plant']['kind']}, which derives it; "
                f"give a [{here}] table so that a model error does not reach it"
            )
    return pins


def _models_taken(document: dict) -> dict[str, dict | None]:
    """Key path -> table of each model the observer of ``document`` takes from the
    plant or the sensor (None: a model the plant derives, which has no table)."""
    pins: dict[str, dict | None] = {}

    def strip(table: dict) -> dict:
        return {key: copy.deepcopy(value) for key, value in table.items() if key != "initial"}

    def walk(role: str, table: dict, path: str) -> None:
        kind = registry.kind(role, table["kind"])
        for parameter in kind.parameters(table.get("design")):
            if parameter.sort != "part":
                continue
            here = f"{path}.{parameter.name}"
            if parameter.name in table:
                if isinstance(table[parameter.name], dict):
                    walk(parameter.role, table[parameter.name], here)
                continue
            if parameter.role in MODEL_ROLES:
                pins[here] = strip(document[parameter.role])
            elif parameter.role in registry.COMPONENT_ROLES or not parameter.from_plant:
                continue
            else:
                found = _plant_part(document["plant"], parameter.role)
                pins[here] = None if found is None else strip(found[1])

    walk("observer", document["observer"], "observer")
    return pins


def condition_case(benchmark: Benchmark, base: dict, condition: Condition) -> dict[str, Any]:
    """Key path -> value of ``condition`` for the campaign of ``base`` (a spelled-out
    composition): its changes, then (for a model error) the observer's models pinned as
    the changed composition has them, then the plant's model error."""
    case = dict(condition.changes)
    if condition.truth_only:
        told = copy.deepcopy(base)
        for path, value in condition.changes.items():
            set_path(told, path, value)
        told = compose(told).document
        case.update(model_pins(told))
        case.update(condition.truth_only)
    return case


def describe_condition(condition: Condition) -> str:
    """What ``condition`` changes, in words: ``key = value`` (the model error's keys marked)."""

    def short(value) -> str:
        if isinstance(value, dict):  # a whole table: its kind (and design)
            return "{" + ", ".join(f"{k} = {json.dumps(v)}" for k, v in value.items() if k in ("kind", "design")) + ", ...}"
        return json.dumps(value)

    told = [f"{key} = {short(value)}" for key, value in condition.changes.items()]
    error = [f"{key} = {short(value)} (the plant alone)" for key, value in condition.truth_only.items()]
    return "; ".join(told + error)


def metric_fit(names, scenario) -> tuple[list[str], dict[str, str]]:
    """The metrics of ``names`` that apply to ``scenario`` (its observer estimates the
    signal, its reference tracks it, ...), and for each other one, why not."""
    from lookout.scenario import metrics as metric_module

    applies, reasons = [], {}
    for name in names:
        try:
            metric_module.resolve([name], scenario)
        except ValueError as error:
            reasons[name] = str(error)
            continue
        if name.partition(":")[0] in ("outage_drift", "recovery_time") and metric_module.outage_of(scenario) is None:
            reasons[name] = f"{name!r}: the sensor has no outage (give outage_signals and a condition with sensor.outage_duration > 0)"
            continue
        applies.append(name)
    return applies, reasons


@dataclass(frozen=True)
class ObserverCampaign:
    """One campaign of one observer of a benchmark: the conditions at which the same
    metrics apply (all of them, usually; a closed loop adds a tracking metric)."""

    name: str  # the observer
    campaign: Campaign
    told: str  # what the observer is given: its design, values and the models it takes
    store_name: str = ""  # its store: <store_name>.zarr (default: the observer's name)
    conditions: tuple[str, ...] = ()

    @property
    def store(self) -> str:
        return self.store_name or self.name


def told(document: dict, table: dict) -> str:
    """What the observer of ``document`` (spelled out) is given, in words: its design
    rule, the values its spec ``table`` sets, and the models it takes from the
    composition (the plant's, the sensor's)."""
    kind = registry.kind("observer", table["kind"])
    design = document["observer"].get("design")
    given = [p.name for p in kind.parameters(design) if p.sort == "value" and p.name in table]
    own = [p.name for p in kind.parameters(design) if p.sort == "part" and p.name in table]
    models = [path.split(".", 1)[1] + ("" if table is not None else " (derived by the plant)") for path, table in _models_taken(document).items()]
    parts = [f"design rule {design}"] if design and design != "gains" else []
    parts.append("sets " + ", ".join(given) if given else "its defaults")
    if own:
        parts.append("its own " + ", ".join(own))
    if models:
        parts.append("models from the composition: " + ", ".join(models))
    return "; ".join(parts)


@dataclass
class _Fit:
    """How observer ``name`` fits each condition: the metrics that apply there, or why it
    does not run there."""

    name: str
    full: dict  # the spelled-out base composition with the observer
    cases: dict[int, dict]  # condition index -> key path -> value
    metrics: dict[int, tuple[str, ...]]
    failures: dict[int, str]
    reasons: dict[str, str]  # metric -> why it applies at none of its conditions
    base_metrics: tuple[str, ...] = ()  # the metrics that apply to the base composition


def _path_error(error: CompositionError, case: dict) -> str:
    """A key path of a condition that the scenario does not have, in the spec's words."""
    if "no such key" in error.reason or "does not exist" in error.reason:
        path = next((p for p in case if error.location and _starts_with(p, error.location)), None)
        if path is not None:
            known = re.search(r"\(known here: (.*)\)$", error.reason)
            where = key_text(error.location[:-1])
            return f"the scenario has no setting {path!r}" + (f" ({where} has {known.group(1)})" if known and where else "")
    return str(error)


def _starts_with(path: str, location: tuple) -> bool:
    from lookout.scenario.composition import path_parts

    try:
        return tuple(path_parts(path))[: len(location)] == tuple(location)
    except CompositionError:
        return False


def _fit(benchmark: Benchmark, size_name: str, name: str) -> _Fit:
    """Compose observer ``name`` on the base and at each condition (nothing is run)."""
    spec = benchmark.spec
    size = getattr(spec, size_name)
    location = ("observers", name)
    base = base_document(benchmark, size, spec.observers[name])
    try:
        composition = compose(base)
    except CompositionError as error:
        if error.location[:1] == ("observer",):
            where = location + error.location[1:]
        elif error.location[:2] == ("sensor", "outage_signals"):  # the spec's own key, not its scenario's
            where = ("outage_signals",)
        else:
            where = ("scenario",) + error.location
        raise benchmark.located(where, error.reason) from None
    full = composition.document
    if spec.divergence is not None and spec.divergence.signal not in {s.name for s in composition.scenario.record_signals.truth}:
        raise benchmark.located(
            ("divergence", "signal"),
            f"the plant has no variable {spec.divergence.signal!r} (it has {', '.join(s.name for s in composition.scenario.record_signals.truth)})",
        )
    fit = _Fit(name, full, {}, {}, {}, {}, tuple(metric_fit(spec.metrics, composition.scenario)[0]))
    for index, condition in enumerate(spec.conditions):
        case: dict = {}
        try:
            case = condition_case(benchmark, full, condition)
            changed = _applied(full, case)  # a key path the scenario does not have fails here
            if not (benchmark.lenient or condition.replaces_a_table):
                # the same components with other numbers: the base's metrics apply, and the
                # campaign's own check composes it (a refusal names the condition)
                fit.cases[index], fit.metrics[index] = case, fit.base_metrics
                continue
            scenario = compose(changed).scenario
        except CompositionError as error:
            fit.failures[index] = _path_error(error, case or {**condition.changes, **condition.truth_only})
            continue
        except ValueError as error:
            fit.failures[index] = str(error)
            continue
        fit.cases[index] = case
        applies, reasons = metric_fit(spec.metrics, scenario)
        fit.metrics[index] = tuple(applies)
        for metric, reason in reasons.items():
            fit.reasons.setdefault(metric, reason)
    return fit


def check_outages(benchmark: Benchmark, size_name: str, fits: list[_Fit] | None = None) -> None:
    """Refuse (at the condition) an outage that does not end before the run does (the
    recovery after it could not be measured), or that silences no sample of a signal it
    names (it would measure nothing)."""
    spec = benchmark.spec
    size = getattr(spec, size_name)
    for index, condition in enumerate(spec.conditions):
        start = condition.changes.get("sensor.outage_start", size.outage_start)
        length = condition.changes.get("sensor.outage_duration", 0.0)
        if not (spec.outage_signals and isinstance(length, (int, float)) and length > 0 and isinstance(start, (int, float))):
            continue
        if start + length >= size.duration:
            raise benchmark.located(
                ("conditions", index),
                f"{condition.name}: the outage ends at {start + length:g} s, not before the {size_name} run "
                f"does ({size.duration:g} s): the recovery after it cannot be measured; start it earlier ({size_name}.outage_start)",
            )
        for fit in fits or ():
            if index not in fit.cases:
                continue
            sensor = compose(_applied(fit.full, fit.cases[index])).scenario.sensor
            if sensor.outage is None:
                break
            periods = np.broadcast_to(np.asarray(sensor.sample_period, dtype=float), (len(sensor.outage.channels),))
            silenced = periods[np.asarray(sensor.outage.channels)]
            first_sample = np.ceil(start / silenced - 1e-9) * silenced
            if np.any(first_sample >= start + length - 1e-9 * max(1.0, start + length)):
                raise benchmark.located(
                    ("conditions", index),
                    f"{condition.name}: the outage of {length:g} s from {start:g} s silences no sample "
                    f"of a signal sampled every {float(silenced.max()):g} s: it would measure nothing; make it longer",
                )
            break


def _applied(document: dict, case: dict) -> dict:
    changed = copy.deepcopy(document)
    for path, value in case.items():
        set_path(changed, path, value)
    return changed


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "-", text).strip("-").lower() or "condition"


@dataclass
class Plan:
    """What a benchmark runs: each observer's campaigns, and what it does not run, why."""

    campaigns: list[ObserverCampaign]
    conditions: list[str]  # the conditions some observer runs, in the spec's order
    skipped: list[str]  # one line each: an observer, or an observer at a condition, not run


def plan(benchmark: Benchmark, size_name: str, observers: list[str] | None = None) -> Plan:
    """Every observer's campaigns (or those named), checked before anything runs.

    An observer that does not compose at a condition is refused there, unless the
    condition replaces a whole table (a closed loop some observers cannot drive) and
    some observer runs it, or the benchmark is a scenario file's (``lenient``): then it
    is skipped there, said in one line. A metric that applies nowhere is refused."""
    spec = benchmark.spec
    names = list(spec.observers) if observers is None else observers
    fits = [_fit(benchmark, size_name, name) for name in names]
    check_outages(benchmark, size_name, fits)
    skipped: list[str] = []
    dropped: set[int] = set()
    for index, condition in enumerate(spec.conditions):
        failing = [fit for fit in fits if index in fit.failures]
        if not failing:
            continue
        everyone = len(failing) == len(fits)
        if benchmark.lenient and everyone:
            skipped.append(f"left out condition '{condition.name}': no observer runs it ({failing[0].name}: {failing[0].failures[index]})")
            dropped.add(index)
        elif benchmark.lenient or (condition.replaces_a_table and not everyone):
            skipped += [f"{fit.name} not run at '{condition.name}': {fit.failures[index]}" for fit in failing]
        else:
            raise benchmark.located(("conditions", index), f"{condition.name} (observer {failing[0].name}): {failing[0].failures[index]}")
    applied = {metric for fit in fits for found in fit.metrics.values() for metric in found}
    for metric in spec.metrics if observers is None else ():  # (over every observer of the spec)
        if metric not in applied and not benchmark.lenient:
            reason = next((fit.reasons[metric] for fit in fits if metric in fit.reasons), "")
            raise benchmark.located(("metrics",), f"{metric!r} applies to no observer at any condition: {reason}")
    campaigns: list[ObserverCampaign] = []
    for fit in fits:
        runs = [index for index in range(len(spec.conditions)) if index in fit.cases and index not in dropped and fit.metrics[index]]
        if not runs:
            reason = next(
                iter(fit.failures.values()),
                f"no metric applies to it (it estimates {', '.join(s.name for s in compose(fit.full).scenario.record_signals.estimate)})",
            )
            if benchmark.lenient:
                skipped.append(f"skipped {fit.name}: {reason}")
                continue
            raise benchmark.located(("metrics",) if not fit.failures else ("observers", fit.name), f"observer {fit.name}: {reason}")
        campaigns += _campaigns_of(benchmark, size_name, fit, runs)
    if not campaigns:
        raise benchmark.located((), "no observer runs at any condition")
    ran = {name for each in campaigns for name in each.conditions}
    return Plan(campaigns, [c.name for c in spec.conditions if c.name in ran], skipped)


def _campaigns_of(benchmark: Benchmark, size_name: str, fit: _Fit, runs: list[int]) -> list[ObserverCampaign]:
    """The campaigns of one observer: the conditions with the metrics of the base
    composition as one campaign on that base (a case each), every other condition (a
    closed loop, with its tracking metric) as a campaign of its own, on its scenario."""
    spec = benchmark.spec
    size = getattr(spec, size_name)
    main = [index for index in runs if fit.metrics[index] == fit.base_metrics]
    groups = [(fit.name, fit.full, main)] if main else []
    used = {fit.name}
    for index in runs:
        if index in main:
            continue
        store = f"{fit.name}.{_slug(spec.conditions[index].name)}"
        while store in used:
            store += f"-{index}"
        used.add(store)
        groups.append((store, compose(_applied(fit.full, fit.cases[index])).document, [index]))
    result = []
    for store, scenario, indices in groups:
        own_base = scenario is not fit.full
        document = {
            "scenario": scenario,
            "seeds_per_point": size.seeds,
            "seed": spec.seed,
            "chunk_runs": size.seeds,
            "metrics": list(fit.metrics[indices[0]]),
            "sweep": {
                "kind": "grid",
                "axes": [
                    {
                        "name": "condition",
                        "labels": [spec.conditions[i].name for i in indices],
                        "cases": [{} if own_base else fit.cases[i] for i in indices],
                    }
                ],
            },
        }
        if size.after is not None:
            document["after"] = size.after
        if spec.divergence is not None:
            document["divergence"] = spec.divergence.model_dump()
        try:
            campaign = campaign_from_document(document, f"{benchmark.source} [observers.{fit.name}]")
        except FileError as error:
            raise _campaign_error(benchmark, size_name, fit.name, indices, str(error)) from None
        result.append(
            ObserverCampaign(fit.name, campaign, told(fit.full, spec.observers[fit.name]), store, tuple(spec.conditions[i].name for i in indices))
        )
    return result


def observer_campaign(benchmark: Benchmark, size_name: str, name: str) -> ObserverCampaign:
    """The (first) campaign of observer ``name`` (a key of the spec's observers) at ``size_name``."""
    return next(each for each in plan(benchmark, size_name, [name]).campaigns if each.name == name)


def _campaign_error(benchmark: Benchmark, size_name: str, observer: str, indices: list[int], message: str) -> FileError:
    """A campaign's refusal, located at the spec's key: a condition's case at the
    condition (the campaign's ``sweep.axes[0].cases`` are the benchmark's conditions),
    its seeds at the size's seeds, its window at the size's after."""
    _, _, detail = message.partition(f"[observers.{observer}]: ")
    key, _, reason = detail.partition(": ")
    key = re.sub(r" \(line \d+\)$", "", key)
    if key.startswith("sweep.axes[0]"):
        names = [benchmark.spec.conditions[i].name for i in indices]
        named = re.match(r"case '(.*?)'(?: makes no scenario)?: (.*)", reason)
        index = indices[names.index(named.group(1))] if named and named.group(1) in names else indices[0]
        return benchmark.located(
            ("conditions", index), f"{benchmark.spec.conditions[index].name} (observer {observer}): {named.group(2) if named else reason}"
        )
    spec_key = {
        "seeds_per_point": (size_name, "seeds"),
        "seed": ("seed",),
        "after": (size_name, "after"),
        "metrics": ("metrics",),
        "divergence.signal": ("divergence", "signal"),
        "sweep": (size_name, "seeds"),
    }.get(key)
    if spec_key is None or not reason:
        return FileError(message)
    return benchmark.located(spec_key, f"(observer {observer}) {reason}")


def campaigns(benchmark: Benchmark, size_name: str, observers: list[str] | None = None) -> list[ObserverCampaign]:
    """Every observer's campaigns (or those named), checked before anything runs."""
    return plan(benchmark, size_name, observers).campaigns


# ------------------------------------------------------------------ running


def observer_cost(scenario, seed: int, repeats: int = COST_REPEATS) -> float:
    """Microseconds per sample of the observer of ``scenario`` alone, stepped over one
    run's recorded measurements and inputs (the run of ``seed``), compiled: the best of
    ``repeats`` passes."""
    import jax
    import numpy as np

    from lookout.sim import keys_of_seeds, simulate
    from lookout.sim.filtering import _filter_scan

    trajectory = simulate(scenario, keys_of_seeds([seed])[0])
    times = jax.numpy.asarray(trajectory.time)
    measurements = jax.numpy.asarray(np.asarray(trajectory.measurement))
    inputs = jax.numpy.asarray(np.asarray(trajectory.applied))
    observer, guess = scenario.observer, scenario.initial_estimate
    jax.block_until_ready(_filter_scan(observer, guess, times, measurements, inputs))  # compiles
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(_filter_scan(observer, guess, times, measurements, inputs))
        best = min(best, time.perf_counter() - start)
    return best / times.shape[0] * 1e6


@dataclass
class Prepared:
    """A benchmark ready to run: its campaigns, checked, and where they go."""

    benchmark: Benchmark
    size: str
    folder: Path
    campaigns: list[ObserverCampaign]
    conditions: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)

    def store(self, each: ObserverCampaign | str) -> Path:
        """The store of a campaign (or of the observer's first campaign, by its name)."""
        return self.folder / f"{each.store if isinstance(each, ObserverCampaign) else each}.zarr"

    @property
    def notes(self) -> list[str]:
        """What loading and planning decided, one line each (to print before running)."""
        return list(self.benchmark.notes) + list(self.skipped)


def prepare(benchmark: Benchmark, size_name: str, out: Path, observers: list[str] | None = None) -> Prepared:
    """Check the benchmark before anything runs: every observer's campaign is built and
    validated, and each store in ``out/<spec name>/`` holds that campaign or nothing (a
    store of other settings is refused, naming it). Writes nothing."""
    from lookout.studies.store import CampaignStore, differences

    folder = Path(out) / benchmark.name
    planned = plan(benchmark, size_name, observers)
    prepared = Prepared(benchmark, size_name, folder, planned.campaigns, planned.conditions, planned.skipped)
    for each in prepared.campaigns:
        path = prepared.store(each)
        store = CampaignStore(path)
        try:
            store.holds(each.campaign)
        except ValueError as error:
            held = store.campaign_document()
            if held is None:
                raise ValueError(f"--out: {error}") from None
            changed = [_short(_spec_words(line)) for line in differences(held, each.campaign.document())]
            raise ValueError(
                f"--out: {path} holds observer {each.name}'s benchmark with other settings ({'; '.join(changed[:3])}"
                f"{f'; and {len(changed) - 3} more' if len(changed) > 3 else ''}): give another --out, or remove {path}"
            ) from None
    return prepared


def check_resources(prepared: list[Prepared], workers: int | None, scheduler: str | None) -> None:
    """Refuse (ValueError, or a SchedulerError for an unreachable scheduler) before
    anything is written: a chunk that would not fit a worker's memory, stores that would
    not fit the disk, a scheduler that does not answer."""
    import os

    from lookout import _resources
    from lookout.studies.execute import SCHEDULER_TIMEOUT, SchedulerError, chunk_memory, store_bytes
    from lookout.studies.store import CampaignStore

    per_worker, count = None, 1
    if scheduler is not None:
        from dask.distributed import Client

        from lookout._validation import one_line

        client = None
        try:
            client = Client(scheduler, timeout=SCHEDULER_TIMEOUT)
            info = client.scheduler_info()["workers"]
        except Exception as error:  # an address dask cannot parse, or a scheduler that does not answer
            raise SchedulerError(f"cannot reach the scheduler ({one_line(error) or type(error).__name__})") from None
        finally:
            if client is not None:
                client.close()
        limits = [w.get("memory_limit") or None for w in info.values()]
        per_worker, count = (min(limits) if limits and all(limits) else None), max(1, len(info))
    else:
        count = 1 if workers == 0 else workers or os.cpu_count() or 1
        available = _resources.available_memory()
        per_worker = None if available is None else available / count
    need = 0.0
    for each in prepared:
        size = getattr(each.benchmark.spec, each.size)
        for campaign in each.campaigns:
            memory = chunk_memory(campaign.campaign)
            if per_worker is not None and memory > per_worker:
                raise ValueError(
                    f"{each.benchmark.source}: {each.size}.seeds = {size.seeds}: a chunk (the {size.seeds} runs of a condition, "
                    f"{size.duration:g} s each) needs about {_resources.format_bytes(memory)}, and a worker has "
                    f"{_resources.format_bytes(per_worker)} ({count} worker{'s' * (count != 1)}): use fewer seeds, shorter runs, "
                    "or fewer workers"
                )
            store = CampaignStore(each.store(campaign))
            done = store.done() if store.holds(campaign.campaign) else {}
            pending = len(campaign.campaign.chunks()) - len(done)
            need += store_bytes(campaign.campaign, pending) if pending else 0.0
    if prepared:
        _resources.refuse_unless_it_fits(
            need,
            f"the benchmark's stores in {prepared[0].folder.parent}",
            "free some space, or give --out on another disk",
            available=_resources.free_disk(prepared[0].folder),
            resource="disk space",
        )


#: A campaign's keys as a benchmark spec names them.
_SPEC_WORDS = (
    ("sweep.axes[0].labels", "condition names"),
    ("sweep.axes[0].cases", "conditions"),
    ("seeds_per_point", "seeds"),
    ("scenario.simulation.duration", "duration"),
    ("scenario.sensor.outage_start", "outage_start"),
    ("scenario.observer", "observer"),
)


def _spec_words(text: str) -> str:
    for campaign_key, spec_words in _SPEC_WORDS:
        text = text.replace(campaign_key, spec_words)
    return text


def _short(text: str, limit: int = 90) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


@dataclass
class Result:
    """Where a benchmark put its results, and how long it took."""

    folder: Path
    stores: dict[str, list[Path]]
    costs: dict[str, float]
    told: dict[str, str]
    seconds: float
    written: dict[str, Path]
    recommendations: list = field(default_factory=list)


def run_benchmark(
    prepared: Prepared,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    say: Callable[[str], None] = print,
    progress: Callable[[str, int, int], None] | None = None,
    command: str = "",
) -> Result:
    """Run a prepared benchmark: its campaigns (into ``<folder>/<store>.zarr``, each
    resumed when its store holds it), then each observer's cost, then the results
    (:func:`lookout.studies.benchmark_report.write_results`, with the recommendation per
    condition) and each campaign's report. Local dask workers (``workers``; 0: this
    process), or a running cluster at ``scheduler`` (one of the user's, or one this
    process started for several benchmarks)."""
    import os

    from lookout.studies import benchmark_report
    from lookout.studies.execute import local_cluster, run_campaign
    from lookout.studies.report import write_report

    start = time.perf_counter()
    prepared.folder.mkdir(parents=True, exist_ok=True)
    cluster = None
    address = scheduler
    if address is None and workers != 0:
        cluster = local_cluster(workers or os.cpu_count() or 1)
        address = cluster.scheduler_address
    stores: dict[str, list[Path]] = {}
    try:
        for index, each in enumerate(prepared.campaigns):
            label = each.name if each.store == each.name else f"{each.name} at {', '.join(each.conditions)}"
            say(
                f"[{index + 1}/{len(prepared.campaigns)}] {label}: {len(each.campaign.chunks())} chunks "
                f"({len(each.campaign.points)} condition{'s' * (len(each.campaign.points) != 1)} x {each.campaign.settings.seeds_per_point} seeds)"
            )
            path = prepared.store(each)
            report = None if progress is None else (lambda done, total, name=each.store: progress(name, done, total))
            run_campaign(each.campaign, path, workers=0 if address is None else None, scheduler=address, say=lambda text: None, progress=report)
            stores.setdefault(each.name, []).append(path)
    finally:
        if cluster is not None:
            cluster.close()
    costs: dict[str, float] = {}
    told_by: dict[str, str] = {}
    for each in prepared.campaigns:
        if each.name in costs:
            continue
        costs[each.name] = observer_cost(each.campaign.base.build(), prepared.benchmark.spec.seed)
        told_by[each.name] = each.told
        say(f"{each.name}: {costs[each.name]:.3g} us per sample (the observer alone, one run)")
    spec = prepared.benchmark.spec
    ds = benchmark_report.collect(
        stores,
        costs,
        told_by,
        metrics=list(spec.metrics),
        title=spec.title,
        command=command,
        changes={c.name: describe_condition(c) for c in spec.conditions},
        conditions=prepared.conditions,
        recommend_by=list(spec.recommend_by) or None,
        skipped=prepared.skipped,
    )
    reports = {each.store: write_report(prepared.store(each), prepared.folder / "reports" / f"{each.store}.html") for each in prepared.campaigns}
    written = benchmark_report.write_results(ds, prepared.folder, reports)
    recommendations = benchmark_report.recommend(ds)
    return Result(prepared.folder, stores, costs, told_by, time.perf_counter() - start, written, recommendations)
