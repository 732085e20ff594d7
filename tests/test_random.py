import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.random import threefry2x32_p
from scipy import stats

from lookout._random import standard_normal, threefry2x32


def test_threefry_equals_jax_bit_for_bit():
    words = jax.random.key_data(jax.random.key(2026))
    x0 = jnp.arange(4096, dtype=jnp.uint32) * np.uint32(2654435761)
    x1 = jnp.arange(4096, dtype=jnp.uint32)[::-1] ^ np.uint32(0xDEADBEEF)
    ours = threefry2x32(words, x0, x1)
    reference = threefry2x32_p.bind(words[0], words[1], x0, x1)
    np.testing.assert_array_equal(ours[0], reference[0])
    np.testing.assert_array_equal(ours[1], reference[1])


def test_standard_normal_is_standard_normal_and_uncorrelated():
    z = np.asarray(standard_normal(jax.random.key(7), jnp.arange(100_000), 12))
    assert z.shape == (100_000, 12)
    assert stats.kstest(z.ravel(), "norm").pvalue > 1e-3
    assert abs(z.mean()) < 4 / np.sqrt(z.size)
    assert abs(z.var() - 1.0) < 4 * np.sqrt(2 / z.size)
    # across the numbers of a sample (including the two branches of a Box–Muller pair)
    # and across consecutive samples
    correlation = np.corrcoef(z.T)
    assert np.max(np.abs(correlation - np.eye(12))) < 5 / np.sqrt(len(z))
    assert abs(np.corrcoef(z[:-1, 0], z[1:, 0])[0, 1]) < 5 / np.sqrt(len(z))


def test_standard_normal_depends_on_key_and_sample_only():
    key = jax.random.key(3)
    block = standard_normal(key, jnp.arange(100, 200), 6)
    alone = standard_normal(key, jnp.asarray(150), 6)
    np.testing.assert_array_equal(block[50], alone)
    # a prefix of a longer draw is the shorter draw
    np.testing.assert_array_equal(standard_normal(key, jnp.asarray(150), 4), alone[:4])
    # and any slice, odd start included (the engine draws the sensor's numbers apart)
    for first in (1, 2, 3):
        np.testing.assert_array_equal(standard_normal(key, jnp.asarray(150), 6 - first, first=first), alone[first:])
    other = standard_normal(jax.random.key(4), jnp.asarray(150), 6)
    assert not np.any(np.asarray(other) == np.asarray(alone))
