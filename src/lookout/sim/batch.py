"""Batches of runs: ``jax.vmap`` of the sample loop over keys (and optionally over the
leading axis of every array in the scenario), with the run axis sharded across
devices when there are several; scenarios stacked for such a batch; and batches
that keep a :class:`~lookout.sim.loop.Summary` of each run instead of its records.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout._resources import refuse_unless_it_fits
from lookout.results import Trajectory
from lookout.sim.loop import Summary, initial_carry, make_trajectory, run_segments, segment
from lookout.sim.memory import check_batch_memory
from lookout.sim.scenario import Scenario, checked_scenario
from lookout.sim.seeds import checked_keys


def stack_scenarios(scenarios: list[Scenario]) -> Scenario:
    """Scenarios that differ only in their arrays (gains, masses, model errors) as one
    scenario with a leading run axis, for ``simulate_batch(..., batched_scenario=True)``.

    Their static structure (periods, durations, component types, sizes) must be equal.
    """
    if not isinstance(scenarios, (list, tuple)) or not scenarios:
        raise ValueError(f"scenarios must be a non-empty list of Scenarios; got {scenarios!r:.60}")
    for index, scenario in enumerate(scenarios):
        if not isinstance(scenario, Scenario):
            raise ValueError(f"scenarios[{index}] must be a lookout Scenario; got {type(scenario).__name__}")
    first = jax.tree.structure(scenarios[0])
    for index, scenario in enumerate(scenarios[1:], start=1):
        same_tree = jax.tree.structure(scenario) == first  # type: ignore[operator]  # jaxlib ships no stub for PyTreeDef, so mypy cannot resolve jax.tree.structure's return type
        if not same_tree or [np.shape(a) for a in jax.tree.leaves(scenario)] != [np.shape(a) for a in jax.tree.leaves(scenarios[0])]:
            raise ValueError(
                f"scenarios[{index}] differs from scenarios[0] in its structure (periods, durations, component types or sizes): "
                "stacked scenarios may differ in their numbers only"
            )
    leaves = [leaf for leaf in jax.tree.leaves(scenarios[0]) if eqx.is_array_like(leaf)]
    per_run = sum(np.asarray(leaf).nbytes for leaf in leaves)
    refuse_unless_it_fits(len(scenarios) * per_run, f"scenarios: {len(scenarios)} stacked x {per_run} B of arrays", "stack fewer scenarios at a time")
    return jax.tree.map(lambda *leaves: jnp.stack([jnp.asarray(leaf) for leaf in leaves]), *scenarios)


@eqx.filter_jit
def _initial_carry_batch(scenario, keys, batched_scenario: bool):
    axes = eqx.if_array(0) if batched_scenario else None
    return eqx.filter_vmap(initial_carry, in_axes=(axes, 0))(scenario, keys)


@eqx.filter_jit
def _segment_batch(scenario, keys, carry, first_record, n_records: int, batched_scenario: bool, summary: Summary | None = None):
    axes = eqx.if_array(0) if batched_scenario else None
    run = eqx.filter_vmap(lambda s, k, c, f: segment(s, k, c, f, n_records, summary), in_axes=(axes, 0, 0, None))
    mesh = _run_mesh(int(keys.shape[0]))
    if mesh is None:
        return run(scenario, keys, carry, first_record)
    # Each device steps its own share of the runs as a batch of its own (shard_map): a
    # loop whose length depends on the runs (a QP's iterations under vmap: until the
    # slowest run is done) then asks only its device's runs, where under the batch's
    # sharding alone every iteration would gather a flag from every device.
    arrays, static = eqx.partition(scenario, eqx.is_array)
    runs, whole = jax.sharding.PartitionSpec("run"), jax.sharding.PartitionSpec()

    def share(arrays, keys, carry, first_record):
        return run(eqx.combine(arrays, static), keys, carry, first_record)

    sharded = jax.shard_map(share, mesh=mesh, in_specs=(runs if batched_scenario else whole, runs, runs, whole), out_specs=runs, check_vma=False)
    return sharded(arrays, keys, carry, first_record)


def _run_mesh(n_runs: int) -> jax.sharding.Mesh | None:
    """The devices' mesh over the run axis, or None with one device or a batch that
    does not divide evenly among them."""
    devices = jax.devices()
    if len(devices) < 2 or n_runs % len(devices):
        return None
    return jax.make_mesh((len(devices),), ("run",), axis_types=(jax.sharding.AxisType.Auto,))


def _shard_runs(tree, n_runs: int):
    """Place the run axis across all devices when it divides evenly (else leave as is).

    Computation follows the data under ``jit``: each device (each CPU core with
    :func:`lookout.configure_cpu`, or each GPU) simulates its share of the runs.
    Results do not depend on the placement.
    """
    mesh = _run_mesh(n_runs)
    if mesh is None:
        return tree
    return jax.device_put(tree, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("run")))


def _sharded_batch(scenario: Scenario, keys: Array, batched_scenario: bool):
    """The batch's scenario, keys and initial carry, with the run axis across devices."""
    n_runs = keys.shape[0]
    keys = _shard_runs(keys, n_runs)
    if batched_scenario:
        scenario = eqx.combine(_shard_runs(eqx.filter(scenario, eqx.is_array), n_runs), eqx.filter(scenario, eqx.is_array, inverse=True))
    return scenario, keys, _shard_runs(_initial_carry_batch(scenario, keys, batched_scenario), n_runs)


def summarize_batch(scenario: Scenario, keys: Array, summary: Summary, *, batched_scenario: bool = False) -> tuple[Any, Any]:
    """Simulate a batch as :func:`simulate_batch` does, keeping ``summary``'s
    accumulation and series of each run instead of its records.

    The runs are the same (same keys, same samples); only what is written per record
    changes, so a study that needs a few numbers per run never holds the records.

    Returns
    -------
    (accumulated, series)
        ``summary``'s pytrees with a leading run axis (``series`` also has a time axis
        of ``scenario.n_records``), left where they were computed (sharded across
        devices when there are several).
    """
    keys = checked_keys(keys)
    checked_scenario(scenario, int(keys.shape[0]) if batched_scenario else None)
    scenario, keys, carry = _sharded_batch(scenario, keys, batched_scenario)
    return _segment_batch(scenario, keys, carry, jnp.asarray(0), scenario.n_records, batched_scenario, summary)[1]


def simulate_batch(
    scenario: Scenario, keys: Array, *, batched_scenario: bool = False, progress: Callable[[int, int], object] | None = None, chunks: int = 20
) -> Trajectory:
    """Simulate a batch of runs with ``jax.vmap``: one run per key.

    Parameters
    ----------
    scenario : Scenario
        Shared by all runs, or, with ``batched_scenario=True``, every array in it
        has a leading axis of length ``len(keys)`` (parameters, initial
        conditions) built e.g. with ``jax.vmap`` or ``jax.tree.map(jnp.stack, ...)``.
    keys : Array
        Batch of PRNG keys, e.g. :func:`~lookout.sim.seeds.seed_keys`.
    batched_scenario : bool
        Map over the leading axis of the scenario's arrays too.
    progress, chunks
        As in :func:`~lookout.sim.loop.simulate`.

    Returns
    -------
    Trajectory
        With a leading run axis on every recorded array.
    """
    keys = checked_keys(keys)
    checked_scenario(scenario, int(keys.shape[0]) if batched_scenario else None)
    check_batch_memory(scenario, int(keys.shape[0]))
    scenario, keys, carry = _sharded_batch(scenario, keys, batched_scenario)

    def step(carry, first, length):
        return _segment_batch(scenario, keys, carry, first, length, batched_scenario)

    records = run_segments(step, carry, scenario.n_records, progress, chunks, time_axis=1)
    # gather the shards onto one device so results index like ordinary arrays
    records = jax.device_put(records, jax.devices()[0])
    return make_trajectory(scenario, records, batched=True)
