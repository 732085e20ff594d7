"""Named sensors live: a scenario's ``[sensors.NAME]`` fed by the readings of their
sources, and the suite's combining stage between them and the observer.

A scenario with a :class:`~lookout.sensing.suite.SensorSuite` names its instruments.
Each instrument a stream can feed, a position reference that a GGA, GLL or RMC fix
measures (``gnss``, ``hydroacoustic``) or a ``gyrocompass`` that an HDT or THS heading
measures, takes the readings of the source its ``source`` key names
(:func:`lookout.io.nmea.source_spec`: a talker, a sender or both). A reading goes to
the sensor of its kind whose source matches it most closely
(:func:`lookout.io.nmea.source_rank`); one no sensor's source matches, or that two
match equally, is ``other_source``.

Each sensor holds its last reading, as a simulated instrument holds its sample, until
it is older than its channel's timeout (``position_timeout``, ``heading_timeout``);
then it is NaN, a dropout. At each step :class:`CombiningObserver` hands the held
samples to the suite's combining stage, the very
:meth:`~lookout.sensing.combining.CombiningStage.step` a simulation runs (its memory
carried from step to step, a sensor's reading new at the step it came), and the
observer reads its output (``measured_position``, ``measured_heading``) through the
hold, timeout and gate of :class:`~lookout.live.gate.GatedObserver`, as it reads a
single receiver's. The combined position is a new reading at a step where a position
reference gave one, the combined heading where a gyrocompass did; the lever arms are
taken back with the combined heading of the step before when no gyrocompass is held,
as the suite's ``read`` takes them back with its held one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import equinox as eqx
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from lookout.components import Layout, Observer, Signal
from lookout.io.nmea import source_rank, source_spec, talker_family
from lookout.live.gate import GatedObserver, GatedState
from lookout.live.options import Gates
from lookout.sensing.combining import CombiningStage
from lookout.sensing.heading import Gyrocompass
from lookout.sensing.instrument import HEADING, POSITION
from lookout.sensing.motion import GnssVelocity, InertialUnit, SpeedLog
from lookout.sensing.position import GnssReceiver, HydroacousticReference
from lookout.sensing.rate_gyro import RateGyro

if TYPE_CHECKING:
    from lookout.sensing.suite import SensorSuite

#: The instrument kinds a stream feeds, and the reading kind each takes.
FED = {GnssReceiver: "position", HydroacousticReference: "position", Gyrocompass: "heading"}
#: Those a stream feeds too when the observer reads each instrument itself (a Kalman
#: filter on the suite): what the combining stage does not combine.
DIRECT_FED = {GnssVelocity: "ground_velocity", SpeedLog: "water_speed", RateGyro: "rate_of_turn"}
#: What each reading kind is read from, in words.
READS = {
    "position": "position fixes (GGA, GLL, RMC)",
    "heading": "headings (HDT, THS)",
    "ground_velocity": "speed and course over ground (RMC, VTG)",
    "water_speed": "speed through the water (VHW)",
    "rate_of_turn": "rates of turn (ROT)",
}
#: The talker family (:data:`lookout.io.nmea.TALKER_FAMILIES`) of each reading kind
#: that has one.
FAMILIES = {"position": "GNSS", "heading": "heading", "ground_velocity": "GNSS", "rate_of_turn": "heading"}
#: The combined channel a sensor's readings make new, by what the instrument provides.
COMBINED = {POSITION: "measured_position", HEADING: "measured_heading"}


@dataclass
class LiveSensor:
    """What a session knows of one named sensor.

    Attributes
    ----------
    name : str
    index : int
        Its place among the suite's instruments.
    kind : {"position", "heading", "imu", "ground_velocity", "water_speed", "rate_of_turn"}
        The readings it takes (the last four only for an observer that reads each
        instrument itself).
    source : str
        Its ``source`` key; ``talker`` and ``sender`` as :func:`~lookout.io.nmea.source_spec` reads it.
    columns : slice
        Its channels in the suite's instrument layout.
    timeout : float
        Seconds after which its last reading is not used.
    """

    name: str
    index: int
    kind: str
    source: str
    talker: str
    sender: str | None
    columns: slice
    timeout: float
    value: tuple | None = None  # its last reading
    time: float = math.nan  # when it came
    fresh: bool = False  # whether it came since the last step
    counts: dict = field(default_factory=lambda: {"accepted": 0, "superseded": 0})

    def held(self, t: float) -> tuple | None:
        """Its last reading at stream time ``t``; None when there is none or it is older than the timeout."""
        return self.value if self.value is not None and t - self.time <= self.timeout else None


def live_sensors(suite: SensorSuite, gates: Gates, direct: bool = False) -> tuple[dict[str, LiveSensor], tuple[str, ...]]:
    """``(sensors, silent)``: the suite's sensors that a stream feeds, by name (those of
    a kind in :data:`FED` with a ``source``), and the names of those of such a kind that
    name no source (never fed: a warning). With ``direct`` (an observer that reads each
    instrument), also those of :data:`DIRECT_FED` (their readings timing out after
    ``position_timeout``, a rate of turn's after ``heading_timeout``) and the suite's IMU (kind ``imu``, fed by the IMU stream: a
    CSV log or a UDP source of ``time,fx,fy,r``; after ``heading_timeout``).

    Raises
    ------
    ValueError
        ``sensors.NAME.source: ...`` for a source of the other kind's talkers (a
        gyro's talker on a receiver) or one that two sensors of a kind share; one line
        when no sensor names a source.
    """
    sensors: dict[str, LiveSensor] = {}
    silent = []
    start = 0
    units = [name for name, each in zip(suite.names, suite.instruments) if isinstance(each, InertialUnit)]
    if direct and len(units) > 1:
        raise ValueError(f"sensors.{units[1]}: one IMU stream feeds one IMU; the suite has {len(units)} ({', '.join(units)})")
    for index, (name, each) in enumerate(zip(suite.names, suite.instruments)):
        columns = slice(start, start + each.size)
        start += each.size
        if direct and isinstance(each, InertialUnit):
            sensors[name] = LiveSensor(name, index, "imu", "imu", "", None, columns, gates.heading_timeout)
            continue
        kind = FED.get(type(each)) or (DIRECT_FED.get(type(each)) if direct else None)
        if kind is None:
            continue
        source = getattr(each, "source", None)
        if source is None:
            silent.append(name)
            continue
        talker, sender = source_spec(source)
        family = talker_family(talker)
        if family is not None and family != FAMILIES.get(kind, family):
            raise ValueError(f"sensors.{name}.source: {source!r} is a {family} talker; sensor {name} takes {READS[kind]}")
        for other in sensors.values():
            if other.kind == kind and (other.talker, other.sender) == (talker, sender):
                raise ValueError(f"sensors.{name}.source: {source!r} is sensor {other.name}'s source too; two sensors of a kind need two sources")
        timeout = gates.heading_timeout if kind in ("heading", "rate_of_turn") else gates.position_timeout
        sensors[name] = LiveSensor(name, index, kind, source, talker, sender, columns, timeout)
    if not any(sensor.kind != "imu" for sensor in sensors.values()):
        raise ValueError(
            "no sensor names a source: live data feeds a [sensors.NAME] of kind gnss, hydroacoustic or gyrocompass "
            'that gives one (source = "GP", "@10.0.0.5" or "GP@10.0.0.5")'
        )
    return sensors, tuple(silent)


def route(sensors: Mapping[str, LiveSensor], source: str, kind: str) -> LiveSensor | None:
    """The sensor that takes a reading of ``kind`` from ``source``: the one of that kind
    whose source matches it most closely (:func:`~lookout.io.nmea.source_rank`); None
    when none matches, or two match equally. A reading of an IMU goes to the IMU
    (:func:`live_sensors` takes one)."""
    if kind == "imu":
        return next((sensor for sensor in sensors.values() if sensor.kind == "imu"), None)
    best, ranks = None, []
    for sensor in sensors.values():
        if sensor.kind != kind:
            continue
        rank = source_rank(source, sensor.talker, sensor.sender)
        if rank is not None:
            ranks.append(rank)
            if best is None or rank > best[0]:
                best = (rank, sensor)
    if best is None or ranks.count(best[0]) > 1:
        return None
    return best[1]


class CombiningState(eqx.Module):
    """The gated observer's state, the combined heading of the step before and the
    combining stage's memory."""

    inner: GatedState
    heading: Array  # 0 where it was NaN
    no_heading: Array  # 1 where it was NaN
    stage: Any = ()


class CombiningObserver(Observer):
    """A :class:`~lookout.live.gate.GatedObserver` fed by a suite's combining stage.

    Its measurement is each instrument's held sample (the suite's instrument layout,
    NaN where none is held) and each instrument's arrival (session s; NaN when no new
    reading came since the step before). Each step combines the samples with the
    suite's :meth:`~lookout.sensing.combining.CombiningStage.step` (the instruments in
    the order of their names, as a simulation's suite hands them) and hands the
    combined channels to the gated observer as new readings (module docstring).

    Parameters
    ----------
    gated : GatedObserver
        The scenario's observer, gated on the combined channels it reads.
    suite : SensorSuite
        The scenario's sensors; its combining stage gives what ``gated`` reads.
    """

    gated: GatedObserver
    instruments: tuple
    combining: CombiningStage
    names: tuple[str, ...] = eqx.field(static=True)
    sizes: tuple[int, ...] = eqx.field(static=True)
    provides: tuple[str, ...] = eqx.field(static=True)
    instrument_signals: tuple[Signal, ...] = eqx.field(static=True)
    # per channel the gated observer reads: its columns in the gated observer's
    # measurement, its columns in the combined vector, and what makes it new
    targets: tuple[tuple[tuple[int, int], tuple[int, int], str], ...] = eqx.field(static=True)
    heading_column: int = eqx.field(static=True)
    order: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, gated: GatedObserver, suite: SensorSuite):
        if suite.combining is None:
            raise ValueError("the suite has no combining stage ([references])")
        self.gated = gated
        self.instruments = suite.instruments
        self.combining = suite.combining
        self.names = suite.names
        self.sizes = tuple(each.size for each in suite.instruments)
        self.provides = tuple(each.provides for each in suite.instruments)
        self.instrument_signals = suite.instrument_layout.signals
        self.order = tuple(sorted(range(len(suite.names)), key=suite.names.__getitem__))
        combined, start = {}, 0
        for signal in suite.combined_signals:
            combined[signal.name] = (start, start + signal.size)
            start += signal.size
        if "measured_heading" not in combined:
            raise ValueError("the suite's combining stage gives no measured_heading (it needs a gyrocompass)")
        self.heading_column = combined["measured_heading"][0]
        inner_columns = dict(zip(gated.channels, gated._columns))
        targets = []
        for name in gated.channels:
            if name not in combined:
                raise ValueError(f"the suite's combining stage gives no {name} (it gives {', '.join(combined) or 'nothing'})")
            kind = POSITION if name == "measured_position" else HEADING
            targets.append((inner_columns[name], combined[name], kind))
        self.targets = tuple(targets)

    # -- what it reads and gives
    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def measurement_layout(self) -> Layout:  # type: ignore[override]  # (read-only, as every observer's)
        arrivals = tuple(Signal(f"arrival_{name}", "s", f"arrival of sensor {name}'s new reading (NaN: none)") for name in self.names)
        return Layout(self.instrument_signals + arrivals)

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def input_layout(self) -> Layout:  # type: ignore[override]  # (read-only, as every observer's)
        return self.gated.input_layout

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def sample_period(self) -> float | None:  # type: ignore[override]  # (read-only, as every observer's)
        return self.gated.sample_period

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def estimate_signals(self) -> tuple[Signal, ...]:  # type: ignore[override]  # (read-only, as every observer's)
        return self.gated.estimate_signals

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def extra_signals(self) -> tuple[Signal, ...]:  # type: ignore[override]  # (read-only, as every observer's)
        return self.gated.extra_signals

    def guess(self) -> Any:
        return self.gated.guess()

    # -- the combining stage
    def _combined(self, heading: Array, no_heading: Array, stage: Any, y: Array, t: ArrayLike) -> tuple[Array, Array, Any]:
        """``(the gated observer's measurement, the combined heading, the stage's memory)``
        of a step's ``y`` at ``t``."""
        total = sum(self.sizes)
        flat, arrivals = y[:total], y[total:]
        samples, start = [], 0
        for size in self.sizes:
            samples.append(flat[start : start + size])
            start += size
        held = jnp.where(no_heading > 0, jnp.nan, heading)
        fresh = jnp.stack([jnp.isfinite(arrivals[i]) for i in self.order])
        stage, combined = self.combining.step(stage, [self.instruments[i] for i in self.order], [samples[i] for i in self.order], fresh, held, t)
        inner = jnp.full(self.gated.inner.measurement_layout.size, jnp.nan)
        arrived = []
        for (inner_start, inner_stop), (start, stop), kind in self.targets:
            value = combined[start:stop]
            mine = jnp.asarray([provides == kind for provides in self.provides])
            latest = jnp.max(jnp.where(mine & jnp.isfinite(arrivals), arrivals, -jnp.inf))
            new = jnp.isfinite(latest) & jnp.all(jnp.isfinite(value))
            inner = inner.at[inner_start:inner_stop].set(value)
            arrived.append(jnp.where(new, latest, jnp.nan))
        return jnp.concatenate([inner, jnp.stack(arrived)]), combined[self.heading_column], stage

    def _state(self, inner: GatedState, heading: Array, stage: Any) -> CombiningState:
        missing = ~jnp.isfinite(heading)
        return CombiningState(inner, jnp.where(missing, 0.0, heading), missing.astype(heading.dtype), stage)

    def init(self, y0: Array, guess: Any) -> CombiningState:
        y0 = jnp.asarray(y0)
        # the first step's time: its latest arrival (session s), 0 when none came
        arrivals = y0[sum(self.sizes) :]
        latest = jnp.max(jnp.where(jnp.isfinite(arrivals), arrivals, -jnp.inf))
        t0 = jnp.where(jnp.isfinite(latest), latest, 0.0)
        stage = self.combining.initial_memory([self.instruments[i] for i in self.order])
        measurement, heading, stage = self._combined(jnp.zeros(()), jnp.ones(()), stage, y0, t0)
        return self._state(self.gated.init(measurement, guess), heading, stage)

    def update(self, state: CombiningState, t: ArrayLike, y: Array) -> CombiningState:
        measurement, heading, stage = self._combined(state.heading, state.no_heading, state.stage, y, t)
        return self._state(self.gated.update(state.inner, t, measurement), heading, stage)

    def output(self, state: CombiningState, y: Array) -> dict[str, Array]:
        return self.gated.output(state.inner, state.inner.measurement)

    def predict(self, state: CombiningState, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> CombiningState:
        inner = self.gated.predict(state.inner, t, state.inner.measurement, u, dt)
        return eqx.tree_at(lambda s: s.inner, state, inner)


def record_layout(suite: SensorSuite) -> Layout:
    """What a session with ``suite`` records as its measurement: each instrument's
    channels (``dgnss1.measured_position``), then the combining stage's, as a
    simulation's record names them (its failures' flags aside: live data has none)."""
    return Layout(suite.instrument_layout.signals + suite.combined_signals)


__all__ = ["CombiningObserver", "CombiningState", "LiveSensor", "live_sensors", "record_layout", "route"]
