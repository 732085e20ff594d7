"""The clock inside NMEA sentences: times for a raw log, one sentence a line, no time column.

Chart plotters, voyage data recorders, OpenCPN, kplex and gpsd captures save the
sentences as they came, without the time each arrived. The time is in the sentences:
the UTC time of day of GGA, GNS, GLL, RMC and ZDA (:data:`TIMED_SENTENCES`), and the
date of RMC (``ddmmyy``) and ZDA (day, month, year). :class:`SentenceClock` turns them
into one time line:

- a timed sentence is at its own UTC time. The other lines (HDT, HDG, VTG, ...) between
  two timed sentences are spread evenly between their times, each kind of line (its
  address and tag-block source) on its own: the n HDG lines after a fix at t0 and
  before the next at t1 are at t0 + i (t1 - t0) / n, i = 0 .. n - 1, which for a
  gyro sampled evenly is its own sampling (:class:`SpreadClock`). Placed at the last
  time instead, a 10 Hz gyro between 1 Hz fixes would give ten headings of one time,
  nine of them superseded in a replay. Lines after the last timed sentence, or
  between two whose times step back, are at the time before them; lines before the
  first timed sentence have no time; a run of more than :data:`MOST_HELD` lines
  without a time is placed at the last time, to keep memory bounded;
- the day advances when the time of day steps back by more than 12 h (23:59:59 then
  00:00:01 is midnight, not a step back of a day); a time of day more than 12 h after
  the one before is a late line of the day before, not a step forward;
- the first date in the log anchors the day count: times are then Unix seconds (UTC).
  A log without a date gives seconds from the UTC midnight before its first timed
  sentence. A later date that disagrees with the day counted is ignored and counted
  (:attr:`SentenceClock.ignored_dates`): the day count comes from the times of day, so
  one wrong date does not move the log's clock.

A log whose times of day hold a silence of more than 12 h without a date cannot be
told from a step back; such a log's replay is refused for its gap or its order by
:func:`lookout.live.run.check_replay`.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Iterable

#: The sentences that carry a UTC time of day, and the field (after the address) that holds it.
TIMED_SENTENCES = {"GGA": 1, "GNS": 1, "RMC": 1, "ZDA": 1, "GLL": 5}
#: The most lines :class:`SpreadClock` holds while it waits for the next time.
MOST_HELD = 100_000
#: Seconds in a day, and half of it: the largest step back that is a step back, not midnight.
DAY = 86400.0
_HALF_DAY = DAY / 2
_EPOCH = _dt.date(1970, 1, 1).toordinal()


def time_of_day(field: bytes) -> float:
    """Seconds since UTC midnight of an ``hhmmss`` or ``hhmmss.ss`` field, NaN when it is
    not one (hours 0-23, minutes 0-59, seconds below 61 for a leap second)."""
    if len(field) < 6 or not field[:6].isdigit():
        return math.nan
    hours, minutes = int(field[0:2]), int(field[2:4])
    try:
        seconds = float(field[4:])
    except ValueError:
        return math.nan
    if hours > 23 or minutes > 59 or not (0.0 <= seconds < 61.0):
        return math.nan
    return hours * 3600.0 + minutes * 60.0 + seconds


def _day_number(year: int, month: int, day: int) -> int | None:
    """Days since 1970-01-01 of a calendar date, None when it is not one."""
    try:
        return _dt.date(year, month, day).toordinal() - _EPOCH
    except ValueError:
        return None


def sentence_date(formatter: str, fields: list[bytes]) -> int | None:
    """The date (days since 1970-01-01) an RMC or ZDA carries, None without one.

    RMC's ``ddmmyy`` has a two-digit year: 80 to 99 are 1980 to 1999 (GPS time began in
    1980), 00 to 79 are 2000 to 2079."""
    try:
        if formatter == "RMC" and len(fields) > 9 and len(fields[9]) == 6 and fields[9].isdigit():
            text = fields[9]
            year = int(text[4:6])
            return _day_number(year + (1900 if year >= 80 else 2000), int(text[2:4]), int(text[0:2]))
        if formatter == "ZDA" and len(fields) > 4 and all(fields[i].isdigit() for i in (2, 3, 4)):
            return _day_number(int(fields[4]), int(fields[3]), int(fields[2]))
    except ValueError:
        return None
    return None


def sentence_time(formatter: str, body: bytes) -> tuple[float, int | None]:
    """``(time of day, date)`` of a sentence: seconds since UTC midnight (NaN when the
    sentence carries none or an unreadable one) and days since 1970-01-01 (None).

    Parameters
    ----------
    formatter : str
        The sentence's formatter (``GGA``).
    body : bytes
        The sentence from its address to before ``*`` (``GPGGA,123519,...``).
    """
    index = TIMED_SENTENCES.get(formatter)
    if index is None:
        return math.nan, None
    fields = body.split(b",")
    if len(fields) <= index:
        return math.nan, None
    return time_of_day(fields[index].strip()), sentence_date(formatter, fields)


class SentenceClock:
    """The time of each line of a raw log, from the times inside its sentences (module
    docstring).

    Parameters
    ----------
    origin_day : int
        The first date's day number (days since 1970-01-01) less the days counted
        before it (:func:`anchor_day`); 0 for a log without a date.

    Attributes
    ----------
    now : float
        The time of the latest timed sentence (s; NaN before the first).
    ignored_dates : int
        Dates that disagreed with the day counted from the times of day.
    """

    def __init__(self, origin_day: int = 0):
        self.origin_day = int(origin_day)
        self.day = 0  # days counted from the first timed sentence's
        self._last = math.nan  # the latest time, days counted from the first
        self.now = math.nan
        self.ignored_dates = 0

    def tick(self, formatter: str, body: bytes) -> float:
        """The time of a line whose sentence is ``formatter`` and ``body`` (see
        :func:`sentence_time`): its own if it carries one, else the latest before it."""
        self.timed(formatter, body)
        return self.now

    def timed(self, formatter: str, body: bytes) -> bool:
        """Whether the sentence carries a time (then :attr:`now` is its time)."""
        if formatter not in TIMED_SENTENCES:
            return False
        seconds, date = sentence_time(formatter, body)
        if math.isnan(seconds):
            return False
        self._advance(seconds, date)
        return True

    def _advance(self, seconds: float, date: int | None) -> None:
        if math.isnan(self._last):
            day = 0
        else:
            # the day of the three around the count that puts it closest to the time before
            day = min((self.day - 1, self.day, self.day + 1), key=lambda d: abs(d * DAY + seconds - self._last))
            if day == self.day + 1:
                self.day = day
        if date is not None and date != self.origin_day + day:
            self.ignored_dates += 1
        time = day * DAY + seconds
        if day >= self.day:  # a late line of the day before does not move the count back
            self._last = time
        self.now = (self.origin_day + day) * DAY + seconds


def anchor_day(lines: Iterable[tuple[str, bytes]]) -> int:
    """The origin day of a :class:`SentenceClock` for a log's sentences: the first
    date's day number less the days counted up to it (0 when no sentence carries a
    date). ``lines`` yields ``(formatter, body)`` of the well-framed sentences in file
    order; it is read up to the first date."""
    clock = SentenceClock()
    for formatter, body in lines:
        if formatter not in TIMED_SENTENCES:
            continue
        seconds, date = sentence_time(formatter, body)
        if math.isnan(seconds):
            continue
        clock._advance(seconds, None)
        if date is not None:
            return date - round((clock.now - seconds) / DAY)  # less the day counted for this line
    return 0


class SpreadClock:
    """The times of a raw log's lines, the lines between two timed sentences spread
    evenly between their times (the module docstring's rule).

    Lines go in with :meth:`feed` in file order and come out, with their times, in the
    same order once their time is known: at the next timed sentence, or at
    :meth:`flush` after the last line.

    Parameters
    ----------
    origin_day : int
        As :class:`SentenceClock`'s.
    most_held : int
        Lines held at most before they are placed at the last time.
    """

    def __init__(self, origin_day: int = 0, most_held: int = MOST_HELD):
        self.clock = SentenceClock(origin_day)
        self.most_held = int(most_held)
        self._latest = math.nan
        self._held: list[tuple[object, bytes]] = []

    @property
    def ignored_dates(self) -> int:
        """As :attr:`SentenceClock.ignored_dates`."""
        return self.clock.ignored_dates

    def feed(self, item: object, formatter: str, body: bytes, key: bytes = b"") -> list[tuple[object, float]]:
        """``[(item, time), ...]`` of the lines whose time this line makes known.

        Parameters
        ----------
        item : object
            What the caller gets back with its time (the line, its number).
        formatter, body : str, bytes
            The line's sentence (:func:`sentence_time`); ``""`` and ``b""`` for a line
            that is not a well-framed sentence (it is held like an untimed one).
        key : bytes
            The kind of line whose lines are spread together (its address and source).
        """
        if formatter in TIMED_SENTENCES and self.clock.timed(formatter, body):
            time = self.clock.now
            placed = self._spread(self._latest, time)
            placed.append((item, time))
            if math.isnan(self._latest) or time > self._latest:
                self._latest = time
            return placed
        self._held.append((item, key))
        if len(self._held) > self.most_held:
            return self.flush()
        return []

    def flush(self) -> list[tuple[object, float]]:
        """The lines held, at the latest time (NaN before the first)."""
        placed = [(item, self._latest) for item, _ in self._held]
        self._held = []
        return placed

    def _spread(self, start: float, end: float) -> list[tuple[object, float]]:
        if math.isnan(start) or not end > start:  # before the first time, or a step back: at the latest
            return self.flush()
        counts: dict[bytes, int] = {}
        for _, key in self._held:
            counts[key] = counts.get(key, 0) + 1
        seen: dict[bytes, int] = {}
        placed = []
        for item, key in self._held:
            i = seen.get(key, 0)
            seen[key] = i + 1
            placed.append((item, start + i * (end - start) / counts[key]))
        self._held = []
        return placed


__all__ = ["DAY", "MOST_HELD", "TIMED_SENTENCES", "SentenceClock", "SpreadClock", "anchor_day", "sentence_date", "sentence_time", "time_of_day"]
