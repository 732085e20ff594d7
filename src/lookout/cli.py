"""The ``lookout`` command: list and run reproductions, design observers.

Every error in the user's input ends with one line on stderr naming the parameter
and the violated condition, and exit code 2.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Annotated, Optional

import typer
from pydantic import ValidationError
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

try:  # typer >= 0.29 vendors click
    from typer._click import exceptions as click_exceptions
except ImportError:  # pragma: no cover - older typer depends on click
    from click import exceptions as click_exceptions

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Nonlinear observers for ships and manipulators.")
design_app = typer.Typer(no_args_is_help=True, help="Design an observer and check its stability conditions.")
app.add_typer(design_app, name="design")
console = Console(soft_wrap=True)


class InputError(Exception):
    """Bad user input, reported as one line with exit code 2."""


def _vector(option: str, text: str) -> list[float]:
    """Parse 'a' or 'a,b,c' into three floats."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        raise InputError(f"{option} must be a number or three comma-separated numbers; got {text!r}") from None
    if len(values) == 1:
        values *= 3
    if len(values) != 3:
        raise InputError(f"{option} must have 1 or 3 values; got {len(values)}")
    return values


@app.command("list")
def list_reproductions() -> None:
    """List the available reproductions."""
    from lookout.papers import REPRODUCTIONS

    for name, module in REPRODUCTIONS.items():
        console.print(f"{name}\t{module.TITLE}", highlight=False)


@app.command()
def reproduce(
    name: Annotated[str, typer.Argument(help="Reproduction name (see `lookout list`).")],
    out: Annotated[Path, typer.Option(help="Output folder.")] = Path("out"),
    seed: Annotated[Optional[int], typer.Option(help="PRNG seed.")] = None,
    duration: Annotated[Optional[float], typer.Option(help="Simulated time in seconds.")] = None,
    runs: Annotated[Optional[int], typer.Option(help="Monte Carlo runs over seeds (batched); the summary gives mean and spread.")] = None,
) -> None:
    """Run a paper's simulation study; write NetCDF, figures and summary.json."""
    from lookout.papers import REPRODUCTIONS

    if name not in REPRODUCTIONS:
        raise InputError(f"unknown reproduction {name!r}; available: {', '.join(REPRODUCTIONS)}")
    module = REPRODUCTIONS[name]
    overrides = {key: value for key, value in {"seed": seed, "duration": duration, "runs": runs}.items() if value is not None}
    config = module.Config(**overrides)
    module.build(config)  # validate the scenario before spending time
    with Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"), TimeRemainingColumn(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("run", total=1.0)
        summary = module.run(config, out, progress=lambda done, total: bar.update(task, completed=done / total))
    _print_summary(summary, out)


def _print_summary(summary: dict, out: Path) -> None:
    dofs = ("surge", "sway", "yaw")
    spread = summary["runs"] > 1
    table = Table(title=f"Estimation error, {summary['reproduction']}, {summary['runs']} run(s): RMS over the second half{' (mean ± std over runs)' if spread else ''} / settling time (s{', median' if spread else ''})")
    table.add_column("state")
    for dof in dofs:
        table.add_column(dof, justify="right")
    table.add_column("units")
    for name, values in summary["rms_second_half"].items():
        cells = [
            (f"{values[dof]:.4g} ± {summary['rms_second_half_std'][name][dof]:.2g}" if spread else f"{values[dof]:.4g}")
            + f" / {summary['settling_time'][name][dof]:.0f}"
            for dof in dofs
        ]
        table.add_row(name, *cells, summary["units"][name].replace("surge: ", "").replace("sway: ", "").replace("yaw: ", ""))
    console.print(table)
    finite = summary["status"].count("finite")
    console.print(f"status: {finite}/{len(summary['status'])} runs finite; outputs in {out}/: {', '.join(summary['files'])}", highlight=False)


@design_app.command("passive-observer")
def design_passive_observer(
    wave_frequency: Annotated[Optional[float], typer.Option(help="Dominating wave frequency w_o (rad/s).")] = None,
    wave_period: Annotated[Optional[float], typer.Option(help="Wave period (s), instead of --wave-frequency.")] = None,
    wave_damping: Annotated[float, typer.Option(help="Wave model damping zeta.")] = 0.1,
    notch_damping: Annotated[float, typer.Option(help="Notch damping zeta_n > zeta.")] = 1.0,
    cutoff_frequency: Annotated[float, typer.Option(help="Cut-off w_c > w_o (rad/s).")] = 1.1,
    bias_time_constant: Annotated[str, typer.Option(help="Bias time constants T (s): one value or three.")] = "1000",
    velocity_gain: Annotated[Optional[str], typer.Option(help="Kappa diagonal, SI (N/m, N/m, N m/rad); default: the paper's (60) converted.")] = None,
    bias_gain: Annotated[Optional[str], typer.Option(help="Lambda diagonal, SI (per second); default: the paper's (60) converted.")] = None,
    normalized: Annotated[bool, typer.Option(help="Read --velocity-gain/--bias-gain as normalized (bis) gains of Northern Clipper.")] = False,
    lyapunov_weight: Annotated[float, typer.Option(help="gamma > 0.")] = 1.0,
    frequency: Annotated[Optional[list[float]], typer.Option(help="Report h0(jw) at this frequency (rad/s); repeatable.")] = None,
    bode: Annotated[Optional[Path], typer.Option(help="Write a Bode plot of h0, hB, h to this PNG file.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Passive observer of Fossen & Strand (1999): gains (45)-(47), tuning rule (48), SPR and KYP."""
    import numpy as np

    from lookout.analysis import check_spr, check_tuning_rule, transfer_functions
    from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_MASS, northern_clipper
    from lookout.observers import PassiveObserver, injection_gains_from_normalized
    from lookout.papers import fossen_strand_1999

    if (wave_frequency is None) == (wave_period is None):
        raise InputError("give exactly one of --wave-frequency and --wave-period")
    if wave_period is not None:
        if not (math.isfinite(wave_period) and wave_period > 0):
            raise InputError(f"--wave-period must be positive; got {wave_period}")
        wave_frequency = 2.0 * math.pi / wave_period
    paper = fossen_strand_1999.Config()  # the paper's (60), in normalized units

    def to_si(kappa, lam):
        return injection_gains_from_normalized(kappa, lam, mass=NORTHERN_CLIPPER_MASS, length=NORTHERN_CLIPPER_LENGTH)

    paper_kappa_si, paper_lambda_si = to_si(paper.velocity_gain_normalized, paper.bias_gain_normalized)
    kappa = _vector("--velocity-gain", velocity_gain) if velocity_gain is not None else None
    lam = _vector("--bias-gain", bias_gain) if bias_gain is not None else None
    if normalized:
        kappa_si, lambda_si = to_si(kappa or paper.velocity_gain_normalized, lam or paper.bias_gain_normalized)
    else:
        kappa_si = kappa if kappa is not None else paper_kappa_si
        lambda_si = lam if lam is not None else paper_lambda_si
    observer = PassiveObserver.design(
        northern_clipper(),
        wave_frequency=wave_frequency,
        wave_damping=wave_damping,
        notch_damping=notch_damping,
        cutoff_frequency=cutoff_frequency,
        velocity_injection_gain=kappa_si,
        bias_injection_gain=lambda_si,
        bias_time_constant=_vector("--bias-time-constant", bias_time_constant),
        lyapunov_weight=lyapunov_weight,
    )
    frequencies = list(frequency or [])
    for value in frequencies:
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"--frequency must be positive; got {value}")
    tuning = check_tuning_rule(observer)
    spr = check_spr(observer)
    h0 = transfer_functions(observer, frequencies)["h0"][:, 0] if frequencies else np.zeros(0)
    result = {
        "wave_frequency": wave_frequency,
        "K1": observer.wave_injection_matrix().tolist(),
        "K2": observer.position_injection_matrix().tolist(),
        "velocity_injection_gain": np.asarray(observer.velocity_injection_gain).tolist(),
        "bias_injection_gain": np.asarray(observer.bias_injection_gain).tolist(),
        "tuning_rule": tuning.to_dict(),
        "spr": {
            "holds": all(report.spr for report in spr),
            "loops": [{k: v for k, v in report.to_dict().items() if k != "certificate"} | {"kyp_verified": bool(report.certificate and report.certificate["verified"])} for report in spr],
        },
        "frequency_response": [
            {"frequency": w, "magnitude": float(abs(h)), "phase_deg": float(np.degrees(np.angle(h)))} for w, h in zip(frequencies, h0)
        ],
    }
    if bode is not None:
        from lookout.analysis import frequency_response
        from lookout.plotting import plot_bode

        plot_bode(frequency_response(observer)).savefig(bode, dpi=110)
        result["bode"] = str(bode)
    if as_json:
        print(json.dumps(result))
        return
    np.set_printoptions(precision=4, suppress=True)
    console.print(f"wave frequency w_o = {wave_frequency:.4f} rad/s", highlight=False)
    console.print(f"K1 =\n{observer.wave_injection_matrix()}\nK2 =\n{observer.position_injection_matrix()}", highlight=False)
    console.print(f"Kappa = {np.asarray(observer.velocity_injection_gain)}  Lambda = {np.asarray(observer.bias_injection_gain)}  (SI)", highlight=False)
    console.print(f"tuning rule (48): {'holds' if tuning.holds else 'FAILS'}", highlight=False)
    for item in tuning.inequalities:
        console.print(f"  {item.describe()}", highlight=False)
    console.print(f"SPR of h = hB h0: {'holds' if result['spr']['holds'] else 'FAILS'}", highlight=False)
    for report, loop in zip(spr, result["spr"]["loops"]):
        console.print(
            f"  {report.dof}: min Re h = {report.min_real_part:.4g} at {report.min_real_part_frequency:.4g} rad/s, "
            f"min phase below 10 w_c {report.min_phase_deg_in_band:.2f} deg at {report.min_phase_frequency_in_band:.4g} rad/s, "
            f"KYP certificate {'verified' if loop['kyp_verified'] else 'none'}",
            highlight=False,
        )
    for item in result["frequency_response"]:
        console.print(f"  |h0(j{item['frequency']:g})| = {item['magnitude']:.6g}, phase {item['phase_deg']:.3f} deg", highlight=False)
    if bode is not None:
        console.print(f"Bode plot written to {bode}", highlight=False)


def _one_line(message: str) -> str:
    return " ".join(str(message).split())


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning every input error into one line and exit code 2."""
    import lookout  # enables float64 before any computation

    lookout.use_all_cpu_cores()

    command = typer.main.get_command(app)
    try:
        command.main(args=argv, prog_name="lookout", standalone_mode=False)
    except typer.Exit as done:
        return done.exit_code
    except typer.Abort:
        print("error: aborted", file=sys.stderr)
        return 1
    except click_exceptions.UsageError as error:
        print(f"error: {_one_line(error.format_message())}", file=sys.stderr)
        return 2
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"]) or "input"
        print(f"error: {where}: {_one_line(first['msg'])}", file=sys.stderr)
        return 2
    except (InputError, ValueError) as error:
        print(f"error: {_one_line(error)}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
