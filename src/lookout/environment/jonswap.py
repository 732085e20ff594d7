"""Long-crested irregular waves from a JONSWAP spectrum, and the first-order motion they give a small hull.

Spectrum
--------
The JONSWAP shape of the ITTC form in Fossen, *Handbook of Marine Craft
Hydrodynamics and Motion Control* (2011), eqs. (8.56)–(8.58), normalized so that
m0 = Hs^2/16 for every gamma::

    S(w)  = Hs^2 / (16 J(gamma)) * T1 s(w T1)                          (m^2 s)
    s(x)  = x^-5 exp(-944 / x^4) gamma^Y(x)
    Y(x)  = exp(-((0.191 x - 1) / (sqrt(2) sigma))^2)
    sigma = 0.07 for x <= 5.24, 0.09 otherwise
    J     = integral over x > 0 of s(x) dx
          = 1 / (4 * 944) + integral of x^-5 exp(-944 / x^4) (gamma^Y(x) - 1) dx

with Hs the significant wave height, T1 the period parameter (``mean_period``) and
gamma the peak enhancement factor. Substituting x = w T1 shows that m0 = Hs^2/16
exactly and that the shape depends on T1 only through w T1. Choices and checks:

- **Normalization.** The ITTC form writes the constant 155 in place of 1 / (16 J),
  a value calibrated at gamma = 3.3 only: its m0 is 0.657, 1.001, 1.220 and 1.460
  Hs^2/16 at gamma = 1, 3.3, 5 and 7. DNV-RP-C205 (2010), sec. 3.5.5, normalizes
  its form (below) by the factor A_gamma = 1 - 0.287 ln gamma, a fit: by quadrature
  (tests) its m0 is 1.0000, 1.0024, 1.0000 and 0.9825 Hs^2/16 at gamma = 1, 3.3, 5
  and 7, and 0.93 Hs^2/16 at 10. lookout computes J instead: the Pierson–Moskowitz
  part 1 / (4 * 944) exactly, and the gamma^Y - 1 bump, which is below 1e-25 of J
  outside 2 <= x <= 11, by Gauss–Legendre quadrature (24 nodes on each of [2, 4.2],
  [4.2, 5.24], [5.24, 6.6], [6.6, 11], split where sigma changes). It is plain
  array arithmetic on fixed nodes, so gamma may be traced (``jit``, ``vmap``,
  gradients), and it agrees with scipy ``quad`` to 2e-15 of J for 1 <= gamma <= 100.
  Chosen over A_gamma so that Hs is 4 sqrt(m0) for every gamma to rounding rather
  than to 2 %, for 96 exponentials per call. The tests integrate
  :func:`jonswap_spectrum` by scipy ``quad``: m0 = Hs^2/16 to 1e-12 at gamma = 1,
  3.3, 5 and 7 (measured: within 7e-16). At gamma = 3.3 the spectrum is
  0.11 % below the ITTC form's. Realizations (:class:`JonswapWaves`) take only the
  shape's relative values and rescale to 4 sqrt(m0) = Hs (below), so the
  normalization does not touch them.
- **Period convention.** ``mean_period`` T1 fixes the peak: S peaks at
  w T1 = 5.24 for every gamma (measured: within 0.08 %), so Tp = T1 / 0.834 and
  wp = 2 pi / Tp = 5.240 / T1. It is the spectrum's mean period 2 pi m0 / m1 only
  near gamma = 3.3, where the ITTC form was calibrated: by quadrature (tests),
  2 pi m0 / m1 = 0.9250 T1 at gamma = 1 (Pierson–Moskowitz: 2 pi / (944^(1/4)
  Gamma(3/4)), exactly), 1.0003 T1 at 3.3, 1.0292 T1 at 5 and 1.0522 T1 at 7. For a
  sea given by its mean period at another gamma, pass that period divided by the
  ratio at its gamma as ``mean_period``; for a sea given by its zero-crossing period
  Tz, ``mean_period = 1.073 Tz``; by its peak period Tp, ``0.834 Tp``
  (:mod:`lookout.papers.wondergem_2009` says how it reads its paper's "time mean
  period").
- **Cross-check.** DNV-RP-C205 writes the spectrum as
  ``A_gamma (5/16) Hs^2 wp^4 w^-5 exp(-1.25 (wp/w)^4)
  gamma^exp(-(w - wp)^2 / (2 sigma^2 wp^2))``. With wp = 5.24 / T1 the shapes
  agree: A_gamma (5/16) wp^4 = 154.87 / T1^4 against 1 / (16 J) = 154.82 / T1^4 at
  gamma = 3.3, 1.25 wp^4 = 942.4 / T1^4 against 944 / T1^4, and the peak shapes
  differ only in 1/0.191 = 5.236 against 5.240; the tests find the two within 0.6 %
  of the peak value everywhere at gamma = 3.3.
- S is one-sided: 0 for w <= 0. The factor w^-5 exp(-944 / (T1^4 w^4)) is
  evaluated as ``exp(-5 ln w - 944 / (T1^4 w^4))``, and S is set to 0 for
  w T1 <= 0.5, where the formula is below exp(-15000) and rounds to 0 anyway:
  w -> 0 gives 0 and a zero gradient, not 0 * inf = NaN.

Realization
-----------
N components on the frequency band [w_lo, w_hi], split into N equal bins of width
dw::

    zeta(t, x, y) = sum_k A_k cos(w_k t - k_k (x cos chi + y sin chi) + phi_k)

with deep-water wavenumbers k_k = w_k^2 / g, waves travelling in direction chi
(Earth frame, x north, y east). ``realize(key)`` draws each w_k uniformly within
its bin (a uniform grid is periodic: with dw = 0.2 rad/s it repeats every
2 pi / dw = 31 s) and phi_k uniformly in [0, 2 pi). Amplitudes are
A_k = sqrt(2 S(w_k) dw), then rescaled so that sum A_k^2 / 2 = Hs^2 / 16 exactly:
the realization's 4 sqrt(m0) is Hs whatever the band and N (the rescaling puts the
1 % of m0 outside the default band back inside it).

Default band: (0.5 wp, 3 wp). Below 0.5 wp the spectrum is under 1e-7 of its
peak and holds 1e-9 of m0; above 3 wp lies 1.0 % of m0 (gamma = 3.3), and there the
hull-averaging gain below is under 0.04 (k L / 2 > 28 for the Cybership II at
Tp = 0.9 s), so those components barely move the ship. N = 64 components give
dw = 0.27 rad/s at T1 = 0.75 s.

Motion of the hull
------------------
With no response amplitude operator of a hull at hand, lookout's crude, documented
choice, applied to the measurement as y = eta + eta_w:

- Surge/sway: the horizontal orbital displacement of the surface particles. Deep
  water, linear theory: for ``zeta = A cos(theta)``, theta = w t - k s + phi, the
  particle velocity along chi is ``u = w A cos(theta)`` (= w zeta: forward under a
  crest, which moves along +chi) and its displacement is ``A sin(theta)``, so
  ``x_w, y_w = sum_k G_k A_k sin(theta_k) (cos chi, sin chi)``.
- G_k = |sinc(k_k L / 2)| = |sin(k_k L / 2) / (k_k L / 2)|, the magnitude of the
  average of a component over a hull of length L lying along the wave direction.
  The exact average has the sign of sinc(k L/2), which flips the phase of some
  components shorter than the hull (L/2 < wavelength < L, ...); the magnitude is taken
  (as an RAO's amplitude is), which changes phases but no statistics. At the peak of
  the basin sea of Wondergem et al. (2009) (Hs = 0.01 m, T1 = 0.75 s, gamma = 3.3)
  the wavelength (1.26 m) is about the length of Cybership II (1.255 m), so G is
  small there (0.006) and the motion comes mostly from the longer waves on the low
  side of the peak.
- Yaw: ``psi_w = yaw_gain * sum_k G_k A_k k_k sin(theta_k)``, yaw_gain times the
  hull-averaged surface slope d zeta / ds along chi (rad per unit slope). A
  long-crested sea exerts no yaw moment on a hull that is aligned with it, so any
  such term is a stand-in; the default 0.1 gives a yaw motion of about 0.013 deg
  std for that sea (and surge 0.4 mm std for waves along x, against an
  elevation std of Hs/4 = 2.5 mm: the hull gain removes most of the peak).

``rate(t, position, velocity)`` is the exact time derivative of
``motion(t, position(t))`` for a ship moving with Earth-frame velocity
``velocity``: each phase changes at the encounter frequency w_k - k_k (v . e_chi)
(the Doppler shift of the ship's own motion).

Phases are evaluated with :func:`lookout._math.sincos`, accurate for
|w_k t| < 1.6e6 rad, i.e. t < 7.6e4 s for the default band at T1 = 0.75 s.
lookout enables float64; everything here assumes it.
"""

from __future__ import annotations

import math
import operator
from typing import final, overload

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import sincos
from lookout.declare import NON_NEGATIVE, Value, component

#: T1 / Tp (Fossen 2011, eq. 8.58): T1 is the mean period of the gamma = 3.3 spectrum; the
#: period parameter puts the peak at wp = 2 pi 0.834 / T1 for every gamma.
MEAN_TO_PEAK_PERIOD = 0.834
#: The default frequency band, in multiples of the peak frequency.
DEFAULT_BAND = (0.5, 3.0)


def _namespace(*values):
    """jax.numpy when any value is a JAX array or tracer, numpy otherwise."""
    return jnp if any(isinstance(v, jax.Array) for v in values) else np


@overload
def peak_frequency(mean_period: float) -> float: ...
@overload
def peak_frequency(mean_period: Array) -> Array: ...
@overload
def peak_frequency(mean_period: np.ndarray) -> np.ndarray: ...
def peak_frequency(mean_period: float | Array | np.ndarray) -> float | Array | np.ndarray:
    """Peak frequency wp = 2 pi / Tp = 2 pi 0.834 / T1 (rad/s) for mean period T1 (s)."""
    return 2.0 * math.pi * MEAN_TO_PEAK_PERIOD / mean_period


def jonswap_spectrum(
    omega: npt.ArrayLike, significant_height: ArrayLike, mean_period: ArrayLike, peak_enhancement: ArrayLike = 3.3
) -> Array | np.ndarray:
    """JONSWAP wave spectrum S(w) in m^2 s, the ITTC shape (Fossen 2011, eqs. 8.56–8.58)
    normalized to m0 = Hs^2/16 for every gamma (module docstring).

    Parameters
    ----------
    omega : array_like
        Wave frequencies (rad/s), any shape; S = 0 for omega <= 0.5 / T1 (the
        formula is below exp(-15000) there).
    significant_height : float
        Hs (m): m0 = Hs^2/16 for every gamma.
    mean_period : float
        T1 (s), the ITTC form's period: the peak is at wp = 5.24 / T1 (Tp = T1 / 0.834)
        for every gamma; 2 pi m0 / m1 equals T1 only near gamma = 3.3 (0.925 T1 at
        gamma = 1, 1.052 T1 at gamma = 7; module docstring).
    peak_enhancement : float
        gamma (1: Pierson–Moskowitz); may be a traced array.

    Returns
    -------
    array
        S(omega), a NumPy array for NumPy inputs and a JAX array otherwise.
    """
    xp = _namespace(omega, significant_height, mean_period, peak_enhancement)
    if xp is np:
        # w^4 underflows to 0 for w < 1e-77: exp(-inf) = 0 is the intended limit
        with np.errstate(divide="ignore", over="ignore"):
            return _jonswap(np, omega, significant_height, mean_period, peak_enhancement)
    return _jonswap(jnp, omega, significant_height, mean_period, peak_enhancement)


def _jonswap_shape(xp, omega, mean_period, peak_enhancement):
    """T1^-4 w^-5 exp(-944 / (T1^4 w^4)) gamma^Y = T1 s(w T1), and 0 for w T1 <= 0.5."""
    w = xp.asarray(omega, dtype=float)
    t1 = mean_period
    # below w T1 = 0.5 the formula is under exp(-15000): exactly 0 in float64 (see module docstring)
    positive = w * t1 > 0.5
    w_safe = xp.where(positive, w, 1.0 / t1)
    t1_4 = t1**4
    sigma = xp.where(w_safe <= 5.24 / t1, 0.07, 0.09)
    y = xp.exp(-(((0.191 * w_safe * t1 - 1.0) / (math.sqrt(2.0) * sigma)) ** 2))
    shape = xp.exp(-5.0 * xp.log(w_safe) - 944.0 / (t1_4 * w_safe**4) + y * xp.log(peak_enhancement))
    return xp.where(positive, shape / t1_4, 0.0)


def _bump_nodes():
    """Gauss–Legendre weights times x^-5 exp(-944 / x^4), and Y(x), at the nodes of the pieces
    of 2 <= x <= 11 where gamma^Y - 1 lives (module docstring)."""
    unit_nodes, unit_weights = np.polynomial.legendre.leggauss(24)
    edges = (2.0, 4.2, 5.24, 6.6, 11.0)  # 5.24: where sigma changes
    x = np.concatenate([0.5 * (b - a) * unit_nodes + 0.5 * (b + a) for a, b in zip(edges[:-1], edges[1:])])
    weights = np.concatenate([0.5 * (b - a) * unit_weights for a, b in zip(edges[:-1], edges[1:])])
    sigma = np.where(x <= 5.24, 0.07, 0.09)
    y = np.exp(-(((0.191 * x - 1.0) / (math.sqrt(2.0) * sigma)) ** 2))
    return weights * x**-5.0 * np.exp(-944.0 / x**4), y


_BUMP_WEIGHTS, _BUMP_Y = _bump_nodes()


def _shape_integral(xp, peak_enhancement):
    """J(gamma) = integral of s(x) dx: Pierson–Moskowitz 1 / (4 * 944) exactly, plus the
    gamma^Y - 1 bump by Gauss–Legendre (module docstring; any gamma > 0, traced or not)."""
    bump = xp.expm1(_BUMP_Y * xp.log(peak_enhancement))
    return 1.0 / (4.0 * 944.0) + xp.sum(_BUMP_WEIGHTS * bump)


def _jonswap(xp, omega, significant_height, mean_period, peak_enhancement):
    normalization = significant_height**2 / (16.0 * _shape_integral(xp, peak_enhancement))
    return normalization * _jonswap_shape(xp, omega, mean_period, peak_enhancement)


def spectral_moment(n: float, significant_height: float, mean_period: float, peak_enhancement: float = 3.3) -> float:
    """m_n = integral over w > 0 of w^n S(w) dw, by adaptive quadrature (scipy ``quad``).

    Parameters
    ----------
    n : float
        Order, < 4 (the w^-5 tail makes m_n diverge for n >= 4).
    significant_height, mean_period, peak_enhancement : float
        As for :func:`jonswap_spectrum`.

    Returns
    -------
    float
        m_n in m^2 (rad/s)^n.
    """
    from scipy.integrate import quad

    if not n < 4:
        raise check.ParameterError("spectral_moment", f"spectral_moment n must be < 4 (m_n diverges for n >= 4); got {n}")
    hs, t1, gamma = float(significant_height), float(mean_period), float(peak_enhancement)
    wp = peak_frequency(t1)

    def integrand(w):
        return w**n * float(jonswap_spectrum(np.float64(w), hs, t1, gamma))

    # split around the narrow gamma^Y bump and where sigma (and so S) jumps, at w T1 = 5.24
    # (within 0.004 % of wp; an unsplit jump costs quad 1e-8 of m0)
    edges = (0.0, 0.8 * wp, 5.24 / t1, 1.25 * wp, 3.0 * wp)
    total = sum(quad(integrand, a, b, limit=200, epsabs=0.0, epsrel=1e-12)[0] for a, b in zip(edges[:-1], edges[1:]))
    return total + quad(integrand, edges[-1], np.inf, limit=200, epsabs=0.0, epsrel=1e-12)[0]


def _scalar(name: str, value) -> Array | np.ndarray:
    """A float scalar (a NumPy one when concrete), or a one-line ValueError naming ``name``."""
    array: Array | np.ndarray
    if check.is_concrete(value):
        array = np.asarray(value, dtype=float)
        if array.ndim != 0:
            raise check.ParameterError(check.key(name), f"{name} must be a scalar; got shape {array.shape}")
        check.finite(name, array)
    else:
        array = jnp.asarray(value, dtype=float)
        if array.ndim != 0:
            raise check.ParameterError(check.key(name), f"{name} must be a scalar; got shape {array.shape}")
    return array


def _components(value) -> int:
    if isinstance(value, bool):
        raise check.ParameterError("jonswap", f"jonswap components must be an integer >= 1; got {value!r}")
    try:
        count = operator.index(value)
    except TypeError:
        raise check.ParameterError("jonswap", f"jonswap components must be an integer >= 1; got {value!r}") from None
    if count < 1:
        raise check.ParameterError("jonswap", f"jonswap components must be an integer >= 1; got {count}")
    return count


def _bin_frequencies(xp, band, count: int, position_in_bin):
    """w_k = w_lo + (k + u_k) dw, dw = (w_hi - w_lo) / count, for u_k in [0, 1) (0.5: bin centres)."""
    width = (band[1] - band[0]) / count
    return band[0] + (xp.arange(count) + position_in_bin) * width


def _components_at(xp, frequencies, significant_height, mean_period, peak_enhancement, gravity, hull_length):
    """(w_k, A_k, k_k, G_k): amplitudes sqrt(2 S(w_k) dw) rescaled to sum A^2/2 = Hs^2/16."""
    # 2 S(w_k) dw as shares of their sum (S's normalization and 2 dw cancel, so the shape is
    # enough): A_k = Hs/4 sqrt(2 share_k) gives sum A^2/2 = Hs^2/16 for any Hs, and zeros
    # (not 0/0) for Hs = 0
    energy = _jonswap_shape(xp, frequencies, mean_period, peak_enhancement)
    share = energy / xp.sum(energy)
    amplitudes = 0.25 * significant_height * xp.sqrt(2.0 * share)
    wavenumbers = frequencies**2 / gravity
    # sinc(x) is sin(pi x) / (pi x) in both NumPy and JAX, 1 at x = 0
    hull_gains = xp.abs(xp.sinc(wavenumbers * hull_length / (2.0 * math.pi)))
    return frequencies, amplitudes, wavenumbers, hull_gains


@component(
    "waves",
    "jonswap",
    summary="Long-crested JONSWAP waves: surface elevation and first-order motion of a small hull.",
    parameters=(
        Value("significant_height", "float", "Hs (m), >= 0 (0: no waves)."),
        Value(
            "mean_period",
            "float",
            "T1 (s), > 0, the spectrum's period parameter: the peak period is T1 / 0.834 for every gamma; T1 is the mean period 2 pi m0 / m1 near gamma = 3.3 only (module docstring).",
        ),
        Value("peak_enhancement", "float", "gamma, >= 1."),
        Value("direction", "float", "chi (rad): the waves travel along (cos chi, sin chi) in the Earth frame (x north, y east)."),
        Value("components", "int", "Number of frequency components N (static), >= 1."),
        Value("band", "array", "(w_lo, w_hi) in rad/s, 0 < w_lo < w_hi; default (0.5 wp, 3 wp).", shape="(2,)"),
        Value(
            "hull_length",
            "float",
            "L (m), the length of the hull the waves move, for the averaging gain |sinc(k L / 2)| (0: no averaging); no default, since it is the vessel's (Cybership II's is 1.255 m, lookout.models.cybership.CYBERSHIP_LENGTH).",
            range=NON_NEGATIVE,
        ),
        Value("yaw_gain", "float", "Yaw motion per unit hull-averaged wave slope (rad), >= 0."),
        Value("gravity", "float", "g (m/s^2), > 0."),
    ),
)
@final
class JonswapWaves(eqx.Module):
    """Long-crested JONSWAP waves: surface elevation and first-order motion of a small hull.

    Built unrealized (bin-centre frequencies, zero phases); :meth:`realize` draws a
    realization from a JAX key. See the module docstring for the formulas and the
    choices.

    Parameters
    ----------
    significant_height : float
        Hs (m), >= 0 (0: no waves).
    mean_period : float
        T1 (s), > 0, the spectrum's period parameter: the peak period is T1 / 0.834 for
        every gamma; T1 is the mean period 2 pi m0 / m1 near gamma = 3.3 only (module
        docstring).
    peak_enhancement : float
        gamma, >= 1.
    direction : float
        chi (rad): the waves travel along (cos chi, sin chi) in the Earth frame
        (x north, y east).
    components : int
        Number of frequency components N (static), >= 1.
    band : pair of floats, optional
        (w_lo, w_hi) in rad/s, 0 < w_lo < w_hi; default (0.5 wp, 3 wp).
    hull_length : float, non-negative
        L (m), the length of the hull the waves move, for the averaging gain |sinc(k L / 2)|
        (0: no averaging); no default, since it is the vessel's (Cybership II's is 1.255 m,
        :data:`lookout.models.cybership.CYBERSHIP_LENGTH`).
    yaw_gain : float
        Yaw motion per unit hull-averaged wave slope (rad), >= 0.
    gravity : float
        g (m/s^2), > 0.

    Attributes
    ----------
    frequencies, amplitudes, phases, wavenumbers, hull_gains : Array, shape (N,)
        w_k (rad/s), A_k (m), phi_k (rad), k_k = w_k^2 / g (rad/m) and G_k.
    """

    significant_height: Array
    mean_period: Array
    peak_enhancement: Array
    direction: Array
    band: Array
    hull_length: Array
    yaw_gain: Array
    gravity: Array
    frequencies: Array
    amplitudes: Array
    phases: Array
    wavenumbers: Array
    hull_gains: Array
    components: int = eqx.field(static=True)

    def __init__(
        self,
        significant_height: ArrayLike,
        mean_period: ArrayLike,
        peak_enhancement: ArrayLike = 3.3,
        direction: ArrayLike = 0.0,
        components: int = 64,
        band: npt.ArrayLike | None = None,
        *,
        hull_length: ArrayLike,
        yaw_gain: ArrayLike = 0.1,
        gravity: ArrayLike = 9.81,
    ):
        hs = _scalar("jonswap significant_height", significant_height)
        t1 = _scalar("jonswap mean_period", mean_period)
        gamma = _scalar("jonswap peak_enhancement", peak_enhancement)
        chi = _scalar("jonswap direction", direction)
        length = _scalar("jonswap hull_length", hull_length)
        gain = _scalar("jonswap yaw_gain", yaw_gain)
        g = _scalar("jonswap gravity", gravity)
        check.positive("jonswap significant_height", hs, allow_zero=True)
        check.positive("jonswap mean_period", t1)
        if check.is_concrete(gamma) and not float(gamma) >= 1.0:
            raise check.ParameterError("jonswap", f"jonswap peak_enhancement must be >= 1; got {float(gamma)}")
        check.positive("jonswap hull_length", length, allow_zero=True)
        check.positive("jonswap yaw_gain", gain, allow_zero=True)
        check.positive("jonswap gravity", g)
        self.components = _components(components)

        if band is None:
            band = [DEFAULT_BAND[0] * peak_frequency(t1), DEFAULT_BAND[1] * peak_frequency(t1)]
        if check.is_concrete(band):
            band = np.asarray(band, dtype=float)
            if band.shape != (2,):
                raise check.ParameterError("jonswap", f"jonswap band must be a pair (low, high) in rad/s; got shape {band.shape}")
            check.finite("jonswap band", band)
            if not 0.0 < band[0] < band[1]:
                raise check.ParameterError("jonswap", f"jonswap band must satisfy 0 < low < high; got {band.tolist()}")
        else:
            band = jnp.asarray(band, dtype=float)  # a traced band, or a default built from a traced T1
            if band.shape != (2,):
                raise check.ParameterError("jonswap", f"jonswap band must be a pair (low, high) in rad/s; got shape {band.shape}")

        # concrete parameters (the usual case): the unrealized components in NumPy, which
        # costs no XLA compilation; traced ones (built inside jit or vmap): in jax.numpy
        concrete = all(check.is_concrete(v) for v in (hs, t1, gamma, band, length, g))
        xp = np if concrete else jnp
        centres = _bin_frequencies(xp, band, self.components, 0.5)
        if concrete and not np.sum(jonswap_spectrum(centres, 1.0, t1, gamma)) > 0:
            raise check.ParameterError("jonswap", f"jonswap band holds no wave energy (S underflows on it); got {band.tolist()}")
        fields = _components_at(xp, centres, hs, t1, gamma, g, length)
        self.frequencies, self.amplitudes, self.wavenumbers, self.hull_gains = (jnp.asarray(f, dtype=float) for f in fields)
        self.phases = jnp.zeros(self.components)
        self.band = jnp.asarray(band, dtype=float)
        self.significant_height = jnp.asarray(hs)
        self.mean_period = jnp.asarray(t1)
        self.peak_enhancement = jnp.asarray(gamma)
        self.direction = jnp.asarray(chi)
        self.hull_length = jnp.asarray(length)
        self.yaw_gain = jnp.asarray(gain)
        self.gravity = jnp.asarray(g)

    def realize(self, key: Array) -> JonswapWaves:
        """A realization drawn from ``key``: frequencies jittered within their bins, random phases.

        Same key, same realization bit for bit; works under ``jit`` and ``vmap``.

        Parameters
        ----------
        key : Array
            A JAX PRNG key (typed or raw uint32).

        Returns
        -------
        JonswapWaves
            A copy with new frequencies, amplitudes, phases, wavenumbers and hull gains.
        """
        jitter_key, phase_key = jax.random.split(key)
        jitter = jax.random.uniform(jitter_key, (self.components,), dtype=float)
        phases = jax.random.uniform(phase_key, (self.components,), dtype=float, minval=0.0, maxval=2.0 * jnp.pi)
        frequencies = _bin_frequencies(jnp, self.band, self.components, jitter)
        fields = _components_at(
            jnp,
            frequencies,
            self.significant_height,
            self.mean_period,
            self.peak_enhancement,
            self.gravity,
            self.hull_length,
        )
        return eqx.tree_at(lambda w: (w.frequencies, w.amplitudes, w.wavenumbers, w.hull_gains, w.phases), self, (*fields, phases))

    # -- derived quantities -----------------------------------------------------------

    @property
    def zeroth_moment(self) -> Array:
        """m0 of the realization, sum A_k^2 / 2 (m^2); equals Hs^2 / 16."""
        return 0.5 * jnp.sum(self.amplitudes**2, axis=-1)

    @property
    def peak_frequency(self) -> Array:
        """wp = 2 pi 0.834 / T1 (rad/s)."""
        return peak_frequency(self.mean_period)

    # -- fields -----------------------------------------------------------------------------

    def _phases(self, t, position) -> tuple[Array, Array]:
        """theta_k(t, position), shape (..., N), and the unit wave direction e_chi."""
        t = jnp.asarray(t, dtype=float)
        position = jnp.asarray(position, dtype=float)
        e = jnp.stack([jnp.cos(self.direction), jnp.sin(self.direction)])
        along = position @ e
        theta = self.frequencies * t[..., None] - self.wavenumbers * jnp.asarray(along)[..., None] + self.phases
        return theta, e

    def elevation(self, t: ArrayLike, position: npt.ArrayLike) -> Array:
        """Surface elevation zeta (m) at Earth position (x, y) and time t.

        Parameters
        ----------
        t : array_like
            Time (s), scalar or any shape broadcasting with ``position[..., 0]``.
        position : array_like, shape (..., 2)
            Earth-fixed (x north, y east) position (m).
        """
        theta, _ = self._phases(t, position)
        _, cos = sincos(theta)
        return jnp.sum(self.amplitudes * cos, axis=-1)

    def motion(self, t: ArrayLike, position: npt.ArrayLike) -> Array:
        """First-order wave motion eta_w = [x_w, y_w, psi_w] (m, m, rad) of a hull at ``position``.

        Parameters
        ----------
        t : array_like
            Time (s).
        position : array_like, shape (..., 2)
            Earth-fixed position of the hull (m).

        Returns
        -------
        Array, shape (..., 3)
        """
        theta, e = self._phases(t, position)
        sin, _ = sincos(theta)
        averaged = self.hull_gains * self.amplitudes
        displacement = jnp.sum(averaged * sin, axis=-1)
        slope = jnp.sum(averaged * self.wavenumbers * sin, axis=-1)
        return jnp.stack([displacement * e[0], displacement * e[1], self.yaw_gain * slope], axis=-1)

    def rate(self, t: ArrayLike, position: npt.ArrayLike, velocity: npt.ArrayLike) -> Array:
        """d eta_w / dt along a ship at ``position`` moving with Earth-frame ``velocity``.

        The exact derivative of ``motion(t, position(t))``: each component at its
        encounter frequency w_k - k_k (velocity . e_chi).

        Parameters
        ----------
        t : array_like
            Time (s).
        position : array_like, shape (..., 2)
            Earth-fixed position (m).
        velocity : array_like, shape (..., 2)
            Earth-fixed planar velocity (m/s), e.g. the first two entries of J(psi) nu.

        Returns
        -------
        Array, shape (..., 3)
        """
        theta, e = self._phases(t, position)
        _, cos = sincos(theta)
        velocity = jnp.asarray(velocity, dtype=float)
        encounter = self.frequencies - self.wavenumbers * jnp.asarray(velocity @ e)[..., None]
        averaged = self.hull_gains * self.amplitudes * encounter * cos
        displacement_rate = jnp.sum(averaged, axis=-1)
        slope_rate = jnp.sum(averaged * self.wavenumbers, axis=-1)
        return jnp.stack([displacement_rate * e[0], displacement_rate * e[1], self.yaw_gain * slope_rate], axis=-1)

    def describe(self) -> dict:
        """The waves as plain numbers (for results' attributes and summaries)."""
        return {
            "spectrum": "JONSWAP (ITTC shape, Fossen 2011 eqs. 8.56-8.58, normalized to m0 = Hs^2/16)",
            "significant_height": float(self.significant_height),
            "mean_period": float(self.mean_period),
            "peak_period": float(self.mean_period) / MEAN_TO_PEAK_PERIOD,
            "peak_frequency": float(self.peak_frequency),
            "peak_enhancement": float(self.peak_enhancement),
            "direction": float(self.direction),
            "components": self.components,
            "band": [float(v) for v in self.band],
            "hull_length": float(self.hull_length),
            "yaw_gain": float(self.yaw_gain),
            "gravity": float(self.gravity),
            "zeroth_moment": float(self.zeroth_moment),
        }
