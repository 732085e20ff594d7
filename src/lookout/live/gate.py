"""The live-data rules as an observer: hold, timeout and the wild-point gate.

:class:`GatedObserver` wraps any observer whose measurement holds the channels a
stream fills (``measured_position``, ``measured_heading``, or a suite's instruments'
``dgnss1.measured_position``, ...). Its own measurement is
what a stream gives at one step: each channel's *new* reading (NaN when none came
since the last step) and the time it arrived (session seconds). Inside it:

- a channel holds its last accepted reading, as a simulated sensor holds its sample
  (:mod:`lookout.sensors`), until the reading is older than the channel's timeout;
  then the channel is NaN, a dropout the observer predicts through (dead reckoning);
  an entry of no channel (a sensor the stream does not feed) is taken as it came, NaN
  when nothing came;
- a new reading that fails the channel's test is a wild point: the step uses the held
  reading instead and the wild one is dropped; after ``reopen_after`` wild points in
  a row the next one passes, so an estimate that drifted during an outage takes the
  position back. The test is one of (:func:`gate_tests` picks it per channel):

  - ``"nis"`` for an observer that gives its innovation's covariance (a Kalman
    filter's :meth:`~lookout.observers.kalman.KalmanFilter.innovation_statistics`):
    the validation gate of a Kalman filter, the normalized innovation squared
    nu^T S^-1 nu of the channel at the prior against a bound, the chi-square quantile
    of the gate probability with the channel's size as degrees of freedom
    (Bar-Shalom, Li & Kirubarajan 2001, Estimation with Applications to Tracking and
    Navigation, Wiley; the NIS's chi-square distribution: Section 5.4);
  - ``"innovation"`` for an observer with an ``innovation_<channel>`` output
    (``y - y_hat``, taken with the reading): its length against a bound in the
    channel's units (m, rad);
  - ``"none"`` for an observer that gives neither: the channel is not gated (a
    session says so; it is never gated silently off).

Because the rules are part of the observer's step, a live session
(:class:`~lookout.Stepper`, one compiled call per step) and a fast replay (the same
step in a ``lax.scan``) apply them identically, and the Stepper's guarantees hold: a
step that is not finite leaves the state as it was.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy.typing as npt
from jax.typing import ArrayLike

from lookout.components import Layout, Observer, Signal


class GatedState(eqx.Module):
    """The wrapped observer's state and the channels' memory."""

    inner: object
    held: jnp.ndarray  # last accepted reading per measurement entry
    held_time: jnp.ndarray  # its arrival (session s) per channel
    wild_in_row: jnp.ndarray  # wild points in a row per channel
    used: jnp.ndarray  # the measurement the step used, 0 where missing (the state stays finite)
    missing: jnp.ndarray  # 1 where that measurement was NaN
    gated: jnp.ndarray  # 1 where the step's new reading was a wild point
    stale: jnp.ndarray  # per channel, 1 where no reading is newer than its timeout (an outage)

    @property
    def measurement(self) -> jax.Array:
        """The measurement the step used, NaN where missing."""
        return jnp.where(self.missing > 0, jnp.nan, self.used)


def flag_name(channel: str) -> str:
    """What a channel's flags are named after: ``position`` for ``measured_position``,
    ``dgnss1_position`` for a named sensor's ``dgnss1.measured_position``."""
    return channel.replace(".measured_", "_").removeprefix("measured_")


#: The tests a channel's new reading can be gated by (module docstring).
GATE_TESTS = ("nis", "innovation", "none")


def gate_tests(observer: Observer, channels: Sequence[str]) -> tuple[str, ...]:
    """The test each of ``channels`` is gated by for ``observer``: ``"nis"`` when it
    gives ``innovation_statistics`` (the Kalman filters), else ``"innovation"`` when it
    declares an ``innovation_<channel>`` output, else ``"none"``."""
    if callable(getattr(observer, "innovation_statistics", None)):
        return ("nis",) * len(channels)
    outputs = {signal.name for signal in observer.extra_signals}
    return tuple("innovation" if name.replace("measured_", "innovation_") in outputs else "none" for name in channels)


class GatedObserver(Observer):
    """``inner`` stepped on stream readings with hold, timeout and a wild-point gate.

    Parameters
    ----------
    inner : Observer
    channels : tuple of str
        The names (in ``inner.measurement_layout``) the stream fills.
    gate : array_like, shape (len(channels),)
        Per channel, the bound of its test: the longest innovation accepted (its units:
        m, rad) for ``"innovation"``, the largest normalized innovation squared for
        ``"nis"``; ignored for ``"none"``.
    timeout : array_like, shape (len(channels),)
        Seconds after which a channel's reading is not used.
    reopen_after : int
        Wild points in a row after which the next reading passes.
    tests : tuple of str, optional
        The test of each channel (:data:`GATE_TESTS`); default :func:`gate_tests`.
    hold : bool
        Whether a channel holds its last reading until the timeout (True: as a
        simulated sensor holds its sample, for an observer that reads its measurement at
        every step), or gives each reading once, at the step it came, and NaN between
        (False: for a Kalman filter, which takes each reading as a new measurement;
        with :meth:`~lookout.observers.kalman.KalmanFilter.due_every` every channel is
        due at every step). Either way a channel older than its timeout is an outage.
    """

    inner: Observer
    gate: jnp.ndarray
    timeout: jnp.ndarray
    channels: tuple = eqx.field(static=True)
    reopen_after: int = eqx.field(static=True)
    tests: tuple = eqx.field(static=True)
    hold: bool = eqx.field(static=True)

    def __init__(
        self,
        inner: Observer,
        channels: Iterable[str],
        gate: npt.ArrayLike,
        timeout: npt.ArrayLike,
        reopen_after: int,
        tests: Iterable[str] | None = None,
        hold: bool = True,
    ):
        self.inner = inner
        self.channels = tuple(channels)
        self.gate = jnp.asarray(gate, dtype=float)
        self.timeout = jnp.asarray(timeout, dtype=float)
        self.reopen_after = reopen_after
        self.tests = gate_tests(inner, self.channels) if tests is None else tuple(tests)
        self.hold = bool(hold)

    def __check_init__(self):
        names = self.inner.measurement_layout.names
        for name in self.channels:
            if name not in names:
                raise ValueError(f"channels: {name!r} is not in the observer's measurement ({', '.join(names)})")
        if jnp.shape(self.gate) != (len(self.channels),) or jnp.shape(self.timeout) != (len(self.channels),):
            raise ValueError(f"gate and timeout must have one entry per channel ({len(self.channels)})")
        if len(self.tests) != len(self.channels) or any(test not in GATE_TESTS for test in self.tests):
            raise ValueError(f"tests must give one of {', '.join(GATE_TESTS)} per channel ({len(self.channels)}); got {self.tests!r}")
        if "nis" in self.tests and not callable(getattr(self.inner, "innovation_statistics", None)):
            raise ValueError(f"tests: 'nis' needs an observer with innovation_statistics (a Kalman filter); {type(self.inner).__name__} has none")

    # -- what it reads and gives
    @property
    def _columns(self) -> tuple:
        """(start, stop) of each channel in the wrapped observer's measurement."""
        spans, start = {}, 0
        for signal in self.inner.measurement_layout.signals:
            spans[signal.name] = (start, start + signal.size)
            start += signal.size
        return tuple(spans[name] for name in self.channels)

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def measurement_layout(self) -> Layout:  # type: ignore[override]  # (read-only, as every observer's)
        arrivals = tuple(
            Signal(f"arrival_{flag_name(name)}", "s", f"arrival of the new {flag_name(name)} reading (NaN: none)") for name in self.channels
        )
        return Layout(self.inner.measurement_layout.signals + arrivals)

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def input_layout(self) -> Layout:  # type: ignore[override]  # (read-only, as every observer's)
        return self.inner.input_layout

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def sample_period(self) -> float | None:  # type: ignore[override]  # (read-only, as every observer's)
        return self.inner.sample_period

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def estimate_signals(self) -> tuple[Signal, ...]:  # type: ignore[override]  # (read-only, as every observer's)
        return self.inner.estimate_signals

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def extra_signals(self) -> tuple[Signal, ...]:  # type: ignore[override]  # (read-only, as every observer's)
        flags = []
        for name in self.channels:
            short = flag_name(name)
            flags.append(Signal(f"gated_{short}", "1", f"new {short} reading rejected as a wild point"))
            flags.append(Signal(f"outage_{short}", "1", f"{short} older than its timeout: dead reckoning"))
        return tuple(self.inner.extra_signals) + tuple(flags)

    def guess(self) -> Any:
        return self.inner.guess()

    # -- the rules
    def _split(self, y):
        size = self.inner.measurement_layout.size
        return y[:size], y[size:]

    def _candidate(self, state: GatedState, t, new, arrival):
        """The measurement with each channel's new reading, else its held one (NaN when
        too old); the entries of no channel as they came (NaN: none)."""
        y = jnp.asarray(new)
        for index, (start, stop) in enumerate(self._columns):
            fresh = jnp.isfinite(arrival[index])
            alive = (t - state.held_time[index] <= self.timeout[index]) & self.hold
            y = y.at[start:stop].set(jnp.where(fresh, new[start:stop], jnp.where(alive, state.held[start:stop], jnp.nan)))
        return y

    def init(self, y0: jax.Array, guess: Any) -> GatedState:
        new, arrival = self._split(jnp.asarray(y0))
        n = len(self.channels)
        # every part of the state is finite (a Stepper refuses a step that is not):
        # a missing reading is held as 0 with an arrival long ago
        held = jnp.where(jnp.isfinite(new), new, 0.0)
        # without a hold, a channel not yet heard is given its timeout from the first step
        # (a second gyro whose first reading comes a moment later is no outage)
        held_time = jnp.where(jnp.isfinite(arrival), arrival, -1e300 if self.hold else 0.0)
        missing = (~jnp.isfinite(new)).astype(held.dtype)
        stale = self._stale(missing, jnp.zeros(n, dtype=bool) if not self.hold else ~jnp.isfinite(arrival))
        return GatedState(self.inner.init(new, guess), held, held_time, jnp.zeros(n), held, missing, jnp.zeros(n), stale)

    def _stale(self, missing: jax.Array, old: jax.Array) -> jax.Array:
        """Per channel, 1 in an outage: a held channel's measurement missing (its reading
        older than the timeout), else ``old`` (no reading within the timeout)."""
        if self.hold:
            return jnp.stack([jnp.any(missing[start:stop] > 0) for start, stop in self._columns]).astype(missing.dtype)
        return old.astype(missing.dtype)

    def _statistics(self, state: GatedState, t, candidate):
        """Per channel, what its test compares with its gate (0 for ``"none"``), and the
        wrapped observer's trial update on ``candidate`` when an ``"innovation"`` test
        needed it (None otherwise)."""
        trial = None
        if "nis" in self.tests:
            innovation, covariance = self.inner.innovation_statistics(state.inner, candidate)  # type: ignore[attr-defined]  # not every Observer has it: __init__ refuses "nis" tests for one without
        if "innovation" in self.tests:
            trial = self.inner.update(state.inner, t, candidate)
            estimate = self.inner.output(trial, candidate)
        sizes = []
        for name, test, (start, stop) in zip(self.channels, self.tests, self._columns):
            if test == "nis":
                nu = innovation[start:stop]
                statistics = nu @ jnp.linalg.solve(covariance[start:stop, start:stop], nu)
            elif test == "innovation":
                statistics = jnp.linalg.norm(jnp.atleast_1d(estimate[name.replace("measured_", "innovation_")]))
            else:
                statistics = jnp.zeros(())
            sizes.append(statistics)
        return jnp.stack(sizes), trial

    def update(self, state: GatedState, t: ArrayLike, y: jax.Array) -> GatedState:
        new, arrival = self._split(y)
        candidate = self._candidate(state, t, new, arrival)
        sizes, trial = self._statistics(state, t, candidate)
        tested = jnp.asarray([test != "none" for test in self.tests])
        wild = tested & jnp.isfinite(arrival) & (sizes > self.gate) & (state.wild_in_row < self.reopen_after)
        kept_arrival = jnp.where(wild, jnp.nan, arrival)
        used = self._candidate(state, t, new, kept_arrival)
        redone = self.inner.update(state.inner, t, used)
        # the trial update on the candidate is the step's when no reading was wild
        inner = redone if trial is None else jax.tree.map(lambda a, b: jnp.where(jnp.any(wild), a, b), redone, trial)
        accepted = jnp.isfinite(kept_arrival)
        held, held_time = state.held, state.held_time
        for index, (start, stop) in enumerate(self._columns):
            held = held.at[start:stop].set(jnp.where(accepted[index], new[start:stop], held[start:stop]))
        held_time = jnp.where(accepted, arrival, held_time)
        in_row = jnp.where(jnp.isfinite(arrival), jnp.where(wild, state.wild_in_row + 1, 0.0), state.wild_in_row)
        missing = ~jnp.isfinite(used)
        stale = self._stale(missing.astype(used.dtype), jnp.asarray(t - held_time > self.timeout))
        return GatedState(inner, held, held_time, in_row, jnp.where(missing, 0.0, used), missing.astype(used.dtype), wild.astype(used.dtype), stale)

    def output(self, state: GatedState, y: jax.Array) -> dict[str, jax.Array]:
        """The wrapped observer's outputs, the gate and outage flags, and under
        ``"measurement_used"`` the measurement the step used (held readings), which a
        session records as its measurement: 0 where it was NaN (an outage, a channel the
        stream does not fill), because a :class:`~lookout.Stepper` refuses a step whose
        outputs are not finite; the outage flags say where."""
        estimate = dict(self.inner.output(state.inner, state.measurement))
        estimate["measurement_used"] = state.used
        for index, name in enumerate(self.channels):
            short = flag_name(name)
            estimate[f"gated_{short}"] = state.gated[index]
            estimate[f"outage_{short}"] = state.stale[index]
        return estimate

    def predict(self, state: GatedState, t: ArrayLike, y: jax.Array, u: jax.Array, dt: ArrayLike) -> GatedState:
        return eqx.tree_at(lambda s: s.inner, state, self.inner.predict(state.inner, t, state.measurement, u, dt))
