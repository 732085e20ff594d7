"""Checks shared by the reproductions' pydantic Configs.

Each raises ``ValueError`` with a message that reads after the field's name
("duration must be ..."); the CLI shows it under the option's name.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

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


class RunsConfig(BaseModel):
    """The part every reproduction's Config shares: frozen, no unknown fields, ``runs``
    vmapped runs over seeds ``seed .. seed + runs - 1``, each a valid JAX key. Subclasses
    may redeclare ``runs`` or ``seed`` for their own description; the checks stay."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    runs: int = Field(1, description="Monte Carlo runs (vmapped); run i uses seed + i")
    seed: int = Field(0, description="PRNG seed of run 0")

    @field_validator("runs")
    @classmethod
    def _positive_runs(cls, value):
        return positive_count(value)

    @field_validator("seed")
    @classmethod
    def _seed_in_key_range(cls, value, info: ValidationInfo):
        return seed_for_runs(value, info.data.get("runs", 1))

    @property
    def seeds(self) -> list[int]:
        """The seed of each run: seed, seed + 1, ..., seed + runs - 1."""
        return list(range(self.seed, self.seed + self.runs))


class NoiseFreeConfig(RunsConfig):
    """A :class:`RunsConfig` for a noise-free reproduction: ``runs`` must be 1, since every
    run would be the same; the seed is recorded with the results and draws nothing."""

    runs: int = Field(1, description="1: the runs are noise-free, every run would be the same")
    seed: int = Field(0, description="recorded with the results; the runs draw no random numbers")

    @field_validator("runs")
    @classmethod
    def _one_run(cls, value):
        if value != 1:
            raise ValueError(f"must be 1: this reproduction is noise-free, so every run would be the same; got {value}")
        return value
