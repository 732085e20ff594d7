"""Counter-based standard normal numbers for the engine: Threefry-2x32 and Box–Muller.

The noise of a run is a pure function of its key and of integer counters, so that
sample ``k`` of a run gets the same numbers however the run is split into blocks,
chunks or batches. The hash is Threefry-2x32 with 20 rounds (Salmon, Moraes, Dror &
Shaw, "Parallel random numbers: as easy as 1, 2, 3", SC 2011), the hash behind
``jax.random``'s default keys. It is written out here as straight-line integer
arithmetic because JAX lowers it on CPU as a rolled loop of 5 iterations, which XLA
cannot fuse with the rest of the computation (13.5 ns per hash measured on the
development machine, against about 3 ns here). The test suite checks it bit for bit
against ``jax.extend.random.threefry2x32_p``.

Standard normals come from pairs of uniforms by the Box–Muller transform,
``sqrt(-2 ln u1) (cos 2 pi u2, sin 2 pi u2)``, with 52-bit uniforms, ``u1`` in (0, 1].
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout._math import computed_once, sincos

# Rotation distances of Threefry-2x32 (Salmon et al. 2011, Table 4), used in order,
# four rounds between key injections, 20 rounds in all.
_ROTATIONS = (13, 15, 26, 6, 17, 29, 16, 24)
# Key schedule parity constant of Threefish/Threefry.
_PARITY = np.uint32(0x1BD11BDA)


def _rotate_left(x: Array, distance: int) -> Array:
    return (x << np.uint32(distance)) | (x >> np.uint32(32 - distance))


def threefry2x32(key: Array, x0: Array, x1: Array) -> tuple[Array, Array]:
    """Threefry-2x32 (20 rounds) of the counter pairs ``(x0, x1)`` under ``key``.

    Parameters
    ----------
    key : Array, shape (2,), uint32
        Key words, e.g. ``jax.random.key_data(key)`` of a default (threefry) key.
    x0, x1 : Array, uint32
        Counter words (broadcast against each other).

    Returns
    -------
    tuple of Array
        The two 32-bit output words, each of the broadcast shape.
    """
    k0, k1 = key[0], key[1]
    schedule = (k0, k1, k0 ^ k1 ^ _PARITY)
    x0 = x0 + schedule[0]
    x1 = x1 + schedule[1]
    for group in range(5):
        for r in range(4):
            x0 = x0 + x1
            x1 = _rotate_left(x1, _ROTATIONS[4 * (group % 2) + r])
            x1 = x1 ^ x0
        x0 = x0 + schedule[(group + 1) % 3]
        x1 = x1 + schedule[(group + 2) % 3] + np.uint32(group + 1)
    return x0, x1


def _unit_interval(hi: Array, lo: Array) -> Array:
    """52 bits of (hi, lo) as a float64 in (0, 1]: (m + 1) / 2**52, m in [0, 2**52).

    Built from two exact uint32 -> float64 conversions (a uint64 conversion does not
    vectorize on x86).
    """
    mantissa = (hi & np.uint32(0xFFFFF)).astype(jnp.float64) * 2.0**32 + lo.astype(jnp.float64)
    return (mantissa + 1.0) * 2.0**-52


#: Most numbers one call draws per sample (a counter of 16 bits per sample).
MAX_COUNT = 2**16


def standard_normal(key: Array, sample: Array, count: int, stream: int = 0) -> Array:
    """``count`` standard normal numbers of stream ``stream`` for each entry of ``sample``.

    The numbers come in Box–Muller pairs: pair ``p`` hashes the counters
    ``(k, c + 2p)`` and ``(k, c + 2p + 1)``, with ``c = stream * 2**16``, into the
    uniforms ``u1`` and ``u2`` and gives ``r cos(2 pi u2)`` and ``r sin(2 pi u2)``,
    ``r = sqrt(-2 ln u1)``. With ``P = ceil(count / 2)`` pairs, numbers ``0 .. P-1``
    are the cosine branches of pairs ``0 .. P-1`` and numbers ``P .. count-1`` their
    sine branches: one hash per number, and no interleaving of the two branches
    (which XLA:CPU would fuse back into a kernel that computes each pair twice).
    The result is a function of ``(key, k, stream, count)`` alone, so a stream is
    drawn with one fixed ``count``; the engine gives the plant's process noise and
    the sensor's noise separate streams.

    Parameters
    ----------
    key : jax.random key
        A default (threefry) key; its two data words key the hash.
    sample : Array, integer
        Sample indices, any shape, in [0, 2**32).
    count : int
        Numbers per sample (static), 0 .. 2**16.
    stream : int
        Stream index (static), 0 .. 2**16 - 1.

    Returns
    -------
    Array, shape ``sample.shape + (count,)``, float64
    """
    if not 0 <= count <= MAX_COUNT:
        raise ValueError(f"count must be in 0 .. {MAX_COUNT}, got {count}")
    if not 0 <= stream < 2**16:
        raise ValueError(f"stream must be in 0 .. 65535, got {stream}")
    if count == 0:
        return jnp.zeros(jnp.shape(sample) + (0,))
    words = jax.random.key_data(key).astype(jnp.uint32)
    k = jnp.asarray(sample).astype(jnp.uint32)[..., None]
    pairs = (count + 1) // 2
    counter = np.uint32(stream << 16) + 2 * jnp.arange(pairs, dtype=jnp.uint32)
    u1 = _unit_interval(*threefry2x32(words, k, counter))
    u2 = _unit_interval(*threefry2x32(words, k, counter + np.uint32(1)))
    radius = computed_once(jnp.sqrt(-2.0 * jnp.log(u1)))
    sin, cos = sincos((2.0 * np.pi) * computed_once(u2))
    return jnp.concatenate([radius * cos, radius * sin], axis=-1)[..., :count]
