"""Planning and running a benchmark: each observer's campaigns, checked before anything
runs (:func:`plan`, :func:`prepare`, :func:`check_resources`), then run, each
observer's cost measured, and the results written (:func:`run_benchmark`).

A model error must not reach the observer's model: for a ``truth_only`` condition, the
benchmark gives the observer, explicitly, each model it would otherwise take from the
plant before it changes the plant (:func:`model_pins`).
"""

from __future__ import annotations

import copy
import json
import math
import re
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lookout.scenario import registry
from lookout.scenario._toml import FileError
from lookout.scenario.composition import MODEL_ROLES, CompositionError, compose, key_text, set_path
from lookout.studies.benchmark.spec import Benchmark, Condition, base_document
from lookout.studies.campaign import Campaign, campaign_from_document

if TYPE_CHECKING:
    from lookout.sim import Scenario

#: Repeats of the timed observer-only pass; the best is reported.
COST_REPEATS = 3

# ------------------------------------------------------------------ the campaigns


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
    return {here: table for here, table in pins.items() if table is not None}  # every one, after the check above


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
            assert parameter.role is not None  # a part names its role
            here = f"{path}.{parameter.name}"
            if parameter.name in table:
                if isinstance(table[parameter.name], dict):
                    walk(parameter.role, table[parameter.name], here)
                continue
            if parameter.role in MODEL_ROLES:
                if parameter.role not in document:  # a sensor suite ([sensors]): no one table to pin
                    continue
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


def metric_fit(names: Iterable[str], scenario: Scenario) -> tuple[list[str], dict[str, str]]:
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


def observer_cost(scenario: Scenario, seed: int, repeats: int = COST_REPEATS) -> float:
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
        per_worker, count = (min(limit for limit in limits if limit is not None) if limits and all(limits) else None), max(1, len(info))
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
