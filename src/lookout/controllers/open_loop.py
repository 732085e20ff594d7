"""Open-loop inputs: controllers that do not look at the measurement or the estimate."""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import Controller
from lookout.declare import Context, Value, component


@component(
    "controller",
    "sinusoidal",
    summary="u_i(t) = offset_i + amplitude_i sin(frequency_i t + phase_i), held over each sample.",
    parameters=(
        Value("amplitude", "array", "In the units of the plant's input.", shape="(n,) or scalar"),
        Value("frequency", "array", "rad/s, >= 0; broadcast to n."),
        Value("phase", "array", "rad; broadcast to n."),
        Value("offset", "array", "Constant part; broadcast to n."),
        Context("size", "n, when every argument is a scalar (default: the longest argument's length)."),
    ),
)
@final
class SinusoidalInput(Controller):
    """u_i(t) = offset_i + amplitude_i sin(frequency_i t + phase_i), held over each sample.

    Fossen & Strand (1999), eq. (61) uses amplitude 1000 (N, N, N m) and
    frequencies 0.05, 0.1, 0.07 rad/s (its reproduction's composition); a constant
    input is ``SinusoidalInput(0.0, 0.0, offset=u)`` (:meth:`constant`).

    Parameters
    ----------
    amplitude : array_like, shape (n,) or scalar
        In the units of the plant's input.
    frequency : array_like
        rad/s, >= 0; broadcast to n.
    phase : array_like
        rad; broadcast to n.
    offset : array_like
        Constant part; broadcast to n.
    size : int, optional
        n, when every argument is a scalar (default: the longest argument's length).
    """

    amplitude: Array
    frequency: Array
    phase: Array
    offset: Array

    def __init__(
        self, amplitude: npt.ArrayLike, frequency: npt.ArrayLike, phase: npt.ArrayLike = 0.0, offset: npt.ArrayLike = 0.0, *, size: int | None = None
    ):
        if size is None:
            size = max(int(jnp.size(jnp.asarray(value))) for value in (amplitude, frequency, phase, offset))
        self.amplitude = jnp.asarray(check.vector("input amplitude", amplitude, size))
        self.frequency = jnp.asarray(check.vector("input frequency", frequency, size))
        self.phase = jnp.asarray(check.vector("input phase", phase, size))
        self.offset = jnp.asarray(check.vector("input offset", offset, size))

    def __check_init__(self):
        check.finite("input amplitude", self.amplitude)
        check.positive("input frequency", self.frequency, allow_zero=True)
        check.finite("input phase", self.phase)
        check.finite("input offset", self.offset)

    @classmethod
    def constant(cls, value: npt.ArrayLike) -> SinusoidalInput:
        """The constant input ``value``."""
        value = jnp.atleast_1d(jnp.asarray(value, dtype=float))
        return cls(0.0, 0.0, offset=value, size=value.shape[0])

    #: an open-loop input reads nothing
    estimate_needs = measurement_needs = reference_needs = property(lambda self: ())

    def init(self) -> tuple[()]:
        """No internal state."""
        return ()

    def step(
        self, control_state: tuple[()], t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[tuple[()], Array]:
        """``(control_state, u(t))``; measurement, estimate and reference unused."""
        del y, estimate, reference, dt
        return control_state, self.offset + self.amplitude * jnp.sin(self.frequency * t + self.phase)


@component(
    "controller",
    "none",
    summary="A zero input of size entries: the plant runs unforced.",
    parameters=(Context("size", "Length of the plant's input vector."),),
)
@final
class NoControl(Controller):
    """A zero input of ``size`` entries: the plant runs unforced.

    Parameters
    ----------
    size : int
        Length of the plant's input vector.
    """

    size: int = eqx.field(static=True)

    estimate_needs = measurement_needs = reference_needs = property(lambda self: ())

    def init(self) -> tuple[()]:
        """No internal state."""
        return ()

    def step(
        self, control_state: tuple[()], t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[tuple[()], Array]:
        """``(control_state, zeros)``."""
        del t, y, estimate, reference, dt
        return control_state, jnp.zeros(self.size)
