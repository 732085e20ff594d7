"""The loops of ``lookout replay`` and ``lookout live``: readings in, steps out.

Both feed a :class:`~lookout.live.session.Session` the same way: for each reading in
arrival order, first the steps that were due before it arrived, then the reading. A
replay takes its arrival times from the log, a live session from the computer's
clock (Unix time, kept monotone: a step of the system clock does not move it), so a
replayed log gives what the live session gave.

Before a replay takes a step, :func:`check_replay` reads the logs' times once
(:func:`lookout.io.logs.scan_log`) and refuses what the session could not replay
faithfully: a log with nothing to give, a log out of order, a log whose times are not
in seconds, a silence longer than ``max_gap``, a thrust log on another clock.
"""

from __future__ import annotations

import heapq
import math
import os
import select
import socket
import sys
import time as _time
from collections import Counter, deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from io import FileIO
from pathlib import Path
from typing import BinaryIO, cast

import numpy as np

from lookout.io.logs import CSV_HEADERS, CsvLog, LogScan, log_format, nmea_log, scan_log
from lookout.io.nmea import LineSplitter, NmeaParser, Reading
from lookout.live.options import MAX_GAP
from lookout.live.session import Block, Session, check_origin, fix_refusal
from lookout.sim.filtering import check_step_length

#: A live source as :func:`open_source` gives it: ``(kind, handle, where)``, the kind
#: ``"udp"`` (a bound socket) or ``"stream"`` (stdin, a device or a FIFO).
_Source = tuple[str, socket.socket | BinaryIO | FileIO, str]

#: The share of a log's lines that may be stamped before a line above them (reordered
#: by the logger; each is dropped as late); more (and more than one line) is a log out
#: of order.
MAX_LATE_SHARE = 0.01
#: Wall seconds between calls of a replay's ``progress``.
PROGRESS_EVERY = 0.2


class Latencies:
    """The last ``size`` latencies (s), in a fixed array: percentiles in constant memory."""

    def __init__(self, size: int = 100_000):
        self._values = np.zeros(size)
        self._count = 0

    def add(self, value: float) -> None:
        self._values[self._count % self._values.size] = value
        self._count += 1

    def values(self) -> np.ndarray:
        """The kept values, oldest first."""
        if self._count <= self._values.size:
            return self._values[: self._count].copy()
        cut = self._count % self._values.size
        return np.concatenate([self._values[cut:], self._values[:cut]])

    def percentiles(self, which: Iterable[float] = (50, 99, 100)) -> dict:
        """``{p: seconds}`` over the kept values (empty without any)."""
        kept = self._values[: min(self._count, self._values.size)]
        return {p: float(np.percentile(kept, p)) for p in which} if kept.size else {}


@dataclass
class Outcome:
    """What a replay or a live session did."""

    steps: int = 0
    readings: int = 0
    first_time: float | None = None
    last_time: float | None = None
    wall_seconds: float = 0.0
    processing: Latencies = field(default_factory=Latencies)
    latency: Latencies = field(default_factory=Latencies)
    counts: dict = field(default_factory=dict)  # lines by cause (the parser's, or a CSV log's rows)
    thrust_counts: dict = field(default_factory=dict)  # thrust rows or lines by cause (empty without thrust)
    imu_counts: dict = field(default_factory=dict)  # IMU rows or lines by cause (empty without an IMU stream)
    check: ReplayCheck | None = None  # a replay's: what check_replay found
    #: why and where the session failed (its first non-finite estimate), or None: a
    #: replay or live session has no truth, so the rule of a failed run there is the
    #: non-finite half of :func:`lookout.scenario.metrics.failures`
    failure: str | None = None

    @property
    def rejected(self) -> dict:
        """The lines that gave no reading, by cause (zeros left out)."""
        return {cause: n for cause, n in self.counts.items() if cause != "accepted" and n}

    def unused(self, session: Session) -> dict:
        """Every line and reading that ``session`` did not use, by cause: the lines that
        gave no reading (:attr:`rejected`), then the readings the session left
        (:attr:`Session.unused`); zeros left out, thrust apart
        (:attr:`thrust_rejected`)."""
        return {**self.rejected, **session.unused}

    @property
    def thrust_rejected(self) -> dict:
        """The thrust rows or lines that gave no thrust, by cause (zeros left out):
        ``missing`` (an empty or NaN value: the previous thrust stays applied) and
        ``malformed``."""
        return {cause: n for cause, n in self.thrust_counts.items() if cause != "accepted" and n}

    @property
    def imu_rejected(self) -> dict:
        """The IMU rows or lines that gave no reading, by cause (zeros left out):
        ``missing`` (an empty or NaN value: a missed sample) and ``malformed``."""
        return {cause: n for cause, n in self.imu_counts.items() if cause != "accepted" and n}


@dataclass
class ReplayCheck:
    """What :func:`check_replay` found: the scans of the log, the thrust log and the IMU log."""

    log: LogScan
    thrust: LogScan | None = None
    imu: LogScan | None = None


def _described(scan: LogScan) -> str:
    counts = ", ".join(f"{cause} {n}" for cause, n in sorted(scan.usable.items(), key=lambda item: -item[1]))
    return f"{scan.lines} lines: {counts}" if counts else "no line but comments"


def check_log_order(scan: LogScan, tolerance: float) -> None:
    """Refuse (ValueError naming the log) a log without a timed line, or one not in the
    order its lines arrived: a line stamped more than ``tolerance`` seconds before a line
    above it, or more than :data:`MAX_LATE_SHARE` of its lines stamped before one above."""
    where = f"{scan.option} {scan.path}"
    if scan.timed == 0:
        if not scan.usable:
            raise ValueError(f"{where}: no line but comments and blank lines: nothing to replay")
        if scan.format == "nmea-raw":
            raise ValueError(
                f"{where}: no sentence gives a time ({_described(scan)}); a raw NMEA log is timed by its GGA, GNS, GLL, RMC or ZDA sentences' UTC times"
            )
        if scan.format.startswith("csv-"):
            header = next(",".join(columns) for columns, kind in CSV_HEADERS.items() if f"csv-{kind}" == scan.format)
            raise ValueError(
                f"{where}: no row can be read ({_described(scan)}); a row is numbers under the header {header}, the time in seconds first"
            )
        raise ValueError(f"{where}: no line has a time ({_described(scan)}); a log's lines are TIME SENTENCE, TIME in seconds")
    if scan.back > tolerance:
        raise ValueError(
            f"{where}: its times run backwards: line {scan.back_line} is stamped {scan.back:.6g} s before line {scan.back_from} "
            f"(more than {tolerance:g} s: a clock that stepped back, or logs joined out of order); a log must be in the order its lines arrived: sort it, or split it where its clock stepped back"
        )
    if scan.late > max(MAX_LATE_SHARE * scan.timed, 1):
        ends = f"; it ends {scan.first - scan.last:.6g} s before it starts" if scan.last < scan.first else ""
        raise ValueError(
            f"{where}: its times run backwards: {scan.late} of its {scan.timed} timed lines are stamped before a line above them{ends} "
            f"(up to {100 * MAX_LATE_SHARE:g} % are replayed as reordered lines, each dropped as late); a log must be in the order its lines arrived"
        )


def check_replay(
    session: Session,
    log: str | Path,
    thrust: str | Path | None = None,
    max_gap: float = MAX_GAP,
    fmt: str | None = None,
    imu: str | Path | None = None,
) -> ReplayCheck:
    """Refuse, before any step, a log that ``session`` cannot replay faithfully.

    One pass over each log (:func:`lookout.io.logs.scan_log`: times and framing, no
    field parsed), then, each refusal a ``ValueError`` of one line naming the log:

    - the log has no line of a channel the observer reads (every sentence fails its
      checksum, an empty log, a log of comments);
    - its times run backwards: a line stamped more than the longest channel timeout
      before a line above it (a clock that stepped back, two logs joined in the wrong
      order), or more than :data:`MAX_LATE_SHARE` of its lines stamped before a line
      above them (a log reversed or shuffled). Fewer are replayed as reordered lines,
      each counted ``late`` and dropped, as a live session drops them;
    - its times are not in seconds: its typical step between lines (the median) is
      longer than the longest channel timeout and is a step the observer cannot take
      (:func:`lookout.sim.filtering.check_step_length`, the test of
      :func:`lookout.filter`: one prediction step over it amplifies a state error more
      than :data:`~lookout.sim.filtering.MAX_STEP_AMPLIFICATION` times);
    - a silence longer than ``max_gap`` seconds: the session would dead-reckon
      through it, step by step, with nothing to correct it;
    - the thrust log is out of order, has no row with a thrust, or does not overlap
      the log's time span (another clock, or milliseconds); the same of the IMU log
      (``time,fx,fy,r``), which an observer that reads an IMU needs and another cannot use;
    - the session's frame was given and its origin lies farther than
      :data:`~lookout.live.options.MAX_ORIGIN_DISTANCE` from the log's first fix (an
      NMEA log; :class:`~lookout.live.session.OriginError`, which the session would
      raise at that fix).

    Parameters
    ----------
    max_gap : float
        The longest silence accepted (s); default :data:`MAX_GAP`.
    fmt : {"raw", "timed", "csv"}, optional
        The log's format (:data:`lookout.io.logs.FORMATS`), detected when not given.
    """
    if isinstance(max_gap, bool) or not isinstance(max_gap, (int, float, np.floating, np.integer)) or not (math.isfinite(max_gap) and max_gap > 0):
        raise ValueError(f"max_gap must be a finite positive number of seconds; got {max_gap!r}")
    tolerance = session.gap_after
    scan = scan_log(log, "LOG", fmt)
    if scan.format == "csv-thrust":
        raise ValueError(f"LOG {log} is a thrust log (time,surge,sway,yaw): give it as the thrust, and a position log as LOG")
    if scan.format == "csv-imu":
        raise ValueError(f"LOG {log} is an IMU log (time,fx,fy,r): give it as the IMU's, and a position log as LOG")
    imu_sensor = next((channel.name for channel in session.channels.values() if channel.kind == "imu"), None)
    if imu_sensor is not None and imu is None:
        raise ValueError(f"the observer reads sensor {imu_sensor}, an IMU: give imu, the CSV log of its readings (time,fx,fy,r)")
    if imu is not None and imu_sensor is None:
        raise ValueError(f"the observer reads no IMU (a Kalman filter or the IMU-aided observer on a suite with an IMU does): leave imu ({imu}) out")
    check_log_order(scan, tolerance)
    for kind in session.kinds:
        if not scan.usable[kind]:
            raise ValueError(f"LOG {log}: no line gives a {kind} reading ({_described(scan)}); the observer needs {' and '.join(session.kinds)}")
    typical = scan.typical_step
    if typical > tolerance and session.observer.sample_period is None:
        observer = session.observer
        zeros = np.zeros(observer.measurement_layout.size), np.zeros(observer.input_layout.size)
        check_step_length(
            observer, session.guess if session.guess is not None else observer.guess(), *zeros, typical, f"LOG {log}: its typical step between lines,"
        )
    if scan.longest_gap > max_gap:
        hint = " (are the times in seconds?)" if typical > max_gap else ""
        raise ValueError(
            f"LOG {log}: no line for {scan.longest_gap:.6g} s before line {scan.gap_line} ({scan.gap_start - scan.first:.6g} s into the log), "
            f"longer than max_gap {max_gap:g} s{hint}; a replay would dead-reckon through it with nothing to correct it: give a longer max_gap to replay it anyway, or split the log there"
        )
    if session.frame is not None and scan.format in ("nmea", "nmea-raw"):
        fix = first_fix(log, session, scan.format)
        if fix is not None:
            check_origin(session.frame, *fix, where="the log's first fix")
    check = ReplayCheck(scan)
    if thrust is not None:
        check.thrust = _side_scan(thrust, "--thrust", "thrust", "time,surge,sway,yaw", scan, tolerance)
    if imu is not None:
        check.imu = _side_scan(imu, "--imu", "imu", "time,fx,fy,r", scan, tolerance)
    return check


def _side_scan(path: str | Path, option: str, kind: str, header: str, scan: LogScan, tolerance: float) -> LogScan:
    """The scan of a CSV log beside ``scan``'s (thrust, IMU), refused when it is of
    another kind, out of order, without a row of ``kind``, or off the log's clock."""
    side = scan_log(path, option)
    if side.format != f"csv-{kind}":
        raise ValueError(f"{option} {path} must be a CSV log whose first line is {header}")
    check_log_order(side, tolerance)
    if not side.usable[kind]:
        raise ValueError(f"{option} {path}: no row gives {'a thrust' if kind == 'thrust' else 'an IMU reading'} ({_described(side)})")
    if side.newest < scan.first or side.first > scan.newest:
        raise ValueError(
            f"{option} {path}: its times ({side.first:.3f} to {side.newest:.3f} s) do not overlap the log's "
            f"({scan.first:.3f} to {scan.newest:.3f} s); are both in seconds, on the same clock?"
        )
    return side


def first_fix(log: str | Path, session: Session, fmt: str = "nmea") -> tuple[float, float] | None:
    """(latitude, longitude) of the first fix of an NMEA log (``fmt`` ``"nmea"`` or
    ``"nmea-raw"``) that ``session``'s gates pass (None without one); the log is read up
    to it."""
    for reading in nmea_log(log, NmeaParser(), fmt):
        if reading.kind == "position" and fix_refusal(reading.values, session.gates) is None:
            return reading.values[0], reading.values[1]
    return None


def _side_line(line: bytes, time: float, counts: dict[str, int] | None = None, kind: str = "thrust") -> Reading | None:
    """A live line of a stream beside the NMEA one, a thrust ``surge,sway,yaw`` (N, N,
    N m) or an IMU's ``fx,fy,r`` (m/s2, m/s2, deg/s) as ``kind`` says, or None if it is
    not one (counted in ``counts``: ``malformed``, or ``missing`` for an empty or NaN
    value, which leaves the previous thrust applied, or misses an IMU sample)."""
    counts = Counter() if counts is None else counts
    try:
        values = tuple(float(cell) if cell.strip() else math.nan for cell in line.decode("ascii").strip().split(","))
    except (UnicodeDecodeError, ValueError):
        values = ()
    if len(values) != 3 or any(math.isinf(v) for v in values):
        counts["malformed"] += 1
        return None
    if not all(math.isfinite(v) for v in values):
        counts["missing"] += 1
        return None
    counts["accepted"] += 1
    return Reading(time, kind, kind, values, "CSV")


def log_readings(path: str | Path, parser: NmeaParser, kind: str | None = None) -> tuple[Iterator[Reading], Counter]:
    """``(readings, counter)`` of a log of any format (:mod:`lookout.io.logs`; ``kind``
    as :func:`~lookout.io.logs.log_format` names it, detected when not given)."""
    kind = kind if kind is not None else log_format(path)
    if kind in ("nmea", "nmea-raw"):
        return nmea_log(path, parser, kind), parser.counts
    log = CsvLog(path)
    if log.kind != "position":
        raise ValueError(f"log {path}: a thrust log (time,surge,sway,yaw) is given with --thrust, not as the log")
    return iter(log), log.counts


def replay(
    session: Session,
    log: str | Path,
    *,
    thrust: str | Path | None = None,
    imu: str | Path | None = None,
    speed: float | None = None,
    emit: Callable[[Block], object] | None = None,
    parser: NmeaParser | None = None,
    status: Callable[[Outcome], object] | None = None,
    status_every: float = 5.0,
    max_gap: float = MAX_GAP,
    check: ReplayCheck | None = None,
    progress: Callable[[float, float], object] | None = None,
    fmt: str | None = None,
) -> Outcome:
    """Step ``session`` through a log; ``emit(record)`` for each step.

    The logs are checked first (:func:`check_replay`); thrust and IMU rows after the
    log's last line are not used (the session ends with the log).

    Parameters
    ----------
    speed : float, optional
        Log seconds per wall-clock second (10: ten times real time); None as fast as
        it goes.
    status : callable, optional
        Called with the :class:`Outcome` every ``status_every`` wall seconds.
    max_gap : float
        The longest silence of the log accepted (s), :func:`check_replay`.
    check : ReplayCheck, optional
        What :func:`check_replay` gave for these logs and ``session``, when the caller
        has checked them already (they are not read twice).
    progress : callable, optional
        Called with ``(done, total)``, the log's seconds replayed and its span, about
        every :data:`PROGRESS_EVERY` wall seconds and once at the end (``done ==
        total``).
    fmt : {"raw", "timed", "csv"}, optional
        The log's format (:data:`lookout.io.logs.FORMATS`), detected when not given.

    Raises
    ------
    ValueError
        As :func:`check_replay`, before any step.
    """
    check = check if check is not None else check_replay(session, log, thrust, max_gap, fmt, imu)
    parser = parser or NmeaParser()
    readings, counts = log_readings(log, parser, check.log.format)
    thrust_log = CsvLog(thrust, source="thrust", option="--thrust") if thrust is not None else None
    imu_log = CsvLog(imu, source="imu", option="--imu") if imu is not None else None
    outcome = Outcome(
        counts=counts,
        thrust_counts=thrust_log.counts if thrust_log is not None else {},
        imu_counts=imu_log.counts if imu_log is not None else {},
        check=check,
    )
    started = _time.perf_counter()
    last_status = last_progress = started
    span = check.log.span
    for reading in _merged(readings, *(iter(side) for side in (thrust_log, imu_log) if side is not None)):
        if outcome.first_time is None:
            outcome.first_time = reading.time
        if speed is not None:
            ahead = (reading.time - outcome.first_time) / speed - (_time.perf_counter() - started)
            if ahead > 0:
                _time.sleep(ahead)
        _emit(session.advance(reading.time), emit, outcome)
        _emit(session.feed(reading), emit, outcome)
        outcome.readings += 1
        outcome.last_time = max(reading.time, outcome.last_time if outcome.last_time is not None else -math.inf)
        if status is not None and _time.perf_counter() - last_status > status_every:
            last_status = _time.perf_counter()
            outcome.wall_seconds = last_status - started
            status(outcome)
        if progress is not None and _time.perf_counter() - last_progress > PROGRESS_EVERY:
            last_progress = _time.perf_counter()
            progress(min(max(reading.time - check.log.first, 0.0), span), span)
    if outcome.last_time is not None:  # through the step that uses the last reading
        last_step = session.time_of(math.ceil(outcome.last_time / session.sample_period - 1e-9))
        _emit(session.advance(math.nextafter(last_step, math.inf)), emit, outcome)
    _emit(session.finish(), emit, outcome)
    outcome.wall_seconds = _time.perf_counter() - started
    if progress is not None:
        progress(span, span)
    return outcome


def _merged(readings, *sides):
    """The log's readings with the readings of the logs beside it (thrust, IMU) stamped
    before each (a side reading and a reading of one time: the reading first; of two
    sides' of one time, the first side's); none after the log's last reading."""
    if not sides:
        yield from readings
        return
    side = heapq.merge(*sides, key=lambda reading: reading.time)
    pending = next(side, None)
    for reading in readings:
        while pending is not None and pending.time < reading.time:
            yield pending
            pending = next(side, None)
        yield reading


def _first_non_finite(block: Block, steps_before: int) -> str | None:
    """``at t = ... s into the session (step k): NAME_hat is not finite`` for the first
    non-finite estimate of ``block`` (its gate and outage flags aside), or None."""
    first = None
    for name, values in block.estimate.items():
        values = np.asarray(values)
        if name.startswith(("gated_", "outage_")) or values.dtype.kind not in "fc":
            continue
        bad = ~np.isfinite(values.reshape(len(block), -1)).all(axis=1)
        if bad.any() and (first is None or int(np.argmax(bad)) < first[0]):
            first = (int(np.argmax(bad)), name)
    if first is None:
        return None
    row, name = first
    return f"at t = {float(block.session_time[row]):g} s into the session (step {steps_before + row}): {name}_hat is not finite"


def _emit(blocks, emit, outcome: Outcome, arrivals: deque | None = None, clock=None) -> None:
    """Hand each block to ``emit`` and count it; live (``arrivals`` of the readings not yet
    in a step, and the ``clock``), the latency from the newest reading a step used to its
    estimate leaving."""
    for block in blocks:
        if emit is not None:
            emit(block)
        if outcome.failure is None:
            outcome.failure = _first_non_finite(block, outcome.steps)
        if arrivals is not None:
            left = clock()
            newest = None
            while arrivals and arrivals[0] <= block.time[-1]:
                newest = arrivals.popleft()
            if newest is not None:
                outcome.latency.add(left - newest)
        outcome.steps += len(block)
        outcome.processing.add(float(block.step_seconds[0]))


def open_source(text: str, option: str = "--nmea") -> _Source:
    """A live source: ``udp://HOST:PORT`` (a bound socket; HOST default 127.0.0.1), ``-``
    (stdin) or a path (a serial device or a file), as ``(kind, handle, where)``."""
    from lookout.live.output import parse_udp

    if text.startswith("udp://"):
        host, port = parse_udp(text, option, any_port=True)
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError as error:
            sock.close()
            raise ValueError(f"{option} {text}: cannot bind {host}:{port} ({error.strerror or error})") from None
        sock.setblocking(False)
        return "udp", sock, "{}:{}".format(*sock.getsockname()[:2])
    if text == "-":
        return "stream", sys.stdin.buffer, "stdin"
    path = Path(text)
    if not path.exists():
        raise ValueError(f"{option} must be udp://HOST:PORT, - (stdin) or an existing serial device or FIFO; {text} does not exist")
    if path.is_file():
        raise ValueError(
            f"{option} {text} is a regular file: its lines have no arrival times live; replay a log with lookout replay, or give a stream (udp://, -, a device or a FIFO)"
        )
    if path.is_dir():
        raise ValueError(f"{option} {text} is a folder; give udp://HOST:PORT, - (stdin), a serial device or a FIFO")
    try:
        handle = path.open("rb", buffering=0)
    except OSError as error:
        raise ValueError(f"{option} {text}: cannot be opened ({error.strerror or error})") from None
    return "stream", handle, str(path)


def unix_clock() -> Callable[[], float]:
    """A clock of Unix time that never steps: Unix time when it is made, then the
    monotonic clock's seconds since (a live session's clock: a system clock set back
    by NTP or by hand would make the readings after it late, and one set forward a gap)."""
    origin, start = _time.time(), _time.monotonic()
    return lambda: origin + (_time.monotonic() - start)


def live(
    session: Session,
    source: _Source,
    *,
    thrust: _Source | None = None,
    imu: _Source | None = None,
    emit: Callable[[Block], object] | None = None,
    parser: NmeaParser | None = None,
    duration: float | None = None,
    idle: float | None = None,
    status: Callable[[Outcome], object] | None = None,
    status_every: float = 5.0,
    clock: Callable[[], float] | None = None,
) -> Outcome:
    """Step ``session`` on a live source (from :func:`open_source`) until ``duration``
    seconds have passed, nothing arrived for ``idle`` seconds, the stream ends, or
    Ctrl-C. ``thrust`` is a second source of ``surge,sway,yaw`` lines, ``imu`` one of
    an IMU's ``fx,fy,r`` lines (m/s2, m/s2, deg/s). ``clock``
    (seconds) stamps each reading's arrival; default :func:`unix_clock`.

    Raises
    ------
    lookout.live.session.OriginError
        At the first fix, when the session's given frame has its origin farther than
        :data:`~lookout.live.options.MAX_ORIGIN_DISTANCE` from it (no step taken yet).
    """
    clock = clock or unix_clock()
    parser = parser or NmeaParser()
    kind, handle, where = source
    splitter = LineSplitter()
    outcome = Outcome(counts=parser.counts, thrust_counts=Counter() if thrust is not None else {}, imu_counts=Counter() if imu is not None else {})
    # the streams beside the NMEA one, by handle: (their kind, source kind, line splitter, counts)
    sides = {
        side[1]: (name, side[0], LineSplitter(), counts)
        for name, side, counts in (("thrust", thrust, outcome.thrust_counts), ("imu", imu, outcome.imu_counts))
        if side is not None
    }
    started = clock()
    last_heard = None  # --idle counts from the first data
    last_status = started
    arrivals: deque = deque(maxlen=64)  # (arrival time) of readings not yet in a step
    handles = [handle, *sides]
    ended = False
    try:
        while not ended:
            now = clock()
            if duration is not None and now - started >= duration:
                break
            if idle is not None and last_heard is not None and now - last_heard >= idle:
                break
            next_time = session.next_step_time  # None until the first step
            due = next_time if next_time is not None else now + 0.05
            wait = max(0.0, min(due - now, 0.05))
            ready, _, _ = select.select(handles, [], [], wait)
            for ready_handle in ready:
                side = sides.get(ready_handle)
                if (side[1] if side is not None else kind) == "udp":
                    try:  # a udp source's handle is its socket
                        data, address = cast(socket.socket, ready_handle).recvfrom(65536)
                    except BlockingIOError:
                        continue
                    origin = address[0]  # by address: a sender may use a new port per datagram
                    lines = data.splitlines()
                else:
                    # what has arrived, not a full buffer (a buffered read of stdin waits for 64 KiB)
                    data = os.read(ready_handle.fileno(), 65536)
                    if not data:
                        handles.remove(ready_handle)
                        if side is None:
                            ended = True
                            lines = splitter.flush()
                            arrival = clock()
                            for reading in (r for line in lines for r in parser.line(line, arrival, "")):
                                arrivals.append(reading.time)
                                _emit(session.feed(reading), emit, outcome, arrivals, clock)
                        continue
                    origin = ""
                    lines = (side[2] if side is not None else splitter).feed(data)
                arrival = clock()
                last_heard = arrival
                if side is not None:
                    readings = [r for r in (_side_line(line, arrival, side[3], side[0]) for line in lines) if r is not None]
                elif kind == "udp":
                    readings = parser.datagram(data, arrival, origin)
                else:
                    readings = [r for line in lines for r in parser.line(line, arrival, origin)]
                for reading in readings:
                    _emit(session.advance(reading.time), emit, outcome, arrivals, clock)
                    arrivals.append(reading.time)
                    _emit(session.feed(reading), emit, outcome, arrivals, clock)
                    outcome.readings += 1
                    if outcome.first_time is None:
                        outcome.first_time = reading.time
                    outcome.last_time = reading.time
            _emit(session.advance(clock()), emit, outcome, arrivals, clock)
            if status is not None and clock() - last_status > status_every:
                last_status = clock()
                outcome.wall_seconds = last_status - started
                status(outcome)
    except KeyboardInterrupt:
        pass
    outcome.wall_seconds = clock() - started
    return outcome
