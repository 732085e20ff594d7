"""An observer on a stream of position and heading readings, one step per sample period.

:class:`Session` takes readings in the order they arrived (:meth:`Session.feed`) and
steps a scenario's observer on a fixed grid ``t_n = n h`` (h the scenario's sample
period) with :meth:`Session.advance`: each step on the readings that had arrived by
``t_n``. What happens to a reading:

- a position fix needs a GGA fix quality of at least ``min_quality`` and an HDOP of
  at most ``max_hdop``; it becomes local north/east on WGS-84 about the session's
  :class:`~lookout.io.LocalFrame` (the first fix's, unless one is given);
- a heading is wrapped to [-pi, pi), as a simulated heading sensor's;
- of several sources of one kind (two DGNSS receivers), the one in use stays in use
  until it has been silent for the channel's timeout; then the next that speaks. A
  source is a device, not a talker ID: a multi-constellation receiver's GP and GN
  fixes, or a gyro's HE and HC headings, from one sender are one source
  (:func:`lookout.io.nmea.receiver`, where ``sources`` binds others by name);
- a fix farther than :data:`~lookout.live.options.MAX_ORIGIN_DISTANCE` from a given
  frame's origin is refused (:class:`OriginError`, before the session uses it);
- the newest reading of each channel since the last step goes into the step. Hold,
  timeout and the wild-point gate are :class:`~lookout.live.gate.GatedObserver`'s,
  inside the compiled step: a Kalman filter's readings are gated on their normalized
  innovation squared (the chi-square bound of ``gate_probability``), another
  observer's on the length of its ``innovation_<channel>`` output (``position_gate``,
  ``heading_gate``); a channel the observer gives neither for is not gated, and the
  session says so (:attr:`Session.ungated`, a warning);
- a silence of every channel longer than the longest timeout is a ``gap`` event
  (where it starts and how long it was), reported when the next reading comes.

With a scenario's named sensors (``suite``, a
:class:`~lookout.sensing.suite.SensorSuite`), each reading goes to the sensor whose
``source`` it comes from instead, each sensor holds its own, and the suite's combining
stage gives the observer its position and heading at each step, as in simulation
(:mod:`lookout.live.sensors`); the session records every sensor's channel
(:attr:`Session.record_layout`).

A step's results come out as a :class:`Block` (one step live; many in a fast replay,
which runs ``batch`` steps in one compiled scan). Events (outage, recovered, gated,
source, frame, gap, refused) go to ``on_event``. Every reading the session does not
use is counted by its reason (:attr:`Session.unused`).
"""

from __future__ import annotations

import math
import time as _time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from lookout.io.geodesy import LocalFrame
from lookout.io.nmea import Reading, receiver
from lookout.live.gate import GatedObserver, flag_name, gate_tests
from lookout.live.options import IMU_LIMITS, MAX_ORIGIN_DISTANCE, Gates, _positive
from lookout.sim.filtering import Stepper

if TYPE_CHECKING:
    from lookout.components import Layout, Observer
    from lookout.live.sensors import LiveSensor
    from lookout.sensing.suite import SensorSuite

#: The measurement signals a live observer's layout may name, and the reading kind
#: that fills each.
CHANNELS = {"measured_position": "position", "measured_heading": "heading"}

#: The reasons a session does not use a reading, in the order a status line lists them:
#: ``late`` (stamped before the reading before it), ``not_read`` (a kind the observer
#: does not read: rate of turn, the error ellipse, a channel it does not measure),
#: ``quality`` and ``hdop`` (a fix below ``min_quality`` or above ``max_hdop``), ``range``
#: (an IMU reading beyond :data:`~lookout.live.options.IMU_LIMITS`),
#: ``other_source`` (a second source while the one in use speaks), ``superseded`` (a
#: newer reading of its channel came before the step) and ``gated`` (a wild point).
UNUSED_REASONS = ("late", "not_read", "quality", "hdop", "range", "other_source", "superseded", "gated")
#: Mean radius of the Earth (m, IUGG), for the distance of a fix from an origin.
EARTH_RADIUS = 6_371_008.8


def distance(latitude_a: float, longitude_a: float, latitude_b: float, longitude_b: float) -> float:
    """Great-circle distance (m) between two points given in degrees (haversine on a
    sphere of :data:`EARTH_RADIUS`: to 0.5 %, enough to tell near from far)."""
    phi_a, phi_b = math.radians(latitude_a), math.radians(latitude_b)
    half = math.sin((phi_b - phi_a) / 2) ** 2 + math.cos(phi_a) * math.cos(phi_b) * math.sin(math.radians(longitude_b - longitude_a) / 2) ** 2
    return 2 * EARTH_RADIUS * math.asin(min(1.0, math.sqrt(half)))


def _wrapped(angle: float) -> float:
    """An angle (rad) wrapped to [-pi, pi), as a simulated heading sensor's (:mod:`lookout.sensors`)."""
    return angle - 2 * math.pi * math.floor((angle + math.pi) / (2 * math.pi))


class OriginError(ValueError):
    """A fix too far from the frame's origin for a flat local frame.

    Attributes
    ----------
    frame : LocalFrame
    latitude, longitude : float
        The fix (degrees).
    meters : float
        Its distance from the origin.
    where : str
        Which fix (``the first fix``, ``the log's first fix``).
    """

    def __init__(self, frame: LocalFrame, latitude: float, longitude: float, meters: float, where: str = "the first fix"):
        self.frame, self.latitude, self.longitude, self.meters, self.where = frame, latitude, longitude, meters, where
        super().__init__(self.message("frame"))

    def message(self, option: str) -> str:
        """The refusal in one line, naming the origin as ``option`` (``--origin`` at the command line)."""
        limit = MAX_ORIGIN_DISTANCE / 1e3
        return (
            f"{option} {self.frame.latitude:g},{self.frame.longitude:g} lies {self.meters / 1e3:.0f} km from {self.where}, "
            f"{self.latitude:.6f},{self.longitude:.6f} (degrees), more than {limit:g} km: a flat north/east frame so far from its origin "
            f"turns and bends the readings; omit {option} to take the first fix as the origin, or give one within {limit:g} km of it"
        )


def check_origin(frame: LocalFrame, latitude: float, longitude: float, where: str = "the first fix") -> None:
    """Refuse (:class:`OriginError`) a fix farther than
    :data:`~lookout.live.options.MAX_ORIGIN_DISTANCE` from ``frame``'s origin."""
    meters = distance(frame.latitude, frame.longitude, latitude, longitude)
    if not meters <= MAX_ORIGIN_DISTANCE:
        raise OriginError(frame, latitude, longitude, meters, where)


def fix_refusal(values: tuple[float, ...], gates: Gates) -> str | None:
    """Why a position reading's fix is not used (``quality``, ``hdop``), None if it passes."""
    _, _, quality, hdop = values
    # 6 estimated (the receiver's own dead reckoning), 7 manual, 8 simulator: never a fix
    if quality < gates.min_quality or quality in (6.0, 7.0, 8.0):
        return "quality"
    if hdop > gates.max_hdop:  # an HDOP the sentence leaves empty (NaN) passes
        return "hdop"
    return None


def percent(probability: float) -> str:
    """``probability`` in percent, every digit it was given with (0.999999: ``99.9999``;
    a rounded label could read 100 %)."""
    from decimal import Decimal

    text = format((Decimal(repr(float(probability))) * 100).normalize(), "f")
    return text


@dataclass
class Block:
    """Consecutive steps' results.

    Attributes
    ----------
    time : ndarray (n,)
        Step times on the stream's clock (s).
    session_time : ndarray (n,)
        Seconds since the session's first step.
    estimate : dict of ndarray
        The observer's outputs, one row per step (with ``gated_<channel>`` and
        ``outage_<channel>`` flags).
    measurement : ndarray (n, n_y)
        What each step used (held readings; NaN in an outage), laid out as the
        session's :attr:`~Session.record_layout`.
    input : ndarray (n, n_u)
    step_seconds : ndarray (n,)
        Wall-clock seconds per step (a scan's time shared out).
    """

    time: np.ndarray
    session_time: np.ndarray
    estimate: dict
    measurement: np.ndarray
    input: np.ndarray
    step_seconds: np.ndarray

    def __len__(self) -> int:
        return self.time.size


@dataclass
class _Channel:
    """What a session knows of one measured signal (a named sensor, read directly)."""

    name: str
    kind: str
    columns: slice
    timeout: float
    flag: str = ""  # what the step's gated_ and outage_ flags are named after (default: kind)
    arrivals: tuple[int, ...] = ()  # its gated channels' arrival entries (default: its index)
    source: str | None = None
    source_time: float = -math.inf  # the last reading of the source in use
    new: tuple | None = None  # the newest reading since the last step
    new_time: float = math.nan
    in_outage: bool = False
    outage_since: float = math.nan

    def __post_init__(self):
        self.flag = self.flag or self.kind
        self.counts = {"accepted": 0, "gated": 0, "quality": 0, "hdop": 0, "other_source": 0, "superseded": 0, "range": 0}


class Session:
    """A scenario's observer stepped on readings as they arrive.

    Parameters
    ----------
    observer : Observer
        Its measurement layout must name ``measured_position`` (north, east) and/or
        ``measured_heading``; other measured channels stay NaN.
    sample_period : float
        The observer's step (s), the scenario's ``simulation.sample_period``.
    guess : PyTree, optional
        The observer's initial guess (default ``observer.guess()``).
    frame : LocalFrame, optional
        The local north-east frame of position fixes; default the first accepted fix.
        A given frame's origin must lie within
        :data:`~lookout.live.options.MAX_ORIGIN_DISTANCE` of the first accepted fix
        (else :meth:`feed` raises :class:`OriginError`).
    gates : Gates, optional
    on_event : callable, optional
        Called with a dict for each event (frame, source, gated, outage, recovered,
        gap, refused).
    batch : int
        Steps per compiled call: 1 live (each step as soon as it is due), more in a
        fast replay (:meth:`finish` runs what is left).
    step_on : {"heading", "position", None}
        The channel whose reading takes its step at once, without waiting for the
        step's time (default heading, the fastest of a DP vessel's: its estimate
        leaves as soon as its sentence came); the others' readings go into the next
        step taken. None: steps at their times only.
    sources : mapping of str to str, optional
        Sources bound to names by the user (:func:`lookout.io.nmea.receiver`): e.g.
        ``{"GP": "dgps", "GN": "rtk"}`` keeps two receivers' GP and GN fixes apart,
        which are otherwise one GNSS receiver's.
    suite : SensorSuite, optional
        The scenario's named sensors (its ``[sensors.NAME]``): each reading goes to the
        sensor whose ``source`` it comes from, and the suite's combining stage gives
        the observer's ``measured_position`` and ``measured_heading``
        (:mod:`lookout.live.sensors`). Not with ``sources``.

    Raises
    ------
    ValueError
        For an observer, a period, gates or sources the session cannot use; with
        ``suite``, for a sensor's ``source`` it cannot use (``sensors.NAME.source: ...``).

    Warns
    -----
    UserWarning
        For a channel no test gates, and for a sensor a stream could feed that names
        no source.
    """

    def __init__(
        self,
        observer: Observer,
        sample_period: float,
        *,
        guess: Any = None,
        frame: LocalFrame | None = None,
        gates: Gates | None = None,
        on_event: Callable[[dict], object] | None = None,
        batch: int = 1,
        step_on: str | None = "heading",
        sources: Mapping[str, str] | None = None,
        suite: SensorSuite | None = None,
    ):
        _positive("sample_period", sample_period)
        if frame is not None and not isinstance(frame, LocalFrame):
            raise ValueError(f"frame must be a lookout.io.LocalFrame; got {type(frame).__name__}")
        gates = Gates() if gates is None else gates
        if not isinstance(gates, Gates):
            raise ValueError(f"gates must be a lookout.live.Gates; got {type(gates).__name__}")
        if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1:
            raise ValueError(f"batch must be a positive integer; got {batch!r}")
        layout = observer.measurement_layout
        names = layout.names
        #: Whether the observer reads the suite's instruments themselves (a Kalman filter
        #: on a suite: :func:`~lookout.observers.kalman.filter_layout`), each fed directly.
        self.direct = suite is not None and names == suite.instrument_layout.names
        if not self.direct and not set(names) & set(CHANNELS):
            raise ValueError(
                f"observer {type(observer).__name__} measures {', '.join(names)}; live data fills measured_position (north, east) and measured_heading"
            )
        if "measured_position" in names and layout.signals[names.index("measured_position")].labels != ("north", "east"):
            raise ValueError("observer's measured_position must be (north, east) for position fixes")
        period = getattr(observer, "sample_period", None)
        if period is not None and abs(period - sample_period) > 1e-9 * period:
            raise ValueError(f"sample_period must be the observer's own {period:g} s (a discrete-time observer); got {sample_period:g} s")
        if step_on not in (None, "heading", "position"):
            raise ValueError(f"step_on must be 'heading', 'position' or None; got {step_on!r}")
        if sources is not None and not (
            hasattr(sources, "items") and all(isinstance(k, str) and isinstance(v, str) and k and v for k, v in sources.items())
        ):
            raise ValueError(f"sources must map sources or talkers (str) to names (str); got {sources!r}")
        self.sources = dict(sources or {})
        if suite is not None and sources:
            raise ValueError("sources binds talkers of one position and one heading channel; a scenario's named sensors each name their own source")
        self._origin_checked = frame is None  # a given origin is checked against the first fix
        self.observer = observer
        self.sample_period = float(sample_period)
        self.guess = guess
        self.frame = frame
        self.gates = gates
        self.on_event = on_event
        self.batch = int(batch)
        self.channels: dict[str, _Channel] = {}
        #: The named sensors a stream feeds, by name (empty without a suite).
        self.sensors: dict[str, LiveSensor] = {}
        # the gated observer's channels: (name, size, kind, the session's channel), in its measurement's order
        gated_channels: list[tuple[str, int, str, str]] = []
        silent: tuple[str, ...] = ()  # the named sensors no source feeds
        if self.direct:
            assert suite is not None  # direct needs one
            from lookout.live.sensors import live_sensors

            self.sensors, silent = live_sensors(suite, gates, direct=True)
            spans, start = [], 0
            for signal in layout.signals:
                spans.append((signal, start))
                start += signal.size
            for sensor in self.sensors.values():
                mine = [(signal, at) for signal, at in spans if sensor.columns.start <= at < sensor.columns.stop]
                arrivals = tuple(range(len(gated_channels), len(gated_channels) + len(mine)))
                gated_channels += [(signal.name, signal.size, sensor.kind, sensor.name) for signal, _ in mine]
                self.channels[sensor.name] = _Channel(sensor.name, sensor.kind, sensor.columns, sensor.timeout, flag_name(mine[0][0].name), arrivals)
        else:
            start = 0
            for signal in layout.signals:
                if signal.name in CHANNELS:
                    kind = CHANNELS[signal.name]
                    timeout = gates.position_timeout if kind == "position" else gates.heading_timeout
                    arrivals = (len(gated_channels),)
                    self.channels[kind] = _Channel(signal.name, kind, slice(start, start + signal.size), timeout, arrivals=arrivals)
                    gated_channels.append((signal.name, signal.size, kind, kind))
                start += signal.size
        self.step_on = step_on if step_on in {channel.kind for channel in self.channels.values()} else None
        from scipy.stats import chi2  # here: scipy.stats takes a while to import, and the command imports this module

        names = tuple(name for name, *_ in gated_channels)
        # an IMU is an input to the observer that integrates it: its readings are
        # range-checked as they come (IMU_LIMITS), not gated on an innovation
        tests = tuple("none" if kind == "imu" else test for (_, _, kind, _), test in zip(gated_channels, gate_tests(observer, names)))
        bounds = []
        for (_, size, kind, _), test in zip(gated_channels, tests):
            if test == "nis":  # the chi-square quantile, the channel's size its degrees of freedom
                bounds.append(float(chi2.ppf(gates.gate_probability, size)))
            else:
                bounds.append(gates.position_gate if kind == "position" else math.radians(gates.heading_gate))
        #: The test of each channel's readings: ``nis``, ``innovation``, ``none``, or for an IMU ``range``.
        self.gate_tests = {key: "range" if channel.kind == "imu" else tests[channel.arrivals[0]] for key, channel in self.channels.items()}
        #: The channels no test gates (the observer gives neither innovation statistics nor an innovation output).
        self.ungated = tuple(kind for kind, test in self.gate_tests.items() if test == "none")
        if self.ungated:
            warnings.warn(
                f"lookout live: observer {type(observer).__name__} gives no innovation for {', '.join(self.ungated)}: "
                "wild points there are not gated",
                UserWarning,
                stacklevel=2,
            )
        timeouts = np.array([self.channels[key].timeout for *_, key in gated_channels])
        stepped = observer
        if self.direct:  # each reading taken once, when it comes, every channel due at every step
            due_every = getattr(observer, "due_every", None)
            if due_every is None:
                raise ValueError(f"observer {type(observer).__name__} reads a suite's instruments; live, only a Kalman filter's can")
            stepped = due_every(self.sample_period)
        self.gated_observer: Observer = GatedObserver(stepped, names, np.array(bounds), timeouts, gates.reopen_after, tests, hold=not self.direct)
        self.suite = suite
        if self.direct:
            self._record_layout = layout
        elif suite is not None:
            from lookout.live.sensors import CombiningObserver, live_sensors, record_layout

            unfed = [name for name in layout.names if name not in CHANNELS]
            if unfed:
                raise ValueError(
                    f"observer {type(observer).__name__} reads {', '.join(unfed)}; live data feeds it the combining stage's "
                    "measured_position and measured_heading only"
                )
            self.sensors, silent = live_sensors(suite, gates)
            gated = self.gated_observer
            assert isinstance(gated, GatedObserver)  # made just above
            self.gated_observer = CombiningObserver(gated, suite)
            self._record_layout = record_layout(suite)
        else:
            self._record_layout = layout
        if silent:
            warnings.warn(
                f"lookout live: sensor{'s' if len(silent) > 1 else ''} {', '.join(silent)} name{'' if len(silent) > 1 else 's'} no source: "
                "no reading feeds them",
                UserWarning,
                stacklevel=2,
            )
        #: A silence of every channel longer than this (s) is a gap: the longest timeout.
        self.gap_after = max(c.timeout for c in self.channels.values())
        self.gaps = 0
        self._last_measurement = math.nan
        self._size = layout.size
        self._input = np.zeros(observer.input_layout.size)
        self.thrust_seen = False
        self.stepper: Stepper | None = None
        self.step_index: int | None = None  # n of the next step, t_n = n h
        self.start_index: int | None = None
        self.steps = 0
        self.late = 0
        self.not_read = 0
        self.refused = 0
        self.events: list[dict] = []
        self.event_counts = {"outage": 0, "recovered": 0, "gated": 0, "source": 0, "refused": 0, "gap": 0}
        # the steps kept for the next compiled call: times, session times, raw measurements, inputs
        n_raw = self.gated_observer.measurement_layout.size
        self._times = np.empty(self.batch)
        self._session_times = np.empty(self.batch)
        self._raw = np.empty((self.batch, n_raw))
        self._inputs = np.empty((self.batch, self._input.size))
        self._kept = 0
        self._started = False
        self._last_reading = -math.inf

    @property
    def gate_rule(self) -> str:
        """The gate in words, for a status line: ``NIS > chi-square 99.99 %`` (the
        probability to every digit given),
        ``position innovation > 30 m, heading innovation > 15 deg``, or ``off``."""
        words = {}
        for key, test in self.gate_tests.items():
            kind = self.channels[key].kind
            if test == "nis":
                words[key] = f"NIS > chi-square {percent(self.gates.gate_probability)} %"
            elif test == "innovation":
                words[key] = f"innovation > {self.gates.position_gate:g} m" if kind == "position" else f"innovation > {self.gates.heading_gate:g} deg"
            elif test == "range":
                words[key] = f"beyond {IMU_LIMITS[0]:g} m/s2 or {math.degrees(IMU_LIMITS[1]):g} deg/s"
            else:
                words[key] = "off"
        tested = {key: rule for key, rule in words.items() if self.gate_tests[key] != "range"}
        rules = set(tested.values())
        if len(rules) == 1 and "innovation" not in next(iter(rules)):
            parts = [next(iter(rules))]
        else:
            parts = [f"{key} {rule}" for key, rule in tested.items()]
        return ", ".join(parts + [f"{key} {rule}" for key, rule in words.items() if key not in tested])

    @property
    def gate_uses(self) -> set[tuple[str, str]]:
        """The (kind, test) pairs of the channels: which gate options apply."""
        return {(self.channels[key].kind, test) for key, test in self.gate_tests.items()}

    @property
    def kinds(self) -> tuple[str, ...]:
        """The kinds of reading the observer needs from a log (position, heading), in order."""
        return tuple(dict.fromkeys(channel.kind for channel in self.channels.values() if channel.kind in ("position", "heading")))

    @property
    def record_layout(self) -> Layout:
        """The layout of a :class:`Block`'s measurement: the observer's measurement; with
        named sensors each sensor's channels, then the combining stage's
        (:func:`lookout.live.sensors.record_layout`)."""
        return self._record_layout

    @property
    def unused(self) -> dict:
        """The readings the session did not use, by reason (:data:`UNUSED_REASONS`, in
        that order; zeros left out). Lines that gave no reading are the parser's."""
        totals = {"late": self.late, "not_read": self.not_read}
        for reason in UNUSED_REASONS[2:]:
            totals[reason] = sum(channel.counts[reason] for channel in self.channels.values())
        return {reason: totals[reason] for reason in UNUSED_REASONS if totals[reason]}

    # ----------------------------------------------------------------- readings
    def feed(self, reading: Reading) -> list[Block]:
        """Take one reading (in arrival order); the next step uses it. A reading of the
        ``step_on`` channel takes its step at once (the blocks computed are returned)."""
        if reading.time < self._last_reading:
            self.late += 1  # stamped before the reading before it: a reordered log
            return []
        self._last_reading = reading.time
        if reading.kind != "thrust":
            silence = reading.time - self._last_measurement
            if silence > self.gap_after:
                self.gaps += 1
                self._event("gap", self._last_measurement, length=silence)
            self._last_measurement = reading.time
        taken = self._take(reading)
        if taken and self.step_on == {"local_position": "position"}.get(reading.kind, reading.kind):
            if self.step_index is None:
                self._start()
            if self.step_index is not None and self.time_of(self.step_index - 1) < reading.time <= self.time_of(self.step_index):
                end = self.step_index + 1
                return self._take_steps(lambda: self.step_index < end)
        return []

    def _take(self, reading: Reading) -> bool:
        """Keep the reading for the next step; whether it was kept as a measurement."""
        if reading.kind == "thrust":
            if self._input.size:  # an observer without input (the IMU-aided one) predicts without thrust
                self._input = np.asarray(reading.values, dtype=float)
            self.thrust_seen = True
            return False
        if self.direct:
            return self._direct_take(reading, {"local_position": "position"}.get(reading.kind, reading.kind))
        kind = {"local_position": "position", "position": "position", "heading": "heading"}.get(reading.kind)
        channel = self.channels.get(kind) if kind is not None else None
        if channel is None:
            self.not_read += 1  # rate of turn, the error ellipse, a channel the observer does not measure
            return False
        sensor = None
        if self.sensors:
            from lookout.live.sensors import route

            assert kind is not None  # a channel was found for it
            sensor = route(self.sensors, reading.source, kind)
            if sensor is None:  # no sensor's source, or two sensors' equally
                channel.counts["other_source"] += 1
                return False
        value = self._value(reading, channel)
        if value is None:
            return False
        if sensor is not None:
            return self._sensor_take(sensor, channel, reading, value)
        source = receiver(reading.source, self.sources)
        if channel.source is not None and source != channel.source and reading.time - channel.source_time <= channel.timeout:
            channel.counts["other_source"] += 1
            return False
        if source != channel.source:
            self._event("source", reading.time, channel=channel.name, source=source, previous=channel.source)
            channel.source = source
        channel.source_time = reading.time
        self._new(channel, reading, value)
        return True

    @staticmethod
    def _new(channel: _Channel, reading: Reading, value: tuple) -> None:
        """Keep ``value`` as the channel's new reading."""
        if channel.new is not None:
            channel.counts["superseded"] += 1  # the step takes the newest reading of its channel
        channel.new, channel.new_time = value, reading.time
        channel.counts["accepted"] += 1

    def _direct_take(self, reading: Reading, kind: str) -> bool:
        """Keep a reading for the named sensor it comes from (an observer reading the
        suite's instruments): the sensor's channel's new reading."""
        from lookout.live.sensors import route

        sensor = route(self.sensors, reading.source, kind)
        if sensor is None:
            if any(each.kind == kind for each in self.sensors.values()):
                next(each for each in self.channels.values() if each.kind == kind).counts["other_source"] += 1
            else:
                self.not_read += 1  # rate of turn, the error ellipse, a kind no sensor of the suite takes
            return False
        channel = self.channels[sensor.name]
        value = self._value(reading, channel)
        if value is None:
            return False
        if channel.source is None:
            self._event("source", reading.time, channel=channel.name, sensor=sensor.name, source=reading.source)
            channel.source = reading.source
        channel.source_time = reading.time
        self._new(channel, reading, value)
        return True

    def _value(self, reading: Reading, channel: _Channel) -> tuple[float, ...] | None:
        """A reading's value in the observer's units (local north/east m, heading rad in
        [-pi, pi), an IMU's m/s2 and rad/s, a rate of turn's rad/s), None when it is not used (counted)."""
        if reading.kind == "ground_velocity":  # m/s, and the course wrapped as a simulated one's (NaN: none)
            speed, course = reading.values
            return (float(speed), _wrapped(math.radians(course)))
        if reading.kind == "water_speed":  # VHW's speed along the keel: the speed log's surge (its sway not measured)
            return (float(reading.values[0]), math.nan)
        if reading.kind == "rate_of_turn":  # ROT's degrees per minute, range-checked as an IMU's yaw rate
            rate = math.radians(float(reading.values[0]) / 60.0)
            if not abs(rate) <= IMU_LIMITS[1]:
                channel.counts["range"] += 1
                return None
            return (rate,)
        if reading.kind == "imu":
            fx, fy, rate = reading.values
            value = (float(fx), float(fy), math.radians(rate))
            if not (abs(value[0]) <= IMU_LIMITS[0] and abs(value[1]) <= IMU_LIMITS[0] and abs(value[2]) <= IMU_LIMITS[1]):
                channel.counts["range"] += 1
                return None
            return value
        if reading.kind == "position":
            latitude, longitude = reading.values[:2]
            refusal = fix_refusal(reading.values, self.gates)
            if refusal is not None:
                channel.counts[refusal] += 1
                return None
            if not self._origin_checked:
                assert self.frame is not None  # only a given origin is left to check
                check_origin(self.frame, latitude, longitude)
                self._origin_checked = True
            if self.frame is None:
                self.frame = LocalFrame(latitude, longitude)
                self._event("frame", reading.time, latitude=latitude, longitude=longitude)
            north, east, _ = self.frame.ned(latitude, longitude)
            return (float(north), float(east))
        if reading.kind == "local_position":
            return (float(reading.values[0]), float(reading.values[1]))
        return (_wrapped(math.radians(reading.values[0])),)

    def _sensor_take(self, sensor: LiveSensor, channel: _Channel, reading: Reading, value: tuple) -> bool:
        """Keep a named sensor's reading: its own held sample, and its channel's mark that a reading came."""
        if sensor.value is None:
            self._event("source", reading.time, channel=channel.name, sensor=sensor.name, source=reading.source)
        if sensor.fresh:
            sensor.counts["superseded"] += 1
            channel.counts["superseded"] += 1  # the step takes the newest reading of its sensor
        sensor.value, sensor.time, sensor.fresh = value, reading.time, True
        sensor.counts["accepted"] += 1
        channel.counts["accepted"] += 1
        channel.new, channel.new_time = value, reading.time  # the first step and step_on wait for it
        return True

    # ----------------------------------------------------------------- stepping
    def time_of(self, n: int) -> float:
        """The stream-clock time of step ``n``."""
        return n * self.sample_period

    @property
    def next_step_time(self) -> float | None:
        """When the next step is due (None before the first reading of every channel)."""
        return None if self.step_index is None else self.time_of(self.step_index)

    def _event(self, kind: str, t: float, **details) -> None:
        event = {"event": kind, "time": t, **details}
        if self.start_index is not None:
            event["session_time"] = t - self.time_of(self.start_index)
        self.event_counts[kind] = self.event_counts.get(kind, 0) + 1
        self.events.append(event)
        if len(self.events) > 1000:  # the latest; the counts keep the totals
            del self.events[:500]
        if self.on_event is not None:
            self.on_event(event)

    def _start(self) -> None:
        """Set the first step: the one that has a reading of every channel."""
        if self.step_index is None and self._every_kind_read():
            first = max(channel.new_time for channel in self.channels.values() if channel.new is not None)
            self.step_index = self.start_index = math.ceil(first / self.sample_period - 1e-9)

    def _every_kind_read(self) -> bool:
        """Whether a reading of every kind the steps need (position, heading, IMU) came;
        a speed over ground or through the water is not waited for."""
        needed = {channel.kind for channel in self.channels.values() if channel.kind in ("position", "heading", "imu")}
        return needed <= {channel.kind for channel in self.channels.values() if channel.new is not None}

    def advance(self, until: float) -> list[Block]:
        """Take every step with ``t_n < until`` (a reading stamped ``until`` is not in
        them); return the blocks computed (a fast replay computes ``batch`` at a time)."""
        self._start()
        if self.step_index is None:
            return []
        return self._take_steps(lambda: self.time_of(self.step_index) < until)

    def _take_steps(self, more) -> list[Block]:
        """Steps from ``step_index`` on while ``more()``."""
        blocks = []
        assert self.step_index is not None  # set by _start before any step is taken
        while more():
            self._row(self.step_index)
            self.step_index += 1
            if self._kept == self.batch:
                blocks.append(self._run())
        return blocks

    def warm_up(self) -> None:
        """Compile the step before data comes (on a stand-in measurement), so that the
        first steps of a live session are not late by a compilation."""
        raw = np.zeros(self._raw.shape[1])
        self.stepper = Stepper(self.gated_observer, self.guess, raw)
        self.stepper(0.0, raw, np.zeros_like(self._input), self.sample_period)  # the first real step resets it

    def finish(self) -> list[Block]:
        """Run the steps kept for a batch."""
        return [self._run()] if self._kept else []

    def _row(self, n: int) -> None:
        """Keep step n: each channel's new reading and its arrival (session s), NaN
        where none came."""
        i = self._kept
        assert self.start_index is not None  # set by _start before any step is taken
        start = self.time_of(self.start_index)
        self._times[i] = self.time_of(n)
        self._session_times[i] = (n - self.start_index) * self.sample_period
        raw = self._raw[i]
        raw[:] = math.nan
        if self.sensors and not self.direct:
            self._sensor_row(raw, self._times[i], start)
            for channel in self.channels.values():
                channel.new = None
            self._inputs[i] = self._input
            self._kept += 1
            return
        for channel in self.channels.values():
            if channel.new is not None:
                raw[channel.columns] = channel.new
                raw[[self._size + index for index in channel.arrivals]] = channel.new_time - start
                channel.new = None
        self._inputs[i] = self._input
        self._kept += 1

    def _sensor_row(self, raw: np.ndarray, t: float, start: float) -> None:
        """The named sensors' part of a step's row: each one's held sample (NaN when none
        is held or it is older than its timeout), then each new one's arrival (session s)."""
        total = self._raw.shape[1] - len(self.suite.names) if self.suite is not None else 0
        for sensor in self.sensors.values():
            held = sensor.held(t)
            if held is not None:
                raw[sensor.columns] = held
            if sensor.fresh:
                raw[total + sensor.index] = sensor.time - start
                sensor.fresh = False

    def _run(self) -> Block:
        n = self._kept
        self._kept = 0
        times, session_times = self._times[:n].copy(), self._session_times[:n].copy()
        raw, inputs = self._raw[:n].copy(), self._inputs[:n].copy()
        started = _time.perf_counter()
        if not self._started:
            if not self.thrust_seen and self._input.size:
                warnings.warn("lookout live: no thrust feedback; the observer predicts with zero input", RuntimeWarning, stacklevel=4)
            if self.stepper is None:
                self.stepper = Stepper(self.gated_observer, self.guess, raw[0])
            else:
                self.stepper.reset(raw[0], self.guess)
            self._started = True
        assert self.stepper is not None  # made on the first run (or by warm_up)
        if n == 1:
            try:
                estimates = {
                    name: np.asarray(value)[None] for name, value in self.stepper(session_times[0], raw[0], inputs[0], self.sample_period).items()
                }
                healthy = np.ones(1, dtype=bool)
            except ValueError as error:
                estimates, healthy = None, np.zeros(1, dtype=bool)
                self._event("refused", times[0], reason=str(error))
        else:
            estimates, healthy = self.stepper.run(session_times, raw, inputs, self.sample_period)
        seconds = (_time.perf_counter() - started) / n
        if estimates is None:  # one refused step: the state is as it was
            estimates = {name: np.full((1, *np.shape(value)), np.nan) for name, value in self.stepper.template().items()}
        measurement = np.array(estimates.pop("measurement_used"), dtype=float)
        filled = np.zeros(self._size, dtype=bool)
        for channel in self.channels.values():
            filled[channel.columns] = True
            measurement[np.asarray(estimates[f"outage_{channel.flag}"]) > 0, channel.columns] = np.nan
            if self.direct:  # a reading is used at the step it came, unless it was a wild point
                unused = ~np.isfinite(raw[:, self._size + channel.arrivals[0]]) | (np.asarray(estimates[f"gated_{channel.flag}"]) > 0)
                measurement[unused, channel.columns] = np.nan
        measurement[:, ~filled] = np.nan
        if self.sensors and not self.direct:
            measurement = self._recorded(raw, measurement)
        refused = ~healthy
        if refused.any():
            self.refused += int(refused.sum())
            if n > 1:
                for i in np.flatnonzero(refused)[:10]:
                    self._event("refused", times[i], reason="the step is not finite; the state is kept")
        self._events(times[healthy], {name: np.asarray(value)[healthy] for name, value in estimates.items()})
        self.steps += n
        return Block(times, session_times, estimates, measurement, inputs, np.full(n, seconds))

    def _recorded(self, raw: np.ndarray, used: np.ndarray) -> np.ndarray:
        """A block's measurement in :attr:`record_layout`: the sensors' held samples of
        its rows, then the combined channels the steps used (NaN where the observer does
        not read one)."""
        layout = self._record_layout
        recorded = np.full((raw.shape[0], layout.size), np.nan)
        total = layout.size - sum(signal.size for signal in self.suite.combined_signals) if self.suite is not None else 0
        recorded[:, :total] = raw[:, :total]
        start = 0
        spans = {}
        for signal in layout.signals:
            spans[signal.name] = slice(start, start + signal.size)
            start += signal.size
        for channel in self.channels.values():
            recorded[:, spans[channel.name]] = used[:, channel.columns]
        return recorded

    def _events(self, times: np.ndarray, estimates: dict) -> None:
        """Count gated points and report outages from the steps' flags."""
        if len(times) == 0:  # every step refused
            return
        for channel in self.channels.values():
            short = channel.flag
            if len(times) == 1:  # a live step: the same on Python numbers (a tenth of the time)
                if estimates[f"gated_{short}"][0] > 0:
                    channel.counts["gated"] += 1
                    self._event("gated", float(times[0]), channel=channel.name, source=channel.source)
                lost = bool(estimates[f"outage_{short}"][0] > 0)
                if lost != channel.in_outage:
                    if lost:
                        channel.outage_since = float(times[0])
                        self._event("outage", float(times[0]), channel=channel.name)
                    else:
                        self._event("recovered", float(times[0]), channel=channel.name, outage=float(times[0]) - channel.outage_since)
                    channel.in_outage = lost
                continue
            gated = np.asarray(estimates[f"gated_{short}"]) > 0
            channel.counts["gated"] += int(gated.sum())
            for i in np.flatnonzero(gated):
                self._event("gated", times[i], channel=channel.name, source=channel.source)
            outage = np.asarray(estimates[f"outage_{short}"]) > 0
            previous = np.concatenate([[channel.in_outage], outage[:-1]])
            for i in np.flatnonzero(outage != previous):
                if outage[i]:
                    channel.outage_since = times[i]
                    self._event("outage", times[i], channel=channel.name)
                else:
                    self._event("recovered", times[i], channel=channel.name, outage=float(times[i] - channel.outage_since))
            channel.in_outage = bool(outage[-1])
