"""The sampled-data simulation engine: one jitted nested ``lax.scan`` per run.

Per sample k (time ``t_k = k * sample_period``):

1. each sensor channel whose period divides ``t_k`` takes a new sample of the plant
   state; the others hold their last sample (zero-order hold);
2. the controller's tau_k, computed from the estimate at t_k (at the end of the
   previous sample, or from the initial estimate), is held over the sample;
3. the observer advances its estimate from t_k to t_{k+1} with the held measurement
   and tau_k (``observer.step``), or, in ``"continuous"`` mode, is integrated
   jointly with the plant on a noise-free continuous measurement;
4. the plant is integrated from t_k to t_{k+1} by RK4 substeps with tau_k held
   (zero-order hold) and process noise held over each substep with variance
   ``1 / plant_step`` (a discretization of unit white noise).

Time is computed from integer indices, never accumulated. Batches are
``jax.vmap`` of the same function over PRNG keys (and optionally over the
leading axis of every array in the scenario), with the run axis sharded across
devices when there are several (GPUs, or CPU cores exposed by
:func:`lookout.use_all_cpu_cores`). Process and measurement noise of sample k is
a function of (key, k) alone (a counter-based Threefry hash), drawn inside the
loop for each sample.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.flatten_util import ravel_pytree

from lookout._math import computed_once
from lookout._random import standard_normal
from lookout.results import Trajectory
from lookout.sim.integrators import rk4_step


def integer_ratio(value: float, base: float) -> int | None:
    """``value / base`` when it is a positive whole number (to 1e-9 relative), else None."""
    ratio = value / base
    steps = int(round(ratio))
    if steps < 1 or abs(ratio - steps) > 1e-9 * max(1.0, ratio):
        return None
    return steps


def _ratio(name: str, period: float, base_name: str, base: float) -> int:
    steps = integer_ratio(period, base)
    if steps is None:
        raise ValueError(
            f"{name} ({period:g} s) must be an integer multiple of {base_name} ({base:g} s)"
        )
    return steps


class Scenario(eqx.Module):
    """Everything one run needs: components, initial conditions and time grid.

    Parameters
    ----------
    plant : Module
        Has ``vector_field(t, state, tau, noise)`` and an int ``noise_size``.
    sensor : Module
        Has ``measure(state, normals)``, ``ideal(state)``, a tuple ``sample_period`` and
        an int ``noise_size`` (standard normals it needs per sample).
    observer : Module
        Has ``step(estimate, t, y, tau, dt, substeps)`` and
        ``vector_field(t, estimate, y, tau)``.
    control : Module
        Has ``init()`` and ``step(control_state, t, estimate) -> (control_state, tau)``.
    initial_state, initial_estimate : PyTree
        Plant state and observer estimate at t = 0.
    plant_step : float
        RK4 step of the plant (s).
    sample_period : float
        Observer and controller period (s), an integer multiple of ``plant_step``.
    duration : float
        Simulated time (s), an integer multiple of ``sample_period * record_every``.
    record_every : int
        Record one sample in this many (decimation for large batches).
    observer_mode : {"sampled", "continuous"}
        ``"sampled"`` runs ``observer.step`` once per sample on the held sensor
        samples; ``"continuous"`` integrates the observer with the plant on the
        noise-free measurement (the setting of the paper's Lyapunov analysis).
    """

    plant: Any
    sensor: Any
    observer: Any
    control: Any
    initial_state: Any
    initial_estimate: Any
    plant_step: float = eqx.field(static=True)
    sample_period: float = eqx.field(static=True)
    duration: float = eqx.field(static=True)
    record_every: int = eqx.field(static=True, default=1)
    observer_mode: Literal["sampled", "continuous"] = eqx.field(static=True, default="sampled")

    def __check_init__(self):
        if not (math.isfinite(self.plant_step) and self.plant_step > 0):
            raise ValueError(f"plant_step must be positive; got {self.plant_step}")
        if not (math.isfinite(self.sample_period) and self.sample_period > 0):
            raise ValueError(f"sample_period must be positive; got {self.sample_period}")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be positive; got {self.duration}")
        if not (isinstance(self.record_every, int) and self.record_every >= 1):
            raise ValueError(f"record_every must be a positive integer; got {self.record_every}")
        if self.observer_mode not in ("sampled", "continuous"):
            raise ValueError(f"observer_mode must be 'sampled' or 'continuous'; got {self.observer_mode!r}")
        _ratio("sample_period", self.sample_period, "plant_step", self.plant_step)
        for channel, period in enumerate(self.sensor.sample_period):
            _ratio(f"sensor sample_period[{channel}]", period, "sample_period", self.sample_period)
        _ratio("duration", self.duration, "sample_period * record_every", self.sample_period * self.record_every)
        if self.duration / self.sample_period >= 2**32:
            raise ValueError(
                f"duration / sample_period must be below 2**32 samples (noise counters); got {self.duration / self.sample_period:.3g}"
            )

    @property
    def substeps(self) -> int:
        """Plant RK4 steps per sample period."""
        return _ratio("sample_period", self.sample_period, "plant_step", self.plant_step)

    @property
    def n_records(self) -> int:
        """Number of recorded samples."""
        return _ratio("duration", self.duration, "sample_period * record_every", self.sample_period * self.record_every)

    @property
    def sensor_steps(self) -> tuple[int, ...]:
        """Sample periods of the sensor channels, in observer samples."""
        return tuple(_ratio("sensor", p, "sample_period", self.sample_period) for p in self.sensor.sample_period)


#: Static loops up to this length are unrolled in Python instead of a lax.scan
#: (a one-trip XLA while loop costs more than its body here).
UNROLL_LIMIT = 4
#: The same for the unrecorded samples of a record group: a whole sample is a large
#: body, and XLA:CPU's compile time grows faster than the unrolled body (a 600 s run
#: recorded every 5 samples compiled in 18 s unrolled, 6.7 s as a scan).
RECORD_GROUP_UNROLL_LIMIT = 1
# Streams of lookout._random.standard_normal: the plant's process noise and the
# sensor's measurement noise of a sample are drawn independently of each other.
PROCESS_STREAM = 0
SENSOR_STREAM = 1


def _static_scan(body, carry, xs, length: int, unroll_limit: int = UNROLL_LIMIT):
    """``lax.scan`` for long loops, a Python loop (unrolled in the trace) for short ones."""
    if length > unroll_limit:
        return jax.lax.scan(body, carry, xs)
    outputs = []
    for i in range(length):
        carry, out = body(carry, jax.tree.map(lambda a: a[i], xs))
        outputs.append(out)
    return carry, jax.tree.map(lambda *o: jnp.stack(o), *outputs)


def _process_noise(scenario: Scenario, key: Array, k: Array) -> Array:
    """Unit white noise of each plant substep of sample k, shape (substeps, plant.noise_size).

    Stream ``PROCESS_STREAM`` of sample k: a function of (key, k) alone
    (counter-based, :func:`lookout._random.standard_normal`), computed once and
    read by every integration stage (:func:`lookout._math.computed_once`).
    """
    substeps, size = scenario.substeps, scenario.plant.noise_size
    normals = computed_once(standard_normal(key, k, substeps * size, stream=PROCESS_STREAM))
    return normals.reshape(substeps, size) / math.sqrt(scenario.plant_step)


def _sensor_noise(scenario: Scenario, key: Array, k: Array, due: Array) -> Array:
    """The sensor's standard normals of sample k: stream ``SENSOR_STREAM``.

    Drawn only when some channel takes a sample (``due``); otherwise zeros, which
    the engine never reads (it holds the last sample). ``k`` is the same for every
    run of a batch, so under ``vmap`` this stays a branch: with 1 Hz fixes and a
    10 Hz observer the sensor's numbers are hashed on one sample in ten.
    """
    size = scenario.sensor.noise_size
    return jax.lax.cond(
        jnp.any(due),
        lambda: standard_normal(key, k, size, stream=SENSOR_STREAM),
        lambda: jnp.zeros(size),
    )


def _sample_time(scenario: Scenario, k):
    """t_k from the integer sample index (never accumulated)."""
    return (k * scenario.substeps) * scenario.plant_step


def _sample(scenario: Scenario, carry, k: Array, key: Array):
    """Advance plant, sensor, controller and observer by one sample period."""
    plant, sensor, observer = scenario.plant, scenario.sensor, scenario.observer
    h = scenario.plant_step
    substeps = scenario.substeps
    state, estimate, held, control_state, tau = carry
    t = _sample_time(scenario, k)
    noise = _process_noise(scenario, key, k)

    if scenario.observer_mode == "sampled":
        due = (k % jnp.asarray(scenario.sensor_steps)) == 0
        measured = sensor.measure(state, _sensor_noise(scenario, key, k, due))
        measurement = jnp.where(due, measured, held)
    else:
        measurement = sensor.ideal(state)
    record = (state, estimate, measurement, tau)

    if scenario.observer_mode == "sampled":
        estimate, _ = observer.step(estimate, t, measurement, tau, scenario.sample_period, substeps)

        def substep(x, j):
            field = lambda s, z: plant.vector_field(s, z, tau, noise[j])
            return rk4_step(field, (k * substeps + j) * h, x, h), None

        state, _ = _static_scan(substep, state, jnp.arange(substeps), substeps)
    else:

        def substep(pair, j):
            def field(s, z):
                x, xhat = z
                return (
                    plant.vector_field(s, x, tau, noise[j]),
                    observer.vector_field(s, xhat, sensor.ideal(x), tau),
                )

            return rk4_step(field, (k * substeps + j) * h, pair, h), None

        (state, estimate), _ = _static_scan(substep, (state, estimate), jnp.arange(substeps), substeps)
        estimate = estimate.wrapped()
    # tau_{k+1} from the estimate at t_{k+1}, computed here and carried into the next
    # sample: a loop-carried value is computed once, whereas XLA:CPU recomputes a
    # value made inside the loop body in every kernel that uses it (the thrust's sine
    # was evaluated for each of the 8 integration stages and every run; 22 % faster)
    control_state, tau = scenario.control.step(control_state, _sample_time(scenario, k + 1), estimate)
    return (state.wrapped(), estimate, measurement, control_state, tau), record


def _initial_carry(scenario: Scenario):
    """Plant state, estimate, held sensor samples, controller state and tau_0.

    Every leaf is given its own (strong) dtype: a weakly typed leaf, such as a
    component's output computed from Python floats, would come back strongly typed
    from the first segment and make ``jit`` compile the segment a second time.
    """
    carry = (
        scenario.initial_state,
        scenario.initial_estimate,
        jnp.full(len(scenario.sensor.sample_period), jnp.nan),
        *scenario.control.step(scenario.control.init(), _sample_time(scenario, 0), scenario.initial_estimate),
    )
    return jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype=jnp.result_type(leaf)), carry)


def _segment(scenario: Scenario, key: Array, carry, first_record: Array, n_records: int):
    """Run ``n_records`` recorded groups of ``record_every`` samples from ``first_record``.

    A scan runs over records and, inside, over the ``record_every`` samples of each
    record; only the first sample of each group is recorded.
    """
    every = scenario.record_every

    def one(c, k):
        return _sample(scenario, c, k, key)

    def group(carry, first):
        carry, record = one(carry, first)
        if every > 1:
            carry, _ = _static_scan(
                lambda c, k: (one(c, k)[0], None), carry, first + 1 + jnp.arange(every - 1), every - 1, RECORD_GROUP_UNROLL_LIMIT
            )
        # one flat vector per record: a single write per record instead of one per leaf
        return carry, ravel_pytree(record)[0]

    template = jax.eval_shape(lambda c: _sample(scenario, c, jnp.asarray(0), key)[1], carry)
    unravel = ravel_pytree(jax.tree.map(lambda leaf: jnp.zeros(leaf.shape, leaf.dtype), template))[1]
    carry, flat = jax.lax.scan(group, carry, (first_record + jnp.arange(n_records)) * every)
    return carry, jax.vmap(unravel)(flat)


_segment_jit = eqx.filter_jit(_segment)


@eqx.filter_jit
def _initial_carry_batch(scenario, n_runs: int, batched_scenario: bool):
    axes = eqx.if_array(0) if batched_scenario else None
    return eqx.filter_vmap(_initial_carry, in_axes=(axes,), axis_size=n_runs)(scenario)


@eqx.filter_jit
def _segment_batch(scenario, keys, carry, first_record, n_records: int, batched_scenario: bool):
    axes = eqx.if_array(0) if batched_scenario else None
    run = eqx.filter_vmap(_segment, in_axes=(axes, 0, 0, None, None))
    return run(scenario, keys, carry, first_record, n_records)


def _segments(n_records: int, chunks: int) -> list[int]:
    """Split n_records into at most two distinct lengths (at most two compilations)."""
    size = max(1, n_records // max(1, chunks))
    lengths = [size] * (n_records // size)
    if n_records % size:
        lengths.append(n_records % size)
    return lengths


def _run(step: Callable, carry, n_records: int, progress, chunks: int, time_axis: int):
    """Run all segments, report progress after each, and join the records in time."""
    outputs = []
    first = 0
    lengths = _segments(n_records, chunks) if progress is not None else [n_records]
    for length in lengths:
        carry, records = step(carry, jnp.asarray(first), length)
        outputs.append(records)
        first += length
        if progress is not None:
            jax.block_until_ready(records)
            progress(first, n_records)
    if len(outputs) == 1:
        return outputs[0]
    return jax.tree.map(lambda *parts: jnp.concatenate(parts, axis=time_axis), *outputs)


def _time_grid(scenario: Scenario) -> np.ndarray:
    return np.arange(scenario.n_records) * scenario.record_every * scenario.sample_period


def simulate(scenario: Scenario, key: Array, *, progress=None, chunks: int = 20) -> Trajectory:
    """Simulate one run.

    Parameters
    ----------
    scenario : Scenario
    key : jax.random key
        Seeds process noise, measurement noise and dropouts.
    progress : callable, optional
        ``progress(done, total)`` called after each of about ``chunks`` segments;
        without it the run is a single jitted scan.
    chunks : int
        Number of segments when ``progress`` is given.

    Returns
    -------
    Trajectory
        Recorded states, estimates, measurements and inputs, with time.
    """
    step = lambda carry, first, length: _segment_jit(scenario, key, carry, first, length)
    records = _run(step, _initial_carry(scenario), scenario.n_records, progress, chunks, time_axis=0)
    state, estimate, measurement, tau = records
    return Trajectory(_time_grid(scenario), state, estimate, measurement, tau, attrs=_attrs(scenario))


#: Largest seed a JAX key accepts (it converts the seed to a signed 64-bit integer).
MAX_SEED = 2**63 - 1


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
    if not (isinstance(runs, int) and runs >= 1):
        raise ValueError(f"runs must be a positive integer; got {runs!r}")
    if not (isinstance(seed, int) and 0 <= seed <= MAX_SEED - runs + 1):
        raise ValueError(f"seed must be an integer from 0 to {MAX_SEED - runs + 1} (seeds seed ... seed + runs - 1 must fit a signed 64-bit integer); got {seed!r}")
    return jax.vmap(jax.random.key)(jnp.arange(runs, dtype=jnp.int64) + seed)


def record_nbytes(scenario: Scenario) -> int:
    """Bytes that one recorded sample of one run takes in the results (state,
    estimate, measurement and input), from the shapes the engine records."""
    record = jax.eval_shape(lambda key: _sample(scenario, _initial_carry(scenario), jnp.asarray(0), key)[1], jax.random.key(0))
    return int(sum(leaf.size * leaf.dtype.itemsize for leaf in jax.tree.leaves(record)))


def _shard_runs(tree, n_runs: int):
    """Place the run axis across all devices when it divides evenly (else leave as is).

    Computation follows the data under ``jit``: each device (each CPU core with
    :func:`lookout.use_all_cpu_cores`, or each GPU) simulates its share of the runs.
    Results do not depend on the placement.
    """
    devices = jax.devices()
    if len(devices) < 2 or n_runs % len(devices):
        return tree
    mesh = jax.make_mesh((len(devices),), ("run",), axis_types=(jax.sharding.AxisType.Auto,))
    return jax.device_put(tree, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("run")))


def simulate_batch(
    scenario: Scenario, keys: Array, *, batched_scenario: bool = False, progress=None, chunks: int = 20
) -> Trajectory:
    """Simulate a batch of runs with ``jax.vmap``: one run per key.

    Parameters
    ----------
    scenario : Scenario
        Shared by all runs, or, with ``batched_scenario=True``, every array in it
        has a leading axis of length ``len(keys)`` (parameters, initial
        conditions) built e.g. with ``jax.vmap`` or ``jax.tree.map(jnp.stack, ...)``.
    keys : Array
        Batch of PRNG keys, e.g. ``jax.random.split(key, n_runs)``.
    batched_scenario : bool
        Map over the leading axis of the scenario's arrays too.
    progress, chunks
        As in :func:`simulate`.

    Returns
    -------
    Trajectory
        With a leading run axis on every recorded array.
    """
    n_runs = keys.shape[0]
    keys = _shard_runs(keys, n_runs)
    if batched_scenario:
        scenario = eqx.combine(_shard_runs(eqx.filter(scenario, eqx.is_array), n_runs), eqx.filter(scenario, eqx.is_array, inverse=True))
    carry = _shard_runs(_initial_carry_batch(scenario, n_runs, batched_scenario), n_runs)

    def step(carry, first, length):
        return _segment_batch(scenario, keys, carry, first, length, batched_scenario)

    records = _run(step, carry, scenario.n_records, progress, chunks, time_axis=1)
    # gather the shards onto one device so results index like ordinary arrays
    records = jax.device_put(records, jax.devices()[0])
    state, estimate, measurement, tau = records
    return Trajectory(_time_grid(scenario), state, estimate, measurement, tau, batched=True, attrs=_attrs(scenario))


def _attrs(scenario: Scenario) -> dict:
    return {
        "plant_step_s": scenario.plant_step,
        "sample_period_s": scenario.sample_period,
        "sensor_sample_period_s": list(scenario.sensor.sample_period),
        "record_every": scenario.record_every,
        "observer_mode": scenario.observer_mode,
    }
