"""From several references to the one position and heading an observer reads: the
combining stage of a sensor suite (``[references]``).

The plain stage, ``weighted-mean``: the heading is the median of the available
gyrocompasses (taken as angles: the median of their differences from the first,
wrapped); each available position reference is taken back to the vessel's reference
point with that heading, ``p_i = y_i - R(psi) r_i``, and the position is their mean
weighted by the inverse variance each states (:meth:`PositionReference.weight_std`).
A reference is available when its last sample is finite: between its samples it
counts with its held value, and a dropped or missing one is left out; with none
available the combined channel is NaN, a dropout the observer rides through.

The lever arms are taken back with the measured heading, not an observer's estimate:
the stage then needs nothing of the observer, and it is what a DP system does with
its gyros; the difference is the gyro's error times the lever arm (2 mrad at 30 m is
6 cm).

A stage is a :class:`CombiningStage`: it names the channels it gives
(:meth:`CombiningStage.signals`, each taken from the position references or from the
gyrocompasses: :meth:`CombiningStage.sources`) and steps a memory of its own
(:meth:`CombiningStage.initial_memory`, :meth:`CombiningStage.step`), which the suite
carries from sample to sample. ``weighted-mean`` keeps none; ``dp-class``
(:class:`lookout.sensing.handling.ReferenceHandler`) keeps its tests' windows, its
tracker and each reference's state.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from typing import Any, final

import equinox as eqx
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from lookout._math import ssa
from lookout.components import EARTH_FIXED, Signal
from lookout.declare import component
from lookout.sensing.heading import Gyrocompass
from lookout.sensing.instrument import HEADING, POSITION, Instrument
from lookout.sensing.position import PositionReference
from lookout.vessel_signals import EARTH_AXES

#: What the stage gives the observer: the names the observers of the papers read.
COMBINED_POSITION = Signal(
    "measured_position",
    "m",
    "combined position of the vessel's reference point (weighted mean of the references)",
    EARTH_FIXED,
    EARTH_AXES,
    "earth_axis",
)
COMBINED_HEADING = Signal("measured_heading", "rad", "combined heading (median of the gyrocompasses)", EARTH_FIXED, angle=True)


def circular_median(angles: Array) -> Array:
    """The median of the finite entries of ``angles`` (rad) as angles: the first finite
    one plus the median of the others' wrapped differences from it; NaN when none is."""
    finite = jnp.isfinite(angles)
    first = angles[jnp.argmax(finite)]
    offsets = jnp.where(finite, ssa(jnp.where(finite, angles, 0.0) - jnp.where(finite, first, 0.0)), jnp.nan)
    return jnp.where(jnp.any(finite), ssa(first + jnp.nanmedian(offsets)), jnp.nan)


class CombiningStage(eqx.Module):
    """A suite's combining stage (abstract): from the instruments' held samples to the
    combined channels, ``measured_position`` and ``measured_heading`` first, then any
    of its own (recorded, read by no observer).

    The suite hands it the instruments in the order of their names, so that the
    order of a file's tables changes no bit of its output.
    """

    @abc.abstractmethod
    def signals(self, instruments: Sequence[Instrument], names: Sequence[str] = ()) -> tuple[Signal, ...]:
        """The channels it gives for a suite of ``instruments`` named ``names``, in order."""

    @abc.abstractmethod
    def sources(self, instruments: Sequence[Instrument], names: Sequence[str] = ()) -> tuple[str, ...]:
        """Per channel of :meth:`signals`: what it is taken from, :data:`POSITION` (the
        position references) or :data:`HEADING` (the gyrocompasses). The suite takes a
        channel anew when one of those has a new sample, and holds it otherwise."""

    @abc.abstractmethod
    def initial_memory(self, instruments: Sequence[Instrument]) -> Any:
        """The stage's memory before the first sample (a PyTree of arrays; ``()`` for none)."""

    @abc.abstractmethod
    def step(
        self, memory: Any, instruments: Sequence[Instrument], samples: Sequence[Array], fresh: Array, held_heading: Array, t: ArrayLike
    ) -> tuple[Any, Array]:
        """``(memory, combined channels)`` at ``t``: ``samples`` each instrument's held
        sample (NaN: missing), ``fresh`` per instrument whether it was taken now, and
        ``held_heading`` the last combined heading (it takes the lever arms back when
        no gyrocompass has a sample)."""


@component(
    "references",
    "weighted-mean",
    summary="The median of the gyrocompasses and the inverse-variance weighted mean of the position references, lever arms taken back.",
    parameters=(),
)
@final
class WeightedMean(CombiningStage):
    """The plain combining stage (see the module docstring).

    It provides ``measured_position`` when the suite has a position reference and
    ``measured_heading`` when it has a gyrocompass.
    """

    def signals(self, instruments: Sequence[Instrument], names: Sequence[str] = ()) -> tuple[Signal, ...]:
        """What it gives for a suite of ``instruments`` (their names do not enter)."""
        provides = {each.provides for each in instruments}
        return ((COMBINED_POSITION,) if POSITION in provides and HEADING in provides else ()) + ((COMBINED_HEADING,) if HEADING in provides else ())

    def sources(self, instruments: Sequence[Instrument], names: Sequence[str] = ()) -> tuple[str, ...]:
        return tuple(HEADING if signal is COMBINED_HEADING else POSITION for signal in self.signals(instruments))

    def initial_memory(self, instruments: Sequence[Instrument]) -> tuple[()]:
        return ()

    def step(
        self, memory: Any, instruments: Sequence[Instrument], samples: Sequence[Array], fresh: Array, held_heading: Array, t: ArrayLike
    ) -> tuple[Any, Array]:
        """:meth:`combine` of the held samples; no memory, and whether a sample is new
        does not enter."""
        return memory, self.combine(instruments, samples, held_heading)

    def combine(self, instruments: Sequence[Instrument], samples: Sequence[Array], held_heading: Array) -> Array:
        """The combined channels (in the order of :meth:`signals`) from each
        instrument's current sample; ``held_heading`` is the last combined heading, which
        takes the lever arms back when no gyrocompass has a sample."""
        headings = [each.heading_of(y) for each, y in zip(instruments, samples) if isinstance(each, Gyrocompass)]
        if not headings:
            return jnp.zeros(0)
        heading = circular_median(jnp.stack(headings))
        lever_heading = jnp.where(jnp.isfinite(heading), heading, held_heading)
        out = []
        references = [(each, y) for each, y in zip(instruments, samples) if isinstance(each, PositionReference)]
        if references:
            points = jnp.stack([each.reference_point(y, lever_heading) for each, y in references])
            weights = jnp.stack([1.0 / jnp.maximum(each.weight_std() ** 2, 1e-12) for each, _ in references])
            present = jnp.all(jnp.isfinite(points), axis=1)
            weights = jnp.where(present, weights, 0.0)
            total = jnp.sum(weights)
            mean = jnp.sum(weights[:, None] * jnp.where(present[:, None], points, 0.0), axis=0) / jnp.where(total > 0, total, 1.0)
            out.append(jnp.where(total > 0, mean, jnp.nan))
        out.append(jnp.reshape(heading, (1,)))
        return jnp.concatenate(out)


__all__ = ["COMBINED_HEADING", "COMBINED_POSITION", "CombiningStage", "WeightedMean", "circular_median"]
