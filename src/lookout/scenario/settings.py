"""Settings as users give them (files, the Python API), and the checks they share.

:class:`Settings` is the strict pydantic base of every schema (a reproduction's Config,
a component kind's parameters, a composition's ``[simulation]``). Each check raises
``ValueError`` with a message that reads after the field's name ("duration must be
..."); the CLI shows it under the option's name.
"""

from __future__ import annotations

import json
import math
from typing import Annotated, TypeVar

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from lookout._validation import short
from lookout.sim import MAX_SEED, integer_ratio

#: Samples a run may have (the noise counters are 32-bit; lookout.sim.Scenario).
MAX_SAMPLES = 2**32


def positive_count(value: int) -> int:
    """``value`` if it is a positive integer (a number of runs or seeds) that seeds can
    count (at most 2^63: a JAX key takes a signed 64-bit seed)."""
    if value < 1:
        raise ValueError(f"must be a positive integer; got {value}")
    if value > MAX_SEED + 1:
        raise ValueError(f"must be at most {MAX_SEED + 1} (each run has its own signed 64-bit seed); got {value}")
    return value


def finite_positive(value: float) -> float:
    """``value`` if it is a finite positive number."""
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"must be a finite positive number; got {value:g}")
    return value


#: A setting that must be a finite positive number (a step, a duration, a gain): the
#: check of :func:`finite_positive`, with its message, under the field's name.
PositiveFloat = Annotated[float, AfterValidator(finite_positive)]
#: A setting that must be a positive count of runs or seeds (:func:`positive_count`).
PositiveCount = Annotated[int, AfterValidator(positive_count)]


def seed_for_runs(seed: int, runs: int) -> int:
    """``seed`` if seeds ``seed .. seed + runs - 1`` all make JAX keys."""
    largest = MAX_SEED - runs + 1
    if not 0 <= seed <= largest:
        raise ValueError(
            f"must be an integer from 0 to {largest} (a JAX key takes a signed 64-bit seed, and the runs use seed ... seed + runs - 1); got {seed}"
        )
    return seed


def whole_samples(duration: float, period: float | None, what: str = "the observer's sample period") -> float:
    """``duration`` if it is a whole number of ``period`` (unchecked when the period itself
    failed, or when ``duration`` is not a positive number: its own check says so)."""
    if period is not None and math.isfinite(duration) and duration > 0 and integer_ratio(duration, period) is None:
        raise ValueError(f"must be a whole multiple of {what} ({period:g} s); got {duration:g} s")
    return duration


def _plain(value):
    """Lists and arrays as tuples, NumPy scalars as Python ones: what strict validation
    takes for a tuple or a number."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return tuple(_plain(item) for item in value)
    if isinstance(value, np.generic):
        return value.item()
    return value


def _first_non_finite(value, location: tuple) -> tuple | None:
    if isinstance(value, float):
        return None if math.isfinite(value) else location
    if isinstance(value, tuple):
        for index, item in enumerate(value):
            found = _first_non_finite(item, location + (index,))
            if found is not None:
                return found
    return None


class Settings(BaseModel):
    """Settings as a user gives them, in a file or in Python: frozen, no unknown keys, and
    strictly typed (pydantic's strict mode: a number must be a number, ``True`` and
    ``"100"`` are not; arrays may be lists or NumPy arrays), every number finite."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)

    @model_validator(mode="before")
    @classmethod
    def _arrays_as_tuples(cls, data):
        if isinstance(data, dict):
            return {key: value if isinstance(value, dict) else _plain(value) for key, value in data.items()}
        return data

    @model_validator(mode="after")
    def _every_number_finite(self):
        for name in type(self).model_fields:
            value = getattr(self, name)
            location = _first_non_finite(value, (name,))
            if location is not None:
                bad = value
                for index in location[1:]:
                    bad = bad[index]
                detail = InitErrorDetails(
                    type=PydanticCustomError("not_finite", "must be finite; got {value}", {"value": bad}), loc=location, input=bad
                )
                raise ValidationError.from_exception_data(type(self).__name__, [detail])
        return self


class RunsConfig(Settings):
    """The part every reproduction's Config shares: :class:`Settings`, ``runs``
    vmapped runs over seeds ``seed .. seed + runs - 1``, each a valid JAX key. Subclasses
    may redeclare ``runs`` or ``seed`` for their own description; the checks stay."""

    runs: int = Field(default=1, description="Monte Carlo runs (vmapped); run i uses seed + i")
    seed: int = Field(default=0, description="PRNG seed of run 0")

    @field_validator("runs")
    @classmethod
    def _positive_runs(cls, value):
        return positive_count(value)

    @field_validator("seed")
    @classmethod
    def _seed_in_key_range(cls, value, info: ValidationInfo):
        return seed_for_runs(value, info.data.get("runs", 1))

    # The sample-loop rules the engine enforces (lookout.sim.Scenario), checked here under
    # the settings' own names for every template whose settings have these fields, so a
    # file's error names its key, not the engine's parameter.
    @field_validator("sample_period", check_fields=False)
    @classmethod
    def _whole_plant_steps(cls, value, info: ValidationInfo):
        return whole_samples(value, info.data.get("plant_step"), "plant_step") if "plant_step" in cls.model_fields else value

    @field_validator("measurement_period", check_fields=False)
    @classmethod
    def _whole_samples_per_fix(cls, value, info: ValidationInfo):
        return whole_samples(value, info.data.get("sample_period"), "sample_period") if "sample_period" in cls.model_fields else value

    @field_validator("duration", check_fields=False)
    @classmethod
    def _counted_samples(cls, value, info: ValidationInfo):
        period = info.data.get("sample_period")
        if period is not None and math.isfinite(value) and value / period >= MAX_SAMPLES:
            raise ValueError(
                f"must be below {MAX_SAMPLES:.4g} samples of sample_period ({period:g} s), the noise counters' range; got {value / period:.3g} samples"
            )
        return value

    @property
    def seeds(self) -> list[int]:
        """The seed of each run: seed, seed + 1, ..., seed + runs - 1."""
        return list(range(self.seed, self.seed + self.runs))


class NoiseFreeConfig(RunsConfig):
    """A :class:`RunsConfig` for a noise-free reproduction: ``runs`` must be 1, since every
    run would be the same; the seed is recorded with the results and draws nothing."""

    runs: int = Field(default=1, description="1: the runs are noise-free, every run would be the same")
    seed: int = Field(default=0, description="recorded with the results; the runs draw no random numbers")

    @field_validator("runs")
    @classmethod
    def _one_run(cls, value):
        if value != 1:
            raise ValueError(f"must be 1: this reproduction is noise-free, so every run would be the same; got {value}")
        return value


#: The names pydantic gives the members of a union in an error's location.
UNION_TAGS = frozenset({"str", "int", "float", "bool", "dict", "list", "tuple"})

#: pydantic's strict type errors, as the file's reader would say them.
STRICT_TYPES = {
    "float_type": "must be a number",
    "int_type": "must be an integer (no decimal point)",
    "bool_type": "must be true or false",
    "string_type": "must be a string (in quotes)",
    "tuple_type": "must be an array",
    "list_type": "must be an array",
    "dict_type": "must be a table",
    "model_type": "must be a table",
}


def _as_toml(value) -> str:
    """A value as it reads in a TOML file: ``true``, ``"100"``, ``2.0``, ``[1, 2]``."""
    if isinstance(value, bool):
        return f"{str(value).lower()} (a boolean)"
    if isinstance(value, str) and value.startswith("<a TOML ") and value.endswith(">"):
        return value[1:-1]
    if isinstance(value, str):
        return f"{json.dumps(value)} (a string)"
    if isinstance(value, float):
        return f"{value!r} (a number with a decimal point)"
    if isinstance(value, (list, tuple)):
        return f"an array of {len(value)}"
    if isinstance(value, dict):
        return "a table"
    return repr(value)


def explain(error: ValidationError) -> tuple[tuple, str]:
    """The first error of a pydantic validation as (the key's location, the condition),
    in the words of a file's reader."""
    errors = error.errors()
    # of a union's members (a number or an array), the error that went deepest says most
    first = max((e for e in errors if e["loc"][:1] == errors[0]["loc"][:1]), key=lambda e: len(e["loc"]))
    # pydantic names the member of a union it tried ("scenario.str"): not a key of the file
    location = tuple(
        part for part in first["loc"] if not (isinstance(part, str) and (part.startswith("function-") or part in UNION_TAGS or "[" in part))
    )
    message = first["msg"]
    if message.startswith("Value error, "):
        message = message[len("Value error, ") :]
    if first["type"] == "extra_forbidden":
        message = "unknown key"
    elif first["type"] == "missing" and isinstance(location[-1], int):
        location, message = location[:-1], f"too few entries (no entry [{location[-1]}])"
    elif first["type"] == "missing":
        message = "missing key"
    elif first["type"] in STRICT_TYPES:
        message = f"{STRICT_TYPES[first['type']]}; got {_as_toml(first.get('input'))}"
    elif "input" in first and first["type"] not in ("value_error", "assertion_error", "not_finite"):  # not_finite says what it got
        message = f"{message}; got {short(first['input'])}"
    return location, message


_Model = TypeVar("_Model", bound=BaseModel)


def validate_strictly(model: type[_Model], values: dict) -> _Model:
    """``model`` validated from a file's ``values`` in pydantic's strict mode: a number
    must be a number (an integer is one), a boolean a boolean and a string a string
    (``duration = true`` and ``duration = "100"`` are refused, not read as 1 s and
    100 s). The values go through JSON, whose strict mode takes arrays for tuples; a
    TOML date or time becomes a string, which no number or boolean accepts."""
    text = json.dumps(values, allow_nan=True, default=lambda value: f"<a TOML {type(value).__name__}: {value}>")
    return model.model_validate_json(text, strict=True)
