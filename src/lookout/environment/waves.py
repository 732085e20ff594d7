"""First-order wave-induced motion from the linear second-order wave model.

Fossen & Strand (1999), eqs. (10)–(11): per degree of freedom the wave-frequency
motion is white noise filtered by ``h(s) = sigma s / (s^2 + 2 zeta w0 s + w0^2)``,
realised with state ``xi = [xi1, xi2]`` and output ``eta_w = xi2`` (Gamma = [0 I]).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array

from lookout import _validation as check
from lookout.declare import NON_NEGATIVE, POSITIVE, Value, component


def stationary_std_per_intensity(peak_frequency: npt.ArrayLike, damping_ratio: npt.ArrayLike) -> np.ndarray | np.float64:
    """Stationary std of eta_w per unit sigma: 1 / sqrt(4 zeta w0).

    For ``xi1' = xi2, xi2' = -w0^2 xi1 - 2 zeta w0 xi2 + sigma w`` with unit white
    noise, the Lyapunov equation gives ``Var(xi2) = sigma^2 / (4 zeta w0)``.
    """
    return 1.0 / np.sqrt(4.0 * np.asarray(damping_ratio) * np.asarray(peak_frequency))


@component(
    "waves",
    "linear",
    summary="Linear second-order wave model in surge, sway and yaw.",
    build="from_amplitude",
    parameters=(
        Value("peak_frequency", "array", "Dominating wave frequency w0_i (rad/s).", shape="(3,)", range=POSITIVE),
        Value("damping_ratio", "array", "Relative damping zeta_i (1).", shape="(3,)", range=POSITIVE),
        Value("amplitude", "array", "Amplitude of the wave motion (m, m, rad), sigmas standard deviations.", shape="(3,)", range=NON_NEGATIVE),
        Value("sigmas", "float", "Standard deviations the amplitude stands for (1).", range=POSITIVE),
    ),
)
class LinearWaveModel(eqx.Module):
    """Linear second-order wave model in surge, sway and yaw.

    Fossen & Strand (1999), eqs. (10)–(11).

    Parameters
    ----------
    peak_frequency : array_like, shape (3,)
        Dominating wave frequency w0_i in rad/s (> 0).
    damping_ratio : array_like, shape (3,)
        Relative damping zeta_i (> 0).
    intensity : array_like, shape (3,)
        sigma_i, in m/sqrt(s) (surge, sway) and rad/sqrt(s) (yaw), >= 0.
    """

    peak_frequency: Array
    damping_ratio: Array
    intensity: Array

    def __init__(self, peak_frequency: npt.ArrayLike, damping_ratio: npt.ArrayLike, intensity: npt.ArrayLike = 0.0):
        self.peak_frequency = jnp.asarray(check.vector("wave peak_frequency", peak_frequency))
        self.damping_ratio = jnp.asarray(check.vector("wave damping_ratio", damping_ratio))
        self.intensity = jnp.asarray(check.vector("wave intensity", intensity))

    def __check_init__(self):
        check.positive("wave peak_frequency", self.peak_frequency)
        check.positive("wave damping_ratio", self.damping_ratio)
        check.positive("wave intensity", self.intensity, allow_zero=True)

    @classmethod
    def from_std(cls, peak_frequency: npt.ArrayLike, damping_ratio: npt.ArrayLike, std: npt.ArrayLike) -> LinearWaveModel:
        """Model whose wave-induced motion has stationary standard deviation ``std``."""
        peak_frequency = check.vector("wave peak_frequency", peak_frequency)
        damping_ratio = check.vector("wave damping_ratio", damping_ratio)
        stds = check.vector("wave std", std)
        check.positive("wave peak_frequency", peak_frequency)
        check.positive("wave damping_ratio", damping_ratio)
        check.positive("wave std", stds, allow_zero=True)
        return cls(peak_frequency, damping_ratio, stds / stationary_std_per_intensity(peak_frequency, damping_ratio))

    @classmethod
    def from_amplitude(
        cls, peak_frequency: npt.ArrayLike, damping_ratio: npt.ArrayLike, amplitude: npt.ArrayLike, *, sigmas: float = 3.0
    ) -> LinearWaveModel:
        """Model whose wave motion stays within ``amplitude`` except rarely.

        The amplitude is taken as ``sigmas`` stationary standard deviations (3 by
        default: a Gaussian motion exceeds it 0.27 % of the time). This is how
        lookout reads "amplitudes limited to 10 m, 10 m and 1.0 deg" in Fossen &
        Strand (1999), Section 6.1.

        Parameters
        ----------
        peak_frequency : array_like, shape (3,), positive
            Dominating wave frequency w0_i (rad/s).
        damping_ratio : array_like, shape (3,), positive
            Relative damping zeta_i (1).
        amplitude : array_like, shape (3,), non-negative
            Amplitude of the wave motion (m, m, rad), ``sigmas`` standard deviations.
        sigmas : float, positive
            Standard deviations the amplitude stands for (1).
        """
        if not sigmas > 0:
            raise check.ParameterError("sigmas", f"sigmas must be positive; got {sigmas}")
        amplitudes = check.vector("wave amplitude", amplitude)
        return cls.from_std(peak_frequency, damping_ratio, amplitudes / sigmas)

    @classmethod
    def from_significant_wave_height(
        cls, peak_frequency: npt.ArrayLike, damping_ratio: npt.ArrayLike, significant_height: npt.ArrayLike
    ) -> LinearWaveModel:
        """Model with significant height ``Hs = 4 std`` of the wave-induced motion per DOF."""
        heights = check.vector("significant_wave_height", significant_height)
        return cls.from_std(peak_frequency, damping_ratio, heights / 4.0)

    def stationary_std(self) -> Array:
        """Stationary standard deviation of eta_w (m, m, rad)."""
        return self.intensity / jnp.sqrt(4.0 * self.damping_ratio * self.peak_frequency)

    def derivative(self, wave_state: Array, noise: Array) -> Array:
        """xi' of eq. (11) for unit white noise ``noise``; ``wave_state`` is [xi1, xi2]."""
        xi1, xi2 = wave_state[:3], wave_state[3:]
        w0, zeta = self.peak_frequency, self.damping_ratio
        return jnp.concatenate([xi2, -(w0**2) * xi1 - 2.0 * zeta * w0 * xi2 + self.intensity * noise])
