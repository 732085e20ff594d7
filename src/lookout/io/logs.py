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
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

from lookout.io.nmea import NmeaParser, Reading

#: CSV headers and the reading kinds their rows give.
CSV_HEADERS = {
    ("time", "north", "east", "heading"): "position",
    ("time", "surge", "sway", "yaw"): "thrust",
}


def log_format(path: str | Path) -> str:
    """``"nmea"``, ``"csv-position"`` or ``"csv-thrust"``, from the file's first line.

    Raises
    ------
    ValueError
        Naming the file when it cannot be read or its first line is neither.
    """
    path = Path(path)
    try:
        with path.open("rb") as handle:
            first = handle.readline(4096)
    except OSError as error:
        raise ValueError(f"log {path}: cannot be read ({error.strerror or error})") from None
    header = tuple(cell.strip() for cell in first.decode("ascii", "replace").strip().lower().split(","))
    if header in CSV_HEADERS:
        return f"csv-{CSV_HEADERS[header]}"
    if b"," in first and not first.lstrip().startswith((b"#", b"$", b"!", b"\\")) and b" " not in first.strip()[:40]:
        wanted = " or ".join(",".join(h) for h in CSV_HEADERS)
        raise ValueError(f"log {path}: a CSV log's first line must be {wanted}; got {first.strip()[:80].decode('ascii', 'replace')!r}")
    return "nmea"


def nmea_log(path: str | Path, parser: NmeaParser):
    """The readings of an NMEA log, in file order; unreadable lines go to ``parser.counts``."""
    with Path(path).open("rb") as handle:
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
        or a time that is not finite).
    """

    def __init__(self, path: str | Path, source: str = "csv"):
        self.path = Path(path)
        self.source = source
        kind = log_format(self.path)
        if not kind.startswith("csv-"):
            raise ValueError(f"log {self.path}: not a CSV log (first line {' or '.join(','.join(h) for h in CSV_HEADERS)})")
        self.kind = kind[4:]
        self.counts: Counter = Counter({"accepted": 0, "malformed": 0})

    def __iter__(self):
        with self.path.open("rb") as handle:
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
        self.counts["accepted"] += 1
        if self.kind == "thrust":
            if not all(math.isfinite(v) for v in (a, b, c)):
                return []
            return [Reading(time, self.source, "thrust", (a, b, c), "CSV")]
        readings = []
        if math.isfinite(a) and math.isfinite(b):
            readings.append(Reading(time, self.source, "local_position", (a, b), "CSV"))
        if math.isfinite(c):
            readings.append(Reading(time, self.source, "heading", (c,), "CSV"))
        return readings
