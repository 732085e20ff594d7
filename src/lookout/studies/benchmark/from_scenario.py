"""A scenario file as a benchmark (what ``--spec FILE`` makes of a scenario file).

Its plant, sensor and sea, every registered observer kind that composes on them, its
own observer as given, and the conditions of the shipped benchmark of its plant kind
(model errors relative to its own model), or generic ones: :func:`scenario_benchmark`,
in the steps below it.
"""

from __future__ import annotations

import copy
import functools
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from lookout.scenario import registry
from lookout.scenario._toml import FileError
from lookout.scenario.composition import (
    MODEL_ROLES,
    Composition,
    CompositionError,
    SimulationSettings,
    compose,
    get_path,
    merge,
    preset_document,
)
from lookout.scenario.file import describe, located
from lookout.scenario.settings import validate_strictly
from lookout.studies.benchmark.spec import (
    BENCHMARK_SENSOR,
    BENCHMARK_SIMULATION,
    SIZES,
    Benchmark,
    BenchmarkSpec,
    Condition,
    Size,
    base_document,
    check_spec,
    shipped_benchmark,
    shipped_plants,
)

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


#: A refusal located in the scenario file: ``fail(location, message)``.
_Fail = Callable[[tuple, str], FileError]


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
    fail: _Fail = functools.partial(located, source, text)
    merged = _expanded(document, fail)
    own = _own_composition(merged, fail)
    simulation = _simulation(merged, source, text)
    plant_kind = merged["plant"].get("kind")
    shipped = shipped_benchmark(plant_kind) if plant_kind in shipped_plants() else None
    notes: list[str] = []
    base = _base(merged)
    own_controller = copy.deepcopy(merged.get("controller", {"kind": "none"}))
    own_reference = copy.deepcopy(merged.get("reference", {"kind": "none"}))
    sizes = _sizes(shipped, simulation)
    # what base_document needs of a spec, before the spec exists: the probes' benchmark
    probe = Benchmark(BenchmarkSpec.model_construct(seed=simulation.seed, outage_signals=()), path.stem, source, text, base, (), True)
    trial = functools.partial(_trial, probe, sizes["quick"], fail)

    # ---- the observers: every registered kind that composes on the file's plant and sensor
    shipped_plant = _shipped_plant(shipped)
    tables = _observer_tables(base, shipped)
    first = _first_composing(tables, own, trial, fail)
    reference = first or own
    assert reference is not None  # _first_composing refuses a file where none composes and it has no observer of its own
    same_model = shipped is not None and shipped_plant is not None and _model_parts(reference.document["plant"]) == _model_parts(shipped_plant)
    if same_model:  # the shipped tables were chosen for this very model: take them whole
        assert shipped is not None
        _take_shipped_tables(tables, shipped)
    observers, built, skipped = _observers(merged, own, tables, trial, fail, notes)

    # ---- the controller: an input stays; a loop on the estimate becomes a condition
    controller_kind = own_controller.get("kind", "none")
    closes_loop = _closes_loop(own, controller_kind)
    tracked: list[str] = []
    if closes_loop:
        tracked = _tracked(probe, sizes["quick"], observers, own_controller, own_reference)
        notes.append(_open_loop(base, shipped, plant_kind, controller_kind))

    # ---- the conditions
    measured = [s.name for s in reference.scenario.sensor.measurement_layout.signals]
    if shipped is not None:
        outage_signals, conditions, metrics, divergence = _shipped_conditions(shipped, reference.document, measured, same_model, notes)
    else:
        outage_signals, conditions, metrics, divergence = _generic_conditions(reference, measured, built, sizes, simulation.sample_period)
    if not outage_signals:
        sizes = {name: size.model_copy(update={"outage_start": None}) for name, size in sizes.items()}
        metrics = [m for m in metrics if m.partition(":")[0] not in ("outage_drift", "recovery_time")]
    if closes_loop:
        conditions.append(Condition(name=f"closed loop ({controller_kind})", changes={"controller": own_controller, "reference": own_reference}))
        metrics += [f"rms_tracking:{name}" for name in tracked if f"rms_tracking:{name}" not in metrics]

    notes.insert(0, _summary(source, document, plant_kind, shipped, len(observers), sizes, simulation.seed))
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


# ------------------------------------------------------------------ its steps: the file


def _expanded(document: dict, fail: _Fail) -> dict:
    """The file's document with its preset expanded; refused without a plant or a
    sensor table."""
    try:
        merged = merge(preset_document(document["preset"]), document) if "preset" in document else copy.deepcopy(document)
    except CompositionError as error:
        raise fail(error.location, error.reason) from None
    for role in ("plant", "sensor"):
        if not isinstance(merged.get(role), dict):
            raise fail((role,), f"missing table (a scenario needs a plant and a sensor; `lookout components {role}` lists the kinds)")
    return merged


def _own_composition(merged: dict, fail: _Fail) -> Composition | None:
    """The file composed as ``lookout run`` takes it, when it has an observer (None
    without one); refused where it does not compose."""
    if "observer" not in merged:
        return None
    try:
        return compose(merged)  # the file as `lookout run` takes it
    except CompositionError as error:
        raise fail(error.location, error.reason) from None


def _simulation(merged: dict, source: str, text: str | None) -> SimulationSettings:
    """The file's ``[simulation]`` settings, validated (its seed, duration and time grid)."""
    try:
        return validate_strictly(SimulationSettings, merged.get("simulation", {}))
    except ValidationError as error:
        raise FileError(describe(error, source, text, ("simulation",))) from None


def _base(merged: dict) -> dict:
    """The benchmark's base scenario: the file without its observer and preset, and
    without the settings of ``[simulation]`` and the sensor that the benchmark sets."""
    base = {key: copy.deepcopy(value) for key, value in merged.items() if key not in ("observer", "preset")}
    base["simulation"] = {key: value for key, value in base.get("simulation", {}).items() if key not in BENCHMARK_SIMULATION}
    base["sensor"] = {key: value for key, value in base["sensor"].items() if key not in BENCHMARK_SENSOR}
    return base


def _sizes(shipped: Benchmark | None, simulation: SimulationSettings) -> dict[str, Size]:
    """The ``full`` and ``quick`` sizes: the shipped benchmark's, their times on the
    file's sample grid, or generic ones (the file's duration, and half of it)."""
    period = simulation.sample_period
    if shipped is not None:
        sizes = {name: getattr(shipped.spec, name) for name in SIZES}
        return {
            name: size.model_copy(
                update={
                    "duration": _on_grid(size.duration, period),
                    "outage_start": None if size.outage_start is None else _on_grid(size.outage_start, period),
                }
            )
            for name, size in sizes.items()
        }
    sizes = {}
    for name, fraction in (("full", 1.0), ("quick", 0.5)):
        duration = _on_grid(simulation.duration * fraction, period)
        sizes[name] = Size(duration=duration, seeds=GENERIC_SEEDS[name], outage_start=_on_grid(duration * GENERIC_OUTAGE[0], period))
    return sizes


# ------------------------------------------------------------------ its steps: the observers


def _trial(probe: Benchmark, size: Size, fail: _Fail, table: dict) -> Composition | CompositionError:
    """Observer ``table`` composed open loop on the file's base at ``size``, or why it
    does not compose; a refusal of the file's own plant, sensor, simulation or actuator
    refuses the file."""
    try:
        return compose(base_document(probe, size, table, open_loop=True))
    except CompositionError as error:
        if error.location[:1] in (("plant",), ("sensor",), ("simulation",), ("actuator",)):
            raise fail(error.location, error.reason) from None
        return error


def _shipped_plant(shipped: Benchmark | None) -> dict | None:
    """The shipped benchmark's plant table, spelled out (None without a shipped benchmark)."""
    if shipped is None:
        return None
    shipped_first = next(iter(shipped.spec.observers.values()))
    return compose(base_document(shipped, shipped.spec.quick, shipped_first)).document["plant"]


def _observer_tables(base: dict, shipped: Benchmark | None) -> dict[str, dict]:
    """Kind -> table of every registered observer kind (of plugin files, those the
    file names): what the kind requires from the shipped benchmark's table of that
    kind, or from its first reproduction case (:func:`required_table`)."""
    tables: dict[str, dict] = {}
    registry.load_entry_points()  # every observer kind means installed packages' too (a listing)
    for each in registry.kinds("observer", plugins=base.get("plugins", [])):
        given = next((t for t in shipped.spec.observers.values() if t["kind"] == each.name), None) if shipped is not None else None
        tables[each.name] = required_table(each.name, given)
    return tables


def _first_composing(tables: dict[str, dict], own: Composition | None, trial, fail: _Fail) -> Composition | None:
    """The composition of the first of ``tables`` that composes; refused when none does
    and the file has no observer of its own (the first two reasons given)."""
    first = next((result for result in map(trial, tables.values()) if not isinstance(result, CompositionError)), None)
    if first is None and own is None:
        reasons = "; ".join(f"{kind}: {trial(table)}" for kind, table in list(tables.items())[:2])
        raise fail((), f"no registered observer composes on its plant and sensor ({reasons}; ...)")
    return first


def _take_shipped_tables(tables: dict[str, dict], shipped: Benchmark) -> None:
    """Replace, in ``tables``, each kind's table by the shipped benchmark's own (the
    first of a kind there wins)."""
    for table in reversed(list(shipped.spec.observers.values())):
        tables[table["kind"]] = copy.deepcopy(table)


def _observers(
    merged: dict, own: Composition | None, tables: dict[str, dict], trial, fail: _Fail, notes: list[str]
) -> tuple[dict[str, dict], dict[str, Composition], list[str]]:
    """(name -> table, name -> open-loop composition, skipped kinds in one line each) of
    the observers that compose: the file's own (``KIND-as-given``) first, unless it is
    its kind's table exactly, then each of ``tables``. A note says when the file's own
    does not compose open loop; refused when no observer composes."""
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
    return observers, built, skipped


# ------------------------------------------------------------------ its steps: the controller


def _closes_loop(own: Composition | None, controller_kind: str) -> bool:
    """Whether the file's controller reads the observer's estimate: as its composition
    says, or (a file without an observer) unless its kind is an input."""
    if own is not None:
        return bool(tuple(own.scenario.controller.estimate_needs))
    return controller_kind not in OPEN_LOOP_CONTROLLERS


def _tracked(probe: Benchmark, size: Size, observers: dict[str, dict], controller: dict, reference: dict) -> list[str]:
    """What the file's loop tracks: each truth with a ``<name>_desired`` reference, in
    the first composition of an observer with the loop closed (none if none composes)."""
    for name in observers:
        try:
            loop = compose({**base_document(probe, size, observers[name]), "controller": controller, "reference": reference})
        except CompositionError:
            continue
        truths = {s.name for s in loop.scenario.record_signals.truth}
        return [
            s.name.removesuffix("_desired")
            for s in loop.scenario.record_signals.reference
            if s.name.endswith("_desired") and s.name.removesuffix("_desired") in truths
        ]
    return []


def _open_loop(base: dict, shipped: Benchmark | None, plant_kind: str, controller_kind: str) -> str:
    """Open the loop of ``base`` (in place): the shipped benchmark's input of the plant
    kind, or none, and no reference. Returns the note that says so."""
    open_input = copy.deepcopy(shipped.base.get("controller", {"kind": "none"})) if shipped is not None else {"kind": "none"}
    base["controller"], base["reference"] = open_input, {"kind": "none"}
    return (
        f"your controller ({controller_kind}) reads the observer's estimate: the benchmark runs open loop "
        f"({'the shipped ' + plant_kind + ' benchmark input, ' + open_input['kind'] if shipped is not None else 'no input'}), "
        f"and your loop is the condition 'closed loop ({controller_kind})'"
    )


# ------------------------------------------------------------------ its steps: the conditions


def _shipped_conditions(
    shipped: Benchmark, user: dict, measured: list[str], same_model: bool, notes: list[str]
) -> tuple[tuple[str, ...], list[Condition], list[str], Any]:
    """(outage signals, conditions, metrics, divergence rule) of the shipped benchmark
    for the file's composition ``user``: its outage where the file's sensor measures
    its signals, each condition whose keys the file has, model errors as the same factor
    on the file's own model (:func:`_relative_error`) unless ``same_model``. What is
    left out is said in ``notes``."""
    conditions: list[Condition] = []
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
    return outage_signals, conditions, list(shipped.spec.metrics), shipped.spec.divergence


def _generic_conditions(
    reference: Composition, measured: list[str], built: dict[str, Composition], sizes: dict[str, Size], period: float
) -> tuple[tuple[str, ...], list[Condition], list[str], None]:
    """(outage signals, conditions, metrics, divergence rule: none) of a plant kind
    without a shipped benchmark, for the file's composition ``reference``: a baseline,
    10 % and 50 % lost samples (where the sensor drops samples), an outage of the first
    measured signal, :data:`GENERIC_MODEL_ERROR` up and down on each mass, damping,
    inertia and friction of the plant's model; the error of each truth some observer
    estimates, a settling time, and the outage's drift and recovery."""
    user = reference.document
    truths = [s.name for s in reference.scenario.record_signals.truth]
    conditions: list[Condition] = []
    outage_signals = tuple(measured[:1])
    conditions.append(Condition(name="baseline"))
    if "dropout_probability" in user["sensor"]:
        conditions += [Condition(name=f"{p} % lost samples", changes={"sensor.dropout_probability": p / 100}) for p in (10, 50)]
    sensor_periods = np.atleast_1d(np.asarray(reference.scenario.sensor.sample_period, dtype=float))
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
    return outage_signals, conditions, metrics, None


# ------------------------------------------------------------------ its steps: the summary


def _summary(source: str, document: dict, plant_kind: str, shipped: Benchmark | None, observers: int, sizes: dict[str, Size], seed: int) -> str:
    """The first note: what the benchmark took from the file and from where, and what
    the file sets that the benchmark sets otherwise (a preset's keys are not the file's)."""
    benchmark_values = {"duration": sizes["full"].duration, "runs": 1, "seed": seed, "record_every": 1, "observer_mode": "sampled"}
    own_simulation = document.get("simulation", {}) if isinstance(document.get("simulation"), dict) else {}
    unused = [
        f"simulation.{key} = {json.dumps(value)}"
        for key, value in own_simulation.items()
        if key in benchmark_values and value != benchmark_values[key]
    ]
    unused += [f"sensor.{key}" for key in document.get("sensor", {}) if key in BENCHMARK_SENSOR]
    origin = f"the shipped {plant_kind} benchmark's" if shipped is not None else "generic"
    return (
        f"{source}: a scenario file: its plant ({plant_kind}), sensor and sea; {observers} observers that compose on them; "
        f"{origin} conditions and sizes ({sizes['full'].duration:g} s x {sizes['full'].seeds} seeds, quick {sizes['quick'].duration:g} s x "
        f"{sizes['quick'].seeds})" + (f"; not used: {', '.join(unused)}" if unused else "")
    )
