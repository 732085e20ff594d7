"""Measurement models: position and heading with noise, per-channel rates, dropouts.

Fossen & Strand (1999), eq. (12): ``y = eta + eta_w + d`` with zero-mean Gaussian
white measurement noise ``d``. The heading channel is wrapped to [-pi, pi), as a
gyro compass reports it.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.scipy.special
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout import _validation as check
from lookout._math import ssa
from lookout.models.vessel import VesselState


class PositionHeadingSensor(eqx.Module):
    """Position fixes (x, y) and heading, each channel with its own noise and rate.

    Between two samples of a channel the engine holds the last sample (zero-order
    hold); a dropped sample is NaN and makes the channel invalid until its next
    sample, during which the observer predicts without injection on that channel.

    Parameters
    ----------
    noise_std : array_like, shape (3,)
        Standard deviation of d per channel (m, m, rad), >= 0.
    sample_period : float or sequence of 3 floats
        Seconds between samples of each channel (static: fixes the loop structure).
    dropout_probability : float
        Probability that a sample of a channel is missing (0 <= p < 1).
    """

    noise_std: Array
    dropout_probability: Array
    sample_period: tuple[float, float, float] = eqx.field(static=True)
    noise_size: int = eqx.field(static=True, default=6)

    def __init__(self, noise_std=0.0, sample_period=1.0, dropout_probability=0.0):
        self.noise_std = jnp.asarray(check.vector("sensor noise_std", noise_std))
        self.dropout_probability = jnp.asarray(float(dropout_probability))
        self.sample_period = tuple(float(p) for p in check.vector("sensor sample_period", sample_period))

    def __check_init__(self):
        check.positive("sensor noise_std", self.noise_std, allow_zero=True)
        check.positive("sensor sample_period", np.asarray(self.sample_period))
        if check.is_concrete(self.dropout_probability):
            p = float(self.dropout_probability)
            if not 0.0 <= p < 1.0:
                raise ValueError(f"sensor dropout_probability must be in [0, 1); got {p}")

    def ideal(self, state: VesselState) -> Array:
        """Noise-free measurement eta + eta_w with wrapped heading."""
        y = state.eta + state.wave
        return y.at[2].set(ssa(y[2]))

    def measure(self, state: VesselState, noise: Array) -> Array:
        """One noisy sample of every channel; dropped channels are NaN.

        Parameters
        ----------
        state : VesselState
            Plant state at the sample time.
        noise : Array, shape (6,)
            Independent standard normal numbers: three for the measurement noise,
            three turned into uniforms (by the normal CDF) for the dropouts.
        """
        y = state.eta + state.wave + self.noise_std * noise[:3]
        y = y.at[2].set(ssa(y[2]))
        # Phi(n) < p, written as n < Phi^-1(p) (Phi increasing): one scalar inverse
        # instead of an erfc per channel and sample
        dropped = noise[3:] < jax.scipy.special.ndtri(self.dropout_probability)
        return jnp.where(dropped, jnp.nan, y)
