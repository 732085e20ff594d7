"""Actuators: what the plant receives for a commanded input."""

from __future__ import annotations

from typing import final

from lookout.components import Actuator


@final
class IdealActuator(Actuator):
    """The plant receives the commanded input unchanged (no limits)."""

    def apply(self, u):
        """``u``."""
        return u
