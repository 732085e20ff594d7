"""The loops of ``lookout replay`` and ``lookout live``: readings in, steps out.

Both feed a :class:`~lookout.live.session.Session` the same way: for each reading in
arrival order, first the steps that were due before it arrived, then the reading. A
replay takes its arrival times from the log, a live session from the computer's
clock (Unix time), so a replayed log gives what the live session gave.
"""

from __future__ import annotations

import heapq
import math
import os
import select
import socket
import sys
import time as _time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lookout.io.logs import CsvLog, log_format, nmea_log
from lookout.io.nmea import LineSplitter, NmeaParser, Reading
from lookout.live.session import Session


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

    def percentiles(self, which=(50, 99, 100)) -> dict:
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

    @property
    def rejected(self) -> dict:
        """The lines that gave no reading, by cause (zeros left out)."""
        return {cause: n for cause, n in self.counts.items() if cause != "accepted" and n}


def _thrust_line(line: bytes, time: float) -> Reading | None:
    """A live thrust line ``surge,sway,yaw`` (N, N, N m), or None if it is not one."""
    try:
        values = tuple(float(cell) for cell in line.decode("ascii").strip().split(","))
    except (UnicodeDecodeError, ValueError):
        return None
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        return None
    return Reading(time, "thrust", "thrust", values, "CSV")


def log_readings(path: str | Path, parser: NmeaParser):
    """``(readings, counter)`` of a log of either format (:mod:`lookout.io.logs`)."""
    kind = log_format(path)
    if kind == "nmea":
        return nmea_log(path, parser), parser.counts
    log = CsvLog(path)
    if log.kind != "position":
        raise ValueError(f"log {path}: a thrust log (time,surge,sway,yaw) is given with --thrust, not as the log")
    return iter(log), log.counts


def replay(session: Session, log: str | Path, *, thrust: str | Path | None = None, speed: float | None = None,
           emit=None, parser: NmeaParser | None = None, status=None, status_every: float = 5.0) -> Outcome:
    """Step ``session`` through a log; ``emit(record)`` for each step.

    Parameters
    ----------
    speed : float, optional
        Log seconds per wall-clock second (10: ten times real time); None as fast as
        it goes.
    status : callable, optional
        Called with the :class:`Outcome` every ``status_every`` wall seconds.
    """
    parser = parser or NmeaParser()
    readings, counts = log_readings(log, parser)
    streams = [readings]
    if thrust is not None:
        thrust_log = CsvLog(thrust, source="thrust")
        if thrust_log.kind != "thrust":
            raise ValueError(f"--thrust {thrust}: the first line must be time,surge,sway,yaw")
        streams.append(iter(thrust_log))
    outcome = Outcome(counts=counts)
    started = _time.perf_counter()
    last_status = started
    for reading in heapq.merge(*streams, key=lambda r: r.time) if len(streams) > 1 else streams[0]:
        if outcome.first_time is None:
            outcome.first_time = reading.time
        if speed is not None:
            ahead = (reading.time - outcome.first_time) / speed - (_time.perf_counter() - started)
            if ahead > 0:
                _time.sleep(ahead)
        _emit(session.advance(reading.time), emit, outcome)
        _emit(session.feed(reading), emit, outcome)
        outcome.readings += 1
        outcome.last_time = reading.time
        if status is not None and _time.perf_counter() - last_status > status_every:
            last_status = _time.perf_counter()
            outcome.wall_seconds = last_status - started
            status(outcome)
    if outcome.last_time is not None:  # through the step that uses the last reading
        last_step = session.time_of(math.ceil(outcome.last_time / session.sample_period - 1e-9))
        _emit(session.advance(math.nextafter(last_step, math.inf)), emit, outcome)
    _emit(session.finish(), emit, outcome)
    outcome.wall_seconds = _time.perf_counter() - started
    return outcome


def _emit(blocks, emit, outcome: Outcome, arrivals: deque | None = None, clock=None) -> None:
    """Hand each block to ``emit`` and count it; live (``arrivals`` of the readings not yet
    in a step, and the ``clock``), the latency from the newest reading a step used to its
    estimate leaving."""
    for block in blocks:
        if emit is not None:
            emit(block)
        if arrivals is not None:
            left = clock()
            newest = None
            while arrivals and arrivals[0] <= block.time[-1]:
                newest = arrivals.popleft()
            if newest is not None:
                outcome.latency.add(left - newest)
        outcome.steps += len(block)
        outcome.processing.add(float(block.step_seconds[0]))


def open_source(text: str, option: str = "--nmea"):
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
        raise ValueError(f"{option} must be udp://HOST:PORT, - (stdin) or an existing device or file; {text} does not exist")
    if path.is_file():
        raise ValueError(f"{option} {text} is a regular file: its lines have no arrival times live; replay a log with lookout replay, or pipe a stream to --nmea -")
    try:
        handle = path.open("rb", buffering=0)
    except OSError as error:
        raise ValueError(f"{option} {text}: cannot be opened ({error.strerror or error})") from None
    return "stream", handle, str(path)


def live(session: Session, source, *, thrust=None, emit=None, parser: NmeaParser | None = None, duration: float | None = None,
         idle: float | None = None, status=None, status_every: float = 5.0, clock=_time.time) -> Outcome:
    """Step ``session`` on a live source (from :func:`open_source`) until ``duration``
    seconds have passed, nothing arrived for ``idle`` seconds, the stream ends, or
    Ctrl-C. ``thrust`` is a second source of ``surge,sway,yaw`` lines."""
    parser = parser or NmeaParser()
    kind, handle, where = source
    splitter = LineSplitter()
    thrust_splitter = LineSplitter()
    outcome = Outcome(counts=parser.counts)
    started = clock()
    last_heard = None  # --idle counts from the first data
    last_status = started
    arrivals: deque = deque(maxlen=64)  # (arrival time) of readings not yet in a step
    handles = [handle] + ([thrust[1]] if thrust is not None else [])
    ended = False
    try:
        while not ended:
            now = clock()
            if duration is not None and now - started >= duration:
                break
            if idle is not None and last_heard is not None and now - last_heard >= idle:
                break
            due = session.next_step_time if session.step_index is not None else now + 0.05
            wait = max(0.0, min(due - now, 0.05))
            ready, _, _ = select.select(handles, [], [], wait)
            for ready_handle in ready:
                is_thrust = thrust is not None and ready_handle is thrust[1]
                if (thrust[0] if is_thrust else kind) == "udp":
                    try:
                        data, address = ready_handle.recvfrom(65536)
                    except BlockingIOError:
                        continue
                    origin = address[0]  # by address: a sender may use a new port per datagram
                    lines = data.splitlines()
                else:
                    # what has arrived, not a full buffer (a buffered read of stdin waits for 64 KiB)
                    data = os.read(ready_handle.fileno(), 65536)
                    if not data:
                        handles.remove(ready_handle)
                        if not is_thrust:
                            ended = True
                            lines = splitter.flush()
                            arrival = clock()
                            for reading in (r for line in lines for r in parser.line(line, arrival, "")):
                                arrivals.append(reading.time)
                                _emit(session.feed(reading), emit, outcome, arrivals, clock)
                        continue
                    origin = ""
                    lines = (thrust_splitter if is_thrust else splitter).feed(data)
                arrival = clock()
                last_heard = arrival
                if is_thrust:
                    readings = [r for r in (_thrust_line(line, arrival) for line in lines) if r is not None]
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
