import jax
import jax.numpy as jnp
import numpy as np
import pytest
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


def test_standard_normal_depends_on_key_sample_and_stream_only():
    key = jax.random.key(3)
    block = standard_normal(key, jnp.arange(100, 200), 6)
    alone = standard_normal(key, jnp.asarray(150), 6)
    np.testing.assert_array_equal(block[50], alone)
    other = standard_normal(jax.random.key(4), jnp.asarray(150), 6)
    assert not np.any(np.asarray(other) == np.asarray(alone))
    sensor = standard_normal(key, jnp.asarray(150), 6, stream=1)
    assert not np.any(np.asarray(sensor) == np.asarray(alone))


def test_standard_normal_is_the_box_muller_transform_of_its_hashes():
    """Numbers 0..P-1 are the cosine branches of pairs 0..P-1, then the sine branches."""
    key = jax.random.key(11)
    samples = jnp.arange(40, 60)
    words = jax.random.key_data(key)
    for count, stream in ((6, 0), (5, 1), (1, 7)):
        pairs = (count + 1) // 2
        counter = (stream << 16) + 2 * np.arange(pairs, dtype=np.uint32)

        def uniform(c):
            hi, lo = threefry2x32(words, samples[:, None].astype(jnp.uint32), jnp.asarray(c, jnp.uint32))
            mantissa = (np.asarray(hi, np.uint64) & 0xFFFFF) << np.uint64(32) | np.asarray(lo, np.uint64)
            return (mantissa.astype(np.float64) + 1.0) / 2.0**52

        u1, u2 = uniform(counter), uniform(counter + 1)
        radius = np.sqrt(-2.0 * np.log(u1))
        expected = np.concatenate([radius * np.cos(2 * np.pi * u2), radius * np.sin(2 * np.pi * u2)], axis=1)[:, :count]
        got = np.asarray(standard_normal(key, samples, count, stream=stream))
        np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-14)


def test_streams_are_uncorrelated():
    key = jax.random.key(5)
    samples = jnp.arange(50_000)
    process = np.asarray(standard_normal(key, samples, 6, stream=0))
    sensor = np.asarray(standard_normal(key, samples, 3, stream=1))
    correlation = np.corrcoef(np.hstack([process, sensor]).T)
    assert np.max(np.abs(correlation - np.eye(9))) < 5 / np.sqrt(len(samples))


def test_standard_normal_rejects_bad_count_and_stream():
    key = jax.random.key(0)
    assert standard_normal(key, jnp.arange(4), 0).shape == (4, 0)
    with pytest.raises(ValueError, match="count must be in 0 .. 65536"):
        standard_normal(key, jnp.arange(4), -1)
    with pytest.raises(ValueError, match="stream must be in 0 .. 65535"):
        standard_normal(key, jnp.arange(4), 2, stream=2**16)
