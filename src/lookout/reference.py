"""Reference generators: the desired trajectory a controller tracks."""

from __future__ import annotations

from typing import final

import equinox as eqx

from lookout.components import Reference, Signal


@final
class NoReference(Reference):
    """No reference: an observer run open loop, or a controller that needs none."""

    reference_signals: tuple[Signal, ...] = eqx.field(static=True, default=(), kw_only=True)
    noise_size: int = eqx.field(static=True, default=0, kw_only=True)

    def init(self):
        """No internal state."""
        return ()

    def step(self, state, t, dt, normals):
        """``(state, {})``."""
        del t, dt, normals
        return state, {}
