"""The ``lookout run`` and ``lookout campaign`` commands (registered by :mod:`lookout.cli`)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.table import Table

from lookout._commandline import DIVERGED_EXIT_CODE, check_memory, console, created_folder, output_folder, progress_bar, simulating, writable_folder
from lookout._json import json_safe

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.figure import Figure
    from rich.progress import TaskID

    from lookout.components import DivergenceBound
    from lookout.scenario.metrics import Failure
from lookout._validation import InputError
from lookout.scenario._toml import FileError

#: What ``lookout run`` writes into its folder, always.
RUN_FILES = ("run.nc", "scenario.toml", "summary.json")
#: And its figures of run 0, each where the run has something to show: every estimate
#: against its truth, the reference against the truth, the commanded and applied input,
#: the thrusters, a sensor suite's position and heading references against the truth
#: (:func:`lookout.plotting.plot_run_estimates`, ``plot_run_reference``, ``plot_run_input``,
#: ``plot_run_thrusters``, ``plot_run_sensor_references``).
RUN_FIGURES = ("estimates.png", "reference.png", "input.png", "thrusters.png", "references.png")
#: Resolution of those figures (that of the reproductions' figures).
RUN_FIGURE_DPI = 110


def console_print(text: str) -> None:
    console.print(text, highlight=False, markup=False)


#: A dask scheduler address: an optional protocol, a host (a name, an IPv4 address or
#: a bracketed IPv6 address) and a port.
SCHEDULER_ADDRESS = re.compile(r"(?:[a-z][a-z0-9+.-]*://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):[0-9]{1,5}")


def _check_cluster_options(workers: int | None, scheduler: str | None) -> None:
    """Refuse (one line) a negative --workers, both options, or a scheduler address without a port."""
    if workers is not None and workers < 0:
        raise InputError(f"--workers must be 0 (this process) or a positive number of workers; got {workers}")
    if workers is not None and scheduler is not None:
        raise InputError("give --workers or --scheduler, not both (a scheduler's cluster has its own workers)")
    if scheduler is not None and not SCHEDULER_ADDRESS.fullmatch(scheduler.strip()):
        raise InputError(f"--scheduler must be an address with a port, such as tcp://10.0.0.5:8786; got {scheduler!r}")


campaign_app = typer.Typer(
    no_args_is_help=True,
    rich_markup_mode=None,
    help="Campaigns: a scenario swept over axes and seeds, run in chunks on dask, stored in Zarr, resumable, reported in HTML.",
)


def _scenario(path: str, runs: int | None, seed: int | None):
    from lookout.scenario.file import read_spec
    from lookout.scenario.settings import positive_count, seed_for_runs

    try:
        if runs is not None:
            positive_count(runs)
    except ValueError as error:
        raise InputError(f"--runs {error}") from None
    try:
        if seed is not None:
            seed_for_runs(seed, runs or 1)
    except ValueError as error:
        raise InputError(f"--seed {error}") from None

    try:
        spec = read_spec(path, runs=runs, seed=seed)[0]
        scenario = spec.build()
    except FileError as error:
        raise InputError(str(error)) from None
    return spec, scenario


def _default_metrics(scenario) -> list[str]:
    """RMS estimation error of every estimated plant variable, RMS tracking error of
    every tracked one (a setpoint that is none of the plant's variables has no tracking
    error), over the second half of the run."""
    record = scenario.record_signals
    truths = {s.name for s in record.truth}
    names = [f"rms_error:{s.name}" for s in record.estimate if s.name in truths]
    names += [
        f"rms_tracking:{s.name.removesuffix('_desired')}"
        for s in record.reference
        if s.name.endswith("_desired") and s.name.removesuffix("_desired") in truths
    ]
    if "thrust" in {s.name for s in record.actuation} and getattr(scenario.actuator, "layout", None) is not None:
        names += ["mean_power:thrust", "time_at_limit:thrust"]
    return names


def _batched(trajectory):
    """The trajectory with a leading run axis (a single run gets one)."""
    import jax

    from lookout.results import Trajectory

    if trajectory.batched:
        return trajectory
    add = lambda tree: jax.tree.map(lambda a: a[None], tree)  # noqa: E731
    return Trajectory(
        trajectory.time,
        add(trajectory.truth),
        add(trajectory.estimate),
        add(trajectory.measurement),
        add(trajectory.reference),
        add(trajectory.command),
        add(trajectory.applied),
        trajectory.signals,
        True,
        trajectory.attrs,
        add(trajectory.actuation),
    )


def run(
    scenario_file: Annotated[
        str, typer.Argument(metavar="SCENARIO.toml", help="A scenario file (see examples/ and `lookout reproduce NAME --write-scenario FILE`).")
    ],
    out: Annotated[str, typer.Option(metavar="FOLDER", help="Output folder; created with its missing parents.")] = "out/run",
    runs: Annotated[int | None, typer.Option(metavar="N", help="Runs over seeds (vmapped), instead of the file's own runs.")] = None,
    seed: Annotated[int | None, typer.Option(metavar="INT", help="Seed of run 0, instead of the file's own seed.")] = None,
) -> None:
    """Simulate a scenario file.

    Writes run.nc (every recorded signal of every run), scenario.toml (the scenario
    with every setting spelled out), summary.json (RMS estimation and tracking
    errors per run over the second half, which runs diverged, the files written) and
    figures of run 0 to --out: estimates.png (every estimated variable against its
    truth, with its measurement; an estimate without a truth alone), reference.png
    (the reference against the truth) where there is a reference, input.png (the
    commanded and applied input, shaded where the actuator limited it) where the
    input is not zero throughout, thrusters.png (each thruster's thrust and angle,
    and the allocation's shortfall) with a thruster actuator, and references.png (each
    position reference and gyrocompass of a sensor suite against the truth, and the
    combined position and heading, failures shaded) with [sensors.NAME] tables. A
    figure that does not apply is not written (one left from an earlier run into the
    folder is removed).
    """
    from lookout.results import write_netcdf
    from lookout.scenario import metrics as metric_module
    from lookout.scenario.file import save, simulate_trajectory, to_dataset

    for name in RUN_FILES + RUN_FIGURES:  # a folder in the way of an output is found before simulating
        if (Path(out) / name).is_dir():
            raise InputError(f"--out: {Path(out) / name} is a folder, and lookout run writes the file {name} there; give another --out")
    spec, scenario = _scenario(scenario_file, runs, seed)
    # the count, not the seeds: nothing that grows with the runs is made before the check
    check_memory(
        [(scenario, spec.runs)], "--runs" if runs is not None else spec.runs_key, spec.runs_key.replace("runs", "duration"), where=scenario_file
    )
    _check_conditions(spec, scenario_file)
    _warn_late_schedule(spec, scenario_file)
    folder = created_folder("--out", out)
    with simulating() as progress:
        trajectory = simulate_trajectory(spec, progress=progress)
    ds = to_dataset(spec, trajectory)
    bound = spec.composition.divergence
    failed = metric_module.failures(_batched(trajectory), bound)
    ds = with_status(ds, failed, bound)
    write_netcdf(ds, folder / "run.nc", history=f"lookout run {scenario_file} (seeds {spec.seeds[0]}..{spec.seeds[-1]})")
    save(
        spec,
        folder / "scenario.toml",
        header=f"lookout scenario, as run into this folder from {scenario_file}.\nRun it again with: lookout run scenario.toml --out DIR",
    )
    figures = _write_figures(ds, folder, spec.title)

    metrics = metric_module.resolve(_default_metrics(scenario), scenario)
    values = metric_module.reduce(_batched(trajectory), metrics)
    summary = {
        "scenario": spec.title,
        "seeds": spec.seeds,
        "status": ds.status.values.tolist(),
        "failures": [None if failure is None else {"time": failure.time, "record": failure.record, "cause": failure.cause} for failure in failed],
        "divergence": None if bound is None else {"signal": bound.signal, "limit": bound.limit},
        "metrics": {
            m.name: {"units": m.units, "description": m.description + " (t >= half the run)", "per_run": values[m.variable].tolist()} for m in metrics
        },
        "files": list(RUN_FILES) + figures,
    }
    (folder / "summary.json").write_text(json.dumps(json_safe(summary), indent=2, allow_nan=False) + "\n")

    table = Table(title=f"{spec.title}: {len(spec.seeds)} run(s)", title_justify="left", box=box.SIMPLE_HEAD)
    table.add_column("metric", justify="left")
    table.add_column("units", justify="left")
    table.add_column("mean over runs", justify="right")
    for metric in metrics:
        table.add_row(metric.name, metric.units, f"{float(values[metric.variable].mean()):.4g}")
    console.print(table)
    warn_limited(ds)
    report_failures(failed, spec.seeds, bound)
    finite = summary["status"].count("finite")
    console_print(f"{finite}/{len(summary['status'])} runs finite; written to the folder {folder}: {', '.join(summary['files'])}")
    if finite < len(summary["status"]):
        raise typer.Exit(code=DIVERGED_EXIT_CODE)


#: ``lookout run`` warns when an actuator limited a command for longer than this fraction
#: of a run (a loop that asks for more than the actuator gives is not the loop designed).
LIMITED_WARNING_FRACTION = 0.10


def _check_conditions(spec, scenario_file: str) -> None:
    """The design conditions of the file's observer and controller (``lookout design
    FILE``), by ``[simulation] conditions``: a warning line on standard error when one
    fails ('warn'), a refusal ('require'), or nothing ('ignore')."""
    import sys

    from lookout.design import component_designs

    mode = spec.composition.simulation.conditions
    if mode == "ignore":
        return
    try:
        designs = component_designs(spec.composition)
    except ValueError as error:  # conditions that cannot be evaluated for this file
        if mode == "require":
            raise InputError(f"{scenario_file}: simulation.conditions is 'require', and the conditions cannot be checked: {error}") from None
        print(f"warning: the design conditions of {scenario_file} were not checked: {error}", file=sys.stderr)
        return
    failing = [
        f"{d.role} {d.kind}: {c.name} ("
        + ", ".join(
            f"{i.relation}: {i.left:.4g} {i.comparison} {i.right:.4g} {i.units}".rstrip() + " fails" for i in c.inequalities if i.verdict == "fails"
        )
        + ")"
        for d in designs
        for c in d.report.conditions
        if c.verdict == "fails"
    ]
    if not failing:
        return
    text = "; ".join(failing)
    if mode == "require":
        raise InputError(
            f"{scenario_file}: simulation.conditions is 'require', and {len(failing)} design condition(s) fail: {text}; "
            f"lookout design {scenario_file} --propose gives gains that meet them"
        )
    print(
        f"warning: {len(failing)} design condition(s) of {scenario_file} fail: {text} (lookout design {scenario_file} shows them; "
        f'[simulation] conditions = "require" refuses such a run)',
        file=sys.stderr,
    )


def _warn_late_schedule(spec, scenario_file: str) -> None:
    """A warning line for setpoints scheduled after the run's end (they never take
    effect). A warning, not a refusal: a reproduction's case written with a shorter
    duration keeps its paper's schedule."""
    import sys

    import numpy as np

    times = getattr(spec.composition.scenario.reference, "schedule_times", None)
    duration = spec.composition.simulation.duration
    if times is None:
        return
    late = [(i, float(t)) for i, t in enumerate(np.asarray(times, dtype=float)) if t >= duration]
    if late:
        shown = ", ".join(f"reference.schedule_times[{i}] = {t:g} s" for i, t in late[:3]) + (f" and {len(late) - 3} more" if len(late) > 3 else "")
        print(
            f"warning: {scenario_file}: {shown} at or after the run's end (simulation.duration {duration:g} s): "
            f"{'that setpoint is' if len(late) == 1 else 'those setpoints are'} never reached; lengthen the run or drop "
            f"{'it' if len(late) == 1 else 'them'}",
            file=sys.stderr,
        )


def warn_limited(ds: xr.Dataset) -> None:
    """A warning line on standard error for each input an actuator limited for more than
    :data:`LIMITED_WARNING_FRACTION` of a run (the worst run), and for a thruster
    allocation short of its command as long (``allocation_saturated``)."""
    import sys

    from lookout.results import limited_fraction

    over = [f"{name} {fraction:.0%} (run {run})" for name, (fraction, run) in limited_fraction(ds).items() if fraction > LIMITED_WARNING_FRACTION]
    if over:
        print(
            f"warning: the actuator limited the command longer than {LIMITED_WARNING_FRACTION:.0%} of the time: {', '.join(over)}; "
            f"the loop asks for more than the actuator gives, so it is not the loop designed: lower the controller's gains "
            f"or the reference's demands (input.png shows where)",
            file=sys.stderr,
        )


def with_status(ds: xr.Dataset, failed: list[Failure | None], bound: DivergenceBound | None) -> xr.Dataset:
    """``ds`` with ``status`` per run from ``failed`` (:func:`lookout.scenario.metrics.failures`)
    and ``failure``, why and where each failed run failed ("" for a finite run)."""
    import numpy as np

    ds = ds.copy()
    ds["status"] = ("run", np.asarray(["finite" if f is None else "diverged" for f in failed], dtype=object), ds["status"].attrs)
    rule = "a non-finite truth or estimate" + (
        "" if bound is None else f", or the estimation or tracking error of {bound.signal} beyond {bound.limit:g}"
    )
    ds["status"].attrs["comment"] = f"diverged: {rule}"
    ds["failure"] = ("run", np.asarray(["" if f is None else str(f) for f in failed], dtype=object), {"long_name": "why and where the run failed"})
    return ds


def report_failures(failed: list[Failure | None], seeds: Sequence[int], bound: DivergenceBound | None) -> None:
    """One line per failed run on standard error: why and where it failed."""
    import sys

    shown = [(run, failure) for run, failure in enumerate(failed) if failure is not None]
    for run, failure in shown[:5]:
        print(f"diverged: run {run} (seed {seeds[run]}) {failure}", file=sys.stderr)
    if len(shown) > 5:
        print(f"diverged: {len(shown) - 5} more runs (run.nc's failure variable says why and where each failed)", file=sys.stderr)
    if shown:
        limit = "" if bound is None else f"; the divergence limit is {bound.limit:g} on the error of {bound.signal} ([simulation] divergence sets it)"
        print(f"diverged: {len(shown)} of {len(failed)} runs failed{limit}; exit code {DIVERGED_EXIT_CODE}", file=sys.stderr)


def _write_figures(ds, folder: Path, title: str) -> list[str]:
    """Write the :data:`RUN_FIGURES` that apply to ``ds`` (run 0) into ``folder``;
    remove those that do not (left by an earlier run); return the names written."""
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_run_estimates, plot_run_input, plot_run_reference, plot_run_sensor_references, plot_run_thrusters

    written = []
    draws: tuple[Callable[..., Figure | None], ...] = (
        plot_run_estimates,
        plot_run_reference,
        plot_run_input,
        plot_run_thrusters,
        plot_run_sensor_references,
    )
    for name, draw in zip(RUN_FIGURES, draws, strict=True):
        figure = draw(ds, run=0, title=title)
        path = folder / name
        if figure is None:
            if path.is_file() or path.is_symlink():
                path.unlink()
            continue
        try:
            figure.savefig(path, dpi=RUN_FIGURE_DPI)
        finally:
            plt.close(figure)
        written.append(name)
    return written


def _campaign(spec_path: str):
    from lookout.studies.campaign import load_campaign

    try:
        return load_campaign(spec_path)
    except FileError as error:
        raise InputError(str(error)) from None
    except ValueError as error:  # the base scenario's components do not fit
        raise InputError(f"{spec_path}: {error}") from None


def _store_path(option: str, text: str, *, must_exist: bool) -> Path:
    if not text.strip():
        raise InputError(f"{option} must name a folder; got an empty path")
    path = Path(text)
    if must_exist:
        if not (path / "_lookout" / "campaign.json").exists():
            raise InputError(
                f"{option}: {path} is not a campaign store (no {path / '_lookout' / 'campaign.json'}); make one with lookout campaign run SPEC --out {path}"
            )
    elif path.exists() and not path.is_dir():
        raise InputError(f"{option} must be a folder; {path} is an existing file")
    elif not path.exists():
        writable_folder(option, path.absolute().parent, f"{option} {text}")
    return path


@campaign_app.command("run")
def campaign_run(
    spec: Annotated[str, typer.Argument(metavar="SPEC.toml", help="A campaign spec (see examples/).")],
    out: Annotated[str, typer.Option(metavar="STORE", help="The Zarr store; an existing store of the same spec is resumed.")] = "out/campaign.zarr",
    workers: Annotated[
        int | None,
        typer.Option(metavar="N", help="Local dask workers, one process and core each; 0 computes in this process.", show_default="one per core"),
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(metavar="ADDRESS", help="Use this dask scheduler (tcp://host:port) instead of a local cluster.")
    ] = None,
) -> None:
    """Run (or resume) a campaign: each chunk of the sweep is one vmapped batch and one
    dask task; the metrics go to the store as chunks finish."""
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeRemainingColumn

    from lookout.studies.execute import SchedulerError, run_campaign

    _check_cluster_options(workers, scheduler)
    campaign = _campaign(spec)
    store = _store_path("--out", out, must_exist=False)
    say = console_print
    with progress_bar(TextColumn("chunks"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn()) as bar:
        task = bar.add_task("chunks", total=len(campaign.chunks()), completed=0)
        try:
            result = run_campaign(
                campaign,
                store,
                workers=workers,
                scheduler=scheduler,
                say=say,
                progress=lambda done, total: bar.update(task, completed=done),
            )
        except SchedulerError as error:
            raise InputError(f"--scheduler {scheduler}: {error}") from None
        except ValueError as error:
            raise InputError(f"{spec}: {error}") from None
    say(f"{result['done']}/{result['chunks']} chunks done ({result['computed']} computed now in {result['seconds']:.1f} s); store: {store}")
    say(f"next: lookout campaign report {store}")


@campaign_app.command("status")
def campaign_status(
    store: Annotated[str, typer.Argument(metavar="STORE", help="A campaign store.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Say what is done: chunks and runs, time spent, diverged runs, per sweep point."""
    from lookout.studies.store import status

    path = _store_path("STORE", store, must_exist=True)
    info = status(path)
    if as_json:
        print(json.dumps(json_safe(info), allow_nan=False))
        return
    say = console_print
    say(f"{path}: {info['title']}")
    say(
        f"chunks: {info['chunks_done']} of {info['chunks']} done ({info['runs_done']} of {info['runs']} runs); {'complete' if info['complete'] else 'incomplete: run lookout campaign run SPEC --out ' + str(path) + ' to resume'}"
    )
    say(
        f"points: {info['points']} ({info['sweep_kind']} over {', '.join(info['axes']) or 'no axes'}), seeds per point: {info['seeds_per_point']}, chunk runs: {info['chunk_runs']}"
    )
    say(f"compute time in finished chunks: {info['chunk_seconds']:.1f} s; diverged runs so far: {info['diverged']}")
    say(f"lookout {info['lookout_version']}, created {info['created']}, fingerprint {info['fingerprint']}")


@campaign_app.command("report")
def campaign_report(
    store: Annotated[str, typer.Argument(metavar="STORE", help="A campaign store.")],
    out: Annotated[str | None, typer.Option(metavar="FILE", help="The HTML file.", show_default="STORE's name + -report.html, beside it")] = None,
    figures: Annotated[str | None, typer.Option(metavar="FOLDER", help="Also save each figure as a PNG in this folder.")] = None,
) -> None:
    """Write a static HTML report of a campaign store (opens in a browser without network)."""
    from lookout.studies.report import write_report

    path = _store_path("STORE", store, must_exist=True)
    target = None
    if out is not None:
        if not out.strip() or not out.endswith((".html", ".htm")):
            raise InputError(f"--out must name an .html file; got {out!r}")
        writable_folder("--out", Path(out).absolute().parent, out)
        target = Path(out)
    folder = None
    if figures is not None:
        folder = output_folder("--figures", figures)  # made when there are figures to put in it
    written = write_report(path, target, figures_dir=folder)
    drawn = folder is not None and folder.is_dir() and any(folder.glob("*.png"))
    console_print(f"report written to {written}" + (f"; figures in {folder}" if drawn else "; no figures (no chunk has finished)" if folder else ""))


benchmark_app = typer.Typer(
    no_args_is_help=True,
    rich_markup_mode=None,
    help="Benchmarks: every observer that fits a plant, on the same seeds, sea states, dropouts and model errors.",
)


@benchmark_app.command("observers")
def benchmark_observers(
    out: Annotated[
        str, typer.Option(metavar="FOLDER", help="Output folder: one subfolder per plant, with its stores, tables, figures and report.")
    ] = "out/benchmark",
    plant: Annotated[
        str | None,
        typer.Option(metavar="KIND", help="Only this plant's benchmark (dp-vessel, cybership-ii, manipulator).", show_default="every shipped one"),
    ] = None,
    spec: Annotated[
        str | None,
        typer.Option(
            metavar="FILE.toml",
            help="Your own benchmark spec (see lookout/studies/benchmarks/), or a scenario file: its plant, sensor and sea, "
            "every observer that composes on them, its own observer as given, the plant kind's conditions.",
        ),
    ] = None,
    quick: Annotated[bool, typer.Option("--quick", help="The specs' quick size: shorter runs, fewer seeds.")] = False,
    workers: Annotated[
        int | None,
        typer.Option(metavar="N", help="Local dask workers, one process and core each; 0 computes in this process.", show_default="one per core"),
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(metavar="ADDRESS", help="Use this dask scheduler (tcp://host:port) instead of a local cluster.")
    ] = None,
) -> None:
    """Run every observer of a benchmark spec on identical scenarios and write, per
    plant, the metrics' tables (table.md, table.csv), figures, benchmark.nc, an HTML
    report (report.html) and each observer's campaign store and report, and say which
    observer to pick per condition (the rule: docs/choosing-an-observer.md). A
    benchmark whose stores exist resumes. Everything is checked before anything is
    written: a refusal leaves nothing behind."""
    import os
    import shutil

    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn

    from lookout.studies import benchmark as bench
    from lookout.studies import benchmark_report
    from lookout.studies.execute import SchedulerError, local_cluster

    if plant is not None and spec is not None:
        raise InputError("give --plant (a shipped benchmark) or --spec (your own), not both")
    _check_cluster_options(workers, scheduler)
    if spec is not None:
        if not spec.strip():
            raise InputError("--spec must name a file; got an empty path")
        if not Path(spec).is_file():
            raise InputError(f"--spec: {spec} is a folder, not a benchmark spec" if Path(spec).is_dir() else f"--spec: no file {spec}")
        paths = [Path(spec)]
    else:
        try:
            paths = [bench.shipped_spec(plant)] if plant is not None else [bench.shipped_spec(name) for name in bench.shipped_plants()]
        except ValueError as error:
            raise InputError(str(error)) from None
    folder = output_folder("--out", out)
    size = "quick" if quick else "full"
    prepared = []
    for path in paths:  # every spec and every campaign is checked before anything runs
        try:
            prepared.append(bench.prepare(bench.load_benchmark(path), size, folder))
        except FileError as error:
            raise InputError(str(error)) from None
        except ValueError as error:
            raise InputError(f"{path}: {error}" if not str(error).startswith("--out") else str(error)) from None
    names = [each.folder for each in prepared]
    if len(set(names)) != len(names):
        raise InputError(f"--out: two benchmarks would share the folder {next(n for n in names if names.count(n) > 1)}")
    try:
        bench.check_resources(prepared, workers, scheduler)
    except SchedulerError as error:
        raise InputError(f"--scheduler {scheduler}: {error}") from None
    except ValueError as error:
        raise InputError(f"--out {out}: {error}" if "disk space" in str(error) else str(error)) from None
    created = [each for each in [folder] + [p.folder for p in prepared] if not each.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    command = " ".join(
        ["lookout benchmark observers", f"--out {out}"]
        + ([f"--plant {plant}"] if plant else [])
        + ([f"--spec {spec}"] if spec else [])
        + (["--quick"] if quick else [])
    )
    cluster = None
    address = scheduler
    try:
        if scheduler is None and workers != 0:
            cluster = local_cluster(workers or os.cpu_count() or 1)  # one cluster for every plant
            address = cluster.scheduler_address
        for each in prepared:
            observers = list(dict.fromkeys(c.name for c in each.campaigns))
            resumed = sum(each.store(c).exists() for c in each.campaigns)
            console_print(
                f"{each.benchmark.name}: {each.benchmark.spec.title} ({size}: {len(observers)} observer{'s' * (len(observers) != 1)}"
                + (f"; resuming {resumed} store{'s' * (resumed != 1)} in {each.folder})" if resumed else ")")
            )
            for note in each.notes:
                console_print(f"  {note}")
            with progress_bar(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn()) as bar:
                tasks: dict[str, TaskID] = {}

                def progress(name, done, total, bar=bar, tasks=tasks):
                    if name not in tasks:
                        tasks[name] = bar.add_task(name, total=total)
                    bar.update(tasks[name], completed=done)

                try:
                    result = bench.run_benchmark(each, workers=workers, scheduler=address, say=console_print, progress=progress, command=command)
                except SchedulerError as error:
                    raise InputError(f"--scheduler {scheduler}: {error}") from None
            console_print(
                f"{each.benchmark.name}: done in {result.seconds:.0f} s; {result.written['report']}, {result.written['table']}, {result.written['figures']}"
            )
            console_print(f"{each.benchmark.name}: which observer ({benchmark_report.overall(result.recommendations)}):")
            for recommendation in result.recommendations:
                console_print(f"  {recommendation.text()}")
    except BaseException as error:
        for made in reversed(created):  # nothing of value: leave no folder behind
            if made.exists() and not any(made.rglob("*.zarr")):
                shutil.rmtree(made, ignore_errors=True)
        if isinstance(error, KeyboardInterrupt):
            console_print(f"interrupted: the chunks stored so far are kept; the same command resumes the benchmark from {folder}")
        raise
    finally:
        if cluster is not None:
            cluster.close()


@benchmark_app.command("dead-reckoning")
def benchmark_dead_reckoning(
    out: Annotated[str, typer.Option(metavar="FOLDER", help="Output folder: table.md, table.csv and drift.png.")] = "out/benchmark/dead-reckoning",
    quick: Annotated[bool, typer.Option("--quick", help="2 seeds instead of 8.")] = False,
) -> None:
    """How far each observer's position drifts when every position reference is lost for
    600 s on the DP vessel in Fossen & Strand's sea (docs/choosing-an-observer.md): the
    passive observer, the extended Kalman filter with and without the IMU, the observer
    without a hull model, and the IMU-aided observer on each IMU grade; per observer the
    drift after 60, 300 and 600 s (median and 95th percentile over seeds) and the recovery
    after the references return."""
    from lookout.studies import dead_reckoning

    folder = output_folder("--out", out)
    written = dead_reckoning.run(folder, "quick" if quick else "full", say=console_print)
    console_print(f"dead reckoning: {written['table']}, {written['csv']}, {written['figure']}")


def failures(
    scenario_file: Annotated[str, typer.Argument(metavar="SCENARIO.toml", help="A scenario with a sensor suite ([sensors.NAME] tables).")],
    out: Annotated[
        str, typer.Option(metavar="STORE", help="The campaign's Zarr store; an existing store of the same analysis is resumed.")
    ] = "out/failures.zarr",
    start: Annotated[float | None, typer.Option(metavar="SECONDS", help="When each failure starts.", show_default="half the run")] = None,
    seeds: Annotated[int, typer.Option(metavar="N", help="Runs per case (seeds from the file's own seed).")] = 4,
    table: Annotated[str | None, typer.Option(metavar="FILE.csv", help="Also write the table as CSV.")] = None,
    workers: Annotated[
        int | None,
        typer.Option(metavar="N", help="Local dask workers, one process and core each; 0 computes in this process.", show_default="one per core"),
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(metavar="ADDRESS", help="Use this dask scheduler (tcp://host:port) instead of a local cluster.")
    ] = None,
) -> None:
    """The worst single failure: the intact suite and each instrument failed in each of
    its modes (dropout, freeze, jump, drift, noise) at --start, as one campaign over
    seeds; a table per failure of the largest position and heading error from the
    setpoint after it (or the largest excursion, without a setpoint) and the position
    estimate's error, worst first. The store is a campaign's: `lookout campaign report
    STORE` draws its HTML report."""
    import csv
    import math

    from lookout.scenario._toml import read
    from lookout.scenario.composition import compose
    from lookout.studies.campaign import campaign_from_document
    from lookout.studies.execute import SchedulerError, run_campaign
    from lookout.studies.single_failures import INTACT, campaign_document, worst_table
    from lookout.studies.store import CampaignStore

    _check_cluster_options(workers, scheduler)
    if seeds < 1:
        raise InputError(f"--seeds must be a whole number >= 1; got {seeds}")
    if start is not None and not (math.isfinite(start) and start >= 0):
        raise InputError(f"--start must be a finite number of seconds >= 0; got {start}")
    if table is not None:
        if Path(table).is_dir():
            raise InputError(f"--table: {table} is a folder; give a file name")
        writable_folder("--table", Path(table).absolute().parent, f"--table {table}")
    try:
        document, _ = read(scenario_file)
    except FileError as error:
        raise InputError(str(error)) from None
    if not isinstance(document.get("sensors"), dict):
        raise InputError(f"{scenario_file}: lookout failures needs a scenario with a sensor suite ([sensors.NAME] tables; docs/sensors.md)")
    try:
        duration = compose(document).simulation.duration
        when = duration / 2 if start is None else start
        spec, metrics = campaign_document(document, start=when, seeds=seeds, seed=compose(document).simulation.seed)
        campaign = campaign_from_document(spec, f"{scenario_file} (failures)", None, Path(scenario_file).parent)
    except ValueError as error:
        raise InputError(f"{scenario_file}: {error}") from None
    store = _store_path("--out", out, must_exist=False)
    say = console_print
    own = [name for name, each in document["sensors"].items() if isinstance(each, dict) and each.get("failures")]
    if own:
        say(f"the failures the file gives ({', '.join(own)}) are left out: each case fails one instrument of the intact suite")
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeRemainingColumn

    with progress_bar(TextColumn("cases"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn()) as bar:
        task = bar.add_task("cases", total=len(campaign.chunks()), completed=0)
        try:
            run_campaign(
                campaign, store, workers=workers, scheduler=scheduler, say=say, progress=lambda done, total: bar.update(task, completed=done)
            )
        except SchedulerError as error:
            raise InputError(f"--scheduler {scheduler}: {error}") from None
    rows = worst_table(CampaignStore(store).open().load(), metrics)
    heading = [m for m in metrics if m.endswith(":heading")]
    shown = Table(box=box.SIMPLE, title=f"single failures at {when:g} s, {seeds} run(s) each: worst first")
    handled = "detected after (s)" in rows[0]
    columns = ["failure", "diverged", f"{metrics[0]} max (m)", f"{heading[0]} max (deg)", "rms_error:position mean (m)"]
    columns += ["detected after (s)", "runs rejecting another"] if handled else []
    for column in columns:
        shown.add_column(column, justify="left" if column == "failure" else "right")
    for row in rows:
        cells = [
            row["failure"],
            f"{row['diverged']}/{row['runs']}",
            f"{row[f'{metrics[0]} max']:.2f}",
            f"{math.degrees(row[f'{heading[0]} max']):.2f}",
            f"{row['rms_error:position mean']:.2f}",
        ]
        if handled:
            detected = row["detected after (s)"]
            cells += ["" if detected is None else ("not in every run" if math.isnan(detected) else f"{detected:.1f}")]
            cells += [f"{row['runs rejecting another sensor']}/{row['runs']}"]
        shown.add_row(*cells)
    console.print(shown)
    worst = next((row for row in rows if row["failure"] != INTACT), None)
    if worst is not None:
        say(
            f"worst single failure: {worst['failure']} ({metrics[0]} {worst[f'{metrics[0]} max']:.2f} m, intact {rows[0][f'{metrics[0]} max']:.2f} m)"
        )
    if table is not None:
        path = Path(table)
        path.absolute().parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        say(f"table: {path}")
    say(f"next: lookout campaign report {store}")


def capability(
    scenario_file: Annotated[
        str, typer.Argument(metavar="SCENARIO.toml", help='A scenario whose actuator is thrusters ([actuator] kind = "thrusters").')
    ],
    out: Annotated[
        str, typer.Option(metavar="FOLDER", help="Where capability.png and capability.csv go; created with its missing parents.")
    ] = "out/capability",
    moment_arm: Annotated[float, typer.Option(metavar="METRES", help="The environment's yaw moment per newton of its force (m).")] = 0.0,
    step: Annotated[float, typer.Option(metavar="DEG", help="Degrees between the directions, dividing 360.")] = 10.0,
) -> None:
    """DP capability: the largest environmental force the thrusters can balance from each
    direction (0 from ahead, 90 from starboard), with a yaw moment of --moment-arm times
    the force, intact and with each thruster out of service; a polar figure, a CSV and
    the smallest of each case."""
    import csv
    import math

    import numpy as np

    from lookout.actuators.capability import single_failure_capability
    from lookout.plotting.capability import plot_capability
    from lookout.scenario.file import read_spec

    if not (math.isfinite(moment_arm)):
        raise InputError(f"--moment-arm must be a finite number of metres; got {moment_arm}")
    count = 360.0 / step if math.isfinite(step) and step > 0 else math.nan
    if not (math.isfinite(count) and abs(count - round(count)) < 1e-9 and count >= 4):
        raise InputError(f"--step must divide 360 degrees into at least 4 directions (10, 15, 30 ...); got {step:g}")
    try:
        spec = read_spec(scenario_file)[0]
    except FileError as error:
        raise InputError(str(error)) from None
    layout = getattr(spec.build().actuator, "layout", None)
    if layout is None or not hasattr(layout, "B"):
        raise InputError(f'{scenario_file}: lookout capability needs thrusters ([actuator] kind = "thrusters" with a layout); its actuator has none')
    folder = output_folder("--out", out)
    directions = np.radians(np.arange(round(count)) * step)
    found = single_failure_capability(layout, directions, moment_arm=moment_arm)
    shown = Table(box=box.SIMPLE, title=f"largest force held (kN), moment arm {moment_arm:g} m")
    for column in ("case", "smallest", "from (deg)", "ahead", "starboard", "astern", "port"):
        shown.add_column(column, justify="left" if column == "case" else "right")
    quarter = {b: int(np.argmin(np.abs(((np.degrees(directions) - b) + 180.0) % 360.0 - 180.0))) for b in (0, 90, 180, 270)}
    for name, values in found.items():
        least = int(np.argmin(values))
        shown.add_row(
            name if name == "intact" else f"{name} out",
            f"{values[least] / 1e3:.1f}",
            f"{math.degrees(directions[least]):g}",
            *(f"{values[quarter[b]] / 1e3:.1f}" for b in (0, 90, 180, 270)),
        )
    console.print(shown)
    target = created_folder("--out", out)
    figure = plot_capability(directions, found, title=f"DP capability of {Path(scenario_file).name}")
    figure.savefig(target / "capability.png", dpi=110)
    with (target / "capability.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["direction_deg", *[name if name == "intact" else f"{name}_out" for name in found]])
        for row, beta in enumerate(directions):
            writer.writerow([f"{math.degrees(beta):g}", *[f"{values[row]:.6g}" for values in found.values()]])
    worst = min((name for name in found if name != "intact"), key=lambda name: float(np.min(found[name])), default=None)
    if worst is not None:
        console_print(
            f"worst single thruster failure: {worst} ({np.min(found[worst]) / 1e3:.1f} kN at its weakest, intact {np.min(found['intact']) / 1e3:.1f} kN)"
        )
    console_print(f"written to {folder}: capability.png, capability.csv")


def register(app: typer.Typer) -> None:
    """Add ``run``, ``campaign`` and ``benchmark`` to the ``lookout`` command."""
    app.command("run")(run)
    app.command("failures")(failures)
    app.command("capability")(capability)
    app.add_typer(campaign_app, name="campaign")
    app.add_typer(benchmark_app, name="benchmark")
