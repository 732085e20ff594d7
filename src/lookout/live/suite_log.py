"""Which of a sensor suite's instruments a simulated log carries, and how each is
stamped so that a replay gives its sentences back to it (``lookout write-log``).

A position reference that a fix measures (``gnss``, ``hydroacoustic``) is written as
GGA, a ``gyrocompass`` as THS (:data:`lookout.live.sensors.FED`), a ``rate-gyro`` as
ROT (in degrees per minute, three decimals); an IMU (the suite's
only one) is written beside the log as a CSV log ``time,fx,fy,r``
(:mod:`lookout.io.logs`); the other kinds are left out: a taut wire and a second IMU
have no sentence that lookout reads, and a speed log's VHW and a GNSS velocity's VTG
carry a speed without a sign, which a simulated speed of noise about zero (a vessel at
rest) does not fit. Each written sensor's sentences carry its ``source``
(:func:`lookout.io.nmea.source_spec`): its talker (GP for a receiver, HE for a gyro
when the source names none) and, when it names a sender, a tag block ``s:SENDER``. A
sensor without a source is given ``@NAME``: a tag block with its own name. Each stamp
is checked with the live session's own routing (:func:`lookout.live.sensors.route`):
a replay with the same sources gives every sentence to the sensor it came from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from lookout.io.nmea import source_rank, source_spec, tag_block, talker_family
from lookout.io.simulated_log import LoggedSensor
from lookout.live.sensors import FAMILIES, FED, READS, LiveSensor, route
from lookout.sensing.motion import InertialUnit
from lookout.sensing.rate_gyro import RateGyro

if TYPE_CHECKING:
    from lookout.sensing.suite import SensorSuite

#: The talker of a sensor's sentences when its source names none, by what it measures.
DEFAULT_TALKERS = {"position": "GP", "heading": "HE", "rate_of_turn": "TI"}
#: The sentence each reading kind is written as.
SENTENCES = {"position": "GGA", "heading": "THS", "rate_of_turn": "ROT"}
#: The instrument kinds a log carries and the reading kind each becomes.
LOGGED = {**FED, RateGyro: "rate_of_turn"}


@dataclass(frozen=True)
class SuiteLog:
    """A suite's instruments as a log carries them.

    Attributes
    ----------
    sensors : tuple of LoggedSensor
        The instruments written, in the suite's order.
    sources : dict of str to str
        Each written sensor's source as a replay must name it (its own ``source``, or
        the one assumed).
    assumed : tuple of str
        The written sensors that name no source, given ``@NAME``.
    skipped : tuple of (str, str)
        ``(name, kind)`` of each instrument left out (no sentence carries it).
    imu : (str, float) or None
        ``(name, sample_period)`` of the IMU written as a CSV log beside the log (the
        suite's only IMU), None when it has none or several.
    """

    sensors: tuple[LoggedSensor, ...]
    sources: dict[str, str]
    assumed: tuple[str, ...]
    skipped: tuple[tuple[str, str], ...]
    imu: tuple[str, float] | None = None


def _written(talker: str, sender: str | None) -> str:
    """A reading's source (:class:`lookout.io.nmea.Reading`) of a sentence so stamped."""
    return talker if sender is None else f"{talker}@{sender}"


def suite_log(suite: SensorSuite) -> SuiteLog:
    """How ``suite``'s instruments are written to a log (module docstring).

    Raises
    ------
    ValueError
        One line: the suite has no position reference or no gyrocompass that a
        sentence carries; a source that cannot be written (a talker of the other kind's
        family, the proprietary talker P, a sender a tag block cannot carry, a sensor
        without a source whose name a tag block cannot carry); two sources a replay
        could not tell apart (the sensor its sentences would go to named).
    """
    from lookout.scenario.registry import kind_of

    logged: list[LoggedSensor] = []
    live: dict[str, LiveSensor] = {}
    sources: dict[str, str] = {}
    assumed: list[str] = []
    skipped: list[tuple[str, str]] = []
    units = [(name, float(each.sample_period)) for name, each in zip(suite.names, suite.instruments) if isinstance(each, InertialUnit)]
    imu = units[0] if len(units) == 1 else None
    for index, (name, each) in enumerate(zip(suite.names, suite.instruments)):
        kind = LOGGED.get(type(each))
        if imu is not None and name == imu[0]:
            continue
        if kind is None:
            skipped.append((name, kind_of(each)))
            continue
        source = getattr(each, "source", None)
        if source is None:
            try:
                tag_block(name)
            except ValueError:
                raise ValueError(
                    f"sensors.{name}: it names no source, and a tag block cannot carry its name (printable ASCII): give it a source "
                    '(source = "GP", "@dgps1" or "GP@dgps1")'
                ) from None
            source = f"@{name}"
            assumed.append(name)
        talker, sender = source_spec(source)
        family = talker_family(talker)
        if family is not None and family != FAMILIES[kind]:
            raise ValueError(f"sensors.{name}.source: {source!r} is a {family} talker; sensor {name} takes {READS[kind]}")
        if talker == "P":
            raise ValueError(
                f"sensors.{name}.source: {source!r}: the proprietary talker P has no {SENTENCES[kind]}; give a talker of two letters or none"
            )
        if sender is not None:
            try:
                tag_block(sender)
            except ValueError as error:
                raise ValueError(f"sensors.{name}.source: {source!r}: {error}") from None
        signal = each.signals[0].name  # a position reference's measured_position, a gyro's measured_heading, a rate gyro's measured_yaw_rate
        logged.append(LoggedSensor(name, kind, f"{name}.{signal}", float(each.sample_period), talker or DEFAULT_TALKERS[kind], sender))
        live[name] = LiveSensor(name, index, kind, source, talker, sender, slice(0, 0), math.inf)
        sources[name] = source
    kinds = {each.kind for each in logged}
    if not {"position", "heading"} <= kinds:
        listed = ", ".join(f"{name} {kind_of(each)}" for name, each in zip(suite.names, suite.instruments))
        missing = " and no ".join(what for what, kind in (("position reference", "position"), ("gyrocompass", "heading")) if kind not in kinds)
        raise ValueError(
            "a log of a sensor suite needs a position reference (gnss, hydroacoustic) and a gyrocompass, the instruments a log carries; "
            f"it has no {missing} (sensors: {listed})"
        )
    for sensor in logged:
        written = _written(sensor.talker, sensor.sender)
        taker = route(live, written, sensor.kind)
        if taker is None or taker.name != sensor.name:
            how = f"{SENTENCES[sensor.kind]} as {sensor.talker}" + (f" with tag block s:{sensor.sender}" if sensor.sender is not None else "")
            if taker is not None:
                whom = f"would go to sensor {taker.name} (source {taker.source!r})"
            else:
                rank = source_rank(written, live[sensor.name].talker, live[sensor.name].sender)
                tied = [
                    o.name
                    for o in live.values()
                    if o.kind == sensor.kind and o.name != sensor.name and source_rank(written, o.talker, o.sender) == rank
                ]
                whom = f"would match sensor {', '.join(tied)}'s source as closely: two sensors of a kind need sources a replay tells apart"
            raise ValueError(f"sensors.{sensor.name}.source: {sources[sensor.name]!r}: its sentences, written {how}, {whom} in a replay")
    return SuiteLog(tuple(logged), sources, tuple(assumed), tuple(skipped), imu)


__all__ = ["DEFAULT_TALKERS", "SuiteLog", "suite_log"]
