"""Recorded logs: raw NMEA, NMEA sentences with arrival times, and CSV for users without NMEA.

Three formats (:data:`FORMATS`), told apart by the first line that is not blank or a
``#`` comment (:func:`log_format`), or named by the caller:

- **raw NMEA** (``raw``; what chart plotters, VDRs, OpenCPN, kplex and gpsd captures
  save): one sentence a line as it came, ``$``, ``!`` or a tag block ``\\`` first, no
  time column. Each line's time is read from the sentences
  (:mod:`lookout.io.sentence_time`: UTC times of day, RMC's and ZDA's dates, midnight
  rollover; a line between two timed sentences is at the time of the one above it).
  CR, LF and CR LF line ends alike.
- **timed NMEA** (``timed``; ``.nmea`` by convention): one sentence a line after the
  time it arrived, ``TIME SENTENCE``, TIME in seconds (Unix time or any other origin);
  lines starting with ``#`` are comments. Tag blocks and 61162-450 headers may stay on
  the sentence.
- **CSV** (``csv``): a header naming its columns, then one row per sample.
  ``time,north,east,heading`` gives local position (m, about any origin) and heading
  (degrees, true); an empty cell is a missing value. ``time,surge,sway,yaw`` gives
  thrust feedback (N, N, N m), the input the observer predicts with.
  ``time,fx,fy,r`` gives an IMU's readings: the specific force along its forward and
  starboard axes (m/s2) and its yaw rate (degrees a second, clockwise seen from above,
  as the heading's degrees); NMEA 0183 has no standard sentence for them.

Both are read line by line, in constant memory, as :class:`~lookout.io.nmea.Reading`
objects; a line that cannot be read is counted (``counts``), never raised.
:func:`scan_log` reads a log's times and framing once, cheaply, before a replay: its
order, its gaps and its typical step, and how many lines can give a reading.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from io import BufferedReader
from pathlib import Path

import numpy as np

from lookout.io.nmea import HEADING_SENTENCES, POSITION_SENTENCES, NmeaParser, Reading
from lookout.io.sentence_time import SpreadClock, anchor_day

#: The formats a caller can name (``--format``), and what :func:`log_format` calls them.
FORMATS = {"raw": "nmea-raw", "timed": "nmea", "csv": "csv"}
#: Steps between a channel's distinct times kept for its median (a sensor's rate
#: shows in its first ones; memory stays bounded).
INSTANT_STEPS = 10_000
#: Lines read for a log's first line that is not blank or a comment before giving up.
HEAD_LINES = 10_000

#: CSV headers and the reading kinds their rows give.
CSV_HEADERS = {
    ("time", "north", "east", "heading"): "position",
    ("time", "surge", "sway", "yaw"): "thrust",
    ("time", "fx", "fy", "r"): "imu",
}
#: The CSV kinds whose row is one reading of three values, given whole or not at all.
WHOLE_ROWS = ("thrust", "imu")


def csv_headers() -> str:
    """The CSV headers in words: ``time,north,east,heading, time,surge,sway,yaw or ...``."""
    headers = [",".join(header) for header in CSV_HEADERS]
    return ", ".join(headers[:-1]) + " or " + headers[-1]


#: Bytes read to tell a log's format, and to tell text from binary data.
HEAD_BYTES = 4096
#: The UTF-8 byte-order mark some editors write at a text file's start (Excel's
#: "CSV UTF-8", Windows Notepad): it is skipped, and :func:`has_bom` says it was there.
UTF8_BOM = b"\xef\xbb\xbf"
#: What a command says, once, about a log that starts with :data:`UTF8_BOM`.
BOM_NOTE = "a UTF-8 byte-order mark at the start was skipped"


def has_bom(path: str | Path) -> bool:
    """Whether the file starts with a UTF-8 byte-order mark (False when it cannot be read)."""
    try:
        with Path(path).open("rb") as handle:
            return handle.read(len(UTF8_BOM)) == UTF8_BOM
    except OSError:
        return False


def open_log(path: str | Path) -> BufferedReader:
    """The log opened for reading bytes, after a UTF-8 byte-order mark if it starts with
    one: every reader of a log (its format, its scan, its readings) sees its first line
    as written, not with the mark glued to its time or its header."""
    handle = Path(path).open("rb")
    if handle.read(len(UTF8_BOM)) != UTF8_BOM:
        handle.seek(0)
    return handle


def _is_binary(head: bytes) -> bool:
    """Whether the first bytes of a file are not text: a NUL byte, a byte sequence that
    is not UTF-8, or more than 1 % control characters other than tab and line ends."""
    if b"\x00" in head:
        return True
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as error:
        if error.start < len(head) - 3:  # not a character cut at the end of the head
            return True
    control = sum(1 for byte in head if (byte < 32 and byte not in (9, 10, 13)) or byte == 127)
    return control > 0.01 * len(head)


#: What a raw NMEA line starts with: a sentence, an AIS message or a tag block.
NMEA_STARTS = (b"$", b"!", b"\\")


def log_format(path: str | Path, option: str = "log", forced: str | None = None) -> str:
    """``"nmea-raw"``, ``"nmea"`` (timed), ``"csv-position"``, ``"csv-thrust"`` or ``"csv-imu"``, from
    the file's first line that is not blank or a ``#`` comment (a CSV's header is its
    first line), or as ``forced`` says (a key of :data:`FORMATS`).

    Parameters
    ----------
    path : path
    option : str
        How messages name the file (``LOG``, ``--thrust``).
    forced : {"raw", "timed", "csv"}, optional
        The format, not detected (a CSV's header still tells position from thrust).

    Raises
    ------
    ValueError
        Naming ``option`` and the file when it cannot be read, is empty, holds binary
        data, its first line is a CSV header of no kind it reads, or ``forced`` is not a
        format.
    """
    if forced is not None and forced not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}; got {forced!r}")
    path = Path(path)
    try:
        with open_log(path) as handle:
            head = handle.read(HEAD_BYTES)
            handle.seek(len(UTF8_BOM) if has_bom(path) else 0)
            first_line = next(
                (line.strip() for _, line in zip(range(HEAD_LINES), _lines(handle)) if line.strip() and not line.lstrip().startswith(b"#")), b""
            )
    except OSError as error:
        raise ValueError(f"{option} {path}: cannot be read ({error.strerror or error})") from None
    if not head.strip():
        raise ValueError(f"{option} {path} is empty" + (" (only blank lines)" if head else ""))
    if _is_binary(head):
        raise ValueError(f"{option} {path} is not a text log: it holds binary data (a log is text: NMEA sentences, TIME SENTENCE lines, or CSV)")
    first = head.replace(b"\r", b"\n").split(b"\n", 1)[0]
    header = tuple(cell.strip() for cell in first.decode("ascii", "replace").strip().lower().split(","))
    raw = first_line.startswith(NMEA_STARTS)
    wanted = csv_headers()  # a CSV header, for the messages
    if header in CSV_HEADERS and forced in (None, "csv"):
        return f"csv-{CSV_HEADERS[header]}"
    if forced == "csv":
        if raw or (first_line[:1].isdigit() and b" $" in first_line[:40]):
            kind, name = ("raw NMEA", "raw") if raw else ("TIME SENTENCE NMEA", "timed")
            raise ValueError(
                f"{option} {path}: a CSV log's first line must be {wanted}; this is a {kind} log: leave the format out (auto), or give {name}"
            )
        if first.lstrip().startswith(b"#"):
            raise ValueError(
                f"{option} {path}: a CSV log's first line must be {wanted}; its first line is a comment (a CSV log starts with its header)"
            )
        raise ValueError(f"{option} {path}: a CSV log's first line must be {wanted}; got {first.strip()[:60].decode('ascii', 'replace')!r}")
    if forced is not None:
        return FORMATS[forced]
    if raw:
        return "nmea-raw"
    if b"," in first and not first.lstrip().startswith((b"#", *NMEA_STARTS)) and b" " not in first.strip()[:40]:
        shown = first.strip()[:60].decode("ascii", "replace")
        raise ValueError(f"{option} {path}: a CSV log's first line must be {wanted}; got {shown!r}")
    return "nmea"


def _framed_sentences(path: str | Path, parser: NmeaParser) -> Iterator[tuple[str, bytes]]:
    """``(formatter, body)`` of a raw log's well-framed sentences, in file order."""
    with open_log(path) as handle:
        for raw in _lines(handle):
            cause, formatter, body = parser.framed(raw)
            if cause == "accepted":
                yield formatter, body


def _lines(handle: BufferedReader) -> Iterator[bytes]:
    """A file's lines, ended by LF, CR LF or CR alone (a CR-only file is one line to
    ``for line in handle``)."""
    for raw in handle:
        if b"\r" in raw.rstrip(b"\r\n"):
            yield from raw.replace(b"\r\n", b"\n").replace(b"\r", b"\n").splitlines()
        else:
            yield raw


def raw_clock(path: str | Path, require_checksum: bool = True) -> SpreadClock:
    """A fresh :class:`~lookout.io.sentence_time.SpreadClock` for a raw log, anchored
    at its first date (the log is read up to it)."""
    return SpreadClock(anchor_day(_framed_sentences(path, NmeaParser(require_checksum=require_checksum))))


def _kind_key(line: bytes, body: bytes) -> bytes:
    """What a raw log's lines of one kind share: the tag block in front and the address."""
    prefix = line[: line.find(b"$")] if line.startswith(b"\\") else b""
    return prefix + body.split(b",", 1)[0]


def raw_log_times(path: str | Path, parser: NmeaParser, clock: SpreadClock | None = None) -> Iterator[tuple[int, bytes, str, str, float]]:
    """``(number, line, cause, formatter, time)`` of each line of a raw log that is not
    blank or a comment, in file order: its number in the file (from 1), its framing
    (:meth:`~lookout.io.nmea.NmeaParser.framed`: nothing counted) and its time from the
    sentences (``clock``, :func:`raw_clock`'s unless given; NaN before the first time)."""
    clock = clock if clock is not None else raw_clock(path, parser.require_checksum)
    with open_log(path) as handle:
        for number, raw in enumerate(_lines(handle), start=1):
            line = raw.strip()
            if not line or line.startswith(b"#"):
                continue
            cause, formatter, body = parser.framed(line)
            for item, time in clock.feed((number, line, cause, formatter), formatter, body, _kind_key(line, body)):
                yield (*item, time)  # type: ignore[misc]  # the item fed in above
    for item, time in clock.flush():
        yield (*item, time)  # type: ignore[misc]


def nmea_log(path: str | Path, parser: NmeaParser, fmt: str = "nmea") -> Iterator[Reading]:
    """The readings of an NMEA log, in file order; unreadable lines go to ``parser.counts``.

    ``fmt`` is ``"nmea"`` (timed, ``TIME SENTENCE``) or ``"nmea-raw"``: each line's
    time is then read from the sentences (:func:`raw_log_times`), and a sentence before
    the first time is counted ``untimed``."""
    if fmt == "nmea-raw":
        for _, line, cause, _, time in raw_log_times(path, parser):
            if math.isnan(time) and cause == "accepted":
                parser.counts["untimed"] += 1
            else:  # a line refused by its framing is counted under its cause, whatever its time
                yield from parser.line(line, time)
        return
    with open_log(path) as handle:
        for raw in _lines(handle):
            yield from nmea_log_line(raw, parser)


def nmea_log_line(raw: bytes, parser: NmeaParser) -> list[Reading]:
    """The readings of one ``TIME SENTENCE`` line (a comment or blank line gives none)."""
    line = raw.strip()
    if not line or line.startswith(b"#"):
        return []
    stamp, _, sentence = line.partition(b" ")
    try:
        time = float(stamp)
    except ValueError:
        time = math.nan
    if not math.isfinite(time):
        parser.counts["malformed"] += 1
        return []
    return parser.line(sentence.strip(), time)


class CsvLog:
    """Readings from a CSV log (position-and-heading, thrust or IMU), row by row.

    Attributes
    ----------
    counts : collections.Counter
        Rows by cause: ``accepted``, ``malformed`` (not numbers, wrong number of cells,
        or a time that is not finite) and, in a thrust or IMU log, ``missing`` (an empty
        or NaN cell: the row gives no reading; the previous thrust stays applied, an IMU
        sample is missed). In a
        position log an empty cell is a channel without a value on that row, as its
        format says, and the row is accepted.
    """

    def __init__(self, path: str | Path, source: str = "csv", option: str = "log", fmt: str | None = None):
        self.path = Path(path)
        self.source = source
        kind = log_format(self.path, option, fmt if fmt == "csv" else None)
        if not kind.startswith("csv-"):
            raise ValueError(f"{option} {self.path}: not a CSV log (first line {csv_headers()})")
        self.kind = kind[4:]
        self.counts: Counter = Counter({"accepted": 0, "malformed": 0, **({"missing": 0} if self.kind in WHOLE_ROWS else {})})

    def __iter__(self):
        with open_log(self.path) as handle:
            lines = _lines(handle)
            next(lines, None)
            for raw in lines:
                yield from self.row(raw)

    def row(self, raw: bytes) -> list[Reading]:
        """The readings of one row."""
        cells = raw.decode("ascii", "replace").strip().split(",")
        if cells == [""]:
            return []
        try:
            if len(cells) != 4:
                raise ValueError
            values = [float(cell) if cell.strip() else math.nan for cell in cells]
        except ValueError:
            self.counts["malformed"] += 1
            return []
        time, a, b, c = values
        if not math.isfinite(time) or any(math.isinf(v) for v in (a, b, c)):
            self.counts["malformed"] += 1
            return []
        if self.kind in WHOLE_ROWS:
            if not all(math.isfinite(v) for v in (a, b, c)):
                self.counts["missing"] += 1  # the thrust applied stays the previous row's; an IMU sample is missed
                return []
            self.counts["accepted"] += 1
            return [Reading(time, self.source, self.kind, (a, b, c), "CSV")]
        self.counts["accepted"] += 1
        readings = []
        if math.isfinite(a) and math.isfinite(b):
            readings.append(Reading(time, self.source, "local_position", (a, b), "CSV"))
        if math.isfinite(c):
            readings.append(Reading(time, self.source, "heading", (c,), "CSV"))
        return readings


def _number(text: bytes) -> float:
    """``text`` as a float, NaN when it is not a number."""
    try:
        return float(text)
    except ValueError:
        return math.nan


#: Bins of the typical-step histogram per decade of seconds (a step is known to 1.2 %).
_BINS_PER_DECADE = 100
#: The histogram's range: steps from 1 us to 1e7 s (shorter and longer ones are clamped).
_SMALLEST_STEP_DECADE, _DECADES = -6, 13


def _median_step(histogram: list) -> float:
    """The median of a histogram of steps (:data:`_BINS_PER_DECADE` bins a decade), NaN when empty."""
    total = sum(histogram)
    if not total:
        return math.nan
    count = 0
    for index, n in enumerate(histogram):
        count += n
        if 2 * count >= total:
            return 10.0 ** ((index + 0.5) / _BINS_PER_DECADE + _SMALLEST_STEP_DECADE)
    return math.nan  # unreachable


@dataclass
class LogScan:
    """What :func:`scan_log` found in a log: its times, their order and gaps, and how
    many lines can give a reading.

    Attributes
    ----------
    path : Path
    option : str
        How messages name the log (``LOG``, ``--thrust``).
    format : str
        ``nmea``, ``csv-position``, ``csv-thrust`` or ``csv-imu``.
    lines : int
        Lines other than blank lines, comments and a CSV header.
    timed : int
        Lines with a finite time.
    first, last : float
        The times of the first and the last timed line (NaN without one).
    newest : float
        The latest time of any line.
    late : int
        Lines stamped before a line above them (before ``newest`` at that line).
    back, back_line, back_from : float, int, int
        The largest step back in time (s), the line (1-based, in the file) that took it
        and the line above it it went back from (the latest then).
    longest_gap, gap_line, gap_start : float, int, float
        The longest step forward between timed lines (s), the line after it and the
        time it starts from.
    bom : bool
        Whether the file starts with a UTF-8 byte-order mark (skipped by every reader).
    instants : collections.Counter
        Distinct times of the position and of the heading lines (``position``,
        ``heading``): consecutive lines of one kind and one time (a GGA and an RMC of
        one fix) count once. :meth:`instant_step` is the median step between them.
    ignored_dates : int
        A raw log's dates that disagreed with the day counted from its times of day
        (:class:`~lookout.io.sentence_time.SentenceClock`).
    usable : collections.Counter
        Lines by what they can give: ``position``, ``heading``, ``thrust``, ``imu``, ``other``
        (a supported sentence of neither), or the cause they cannot (the NMEA parser's
        framing causes, or a CSV row's ``malformed`` or ``missing``).
    """

    path: Path
    option: str
    format: str
    lines: int = 0
    timed: int = 0
    first: float = math.nan
    last: float = math.nan
    newest: float = -math.inf
    late: int = 0
    back: float = 0.0
    back_line: int = 0
    back_from: int = 0
    newest_line: int = 0
    longest_gap: float = 0.0
    gap_line: int = 0
    gap_start: float = math.nan
    bom: bool = False
    ignored_dates: int = 0
    instants: Counter = field(default_factory=Counter)
    _last_of: dict = field(default_factory=dict, repr=False)
    _instant_steps: dict = field(default_factory=dict, repr=False)
    usable: Counter = field(default_factory=Counter)
    _steps: list = field(default_factory=lambda: [0] * (_BINS_PER_DECADE * _DECADES), repr=False)

    @property
    def span(self) -> float:
        """Seconds from the first to the latest timed line (0 without one)."""
        return self.newest - self.first if self.timed else 0.0

    def gaps_longer_than(self, seconds: float) -> int:
        """Steps forward between timed lines longer than ``seconds`` (to the histogram's
        1.2 %)."""
        start = self._bin(seconds) + 1
        return sum(self._steps[start:])

    @property
    def typical_step(self) -> float:
        """The median step forward between consecutive timed lines (s, to 1.2 %; NaN
        when no line follows another later in time)."""
        return _median_step(self._steps)

    @staticmethod
    def _bin(step: float) -> int:
        index = math.floor((math.log10(step) - _SMALLEST_STEP_DECADE) * _BINS_PER_DECADE) if step > 0 else 0
        return min(max(index, 0), _BINS_PER_DECADE * _DECADES - 1)

    def _instant(self, kind: str, time: float) -> None:
        if kind in ("position", "heading") and self._last_of.get(kind) != time:
            self.instants[kind] += 1
            last = self._last_of.get(kind)
            steps = self._instant_steps.setdefault(kind, [])
            if last is not None and time > last and len(steps) < INSTANT_STEPS:
                steps.append(time - last)
            self._last_of[kind] = time

    def instant_step(self, kind: str) -> float:
        """The median step forward between consecutive distinct times of a kind's lines
        (``position`` or ``heading``; s; over the first :data:`INSTANT_STEPS`; NaN with
        fewer than two)."""
        steps = self._instant_steps.get(kind)
        return float(np.median(steps)) if steps else math.nan

    def _time(self, number: int, time: float) -> None:
        if not math.isfinite(time):
            return
        self.timed += 1
        if self.timed == 1:
            self.first = time
        self.last = time
        if time < self.newest:
            self.late += 1
            if self.newest - time > self.back:
                self.back, self.back_line, self.back_from = self.newest - time, number, self.newest_line
            return
        if self.timed > 1 and time > self.newest:
            step = time - self.newest
            self._steps[self._bin(step)] += 1
            if step > self.longest_gap:
                self.longest_gap, self.gap_line, self.gap_start = step, number, self.newest
        self.newest, self.newest_line = time, number


def scan_log(path: str | Path, option: str = "log", fmt: str | None = None) -> LogScan:
    """One cheap pass over a log: each line's time and, for NMEA, its framing and
    checksum (no field is parsed but a raw log's times), in constant memory.

    Parameters
    ----------
    fmt : {"raw", "timed", "csv"}, optional
        The format (:data:`FORMATS`), detected when not given.

    Raises
    ------
    ValueError
        As :func:`log_format` (naming ``option``).
    """
    kind = log_format(path, option, fmt)
    scan = LogScan(Path(path), option, kind)
    parser = NmeaParser()
    csv = CsvLog(path, option=option, fmt=fmt) if kind.startswith("csv-") else None
    scan.bom = has_bom(path)
    if kind == "nmea-raw":
        clock = raw_clock(path)
        for number, _, cause, formatter, time in raw_log_times(path, parser, clock):
            scan.lines += 1
            if math.isnan(time) and cause == "accepted":
                scan.usable["untimed"] += 1
                continue
            scan.usable[_usable(cause, formatter)] += 1
            if cause == "accepted":
                scan._time(number, time)
                scan._instant(_usable(cause, formatter), time)
        scan.ignored_dates = clock.ignored_dates
        return scan
    with open_log(path) as handle:
        for number, raw in enumerate(_lines(handle), start=1):
            line = raw.strip()
            if not line or line.startswith(b"#") or (csv is not None and number == 1):
                continue
            scan.lines += 1
            if csv is not None:
                before = dict(csv.counts)
                readings = csv.row(line)
                cause = next((name for name, n in csv.counts.items() if n != before.get(name, 0)), "malformed")
                for reading in readings:
                    scan.usable[{"local_position": "position"}.get(reading.kind, reading.kind)] += 1
                    scan._instant({"local_position": "position"}.get(reading.kind, reading.kind), reading.time)
                if not readings:  # malformed, a thrust or IMU row with a missing value, or a position row without values
                    scan.usable["no_value" if cause == "accepted" else cause] += 1
                scan._time(number, math.nan if cause == "malformed" else _number(line.split(b",", 1)[0]))
                continue
            stamp, _, sentence = line.partition(b" ")
            time = _number(stamp)
            if not math.isfinite(time):
                scan.usable["malformed"] += 1
                continue
            cause, formatter = parser.frame(sentence.strip())
            scan.usable[_usable(cause, formatter)] += 1
            scan._time(number, time)
            scan._instant(_usable(cause, formatter), time)
    return scan


def _usable(cause: str, formatter: str) -> str:
    """What a line can give (:attr:`LogScan.usable`), from its framing."""
    if cause != "accepted":
        return cause
    return "position" if formatter in POSITION_SENTENCES else "heading" if formatter in HEADING_SENTENCES else "other"
