"""The settings the reproductions' Configs share beyond :mod:`lookout.scenario.settings`: a DP vessel
by name or by its matrices."""

from __future__ import annotations

import math

from pydantic import Field, field_validator, model_validator

from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_MASS
from lookout.scenario.settings import PositiveFloat, Settings

Row3 = tuple[float, float, float]
#: A 3x3 matrix as three rows (a TOML array of three arrays of three numbers).
Matrix3 = tuple[Row3, Row3, Row3]
#: Built-in DP vessels by name.
VESSELS = ("northern-clipper",)


class VesselSettings(Settings):
    """The vessel of a DP scenario: a built-in model by name, or the user's own matrices.

    ``model = "northern-clipper"`` is Fossen & Strand (1999), eqs. (56)–(57).
    ``model = "custom"`` takes ``mass_matrix`` (M with added mass, symmetric positive
    definite: assumption A1) and ``damping_matrix`` (D) in SI units (kg, kg m^2,
    kg/s, ...). ``mass`` and ``length`` scale the normalized ("bis") gains to SI.
    """

    model: str = Field(
        default="northern-clipper",
        description="'northern-clipper' (Fossen & Strand 1999, eqs. 56-57) or 'custom' (give mass_matrix and damping_matrix)",
    )
    mass_matrix: Matrix3 | None = Field(default=None, description="M (3x3, SI, symmetric positive definite), only with model = 'custom'")
    damping_matrix: Matrix3 | None = Field(default=None, description="D (3x3, SI), only with model = 'custom'")
    mass: PositiveFloat = Field(default=NORTHERN_CLIPPER_MASS, description="vessel mass m (kg) of the bis normalization")
    length: PositiveFloat = Field(default=NORTHERN_CLIPPER_LENGTH, description="length L (m) of the bis normalization")

    @field_validator("model")
    @classmethod
    def _known_model(cls, value):
        if value not in (*VESSELS, "custom"):
            raise ValueError(f"must be one of {', '.join(repr(v) for v in (*VESSELS, 'custom'))}; got {value!r}")
        return value

    @field_validator("mass_matrix")
    @classmethod
    def _positive_definite(cls, value):
        from lookout._validation import symmetric_positive_definite

        if value is not None:
            try:
                symmetric_positive_definite("M", value, size=3)
            except ValueError as error:
                raise ValueError(str(error).replace("M must", "must", 1)) from None
        return value

    @field_validator("damping_matrix")
    @classmethod
    def _finite(cls, value):
        from lookout._validation import dissipative

        if value is not None and not all(math.isfinite(v) for row in value for v in row):
            raise ValueError("entries must be finite")
        if value is not None:
            try:
                dissipative("D", value)
            except ValueError as error:
                raise ValueError(str(error).replace("D must", "must", 1)) from None
        return value

    @model_validator(mode="after")
    def _matrices_with_custom(self):
        given = [name for name in ("mass_matrix", "damping_matrix") if getattr(self, name) is not None]
        if self.model == "custom" and len(given) != 2:
            missing = [name for name in ("mass_matrix", "damping_matrix") if name not in given]
            raise ValueError(f"model 'custom' needs {' and '.join(missing)}")
        if self.model != "custom" and given:
            raise ValueError(f"{' and '.join(given)} are taken only with model = 'custom' (model is {self.model!r})")
        return self

    def composition(self) -> dict:
        """The vessel as a composition's ``[plant.vessel]`` table."""
        if self.model == "custom":
            return {"kind": "custom", "mass_matrix": self.mass_matrix, "damping_matrix": self.damping_matrix}
        return {"kind": self.model}

    def dp_vessel(self):
        """The :class:`~lookout.models.vessel.DPVessel`."""
        from lookout.models.vessel import DPVessel, northern_clipper

        if self.model == "custom":
            return DPVessel(self.mass_matrix, self.damping_matrix)
        return northern_clipper()
