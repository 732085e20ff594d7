"""Checks shared by the reproductions' pydantic Configs.

Each raises ``ValueError`` with a message that reads after the field's name
("duration must be ..."); the CLI shows it under the option's name.
"""

from __future__ import annotations

import math

from lookout.sim import MAX_SEED, integer_ratio


def positive_count(value: int) -> int:
    """``value`` if it is a positive integer (a number of runs or seeds)."""
    if value < 1:
        raise ValueError(f"must be a positive integer; got {value}")
    return value


def finite_positive(value: float) -> float:
    """``value`` if it is a finite positive number."""
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"must be a finite positive number; got {value:g}")
    return value


def seed_for_runs(seed: int, runs: int) -> int:
    """``seed`` if seeds ``seed .. seed + runs - 1`` all make JAX keys."""
    largest = MAX_SEED - runs + 1
    if not 0 <= seed <= largest:
        raise ValueError(
            f"must be an integer from 0 to {largest} (a JAX key takes a signed 64-bit seed, and the runs use seed ... seed + runs - 1); got {seed}"
        )
    return seed


def whole_samples(duration: float, period: float | None, what: str = "the observer's sample period") -> float:
    """``duration`` if it is a whole number of ``period`` (unchecked when the period itself failed)."""
    if period is not None and integer_ratio(duration, period) is None:
        raise ValueError(f"must be a whole multiple of {what} ({period:g} s); got {duration:g} s")
    return duration
