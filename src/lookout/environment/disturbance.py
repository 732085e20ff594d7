"""Unmodelled body-fixed forces: the model error E_nu w_nu of Kim (2002), eq. (1).

Kim (2002) writes the vessel as M nu' + D nu = tau + J^T(psi) b + E_nu w_nu, where
E_nu w_nu lumps "uncertainties and disturbances in the ship dynamics" that neither
the bias model nor the observer's M and D describe. lookout's plant adds it as a
body-fixed force and moment::

    f(t) = constant + amplitude sin(2 pi t / period) + white_std w(t)

with w unit white noise (held over a plant step, like the bias noise). A constant
body-fixed force is not absorbed by the Earth-fixed bias estimate when the vessel
turns; the sinusoid is the "slowly varying" part; the white part is Kim's Gaussian
E_nu w_nu.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.declare import Value, component


@component(
    "disturbance",
    "body-force",
    summary="A body-fixed force and moment [X, Y, N] (N, N, N m) added to the vessel's dynamics.",
    parameters=(
        Value("constant", "array", "Constant part (N, N, N m).", shape="(3,)"),
        Value("amplitude", "array", "Amplitude of the sinusoid (N, N, N m), >= 0.", shape="(3,)"),
        Value("period", "float", "Period of the sinusoid (s), > 0."),
        Value(
            "white_std",
            "array",
            "Intensity of the white part E_nu (N sqrt(s), N sqrt(s), N m sqrt(s)), >= 0; non-zero adds three noise channels to the plant.",
            shape="(3,)",
        ),
    ),
)
class BodyDisturbance(eqx.Module):
    """A body-fixed force and moment [X, Y, N] (N, N, N m) added to the vessel's dynamics.

    Parameters
    ----------
    constant : array_like, shape (3,)
        Constant part (N, N, N m).
    amplitude : array_like, shape (3,)
        Amplitude of the sinusoid (N, N, N m), >= 0.
    period : float
        Period of the sinusoid (s), > 0.
    white_std : array_like, shape (3,)
        Intensity of the white part E_nu (N sqrt(s), N sqrt(s), N m sqrt(s)), >= 0;
        non-zero adds three noise channels to the plant.
    """

    constant: Array
    amplitude: Array
    period: Array
    white_std: Array
    white: bool = eqx.field(static=True)

    def __init__(self, constant: npt.ArrayLike = 0.0, amplitude: npt.ArrayLike = 0.0, period: ArrayLike = 600.0, white_std: npt.ArrayLike = 0.0):
        self.constant = jnp.asarray(check.vector("disturbance constant", constant))
        self.amplitude = jnp.asarray(check.vector("disturbance amplitude", amplitude))
        self.period = jnp.asarray(period, dtype=float)
        white_std = check.vector("disturbance white_std", white_std)
        self.white_std = jnp.asarray(white_std)
        # a traced intensity (built under vmap) may be non-zero: keep the channels
        self.white = bool(np.any(white_std != 0)) if check.is_concrete(white_std) else True

    def __check_init__(self):
        check.finite("disturbance constant", self.constant)
        check.positive("disturbance amplitude", self.amplitude, allow_zero=True)
        check.positive("disturbance period", self.period)
        check.positive("disturbance white_std", self.white_std, allow_zero=True)

    @property
    def noise_size(self) -> int:
        """White-noise channels the disturbance draws (0 or 3)."""
        return 3 if self.white else 0

    def force(self, t: ArrayLike, noise: Array) -> Array:
        """f(t) for the unit white noise ``noise`` (shape (noise_size,))."""
        value = self.constant + self.amplitude * jnp.sin(2.0 * math.pi * t / self.period)
        if self.white:
            value = value + self.white_std * noise
        return value

    def describe(self) -> dict:
        """The disturbance as plain numbers (for results' attributes and summaries)."""
        return {
            "constant": [float(v) for v in self.constant],
            "amplitude": [float(v) for v in self.amplitude],
            "period": float(self.period),
            "white_std": [float(v) for v in self.white_std],
        }
