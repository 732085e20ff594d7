"""NMEA 0183 position and heading sentences: framing, checksums, parsing.

A DP vessel's position references and gyros speak NMEA 0183 (IEC 61162-1): GGA, GLL
and RMC for position, GST for the position's error ellipse, HDT and THS for true
heading (THS, IEC 61162-1 ed. 4, carries a mode indicator and replaces HDT), ROT for
rate of turn. Over Ethernet, IEC 61162-450 puts a ``UdPbC\\0`` header in front of a
datagram and a tag block ``\\s:GP0001,c:1577836800*hh\\`` in front of a sentence; a
datagram may carry several sentences.

The sentences' fields are parsed by pynmeagps (a maintained parser that knows all seven
sentences, THS included); this module frames lines, verifies checksums (the sentence's
and the tag block's), tells sources apart and turns each line into at most one
:class:`Reading`, counting every line exactly once in :attr:`NmeaParser.counts` under
one cause. Nothing a line contains makes it raise.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import reduce

from pynmeagps import NMEAReader
from pynmeagps.nmeatypes_core import VALNONE

#: The sentences turned into readings, by what they measure.
POSITION_SENTENCES = ("GGA", "GLL", "RMC")
HEADING_SENTENCES = ("HDT", "THS")
SUPPORTED = POSITION_SENTENCES + HEADING_SENTENCES + ("ROT", "GST")
#: The longest line kept (IEC 61162-1 allows 82 characters a sentence; a tag block
#: and a 61162-450 header make it longer). Longer lines are dropped as ``too_long``.
MAX_LINE = 1024
#: The causes under which :class:`NmeaParser` counts a line (each line exactly one).
CAUSES = ("accepted", "no_fix", "checksum", "malformed", "out_of_range", "unsupported", "too_long", "empty")
_HEADER = b"UdPbC\x00"

#: Talker IDs that one device speaks under, by the device they name: a
#: multi-constellation receiver's GGA comes as GP, GN, GL, ... as its solution changes,
#: and a heading source's THS or HDT as HE, HC, HN or TI. A session treats the talkers
#: of one family from one place as one source (:func:`receiver`).
TALKER_FAMILIES = {
    "GNSS": ("GP", "GN", "GL", "GA", "GB", "BD", "GQ", "GI"),
    "heading": ("HE", "HC", "HN", "TI"),
}
_FAMILY_OF = {talker: family for family, talkers in TALKER_FAMILIES.items() for talker in talkers}


def receiver(source: str, bindings: Mapping[str, str] | None = None) -> str:
    """The device a reading's ``source`` (``TALKER`` or ``TALKER@WHERE``) comes from: the
    one place where a talker and its sender are bound to a source.

    Parameters
    ----------
    source : str
        A :class:`Reading`'s source.
    bindings : mapping of str to str, optional
        Names the user gives: a key is a source (``GN@10.0.0.5``) or a talker alone
        (``GN``, from any sender), its value the source's name. An exact source wins
        over a talker.

    Returns
    -------
    str
        The bound name if ``bindings`` names the source; else the talker's family from
        :data:`TALKER_FAMILIES` in its place (``GN@10.0.0.5`` is ``GNSS@10.0.0.5``,
        ``HC`` is ``heading``); else ``source`` itself.
    """
    talker, at, where = source.partition("@")
    if bindings:
        if source in bindings:
            return bindings[source]
        if talker in bindings:
            return bindings[talker]
    family = _FAMILY_OF.get(talker)
    return source if family is None else family + at + where


#: How a scenario names the source of a sensor (``[sensors.NAME]``'s ``source``): a
#: talker ID, a sender (``@`` and the tag block's ``s:`` source or a UDP sender's
#: address), or both.
SOURCE_SPELLING = "TALKER, @SENDER or TALKER@SENDER (GP, @10.0.0.5, GP@10.0.0.5)"
_TALKER = re.compile(r"P|[A-Z][A-Z0-9]")
_SENDER = re.compile(r"[^\s@,*\\$!]+")


def source_spec(text: object) -> tuple[str, str | None]:
    """``(talker, sender)`` of a sensor's source as a scenario spells it
    (:data:`SOURCE_SPELLING`): the talker ``""`` for any talker, the sender None for any
    sender.

    Raises
    ------
    ValueError
        ``must be ...; got ...`` (one line) for any other text: a talker of other than
        two capital letters or digits, an empty or spaced sender, an empty text.
    """
    if not isinstance(text, str):
        raise ValueError(f"must be a string, {SOURCE_SPELLING}; got {text!r}")
    talker, at, sender = text.partition("@")
    if not (talker or at) or (talker and not _TALKER.fullmatch(talker)) or (at and not _SENDER.fullmatch(sender)):
        raise ValueError(
            f"must be {SOURCE_SPELLING}: a talker ID of two capital letters or digits, a sender without spaces, '@' or ','; got {text!r}"
        )
    return talker, (sender if at else None)


def source_rank(source: str, talker: str, sender: str | None) -> tuple[int, int] | None:
    """How closely a reading's ``source`` (``TALKER@WHERE``) matches a sensor's
    :func:`source_spec`, None when it does not: ``(sender given, talker)``, the talker
    2 for the same talker ID, 1 for another of its family (:data:`TALKER_FAMILIES`: a
    multi-constellation receiver's GP and GN), 0 for a sensor of any talker. Of several
    sensors a reading matches, the highest rank takes it (a named sender before a talker
    alone, as :func:`receiver` takes a source before a talker)."""
    got_talker, _, got_sender = source.partition("@")
    if sender is not None and got_sender != sender:
        return None
    if not talker:
        closeness = 0
    elif talker == got_talker:
        closeness = 2
    elif _FAMILY_OF.get(talker) is not None and _FAMILY_OF.get(talker) == _FAMILY_OF.get(got_talker):
        closeness = 1
    else:
        return None
    return (int(sender is not None), closeness)


def talker_family(talker: str) -> str | None:
    """The family (:data:`TALKER_FAMILIES`) of a talker ID, None for a talker of none."""
    return _FAMILY_OF.get(talker)


class _OutOfRange(ValueError):
    """A field read as a number that cannot be what it measures (latitude 91)."""


@dataclass(frozen=True)
class Reading:
    """One measurement from one sentence.

    Attributes
    ----------
    time : float
        When the sentence arrived (s; the clock of the source: a log's time column, the
        receiving computer's clock for a live stream).
    source : str
        The sender: the talker ID, then the tag block's ``s:`` source or the stream's
        origin (``GP@192.168.1.5:10110``), so two receivers of one kind stay apart.
    kind : {"position", "heading", "rate_of_turn", "position_error"}
    values : tuple of float
        ``position``: latitude, longitude (degrees), fix quality (GGA; 1 for GLL and RMC),
        HDOP (GGA; NaN otherwise). ``heading``: true heading (degrees).
        ``rate_of_turn``: degrees per minute, positive to starboard. ``position_error``:
        standard deviations of latitude and longitude (m).
    sentence : str
        The sentence's formatter (``GGA``).
    """

    time: float
    source: str
    kind: str
    values: tuple
    sentence: str


def checksum(body: bytes) -> int:
    """The NMEA checksum of ``body`` (the characters between ``$`` and ``*``): their XOR."""
    return reduce(lambda a, b: a ^ b, body, 0)


def sentence(talker: str, formatter: str, fields: Iterable[object]) -> str:
    """A sentence with its checksum, ``$TTFFF,f1,f2*hh`` (no line ending)."""
    body = ",".join([talker + formatter, *map(str, fields)]).encode("ascii")
    return f"${body.decode()}*{checksum(body):02X}"


def tag_block(source: str) -> str:
    """An IEC 61162-450 tag block naming a sentence's source, ``\\s:SOURCE*hh\\``, to
    put in front of it (its checksum that of the characters between ``\\`` and ``*``).

    Raises
    ------
    ValueError
        For a source that a tag block cannot carry: empty, not printable ASCII, or with
        a space, ``,``, ``*``, ``\\``, ``$`` or ``!`` in it.
    """
    if not (source and source.isascii() and source.isprintable()) or any(c in source for c in " ,*\\$!"):
        raise ValueError(f"a tag block's source must be printable ASCII without spaces, ',', '*', '\\', '$' or '!'; got {source!r}")
    body = f"s:{source}"
    return f"\\{body}*{checksum(body.encode('ascii')):02X}\\"


def _verified(text: bytes) -> bytes | None:
    """The part between the start character and ``*`` if the checksum after it holds."""
    star = text.rfind(b"*")
    if star < 0 or len(text) - star - 1 != 2:
        return None
    try:
        expected = int(text[star + 1 :], 16)
    except ValueError:
        return None
    body = text[1:star]
    return body if checksum(body) == expected else None


def _tag_block(line: bytes):
    """``(tags, rest)``: the tag block's ``key: value`` pairs and the line after it, or
    ``(None, line)`` without one; ``("bad", line)`` for a tag block whose checksum fails."""
    if not line.startswith(b"\\"):
        return None, line
    end = line.find(b"\\", 1)
    if end < 0:
        return "bad", line
    block = line[:end]  # "\" + "s:..,c:..*hh"
    body = _verified(block)
    if body is None:
        return "bad", line
    tags = {}
    for item in body.split(b","):
        key, _, value = item.partition(b":")
        tags[key.decode("ascii", "replace")] = value.decode("ascii", "replace")
    return tags, line[end + 1 :]


def _float(value) -> float:
    if value in ("", None):
        return math.nan
    return float(value)


class NmeaParser:
    """Lines of NMEA 0183 to :class:`Reading` objects, every line counted once.

    Parameters
    ----------
    require_checksum : bool
        Refuse a sentence without a ``*hh`` checksum (IEC 61162-1 makes it mandatory
        for these sentences); default True.

    Attributes
    ----------
    counts : collections.Counter
        Lines by cause (:data:`CAUSES`): ``accepted`` (a reading), ``no_fix`` (valid, but
        says it has no fix: GGA quality 0, status V, empty fields), ``checksum``,
        ``malformed``, ``out_of_range`` (a latitude, longitude or heading outside its
        range), ``unsupported`` (a sentence this module does not use),
        ``too_long``, ``empty``.
    sources : collections.Counter
        Readings by ``(source, kind)``.
    """

    def __init__(self, require_checksum: bool = True):
        if not isinstance(require_checksum, bool):
            raise ValueError(f"require_checksum must be True or False; got {require_checksum!r}")
        self.require_checksum = require_checksum
        self.counts: Counter = Counter({cause: 0 for cause in CAUSES})
        self.sources: Counter = Counter()

    @property
    def lines(self) -> int:
        """Lines seen (the sum of :attr:`counts`)."""
        return sum(self.counts.values())

    @property
    def rejected(self) -> dict:
        """Counts of the lines that gave no reading, by cause (zeros left out)."""
        return {cause: n for cause, n in self.counts.items() if cause != "accepted" and n}

    def datagram(self, data: bytes, time: float, origin: str = "") -> list[Reading]:
        """The readings of one UDP datagram: an optional IEC 61162-450 header, then
        sentences separated by line ends."""
        if data.startswith(_HEADER):
            data = data[len(_HEADER) :]
        return [reading for line in data.splitlines() if line.strip() for reading in self.line(line, time, origin)]

    def line(self, line: bytes | str, time: float, origin: str = "") -> list[Reading]:
        """The reading of one line (a list of none or one), the line counted once."""
        cause, reading = self._parse(line, time, origin)
        self.counts[cause] += 1
        if reading is None:
            return []
        self.sources[(reading.source, reading.kind)] += 1
        return [reading]

    def frame(self, line: bytes | str) -> tuple[str, str]:
        """``(cause, formatter)`` of a line's framing alone: its length, tag block,
        start character, checksum and address, without parsing its fields (cheap: a
        pre-scan of a log, :func:`lookout.io.logs.scan_log`). ``cause`` is one of
        :data:`CAUSES`, ``"accepted"`` when the line is a supported sentence whose
        fields remain to be read; nothing is counted."""
        cause, framed = self._frame(line)
        return cause, (framed[2] if framed else "")

    def _frame(self, line):
        """``(cause, (line, talker, formatter, tags))``: the framing checks of :meth:`line`."""
        if isinstance(line, str):
            line = line.encode("ascii", "replace")
        if len(line) > MAX_LINE:
            return "too_long", None
        line = line.strip()
        if not line:
            return "empty", None
        tags, line = _tag_block(line)
        if tags == "bad":
            return "checksum", None
        if line[:1] not in (b"$", b"!") or len(line) < 7:
            return "malformed", None
        if b"*" in line:
            if _verified(line) is None:
                return "checksum", None
        elif self.require_checksum:
            return "checksum", None
        else:
            line = line + b"*%02X" % checksum(line[1:])
        try:
            address = line[1 : line.index(b",") if b"," in line else 6].decode("ascii")
        except UnicodeDecodeError:
            return "malformed", None
        if not (5 <= len(address) <= 6 and address.isalnum()):
            return "malformed", None
        talker, formatter = (address[:2], address[2:]) if not address.startswith("P") else (address[:1], address[1:])
        if formatter not in SUPPORTED:
            return "unsupported", None
        return "accepted", (line, talker, formatter, tags)

    def _parse(self, line, time: float, origin: str):
        cause, framed = self._frame(line)
        if framed is None:
            return cause, None
        line, talker, formatter, tags = framed
        try:
            message = NMEAReader.parse(line, validate=VALNONE)
            kind, values = _values(formatter, message)
        except _OutOfRange:
            return "out_of_range", None
        except Exception:  # noqa: BLE001 - a line never raises: pynmeagps raises several types on bad fields
            return "malformed", None
        if kind is None:
            return "no_fix", None
        where = (tags or {}).get("s") or origin
        source = f"{talker}@{where}" if where else talker
        return "accepted", Reading(float(time), source, kind, values, formatter)


def _values(formatter: str, message):
    """``(kind, values)`` of a parsed sentence, ``(None, ())`` when it reports no fix.
    Raises on a missing or unreadable field."""
    if formatter in POSITION_SENTENCES:
        if formatter == "GGA":
            quality = int(message.quality)
            if quality == 0 or message.lat == "" or message.lon == "":
                return None, ()
            hdop = _float(message.HDOP)
        else:
            if message.status != "A" or message.lat == "" or message.lon == "":
                return None, ()
            quality, hdop = 1, math.nan
        lat, lon = float(message.lat), float(message.lon)
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise _OutOfRange("position out of range")
        return "position", (lat, lon, float(quality), hdop)
    if formatter in HEADING_SENTENCES:
        if formatter == "THS":
            # mode indicator: A autonomous, E estimated (dead reckoning), M manual, S simulator, V not valid
            if message.mi not in ("A", "E") or message.headt == "":
                return None, ()
            heading = float(message.headt)
        else:
            if message.headingT == "":
                return None, ()
            heading = float(message.headingT)
        if not (math.isfinite(heading) and 0.0 <= heading <= 360.0):
            raise _OutOfRange("heading out of range")
        return "heading", (heading,)
    if formatter == "ROT":
        if message.valid != "A" or message.rot == "":
            return None, ()
        rate = float(message.rot)
        if not math.isfinite(rate):
            raise ValueError("rate of turn not finite")
        return "rate_of_turn", (rate,)
    # GST: the error ellipse's standard deviations in latitude and longitude (m)
    if message.stdLat == "" or message.stdLong == "":
        return None, ()
    std = (float(message.stdLat), float(message.stdLong))
    if not all(math.isfinite(s) and s >= 0 for s in std):
        raise ValueError("GST standard deviation not finite")
    return "position_error", std


class LineSplitter:
    """Bytes of a stream (a serial port, stdin, a file) to lines, in bounded memory.

    A line longer than :data:`MAX_LINE` is not kept: its bytes are dropped as they come
    and it is returned once, as a too-long marker that :meth:`NmeaParser.line` counts
    as ``too_long``.
    """

    def __init__(self):
        self._buffer = bytearray()
        self._overflow = False

    def feed(self, data: bytes) -> list[bytes]:
        """The complete lines in ``data`` and what came before it."""
        lines = []
        for piece in data.splitlines(keepends=True):
            ended = piece.endswith((b"\n", b"\r"))
            body = piece.rstrip(b"\r\n")
            if self._overflow or len(self._buffer) + len(body) > MAX_LINE:
                self._overflow = True
                self._buffer.clear()
            else:
                self._buffer += body
            if ended:
                if self._overflow:
                    lines.append(b"x" * (MAX_LINE + 1))
                elif self._buffer:
                    lines.append(bytes(self._buffer))
                self._buffer.clear()
                self._overflow = False
        return lines

    def flush(self) -> list[bytes]:
        """What is left when the stream ends, as a last line."""
        lines = self.feed(b"\n") if (self._buffer or self._overflow) else []
        return lines
