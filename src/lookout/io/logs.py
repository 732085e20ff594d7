"""Recorded logs: NMEA sentences with arrival times, and CSV for users without NMEA.

Two formats, told apart by the first line:

- **NMEA log** (any name; ``.nmea`` by convention): one sentence a line after the time
  it arrived, ``TIME SENTENCE``, TIME in seconds (Unix time or any other origin); lines
  starting with ``#`` are comments. Tag blocks and 61162-450 headers may stay on the
  sentence.
- **CSV**: a header naming its columns, then one row per sample.
  ``time,north,east,heading`` gives local position (m, about any origin) and heading
  (degrees, true); an empty cell is a missing value. ``time,surge,sway,yaw`` gives
  thrust feedback (N, N, N m), the input the observer predicts with.

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

from lookout.io.nmea import HEADING_SENTENCES, POSITION_SENTENCES, NmeaParser, Reading

#: CSV headers and the reading kinds their rows give.
CSV_HEADERS = {
    ("time", "north", "east", "heading"): "position",
    ("time", "surge", "sway", "yaw"): "thrust",
}


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


def log_format(path: str | Path, option: str = "log") -> str:
    """``"nmea"``, ``"csv-position"`` or ``"csv-thrust"``, from the file's first line.

    Parameters
    ----------
    path : path
    option : str
        How messages name the file (``LOG``, ``--thrust``).

    Raises
    ------
    ValueError
        Naming ``option`` and the file when it cannot be read, is empty, holds binary
        data, or its first line is a CSV header of neither kind.
    """
    path = Path(path)
    try:
        with open_log(path) as handle:
            head = handle.read(HEAD_BYTES)
    except OSError as error:
        raise ValueError(f"{option} {path}: cannot be read ({error.strerror or error})") from None
    if not head.strip():
        raise ValueError(f"{option} {path} is empty" + (" (only blank lines)" if head else ""))
    if _is_binary(head):
        raise ValueError(f"{option} {path} is not a text log: it holds binary data (a log is text: TIME SENTENCE lines of NMEA, or CSV)")
    first = head.split(b"\n", 1)[0]
    header = tuple(cell.strip() for cell in first.decode("ascii", "replace").strip().lower().split(","))
    if header in CSV_HEADERS:
        return f"csv-{CSV_HEADERS[header]}"
    if b"," in first and not first.lstrip().startswith((b"#", b"$", b"!", b"\\")) and b" " not in first.strip()[:40]:
        wanted = " or ".join(",".join(h) for h in CSV_HEADERS)
        shown = first.strip()[:60].decode("ascii", "replace")
        raise ValueError(f"{option} {path}: a CSV log's first line must be {wanted}; got {shown!r}")
    return "nmea"


def nmea_log(path: str | Path, parser: NmeaParser) -> Iterator[Reading]:
    """The readings of an NMEA log, in file order; unreadable lines go to ``parser.counts``."""
    with open_log(path) as handle:
        for raw in handle:
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
    """Readings from a CSV log (position-and-heading or thrust), row by row.

    Attributes
    ----------
    counts : collections.Counter
        Rows by cause: ``accepted``, ``malformed`` (not numbers, wrong number of cells,
        or a time that is not finite) and, in a thrust log, ``missing`` (an empty or NaN
        cell: the row gives no thrust, and the previous thrust stays applied). In a
        position log an empty cell is a channel without a value on that row, as its
        format says, and the row is accepted.
    """

    def __init__(self, path: str | Path, source: str = "csv", option: str = "log"):
        self.path = Path(path)
        self.source = source
        kind = log_format(self.path, option)
        if not kind.startswith("csv-"):
            raise ValueError(f"{option} {self.path}: not a CSV log (first line {' or '.join(','.join(h) for h in CSV_HEADERS)})")
        self.kind = kind[4:]
        self.counts: Counter = Counter({"accepted": 0, "malformed": 0, **({"missing": 0} if self.kind == "thrust" else {})})

    def __iter__(self):
        with open_log(self.path) as handle:
            handle.readline()
            for raw in handle:
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
        if self.kind == "thrust":
            if not all(math.isfinite(v) for v in (a, b, c)):
                self.counts["missing"] += 1  # the thrust applied stays the previous row's
                return []
            self.counts["accepted"] += 1
            return [Reading(time, self.source, "thrust", (a, b, c), "CSV")]
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
        ``nmea``, ``csv-position`` or ``csv-thrust``.
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
    usable : collections.Counter
        Lines by what they can give: ``position``, ``heading``, ``thrust``, ``other``
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
        total = sum(self._steps)
        if not total:
            return math.nan
        count = 0
        for index, n in enumerate(self._steps):
            count += n
            if 2 * count >= total:
                return 10.0 ** ((index + 0.5) / _BINS_PER_DECADE + _SMALLEST_STEP_DECADE)
        return math.nan  # unreachable

    @staticmethod
    def _bin(step: float) -> int:
        index = math.floor((math.log10(step) - _SMALLEST_STEP_DECADE) * _BINS_PER_DECADE) if step > 0 else 0
        return min(max(index, 0), _BINS_PER_DECADE * _DECADES - 1)

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


def scan_log(path: str | Path, option: str = "log") -> LogScan:
    """One cheap pass over a log: each line's time and, for NMEA, its framing and
    checksum (no field is parsed), in constant memory.

    Raises
    ------
    ValueError
        As :func:`log_format` (naming ``option``).
    """
    kind = log_format(path, option)
    scan = LogScan(Path(path), option, kind)
    parser = NmeaParser()
    csv = CsvLog(path, option=option) if kind.startswith("csv-") else None
    scan.bom = has_bom(path)
    with open_log(path) as handle:
        for number, raw in enumerate(handle, start=1):
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
                if not readings:  # malformed, a thrust row with a missing value, or a position row without values
                    scan.usable["no_value" if cause == "accepted" else cause] += 1
                scan._time(number, math.nan if cause == "malformed" else _number(line.split(b",", 1)[0]))
                continue
            stamp, _, sentence = line.partition(b" ")
            time = _number(stamp)
            if not math.isfinite(time):
                scan.usable["malformed"] += 1
                continue
            cause, formatter = parser.frame(sentence.strip())
            if cause == "accepted":
                cause = "position" if formatter in POSITION_SENTENCES else "heading" if formatter in HEADING_SENTENCES else "other"
            scan.usable[cause] += 1
            scan._time(number, time)
    return scan
