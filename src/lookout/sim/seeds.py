"""Seeds and the PRNG keys of runs: one key per run, made from integer seeds, and the
check that a key (or a batch of keys) is one."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeGuard

import jax
import jax.numpy as jnp
from jax import Array

from lookout._resources import refuse_unless_it_fits

#: Largest seed a JAX key accepts (it converts the seed to a signed 64-bit integer).
MAX_SEED = 2**63 - 1

#: Bytes a key and its seed take while :func:`seed_keys` makes them.
KEY_BYTES = 16


def keys_of_seeds(seeds: Sequence[int]) -> Array:
    """PRNG keys of a batch whose run i uses ``jax.random.key(seeds[i])`` (as :func:`seed_keys`
    with seed = seeds[i], runs = 1), for batches that mix scenarios and seeds."""
    # each seed is a Python int while it is checked (36 B), then a key
    refuse_unless_it_fits((KEY_BYTES + 36) * len(seeds), f"seeds: {len(seeds)} keys x {KEY_BYTES + 36} B", "make fewer keys at a time")
    seeds = [int(seed) for seed in seeds]
    for seed in seeds:
        if not 0 <= seed <= MAX_SEED:
            raise ValueError(f"seeds must be integers from 0 to {MAX_SEED} (a JAX key takes a signed 64-bit seed); got {seed!r}")
    # the keys seed_keys(seed, 1)[0] would give, made in one vmapped call, not one per seed
    return jax.vmap(jax.random.key)(jnp.asarray(seeds, dtype=jnp.int64))


def seed_keys(seed: int, runs: int) -> Array:
    """PRNG keys of a Monte Carlo: run i uses ``jax.random.key(seed + i)``.

    So run 0 of a batch is the single run with the same ``seed``, and a batch of
    ``seed=S, runs=N`` extends the batch ``seed=S, runs=M < N`` (its first M runs
    are the same realizations).

    Parameters
    ----------
    seed : int
        Seed of run 0, from 0 to ``MAX_SEED - runs + 1``.
    runs : int
        Number of keys, at least 1.

    Returns
    -------
    Array
        ``runs`` keys, shape (runs,).
    """
    if not (isinstance(runs, int) and not isinstance(runs, bool) and runs >= 1):
        raise ValueError(f"runs must be a positive integer; got {runs!r}")
    if not (isinstance(seed, int) and 0 <= seed <= MAX_SEED - runs + 1):
        raise ValueError(
            f"seed must be an integer from 0 to {MAX_SEED - runs + 1} (seeds seed ... seed + runs - 1 must fit a signed 64-bit integer); got {seed!r}"
        )
    refuse_unless_it_fits(KEY_BYTES * runs, f"runs: {runs} keys x {KEY_BYTES} B", "make fewer keys at a time")
    return jax.vmap(jax.random.key)(jnp.arange(runs, dtype=jnp.int64) + seed)


def _describe_key(value) -> str:
    if isinstance(value, jax.Array):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    return type(value).__name__


def _is_typed_key(value: object) -> TypeGuard[Array]:
    return isinstance(value, jax.Array) and jnp.issubdtype(value.dtype, jax.dtypes.prng_key)


def _is_raw_key(value: object, batch: bool) -> TypeGuard[Array]:
    return isinstance(value, jax.Array) and value.dtype == jnp.uint32 and value.ndim == (2 if batch else 1) and value.shape[-1] == 2


def checked_key(key: object) -> Array:
    """``key`` if it is one PRNG key (typed, or a raw uint32 pair); else a ValueError."""
    if (_is_typed_key(key) and key.ndim == 0) or _is_raw_key(key, batch=False):
        return key
    hint = ": a batch of keys goes to simulate_batch" if (_is_typed_key(key) and key.ndim == 1) or _is_raw_key(key, batch=True) else ""
    raise ValueError(f"key must be one JAX PRNG key (jax.random.key(seed), or lookout.seed_keys(seed, 1)[0]); got {_describe_key(key)}{hint}")


def checked_keys(keys: object) -> Array:
    """``keys`` if it is a 1-D batch of PRNG keys; else a ValueError."""
    if (_is_typed_key(keys) and keys.ndim == 1 and keys.shape[0] >= 1) or (_is_raw_key(keys, batch=True) and keys.shape[0] >= 1):
        return keys
    raise ValueError(f"keys must be a 1-D batch of JAX PRNG keys, one per run (lookout.seed_keys(seed, runs)); got {_describe_key(keys)}")
