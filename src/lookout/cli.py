"""The ``lookout`` command: list and run reproductions, design observers.

Exit codes: 0 success; 1 a design whose verdict fails (``design``); 2 bad input.
Every error in the user's input ends with one line on stderr that names the
option and the violated condition, exit code 2, before anything is written.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich import box
from rich.table import Table

from lookout._commandline import PIPE_WIDTH, check_memory, console, created_folder, image_file, simulating, use_compilation_cache, writable_folder
from lookout._json import json_safe
from lookout._validation import InputError, one_line
from lookout.cli_design import DESIGN_VERDICTS

try:  # typer >= 0.29 vendors click
    from typer._click import exceptions as click_exceptions
except ImportError:  # pragma: no cover - older typer depends on click
    from click import exceptions as click_exceptions  # type: ignore[no-redef]  # the same module, where older typer keeps it

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=None,
    help="Nonlinear observers and observer-based control of ships and manipulators.",
)
design_app = typer.Typer(
    no_args_is_help=True,
    rich_markup_mode=None,
    help="Check the stability conditions of a scenario file's components (lookout design FILE), or design one paper's observer. Exit code 0: the design passes; 1: a verdict fails; 2: bad input.",
)
app.add_typer(design_app, name="design")
#: zeta_n of Fossen & Strand (1999), eq. (59), the default of --notch-damping.
DEFAULT_NOTCH_DAMPING = 1.0
#: Frequencies (rad/s) and the Lyapunov weight must lie in this range for the loop
#: analysis to stay finite in float64 (h0's denominator grows as w^3).
ANALYSIS_RANGE = (1e-12, 1e12)

#: Reproduction options and the Config fields they set.
REPRODUCE_OPTIONS = {
    "seed": "--seed",
    "runs": "--runs",
    "duration": "--duration",
    "model_error": "--model-error",
    "model_error.mass": "--model-error mass",
    "model_error.damping": "--model-error damping",
    "model_error.force": "--model-error force",
    "model_error.force_period": "--model-error force_period",
    "gains": "--gains",
    "sweep": "--sweep/--no-sweep",
    "sample_interval": "--sample-interval",
    "conditions": "--condition",
}


def _version(value: bool) -> None:
    if value:
        from lookout import __version__

        print(f"lookout {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit.")] = False,
) -> None:
    """Nonlinear observers and observer-based control of ships and manipulators."""


# ----------------------------------------------------------------------------------
# Checks of what the user typed: each raises InputError naming the option


def _positive_number(option: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{option} must be a finite positive number; got {value:g}")
    return value


def _positive_numbers(option: str, text: str) -> list[float]:
    """'a' or 'a,b,c' -> three finite positive floats (one value is used for all three DOFs)."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (1, 3) or not all(math.isfinite(v) and v > 0 for v in values):
        raise InputError(f"{option} must be one finite positive number, or three separated by commas (surge,sway,yaw); got {text}")
    return values * 3 if len(values) == 1 else values


def _analysable(option: str, symbol: str, value: float, unit: str) -> None:
    """Fail unless ``value`` lies in ANALYSIS_RANGE, where the loop analysis stays finite."""
    low, high = ANALYSIS_RANGE
    unit = f" {unit}" if unit else ""
    if not low <= value <= high:
        raise InputError(
            f"{option}: {symbol} = {value:.3g}{unit} is outside {low:g} to {high:g}{unit}, the range in which the loop analysis is finite in float64"
        )


def _within_range(option: str, values, *, allow_zero: bool = False) -> None:
    """Fail unless every value lies in ANALYSIS_RANGE (or is 0, where ``allow_zero``)."""
    low, high = ANALYSIS_RANGE
    values = list(values)
    smallest = min((v for v in values if not (allow_zero and v == 0)), default=low)
    if max(values) > high or smallest < low:
        raise InputError(f"{option} must lie within 1e-12..1e12; got {', '.join(f'{v:g}' for v in values)}")


def _finish_design(design: str, report, inputs: dict, as_json: bool) -> None:
    """The end of every ``design`` command: the report (a :class:`lookout.analysis.Report`)
    as one JSON object (``design``, ``inputs``, then the report's own layout, whose
    ``verdict`` and ``holds`` say whether it passes), or as text with a last verdict line;
    exit code 0 when the report holds, else 1."""
    if as_json:
        print(json.dumps(json_safe({"design": design, "inputs": inputs, **report.to_dict()}), allow_nan=False))
    else:
        for line in report.lines():
            console.print(line, highlight=False, markup=False)
        console.print(f"verdict: {DESIGN_VERDICTS[report.verdict]} (exit code {0 if report.holds else 1})", highlight=False, markup=False)
    if not report.holds:
        raise typer.Exit(code=1)


def _config(reproduction, options: dict):
    """A reproduction's Config from the CLI options, pydantic's error turned into one line."""
    from pydantic import ValidationError

    try:
        return reproduction.Config(**{key: value for key, value in options.items() if value is not None})
    except ValidationError as error:
        first = error.errors()[0]
        field = ".".join(str(part) for part in first["loc"])
        message = first["msg"].removeprefix("Value error, ")
        option = REPRODUCE_OPTIONS.get(field, field)
        raise InputError(f"{option} {message}" if message.startswith("must") else f"{option}: {message}") from None


def _model_error(text: str) -> dict:
    """'mass=0.2,force=4000' -> {'mass': 0.2, 'damping': 0.0, 'force': 4000.0}: the option
    states the whole error, so keys not given are 0 ('none': no error at all)."""
    result = {"mass": 0.0, "damping": 0.0, "force": 0.0}
    if text.strip() == "none":
        return result
    for part in text.split(","):
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InputError(f"--model-error must be KEY=VALUE pairs separated by commas (mass, damping, force, force_period); got {text}")
        try:
            result[key] = float(value)
        except ValueError:
            raise InputError(f"--model-error {key} must be a number; got {value.strip()!r}") from None
    unknown = sorted(set(result) - {"mass", "damping", "force", "force_period"})
    if unknown:
        raise InputError(f"--model-error: unknown key {unknown[0]!r}; the keys are mass, damping, force, force_period")
    return result


# ----------------------------------------------------------------------------------
# Commands


@app.command("list")
def list_reproductions() -> None:
    """List the available reproductions (name and title; `lookout reproduce NAME --help`
    for the options, `--write-scenario FILE` for every setting and its default)."""
    from lookout.papers import CATALOG

    for name, entry in CATALOG.items():
        console.print(f"{name}\t{entry.title}", highlight=False)


@app.command()
def reproduce(
    name: Annotated[str, typer.Argument(metavar="NAME", help="Reproduction, e.g. fossen-strand-1999 (see `lookout list`).")],
    out: Annotated[
        str | None, typer.Option(metavar="FOLDER", help="Output folder; created with its missing parents.", show_default="out/NAME")
    ] = None,
    seed: Annotated[int, typer.Option(metavar="INT", help="Seed of run 0; run i uses seed + i.")] = 0,
    runs: Annotated[int, typer.Option(metavar="N", help="Monte Carlo runs over seeds (vmapped); the summary gives mean ± std.")] = 1,
    duration: Annotated[
        float | None,
        typer.Option(metavar="SECONDS", help="Simulated time.", show_default="the reproduction's own (its --write-scenario file shows it)"),
    ] = None,
    model_error: Annotated[
        str | None,
        typer.Option(
            metavar="KEY=VALUE,...",
            help="kim-2002: how the vessel differs from the model: mass and damping (relative, M_true = (1 + mass) M), "
            "force (N, unmodelled body-fixed), force_period (s); keys not given are 0, 'none' for no error.",
            show_default="mass=0.2,damping=0.5,force=4000,force_period=100",
        ),
    ] = None,
    gains: Annotated[
        str | None, typer.Option(metavar="SET", help="kim-2002: observer H3, H4: printed (A.4) or kyp (satisfy (14)).", show_default="printed")
    ] = None,
    sweep: Annotated[
        bool | None,
        typer.Option(
            "--sweep/--no-sweep", help="Run the sweeps and studies of the reproductions that have them (see lookout list).", show_default="--sweep"
        ),
    ] = None,
    sample_interval: Annotated[
        float | None, typer.Option(metavar="SECONDS", help="calugi-2003: observer and controller sample interval Delta.", show_default="0.1")
    ] = None,
    condition: Annotated[
        str | None,
        typer.Option(metavar="NAME[,NAME]", help="wondergem-2009: simulation, basin-calm, basin-waves (comma-separated).", show_default="all three"),
    ] = None,
    write_scenario: Annotated[
        str | None,
        typer.Option(
            metavar="FILE",
            help="Write the reproduction's scenario (its first case, with these settings) as a scenario file for `lookout run`, and stop.",
        ),
    ] = None,
) -> None:
    """Run a paper's simulation study.

    Writes a NetCDF of the runs, the paper's figures and summary.json to --out,
    and prints the RMS estimation errors. With --write-scenario, writes the
    scenario file instead and simulates nothing.
    """
    from lookout.papers import REPRODUCTIONS

    if name not in REPRODUCTIONS:
        raise InputError(f"unknown reproduction {name!r}; available: {', '.join(REPRODUCTIONS)}")
    reproduction = REPRODUCTIONS[name]
    extra = {
        "model_error": None if model_error is None else _model_error(model_error),
        "gains": gains,
        "sweep": sweep,
        "sample_interval": sample_interval,
        "conditions": None if condition is None else tuple(part.strip() for part in condition.split(",")),
    }
    for field, value in extra.items():
        if value is not None and field not in reproduction.Config.model_fields:
            owners = [other for other, candidate in REPRODUCTIONS.items() if field in candidate.Config.model_fields]
            raise InputError(f"{REPRODUCE_OPTIONS[field]}: {name} has no such setting (it belongs to {', '.join(owners)})")
    config = _config(reproduction, {"seed": seed, "runs": runs, "duration": duration, **extra})
    if write_scenario is not None:
        _write_scenario(name, config, write_scenario)
        return
    check_memory(reproduction.batches(config), runs=config.runs)
    folder = created_folder("--out", f"out/{name}" if out is None else out)
    with simulating() as progress:
        summary = reproduction.run(config, folder, progress=progress)
    _print_summary(summary, reproduction.tables(summary), folder)


def _write_scenario(name: str, config, text: str) -> None:
    from lookout.papers import REPRODUCTIONS
    from lookout.scenario.composition import compose
    from lookout.scenario.file import CompositionSpec, save

    if not text.strip():
        raise InputError("--write-scenario must name a file; got an empty path")
    path = Path(text)
    if path.is_dir():
        raise InputError(f"--write-scenario must name a file, not the folder {path}; e.g. {path / (name + '.toml')}")
    if path.suffix != ".toml":
        raise InputError(f"--write-scenario must end in .toml; got {text}")
    writable_folder("--write-scenario", path.absolute().parent, text)
    reproduction = REPRODUCTIONS[name]
    cases = reproduction.cases
    save(
        CompositionSpec(compose(reproduction.composition(config, cases[0]))),
        path,
        header=f'lookout scenario: {reproduction.title}, case {cases[0]!r} (preset "{name}:{cases[0]}"), as a composition.\n'
        f"Run it with: lookout run {path.name} --out DIR",
    )
    console.print(
        f"scenario written to {path} (case {cases[0]!r}; cases: {', '.join(cases)}); run it with: lookout run {path} --out FOLDER", highlight=False
    )


def _print_summary(summary: dict, tables, out: Path) -> None:
    for spec in tables:
        table = Table(title=spec.title, title_justify="left", box=box.SIMPLE_HEAD, caption=spec.caption or None, caption_justify="left")
        for i, column in enumerate(spec.columns):
            table.add_column(column, justify="left" if i == 0 else "right")
        for row in spec.rows:
            table.add_row(*row)
        console.print(table)
    finite = summary["status"].count("finite")
    console.print(f"{finite}/{len(summary['status'])} runs finite; written to the folder {out}: {', '.join(summary['files'])}", highlight=False)


@design_app.command("passive-observer")
def design_passive_observer(
    wave_frequency: Annotated[float | None, typer.Option(metavar="RAD_PER_S", help="Dominating wave frequency w_o.")] = None,
    wave_period: Annotated[
        float | None, typer.Option(metavar="SECONDS", help="Wave period, instead of --wave-frequency (w_o = 2 pi / period).")
    ] = None,
    wave_damping: Annotated[float, typer.Option(metavar="ZETA", help="Wave model damping zeta.")] = 0.1,
    notch_damping: Annotated[float | None, typer.Option(metavar="ZETA_N", help="Notch damping zeta_n > zeta.", show_default="1.0")] = None,
    cutoff_frequency: Annotated[
        float | None, typer.Option(metavar="RAD_PER_S", help="Filter cut-off w_c > w_o.", show_default="max(1.1, 1.2255 w_o), the paper's (59)")
    ] = None,
    bias_time_constant: Annotated[str, typer.Option(metavar="T[,T,T]", help="Bias time constants T (s): one value or three.")] = "1000",
    velocity_gain: Annotated[
        str | None, typer.Option(metavar="K[,K,K]", help="Kappa diagonal, SI (N/m, N/m, N m/rad).", show_default="the paper's (60) converted to SI")
    ] = None,
    bias_gain: Annotated[
        str | None,
        typer.Option(metavar="L[,L,L]", help="Lambda diagonal, SI (Kappa's units per second).", show_default="the paper's (60) converted to SI"),
    ] = None,
    normalized: Annotated[
        bool, typer.Option("--normalized", help="Read --velocity-gain and --bias-gain as normalized (bis) gains of Northern Clipper.")
    ] = False,
    lyapunov_weight: Annotated[float, typer.Option(metavar="GAMMA", help="Lyapunov weight gamma > 0.")] = 1.0,
    frequency: Annotated[list[float] | None, typer.Option(metavar="RAD_PER_S", help="Report h0(jw) at this frequency; repeatable.")] = None,
    bode: Annotated[str | None, typer.Option(metavar="FILE", help="Write a Bode plot of h0, hB, h (.png, .pdf, .svg, ...).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of the report.")] = False,
) -> None:
    """Fossen & Strand (1999) passive observer: gains, tuning rule, SPR.

    Gains (45)-(47), the tuning rule (48) inequality by inequality, SPR of each
    loop h = hB h0 with a verified KYP certificate, and |h0(jw)|.

    Exit code 0 when the tuning rule (48) and SPR hold, 1 when a verdict fails or
    SPR cannot be established (the report or JSON is still printed), 2 for bad input.
    """
    import numpy as np

    from lookout.analysis import check_passive_observer, transfer_functions
    from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_MASS, northern_clipper
    from lookout.observers import CUTOFF_RATIO, PassiveObserver, default_cutoff_frequency, injection_gains_from_normalized
    from lookout.papers import fossen_strand_1999

    if (wave_frequency is None) == (wave_period is None):
        raise InputError("give exactly one of --wave-frequency and --wave-period")
    if wave_period is not None:
        wave_frequency = 2.0 * math.pi / _positive_number("--wave-period", wave_period)
        source = f"--wave-period {wave_period:g}"
    else:
        assert wave_frequency is not None  # exactly one of the two is given (checked above)
        _positive_number("--wave-frequency", wave_frequency)
        source = f"--wave-frequency {wave_frequency:g}"
    _positive_number("--wave-damping", wave_damping)
    if notch_damping is None:
        notch_damping = DEFAULT_NOTCH_DAMPING
        if notch_damping <= wave_damping:
            raise InputError(
                f"--wave-damping must be below --notch-damping ({notch_damping:g}, its default); got {wave_damping:g}: lower it or raise --notch-damping"
            )
    elif not (math.isfinite(notch_damping) and notch_damping > wave_damping):
        raise InputError(f"--notch-damping must exceed --wave-damping ({wave_damping:g}); got {notch_damping:g}")
    if cutoff_frequency is None:
        cutoff_frequency = float(default_cutoff_frequency(wave_frequency))
        cutoff_rule = f"default max(1.1, {CUTOFF_RATIO:.4f} w_o)"
    else:
        if not (math.isfinite(cutoff_frequency) and cutoff_frequency > wave_frequency):
            raise InputError(
                f"--cutoff-frequency must exceed the wave frequency w_o = {wave_frequency:.4g} rad/s (from {source}); "
                f"got {cutoff_frequency:g}: raise it, or leave it out for max(1.1, {CUTOFF_RATIO:.4f} w_o)"
            )
        cutoff_rule = "--cutoff-frequency"
    time_constants = _positive_numbers("--bias-time-constant", bias_time_constant)
    kappa = _positive_numbers("--velocity-gain", velocity_gain) if velocity_gain is not None else None
    lam = _positive_numbers("--bias-gain", bias_gain) if bias_gain is not None else None
    _positive_number("--lyapunov-weight", lyapunov_weight)
    frequencies = [_positive_number("--frequency", value) for value in frequency or []]
    bode_path = image_file("--bode", bode) if bode is not None else None

    paper = fossen_strand_1999.Config()  # the paper's (60), in normalized units

    def to_si(kappa, lam):
        with np.errstate(over="ignore"):  # an overflow gives inf, refused below with the option's name
            return injection_gains_from_normalized(kappa, lam, mass=NORTHERN_CLIPPER_MASS, length=NORTHERN_CLIPPER_LENGTH)

    if normalized:
        kappa_si, lambda_si = to_si(kappa or paper.velocity_gain_normalized, lam or paper.bias_gain_normalized)
    else:
        paper_kappa_si, paper_lambda_si = to_si(paper.velocity_gain_normalized, paper.bias_gain_normalized)
        kappa_si = kappa if kappa is not None else paper_kappa_si
        lambda_si = lam if lam is not None else paper_lambda_si
    wave_option = "--wave-period" if wave_period is not None else "--wave-frequency"
    _analysable(wave_option, "w_o", wave_frequency, "rad/s")
    _analysable("--cutoff-frequency" if cutoff_rule == "--cutoff-frequency" else wave_option, "w_c", cutoff_frequency, "rad/s")
    for T, kappa_i, lambda_i in zip(time_constants, kappa_si, lambda_si):
        _analysable("--bias-time-constant", "1/T", 1.0 / T, "rad/s")
        with np.errstate(all="ignore"):  # an overflowing conversion gives 0 or inf, refused here
            _analysable("--bias-gain and --velocity-gain", "lambda/kappa", float(lambda_i / kappa_i), "rad/s")
    for value in frequencies:
        _analysable("--frequency", "w", value, "rad/s")
    _analysable("--lyapunov-weight", "gamma", lyapunov_weight, "")
    observer = PassiveObserver.design(
        northern_clipper(),
        wave_frequency=wave_frequency,
        wave_damping=wave_damping,
        notch_damping=notch_damping,
        cutoff_frequency=cutoff_frequency,
        velocity_injection_gain=kappa_si,
        bias_injection_gain=lambda_si,
        bias_time_constant=time_constants,
        lyapunov_weight=lyapunov_weight,
    )
    h0 = transfer_functions(observer, frequencies)["h0"][:, 0] if frequencies else np.zeros(0)
    response = [{"frequency": w, "magnitude": float(abs(h)), "phase_deg": float(np.degrees(np.angle(h)))} for w, h in zip(frequencies, h0)]
    notes = [f"|h0(j{item['frequency']:g})| = {item['magnitude']:.6g} s, phase {item['phase_deg']:.3f} deg" for item in response]
    if bode_path is not None:
        import matplotlib.pyplot as plt

        from lookout.analysis import frequency_response
        from lookout.plotting import plot_bode

        figure = plot_bode(frequency_response(observer))
        bode_path.parent.mkdir(parents=True, exist_ok=True)
        figure.savefig(bode_path, dpi=110)
        plt.close(figure)
        notes.append(f"Bode plot written to {bode_path}")
    report = check_passive_observer(observer).extended(
        summary=[
            f"wave frequency w_o = {wave_frequency:.4g} rad/s (period {2 * math.pi / wave_frequency:.4g} s), "
            f"cut-off w_c = {cutoff_frequency:.4g} rad/s ({cutoff_rule})"
        ],
        notes=notes,
        quantities={"frequency_response": response},
    )
    inputs = {
        "wave_frequency": wave_frequency,
        "wave_damping": wave_damping,
        "notch_damping": notch_damping,
        "cutoff_frequency": cutoff_frequency,
        "cutoff_rule": cutoff_rule,
        "bias_time_constant": time_constants,
        "velocity_injection_gain": np.asarray(kappa_si).tolist(),
        "bias_injection_gain": np.asarray(lambda_si).tolist(),
        "lyapunov_weight": lyapunov_weight,
        "frequency": frequencies,
        "bode": None if bode_path is None else str(bode_path),
    }
    _finish_design("passive-observer", report, inputs, as_json)


def _non_negative_numbers(option: str, text: str) -> list[float]:
    """'a' or 'a,b,c' -> three finite floats >= 0."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (1, 3) or not all(math.isfinite(v) and v >= 0 for v in values):
        raise InputError(f"{option} must be one finite number >= 0, or three separated by commas (surge,sway,yaw); got {text}")
    return values * 3 if len(values) == 1 else values


@design_app.command("sliding-mode-observer")
def design_sliding_mode_observer(
    gains: Annotated[
        str, typer.Option(metavar="SET", help="H3, H4: printed (Kim's A.4) or kyp (Fossen & Strand (60) in SI, satisfy (14)).")
    ] = "printed",
    velocity_gain: Annotated[str | None, typer.Option(metavar="H4[,H4,H4]", help="H4 diagonal, SI (N/m, N/m, N m/rad); overrides --gains.")] = None,
    bias_gain: Annotated[str | None, typer.Option(metavar="H3[,H3,H3]", help="H3 diagonal, SI (H4's units per second); overrides --gains.")] = None,
    switching_gain: Annotated[
        str, typer.Option(metavar="K[,K,K]", help="Kbar diagonal (m/s, m/s, rad/s); 0 for the passive observer.")
    ] = "10,10,0.01",
    boundary_layer: Annotated[str, typer.Option(metavar="EPS[,EPS,EPS]", help="Boundary layer eps of sat(y~/eps) (m, m, rad).")] = "5,5,0.01745",
    disturbance: Annotated[
        str | None, typer.Option(metavar="F[,F,F]", help="Bound on the unmodelled body-fixed force (N, N, N m): checks the switching gain (17).")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of the report.")] = False,
) -> None:
    """Kim (2002) sliding-mode observer on Northern Clipper: gains and conditions.

    Fossen & Strand's tuning rule (48), KYP (14) with P and Q verified, the
    eigenvalues of the error system without the switching term and inside its
    boundary layer, and, with --disturbance, the switching gain (17) needs.

    Exit code 0 when (48), (14) and every checked condition hold, 1 when one fails
    or (14) cannot be established (the report or JSON is still printed), 2 for bad input.
    """
    from lookout.analysis.sliding_mode import check_kim_2002
    from lookout.models.vessel import northern_clipper
    from lookout.papers import kim_2002

    sets = kim_2002.gain_sets()
    if gains not in sets:
        raise InputError(f"--gains must be one of {', '.join(sets)}; got {gains!r}")
    chosen = dict(sets[gains])
    if velocity_gain is not None:
        chosen["velocity_injection_gain"] = _positive_numbers("--velocity-gain", velocity_gain)
    if bias_gain is not None:
        chosen["bias_injection_gain"] = _positive_numbers("--bias-gain", bias_gain)
    kbar = _non_negative_numbers("--switching-gain", switching_gain)
    eps = _positive_numbers("--boundary-layer", boundary_layer)
    bound = _non_negative_numbers("--disturbance", disturbance) if disturbance is not None else None
    for option, values in (
        ("--velocity-gain", chosen["velocity_injection_gain"]),
        ("--bias-gain", chosen["bias_injection_gain"]),
        ("--switching-gain", kbar),
        ("--boundary-layer", eps),
    ):
        _within_range(option, values, allow_zero=True)
    model = northern_clipper()
    observer = kim_2002.printed_observer(model, boundary_layer=eps, switching_gain=kbar, **chosen)
    inputs = {
        "gain_set": gains,
        "velocity_injection_gain": list(chosen["velocity_injection_gain"]),
        "bias_injection_gain": list(chosen["bias_injection_gain"]),
        "switching_gain": kbar,
        "boundary_layer": eps,
        "disturbance": bound,
    }
    _finish_design("sliding-mode-observer", check_kim_2002(observer, model, disturbance_bound=bound), inputs, as_json)


@design_app.command("adaptive-observer")
def design_adaptive_observer(
    observer_gains: Annotated[str, typer.Option("--k1", metavar="K1[,K1,K1]", help="K1 diagonal (1/s).")] = "1e-3",
    velocity_gains: Annotated[str, typer.Option("--k2", metavar="K2[,K2,K2]", help="K2 diagonal (1/s).")] = "1e-3",
    damping_weights: Annotated[str, typer.Option("--d", metavar="D1,...,D6", help="Damping weights d1..d6 (s): one value or six.")] = "0.1",
    theta_bounds: Annotated[str, typer.Option(metavar="LOW,HIGH", help="Bounds of the unknown m11, as ratios to its value.")] = "0.5,2",
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of the report.")] = False,
) -> None:
    """Calugi, Robertsson & Johansson (2003) on the supply vessel (59): conditions.

    The observer condition (22) and the closed-loop conditions (57)-(58), each
    inequality with both sides, for theta = m11 unknown within --theta-bounds.

    Exit code 0 when all three hold, 1 when one fails (the report or JSON is still
    printed), 2 for bad input.
    """
    from lookout.analysis.adaptive_dp import check_calugi_2003
    from lookout.papers.calugi_2003 import paper_vessel

    k1 = _positive_numbers("--k1", observer_gains)
    k2 = _positive_numbers("--k2", velocity_gains)
    try:
        d = [float(part) for part in damping_weights.split(",")]
    except ValueError:
        d = []
    if len(d) not in (1, 6) or not all(math.isfinite(v) and v > 0 for v in d):
        raise InputError(f"--d must be one finite positive number, or six separated by commas (d1..d6); got {damping_weights}")
    d = d * 6 if len(d) == 1 else d
    try:
        low, high = (float(part) for part in theta_bounds.split(","))
    except ValueError:
        raise InputError(f"--theta-bounds must be two numbers LOW,HIGH; got {theta_bounds}") from None
    if not (0 < low <= 1 <= high and math.isfinite(high)):
        raise InputError(f"--theta-bounds must satisfy 0 < LOW <= 1 <= HIGH (ratios to m11); got {theta_bounds}")
    for option, values in (("--k1", k1), ("--k2", k2), ("--d", d)):
        _within_range(option, values)
    vessel = paper_vessel()
    m11 = float(vessel.mass_matrix[0, 0])
    report = check_calugi_2003(vessel, K1=k1, K2=k2, d=d, theta_bounds=[low * m11, high * m11])
    _finish_design("adaptive-observer", report, {"K1": k1, "K2": k2, "d": d, "theta_bounds": [low, high]}, as_json)


@design_app.command("adaptive-arm")
def design_adaptive_arm(
    arm: Annotated[
        str,
        typer.Option(
            metavar="ARM",
            help="pendulum (Section 4.8: m = 1 kg, l = 1.5 m, theta = m) or two-link (Section 5.3: m1 = 1, m2 = 1.5 kg, l = 1 m, theta = m2).",
        ),
    ] = "two-link",
    gain: Annotated[
        str | None, typer.Option("--k", metavar="K[,K]", help="Observer gain K diagonal (1/s); default the thesis's (20 pendulum, 5 two-link).")
    ] = None,
    adaptation_gain: Annotated[
        float | None, typer.Option("--gamma", metavar="G", help="Adaptation gain Gamma; default the thesis's (10 pendulum, 0.1 two-link).")
    ] = None,
    max_speed: Annotated[float, typer.Option(metavar="W", help="Bound w_max on ||q'|| (rad/s).")] = 1.0,
    margin: Annotated[float, typer.Option(metavar="BETA", help="Margin beta >= 0 of Theorem 4.1.")] = 0.0,
    velocity_error: Annotated[
        str | None, typer.Option(metavar="E[,E]", help="Initial velocity error x1~(0) (rad/s); default q'(0) - x1_hat(0) of the thesis's example.")
    ] = None,
    theta_error: Annotated[
        float | None, typer.Option(metavar="E", help="Initial parameter error theta~(0) (kg); default the thesis's example.")
    ] = None,
    damping_weights: Annotated[
        str | None, typer.Option("--d", metavar="D[,...]", help="Backstepping weights d_1..d_2n (s): also checks (5.28); default 1 for two-link.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of the report.")] = False,
) -> None:
    """Calugi (2002), Theorem 4.1 (adaptive observer) and (5.28) (observer backstepping).

    Theorem 4.1: sigma = inf lambda_min(KM + MK)/2 > C_M w_max + beta, and the initial
    error inside its region; (5.28): sigma > C_M w_max + C_M |x1~(0)| + p/4, p = sum 1/d_i.
    Each inequality with both sides, for the thesis's pendulum or two-link arm.

    Exit code 0 when every checked condition holds, 1 when one fails (the report or JSON
    is still printed), 2 for bad input.
    """
    from lookout.analysis import Report
    from lookout.analysis.adaptive_manipulator import check_5_28, check_theorem_4_1

    if arm not in ("pendulum", "two-link"):
        raise InputError(f"--arm must be pendulum or two-link; got {arm!r}")
    if arm == "pendulum":
        from lookout.papers import calugi_2002_adaptive_observer as example

        parameters, n = example.parameters(), 1
        defaults: dict[str, Any] = {"K": [20.0], "G": 10.0, "x": [-1.0], "theta": 1.0 - 0.1, "d": None}
    else:
        from lookout.papers import calugi_2002_backstepping as example  # type: ignore[no-redef]  # one name for either arm's paper module

        parameters, n = example.parameters(), 2
        defaults = {"K": [5.0, 5.0], "G": 0.1, "x": [-1.0, -1.0], "theta": 1.5 - 0.7, "d": [1.0] * 4}

    def numbers(option: str, text: str, count: int, allow_zero: bool = False) -> list[float]:
        try:
            values = [float(part) for part in text.split(",")]
        except ValueError:
            values = []
        ok = len(values) in (1, count) and all(math.isfinite(v) and (v >= 0 if allow_zero else v > 0) for v in values)
        if not ok:
            condition = ">= 0" if allow_zero else "positive"
            raise InputError(f"{option} must be one finite {condition} number or {count} separated by commas; got {text}")
        return values * count if len(values) == 1 else values

    K = numbers("--k", gain, n) if gain is not None else defaults["K"]
    G = _positive_number("--gamma", adaptation_gain) if adaptation_gain is not None else defaults["G"]
    if not (math.isfinite(max_speed) and max_speed >= 0):
        raise InputError(f"--max-speed must be finite and >= 0; got {max_speed:g}")
    if not (math.isfinite(margin) and margin >= 0):
        raise InputError(f"--margin must be finite and >= 0; got {margin:g}")
    if velocity_error is not None:
        try:
            x = [float(part) for part in velocity_error.split(",")]
        except ValueError:
            x = []
        if len(x) not in (1, n) or not all(math.isfinite(v) for v in x):
            raise InputError(f"--velocity-error must be {n} finite number(s) separated by commas; got {velocity_error}")
        x = x * n if len(x) == 1 else x
    else:
        x = defaults["x"]
    theta = defaults["theta"] if theta_error is None else theta_error
    if not math.isfinite(theta):
        raise InputError(f"--theta-error must be finite; got {theta:g}")
    d = numbers("--d", damping_weights, 2 * n) if damping_weights is not None else defaults["d"]
    for option, values in (("--k", K), ("--gamma", [G]), ("--d", d or [1.0])):
        _within_range(option, values)
    parts = [check_theorem_4_1(parameters, K, G, max_speed, margin=margin, initial_error=(x, [theta]))]
    if d is not None:
        parts.append(check_5_28(parameters, K, d, max_speed, initial_error=x))
    report = Report(
        f"Calugi (2002), {arm} arm: " + " and ".join(part.conditions[0].name for part in parts),
        [condition for part in parts for condition in part.conditions],
        quantities={part.conditions[0].key: part.quantities for part in parts},
        notes=[note for part in parts for note in part.notes],
    )
    inputs = {"arm": arm, "K": K, "Gamma": G, "max_speed": max_speed, "margin": margin, "velocity_error": x, "theta_error": theta, "d": d}
    _finish_design("adaptive-arm", report, inputs, as_json)


@design_app.command("tracking-gains")
def design_tracking_gains(
    position_gain: Annotated[
        str | None, typer.Option("--l1", metavar="L1[,L1,L1]", help="Observer gain L1 diagonal (1/s).", show_default="Section 5's")
    ] = None,
    velocity_gain: Annotated[
        str | None, typer.Option("--l2", metavar="L2[,L2,L2]", help="Observer gain L2 diagonal (1/s2).", show_default="Section 5's")
    ] = None,
    omega: Annotated[
        str | None,
        typer.Option(
            "--omega", metavar="W[,W,W]", help="Omega diagonal (rad/s), natural frequencies of the error dynamics (20).", show_default="Section 5's"
        ),
    ] = None,
    damping_ratio: Annotated[
        str | None,
        typer.Option("--lambda", metavar="Z[,Z,Z]", help="Lambda diagonal, relative damping of the error dynamics (20).", show_default="Section 5's"),
    ] = None,
    start: Annotated[
        str,
        typer.Option(
            metavar="ESTIMATE",
            help="Initial estimate: printed (Section 5's eta_hat0 and velocity estimate) or measured (eta_hat0 = eta0, v_hat0 = 0).",
        ),
    ] = "printed",
    velocity_bound: Annotated[
        float | None,
        typer.Option(metavar="V_M", help="Bound on the ship's speed ||eta'|| (m/s) for Proposition 3.1.", show_default="the reproduction's"),
    ] = None,
    epsilon3: Annotated[float | None, typer.Option(metavar="EPS", help="eps3 of Proposition 3.3; default the largest that (27) admits.")] = None,
    start_angle: Annotated[
        float | None, typer.Option(metavar="RAD", help="Start of the reference on the ellipse, theta_0 (rad).", show_default="the reproduction's")
    ] = None,
    direction: Annotated[
        int | None, typer.Option(metavar="1|-1", help="1: yaw rate positive, -1: negative.", show_default="the reproduction's")
    ] = None,
    propose: Annotated[
        bool,
        typer.Option(
            "--propose", help="Search for gains that satisfy every condition (uses --lambda, --start, --velocity-bound; ignores --l1, --l2, --omega)."
        ),
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of the report.")] = False,
) -> None:
    """Wondergem et al. (2009) on Cybership II around the reproduction's ellipse: conditions.

    (25) for the controller, Proposition 3.1 ((10), (11), (13), (14)) for the observer
    and Proposition 3.3 ((27), (29)-(33)) for the combined scheme, each inequality with
    both sides, at Section 5's initial conditions. With --propose, the gains a search
    finds that satisfy all of them, and their check. The defaults are the paper's
    printed gains and the reproduction's settings (lookout.papers.wondergem_2009).

    Exit code 0 when every condition holds (with --propose: gains were found), 1 when
    one fails (the report or JSON is still printed), 2 for bad input.
    """
    import numpy as np

    from lookout.papers import wondergem_2009
    from lookout.papers.wondergem_2009 import config as paper

    if start not in ("printed", "measured"):
        raise InputError(f"--start must be printed or measured; got {start!r}")
    if direction is not None and direction not in (1, -1):
        raise InputError(f"--direction must be 1 or -1; got {direction}")
    if start_angle is not None and not math.isfinite(start_angle):
        raise InputError(f"--start-angle must be finite; got {start_angle}")
    velocity_bound = paper.VELOCITY_BOUND if velocity_bound is None else velocity_bound
    if not (math.isfinite(velocity_bound) and 0 <= velocity_bound <= 100):
        raise InputError(f"--velocity-bound must lie within 0..100 m/s; got {velocity_bound:g}")
    if epsilon3 is not None:
        _positive_number("--epsilon3", epsilon3)

    def chosen(option: str, text: str | None, printed) -> list[float]:
        return _positive_numbers(option, text) if text is not None else [float(v) for v in np.broadcast_to(printed, 3)]

    gains = {
        "L1": chosen("--l1", position_gain, paper.OBSERVER_POSITION_GAIN),
        "L2": chosen("--l2", velocity_gain, paper.OBSERVER_VELOCITY_GAIN),
        "natural_frequency": chosen("--omega", omega, paper.NATURAL_FREQUENCY),
        "damping_ratio": chosen("--lambda", damping_ratio, paper.DAMPING_RATIO),
    }
    for option, key in (("--l1", "L1"), ("--l2", "L2"), ("--omega", "natural_frequency"), ("--lambda", "damping_ratio")):
        _within_range(option, gains[key])
    given: dict[str, Any] = {key: value for key, value in (("start_angle", start_angle), ("direction", direction)) if value is not None}
    config = wondergem_2009.Config(**given)
    start_angle, direction = config.start_angle, config.direction
    inputs = {"start": start, "velocity_bound": velocity_bound, "start_angle": start_angle, "direction": direction, "propose": propose}
    if propose:
        if len(set(gains["damping_ratio"])) != 1:
            raise InputError(f"--lambda must be one number with --propose (Lambda = lambda I); got {damping_ratio}")
        proposal = wondergem_2009.proposed_gains(config, velocity_bound, estimate=start, damping_ratio=gains["damping_ratio"][0])
        hint = (
            ["--start measured (eta_hat0 = eta0, v_hat0 = 0) removes V0's dependence on L1, L2"] if not proposal.found and start == "printed" else []
        )
        report = proposal.outcome().extended(notes=hint)
        inputs["damping_ratio"] = gains["damping_ratio"][0]
    else:
        report = wondergem_2009.gain_conditions(config, velocity_bound, estimate=start, gains=gains, epsilon3=epsilon3)
        inputs |= {"gains": gains, "epsilon3": epsilon3}
    _finish_design("tracking-gains", report, inputs, as_json)


from lookout.studies.cli import register as _register_studies  # noqa: E402  (after the commands above: list, reproduce, design come first)

_register_studies(app)

from lookout.cli_components import register as _register_components  # noqa: E402

_register_components(app)

from lookout.tuning.cli import register as _register_tuning  # noqa: E402

_register_tuning(app)

from lookout.live.cli import register as _register_live  # noqa: E402

_register_live(app)

from lookout.live.identify_cli import register as _register_identify  # noqa: E402

_register_identify(app)

from lookout.cli_design import register as _register_design  # noqa: E402

_register_design(design_app)


#: Options that only print what lookout is (and compile nothing).
INFORMATION_OPTIONS = frozenset({"--version", "--help", "-h"})


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning every input error into one line and exit code 2.

    ``lookout --version`` and ``--help`` import neither JAX nor NumPy (tests/test_cli.py
    checks); the commands that compute import them when they run.
    """
    import lookout  # enables float64 before any computation

    # first of all: XLA reads these options when its backend starts, and nothing this
    # module imported has started it (tests/test_cli.py checks)
    lookout.configure_cpu()
    # a pipe or a file has no width: tables keep their own instead of rich's 80 columns
    # (COLUMNS, or a terminal, sets it as usual)
    console.width = PIPE_WIDTH if not console.is_terminal and "COLUMNS" not in os.environ else None  # type: ignore[assignment]  # rich reads None as "the terminal's", as Console(width=None) does

    command = typer.main.get_command(app)
    from lookout.cli_design import route

    argv = route(list(sys.argv[1:] if argv is None else argv), set(command.commands["design"].commands))  # type: ignore[attr-defined]  # typer's Command is a Group at run time, with .commands
    try:
        if not INFORMATION_OPTIONS & set(argv) and argv:  # --version and --help compile nothing
            use_compilation_cache()  # a second run of the same file loads what the first compiled
        # without standalone mode, click returns the code of a typer.Exit raised by a command
        code = command.main(args=argv, prog_name="lookout", standalone_mode=False)
    except typer.Exit as done:
        return done.exit_code
    except typer.Abort:
        print("error: aborted", file=sys.stderr)
        return 1
    except click_exceptions.NoArgsIsHelpError as error:
        print(error.format_message())  # the help text
        return 2
    except click_exceptions.UsageError as error:
        print(f"error: {one_line(error.format_message())}", file=sys.stderr)
        return 2
    except (InputError, ValueError) as error:
        print(f"error: {one_line(error)}", file=sys.stderr)
        return 2
    except OSError as error:  # a write that failed after the checks (disk full, a file system that changed)
        text = error.strerror or str(error)
        if error.filename and str(error.filename) not in text:
            text += f": {error.filename}"
        print(f"error: {one_line(text)}", file=sys.stderr)
        return 1
    return code if isinstance(code, int) else 0


if __name__ == "__main__":
    sys.exit(main())
