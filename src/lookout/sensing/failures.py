"""The ways a sensor fails, as data: dropout, freeze, jump, drift, noise, wild points
and latency, each over a window of time.

A failure acts on one instrument of a suite (``[[sensors.NAME.failures]]``), on all
its channels or on those of one of its signals, from ``start`` for ``duration``
seconds (to the end of the run when not given); ``start = inf`` is a failure that never
happens, which a campaign's axis can switch on without compiling again. ``start``, ``duration`` and each
size are arrays, so a campaign sweeps them without compiling again; the mode, the
signal and a latency's delay are the structure. While a failure is active the suite
records a flag of 1 beside the measurements (``NAME.MODE_failure``; for ``wild``, 1
at the samples an outlier was added).

Modes, applied in the order given to a sample ``y = value + white`` of the instrument:

========  ==================================================================
dropout   NaN: the sample is missing (the observer rides through it)
freeze    the channel holds its last sample, bit for bit (its first, when the
          failure starts before the instrument has one)
jump      ``y + size`` (a step; one number, or one per channel)
drift     ``y + rate (t - start)`` (a ramp; m/s, rad/s, ... per channel)
noise     ``y + (factor - 1) white``: the white noise's std times ``factor``
wild      with ``probability`` per sample, ``y + size n`` (n standard normal)
latency   the sample taken ``delay`` seconds earlier (a multiple of the period;
          NaN while the instrument has none that old, from the run's start)
========  ==================================================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.special
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import Signal

#: The failure modes and the keys each takes besides mode, start, duration and signal.
MODES: dict[str, tuple[str, ...]] = {
    "dropout": (),
    "freeze": (),
    "jump": ("size",),
    "drift": ("rate",),
    "noise": ("factor",),
    "wild": ("probability", "size"),
    "latency": ("delay",),
}
COMMON_KEYS = ("mode", "start", "duration", "signal")


class Failure(eqx.Module):
    """One failure of one instrument.

    Attributes
    ----------
    mode : str
        One of :data:`MODES` (static).
    start, duration : Array
        The window ``[start, start + duration)`` (s); an infinite duration lasts to the end.
    channels : tuple of bool
        Per channel of the instrument: whether the failure acts on it (static).
    size : Array
        Per channel: a jump's step, a wild point's standard deviation, a drift's rate,
        a noise failure's factor (unused by the other modes).
    probability : Array
        A wild point's probability per sample.
    delay_samples : int
        A latency's delay in samples of the instrument (static).
    """

    mode: str = eqx.field(static=True)
    start: Array
    duration: Array
    channels: tuple[bool, ...] = eqx.field(static=True)
    size: Array
    probability: Array
    delay_samples: int = eqx.field(static=True, default=0)

    @property
    def noise_count(self) -> int:
        """Standard normals a sample of it draws (two per channel for a wild point)."""
        return 2 * len(self.channels) if self.mode == "wild" else 0

    def active(self, t: ArrayLike) -> Array:
        """Whether the window holds ``t``."""
        return jnp.asarray((t >= self.start) & (t < self.start + self.duration))

    def initial_memory(self, size: int) -> Any:
        """A latency's buffer of its last ``delay_samples`` samples, a freeze's frozen
        sample (NaN: none yet)."""
        if self.mode == "latency":
            return jnp.full((self.delay_samples, size), jnp.nan)
        if self.mode == "freeze":
            return jnp.full(size, jnp.nan)
        return ()

    def apply(self, memory: Any, t: ArrayLike, y: Array, white: Array, held: Array, normals: Array, due: Array) -> tuple[Any, Array, Array]:
        """``(memory, y, flag)``: the sample ``y`` of the instrument (``white`` its white
        noise, ``held`` its last sample, ``due`` whether it samples now) after this
        failure at ``t``, and the failure's flag (1 while it acts)."""
        on = self.active(t)
        hit = on & jnp.asarray(self.channels)
        flag = on.astype(float)
        if self.mode == "dropout":
            y = jnp.where(hit, jnp.nan, y)
        elif self.mode == "freeze":
            # the value it froze on: the last sample, or this one when there is none yet
            frozen = jnp.where(jnp.isnan(memory), jnp.where(jnp.isfinite(held), held, y), memory)
            memory = jnp.where(on, jnp.where(due, frozen, memory), jnp.nan)
            y = jnp.where(hit, frozen, y)
        elif self.mode == "jump":
            y = jnp.where(hit, y + self.size, y)
        elif self.mode == "drift":
            y = jnp.where(hit, y + self.size * (t - self.start), y)
        elif self.mode == "noise":
            y = jnp.where(hit, y + (self.size - 1.0) * white, y)
        elif self.mode == "wild":
            n = len(self.channels)
            # Phi(n) < p written as n < Phi^-1(p), one draw for the whole sample
            outlier = on & (normals[0] < jax.scipy.special.ndtri(self.probability))
            y = jnp.where(outlier & jnp.asarray(self.channels), y + self.size * normals[n : 2 * n], y)
            flag = outlier.astype(float)
        elif self.mode == "latency":
            oldest = memory[0]
            memory = jnp.where(due, jnp.concatenate([memory[1:], y[None]], axis=0), memory)
            y = jnp.where(hit, oldest, y)
        return memory, y, flag


_number = check.table_number


def _per_channel(location: tuple, value: Any, size: int) -> np.ndarray:
    name = location[-1]
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        array = np.asarray([np.nan])
    if array.ndim == 0:
        array = np.full(size, float(array))
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise check.ParameterError(location, f"{name} must be one finite number or {size} (one per channel); got {check.short(value)}")
    return array


def failure_from_table(table: Any, signals: Sequence[Signal], period: float, location: tuple = (), *, run_duration: float | None = None) -> Failure:
    """The :class:`Failure` a ``[[sensors.NAME.failures]]`` table describes, for an
    instrument of ``signals`` sampled every ``period`` seconds (``run_duration``: the
    run's, which the start must precede); every refusal is a one-line
    :class:`~lookout._validation.ParameterError` whose location is ``location`` and the key."""
    if not isinstance(table, dict):
        raise check.ParameterError(location, f"must be a table with a mode; got {check.short(table)}")
    mode = table.get("mode")
    if mode not in MODES:
        raise check.ParameterError(location + ("mode",), f"mode must be one of {', '.join(MODES)}; got {check.short(mode)}")
    allowed = COMMON_KEYS + MODES[mode]
    for key in table:
        if key not in allowed:
            raise check.ParameterError(location + (key,), f"unknown key (a {mode} failure takes {', '.join(allowed)})")
    for key in ("start",) + MODES[mode]:
        if key not in table:
            raise check.ParameterError(location + (key,), f"missing key (a {mode} failure needs {', '.join(('start',) + MODES[mode])})")
    # inf: never (a failure that a campaign's axis switches on, lookout failures)
    start = _number(location + ("start",), table["start"], allow_inf=True, inf_means="never")
    if run_duration is not None and math.isfinite(start) and start >= run_duration:
        raise check.ParameterError(
            location + ("start",), f"start ({start:g} s) must be before the run's end (duration {run_duration:g} s) for the failure to happen"
        )
    length = _number(location + ("duration",), table.get("duration", math.inf), positive=True, allow_inf=True)
    names = [signal.name for signal in signals]
    signal = table.get("signal")
    if signal is not None and signal not in names:
        raise check.ParameterError(location + ("signal",), f"the sensor measures no {check.short(signal)} (it measures {', '.join(names)})")
    channels = tuple(signal is None or s.name == signal for s in signals for _ in range(s.size))
    size = np.zeros(len(channels))
    probability = 0.0
    delay_samples = 0
    if mode in ("jump", "wild"):
        size = _per_channel(location + ("size",), table["size"], len(channels))
        if mode == "wild" and np.any(size < 0):
            raise check.ParameterError(location + ("size",), f"size must be >= 0 (a standard deviation); got {check.short(table['size'])}")
    if mode == "drift":
        size = _per_channel(location + ("rate",), table["rate"], len(channels))
    if mode == "noise":
        size = np.full(len(channels), _number(location + ("factor",), table["factor"]))
    if mode == "wild":
        probability = _number(location + ("probability",), table["probability"])
        if probability >= 1.0:
            raise check.ParameterError(location + ("probability",), f"probability must be in [0, 1); got {table['probability']}")
    if mode == "latency":
        delay = _number(location + ("delay",), table["delay"], positive=True)
        ratio = delay / period
        if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
            raise check.ParameterError(
                location + ("delay",), f"delay ({delay:g} s) must be a whole number of the sensor's sample periods ({period:g} s)"
            )
        delay_samples = int(round(ratio))
    return Failure(mode, jnp.asarray(start), jnp.asarray(length), channels, jnp.asarray(size), jnp.asarray(probability), delay_samples)


def flag_signal(sensor: str, mode: str, index: int, modes: Sequence[str]) -> Signal:
    """The recorded flag of failure ``index`` (of ``modes``, the sensor's failures in
    order): ``SENSOR.MODE_failure``, with the index when the sensor has two of a mode."""
    suffix = f"{mode}_failure" if list(modes).count(mode) == 1 else f"{mode}{index + 1}_failure"
    return Signal(f"{sensor}.{suffix}", "1", f"{sensor}: {mode} failure active (1) or not (0), the truth of the injected failure")
