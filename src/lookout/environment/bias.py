"""Slowly varying environmental bias: first-order Gauss–Markov process.

Fossen & Strand (1999), eq. (7): ``b' = -T^{-1} b + Psi n`` with ``T`` a diagonal
matrix of positive time constants, ``Psi`` a diagonal noise gain and ``n`` unit
zero-mean Gaussian white noise.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array

from lookout import _validation as check
from lookout.declare import NON_NEGATIVE, POSITIVE, Value, component


@component(
    "bias",
    "gauss-markov",
    summary="Earth-fixed bias forces and moment b = [X, Y, N] driven by white noise.",
    build="from_stationary_std",
    parameters=(
        Value("time_constant", "array", "Time constants T_i (s) of eq. (7).", shape="(3,)", range=POSITIVE),
        Value("std", "array", "Stationary standard deviation (N, N, N m).", shape="(3,)", range=NON_NEGATIVE),
    ),
)
class GaussMarkovBias(eqx.Module):
    """Earth-fixed bias forces and moment b = [X, Y, N] driven by white noise.

    Fossen & Strand (1999), eq. (7). The stationary standard deviation of each
    component is ``noise_gain * sqrt(time_constant / 2)``.

    Parameters
    ----------
    time_constant : array_like, shape (3,)
        Bias time constants T_i in seconds (> 0).
    noise_gain : array_like, shape (3,)
        Diagonal of Psi, in N/sqrt(s) (surge, sway) and N m/sqrt(s) (yaw), >= 0.
    """

    time_constant: Array
    noise_gain: Array

    def __init__(self, time_constant: npt.ArrayLike, noise_gain: npt.ArrayLike = 0.0):
        self.time_constant = jnp.asarray(check.vector("bias time_constant", time_constant))
        self.noise_gain = jnp.asarray(check.vector("bias noise_gain", noise_gain))

    def __check_init__(self):
        check.positive("bias time_constant", self.time_constant)
        check.positive("bias noise_gain", self.noise_gain, allow_zero=True)

    @classmethod
    def from_stationary_std(cls, time_constant: npt.ArrayLike, std: npt.ArrayLike) -> GaussMarkovBias:
        """Build the process whose stationary standard deviation is ``std``.

        Parameters
        ----------
        time_constant : array_like, shape (3,), positive
            Time constants T_i (s) of eq. (7).
        std : array_like, shape (3,), non-negative
            Stationary standard deviation (N, N, N m).
        """
        time_constants = check.vector("bias time_constant", time_constant)
        stds = check.vector("bias std", std)
        check.positive("bias time_constant", time_constants)
        check.positive("bias std", stds, allow_zero=True)
        return cls(time_constants, stds * np.sqrt(2.0 / time_constants))

    def stationary_std(self) -> Array:
        """Stationary standard deviation of each component (N, N, N m)."""
        return self.noise_gain * jnp.sqrt(self.time_constant / 2.0)

    def derivative(self, bias: Array, noise: Array) -> Array:
        """b' of eq. (7) for unit white noise ``noise`` (held over the integration step)."""
        return -bias / self.time_constant + self.noise_gain * noise
