"""A vessel's sensors as one :class:`~lookout.components.KinematicSensor`: named
instruments, their failures, and the stage that combines the references.

The measurement lays out, in order: each instrument's channels, named
``NAME.signal`` (``dgnss1.measured_position``); each failure's flag
(``NAME.MODE_failure``, 1 while it acts: the truth of the injected failure); and the
combining stage's channels (``measured_position`` and ``measured_heading``, what the
observers of the papers read). An observer reads the signals it names, found by
name; a Kalman filter may read every instrument's channels.

At a sample where an instrument is due, the suite takes ``value + white`` of it
(:meth:`~lookout.sensing.instrument.Instrument.emit`), applies its failures in
order, wraps its angles, and holds the result until its next sample. The combined
position is taken when a position reference has a new sample, the combined heading when
a gyrocompass has one (so a held fix is not taken again at the gyros' rate), from the
instruments in the order of their names (so that the order of the record changes none
of their bits). A stage with tests (``dp-class``) steps its memory at each sample,
with each instrument's sample and whether it is new, and adds its own channels after
the combined position and heading (each reference's state, weight and test
statistics), taken and held as the combined channel of the references they concern.

Noise. Instrument ``NAME`` draws its normals (its own and its failures') from a
stream of its own, numbered from the name (:func:`noise_stream`): adding, removing
or reordering instruments never changes another's draws.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping, Sequence
from typing import Any, final

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa
from lookout.components import KinematicSensor, Layout, Signal
from lookout.sensing.combining import COMBINED_HEADING, CombiningStage
from lookout.sensing.failures import Failure, flag_signal
from lookout.sensing.instrument import Instrument

#: Streams below this are the engine's own (process, sensor and reference noise).
FIRST_STREAM = 16


def noise_stream(name: str) -> int:
    """The noise stream of the instrument named ``name``: a hash of the name, in
    ``[FIRST_STREAM, 2**16)``."""
    return FIRST_STREAM + zlib.crc32(name.encode()) % (2**16 - FIRST_STREAM)


@final
class SensorSuite(KinematicSensor):
    """Named instruments with their failures, and a combining stage.

    Parameters
    ----------
    instruments : dict of str to Instrument
        The instruments by name (an identifier: ``dgnss1``), in the order of the record.
    failures : dict of str to sequence of Failure, optional
        Each instrument's failures, in the order they act.
    combining : CombiningStage or None
        The stage that gives ``measured_position`` and ``measured_heading`` (a
        :class:`~lookout.sensing.combining.WeightedMean`, a
        :class:`~lookout.sensing.handling.ReferenceHandler`); None gives the
        instruments' channels only.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    instruments: tuple[Instrument, ...]
    failures: tuple[tuple[Failure, ...], ...]
    combining: CombiningStage | None
    measurement_layout: Layout = eqx.field(static=True)
    sample_period: tuple[float, ...] = eqx.field(static=True)
    noise_size: int = eqx.field(static=True)
    noise_streams: tuple[tuple[int, int], ...] = eqx.field(static=True)

    def __init__(
        self,
        instruments: dict[str, Instrument],
        failures: Mapping[str, Sequence[Failure]] | None = None,
        combining: CombiningStage | None = None,
    ):
        if not isinstance(instruments, dict) or not instruments:
            raise check.ParameterError("instruments", "instruments must be a non-empty dict of name -> Instrument")
        failures = dict(failures or {})
        streams: dict[int, str] = {}
        for name, each in instruments.items():
            if not (isinstance(name, str) and name.isidentifier()):
                raise check.ParameterError("instruments", f"instruments: a sensor's name must be an identifier (letters, digits, _); got {name!r}")
            if not isinstance(each, Instrument):
                raise check.ParameterError(("instruments", name), f"instruments[{name!r}] must be an Instrument; got {type(each).__name__}")
            stream = noise_stream(name)
            if stream in streams:
                raise check.ParameterError(("instruments", name), f"sensors {streams[stream]!r} and {name!r} hash to one noise stream: rename one")
            streams[stream] = name
        for name, listed in failures.items():
            if name not in instruments:
                raise check.ParameterError(("failures", name), f"failures: no sensor named {name!r} (sensors: {', '.join(instruments)})")
            for failure in listed:
                if not isinstance(failure, Failure) or len(failure.channels) != instruments[name].size:
                    raise check.ParameterError(
                        ("failures", name), f"failures[{name!r}]: each must be a Failure of the sensor's {instruments[name].size} channels"
                    )
        self.names = tuple(instruments)
        self.instruments = tuple(instruments.values())
        self.failures = tuple(tuple(failures.get(name, ())) for name in self.names)
        self.combining = combining
        signals: list[Signal] = []
        periods: list[float] = []
        for name, each in zip(self.names, self.instruments):
            signals += [s.renamed(f"{name}.{s.name}", f"{name}: {s.long_name}") for s in each.signals]
            periods += [each.sample_period] * each.size
        for name, each, listed in zip(self.names, self.instruments, self.failures):
            modes = [failure.mode for failure in listed]
            signals += [flag_signal(name, failure.mode, index, modes) for index, failure in enumerate(listed)]
            periods += [each.sample_period] * len(listed)
        for signal, source in zip(self.combined_signals, self._combined_sources()):
            signals.append(signal)
            periods += [self._combined_period(source)] * signal.size
        self.measurement_layout = Layout(tuple(signals))
        self.sample_period = tuple(periods)
        counts = [each.noise_count + sum(f.noise_count for f in listed) for each, listed in zip(self.instruments, self.failures)]
        self.noise_streams = tuple((noise_stream(name), count) for name, count in zip(self.names, counts))
        self.noise_size = sum(counts)

    @property
    def _order(self) -> list[int]:
        """The instruments in the order of their names: the order the stage sees them in
        (the file's order of the tables, which a campaign's spec, sorted, does not keep,
        then changes no bit of the combined channels)."""
        return sorted(range(len(self.names)), key=self.names.__getitem__)

    def _contributors(self, source: str) -> list[int]:
        """The instruments a combined channel of ``source`` is taken from: the position
        references (``"position"``) or the gyrocompasses (``"heading"``)."""
        return [i for i, each in enumerate(self.instruments) if each.provides == source]

    def _combined_period(self, source: str) -> float:
        return min(self.instruments[i].sample_period for i in self._contributors(source))

    def _combined_sources(self) -> tuple[str, ...]:
        if self.combining is None:
            return ()
        order = self._order
        return self.combining.sources([self.instruments[i] for i in order], [self.names[i] for i in order])

    @property
    def combined_signals(self) -> tuple[Signal, ...]:
        """The combining stage's channels (the last of the measurement)."""
        if self.combining is None:
            return ()
        order = self._order
        return self.combining.signals([self.instruments[i] for i in order], [self.names[i] for i in order])

    @property
    def instrument_layout(self) -> Layout:
        """The instruments' channels alone (what a Kalman filter on the suite reads), in order."""
        size = sum(each.size for each in self.instruments)
        signals, count = [], 0
        for signal in self.measurement_layout.signals:
            if count >= size:
                break
            signals.append(signal)
            count += signal.size
        return Layout(tuple(signals))

    def initial_memory(self, kinematics: dict[str, Array]) -> Any:
        """``(each instrument's memory and its failures', the combining stage's)``."""
        instruments = tuple(
            (each.initial_memory(kinematics), tuple(failure.initial_memory(each.size) for failure in listed))
            for each, listed in zip(self.instruments, self.failures)
        )
        stage = self.combining.initial_memory([self.instruments[i] for i in self._order]) if self.combining is not None else ()
        return instruments, stage

    def read(self, memory: Any, t: ArrayLike, kinematics: dict[str, Array], normals: Array, due: Array, held: Array) -> tuple[Any, Array]:
        instrument_memory, stage_memory = memory
        channel, noise, memories = 0, 0, []
        samples, flags, flags_due = [], [], []
        for each, listed, (own, failure_memories) in zip(self.instruments, self.failures, instrument_memory):
            n = each.size
            now = due[channel]  # an instrument's channels share its period
            drawn = normals[noise : noise + each.noise_count]
            noise += each.noise_count
            own_next, value, white = each.emit(own, kinematics, drawn)
            own = jax.tree.map(lambda new, old: jnp.where(now, new, old), own_next, own)
            y = value + white
            before = held[channel : channel + n]
            next_memories, sample_flags = [], []
            for failure, failure_memory in zip(listed, failure_memories):
                drawn = normals[noise : noise + failure.noise_count]
                noise += failure.noise_count
                failure_memory, y, flag = failure.apply(failure_memory, t, y, white, before, drawn, now)
                next_memories.append(failure_memory)
                sample_flags.append(flag)
            angles = jnp.asarray(each.angles())
            y = jnp.where(angles, ssa(y), y)
            samples.append(jnp.where(now, y, before))
            flags.append(jnp.stack(sample_flags) if sample_flags else jnp.zeros(0))
            flags_due.append(jnp.full(len(sample_flags), now))
            memories.append((own, tuple(next_memories)))
            channel += n
        flag_count = sum(len(listed) for listed in self.failures)
        flag_values = (
            jnp.where(jnp.concatenate(flags_due), jnp.concatenate(flags), held[channel : channel + flag_count]) if flag_count else jnp.zeros(0)
        )
        channel += flag_count
        pieces = samples + [flag_values]
        combined_signals = self.combined_signals
        combined_size = sum(s.size for s in combined_signals)
        if combined_size:
            combining = self.combining
            assert combining is not None  # combined_signals is empty without a stage
            before = held[channel : channel + combined_size]
            heading_at = _offset(combined_signals, COMBINED_HEADING.name)
            held_heading = before[heading_at] if heading_at is not None else jnp.asarray(jnp.nan)
            order = self._order
            first = [sum(each.size for each in self.instruments[:i]) for i in range(len(self.instruments))]
            fresh = jnp.stack([due[first[i]] for i in order])  # an instrument's channels share its period
            stage_memory, combined = combining.step(
                stage_memory, [self.instruments[i] for i in order], [samples[i] for i in order], fresh, held_heading, t
            )
            # a combined channel is new when one of the instruments it is taken from is
            now = jnp.concatenate(
                [
                    jnp.full(signal.size, jnp.any(jnp.stack([due[first[i]] for i in self._contributors(source)])))
                    for signal, source in zip(combined_signals, self._combined_sources())
                ]
            )
            pieces.append(jnp.where(now, combined, before))
        return (tuple(memories), stage_memory), jnp.concatenate(pieces)

    def expected(self, kinematics: dict[str, Array]) -> Array:
        """The instruments' noise-free, fault-free channels (:attr:`instrument_layout`)."""
        parts = [each.expected(kinematics) for each in self.instruments]
        angles = jnp.asarray([a for each in self.instruments for a in each.angles()])
        y = jnp.concatenate(parts)
        return jnp.where(angles, ssa(y), y)

    def noise_std(self) -> Array:
        """The instruments' white noise per channel (:attr:`instrument_layout`)."""
        return jnp.concatenate([each.noise_std() for each in self.instruments])


def _offset(signals: Sequence[Signal], name: str) -> int | None:
    """Where the signal ``name`` starts in ``signals`` laid end to end (None: absent)."""
    start = 0
    for signal in signals:
        if signal.name == name:
            return start
        start += signal.size
    return None


__all__ = ["SensorSuite", "noise_stream"]
