"""The live commands' settings that have defaults: what a reading must pass
(:class:`Gates`) and the longest silence a replay bridges (:data:`MAX_GAP`).

They live apart from the session and its loops, which import JAX, so that the
command's options (and ``lookout --help``) take their defaults from here without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: The longest silence of a log (s) a replay dead-reckons through unless told more:
#: docs/live.md, "Why 60 s for --max-gap", gives the reason.
MAX_GAP = 60.0

#: The farthest (m) a given origin may lie from the first fix. The frame is flat, the
#: tangent plane at the origin: a fix d east of it sees the frame's north turned from
#: its own true north (the gyro's) by about (d / R) tan(latitude) <= (d / R) / cos(latitude),
#: at 100 km 0.9 deg / cos(latitude), about a gyrocompass's allowed error (IMO A.424:
#: 0.75 deg / cos(latitude)); docs/live.md, "Why 100 km for an origin".
MAX_ORIGIN_DISTANCE = 100e3

#: The largest IMU reading a live session takes: horizontal specific force (m/s2, per
#: axis) and yaw rate (rad/s). A ship's horizontal acceleration stays far below 1 g and
#: its yaw rate below a few degrees a second (a DP vessel's below 0.1 g and 1 deg/s);
#: 2 g and 30 deg/s are beyond any hull's motion, so that a reading past them is a
#: corrupted sample (a bit error, a units mistake), counted as ``range`` and not used:
#: an IMU drives the observer that integrates it, and one such sample would move its state.
#: A rate of turn (ROT) is checked against the same yaw-rate limit.
IMU_LIMITS = (2 * 9.80665, math.radians(30.0))


def _positive(name: str, value) -> None:
    import numpy as np  # here, not at the top: `lookout --help` needs no NumPy

    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) or not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite positive number; got {value!r}")


@dataclass(frozen=True)
class Gates:
    """What a reading must pass to be used.

    Parameters
    ----------
    min_quality : int
        Lowest GGA fix quality accepted (1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float).
    max_hdop : float
        Highest HDOP accepted.
    position_gate : float
        Largest position innovation accepted (m).
    heading_gate : float
        Largest heading innovation accepted (degrees).
    position_timeout, heading_timeout : float
        Age (s) after which a channel's last reading is no longer used.
    reopen_after : int
        Wild points in a row after which the gate lets the next reading through.
    gate_probability : float
        The gate of a Kalman filter's readings: the probability that a reading of a
        consistent filter passes (its normalized innovation squared below the
        chi-square quantile of this probability). 0.9999 rejects one good reading in
        10 000 (a 10 Hz heading: one every 17 min) and a fix 60 m off when its
        innovation's standard deviation is below 14 m (a 2-DOF bound of 18.4).
    """

    min_quality: int = 1
    max_hdop: float = 5.0
    position_gate: float = 30.0
    heading_gate: float = 15.0
    position_timeout: float = 2.5
    heading_timeout: float = 1.0
    reopen_after: int = 5
    gate_probability: float = 0.9999

    def __post_init__(self):
        import numpy as np

        if isinstance(self.min_quality, bool) or not isinstance(self.min_quality, (int, np.integer)) or not 0 <= self.min_quality <= 9:
            raise ValueError(f"min_quality must be an integer GGA fix quality in 0..9; got {self.min_quality!r}")
        for name in ("max_hdop", "position_gate", "heading_gate", "position_timeout", "heading_timeout"):
            _positive(name, getattr(self, name))
        if isinstance(self.reopen_after, bool) or not isinstance(self.reopen_after, (int, np.integer)) or self.reopen_after < 1:
            raise ValueError(f"reopen_after must be a positive integer; got {self.reopen_after!r}")
        probability = self.gate_probability
        if isinstance(probability, bool) or not isinstance(probability, (int, float, np.floating, np.integer)) or not 0.0 < probability < 1.0:
            raise ValueError(f"gate_probability must be a probability strictly between 0 and 1; got {probability!r}")
