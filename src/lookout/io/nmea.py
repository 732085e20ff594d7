"""NMEA 0183 sentences of position, heading and speed: framing, checksums, parsing.

A DP vessel's position references and gyros speak NMEA 0183 (IEC 61162-1): GGA, GNS,
GLL and RMC for position, GST for the position's error ellipse, HDT and THS for true
heading (THS, IEC 61162-1 ed. 4, carries a mode indicator and replaces HDT), HDG and
HDM for magnetic heading (turned to true with the sentence's deviation and variation,
:class:`NmeaParser`), ROT for rate of turn, RMC and VTG for speed and course over
ground, VHW for speed through the water, ZDA for the date. Over Ethernet, IEC 61162-450 puts a ``UdPbC\\0`` header in front of a
datagram and a tag block ``\\s:GP0001,c:1577836800*hh\\`` in front of a sentence; a
datagram may carry several sentences.

The sentences' fields are parsed by pynmeagps (a maintained parser that knows them all,
THS included); this module frames lines, verifies checksums (the sentence's and the tag
block's), tells sources apart and turns each line into its :class:`Reading` objects (an
RMC gives a position and a velocity over ground; the others at most one), counting
every line exactly once in :attr:`NmeaParser.counts` under one cause. AIS (``!``) and
proprietary (``$P``) lines are counted apart and skipped. Nothing a line contains makes
it raise.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import reduce
from operator import xor
from types import SimpleNamespace

from pynmeagps import NMEAMessage, NMEAReader
from pynmeagps.exceptions import NMEAMessageError
from pynmeagps.nmeahelpers import get_parts
from pynmeagps.nmeatypes_core import LAD, LND, VALNONE
from pynmeagps.nmeatypes_get import NMEA_PAYLOADS_GET

#: The sentences turned into readings, by what they measure.
POSITION_SENTENCES = ("GGA", "GNS", "GLL", "RMC")
HEADING_SENTENCES = ("HDT", "THS", "HDG", "HDM")
#: Magnetic heading sentences, turned to true heading with a variation.
MAGNETIC_SENTENCES = ("HDG", "HDM")
#: Speed and course over ground (RMC's and VTG's), speed through the water (VHW's).
VELOCITY_SENTENCES = ("RMC", "VTG")
SUPPORTED = POSITION_SENTENCES + HEADING_SENTENCES + ("ROT", "GST", "VTG", "VHW", "ZDA")
#: Metres per second in a knot (1852 m per hour).
KNOT = 1852.0 / 3600.0
#: The longest line kept (IEC 61162-1 allows 82 characters a sentence; a tag block
#: and a 61162-450 header make it longer). Longer lines are dropped as ``too_long``.
MAX_LINE = 1024
#: The causes under which :class:`NmeaParser` counts a line (each line exactly one).
CAUSES = (
    "accepted",
    "time_only",
    "untimed",
    "no_fix",
    "no_variation",
    "checksum",
    "malformed",
    "out_of_range",
    "unsupported",
    "ais",
    "proprietary",
    "too_long",
    "empty",
)
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
    kind : {"position", "heading", "rate_of_turn", "position_error", "ground_velocity", "water_speed"}
    values : tuple of float
        ``position``: latitude, longitude (degrees), fix quality (GGA's; GNS's mode
        indicator as GGA's quality: :data:`GNS_QUALITY`; 1 for GLL and RMC), HDOP (GGA,
        GNS; NaN otherwise). ``heading``: true heading (degrees; from HDG and HDM, the
        magnetic heading turned to true). ``rate_of_turn``: degrees per minute, positive
        to starboard. ``position_error``: standard deviations of latitude and longitude
        (m). ``ground_velocity``: speed over ground (m/s) and course over ground (degrees
        true, NaN where the sentence leaves it empty). ``water_speed``: speed through the
        water (m/s).
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
    return reduce(xor, body, 0)


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

    Magnetic heading (HDG, HDM) is turned to true heading: true = magnetic + deviation
    + variation, east positive (HDG's heading is the magnetic sensor's, before its
    deviation; an empty deviation is 0). The variation is the sentence's own (HDG), else
    the latest RMC's, else ``variation``; a magnetic heading with none of the three is
    counted ``no_variation``.

    Parameters
    ----------
    require_checksum : bool
        Refuse a sentence without a ``*hh`` checksum (IEC 61162-1 makes it mandatory
        for these sentences); default True.
    variation : float, optional
        Magnetic variation (degrees, east positive, within +-180) for magnetic headings
        whose sentence carries none, when no RMC has given one.

    Attributes
    ----------
    counts : collections.Counter
        Lines by cause (:data:`CAUSES`): ``accepted`` (one reading or more),
        ``time_only`` (a ZDA: a date and time, no measurement), ``untimed`` (a raw
        log's line before its first time, counted by its reader,
        :func:`lookout.io.logs.nmea_log`), ``no_fix`` (valid, but
        says it has no fix: GGA quality 0, status V, empty fields), ``no_variation`` (a
        magnetic heading without a variation), ``checksum``, ``malformed``,
        ``out_of_range`` (a latitude, longitude, heading or variation outside its
        range), ``unsupported`` (a sentence this module does not use), ``ais`` (a ``!``
        line), ``proprietary`` (a ``$P`` line), ``too_long``, ``empty``.
    sentences : collections.Counter
        Lines by ``(formatter, cause)`` for the supported sentences: what each kind of
        sentence gave.
    sources : collections.Counter
        Readings by ``(source, kind)``.
    """

    def __init__(self, require_checksum: bool = True, variation: float | None = None):
        if not isinstance(require_checksum, bool):
            raise ValueError(f"require_checksum must be True or False; got {require_checksum!r}")
        if variation is not None and (
            isinstance(variation, bool) or not isinstance(variation, (int, float)) or not (math.isfinite(variation) and -180.0 <= variation <= 180.0)
        ):
            raise ValueError(f"variation must be degrees within -180 to 180 (east positive); got {variation!r}")
        self.require_checksum = require_checksum
        self.variation = None if variation is None else float(variation)
        self.rmc_variation: float | None = None  # the latest RMC's (degrees, east positive)
        self.counts: Counter = Counter({cause: 0 for cause in CAUSES})
        self.sentences: Counter = Counter()
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
        """The readings of one line (none, one, or an RMC's two), the line counted once."""
        cause, formatter, readings = self._parse(line, time, origin)
        self.counts[cause] += 1
        if formatter:
            self.sentences[(formatter, cause)] += 1
        for reading in readings:
            self.sources[(reading.source, reading.kind)] += 1
        return readings

    def frame(self, line: bytes | str) -> tuple[str, str]:
        """``(cause, formatter)`` of a line's framing alone: its length, tag block,
        start character, checksum and address, without parsing its fields (cheap: a
        pre-scan of a log, :func:`lookout.io.logs.scan_log`). ``cause`` is one of
        :data:`CAUSES`, ``"accepted"`` when the line is a supported sentence whose
        fields remain to be read; nothing is counted."""
        cause, formatter, _ = self.framed(line)
        return cause, formatter

    def framed(self, line: bytes | str) -> tuple[str, str, bytes]:
        """``(cause, formatter, body)``: :meth:`frame`, and the checksum-verified
        sentence from its address to before ``*`` (``b""`` when refused)."""
        cause, framed = self._frame(line)
        if framed is None:
            return cause, "", b""
        text = framed[0]
        return cause, framed[2], text[1 : text.rfind(b"*")]

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
        if line[:1] == b"!":
            return "ais", None
        if line[:2] == b"$P":
            return "proprietary", None
        if line[:1] != b"$" or len(line) < 7:
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
        talker, formatter = address[:2], address[2:]
        if formatter not in SUPPORTED:
            return "unsupported", None
        return "accepted", (line, talker, formatter, tags)

    def _parse(self, line, time: float, origin: str) -> tuple[str, str, list[Reading]]:
        """``(cause, formatter, readings)`` of one line."""
        cause, framed = self._frame(line)
        if framed is None:
            return cause, "", []
        line, talker, formatter, tags = framed
        try:
            message = _message(line, formatter)
            if formatter == "RMC" and message.status == "A":
                self._remember_variation(message)
            values = _values(formatter, message)
            if formatter in MAGNETIC_SENTENCES and values:
                values = [self._true_heading(formatter, message, values[0][1][0])]
        except _OutOfRange:
            return "out_of_range", formatter, []
        except _NoVariation:
            return "no_variation", formatter, []
        except Exception:  # noqa: BLE001 - a line never raises: pynmeagps raises several types on bad fields
            return "malformed", formatter, []
        if formatter == "ZDA":
            return "time_only", formatter, []
        if not values:
            return "no_fix", formatter, []
        where = (tags or {}).get("s") or origin
        source = f"{talker}@{where}" if where else talker
        return "accepted", formatter, [Reading(float(time), source, kind, value, formatter) for kind, value in values]

    def _remember_variation(self, message) -> None:
        """Keep an RMC's magnetic variation for the magnetic headings that carry none."""
        variation = _signed(message.mv, message.mvEW)
        if variation is not None:
            self.rmc_variation = variation

    def _true_heading(self, formatter: str, message, magnetic: float) -> tuple[str, tuple[float, ...]]:
        """A magnetic heading turned to true (the class docstring's rule)."""
        variation = _signed(message.variation, message.variationEW) if formatter == "HDG" else None
        if variation is None:
            variation = self.rmc_variation if self.rmc_variation is not None else self.variation
        if variation is None:
            raise _NoVariation
        deviation = (_signed(message.deviation, message.deviationEW) or 0.0) if formatter == "HDG" else 0.0
        if abs(deviation) > 180.0:
            raise _OutOfRange("deviation out of range")
        return "heading", ((magnetic + deviation + variation) % 360.0,)


#: pynmeagps's definition of each supported sentence whose fields are all scalars, in order.
_FLAT = {f: tuple(NMEA_PAYLOADS_GET[f].items()) for f in SUPPORTED if all(isinstance(t, str) for t in NMEA_PAYLOADS_GET[f].values())}


def _message(line: bytes, formatter: str):
    """The fields of a framed sentence as ``NMEAReader.parse(line, validate=VALNONE)``
    gives them (None where it gives None), in a third of its time: pynmeagps's own field
    definitions and conversions (``NMEAMessage.str2val``) read in one pass, without its
    message object (docs/benchmarks.md). A sentence whose definition has groups goes to
    pynmeagps."""
    definition = _FLAT.get(formatter)
    if definition is None:
        return NMEAReader.parse(line, validate=VALNONE)
    try:
        _, _, _, payload, _ = get_parts(line)
    except NMEAMessageError:
        return None
    values: dict = {}
    for (name, kind), text in zip(definition, payload, strict=False):  # fewer fields: the rest unset, as pynmeagps leaves them
        value = values[name] = NMEAMessage.str2val(text, kind)
        # pynmeagps's rule: a hemisphere letter signs the latitude or longitude read before it
        if kind == LND and isinstance(values.get("lon"), (int, float)):
            values["lon"] = -abs(values["lon"]) if value == "W" else abs(values["lon"])
        elif kind == LAD and isinstance(values.get("lat"), (int, float)):
            values["lat"] = -abs(values["lat"]) if value == "S" else abs(values["lat"])
    return SimpleNamespace(**values)  # by pynmeagps's attribute names, as _values reads them


class _NoVariation(ValueError):
    """A magnetic heading with no variation to turn it to true."""


def _signed(value, hemisphere) -> float | None:
    """An angle with its E/W letter, east positive (None when the field is empty)."""
    if value in ("", None):
        return None
    angle = float(value)
    if not (math.isfinite(angle) and 0.0 <= angle <= 180.0) or hemisphere not in ("E", "W"):
        raise _OutOfRange("variation or deviation out of range")
    return angle if hemisphere == "E" else -angle


#: A GNS mode indicator's letters as GGA's fix quality: autonomous 1, differential 2,
#: precise 3, RTK fixed 4, RTK float 5, estimated 6, manual 7, simulator 8. A GNS with
#: several constellations' letters takes the best (the order of this table), and one
#: of only N (no fix) gives none.
GNS_QUALITY = {"R": 4, "F": 5, "P": 3, "D": 2, "A": 1, "E": 6, "M": 7, "S": 8}


def _gns_quality(mode: str) -> int:
    """GGA's fix quality of a GNS mode indicator (0: no fix)."""
    for letter, quality in GNS_QUALITY.items():
        if letter in mode:
            return quality
    return 0


def _position(lat, lon) -> tuple[float, float]:
    latitude, longitude = float(lat), float(lon)
    if not (-90.0 <= latitude <= 90.0 and -180.0 <= longitude <= 180.0):
        raise _OutOfRange("position out of range")
    return latitude, longitude


def _angle(value) -> float:
    """A heading or course field (degrees in [0, 360])."""
    angle = float(value)
    if not (math.isfinite(angle) and 0.0 <= angle <= 360.0):
        raise _OutOfRange("heading out of range")
    return angle


def _speed(knots) -> float:
    """A speed field in knots, as m/s (a negative or non-finite speed is malformed)."""
    speed = float(knots)
    if not (math.isfinite(speed) and speed >= 0.0):
        raise ValueError("speed not finite and non-negative")
    return speed * KNOT


def _values(formatter: str, message) -> list[tuple[str, tuple[float, ...]]]:
    """``[(kind, values), ...]`` of a parsed sentence, empty when it reports no fix (a
    ZDA's too: it measures nothing). Raises on a missing or unreadable field."""
    if formatter in ("GGA", "GNS"):
        quality = int(message.quality) if formatter == "GGA" else _gns_quality(str(message.posMode))
        if quality == 0 or message.lat == "" or message.lon == "":
            return []
        return [("position", (*_position(message.lat, message.lon), float(quality), _float(message.HDOP)))]
    if formatter in ("GLL", "RMC"):
        if message.status != "A" or message.lat == "" or message.lon == "":
            return []
        readings: list[tuple[str, tuple[float, ...]]] = [("position", (*_position(message.lat, message.lon), 1.0, math.nan))]
        if formatter == "RMC" and message.spd not in ("", None):
            course = math.nan if message.cog in ("", None) else _angle(message.cog)
            readings.append(("ground_velocity", (_speed(message.spd), course)))
        return readings
    if formatter == "THS":
        # mode indicator: A autonomous, E estimated (dead reckoning), M manual, S simulator, V not valid
        if message.mi not in ("A", "E") or message.headt == "":
            return []
        return [("heading", (_angle(message.headt),))]
    if formatter == "HDT":
        return [] if message.headingT == "" else [("heading", (_angle(message.headingT),))]
    if formatter in MAGNETIC_SENTENCES:  # magnetic: the parser turns it to true
        return [] if message.headingM == "" else [("heading", (_angle(message.headingM),))]
    if formatter == "ROT":
        if message.valid != "A" or message.rot == "":
            return []
        rate = float(message.rot)
        if not math.isfinite(rate):
            raise ValueError("rate of turn not finite")
        return [("rate_of_turn", (rate,))]
    if formatter == "VTG":
        if str(message.posMode) == "N" or message.sogn in ("", None):
            return []
        course = math.nan if message.cogt in ("", None) else _angle(message.cogt)
        return [("ground_velocity", (_speed(message.sogn), course))]
    if formatter == "VHW":
        return [] if message.spdN in ("", None) else [("water_speed", (_speed(message.spdN),))]
    if formatter == "ZDA":
        return []
    # GST: the error ellipse's standard deviations in latitude and longitude (m)
    if message.stdLat == "" or message.stdLong == "":
        return []
    std = (float(message.stdLat), float(message.stdLong))
    if not all(math.isfinite(s) and s >= 0 for s in std):
        raise ValueError("GST standard deviation not finite")
    return [("position_error", std)]


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
