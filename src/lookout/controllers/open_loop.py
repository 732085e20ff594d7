"""Open-loop inputs: forces that do not depend on the estimate."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from lookout import _validation as check


class SinusoidalThrust(eqx.Module):
    """tau_i(t) = amplitude_i sin(frequency_i t + phase_i), held over each sample period.

    Fossen & Strand (1999), eq. (61) uses amplitude 1000 (N, N, N m) and
    frequencies 0.05, 0.1, 0.07 rad/s; :meth:`fossen_strand_1999` builds it.

    Parameters
    ----------
    amplitude : array_like, shape (3,)
        N, N, N m.
    frequency : array_like, shape (3,)
        rad/s, >= 0.
    phase : array_like, shape (3,)
        rad.
    """

    amplitude: Array
    frequency: Array
    phase: Array

    def __init__(self, amplitude, frequency, phase=0.0):
        self.amplitude = jnp.asarray(check.vector("thrust amplitude", amplitude))
        self.frequency = jnp.asarray(check.vector("thrust frequency", frequency))
        self.phase = jnp.asarray(check.vector("thrust phase", phase))

    def __check_init__(self):
        check.finite("thrust amplitude", self.amplitude)
        check.positive("thrust frequency", self.frequency, allow_zero=True)
        check.finite("thrust phase", self.phase)

    @classmethod
    def fossen_strand_1999(cls) -> "SinusoidalThrust":
        """tau of Fossen & Strand (1999), eq. (61)."""
        return cls(1000.0, [0.05, 0.1, 0.07])

    def init(self):
        """No internal state."""
        return ()

    def step(self, control_state, t, estimate):
        """Return ``(control_state, tau)`` at time ``t``; the estimate is not used."""
        del estimate
        return control_state, self.amplitude * jnp.sin(self.frequency * t + self.phase)
