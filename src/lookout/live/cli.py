"""``lookout live``, ``lookout replay`` and ``lookout write-log`` (registered by :mod:`lookout.cli`)."""

from __future__ import annotations

import math
import sys

import numpy as np
from pathlib import Path
from typing import Annotated, Optional

import typer

from lookout._validation import InputError
from lookout.live.session import Gates  # the defaults of the gate options

#: Steps per compiled scan in a fast replay.
REPLAY_BATCH = 4096

_GATES = {
    "min_quality": ("--min-quality", "Lowest GGA fix quality used (1 GPS, 2 DGPS, 4 RTK)."),
    "max_hdop": ("--max-hdop", "Highest HDOP used."),
    "position_gate": ("--position-gate", "Largest position innovation used (m); larger is a wild point."),
    "heading_gate": ("--heading-gate", "Largest heading innovation used (degrees)."),
    "position_timeout": ("--position-timeout", "Seconds after which the last fix is not used (dead reckoning)."),
    "heading_timeout": ("--heading-timeout", "Seconds after which the last heading is not used."),
}


def _session(scenario_file: str, origin: Optional[str], gates: dict, on_event, batch: int = 1):
    from lookout.io.geodesy import LocalFrame
    from lookout.live.session import Gates, Session
    from lookout.studies.cli import _scenario

    try:
        gate_values = Gates(**gates)
    except ValueError as error:
        name = str(error).split(" ", 1)[0]
        option = _GATES.get(name, (name,))[0]
        raise InputError(f"{option}{str(error)[len(name):]}") from None
    frame = None
    if origin is not None:
        try:
            latitude, longitude = (float(part) for part in origin.split(","))
            frame = LocalFrame(latitude, longitude)
        except ValueError as error:
            detail = str(error) if "must" in str(error) else "two numbers, degrees"
            raise InputError(f"--origin must be LAT,LON in degrees ({detail}); got {origin!r}") from None
    spec, scenario = _scenario(scenario_file, None, None)
    try:
        session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=frame, gates=gate_values, on_event=on_event, batch=batch)
    except ValueError as error:
        raise InputError(f"{scenario_file}: {error}") from None
    return session


def _outputs(session, out: Optional[str], publish: Optional[str], scenario_file: str, source: str, flush_every: int):
    from lookout.live.output import Publisher, SessionWriter, parse_udp

    emitters, closers = [], []
    writer = None
    if out is not None:
        path = Path(out)
        if path.suffix != ".nc":
            raise InputError(f"--out must name a NetCDF file ending in .nc; got {out}")
        if path.is_dir():
            raise InputError(f"--out must name a file, not the folder {out}")
        from lookout._commandline import writable_folder

        writable_folder("--out", path.absolute().parent, out)
        path.absolute().parent.mkdir(parents=True, exist_ok=True)
        writer = SessionWriter(path, session.observer, {"scenario": scenario_file, "source_of_data": source}, flush_every=flush_every,
                               attrs_of=lambda: {} if session.frame is None else {"origin_latitude": session.frame.latitude,
                                                                                 "origin_longitude": session.frame.longitude})
        emitters.append(writer.add)
        closers.append(writer.close)
    if publish is not None:
        if publish != "-":
            try:
                parse_udp(publish, "--publish")
            except ValueError as error:
                raise InputError(str(error)) from None
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

    return emit, close, writer


def _status_line(session, parser, outcome, final: bool = False) -> str:
    span = (outcome.last_time - outcome.first_time) if outcome.first_time is not None else 0.0
    rates = []
    for kind, channel in session.channels.items():
        rates.append(f"{kind} {channel.counts['accepted'] / span:.2f}/s" if span > 0 else f"{kind} -")
    rejected = outcome.rejected
    gated = sum(channel.counts["gated"] for channel in session.channels.values())
    quality = sum(channel.counts["quality"] + channel.counts["hdop"] for channel in session.channels.values())
    if outcome.latency.percentiles():
        which, lat = "latency", " ".join(f"p{p} {v * 1e3:.2f} ms" for p, v in outcome.latency.percentiles().items())
    elif session.batch > 1:  # a fast replay: blocks of steps in one scan; the first compiles
        kept = outcome.processing.values()[1:]
        which, lat = "compute", (f"{np.mean(kept) * 1e6:.1f} us per step after the first block (which compiles)" if kept.size else "")
    else:
        which, lat = "step", " ".join(f"p{p} {v * 1e3:.2f} ms" for p, v in outcome.processing.percentiles().items())
    outages = session.event_counts["outage"]
    return (f"{'done' if final else 'status'}: {outcome.steps} steps, {outcome.readings} readings; " + ", ".join(rates)
            + f"; rejected {sum(rejected.values())} ({', '.join(f'{k} {v}' for k, v in rejected.items()) or 'none'})"
            + f"; quality/HDOP {quality}; gated {gated}; outages {outages}; late {session.late}; {which} {lat or '-'}")


def _gates(min_quality, max_hdop, position_gate, heading_gate, position_timeout, heading_timeout) -> dict:
    return {"min_quality": min_quality, "max_hdop": max_hdop, "position_gate": position_gate, "heading_gate": heading_gate,
            "position_timeout": position_timeout, "heading_timeout": heading_timeout}


def _say(quiet: bool):
    def say(text: str) -> None:
        if not quiet:
            print(text, file=sys.stderr, flush=True)
    return say


def _on_event(say):
    def on_event(event):
        if event["event"] in ("outage", "recovered", "source", "reopened"):
            details = ", ".join(f"{k} {v:.6g} s" if isinstance(v, float) else f"{k} {v}" for k, v in event.items() if k not in ("event", "time", "session_time"))
            when = f"{event['session_time']:.1f} s into the session" if "session_time" in event else f"clock {event['time']:.2f} s"
            say(f"{event['event']} at {when}: {details}")
    return on_event


Quiet = Annotated[bool, typer.Option("--quiet", help="No status lines or events on stderr.")]
Origin = Annotated[Optional[str], typer.Option(metavar="LAT,LON", help="Origin of the local north/east frame (degrees).", show_default="the first fix")]
Publish = Annotated[Optional[str], typer.Option(metavar="udp://HOST:PORT | -", help="Send each estimate as a JSON line (- for stdout).")]
MinQuality = Annotated[int, typer.Option("--min-quality", help=_GATES["min_quality"][1])]
MaxHdop = Annotated[float, typer.Option("--max-hdop", help=_GATES["max_hdop"][1])]
PositionGate = Annotated[float, typer.Option("--position-gate", help=_GATES["position_gate"][1])]
HeadingGate = Annotated[float, typer.Option("--heading-gate", help=_GATES["heading_gate"][1])]
PositionTimeout = Annotated[float, typer.Option("--position-timeout", help=_GATES["position_timeout"][1])]
HeadingTimeout = Annotated[float, typer.Option("--heading-timeout", help=_GATES["heading_timeout"][1])]
FlushEvery = Annotated[int, typer.Option(metavar="STEPS", help="Steps between writes of --out (a killed session loses at most these).")]


def replay_command(
    log: Annotated[str, typer.Argument(metavar="LOG", help="An NMEA log (TIME SENTENCE lines) or a CSV log (time,north,east,heading).")],
    scenario_file: Annotated[str, typer.Option("--scenario", metavar="SCENARIO.toml", help="The scenario whose observer (kind, gains, vessel model, sample period) runs.")],
    out: Annotated[Optional[str], typer.Option(metavar="FILE.nc", help="The session's estimates as NetCDF (a simulation's layout).")] = None,
    thrust: Annotated[Optional[str], typer.Option(metavar="THRUST.csv", help="Thrust feedback, time,surge,sway,yaw (N, N, N m).", show_default="zero, with a warning")] = None,
    speed: Annotated[Optional[float], typer.Option(metavar="FACTOR", help="Log seconds per wall-clock second.", show_default="--fast")] = None,
    fast: Annotated[bool, typer.Option("--fast", help="As fast as it goes (the default).")] = False,
    publish: Publish = None,
    origin: Origin = None,
    min_quality: MinQuality = Gates.min_quality,
    max_hdop: MaxHdop = Gates.max_hdop,
    position_gate: PositionGate = Gates.position_gate,
    heading_gate: HeadingGate = Gates.heading_gate,
    position_timeout: PositionTimeout = Gates.position_timeout,
    heading_timeout: HeadingTimeout = Gates.heading_timeout,
    flush_every: FlushEvery = 1000,
    truth: Annotated[Optional[str], typer.Option(metavar="TRUTH.nc", help="The run behind a simulated log (lookout write-log), for --figure.")] = None,
    figure: Annotated[Optional[str], typer.Option(metavar="FILE.png", help="Draw the estimates (against --truth if given) from --out.")] = None,
    quiet: Quiet = False,
) -> None:
    """Run a scenario's observer over a recorded log, as it would have run live."""
    from lookout.io.nmea import NmeaParser
    from lookout.live.run import replay

    if speed is not None and fast:
        raise InputError("--speed and --fast exclude each other: give one")
    if speed is not None and not (math.isfinite(speed) and speed > 0):
        raise InputError(f"--speed must be a finite positive factor; got {speed:g}")
    if flush_every < 1:
        raise InputError(f"--flush-every must be a positive number of steps; got {flush_every}")
    if figure is not None and out is None:
        raise InputError("--figure needs --out: the figure is drawn from the session's file")
    if truth is not None and figure is None:
        raise InputError("--truth is for --figure: give --figure FILE.png too")
    figure_path = None
    if figure is not None:
        from lookout._commandline import image_file

        figure_path = image_file("--figure", figure)
    for option, path in (("LOG", log), ("--thrust", thrust), ("--truth", truth)):
        if path is not None and not Path(path).is_file():
            raise InputError(f"{option} must be an existing file; got {path}")
    from lookout.io.logs import log_format

    try:
        if log_format(log) == "csv-thrust":
            raise InputError(f"LOG {log} is a thrust log (time,surge,sway,yaw): give it with --thrust, and a position log as LOG")
        if thrust is not None and log_format(thrust) != "csv-thrust":
            raise InputError(f"--thrust {thrust} must be a CSV log whose first line is time,surge,sway,yaw")
    except ValueError as error:
        raise InputError(str(error)) from None
    say = _say(quiet)
    # paced: one step per compiled call, as live; fast: a scan over blocks of steps
    session = _session(scenario_file, origin, _gates(min_quality, max_hdop, position_gate, heading_gate, position_timeout, heading_timeout), _on_event(say),
                       batch=1 if speed is not None else REPLAY_BATCH)
    emit, close, writer = _outputs(session, out, publish, scenario_file, f"replay of {log}", flush_every)
    parser = NmeaParser()
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            if thrust is None:
                say("no --thrust: the observer predicts with zero input")
            outcome = replay(session, log, thrust=thrust, speed=speed, emit=emit, parser=parser,
                             status=lambda o: say(_status_line(session, parser, o)))
    except ValueError as error:
        raise InputError(str(error)) from None
    finally:  # what was computed is written, whatever stopped the replay
        close()
    if outcome.steps == 0:
        raise InputError(f"{log}: no step was taken: the log never had both a usable position and a heading ({_status_line(session, parser, outcome, True)})")
    span = outcome.last_time - outcome.first_time
    say(_status_line(session, parser, outcome, final=True))
    say(f"{span:.1f} s of log in {outcome.wall_seconds:.2f} s ({span / outcome.wall_seconds:.0f}x real time)" + (f"; written to {out}" if out else ""))
    if figure_path is not None:
        _figure(out, truth, figure_path, log)


def _figure(out: str, truth: Optional[str], path: Path, log: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import xarray as xr

    from lookout.live.figures import plot_session

    with xr.open_dataset(out) as session:
        truth_ds = None
        if truth is not None:
            try:
                truth_ds = xr.open_dataset(truth)
            except (OSError, ValueError) as error:
                raise InputError(f"--truth {truth}: not a NetCDF file lookout can read ({error})") from None
        try:
            fig = plot_session(session.load(), truth_ds, title=f"lookout replay {Path(log).name}")
        except ValueError as error:
            raise InputError(f"--truth {truth}: {error}") from None
    path.absolute().parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"figure: {path}", file=sys.stderr)


def live_command(
    scenario_file: Annotated[str, typer.Argument(metavar="SCENARIO.toml", help="The scenario whose observer (kind, gains, vessel model, sample period) runs.")],
    nmea: Annotated[str, typer.Option(metavar="SOURCE", help="udp://HOST:PORT (bound; HOST default 127.0.0.1), - (stdin) or a serial device or file.")] = "udp://127.0.0.1:10110",
    out: Annotated[Optional[str], typer.Option(metavar="FILE.nc", help="The session's estimates as NetCDF (a simulation's layout).")] = None,
    publish: Publish = None,
    thrust: Annotated[Optional[str], typer.Option(metavar="SOURCE", help="Thrust feedback lines surge,sway,yaw (N, N, N m): udp://HOST:PORT or a path.", show_default="zero, with a warning")] = None,
    duration: Annotated[Optional[float], typer.Option(metavar="SECONDS", help="Stop after this long.")] = None,
    idle: Annotated[Optional[float], typer.Option(metavar="SECONDS", help="Stop when nothing arrived for this long (counted from the first data).")] = None,
    origin: Origin = None,
    min_quality: MinQuality = Gates.min_quality,
    max_hdop: MaxHdop = Gates.max_hdop,
    position_gate: PositionGate = Gates.position_gate,
    heading_gate: HeadingGate = Gates.heading_gate,
    position_timeout: PositionTimeout = Gates.position_timeout,
    heading_timeout: HeadingTimeout = Gates.heading_timeout,
    flush_every: FlushEvery = 100,
    quiet: Quiet = False,
) -> None:
    """Run a scenario's observer live on NMEA 0183 position and heading; stop with Ctrl-C."""
    import jax

    # each step runs on this thread instead of being handed to an XLA worker and waited
    # for: the hand-off is most of a step's cost when the other cores are busy
    # (docs/benchmarks.md, "Live stepping against MCSimPython"); read when JAX's CPU
    # client starts, which nothing before this line has started
    jax.config.update("jax_cpu_enable_async_dispatch", False)
    from lookout.io.nmea import NmeaParser
    from lookout.live.run import live, open_source

    for option, value in (("--duration", duration), ("--idle", idle)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{option} must be a finite positive number of seconds; got {value:g}")
    if flush_every < 1:
        raise InputError(f"--flush-every must be a positive number of steps; got {flush_every}")
    say = _say(quiet)
    session = _session(scenario_file, origin, _gates(min_quality, max_hdop, position_gate, heading_gate, position_timeout, heading_timeout), _on_event(say))
    emit, close, writer = _outputs(session, out, publish, scenario_file, f"live from {nmea}", flush_every)
    try:
        source = open_source(nmea, "--nmea")
        thrust_source = open_source(thrust, "--thrust") if thrust is not None else None
    except ValueError as error:
        close()
        raise InputError(str(error)) from None
    if thrust_source is None:
        say("no --thrust: the observer predicts with zero input")
    parser = NmeaParser()
    session.warm_up()
    say(f"listening on {source[2]} (Ctrl-C stops)")
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            outcome = live(session, source, thrust=thrust_source, emit=emit, parser=parser, duration=duration, idle=idle,
                           status=lambda o: say(_status_line(session, parser, o)))
    finally:  # what was computed is written, whatever stopped the session
        close()
    say(_status_line(session, parser, outcome, final=True) + (f"; written to {out}" if out and outcome.steps else ""))


def write_log_command(
    scenario_file: Annotated[str, typer.Argument(metavar="SCENARIO.toml", help="A vessel scenario (position-heading sensor) to simulate, one run.")],
    out: Annotated[str, typer.Option(metavar="FOLDER", help="Where NAME.nmea, NAME.csv, NAME-thrust.csv and NAME-truth.nc go.")] = "out/log",
    name: Annotated[str, typer.Option(metavar="NAME", help="The files' stem.")] = "dp-vessel",
    origin: Annotated[str, typer.Option(metavar="LAT,LON", help="Where north = east = 0 lies (degrees).")] = "63.44,10.40",
    outage: Annotated[Optional[str], typer.Option(metavar="START,LENGTH", help="Seconds of run time without fixes.")] = "300,30",
    seed: Annotated[int, typer.Option(help="Seed of the arrival jitter and the corruptions (the run's own is the file's).")] = 0,
) -> None:
    """Simulate a scenario once and write what a bridge computer would have logged: GGA
    and THS with arrival times, an outage, corrupted and wild sentences; the same
    samples as CSV, the thrust, and the run's truth."""
    import re

    from lookout._commandline import created_folder, simulating
    from lookout.io.geodesy import LocalFrame
    from lookout.io.simulated_log import write_simulated_log
    from lookout.studies.cli import _scenario

    if not re.fullmatch(r"[A-Za-z0-9._-]+", name):
        raise InputError(f"--name must be a file stem of letters, digits, '.', '_' or '-'; got {name!r}")
    try:
        latitude, longitude = (float(part) for part in origin.split(","))
        frame = LocalFrame(latitude, longitude)
    except ValueError as error:
        detail = str(error) if "must" in str(error) else "two numbers, degrees"
        raise InputError(f"--origin must be LAT,LON in degrees ({detail}); got {origin!r}") from None
    window = None
    if outage is not None and outage.lower() != "none":
        try:
            window = tuple(float(part) for part in outage.split(","))
            if len(window) != 2 or not all(math.isfinite(v) and v >= 0 for v in window):
                raise ValueError
        except ValueError:
            raise InputError(f"--outage must be START,LENGTH in seconds (finite, >= 0) or none; got {outage!r}") from None
    spec, scenario = _scenario(scenario_file, 1, None)
    wanted = {"measured_position", "measured_heading"}
    if not wanted <= set(scenario.sensor.measurement_layout.names):
        raise InputError(f"{scenario_file}: the sensor must measure position and heading (kind position-heading); it measures "
                         f"{', '.join(scenario.sensor.measurement_layout.names)}")
    folder = created_folder("--out", out)
    from lookout.composition import simulate

    with simulating() as progress:
        trajectory = simulate(spec.composition, progress=progress)
    ds = trajectory.to_xarray()
    ds.attrs["scenario"] = scenario_file
    paths = write_simulated_log(ds, folder, name=name, frame=frame, outage=window, seed=seed)
    print("written: " + ", ".join(str(path) for path in paths.values()))


def play_command(
    log: Annotated[str, typer.Argument(metavar="LOG", help="An NMEA log (TIME SENTENCE lines).")],
    to: Annotated[str, typer.Option(metavar="udp://HOST:PORT", help="Where the sentences go.")] = "udp://127.0.0.1:10110",
    speed: Annotated[float, typer.Option(metavar="FACTOR", help="Log seconds per wall-clock second (1: as recorded, what a live observer needs).")] = 1.0,
    duration: Annotated[Optional[float], typer.Option(metavar="SECONDS", help="Stop after this many seconds of log.")] = None,
) -> None:
    """Send an NMEA log's sentences over UDP at the pace they were recorded: a stand-in
    for a ship's network, to try lookout live."""
    import socket
    import time

    from lookout.live.output import parse_udp

    if not (math.isfinite(speed) and speed > 0):
        raise InputError(f"--speed must be a finite positive factor; got {speed:g}")
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise InputError(f"--duration must be a finite positive number of seconds; got {duration:g}")
    if not Path(log).is_file():
        raise InputError(f"LOG must be an existing file; got {log}")
    try:
        address = parse_udp(to, "--to")
    except ValueError as error:
        raise InputError(str(error)) from None
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = skipped = 0
    first = None
    started = time.perf_counter()
    try:
        with open(log, "rb") as handle:
            for raw in handle:
                stamp, _, sentence = raw.strip().partition(b" ")
                try:
                    t = float(stamp)
                except ValueError:
                    skipped += 1  # comments and lines without a time
                    continue
                first = t if first is None else first
                if duration is not None and t - first > duration:
                    break
                ahead = (t - first) / speed - (time.perf_counter() - started)
                if ahead > 0:
                    time.sleep(ahead)
                sender.sendto(sentence.strip() + b"\r\n", address)
                sent += 1
    except KeyboardInterrupt:
        pass
    finally:
        sender.close()
    print(f"sent {sent} sentences to {address[0]}:{address[1]} in {time.perf_counter() - started:.1f} s ({skipped} lines without a time skipped)",
          file=sys.stderr)


def register(app: typer.Typer) -> None:
    """Add ``live``, ``replay`` and ``write-log`` to the ``lookout`` command."""
    app.command("live")(live_command)
    app.command("replay")(replay_command)
    app.command("write-log")(write_log_command)
    app.command("play")(play_command)
