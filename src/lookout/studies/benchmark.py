"""The observer benchmark: every observer that fits a plant, on identical scenarios.

Which observer, for my vessel and my sea, at what cost? A **benchmark spec** (TOML; the
shipped ones are in ``lookout/studies/benchmarks/``, one per plant) names

- a base scenario (a composition, or a reproduction's case as a preset), run open loop
  with its own input, so that what the sensor measures does not depend on the observer;
- the observers to compare, each an ``[observer]`` table of the composition (a kind, its
  design rule and gains; the models it leaves out are the plant's);
- the conditions, each one change from the base: ``changes`` reach the whole
  composition (a calmer sea, lost fixes, an outage: the observers that take the sea
  from the plant are told), ``truth_only`` reaches the plant alone (a model error: the
  observers keep the nominal model);
- the metrics (those of :mod:`lookout.studies.metrics`; each observer is measured on
  the signals it estimates), a divergence rule, and two sizes, ``full`` and ``quick``
  (duration, seeds, when the outage starts).

Each observer's benchmark is one campaign (:mod:`lookout.studies.campaign`): the base
scenario with that observer, and one sweep axis, ``condition``, with a case per
condition. Every campaign runs the same seeds at every condition, so every observer
sees the same plant, the same sea and the same measurements, bit for bit, and the
chunks run on dask as any campaign's, into a Zarr store per observer that a killed
benchmark resumes.

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
import math
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Callable

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from lookout import registry
from lookout.composition import MODEL_ROLES, CompositionError, compose, merge, preset_document, set_path
from lookout.settings import PositiveCount, PositiveFloat, validate_strictly
from lookout.studies._toml import FileError, read
from lookout.studies.campaign import Campaign, Divergence, campaign_from_document
from lookout.studies.scenario_file import describe, located

#: The folder of the shipped benchmark specs (``<plant>.toml``).
SHIPPED = "benchmarks"
#: The sizes a spec defines.
SIZES = ("full", "quick")
#: Repeats of the timed observer-only pass; the best is reported.
COST_REPEATS = 3


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

    @field_validator("truth_only")
    @classmethod
    def _plant_only(cls, value):
        for path in value:
            if not path.startswith("plant."):
                raise ValueError(f"{path!r}: a model error changes the plant (keys plant.*); put other changes under changes")
        return value


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
    scenario: str | dict = Field(description="a scenario file (relative to the spec) or an inline composition (may hold a preset)")
    seed: int = 0
    metrics: tuple[str, ...]
    divergence: Divergence | None = None
    outage_signals: tuple[str, ...] = Field((), description="the measured signals an outage condition silences")
    full: Size
    quick: Size
    observers: dict[str, dict] = Field(description="name -> an [observer] table")
    conditions: tuple[Condition, ...]

    @field_validator("observers")
    @classmethod
    def _some_observers(cls, value):
        if not value:
            raise ValueError("name at least one observer")
        for name, table in value.items():
            if not isinstance(table, dict) or "kind" not in table:
                raise ValueError(f"{name}: must be an [observer] table with a kind")
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

    @model_validator(mode="after")
    def _outage(self):
        for size_name in SIZES:
            size = getattr(self, size_name)
            if self.outage_signals and size.outage_start is None:
                raise ValueError(f"{size_name}.outage_start: give it (outage_signals names an outage)")
            if size.outage_start is not None and not (0.0 <= size.outage_start < size.duration):
                raise ValueError(f"{size_name}.outage_start must be in [0, duration = {size.duration:g} s); got {size.outage_start:g}")
        return self


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
    """A loaded spec: its settings, where it came from, and its base scenario."""

    spec: BenchmarkSpec
    name: str
    source: str
    text: str | None
    base: dict  # the scenario, a preset expanded, without its observer

    def located(self, location: tuple, message: str) -> FileError:
        return located(self.source, self.text, location, message)


def load_benchmark(path: str | Path) -> Benchmark:
    """Read and validate the benchmark spec at ``path`` (one-line FileError on bad input)."""
    path = Path(path)
    document, text = read(path)
    try:
        spec = validate_strictly(BenchmarkSpec, document)
    except ValidationError as error:
        raise FileError(describe(error, str(path), text)) from None
    source = str(path)
    scenario = spec.scenario
    if isinstance(scenario, str):
        scenario_path = Path(scenario) if Path(scenario).is_absolute() else path.parent / scenario
        try:
            scenario, _ = read(scenario_path)
        except FileError as error:
            raise located(source, text, ("scenario",), str(error)) from None
    try:
        base = merge(preset_document(scenario["preset"]), scenario) if "preset" in scenario else copy.deepcopy(scenario)
    except CompositionError as error:
        raise located(source, text, ("scenario",) + error.location, error.reason) from None
    base.pop("observer", None)
    return Benchmark(spec, path.stem, source, text, base)


# ------------------------------------------------------------------ the campaigns


def base_document(benchmark: Benchmark, size: Size, observer: dict) -> dict:
    """The composition of the base condition with ``observer``: the spec's scenario with
    the size's duration, the spec's seed, every sample recorded, the observer sampled on
    the sensor's measurements, and the outage's structure (of 0 s) on the sensor."""
    document = copy.deepcopy(benchmark.base)
    simulation = document.setdefault("simulation", {})
    simulation.update(duration=size.duration, seed=benchmark.spec.seed, runs=1, record_every=1, observer_mode="sampled")
    if benchmark.spec.outage_signals:
        document.setdefault("sensor", {}).update(outage_signals=list(benchmark.spec.outage_signals), outage_start=size.outage_start, outage_duration=0.0)
    document["observer"] = copy.deepcopy(observer)
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
    pins: dict[str, dict] = {}

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
                if found is None:
                    raise ValueError(
                        f"{here}: the observer takes its {parameter.name} from plant {document['plant']['kind']}, which derives it; "
                        f"give a [{here}] table so that a model error does not reach it"
                    )
                pins[here] = strip(found[1])

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
    import json

    told = [f"{key} = {json.dumps(value)}" for key, value in condition.changes.items()]
    error = [f"{key} = {json.dumps(value)} (the plant alone)" for key, value in condition.truth_only.items()]
    return "; ".join(told + error)


def applicable_metrics(names, scenario) -> list[str]:
    """The metrics of ``names`` that apply to ``scenario``: an estimation metric of a
    plant variable its observer does not estimate is left out; a name that is no metric,
    or a signal the plant does not have, is refused (ValueError)."""
    from lookout.studies import metrics as metric_module

    truth = {signal.name for signal in scenario.record_signals.truth}
    found = []
    for name in names:
        try:
            metric_module.resolve([name], scenario)
        except ValueError:
            kind, _, signal = name.partition(":")
            if metric_module.KINDS.get(kind, ("",))[0] == "estimate" and signal in truth:
                continue  # the plant has it; this observer does not estimate it
            raise
        found.append(name)
    return found


@dataclass(frozen=True)
class ObserverCampaign:
    """The campaign of one observer of a benchmark."""

    name: str
    campaign: Campaign
    told: str  # what the observer is given: its design, values and the models it takes


def told(document: dict, table: dict) -> str:
    """What the observer of ``document`` (spelled out) is given, in words: its design
    rule, the values its spec ``table`` sets, and the models it takes from the
    composition (the plant's, the sensor's)."""
    kind = registry.kind("observer", table["kind"])
    design = document["observer"].get("design")
    given = [p.name for p in kind.parameters(design) if p.sort == "value" and p.name in table]
    own = [p.name for p in kind.parameters(design) if p.sort == "part" and p.name in table]
    models = [path.split(".", 1)[1] for path in model_pins(document)]
    parts = [f"design rule {design}"] if design and design != "gains" else []
    parts.append("sets " + ", ".join(given) if given else "its defaults")
    if own:
        parts.append("its own " + ", ".join(own))
    if models:
        parts.append("models from the composition: " + ", ".join(models))
    return "; ".join(parts)


def observer_campaign(benchmark: Benchmark, size_name: str, name: str) -> ObserverCampaign:
    """The campaign of observer ``name`` (a key of the spec's observers) at ``size_name``."""
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
    try:
        metrics = applicable_metrics(spec.metrics, composition.scenario)
    except ValueError as error:
        raise benchmark.located(("metrics",), str(error)) from None
    if not metrics:
        raise benchmark.located(("metrics",), f"no metric applies to observer {name} (it estimates {', '.join(s.name for s in composition.scenario.record_signals.estimate)})")
    cases = []
    for index, condition in enumerate(spec.conditions):
        try:
            cases.append(condition_case(benchmark, full, condition))
        except (CompositionError, ValueError) as error:
            raise benchmark.located(("conditions", index), f"{condition.name}: {error}") from None
    seeds = size.seeds
    document = {
        "scenario": full,
        "seeds_per_point": seeds,
        "seed": spec.seed,
        "chunk_runs": seeds,
        "metrics": metrics,
        "sweep": {"kind": "grid", "axes": [{"name": "condition", "labels": [c.name for c in spec.conditions], "cases": cases}]},
    }
    if size.after is not None:
        document["after"] = size.after
    if spec.divergence is not None:
        document["divergence"] = spec.divergence.model_dump()
    try:
        campaign = campaign_from_document(document, f"{benchmark.source} [observers.{name}]")
    except FileError as error:
        raise _condition_error(benchmark, name, str(error)) from None
    return ObserverCampaign(name, campaign, told(full, spec.observers[name]))


def _condition_error(benchmark: Benchmark, observer: str, message: str) -> FileError:
    """A campaign's refusal of a condition's case, located at the spec's condition (the
    campaign's ``sweep.axes[0].cases`` is the benchmark's ``conditions``)."""
    import re

    _, _, detail = message.partition(".cases: ")
    if not detail:
        return FileError(message)
    names = [c.name for c in benchmark.spec.conditions]
    named = re.match(r"case '(.*?)'(?: makes no scenario)?: (.*)", detail)
    missing = re.search(r"no setting '(.*?)'", detail)
    if named and named.group(1) in names:
        index, detail = names.index(named.group(1)), named.group(2)
    elif missing:
        index = next((i for i, c in enumerate(benchmark.spec.conditions) if missing.group(1) in {**c.changes, **c.truth_only}), 0)
    else:
        return FileError(message)
    return benchmark.located(("conditions", index), f"{names[index]} (observer {observer}): {detail}")


def check_outages(benchmark: Benchmark, size_name: str) -> None:
    """Refuse (at the condition) an outage that does not end before the run does: the
    recovery after it could not be measured."""
    size = getattr(benchmark.spec, size_name)
    for index, condition in enumerate(benchmark.spec.conditions):
        start = condition.changes.get("sensor.outage_start", size.outage_start)
        length = condition.changes.get("sensor.outage_duration", 0.0)
        if benchmark.spec.outage_signals and isinstance(length, (int, float)) and length > 0 and isinstance(start, (int, float)) \
                and start + length >= size.duration:
            raise benchmark.located(("conditions", index), f"{condition.name}: the outage ends at {start + length:g} s, not before the {size_name} run "
                                    f"does ({size.duration:g} s): the recovery after it cannot be measured; start it earlier ({size_name}.outage_start)")


def campaigns(benchmark: Benchmark, size_name: str, observers: list[str] | None = None) -> list[ObserverCampaign]:
    """Every observer's campaign (or those named), checked before anything runs."""
    check_outages(benchmark, size_name)
    names = list(benchmark.spec.observers) if observers is None else observers
    return [observer_campaign(benchmark, size_name, name) for name in names]


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

    def store(self, name: str) -> Path:
        return self.folder / f"{name}.zarr"


def prepare(benchmark: Benchmark, size_name: str, out: Path, observers: list[str] | None = None) -> Prepared:
    """Check the benchmark before anything runs: every observer's campaign is built and
    validated, and each store in ``out/<spec name>/`` holds that campaign or nothing (a
    store of other settings is refused, naming it). Writes nothing."""
    from lookout.studies.store import CampaignStore, differences

    folder = Path(out) / benchmark.name
    prepared = Prepared(benchmark, size_name, folder, campaigns(benchmark, size_name, observers))
    for each in prepared.campaigns:
        path = prepared.store(each.name)
        store = CampaignStore(path)
        try:
            store.holds(each.campaign)
        except ValueError as error:
            held = store.campaign_document()
            if held is None:
                raise ValueError(f"--out: {error}") from None
            changed = [_short(_spec_words(line)) for line in differences(held, each.campaign.document())]
            raise ValueError(f"--out: {path} holds observer {each.name}'s benchmark with other settings ({'; '.join(changed[:3])}"
                             f"{f'; and {len(changed) - 3} more' if len(changed) > 3 else ''}): give another --out, or remove {path}") from None
    return prepared


#: A campaign's keys as a benchmark spec names them.
_SPEC_WORDS = (("sweep.axes[0].labels", "condition names"), ("sweep.axes[0].cases", "conditions"), ("seeds_per_point", "seeds"),
               ("scenario.simulation.duration", "duration"), ("scenario.sensor.outage_start", "outage_start"), ("scenario.observer", "observer"))


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
    stores: dict[str, Path]
    costs: dict[str, float]
    told: dict[str, str]
    seconds: float
    written: dict[str, Path]


def run_benchmark(prepared: Prepared, *, workers: int | None = None, scheduler: str | None = None,
                  say: Callable[[str], None] = print, progress: Callable[[str, int, int], None] | None = None, command: str = "") -> Result:
    """Run a prepared benchmark: its campaigns (one per observer, into
    ``<folder>/<observer>.zarr``, each resumed when its store holds it), then each
    observer's cost, then the results (:func:`lookout.studies.benchmark_report.write_results`)
    and each observer's campaign report. Local dask workers (``workers``; 0: this
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
    stores = {}
    try:
        for index, each in enumerate(prepared.campaigns):
            say(f"[{index + 1}/{len(prepared.campaigns)}] {each.name}: {len(each.campaign.chunks())} chunks "
                f"({len(each.campaign.points)} conditions x {each.campaign.settings.seeds_per_point} seeds)")
            path = prepared.store(each.name)
            report = None if progress is None else (lambda done, total, name=each.name: progress(name, done, total))
            run_campaign(each.campaign, path, workers=0 if address is None else None, scheduler=address, say=lambda text: None, progress=report)
            stores[each.name] = path
    finally:
        if cluster is not None:
            cluster.close()
    costs = {}
    for each in prepared.campaigns:
        costs[each.name] = observer_cost(each.campaign.base.build(), prepared.benchmark.spec.seed)
        say(f"{each.name}: {costs[each.name]:.3g} us per sample (the observer alone, one run)")
    told_by = {each.name: each.told for each in prepared.campaigns}
    ds = benchmark_report.collect(stores, costs, told_by, metrics=list(prepared.benchmark.spec.metrics), title=prepared.benchmark.spec.title, command=command,
                                  changes={c.name: describe_condition(c) for c in prepared.benchmark.spec.conditions})
    reports = {name: write_report(path, prepared.folder / "reports" / f"{name}.html") for name, path in stores.items()}
    written = benchmark_report.write_results(ds, prepared.folder, reports)
    return Result(prepared.folder, stores, costs, told_by, time.perf_counter() - start, written)
