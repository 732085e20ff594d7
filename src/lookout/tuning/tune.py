"""Gains that perform and stay proven: tuning by gradient through the simulation.

The objective is the mean, over training seeds, of a weighted sum of campaign metrics
(:mod:`lookout.scenario.metrics`) that are differentiable in the gains: RMS estimation,
tracking or input values (``rms_error:position + 0.01*rms_input:force``). It is computed
by the engine's own batch (:func:`lookout.sim.summarize_batch`, the metrics accumulated
in the scan), and ``jax.value_and_grad`` differentiates it through the whole simulation
with respect to the family's unconstrained parameters theta
(:mod:`lookout.tuning.families`): every theta gives gains inside the conditions that
the family writes as a parametrization. optax's Adam moves theta; a step whose gains
fail a condition that can only be checked (SPR by its KYP certificate), or whose
objective is not finite, is halved until it passes (at most :data:`BACKTRACKS` times),
and the tuner stops when none passes twice in a row. So every gain set it returns, including the
start, satisfies every condition of its family as the ``lookout design`` command
checks it.

Held-out seeds (after the training seeds) measure the start and the tuned gains on
runs the tuner never saw.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lookout.tuning.families import Family, build, family_of

if TYPE_CHECKING:
    from pathlib import Path

    from jax import Array
    from jax.typing import ArrayLike

    from lookout.analysis.conditions import Report
    from lookout.scenario.composition import Composition
    from lookout.scenario.metrics import Metric
    from lookout.sim import Scenario

#: Metric kinds an objective may use: smooth in the gains (an RMS over the window).
DIFFERENTIABLE = ("rms_error", "rms_tracking", "rms_input")
#: Halvings of a step that fails a condition before the tuner stops.
BACKTRACKS = 8


@dataclass(frozen=True)
class Objective:
    """A weighted sum of metrics: ``(weight, metric name)`` terms."""

    terms: tuple[tuple[float, str], ...]

    @property
    def text(self) -> str:
        return " + ".join(name if weight == 1.0 else f"{weight:g}*{name}" for weight, name in self.terms)


def parse_objective(text: str, scenario: Scenario) -> tuple[Objective, list[Metric]]:
    """``"rms_error:position + 0.01*rms_error:velocity"`` for ``scenario``: the objective
    and its resolved metrics; a ValueError names a term that is not a differentiable
    metric of the scenario."""
    from lookout.scenario import metrics as metric_module

    terms = []
    for part in (p.strip() for p in text.split("+")):
        match = re.fullmatch(r"(?:([0-9.eE+-]+)\s*\*\s*)?([a-z_]+:[a-z_]+)", part)
        if not match:
            raise ValueError(f"--objective: {part!r} is not a term (write KIND:SIGNAL or WEIGHT*KIND:SIGNAL, joined by +)")
        weight = float(match.group(1)) if match.group(1) else 1.0
        if not (math.isfinite(weight) and weight > 0):
            raise ValueError(f"--objective: the weight of {match.group(2)} must be a finite positive number; got {weight:g}")
        kind = match.group(2).partition(":")[0]
        if kind not in DIFFERENTIABLE:
            raise ValueError(f"--objective: {match.group(2)} is not smooth in the gains; use one of {', '.join(DIFFERENTIABLE)}")
        terms.append((weight, match.group(2)))
    try:
        metrics = metric_module.resolve([name for _, name in terms], scenario)
    except ValueError as error:
        raise ValueError(f"--objective: {error}") from None
    return Objective(tuple(terms)), metrics


def _objective_function(scenario, family: Family | None, objective: Objective, metrics, after: float | None):
    """gains, keys -> (objective, per-run values of each metric); with ``family`` None,
    scenario, keys -> the same."""
    from lookout.scenario import metrics as metric_module
    from lookout.sim import summarize_batch

    time_grid = np.asarray(scenario.record_times)
    plan = metric_module.summary(scenario.record_signals, time_grid, metrics, after=after)
    weights = [weight for weight, _ in objective.terms]

    def value(gains, keys):
        tuned = gains if family is None else build(family, scenario, gains)
        accumulated, series = summarize_batch(tuned, keys, plan)
        out = plan.finish(accumulated, series, jnp.asarray(time_grid))
        per_run = {m.name: out[m.variable] for m in metrics}
        total = sum(w * jnp.mean(per_run[m.name]) for w, m in zip(weights, metrics))
        return total, per_run

    return value


@dataclass
class Step:
    """One step of the tuner: the objective at its start, and what became of it."""

    step: int
    objective: float
    gains: list
    halvings: int
    accepted: bool


@dataclass
class Tuning:
    """What :func:`tune` found."""

    family: Family
    objective: Objective
    start_gains: tuple
    gains: tuple
    report_before: Report  # the conditions of the start
    steps: list[Step] = field(default_factory=list)
    stopped: str = ""
    seconds: float = 0.0
    report_after: Report | None = None  # the conditions of the tuned gains, once the steps are done
    held_out: dict = field(default_factory=dict)  # metric -> {"start": per run, "tuned": per run}
    units: dict = field(default_factory=dict)  # metric -> its units
    train_seeds: list = field(default_factory=list)
    test_seeds: list = field(default_factory=list)
    notes: list = field(default_factory=list)  # components left as they are, a start moved inside the conditions
    given_gains: tuple | None = None  # the scenario's own gains, when outside the conditions
    report_given: Report | None = None  # and their conditions


def tune(
    scenario: Scenario,
    objective_text: str,
    *,
    train_seeds: list[int],
    test_seeds: list[int],
    steps: int = 30,
    learning_rate: float = 0.1,
    after: float | None = None,
    components: tuple[str, ...] | None = None,
    say: Callable[[str], None] = print,
) -> Tuning:
    """Tune the gains of ``scenario``'s observer and controller (their family,
    :func:`~lookout.tuning.families.family_of`; ``components`` chooses among them) for the
    objective over ``train_seeds``; measure the scenario's own gains, the start (the
    nearest gains inside the conditions when its own are outside) and the result on
    ``test_seeds``."""
    import optax

    from lookout.sim import keys_of_seeds

    started = time.perf_counter()
    objective, metrics = parse_objective(objective_text, scenario)
    family, start, notes = family_of(scenario, components)
    for note in notes:
        say(note)
    report_before = family.check(build(family, scenario, start))
    given = None if all(np.array_equal(np.asarray(a, float), np.asarray(b, float)) for a, b in zip(start, family.current(scenario))) else scenario
    value = _objective_function(scenario, family, objective, metrics, after)
    train = keys_of_seeds(list(train_seeds))
    theta = jnp.asarray(family.theta(start))
    with_runs = compile_within_memory(value_and_gradient(value, family), theta, train)

    def value_and_grad(theta, keys):
        (total, _), gradient = with_runs(theta, keys)
        return total, gradient

    evaluate = eqx.filter_jit(value)
    optimizer = optax.adam(learning_rate)
    state = optimizer.init(theta)
    result = Tuning(
        family,
        objective,
        start,
        start,
        train_seeds=list(train_seeds),
        test_seeds=list(test_seeds),
        report_before=report_before,
        units={m.name: m.units for m in metrics},
        notes=notes,
    )
    if given is not None:
        result.given_gains = family.current(scenario)
        result.report_given = family.check(scenario)

    def finite(total, gradient) -> bool:
        return math.isfinite(float(total)) and bool(jnp.all(jnp.isfinite(gradient)))

    current, gradient = value_and_grad(theta, train)
    if not finite(current, gradient):
        raise ValueError("the objective or its gradient is not finite at the starting gains (a run diverges); start from gains that keep it finite")
    refused = 0
    for step in range(steps):
        updates, new_state = optimizer.update(gradient, state)
        halvings, accepted = 0, False
        while True:  # halve until the conditions hold and the objective stays finite
            candidate = theta + updates
            if family.check(build(family, scenario, family.gains(candidate))).holds:
                candidate_value, candidate_gradient = value_and_grad(candidate, train)
                accepted = finite(candidate_value, candidate_gradient)
            if accepted or halvings == BACKTRACKS:  # kept, or the step and its BACKTRACKS halvings all tried
                break
            halvings += 1
            updates = updates / 2.0
        result.steps.append(Step(step, float(current), [np.asarray(g).tolist() for g in family.gains(theta)], halvings, accepted))
        say(
            f"step {step + 1}/{steps}: objective {float(current):.6g}"
            + (f" ({halvings} halving{'s' * (halvings != 1)} to stay inside the conditions)" if halvings and accepted else "")
            + ("" if accepted else f"; neither the step nor its {halvings} halvings kept the conditions")
        )
        if accepted:
            theta, state, current, gradient = candidate, new_state, candidate_value, candidate_gradient
            refused = 0
            continue
        # Adam's momentum points across the boundary: forget it and try again from here
        refused += 1
        if refused == 2:
            result.stopped = f"step {step + 1}: twice in a row, neither the step nor its {BACKTRACKS} halvings kept the conditions (the gains are at their boundary)"
            break
        state = optimizer.init(theta)
    result.steps.append(Step(len(result.steps), float(current), [np.asarray(g).tolist() for g in family.gains(theta)], 0, True))
    result.gains = tuple(np.asarray(g, dtype=float) for g in family.gains(theta))
    result.report_after = family.check(build(family, scenario, result.gains))
    test = keys_of_seeds(list(test_seeds))

    def runs_of(parameters):
        """Each held-out run's metrics: through the compiled gradient when the held-out batch
        has the training batch's size (no second compilation; its gradient is dropped)."""
        if len(test_seeds) == len(train_seeds):
            return with_runs(parameters, test)[0][1]
        return evaluate(family.gains(parameters), test)[1]

    before_runs = runs_of(jnp.asarray(family.theta(start)))
    after_runs = runs_of(theta)
    result.held_out = {
        name: {"start": np.asarray(before_runs[name]).tolist(), "tuned": np.asarray(after_runs[name]).tolist()} for name in before_runs
    }
    if given is not None:  # the file's own gains, outside the conditions
        given_runs = eqx.filter_jit(_objective_function(scenario, None, objective, metrics, after))(scenario, test)[1]
        for name in result.held_out:
            result.held_out[name] = {"given": np.asarray(given_runs[name]).tolist(), **result.held_out[name]}
    result.seconds = time.perf_counter() - started
    return result


def value_and_gradient(
    value: Callable[[Sequence[ArrayLike], Array], tuple[Array, dict[str, Array]]], family: Family
) -> Callable[[Array, Array], tuple[tuple[Array, dict[str, Array]], Array]]:
    """``theta, keys -> ((objective, per-run metrics), gradient in theta)`` of an objective
    ``value`` (:func:`_objective_function`), under ``eqx.filter_jit``: the program
    :func:`tune` compiles. Built here once, so that a check of the gradient compiles the
    very program the tuner runs (the persistent compilation cache then holds one copy)."""
    return eqx.filter_jit(jax.value_and_grad(lambda theta, keys: value(family.gains(theta), keys), has_aux=True))


def compile_within_memory(function: Callable[..., Any], theta: Array, keys: Array, *, available: float | None = None) -> Callable[..., Any]:
    """``function`` (an ``eqx.filter_jit``) compiled for ``theta`` and ``keys``, refused
    (ValueError naming --train-seeds) when the program's working memory, as XLA's memory
    analysis of the compiled program states it, exceeds the memory available.

    Reverse mode through the scan keeps every sample's residuals, whose size depends on
    the models (0.50 GB for 32 runs x 1500 s of the Northern Clipper's passive observer,
    28 GB for 32 runs x 120 s of Cybership II at a 0.01 s plant step): measured on the
    program, not estimated."""
    from lookout._resources import refuse_unless_it_fits
    from lookout.studies.execute import WORKER_BASE_BYTES

    compiled = function.lower(theta, keys).compile()  # type: ignore[attr-defined]  # eqx.filter_jit's wrapper has lower(); equinox declares it a plain Callable
    analysis = compiled.compiled.memory_analysis()
    if analysis is not None:
        need = analysis.temp_size_in_bytes + analysis.argument_size_in_bytes + analysis.output_size_in_bytes + WORKER_BASE_BYTES
        refuse_unless_it_fits(
            need, f"--train-seeds: a gradient over {int(keys.shape[0])} runs", "use fewer training seeds or a shorter duration", available=available
        )
    return compiled


def write_results(result: Tuning, composition: Composition, folder: str | Path, *, source: str, command: str) -> dict[str, Path]:
    """Write into ``folder``: ``tuned.toml`` (the scenario with the tuned gains, ready for
    ``lookout run``), ``tuning.json`` (objective, seeds, steps, gains, every condition
    before and after, held-out values), ``training.png`` and ``held_out.png``."""
    import copy
    import json
    import textwrap
    from pathlib import Path

    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    from lookout._json import json_safe
    from lookout.scenario.composition import compose, set_path
    from lookout.scenario.file import CompositionSpec, save

    if result.report_after is None:
        raise ValueError("the tuning has no conditions of its tuned gains: its steps were not done")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    document = copy.deepcopy(composition.document)
    for key, gains in zip(result.family.keys, result.gains):
        table, name = key.split(".", 1)
        document[table][name] = np.asarray(gains).tolist()
    tuned = compose(document)
    if "design" in document["observer"]:
        set_path(document, "observer.design", document["observer"]["design"])
    scenario_path = save(
        CompositionSpec(tuned, str(folder / "tuned.toml")),
        folder / "tuned.toml",
        header=f"lookout scenario: {source} with the gains {command} found.\nRun it with: lookout run tuned.toml --out DIR",
    )
    medians = {name: {which: float(np.median(v)) for which, v in values.items()} for name, values in result.held_out.items()}
    given = {} if result.given_gains is None else {"given": result.given_gains}
    summary = {
        "command": command,
        "scenario": source,
        "family": result.family.name,
        "objective": result.objective.text,
        "train_seeds": result.train_seeds,
        "test_seeds": result.test_seeds,
        "stopped": result.stopped or f"after {len(result.steps) - 1} steps",
        "seconds": result.seconds,
        "notes": result.notes,
        "gains": {
            key: {
                **{which: np.asarray(g[i]).tolist() for which, g in given.items()},
                "start": np.asarray(a).tolist(),
                "tuned": np.asarray(b).tolist(),
            }
            for i, (key, a, b) in enumerate(zip(result.family.keys, result.start_gains, result.gains))
        },
        "steps": [{"step": s.step, "objective": s.objective, "halvings": s.halvings, "accepted": s.accepted} for s in result.steps],
        **({} if result.report_given is None else {"conditions_given": result.report_given.to_dict()}),
        "conditions_before": result.report_before.to_dict(),
        "conditions_after": result.report_after.to_dict(),
        "held_out": result.held_out,
        "held_out_median": medians,
    }
    (folder / "tuning.json").write_text(json.dumps(json_safe(summary), indent=2, allow_nan=False) + "\n")

    figure, ax = plt.subplots(figsize=(7.0, 3.6), dpi=100, layout="constrained")
    ax.plot([s.step for s in result.steps], [s.objective for s in result.steps], "o-", color="tab:blue")
    for s in result.steps:
        if s.halvings or not s.accepted:
            ax.annotate(
                f"{s.halvings}" if s.accepted else "refused",
                (s.step, s.objective),
                textcoords="offset points",
                xytext=(0, 6),
                ha="center",
                fontsize=7,
                color="0.4" if s.accepted else "tab:red",
            )
    ax.margins(y=0.12)  # room for the numbers above the points
    ax.set_xlabel("step")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # steps are counted
    ax.set_ylabel("objective\n" + textwrap.fill(result.objective.text, 40), fontsize=8)
    ax.set_title(
        f"training: mean over {len(result.train_seeds)} seeds (numbers: halvings to stay inside the conditions; refused: no halving did)", fontsize=9
    )
    ax.grid(alpha=0.3)
    figure.savefig(folder / "training.png", dpi=150)
    plt.close(figure)

    names = list(result.held_out)
    figure, axes = plt.subplots(1, len(names), figsize=(3.6 * len(names) + 1.0, 3.8), dpi=100, layout="constrained", squeeze=False)
    colours = {"given": "tab:red", "start": "tab:gray", "tuned": "tab:orange"}
    labels = {"given": "file's gains\n(outside)", "start": "start", "tuned": "tuned"}
    for ax, name in zip(axes[0], names):
        columns = list(result.held_out[name])
        values = [np.asarray(result.held_out[name][c]) for c in columns]
        for run in np.stack(values, axis=1):
            ax.plot(range(len(columns)), run, color="0.75", linewidth=0.8)
        for x, (column, v) in enumerate(zip(columns, values)):
            ax.plot(np.full_like(v, x), v, "o", color=colours[column], label=labels[column].replace("\n", " "))
        ax.plot(range(len(columns)), [np.median(v) for v in values], "k_", markersize=30, markeredgewidth=2, label="median")
        ax.set_xticks(range(len(columns)), [labels[c] for c in columns])
        ax.set_xlim(-0.5, len(columns) - 0.5)
        ax.set_title(name, fontsize=9)
        ax.set_ylabel(f"{name} ({result.units.get(name, '')})")
        ax.grid(axis="y", alpha=0.3)
    handles, labels_ = axes[0][0].get_legend_handles_labels()
    figure.legend(handles, labels_, loc="outside lower center", ncol=len(handles), fontsize=8)
    figure.suptitle(f"held-out seeds {result.test_seeds[0]}..{result.test_seeds[-1]}: each line one seed", fontsize=10)
    figure.savefig(folder / "held_out.png", dpi=150)
    plt.close(figure)
    return {"scenario": scenario_path, "json": folder / "tuning.json", "training": folder / "training.png", "held_out": folder / "held_out.png"}
