"""The components a scenario has where it names none: no reference, and an actuator
that passes the command on unchanged.

They are defined beside the contract (:mod:`lookout.components`), so that the engine
(:class:`lookout.sim.Scenario`, whose defaults they are) needs no reference or actuator
module; :mod:`lookout.reference` and :mod:`lookout.actuators` re-export them.
"""

from __future__ import annotations

from typing import Any, final

import equinox as eqx
from jax import Array
from jax.typing import ArrayLike

from lookout.components import Reference, Signal, StatelessActuator
from lookout.declare import component


@component(
    "reference",
    "none",
    summary="No reference: an observer run open loop, or a controller that needs none.",
    parameters=(),
)
@final
class NoReference(Reference):
    """No reference: an observer run open loop, or a controller that needs none."""

    reference_signals: tuple[Signal, ...] = eqx.field(static=True, default=(), kw_only=True)
    noise_size: int = eqx.field(static=True, default=0, kw_only=True)

    def init(self) -> tuple[()]:
        """No internal state."""
        return ()

    def step(self, state: Any, t: ArrayLike, dt: ArrayLike, normals: Array) -> tuple[Any, dict[str, Array]]:
        """``(state, {})``."""
        del t, dt, normals
        return state, {}


@component(
    "actuator",
    "ideal",
    summary="The plant receives the commanded input unchanged (no limits).",
    parameters=(),
)
@final
class IdealActuator(StatelessActuator):
    """The plant receives the commanded input unchanged (no limits)."""

    def apply(self, u: Array) -> Array:
        """``u``."""
        return u
