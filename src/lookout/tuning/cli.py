"""The ``lookout tune`` command (registered by :mod:`lookout.cli`)."""

from __future__ import annotations

from typing import Annotated

import typer

from lookout._validation import InputError


def tune_command(
    scenario_file: Annotated[
        str,
        typer.Argument(
            metavar="SCENARIO.toml",
            help="A scenario file whose observer or controller has a tunable family (lookout.tuning.families: observers passive, sliding-mode, earth-fixed, adaptive-dp, ekf, ukf, velocity, adaptive-manipulator; controllers observer-backstepping, vectorial-backstepping, tracking, pid).",
        ),
    ],
    out: Annotated[str, typer.Option(metavar="FOLDER", help="Output folder: tuned.toml, tuning.json, training.png, held_out.png.")] = "out/tune",
    objective: Annotated[
        str, typer.Option(metavar="TERMS", help="KIND:SIGNAL or WEIGHT*KIND:SIGNAL joined by +, KIND one of rms_error, rms_tracking, rms_input.")
    ] = "rms_error:position",
    train_seeds: Annotated[int, typer.Option(metavar="N", help="Training runs: seeds seed .. seed + N - 1 of the file.")] = 16,
    test_seeds: Annotated[int, typer.Option(metavar="M", help="Held-out runs: the M seeds after the training seeds.")] = 16,
    steps: Annotated[int, typer.Option(metavar="N", help="Optimizer steps (Adam).")] = 30,
    learning_rate: Annotated[float, typer.Option(metavar="RATE", help="Adam's step in the gains' parameters (log-scale for positive gains).")] = 0.1,
    tune_components: Annotated[
        str | None,
        typer.Option(
            "--tune",
            metavar="observer,controller",
            help="The components to tune.",
            show_default="each that has a family and whose conditions can hold",
        ),
    ] = None,
) -> None:
    """Tune the gains of a scenario's observer and controller by gradient through the
    simulation, inside their papers' conditions (every returned gain set satisfies them
    as lookout design checks them), and compare the start and the result on held-out
    seeds."""
    import math

    from lookout._commandline import console, output_folder
    from lookout.scenario.settings import positive_count
    from lookout.studies.cli import _scenario, console_print
    from lookout.tuning.tune import tune, write_results

    for option, value in (("--train-seeds", train_seeds), ("--test-seeds", test_seeds), ("--steps", steps)):
        try:
            positive_count(value)
        except ValueError as error:
            raise InputError(f"{option}: {error}") from None
    if not (math.isfinite(learning_rate) and learning_rate > 0):
        raise InputError(f"--learning-rate must be a finite positive number; got {learning_rate:g}")
    _refuse_a_study(scenario_file)
    spec, scenario = _scenario(scenario_file, None, None)
    first = spec.seeds[0]
    train = list(range(first, first + train_seeds))
    test = list(range(first + train_seeds, first + train_seeds + test_seeds))
    folder = output_folder("--out", out)  # checked now, made when the results are written
    command = (
        f"lookout tune {scenario_file} --objective '{objective}' --train-seeds {train_seeds} --test-seeds {test_seeds} --steps {steps} "
        f"--learning-rate {learning_rate:g}" + (f" --tune {tune_components}" if tune_components else "")
    )
    try:
        components = None if tune_components is None else tuple(part.strip() for part in tune_components.split(","))
        result = tune(
            scenario,
            objective,
            train_seeds=train,
            test_seeds=test,
            steps=steps,
            learning_rate=learning_rate,
            components=components,
            say=console_print,
        )
    except ValueError as error:  # the family, the objective, the starting gains: refused before any simulation
        raise InputError(str(error) if str(error).startswith("--") else f"{scenario_file}: {error}") from None
    written = write_results(result, spec.composition, folder, source=scenario_file, command=command)
    import numpy as np
    from rich import box
    from rich.table import Table

    table = Table(title=f"{result.family.name}; objective {result.objective.text}", title_justify="left", box=box.SIMPLE_HEAD)
    given = result.given_gains is not None
    for column in ("held-out metric", *(("file's gains (median)",) if given else ()), "start (median)", "tuned (median)", "change"):
        table.add_column(column, justify="right" if column != "held-out metric" else "left")
    for name, values in result.held_out.items():
        a, b = float(np.median(values["start"])), float(np.median(values["tuned"]))
        table.add_row(name, *((f"{float(np.median(values['given'])):.4g}",) if given else ()), f"{a:.4g}", f"{b:.4g}", f"{(b - a) / a:+.1%}")
    console.print(table)
    if result.report_after is None:
        raise ValueError("the tuning has no conditions of its tuned gains: its steps were not done")
    verdicts = ", ".join(f"{key} {verdict}" for key, verdict in result.report_after.verdicts.items())
    console_print(f"conditions of the tuned gains: {verdicts}")
    console_print(
        f"{result.stopped or 'all steps taken'}; {result.seconds:.0f} s; written to {folder}: " + ", ".join(p.name for p in written.values())
    )


def _refuse_a_study(path: str) -> None:
    """A campaign's study file (``scenario = "..."`` and a sweep) is not a scenario: say
    which scenario to tune instead of reporting its keys as unknown."""
    from lookout.scenario._toml import read

    try:
        document, _ = read(path)
    except Exception:
        return  # the scenario reader says what is wrong with the file
    if isinstance(document.get("scenario"), str) and "simulation" not in document:
        raise InputError(
            f"{path} is a campaign's study (a sweep over {document['scenario']}); tune its scenario: lookout tune "
            f"{document['scenario']} (relative to the study's folder)"
        )


def register(app: typer.Typer) -> None:
    """Add ``tune`` to the ``lookout`` command."""
    app.command("tune")(tune_command)
