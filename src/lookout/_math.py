"""Planar kinematics shared by every model: rotation about z and angle wrapping.

One place only: every other module calls these, so the heading convention
(radians, wrapped to [-pi, pi)) is defined here once.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import struct
from decimal import Decimal, localcontext

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike


def ssa(angle: ArrayLike) -> Array:
    """Smallest signed angle: wrap ``angle`` (rad) to the interval [-pi, pi).

    Computed as ``angle - 2 pi floor((angle + pi) / (2 pi))``: on XLA:CPU ``floor``
    vectorizes and ``mod`` does not (0.3 against 9 ns per element, measured).

    Parameters
    ----------
    angle : array_like
        Angle or angle difference in radians, any shape.

    Returns
    -------
    Array
        The same angle modulo 2 pi, in [-pi, pi).
    """
    angle = jnp.asarray(angle)
    turns = jnp.floor((angle + jnp.pi) * (0.5 / jnp.pi))
    wrapped = angle - (2.0 * jnp.pi) * turns
    # one rounding step can land on the excluded end point +pi, or a hair below -pi
    wrapped = jnp.where(wrapped >= jnp.pi, wrapped - 2.0 * jnp.pi, wrapped)
    return jnp.where(wrapped < -jnp.pi, wrapped + 2.0 * jnp.pi, wrapped)


def _split_half_pi() -> tuple[float, float, float]:
    """pi/2 as hi + mid + lo, hi and mid with 33 significant bits (Cody–Waite split).

    ``n * hi`` and ``n * mid`` are then exact in float64 for ``|n| < 2**20``, so the
    argument reduction below loses no accuracy for ``|angle| < 1.6e6`` rad.
    """

    def top_bits(value: Decimal) -> float:
        bits = struct.unpack("<q", struct.pack("<d", float(value)))[0]
        bits &= ~((1 << 20) - 1)  # keep 1 + 32 of the 52 stored mantissa bits
        return struct.unpack("<d", struct.pack("<q", bits))[0]

    with localcontext() as context:
        context.prec = 60
        half_pi = Decimal("1.57079632679489661923132169163975144209858469968755291048747")
        hi = top_bits(half_pi)
        mid = top_bits(half_pi - Decimal(hi))
        return hi, mid, float(half_pi - Decimal(hi) - Decimal(mid))


_HALF_PI_HI, _HALF_PI_MID, _HALF_PI_LO = _split_half_pi()
# Taylor coefficients (-1)^k / (2k+1)! and (-1)^k / (2k)!: on |r| <= pi/4 the first
# omitted terms are below 5e-17 (sin, r^17/17!) and 3e-18 (cos, r^18/18!).
_SIN_COEFFICIENTS = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(1, 8))
_COS_COEFFICIENTS = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(2, 9))


def _polynomial(coefficients: tuple[float, ...], x: Array) -> Array:
    result = coefficients[-1] * x + coefficients[-2]  # the loop's first step, taken out so that ``result`` is an Array
    for c in reversed(coefficients[:-2]):
        result = result * x + c
    return result


def sincos(angle: Array) -> tuple[Array, Array]:
    """``(sin(angle), cos(angle))`` by argument reduction and polynomials.

    Agrees with ``numpy.sin``/``numpy.cos`` to a few units in the last place for
    ``|angle| < 1.6e6`` rad (tested). It exists because XLA:CPU evaluates
    ``jnp.sin``/``jnp.cos`` element by element (about 11 ns each, measured), while
    this is a handful of vectorized multiply-adds; every rotation J(psi) of every
    integration stage goes through it.

    Parameters
    ----------
    angle : array_like
        Radians, any shape, float64.

    Returns
    -------
    tuple of Array
        Sine and cosine, each with the shape of ``angle``.
    """
    angle = jnp.asarray(angle)
    quadrant = jnp.round(angle * (2.0 / math.pi))
    r = ((angle - quadrant * _HALF_PI_HI) - quadrant * _HALF_PI_MID) - quadrant * _HALF_PI_LO
    r2 = r * r
    sin_r = r + r * r2 * _polynomial(_SIN_COEFFICIENTS, r2)
    cos_r = 1.0 - 0.5 * r2 + r2 * r2 * _polynomial(_COS_COEFFICIENTS, r2)
    q = quadrant.astype(jnp.int32) & 3
    odd = (q & 1) == 1
    sin = jnp.where(odd, cos_r, sin_r)
    cos = jnp.where(odd, sin_r, cos_r)
    return jnp.where(q >= 2, -sin, sin), jnp.where((q == 1) | (q == 2), -cos, cos)


def computed_once(value: Array) -> Array:
    """``value`` unchanged, marked so that XLA:CPU computes it once per element.

    XLA:CPU fuses a chain of cheap elementwise operations into every kernel that
    reads its result, and inside a kernel evaluates it once per *output* element:
    the sine and cosine of a heading, read by the components of rotated vectors in
    several kernels, were evaluated about 30 times per run and sample in a batch.
    A division is "expensive" to XLA's fusion heuristics and is not duplicated;
    dividing by a one that XLA cannot fold (``1 + 0 * value``: exactly 1 for
    finite ``value``, NaN where ``value`` is already NaN or infinite) makes the
    chain one kernel whose result its consumers read. Results are bit-identical;
    the speed-up is recorded in docs/benchmarks.md.

    Parameters
    ----------
    value : Array
        Any float array.

    Returns
    -------
    Array
        ``value``, bit for bit (NaN where ``value`` is not finite; subnormals
        become zero, as in any XLA:CPU arithmetic).
    """
    if not _MARKED.get():
        return value
    return value / (1.0 + 0.0 * value)


#: Whether :func:`computed_once` marks its value (see :func:`unmarked`).
_MARKED = contextvars.ContextVar("lookout_computed_once", default=True)


@contextlib.contextmanager
def unmarked():
    """Trace the code inside with :func:`computed_once` as the identity.

    The marks help a batch of simulations, where each value is read by many kernels;
    under a forward-mode Jacobian (``jax.jacfwd``: every value carries a tangent per
    state entry) they split the computation into many small kernels instead. The
    Kalman filters trace their model step inside this (the DP vessel's extended
    filter's propagation: 26 us per sample marked, 11 us unmarked). Values are the same
    bit for bit; the flag is read while tracing, so it changes no compiled program.
    """
    token = _MARKED.set(False)
    try:
        yield
    finally:
        _MARKED.reset(token)


#: Products with at most this many columns are written out (see :func:`matvec`).
MATVEC_UNROLL_COLUMNS = 8


def matvec(matrix: Array, vector: Array) -> Array:
    """``matrix @ vector``, written out as multiply-adds over the columns.

    Under ``vmap`` a batched small product is a separate library call per product
    on XLA:CPU; written out, it fuses with its neighbours. The vector goes through
    :func:`computed_once` so that the chain producing it is not re-evaluated for
    each output component. Matrices with more than :data:`MATVEC_UNROLL_COLUMNS`
    columns use ``@``.

    Parameters
    ----------
    matrix : Array, shape (m, n)
    vector : Array, shape (n,)

    Returns
    -------
    Array, shape (m,)
    """
    matrix, vector = jnp.asarray(matrix), jnp.asarray(vector)
    if matrix.ndim != 2 or vector.ndim != 1 or matrix.shape[1] != vector.shape[0]:
        raise ValueError(f"matvec needs an (m, n) matrix and an (n,) vector; got shapes {matrix.shape} and {vector.shape}")
    columns = matrix.shape[1]
    if columns > MATVEC_UNROLL_COLUMNS:
        return matrix @ vector
    v = computed_once(vector)
    result = matrix[:, 0] * v[0]
    for j in range(1, columns):
        result = result + matrix[:, j] * v[j]
    return result


def solve(matrix: Array, vector: Array) -> Array:
    """``matrix^-1 vector`` for a small square matrix, by Cramer's rule up to 3x3.

    ``jnp.linalg.solve`` is a LAPACK call on XLA:CPU that does not fuse with its
    neighbours and costs microseconds per call, which dominates a manipulator's
    integration stage (M(q) q'' = f is solved eight times per RK4 step of plant and
    observer); for n <= 3 the determinant formulas are a few fused multiply-adds.
    Larger systems use ``jnp.linalg.solve``. For the well-conditioned inertia
    matrices this is meant for, the result agrees with LAPACK to rounding (tested).

    Parameters
    ----------
    matrix : Array, shape (n, n)
    vector : Array, shape (n,)

    Returns
    -------
    Array, shape (n,)
    """
    matrix, vector = jnp.asarray(matrix), jnp.asarray(vector)
    n = vector.shape[0]
    if matrix.shape != (n, n):
        raise ValueError(f"solve needs an (n, n) matrix and an (n,) vector; got shapes {matrix.shape} and {vector.shape}")
    if n == 1:
        return vector / matrix[0, 0]
    if n == 2:
        a, b, c, d = matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1]
        det = a * d - b * c
        return jnp.stack([d * vector[0] - b * vector[1], a * vector[1] - c * vector[0]]) / det
    if n == 3:
        # x = adj(A) b / det(A), the adjugate from the cofactors of the columns' cross products
        c0, c1, c2 = matrix[:, 0], matrix[:, 1], matrix[:, 2]
        r0, r1, r2 = jnp.cross(c1, c2), jnp.cross(c2, c0), jnp.cross(c0, c1)
        det = jnp.dot(c0, r0)
        return jnp.stack([jnp.dot(r0, vector), jnp.dot(r1, vector), jnp.dot(r2, vector)]) / det
    return jnp.linalg.solve(matrix, vector)


def _heading_terms(psi: Array) -> tuple[Array, Array]:
    """sin(psi), cos(psi), each computed once (see :func:`computed_once`)."""
    s, c = sincos(psi)
    return computed_once(s), computed_once(c)


def rotation(psi: Array) -> Array:
    """Rotation matrix J(psi) from body to Earth-fixed axes (Fossen & Strand 1999, eq. 2).

    Parameters
    ----------
    psi : array_like
        Heading in radians, scalar.

    Returns
    -------
    Array
        The 3x3 matrix [[c, -s, 0], [s, c, 0], [0, 0, 1]].
    """
    s, c = _heading_terms(psi)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack([jnp.stack([c, -s, zero]), jnp.stack([s, c, zero]), jnp.stack([zero, zero, one])])


def rotate(psi: Array, vector: Array | np.ndarray) -> Array:
    """J(psi) @ vector, written out with cos/sin (cheaper than a 3x3 product under vmap).

    Parameters
    ----------
    psi : array_like
        Heading in radians.
    vector : array_like, shape (3,)
        Body-frame vector [surge, sway, yaw].

    Returns
    -------
    Array, shape (3,)
        The Earth-fixed vector.
    """
    s, c = _heading_terms(psi)
    return jnp.stack([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1], vector[2]])


def rotate_transpose(psi: Array, vector: Array | np.ndarray) -> Array:
    """J(psi)^T @ vector: an Earth-fixed vector decomposed in body axes.

    Parameters
    ----------
    psi : array_like
        Heading in radians.
    vector : array_like, shape (3,)
        Earth-fixed vector [north, east, yaw].

    Returns
    -------
    Array, shape (3,)
        The body-frame vector.
    """
    s, c = _heading_terms(psi)
    return jnp.stack([c * vector[0] + s * vector[1], -s * vector[0] + c * vector[1], vector[2]])
