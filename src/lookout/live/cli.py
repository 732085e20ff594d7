"""``lookout live``, ``lookout replay``, ``lookout write-log`` and ``lookout play`` (registered by :mod:`lookout.cli`)."""

from __future__ import annotations

import contextlib
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from lookout._validation import InputError
from lookout.live.options import MAX_GAP, Gates  # the defaults of --max-gap and of the gate options

if TYPE_CHECKING:
    import xarray as xr

    from lookout.observers.kalman import KalmanFilter

#: Steps per compiled scan in a fast replay.
REPLAY_BATCH = 4096
#: write-log's outage when --outage is not given (START,LENGTH in seconds of run time).
DEFAULT_OUTAGE_TEXT = "300,30"

_GATES = {
    "min_quality": ("--min-quality", "Lowest GGA fix quality used (1 GPS, 2 DGPS, 4 RTK)."),
    "max_hdop": ("--max-hdop", "Highest HDOP used."),
    "position_gate": ("--position-gate", "Largest position innovation used (m); larger is a wild point."),
    "heading_gate": ("--heading-gate", "Largest heading innovation used (degrees)."),
    "position_timeout": ("--position-timeout", "Seconds after which the last fix is not used (dead reckoning)."),
    "heading_timeout": ("--heading-timeout", "Seconds after which the last heading is not used."),
    "gate_probability": (
        "--gate-probability",
        "A Kalman filter's gate: the probability that a good reading passes (its NIS under the chi-square bound).",
    ),
}


#: The gate options that only some observers' tests use: option name -> (the channel
#: it is for, None for every channel; the test, lookout.live.gate.gate_tests, that uses it).
_GATE_TESTS = {"gate_probability": (None, "nis"), "position_gate": ("position", "innovation"), "heading_gate": ("heading", "innovation")}


def _gate_values(gates: dict):
    gates = {name: value for name, value in gates.items() if value is not None}  # an option not given takes its default
    try:
        return Gates(**gates)
    except ValueError as error:
        name = str(error).split(" ", 1)[0]
        option = _GATES.get(name, (name,))[0]
        raise InputError(f"{option}{str(error)[len(name) :]}") from None


def _frame(origin: str | None):
    from lookout.io.geodesy import LocalFrame

    if origin is None:
        return None
    try:
        latitude, longitude = (float(part) for part in origin.split(","))
        return LocalFrame(latitude, longitude)
    except ValueError as error:
        detail = str(error) if "must" in str(error) else "two numbers, degrees"
        raise InputError(f"--origin must be LAT,LON in degrees ({detail}); got {origin!r}") from None


def _session(scenario_file: str, origin: str | None, gates: dict, on_event, say, batch: int = 1):
    """The scenario's observer in a :class:`~lookout.live.Session`; a warning of the
    session (a channel its observer cannot gate) said in one line."""
    import warnings

    from lookout.live.session import Session
    from lookout.studies.cli import _scenario

    gate_values = _gate_values(gates)
    frame = _frame(origin)
    from lookout.sensing.suite import SensorSuite

    spec, scenario = _scenario(scenario_file, None, None)
    suite = scenario.sensor if isinstance(scenario.sensor, SensorSuite) else None
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UserWarning)
            session = Session(
                scenario.observer,
                scenario.sample_period,
                guess=scenario.initial_estimate,
                frame=frame,
                gates=gate_values,
                on_event=on_event,
                batch=batch,
                suite=suite,
            )
    except ValueError as error:
        raise InputError(f"{scenario_file}: {error}") from None
    for warning in caught:
        say(f"warning: {warning.message}")
    _check_gate_options(session, gates, scenario_file)
    return session


def _model_free_session(
    log: str,
    forced: str | None,
    waves: bool,
    origin: str | None,
    gates: dict,
    on_event,
    say,
    batch: int,
    variation: float | None = None,
    imu: str | None = None,
):
    """A session of the model-free observer (:class:`~lookout.observers.model_free.ModelFreeFilter`)
    on the log's own sensors (:func:`lookout.live.log_sensors.log_sensors`: periods (the
    median step between a channel's distinct times, two digits), noise
    and, with ``waves``, the waves measured from the log), stepped at the faster
    channel's period; said in one line. With ``imu`` (an IMU's CSV log), the IMU-aided
    observer instead (:func:`_imu_aided_session`)."""
    from lookout.io.logs import scan_log
    from lookout.live.log_sensors import log_sensors
    from lookout.live.run import check_log_order
    from lookout.live.session import Session
    from lookout.observers.model_free import SETTLING_TIME, ModelFreeFilter
    from lookout.sensors import PositionHeadingSensor

    try:
        scan = scan_log(log, "LOG", forced)
        check_log_order(scan, math.inf)  # a log without a time, or reversed, refused as a replay refuses it
    except ValueError as error:
        raise InputError(str(error)) from None
    # each channel's median step between its distinct times (an outage does not slow it)
    steps = {kind: scan.instant_step(kind) for kind in ("position", "heading")}
    if not all(math.isfinite(step) for step in steps.values()):
        missing = " and ".join(f"no {kind}" for kind, step in steps.items() if not math.isfinite(step))
        raise InputError(
            f"LOG {log}: without --scenario the observer without a hull model reads the log's positions and headings, and it has {missing} over a span of time"
        )
    try:  # of several sources of a kind, the one most readings came from: its rate and noise
        measured = log_sensors(log, scan.format, waves=waves, variation=variation)
    except ValueError as error:
        raise InputError(str(error)) from None
    periods = {"position": measured.position_period, "heading": measured.heading_period}  # 1 Hz, 10 Hz: two digits
    step = min(periods.values())
    # each channel due at its own period, a whole number of steps (a held fix is not new)
    periods = {kind: step * max(round(period / step), 1) for kind, period in periods.items()}
    if waves and measured.wave_period is None:
        raise InputError(f"--waves: LOG {log} shows no wave motion with a peak period between 3 and 25 s; leave --waves out")
    if imu is not None:
        return _imu_aided_session(log, scan.format, imu, measured, periods, waves, origin, gates, on_event, say, batch)
    heading_std = math.radians(measured.heading_std)
    sensor = PositionHeadingSensor(
        (measured.position_std, measured.position_std, heading_std), (periods["position"], periods["position"], periods["heading"])
    )
    observer = ModelFreeFilter(sensor, **_wave_model(measured, waves), plant_step=step, filter_period=step)
    say(
        f"no --scenario: the model-free observer (no hull model, settling {SETTLING_TIME:g} s) on the log's sensors: {measured.describe()}, "
        f"stepped every {step:g} s; give --scenario to choose the observer"
    )
    return Session(observer, step, frame=_frame(origin), gates=_gate_values(gates), on_event=on_event, batch=batch)


def _wave_model(measured, waves: bool) -> dict:
    """The ``wave_period`` and ``wave_std`` (m, m, rad) of an observer without a hull model
    on a log's sensors: the waves measured from the log with ``waves``, none without."""
    if not waves or measured.wave_std is None:
        return {"wave_period": None, "wave_std": None}
    north, east, heading = measured.wave_std
    return {"wave_period": measured.wave_period, "wave_std": (north, east, math.radians(heading))}


def _imu_aided_session(
    log: str, fmt: str, imu: str, measured, periods: dict, waves: bool, origin: str | None, gates: dict, on_event, say, batch: int
):
    """A session of the IMU-aided observer (:class:`~lookout.observers.ins.InertialNavigationFilter`,
    no hull model) on a suite of the log's own sensors, each fed by the source most of its
    readings came from, and the IMU measured from its log
    (:func:`lookout.live.log_sensors.imu_log`), stepped at the IMU's period; said in one line."""
    import warnings

    from lookout.io.nmea import source_spec
    from lookout.live.log_sensors import imu_log
    from lookout.live.session import Session
    from lookout.observers.ins import InertialNavigationFilter
    from lookout.sensing.combining import WeightedMean
    from lookout.sensing.heading import Gyrocompass
    from lookout.sensing.motion import InertialUnit
    from lookout.sensing.position import GnssReceiver
    from lookout.sensing.suite import SensorSuite

    if fmt.startswith("csv"):
        raise InputError(f"LOG {log}: a CSV log names no source for its readings; the IMU-aided observer without --scenario reads an NMEA log")
    try:
        unit = imu_log(imu)
    except ValueError as error:
        raise InputError(str(error)) from None
    step = unit.sample_period
    sources = {"position": measured.position_source, "heading": measured.heading_source}
    for kind, source in sources.items():
        try:
            source_spec(source)
        except ValueError:
            raise InputError(f"LOG {log}: its {kind} readings come from {source!r}, not a source a sensor can name; give --scenario") from None
    suite = SensorSuite(
        {
            "gnss": GnssReceiver(
                noise_std=measured.position_std, sample_period=step * max(round(periods["position"] / step), 1), source=sources["position"]
            ),
            "gyro": Gyrocompass(
                noise_std=math.radians(measured.heading_std),
                sample_period=step * max(round(periods["heading"] / step), 1),
                source=sources["heading"],
            ),
            "imu": InertialUnit(accelerometer_std=unit.accelerometer_std, gyro_std=unit.gyro_std, sample_period=step),
        },
        combining=WeightedMean(),
    )
    observer = InertialNavigationFilter(suite, **_wave_model(measured, waves), plant_step=step, filter_period=step)
    say(
        f"no --scenario: the IMU-aided observer (no hull model; its IMU's biases constants it estimates) on the log's sensors: "
        f"{measured.describe()}, positions from {sources['position']}, headings from {sources['heading']}; {unit.describe()}, "
        f"stepped every {step:g} s; give --scenario to choose the observer"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return Session(observer, step, frame=_frame(origin), gates=_gate_values(gates), on_event=on_event, batch=batch, suite=suite)


def _say_thrust(session, given: bool, say) -> None:
    """What the thrust does for the session's observer, where it is not what one expects:
    none given for an observer that predicts with it, or given to one without input."""
    if not session.observer.input_layout.size:
        if given:
            say("--thrust: the observer has no input (the IMU-aided one integrates its IMU): the thrust is not used")
    elif not given:
        say("no --thrust: the observer predicts with zero input")


def _check_gate_options(session, gates: dict, scenario_file: str) -> None:
    """Refuse a gate option given for an observer whose gate does not use it (a chi-square
    probability for an observer without an innovation covariance, a gate in metres or
    degrees for a Kalman filter)."""
    from lookout.scenario.registry import kind_of, kinds

    used = session.gate_uses
    observer = kind_of(session.observer)
    for name, (channel, test) in _GATE_TESTS.items():
        if gates.get(name) is None or any(test == t and channel in (None, kind) for kind, t in used):
            continue
        option = _GATES[name][0]
        tests = sorted({t for _, t in used})
        by = {
            "nis": "its normalized innovation squared (--gate-probability)",
            "innovation": "its innovations' length (--position-gate, --heading-gate)",
            "none": "nothing: it gives no innovation",
        }
        if test == "nis":
            filters = [each.name for each in kinds("observer") if callable(getattr(each.component_class, "innovation_statistics", None))]
            applies = f"observers with an innovation covariance ({', '.join(filters)})"
        else:
            applies = f"observers gated on the length of their innovation_{channel} output"
        gated_by = " and ".join(by[t] for t in tests)
        raise InputError(f"{option} applies to {applies}; the observer of {scenario_file}, {observer}, is gated on {gated_by}: leave {option} out")


def _check_out(out: str | None) -> None:
    """Refuse a bad --out before any work; nothing is created (the writer makes the file
    and its folders at its first write)."""
    if out is None:
        return
    path = Path(out)
    if not out.strip():
        raise InputError("--out must name a file; got an empty path")
    if path.suffix != ".nc":
        raise InputError(f"--out must name a NetCDF file ending in .nc; got {out}")
    if path.is_dir():
        raise InputError(f"--out must name a file, not the folder {out}")
    from lookout._commandline import writable_folder

    writable_folder("--out", path.absolute().parent, out)


def _check_publish(publish: str | None) -> None:
    if publish is not None and publish != "-":
        from lookout.live.output import parse_udp

        try:
            parse_udp(publish, "--publish")
        except ValueError as error:
            raise InputError(str(error)) from None


def _outputs(session, out: str | None, publish: str | None, scenario_file: str, source: str, flush_every: int):
    """``(emit, close, remove)``: each step to the writer and the publisher; ``close``
    writes what is kept; ``remove`` takes back what the writer created (a command refused
    after it wrote)."""
    from lookout.live.output import Publisher, SessionWriter

    emitters, closers = [], []
    writer = None
    if out is not None:
        writer = SessionWriter(
            Path(out),
            session.observer,
            {"scenario": scenario_file, "source_of_data": source},
            flush_every=flush_every,
            measurement=session.record_layout,
            attrs_of=lambda: (
                {} if session.frame is None else {"origin_latitude": session.frame.latitude, "origin_longitude": session.frame.longitude}
            ),
        )
        emitters.append(writer.add)
        closers.append(writer.close)
    if publish is not None:
        try:
            publisher = Publisher(publish, frame_of=lambda: session.frame)
        except ValueError as error:
            raise InputError(str(error)) from None
        emitters.append(publisher)
        closers.append(publisher.close)

    def emit(record):
        for each in emitters:
            each(record)

    def close():
        for each in closers:
            each()

    def remove():
        if writer is not None:
            writer.remove()

    return emit, close, remove


def _status_line(session, parser, outcome, final: bool = False) -> str:
    """The session in one line: steps, readings and rates, every line or reading not used
    by its cause (:meth:`lookout.live.run.Outcome.unused`), the gate's rule, outages,
    gaps, and the latency or the cost of a step."""
    import numpy as np

    span = (outcome.last_time - outcome.first_time) if outcome.first_time is not None else 0.0
    rates = []
    counted = {name: sensor.counts for name, sensor in session.sensors.items() if not session.direct} or {
        name: channel.counts for name, channel in session.channels.items()
    }
    for name, counts in counted.items():
        # the readings that reached a step: a fix told twice in one epoch (GGA and RMC)
        # counts once, the second superseding the first
        used = counts["accepted"] - counts["superseded"]
        rates.append(f"{name} {used / span:.2f}/s" if span > 0 else f"{name} -")
    unused = outcome.unused(session)
    if outcome.latency.percentiles():
        which, lat = "latency", " ".join(f"p{p} {v * 1e3:.2f} ms" for p, v in outcome.latency.percentiles().items())
    elif session.batch > 1:  # a fast replay: blocks of steps in one scan; the first compiles
        kept = outcome.processing.values()[1:]
        which = "compute"
        if kept.size:
            lat = f"{np.mean(kept) * 1e6:.1f} us per step after the first block (which compiles)"
        else:
            lat = "- (one block, which compiled)" if final else "- (the first block compiles)"
    else:
        which, lat = "step", " ".join(f"p{p} {v * 1e3:.2f} ms" for p, v in outcome.processing.percentiles().items())
    outages = session.event_counts["outage"]
    thrust = ""
    if outcome.thrust_counts:
        bad = outcome.thrust_rejected
        thrust = (
            f"; thrust rejected {sum(bad.values())} ({', '.join(f'{k} {v}' for k, v in bad.items())}: the previous thrust held)"
            if bad
            else "; thrust rejected 0"
        )
    return (
        f"{'done' if final else 'status'}: {outcome.steps} steps, {outcome.readings} readings; "
        + ", ".join(rates)
        + f"; not used {sum(unused.values())}"
        + (f" ({', '.join(f'{k} {v}' for k, v in unused.items())})" if unused else "")
        + thrust
        + f"; gate {session.gate_rule}; outages {outages}; gaps {session.gaps}; {which} {lat or '-'}"
    )


def _sentence_line(parser) -> str:
    """Each sentence kind of the log by what it gave: ``GGA 600, HDG 5990 (no_variation 10)``."""
    kinds: dict[str, dict[str, int]] = {}
    for (formatter, cause), n in parser.sentences.items():
        kinds.setdefault(formatter, {})[cause] = n
    parts = []
    for formatter in sorted(kinds):
        causes = kinds[formatter]
        others = ", ".join(f"{cause} {n}" for cause, n in sorted(causes.items()) if cause != "accepted")
        parts.append(f"{formatter} {causes.get('accepted', 0)}" + (f" ({others})" if others else ""))
    return (
        "sentences: "
        + ", ".join(parts)
        + (" (read; in parentheses, lines that gave no reading, by cause)" if any("(" in part for part in parts) else " (read)")
    )


def _gates(min_quality, max_hdop, position_gate, heading_gate, position_timeout, heading_timeout, gate_probability) -> dict:
    return {
        "min_quality": min_quality,
        "max_hdop": max_hdop,
        "position_gate": position_gate,
        "heading_gate": heading_gate,
        "position_timeout": position_timeout,
        "heading_timeout": heading_timeout,
        "gate_probability": gate_probability,
    }


def _positive_seconds(option: str, value: float | None) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise InputError(f"{option} must be a finite positive number of seconds; got {value:g}")


def _existing_file(option: str, path: str | None) -> None:
    if path is not None and not Path(path).is_file():
        raise InputError(f"{option} must be an existing file; got {path}" + (" (a folder)" if Path(path).is_dir() else ""))


def _format(option: str, path: str, forced: str | None = None) -> str:
    """The log's format (:func:`lookout.io.logs.log_format`), a bad file refused naming ``option``."""
    from lookout.io.logs import log_format

    try:
        return log_format(path, option, forced)
    except ValueError as error:
        raise InputError(str(error)) from None


def _check_truth(truth: str) -> None:
    """Refuse a --truth that is not a NetCDF run with what the figure draws."""
    import xarray as xr

    from lookout.live.figures import PANELS

    try:
        ds = xr.open_dataset(truth)
    except Exception:  # noqa: BLE001 - xarray raises several types for a file it has no engine for
        raise InputError(
            f"--truth {truth}: not a NetCDF file lookout can read (it takes a run's NetCDF, e.g. NAME-truth.nc of lookout write-log)"
        ) from None
    with ds:
        missing = sorted({name for name, _ in PANELS if name not in ds})
        if missing:
            raise InputError(
                f"--truth {truth} has no {', '.join(missing)}: it must be a run of a vessel scenario (e.g. NAME-truth.nc of lookout write-log)"
            )
        if "run" not in ds.dims or "time" not in ds.coords or ds.sizes["time"] < 2:
            raise InputError(f"--truth {truth} must have a run dimension and a time axis of at least two records (a run written by lookout)")


def _check_truth_period(truth: str, sample_period: float) -> None:
    """Refuse a --truth whose time step is not the scenario's sample period (the session's step)."""
    import xarray as xr

    with xr.open_dataset(truth) as ds:
        step = float(ds["time"].values[1] - ds["time"].values[0])
    if abs(step - sample_period) > 1e-9 * sample_period:
        raise InputError(
            f"--truth {truth} is recorded every {step:g} s; the scenario's observer steps every {sample_period:g} s: give the truth of this scenario's run"
        )


def _check_truth_range(truth: str, log: str, scan, sample_period: float) -> None:
    """Refuse, before any step, a --truth whose time range does not cover the session's
    steps: the figure compares the session's time since its first step with the
    truth's run time, and the log's span says how far the steps go (a truth short by
    less than a step is found when the figure is drawn)."""
    import xarray as xr

    with xr.open_dataset(truth) as ds:
        times = ds["time"].values.astype(float)
        epoch = ds.attrs.get("log_epoch_unix_s")
    start, end = float(times[0]), float(times[-1])
    step = float(times[1] - times[0])
    first_step = math.ceil(scan.first / sample_period - 1e-9)
    steps_to = (math.ceil(scan.newest / sample_period - 1e-9) - first_step) * sample_period  # the session's last step time
    if start <= sample_period and end + sample_period >= steps_to - 1e-9 * max(1.0, steps_to):
        return
    clock = f", {scan.first - epoch:.3f} to {scan.newest - epoch:.3f} s on the truth's clock" if epoch is not None else ""
    raise InputError(
        f"--truth {truth} covers {start:g} to {end:g} s (every {step:g} s); LOG {log} runs from {scan.first:.6f} to {scan.newest:.6f} s{clock}, "
        f"steps 0 to {steps_to:g} s of a session: give the truth of the run behind this log (lookout write-log's NAME-truth.nc)"
    )


def _say(quiet: bool):
    def say(text: str) -> None:
        if not quiet:
            print(text, file=sys.stderr, flush=True)

    return say


def _on_event(say):
    def on_event(event):
        when = f"{round(event['session_time'], 1) + 0.0:.1f} s into the session" if "session_time" in event else f"clock {event['time']:.2f} s"
        if event["event"] == "gap":
            say(f"gap at {when}: no reading for {event['length']:.1f} s (every channel dead-reckoned)")
        elif event["event"] in ("outage", "recovered", "source", "reopened"):
            details = ", ".join(
                f"{k} {v:.6g} s" if isinstance(v, float) else f"{k} {v}" for k, v in event.items() if k not in ("event", "time", "session_time")
            )
            say(f"{event['event']} at {when}: {details}")

    return on_event


Quiet = Annotated[bool, typer.Option("--quiet", help="No status lines or events on stderr.")]
Origin = Annotated[str | None, typer.Option(metavar="LAT,LON", help="Origin of the local north/east frame (degrees).", show_default="the first fix")]
Publish = Annotated[str | None, typer.Option(metavar="udp://HOST:PORT | -", help="Send each estimate as a JSON line (- for stdout).")]
Variation = Annotated[
    float | None,
    typer.Option(
        metavar="DEGREES",
        help="Magnetic variation, east positive, for magnetic headings (HDG, HDM) that carry none when no RMC has given one.",
        show_default="the sentences' own",
    ),
]


def _check_variation(variation: float | None) -> None:
    if variation is not None and not (math.isfinite(variation) and -180.0 <= variation <= 180.0):
        raise InputError(f"--variation must be degrees within -180 to 180 (east positive); got {variation:g}")


MinQuality = Annotated[int, typer.Option("--min-quality", help=_GATES["min_quality"][1])]
MaxHdop = Annotated[float, typer.Option("--max-hdop", help=_GATES["max_hdop"][1])]
PositionGate = Annotated[float | None, typer.Option("--position-gate", help=_GATES["position_gate"][1], show_default=f"{Gates.position_gate:g}")]
HeadingGate = Annotated[float | None, typer.Option("--heading-gate", help=_GATES["heading_gate"][1], show_default=f"{Gates.heading_gate:g}")]
PositionTimeout = Annotated[float, typer.Option("--position-timeout", help=_GATES["position_timeout"][1])]
HeadingTimeout = Annotated[float, typer.Option("--heading-timeout", help=_GATES["heading_timeout"][1])]
GateProbability = Annotated[
    float | None, typer.Option("--gate-probability", help=_GATES["gate_probability"][1], show_default=str(Gates.gate_probability))
]
FlushEvery = Annotated[int, typer.Option(metavar="STEPS", help="Steps between writes of --out (a killed session loses at most these).")]
MaxGap = Annotated[
    float,
    typer.Option(
        "--max-gap",
        metavar="SECONDS",
        help="The longest silence of the log (no line at all) accepted; a longer one is refused (docs/live.md: why 60 s).",
    ),
]


def replay_command(
    log: Annotated[
        str,
        typer.Argument(
            metavar="LOG", help="A raw NMEA log (sentences as they came), an NMEA log of TIME SENTENCE lines, or a CSV log (time,north,east,heading)."
        ),
    ],
    scenario_file: Annotated[
        str | None,
        typer.Option(
            "--scenario",
            metavar="SCENARIO.toml",
            help="The scenario whose observer (kind, gains, vessel model, sample period) runs.",
            show_default="the model-free observer on the log's own sensors",
        ),
    ] = None,
    out: Annotated[str | None, typer.Option(metavar="FILE.nc", help="The session's estimates as NetCDF (a simulation's layout).")] = None,
    thrust: Annotated[
        str | None, typer.Option(metavar="THRUST.csv", help="Thrust feedback, time,surge,sway,yaw (N, N, N m).", show_default="zero, with a warning")
    ] = None,
    imu: Annotated[
        str | None,
        typer.Option(
            metavar="IMU.csv",
            help="The IMU's readings, time,fx,fy,r (m/s2, m/s2, deg/s), for an observer on a suite with an IMU (the IMU-aided observer needs them).",
        ),
    ] = None,
    speed: Annotated[float | None, typer.Option(metavar="FACTOR", help="Log seconds per wall-clock second.", show_default="--fast")] = None,
    fast: Annotated[bool, typer.Option("--fast", help="As fast as it goes (the default).")] = False,
    publish: Publish = None,
    origin: Origin = None,
    min_quality: MinQuality = Gates.min_quality,
    max_hdop: MaxHdop = Gates.max_hdop,
    position_gate: PositionGate = None,
    heading_gate: HeadingGate = None,
    position_timeout: PositionTimeout = Gates.position_timeout,
    heading_timeout: HeadingTimeout = Gates.heading_timeout,
    gate_probability: GateProbability = None,
    max_gap: MaxGap = MAX_GAP,
    flush_every: FlushEvery = 1000,
    truth: Annotated[str | None, typer.Option(metavar="TRUTH.nc", help="The run behind a simulated log (lookout write-log), for --figure.")] = None,
    figure: Annotated[str | None, typer.Option(metavar="FILE.png", help="Draw the estimates (against --truth if given) from --out.")] = None,
    quiet: Quiet = False,
    log_format: Annotated[
        str,
        typer.Option(
            "--format",
            metavar="FORMAT",
            help="The log's format: raw (NMEA sentences, times inside them), timed (TIME SENTENCE lines), csv, or auto (from its first line).",
        ),
    ] = "auto",
    variation: Variation = None,
    smooth: Annotated[
        bool,
        typer.Option(
            "--smooth",
            help="After the replay, run the Rauch-Tung-Striebel smoother over the session (a Kalman-type observer: ekf, ukf, model-free) and write its estimates beside the filtered ones in --out.",
        ),
    ] = False,
    waves: Annotated[
        bool,
        typer.Option(
            "--waves",
            help="Without --scenario: the vessel is in waves; their peak period and size are measured from the log and the model-free observer filters them out.",
        ),
    ] = False,
) -> None:
    """Run a scenario's observer over a recorded log, as it would have run live (without
    --scenario: an observer without a hull model on the log's own sensors)."""
    from lookout._commandline import progress_bar
    from lookout.io.logs import BOM_NOTE
    from lookout.io.nmea import NmeaParser
    from lookout.live.run import check_replay, replay
    from lookout.live.session import OriginError

    # what the user typed, then the files, then the scenario: each refused before any work
    if speed is not None and fast:
        raise InputError("--speed and --fast exclude each other: give one")
    if speed is not None and not (math.isfinite(speed) and speed > 0):
        raise InputError(f"--speed must be a finite positive factor; got {speed:g}")
    if flush_every < 1:
        raise InputError(f"--flush-every must be a positive number of steps; got {flush_every}")
    _positive_seconds("--max-gap", max_gap)
    if log_format not in ("auto", "raw", "timed", "csv"):
        raise InputError(f"--format must be auto, raw, timed or csv; got {log_format!r}")
    forced = None if log_format == "auto" else log_format
    if smooth and out is None:
        raise InputError("--smooth needs --out: the smoothed estimates are written beside the filtered ones in the session's file")
    if waves and scenario_file is not None:
        raise InputError("--waves is for a replay without --scenario: a scenario's observer has its own wave model")
    _check_variation(variation)
    if figure is not None and out is None:
        raise InputError("--figure needs --out: the figure is drawn from the session's file")
    if truth is not None and figure is None:
        raise InputError("--truth is for --figure: give --figure FILE.png too")
    gates = _gates(min_quality, max_hdop, position_gate, heading_gate, position_timeout, heading_timeout, gate_probability)
    _gate_values(gates)
    _frame(origin)
    _check_out(out)
    _check_publish(publish)
    figure_path = None
    if figure is not None:
        from lookout._commandline import image_file

        figure_path = image_file("--figure", figure)
        if out is not None and figure_path.absolute() == Path(out).absolute():
            raise InputError(f"--figure and --out must be two files; both are {out}")
    for option, path in (("LOG", log), ("--thrust", thrust), ("--imu", imu), ("--truth", truth)):
        _existing_file(option, path)
    if _format("LOG", log, forced) == "csv-thrust":
        raise InputError(f"LOG {log} is a thrust log (time,surge,sway,yaw): give it with --thrust, and a position log as LOG")
    if _format("LOG", log, forced) == "csv-imu":
        raise InputError(f"LOG {log} is an IMU log (time,fx,fy,r): give it with --imu, and a position log as LOG")
    if thrust is not None and _format("--thrust", thrust) != "csv-thrust":
        raise InputError(f"--thrust {thrust} must be a CSV log whose first line is time,surge,sway,yaw")
    if imu is not None and _format("--imu", imu) != "csv-imu":
        raise InputError(f"--imu {imu} must be a CSV log whose first line is time,fx,fy,r")
    if imu is not None and thrust is not None and Path(imu).absolute() == Path(thrust).absolute():
        raise InputError(f"--imu and --thrust must be two files; both are {imu}")
    if truth is not None:
        _check_truth(truth)
    # what the replay says is held until its first step: a replay refused after reading
    # the log (no step taken) ends in one line
    held: list | None = []
    say_now = _say(quiet)

    def say(text: str) -> None:
        if held is None:
            say_now(text)
        else:
            held.append(text)

    # paced: one step per compiled call, as live; fast: a scan over blocks of steps
    batch = 1 if speed is not None else REPLAY_BATCH
    if scenario_file is None:
        session = _model_free_session(log, forced, waves, origin, gates, _on_event(say), say, batch, variation, imu)
        scenario_file = "no scenario: the model-free observer"
    else:
        session = _session(scenario_file, origin, gates, _on_event(say), say, batch=batch)
    if truth is not None:
        _check_truth_period(truth, session.sample_period)
    smoothed_filter = _kalman_of(session) if smooth else None
    if smooth and smoothed_filter is None:
        kind = "on a sensor suite" if hasattr(session.observer, "gated") else f"of kind {type(_inner_of(session)).__name__}"
        raise InputError(
            f"--smooth needs a Kalman-type observer (ekf, ukf, model-free) on a position-heading sensor; {scenario_file}'s is {kind}: leave --smooth out"
        )
    try:  # the logs' times, order and lines, before any step
        check = check_replay(session, log, thrust, max_gap, forced, imu)
    except OriginError as error:
        raise InputError(error.message("--origin")) from None
    except ValueError as error:
        raise InputError(
            str(error).replace("max_gap", "--max-gap").replace("give imu,", "give --imu IMU.csv,").replace("leave imu", "leave --imu")
        ) from None
    if truth is not None:
        _check_truth_range(truth, log, check.log, session.sample_period)
    for option, path, scanned in (("LOG", log, check.log), ("--thrust", thrust, check.thrust), ("--imu", imu, check.imu)):
        if scanned is not None and scanned.bom:
            say(f"{option} {path}: {BOM_NOTE}")
    write, close, remove = _outputs(session, out, publish, scenario_file, f"replay of {log}", flush_every)

    def emit(block) -> None:
        nonlocal held
        if held is not None:
            kept, held = held, None
            for text in kept:
                say_now(text)
        write(block)

    parser = NmeaParser(variation=variation)
    import warnings

    if not scenario_file.startswith("no scenario") and (thrust is None or not session.observer.input_layout.size):
        _say_thrust(session, thrust is not None, say)
    elif (
        check.thrust is not None and max(check.thrust.first - check.log.first, check.log.newest - check.thrust.newest) > session.gap_after
    ):  # more than a silence
        say(
            f"--thrust covers {max(check.thrust.first, check.log.first) - check.log.first:.1f} to "
            f"{min(check.thrust.newest, check.log.newest) - check.log.first:.1f} s of the log's {check.log.span:.1f} s: zero input before, the last thrust held after"
        )
    refused = None
    try:
        with warnings.catch_warnings(), _replay_progress(progress_bar) as progress:
            warnings.simplefilter("ignore", RuntimeWarning)
            outcome = replay(
                session,
                log,
                thrust=thrust,
                imu=imu,
                speed=speed,
                emit=emit,
                parser=parser,
                max_gap=max_gap,
                check=check,
                status=lambda o: say(_status_line(session, parser, o)),
                progress=progress,
            )
    except OriginError as error:
        refused = error.message("--origin")
    except ValueError as error:  # the log's check (before any step) or a refusal on the way
        refused = str(error).replace("max_gap", "--max-gap")
    finally:  # what was computed is written, whatever stopped the replay (Ctrl-C keeps it)
        close()
    if refused is not None:
        remove()
        raise InputError(refused)
    if outcome.steps == 0:
        remove()
        raise InputError(
            f"{log}: no step was taken: the log never had both a usable position and a heading ({_status_line(session, parser, outcome, True)})"
            + ("; its magnetic headings (HDG, HDM) carry no variation: give --variation" if parser.counts["no_variation"] else "")
        )
    assert outcome.first_time is not None and outcome.last_time is not None  # set with the first step
    span = outcome.last_time - outcome.first_time
    say(_status_line(session, parser, outcome, final=True))
    if parser.sentences:
        say(_sentence_line(parser))
    if check.log.ignored_dates:
        say(f"LOG {log}: {check.log.ignored_dates} dates disagreed with the day counted from the sentences' times of day and were ignored")
    say(
        f"{span:.1f} s of log in {outcome.wall_seconds:.2f} s ({span / outcome.wall_seconds:.0f}x real time)" + (f"; written to {out}" if out else "")
    )
    if smoothed_filter is not None:
        assert out is not None  # --smooth needs --out (checked above)
        say(_smooth_session(Path(out), smoothed_filter))
    if figure_path is not None:
        assert out is not None  # --figure needs --out (checked above)
        try:
            _figure(out, truth, figure_path, log)
        except InputError:
            remove()  # a refused command leaves nothing: the session's file goes with it
            raise
    _exit_if_failed(outcome)


def _inner_of(session):
    """The scenario's observer inside a session's gate (and combining stage)."""
    observer = session.observer
    observer = getattr(observer, "gated", observer)
    return getattr(observer, "inner", observer)


def _kalman_of(session):
    """The session's Kalman-type filter, None when its observer is of another kind."""
    from lookout.observers.kalman import KalmanFilter

    inner = _inner_of(session)
    return inner if isinstance(inner, KalmanFilter) and not hasattr(session.observer, "gated") else None


def smoothed_session(ds: xr.Dataset, observer: KalmanFilter) -> tuple[xr.Dataset, float]:
    """``(ds, gap)``: a session's Dataset with ``v_smoothed`` beside each ``v_hat``
    (:func:`lookout.observers.smoothing.smooth` over the measurement its filter used, NaN
    where the session had none), and how closely the smoother's own forward pass
    reproduced the session's filter (the largest difference of their estimates)."""
    import numpy as np

    from lookout.observers.smoothing import smooth

    columns = []
    for signal in observer.measurement_layout.signals:
        values = ds[signal.name].values[0].reshape(ds.sizes["time"], -1).copy()
        flag = f"outage_{signal.name.removeprefix('measured_')}"
        if flag in ds:
            values[ds[flag].values[0] > 0] = np.nan
        columns.append(values)
    inputs = np.concatenate(
        [ds[f"{signal.name}_applied"].values[0].reshape(ds.sizes["time"], -1) for signal in observer.input_layout.signals], axis=1
    )
    smoothed = smooth(observer, ds["time"].values, np.concatenate(columns, axis=1), inputs)
    gap = 0.0
    ds = ds.copy()
    for signal in observer.estimate_signals:
        name = signal.name
        if f"{name}_hat" in ds:
            gap = max(gap, float(np.nanmax(np.abs(smoothed[f"{name}_hat"].values - ds[f"{name}_hat"].values))))
            ds[f"{name}_smoothed"] = smoothed[f"{name}_smoothed"]
    return ds, gap


def _smooth_session(path: Path, observer) -> str:
    """Smooth a replayed session's file in place (:func:`smoothed_session`); one line on
    what was done and how closely the smoother's forward pass reproduced the session."""
    import xarray as xr

    from lookout.results import write_netcdf

    with xr.open_dataset(path) as opened:
        ds, gap = smoothed_session(opened.load(), observer)
    partial = path.with_name(path.name + ".partial")
    write_netcdf(ds, partial, history="smoothed (Rauch-Tung-Striebel) after the replay")
    partial.replace(path)
    return f"smoothed: the Rauch-Tung-Striebel smoother's estimates written beside the filtered ones as *_smoothed in {path} (its forward pass within {gap:.2g} of the session's filter)"


def _exit_if_failed(outcome) -> None:
    """A session whose estimates went non-finite: why and where on stderr (even with
    --quiet), and the exit code of a failed run."""
    from lookout._commandline import DIVERGED_EXIT_CODE

    if outcome.failure is not None:
        print(f"diverged: the observer's estimates failed {outcome.failure}; exit code {DIVERGED_EXIT_CODE}", file=sys.stderr, flush=True)
        raise typer.Exit(code=DIVERGED_EXIT_CODE)


#: Wall seconds a replay runs before its progress line shows (a shorter one shows none).
PROGRESS_AFTER = 2.0


@contextlib.contextmanager
def _replay_progress(progress_bar):
    """A replay's progress line on stderr: the share of the log replayed and the time
    left, shown once the replay has run :data:`PROGRESS_AFTER` seconds, and only on a
    terminal (a pipe or a log sees nothing); yields the replay's ``progress(done, total)``."""
    import time

    from rich.progress import BarColumn, TextColumn, TimeRemainingColumn

    started = time.perf_counter()
    with progress_bar(TextColumn("replaying"), BarColumn(), TextColumn("{task.percentage:>5.1f}% of the log"), TimeRemainingColumn()) as bar:
        task = bar.add_task("replay", total=1.0, visible=False)

        def progress(done: float, total: float) -> None:
            shown = time.perf_counter() - started > PROGRESS_AFTER
            bar.update(task, completed=done / total if total > 0 else 1.0, visible=shown)

        yield progress


def _figure(out: str, truth: str | None, path: Path, log: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import xarray as xr

    from lookout.live.figures import plot_session

    with xr.open_dataset(out) as session:
        truth_ds = None
        if truth is not None:
            try:
                truth_ds = xr.open_dataset(truth)
            except Exception:  # noqa: BLE001 - checked before the replay; a file changed since
                raise InputError(f"--truth {truth}: not a NetCDF file lookout can read") from None
        try:
            fig = plot_session(session.load(), truth_ds, title=f"lookout replay {Path(log).name}")
        except ValueError as error:
            raise InputError(f"--truth {truth}: {error}") from None
    assert fig is not None  # a session records its observer's estimates, so there is a figure
    path.absolute().parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"figure: {path}", file=sys.stderr)


def live_command(
    scenario_file: Annotated[
        str, typer.Argument(metavar="SCENARIO.toml", help="The scenario whose observer (kind, gains, vessel model, sample period) runs.")
    ],
    nmea: Annotated[
        str, typer.Option(metavar="SOURCE", help="udp://HOST:PORT (bound; HOST default 127.0.0.1), - (stdin) or a serial device or FIFO.")
    ] = "udp://127.0.0.1:10110",
    out: Annotated[str | None, typer.Option(metavar="FILE.nc", help="The session's estimates as NetCDF (a simulation's layout).")] = None,
    publish: Publish = None,
    thrust: Annotated[
        str | None,
        typer.Option(
            metavar="SOURCE",
            help="Thrust feedback lines surge,sway,yaw (N, N, N m): udp://HOST:PORT, - (stdin) or a device or FIFO.",
            show_default="zero, with a warning",
        ),
    ] = None,
    imu: Annotated[
        str | None,
        typer.Option(
            metavar="SOURCE",
            help="An IMU's lines fx,fy,r (m/s2, m/s2, deg/s), for an observer on a suite with an IMU: udp://HOST:PORT, - (stdin) or a device or FIFO.",
        ),
    ] = None,
    duration: Annotated[float | None, typer.Option(metavar="SECONDS", help="Stop after this long.")] = None,
    idle: Annotated[
        float | None, typer.Option(metavar="SECONDS", help="Stop when nothing arrived for this long (counted from the first data).")
    ] = None,
    origin: Origin = None,
    min_quality: MinQuality = Gates.min_quality,
    max_hdop: MaxHdop = Gates.max_hdop,
    position_gate: PositionGate = None,
    heading_gate: HeadingGate = None,
    position_timeout: PositionTimeout = Gates.position_timeout,
    heading_timeout: HeadingTimeout = Gates.heading_timeout,
    gate_probability: GateProbability = None,
    flush_every: FlushEvery = 100,
    quiet: Quiet = False,
    variation: Variation = None,
) -> None:
    """Run a scenario's observer live on NMEA 0183 position and heading; stop with Ctrl-C."""
    import jax

    # each step runs on this thread instead of being handed to an XLA worker and waited
    # for: the hand-off is most of a step's cost when the other cores are busy
    # (docs/benchmarks.md, "Live stepping against MCSimPython"); read when JAX's CPU
    # client starts, which nothing before this line has started
    jax.config.update("jax_cpu_enable_async_dispatch", False)
    from lookout.io.nmea import NmeaParser
    from lookout.live.output import parse_udp
    from lookout.live.run import live, open_source

    for option, value in (("--duration", duration), ("--idle", idle)):
        _positive_seconds(option, value)
    if flush_every < 1:
        raise InputError(f"--flush-every must be a positive number of steps; got {flush_every}")
    gates = _gates(min_quality, max_hdop, position_gate, heading_gate, position_timeout, heading_timeout, gate_probability)
    _gate_values(gates)
    _frame(origin)
    _check_out(out)
    _check_publish(publish)
    _check_variation(variation)
    given = [(option, text) for option, text in (("--nmea", nmea), ("--thrust", thrust), ("--imu", imu)) if text is not None]
    for i, (option, text) in enumerate(given):
        for other, other_text in given[:i]:
            if text == other_text and not (text.startswith("udp://") and text.endswith(":0")):  # port 0: two ports the system picks
                raise InputError(f"{option} and {other} must be two sources; both are {text}")
    for option, text in given:
        try:
            if text is not None and text.startswith("udp://"):
                parse_udp(text, option, any_port=True)
        except ValueError as error:
            raise InputError(str(error)) from None
    say = _say(quiet)
    session = _session(scenario_file, origin, gates, _on_event(say), say)
    reads_imu = next((channel.name for channel in session.channels.values() if channel.kind == "imu"), None)
    if reads_imu is not None and imu is None:
        raise InputError(f"{scenario_file}: the observer reads sensor {reads_imu}, an IMU: give --imu SOURCE, the stream of its fx,fy,r lines")
    if imu is not None and reads_imu is None:
        raise InputError(
            f"{scenario_file}: the observer reads no IMU (a Kalman filter or the IMU-aided observer on a suite with an IMU does): leave --imu out"
        )
    # the sources are opened (bound) before anything is created; a refusal leaves nothing
    opened: list = []
    try:
        for option, text in given:
            opened.append(open_source(text, option))
    except ValueError as error:
        for each in opened:
            if each[1] is not sys.stdin.buffer:
                each[1].close()
        raise InputError(str(error)) from None
    bound = [(option, each[2]) for option, each in zip((option for option, _ in given), opened) if each[0] == "udp"]
    for i, (option, where) in enumerate(bound):  # two spellings of one address (udp://:10110, udp://localhost:10110)
        for other, other_where in bound[:i]:
            if where == other_where:
                for each in opened:
                    if each[1] is not sys.stdin.buffer:
                        each[1].close()
                raise InputError(f"{option} and {other} must be two sources; both are {where}")
    sources = dict(zip((option for option, _ in given), opened))
    source, thrust_source, imu_source = sources["--nmea"], sources.get("--thrust"), sources.get("--imu")
    emit, close, remove = _outputs(session, out, publish, scenario_file, f"live from {nmea}", flush_every)
    _say_thrust(session, thrust_source is not None, say)
    parser = NmeaParser(variation=variation)
    session.warm_up()
    others = "".join(f", {what} on {each[2]}" for what, each in (("thrust", thrust_source), ("IMU", imu_source)) if each is not None)
    say(f"listening on {source[2]}{others} (Ctrl-C stops)")
    import warnings

    from lookout.live.session import OriginError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            outcome = live(
                session,
                source,
                thrust=thrust_source,
                imu=imu_source,
                emit=emit,
                parser=parser,
                duration=duration,
                idle=idle,
                status=lambda o: say(_status_line(session, parser, o)),
            )
    except OriginError as error:  # at the first fix: no step was taken (a step needs a fix)
        remove()
        raise InputError(error.message("--origin")) from None
    finally:  # what was computed is written, whatever stopped the session
        close()
    say(_status_line(session, parser, outcome, final=True) + (f"; written to {out}" if out and outcome.steps else ""))
    _exit_if_failed(outcome)


def write_log_command(
    scenario_file: Annotated[
        str, typer.Argument(metavar="SCENARIO.toml", help="A vessel scenario (a position-heading sensor or a sensor suite) to simulate, one run.")
    ],
    out: Annotated[
        str,
        typer.Option(
            metavar="FOLDER",
            help="Where NAME.nmea, NAME.csv, NAME-thrust.csv, NAME-truth.nc (and for a suite NAME-scenario.toml, with an IMU NAME-imu.csv) go.",
        ),
    ] = "out/log",
    name: Annotated[str, typer.Option(metavar="NAME", help="The files' stem.")] = "dp-vessel",
    origin: Annotated[str, typer.Option(metavar="LAT,LON", help="Where north = east = 0 lies (degrees).")] = "63.44,10.40",
    outage: Annotated[
        str | None,
        typer.Option(
            metavar="START,LENGTH", help="Seconds of run time without fixes, within the run (none: no outage).", show_default=DEFAULT_OUTAGE_TEXT
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the arrival jitter and the corruptions (the run's own is the file's).")] = 0,
    raw: Annotated[
        bool,
        typer.Option(
            "--raw",
            help="Also write NAME-raw.nmea, raw NMEA as a chart plotter logs it: GGA, RMC, VTG and HDG (3.5 W variation, 1.2 E deviation), no time column.",
        ),
    ] = False,
) -> None:
    """Simulate a scenario once and write what a bridge computer would have logged: GGA
    and THS with arrival times, an outage, corrupted and wild sentences; the same
    samples as CSV, the thrust, and the run's truth. With --raw, also the raw log a
    chart plotter would have saved (the time inside the sentences). A sensor suite's log has each
    position reference's GGA and each gyrocompass's THS, stamped with its source, and
    NAME-scenario.toml, the scenario with every such sensor's source, to replay it."""
    import re

    from lookout._commandline import output_folder, simulating
    from lookout.io.simulated_log import write_simulated_log
    from lookout.studies.cli import _scenario

    if not re.fullmatch(r"[A-Za-z0-9._-]+", name) or name in (".", ".."):
        raise InputError(f"--name must be a file stem of letters, digits, '.', '_' or '-'; got {name!r}")
    frame = _frame(origin)
    window: tuple[float, float] | None = None
    given = outage is not None
    outage = DEFAULT_OUTAGE_TEXT if outage is None else outage
    if outage.lower() != "none":
        try:
            parts = tuple(float(part) for part in outage.split(","))
            if len(parts) != 2 or not all(math.isfinite(v) and v >= 0 for v in parts):
                raise ValueError
            window = (parts[0], parts[1])
        except ValueError:
            raise InputError(f"--outage must be START,LENGTH in seconds (finite, >= 0) or none; got {outage!r}") from None
        if window[1] == 0:
            raise InputError(f"--outage LENGTH must be positive (none: no outage); got {outage!r}")
    if seed < 0:
        raise InputError(f"--seed must be a non-negative integer; got {seed}")
    folder = output_folder("--out", out)
    spec, scenario = _scenario(scenario_file, 1, None)
    from lookout.sensing.suite import SensorSuite

    plan = None
    if isinstance(scenario.sensor, SensorSuite):
        from lookout.live.suite_log import suite_log

        try:
            plan = suite_log(scenario.sensor)
        except ValueError as error:
            raise InputError(f"{scenario_file}: {error}") from None
        if raw:
            raise InputError(f"--raw writes the log of one receiver and one gyro (a position-heading sensor); {scenario_file} has a sensor suite")
    elif not {"measured_position", "measured_heading"} <= set(scenario.sensor.measurement_layout.names):
        raise InputError(
            f"{scenario_file}: the sensor must measure position and heading (kind position-heading); it measures "
            f"{', '.join(scenario.sensor.measurement_layout.names)}"
        )
    if window is not None and window[0] + window[1] > scenario.duration:
        if not given:  # the default's window, which the user did not choose: name the run they gave
            raise InputError(
                f"{scenario_file}: its run lasts {scenario.duration:g} s (simulation.duration), shorter than the default outage, "
                f"{DEFAULT_OUTAGE_TEXT} (from {window[0]:g} to {window[0] + window[1]:g} s): give --outage START,LENGTH within the run, or --outage none"
            )
        raise InputError(
            f"--outage {outage} ends at {window[0] + window[1]:g} s, after the run's end: its duration is {scenario.duration:g} s "
            f"(give START + LENGTH <= {scenario.duration:g}, or none)"
        )
    from lookout._commandline import check_memory
    from lookout.scenario.composition import simulate

    check_memory([(scenario, 1)], "simulation.runs", "simulation.duration", where=scenario_file)
    with simulating() as progress:
        trajectory = simulate(spec.composition, progress=progress)
    ds = trajectory.to_xarray()
    ds.attrs["scenario"] = scenario_file
    try:
        paths = write_simulated_log(
            ds, folder, name=name, frame=frame, outage=window, seed=seed, sensors=plan.sensors if plan else None, imu=plan.imu if plan else None
        )
    except ValueError as error:
        raise InputError(str(error)) from None
    if raw:
        from lookout.io.simulated_log import write_raw_log

        paths["raw"] = write_raw_log(ds, folder / f"{name}-raw.nmea", frame=frame)
    if plan is not None:
        paths["scenario"] = _scenario_with_sources(spec, plan, folder / f"{name}-scenario.toml", scenario_file, origin)
        for sensor, kind in plan.skipped:
            print(
                f"sensor {sensor} ({kind}) not written: a log carries position fixes (gnss, hydroacoustic), headings (gyrocompass) and rates of turn (rate-gyro)",
                file=sys.stderr,
            )
        for each in plan.sensors:
            assumed = f" (it names no source: source {plan.sources[each.name]!r} assumed)" if each.name in plan.assumed else ""
            print(f"sensor {each.name}: {each.describe()}{assumed}", file=sys.stderr)
        if plan.imu is not None:
            print(f"sensor {plan.imu[0]}: time,fx,fy,r to {paths['imu'].name}, every {plan.imu[1]:g} s", file=sys.stderr)
    print("written: " + ", ".join(str(path) for path in paths.values()))
    if plan is not None:
        print(
            f"replay it with: lookout replay {paths['nmea']} --scenario {paths['scenario']} --origin {origin} "
            f"--thrust {paths['thrust']}"
            + (f" --imu {paths['imu']}" if "imu" in paths else "")
            + f" --figure {paths['nmea'].with_name('replay.png')} --truth {paths['truth']}",
            file=sys.stderr,
        )


def _scenario_with_sources(spec, plan, path: Path, scenario_file: str, origin: str) -> Path:
    """Write the scenario as simulated (every key spelled out, as ``lookout run``
    writes it) with each logged sensor's source: the one its sentences carry."""
    from lookout.scenario._toml import write as write_toml
    from lookout.scenario.file import composition_comments

    document = spec.document()
    for sensor, source in plan.sources.items():
        document["sensors"][sensor]["source"] = source
    assumed = f"\nSources assumed (the file names none): {', '.join(plan.assumed)}." if plan.assumed else ""
    header = (
        f"lookout scenario, as simulated by lookout write-log from {scenario_file}, with the source of every sensor its log carries.{assumed}\n"
        f"Replay the log with: lookout replay {path.stem.removesuffix('-scenario')}.nmea --scenario {path.name} --origin {origin}"
        + (f" --imu {path.stem.removesuffix('-scenario')}-imu.csv" if plan.imu is not None else "")
    )
    return write_toml(path, document, composition_comments(document), header)


def play_command(
    log: Annotated[str, typer.Argument(metavar="LOG", help="An NMEA log (TIME SENTENCE lines).")],
    to: Annotated[str, typer.Option(metavar="udp://HOST:PORT", help="Where the sentences go.")] = "udp://127.0.0.1:10110",
    speed: Annotated[
        float, typer.Option(metavar="FACTOR", help="Log seconds per wall-clock second (1: as recorded, what a live observer needs).")
    ] = 1.0,
    duration: Annotated[float | None, typer.Option(metavar="SECONDS", help="Stop after this many seconds of log.")] = None,
    max_gap: MaxGap = MAX_GAP,
) -> None:
    """Send an NMEA log's sentences over UDP at the pace they were recorded: a stand-in
    for a ship's network, to try lookout live."""
    import socket
    import time

    from lookout.io.logs import BOM_NOTE, open_log, scan_log
    from lookout.live.output import parse_udp
    from lookout.live.run import check_log_order

    if not (math.isfinite(speed) and speed > 0):
        raise InputError(f"--speed must be a finite positive factor; got {speed:g}")
    _positive_seconds("--duration", duration)
    _positive_seconds("--max-gap", max_gap)
    try:
        host, port = parse_udp(to, "--to")
        address = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)[0][4]
        assert isinstance(address[0], str)  # AF_INET: (host, port), the host a string
    except ValueError as error:
        raise InputError(str(error)) from None
    except OSError:
        raise InputError(f"--to {to}: cannot resolve the host {host}") from None
    _existing_file("LOG", log)
    if _format("LOG", log) != "nmea":
        raise InputError(f"LOG {log} is a CSV log: play sends NMEA sentences (TIME SENTENCE lines); replay a CSV log with lookout replay")
    try:
        scan = scan_log(log, "LOG")
        check_log_order(scan, max(Gates.position_timeout, Gates.heading_timeout))
    except ValueError as error:
        raise InputError(str(error)) from None
    if not (scan.usable["position"] or scan.usable["heading"] or scan.usable["other"]):
        raise InputError(
            f"LOG {log}: no line is a supported sentence with a valid checksum ({', '.join(f'{k} {v}' for k, v in scan.usable.items())})"
        )
    if scan.typical_step > max_gap:
        raise InputError(
            f"LOG {log}: its lines are typically {scan.typical_step:.3g} s apart, more than --max-gap {max_gap:g} s: are the times in seconds?"
        )
    if scan.longest_gap > max_gap:
        raise InputError(
            f"LOG {log}: no line for {scan.longest_gap:.6g} s before line {scan.gap_line} ({scan.gap_start - scan.first:.6g} s into the log), "
            f"longer than --max-gap {max_gap:g} s, which play would wait; allow it with a longer --max-gap, or split the log there"
        )
    if scan.bom:
        print(f"LOG {log}: {BOM_NOTE}", file=sys.stderr)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = skipped = failed = 0
    first = None
    started = time.perf_counter()
    try:
        with open_log(log) as handle:
            for raw in handle:
                stamp, _, sentence = raw.strip().partition(b" ")
                try:
                    t = float(stamp)
                    if not math.isfinite(t):
                        raise ValueError
                except ValueError:
                    skipped += 1  # comments and lines without a time
                    continue
                first = t if first is None else first
                if duration is not None and t - first > duration:
                    break
                ahead = (t - first) / speed - (time.perf_counter() - started)
                if ahead > 0:
                    time.sleep(ahead)
                try:  # a network that refuses one datagram does not stop the play
                    sender.sendto(sentence.strip() + b"\r\n", address)
                except OSError:
                    failed += 1
                    continue
                sent += 1
    except KeyboardInterrupt:
        pass
    finally:
        sender.close()
    print(
        f"sent {sent} sentences to {address[0]}:{address[1]} in {time.perf_counter() - started:.1f} s ({skipped} lines without a time skipped"
        + (f", {failed} refused by the network" if failed else "")
        + ")",
        file=sys.stderr,
    )


def register(app: typer.Typer) -> None:
    """Add ``live``, ``replay``, ``write-log`` and ``play`` to the ``lookout`` command."""
    app.command("live")(live_command)
    app.command("replay")(replay_command)
    app.command("write-log")(write_log_command)
    app.command("play")(play_command)
