"""The sample loop: one run as one jitted nested ``lax.scan``.

Sample k (``t_k = k * sample_period``) of a :class:`~lookout.sim.scenario.Scenario`
runs in this order::

    1. sensor: each channel due at t_k takes a sample of x(t_k); the others hold
    2. observer.update(S, t_k, y_k)                   correction
    3. e_k = observer.output(S, y_k)                  labelled estimate at t_k
    4. r_k = reference.step(R, t_k, dt, normals)
    5. u_k = controller.step(C, t_k, y_k, e_k, r_k, dt)
    6. A, v_k, a_k = actuator.step(A, t_k, u_k, dt)   applied input, actuator outputs
    7. record (plant.variables(x(t_k)), e_k, y_k, r_k, u_k, v_k, a_k)
    8. plant integrated over [t_k, t_k+1] with v_k held (RK4 or Euler substeps of
       ``plant_step``, process noise held over each substep with variance
       1/plant_step), then ``plant.normalize``;
       observer.predict(S, t_k, y_k, v_k, sample_period)

so no component acts on a value one sample stale. At t_0 the observer's state is
``observer.init(y_0, initial_estimate)``. With ``observer_mode="continuous"`` a
:class:`~lookout.components.ContinuousObserver` is instead integrated jointly with
the plant on the noise-free measurement ``sensor.ideal(x)`` (the setting of
continuous-time Lyapunov analyses). What a sample measures of the plant (step 1, and
the truth of step 7) is :func:`sample_measurements`.

Randomness. Every random number of a run is a function of the run's key and of
integer counters: process noise and sensor noise of sample k come from separate
streams of :func:`lookout._random.standard_normal` (``PROCESS_STREAM``,
``SENSOR_STREAM``, ``REFERENCE_STREAM``), and ``plant.realize`` draws the plant's
per-run randomness (wave phases, parameter errors) from a key folded from the run's
key. So batching (:mod:`lookout.sim.batch`), chunking and decimation never change a
run. Time is computed from integer indices, never accumulated.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple, cast

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array
from jax.flatten_util import ravel_pytree
from jax.typing import ArrayLike

from lookout._math import computed_once
from lookout._random import standard_normal
from lookout.components import ContinuousObserver, KinematicSensor, Plant, kinematics_of
from lookout.results import Trajectory
from lookout.sim.integrators import INTEGRATORS
from lookout.sim.memory import check_batch_memory
from lookout.sim.scenario import Scenario, checked_scenario
from lookout.sim.seeds import checked_key

#: Static loops up to this length are unrolled in Python instead of a lax.scan
#: (a one-trip XLA while loop costs more than its body here).
UNROLL_LIMIT = 4
#: The same for the unrecorded samples of a record group: a whole sample is a large
#: body, and XLA:CPU's compile time grows faster than the unrolled body (a 600 s run
#: recorded every 5 samples compiled in 18 s unrolled, 6.3 s as a scan).
RECORD_GROUP_UNROLL_LIMIT = 1
# Streams of lookout._random.standard_normal: the plant's process noise, the
# sensor's noise and the reference's noise of a sample are drawn independently.
PROCESS_STREAM = 0
SENSOR_STREAM = 1
REFERENCE_STREAM = 2
#: Folded into a run's key for ``plant.realize``.
REALIZATION_KEY = 0x5EA


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
    sensor = scenario.sensor
    size = sensor.noise_size
    if isinstance(sensor, KinematicSensor):  # one stream per member: adding one never changes another's draws

        def draw():
            parts = [standard_normal(key, k, count, stream=stream) for stream, count in sensor.noise_streams]
            return jnp.concatenate(parts) if parts else jnp.zeros(0)

    else:

        def draw():
            return standard_normal(key, k, size, stream=SENSOR_STREAM)

    return jax.lax.cond(jnp.any(due), draw, lambda: jnp.zeros(size))


def _sample_time(scenario: Scenario, k):
    """t_k from the integer sample index (never accumulated)."""
    return (k * scenario.substeps) * scenario.plant_step


def _realized_plant(scenario: Scenario, key: Array) -> Plant:
    return scenario.plant.realize(jax.random.fold_in(key, REALIZATION_KEY))


def sample_measurements(
    scenario: Scenario, plant: Plant, state: Any, held: Array | None, t: ArrayLike, k: Array, key: Array
) -> tuple[Any, dict[str, Array]]:
    """What sample k takes of the plant state ``state`` at time ``t``: the sensor
    readings ``y_k`` (the record's measurement; the observer and the controller read
    their channels of it) and ``plant.variables(state)`` (the record's truth). For a
    :class:`~lookout.components.KinematicSensor` the readings come in a
    :class:`SuiteCarry` with the sensor's memory.

    With ``observer_mode="sampled"`` each channel due at sample k (its period, in
    samples, divides k) takes a sample with the sensor's noise of sample k, and the
    others hold ``held``, their last sample (``held=None``: every channel is due, as
    the initial sample is); with ``"continuous"``, the noise-free ``sensor.ideal(state)``.
    """
    sensor = scenario.sensor
    if isinstance(sensor, KinematicSensor):
        return _read_kinematic(scenario, plant, state, held, t, k, key), plant.variables(state)
    if scenario.observer_mode == "sampled":
        if held is None:
            y = sensor.sample(t, state, _sensor_noise(scenario, key, k, jnp.asarray(True)))
        else:
            due = (k % jnp.asarray(scenario.sensor_steps)) == 0
            measured = sensor.sample(t, state, _sensor_noise(scenario, key, k, due))
            y = jnp.where(due, measured, held)
    else:
        y = sensor.ideal(state)
    return y, plant.variables(state)


class SuiteCarry(NamedTuple):
    """What the engine carries for a :class:`~lookout.components.KinematicSensor`: its
    last measurement, its memory, and the input applied over the interval that ends at
    the next sample (the input under which its kinematics are taken)."""

    measurement: Array
    memory: Any
    applied: Array


def _read_kinematic(scenario: Scenario, plant: Plant, state: Any, held: Any, t: ArrayLike, k: Array, key: Array) -> SuiteCarry:
    """Sample k of a kinematic sensor (every channel due at the first sample, ``held``
    None): its kinematics under the input applied since the sample before."""
    sensor = cast(KinematicSensor, scenario.sensor)
    if held is None:
        applied = jnp.zeros(plant.input_layout.size)
        kinematics = kinematics_of(plant, t, state, applied)
        held = SuiteCarry(jnp.full(sensor.measurement_layout.size, jnp.nan), sensor.initial_memory(kinematics), applied)
        due = jnp.ones(sensor.measurement_layout.size, dtype=bool)
    else:
        kinematics = kinematics_of(plant, t, state, held.applied)
        due = (k % jnp.asarray(scenario.sensor_steps)) == 0
    memory, y = sensor.read(held.memory, t, kinematics, _sensor_noise(scenario, key, k, due), due, held.measurement)
    return SuiteCarry(y, memory, held.applied)


def _observed(scenario: Scenario, y: Any) -> Array:
    """The channels of the measurement the observer (and the controller) read, by name."""
    measurement = y.measurement if isinstance(y, SuiteCarry) else y
    channels = scenario.observer_channels
    return measurement if channels is None else measurement[jnp.asarray(channels)]


def _sample(scenario: Scenario, plant: Plant, carry, k: Array, key: Array):
    """One sample period in the order of the module docstring; returns (carry, record)."""
    sensor, observer, reference, controller = scenario.sensor, scenario.observer, scenario.reference, scenario.controller
    h, substeps, dt = scenario.plant_step, scenario.substeps, scenario.sample_period
    integrate = INTEGRATORS[scenario.integrator]
    state, estimate_state, held, reference_state, control_state, actuator_state = carry
    t = _sample_time(scenario, k)
    noise = _process_noise(scenario, key, k)

    held, truth = sample_measurements(scenario, plant, state, held, t, k, key)
    y = _observed(scenario, held)
    estimate_state = observer.update(estimate_state, t, y)
    estimate = observer.output(estimate_state, y)
    reference_noise = standard_normal(key, k, reference.noise_size, stream=REFERENCE_STREAM)
    reference_state, reference_sample = reference.step(reference_state, t, dt, reference_noise)
    control_state, command = controller.step(control_state, t, y, estimate, reference_sample, dt)
    # the applied input is read by every integration stage of plant and observer:
    # computed once (a value made in the loop body is otherwise recomputed by XLA:CPU
    # in every kernel that reads it)
    actuator_state, applied, actuation = scenario.actuator.step(actuator_state, t, command, dt)
    applied = computed_once(applied)
    if isinstance(held, SuiteCarry):
        held = held._replace(applied=applied)
    measured = held.measurement if isinstance(held, SuiteCarry) else held
    record = (truth, estimate, measured, reference_sample, command, applied, actuation)

    if scenario.observer_mode == "sampled":
        estimate_state = observer.predict(estimate_state, t, y, applied, dt)

        def substep(x, j):
            field = lambda s, z: plant.vector_field(s, z, applied, noise[j])
            return integrate(field, (k * substeps + j) * h, x, h), None

        state, _ = _static_scan(substep, state, jnp.arange(substeps), substeps)
    else:

        def substep(pair, j):
            def field(s, z):
                x, xhat = z
                return plant.vector_field(s, x, applied, noise[j]), observer.vector_field(s, xhat, _observed(scenario, sensor.ideal(x)), applied)

            return integrate(field, (k * substeps + j) * h, pair, h), None

        (state, estimate_state), _ = _static_scan(substep, (state, estimate_state), jnp.arange(substeps), substeps)
        estimate_state = cast(ContinuousObserver, observer).normalize(estimate_state)  # Scenario takes "continuous" with a ContinuousObserver only
    return (plant.normalize(state), estimate_state, held, reference_state, control_state, actuator_state), record


def initial_carry(scenario: Scenario, key: Array) -> tuple[Any, Any, Array, Any, Any, Any]:
    """Plant state, observer state, held sensor samples, reference, controller and actuator state.

    The observer starts from ``observer.init(y_0, initial_estimate)`` with y_0 the
    sample that sample 0 takes (the same numbers: the noise is a function of the
    key and the sample index). Every leaf gets its own (strong) dtype: a weakly
    typed leaf would come back strongly typed from the first segment and make
    ``jit`` compile the segment a second time.
    """
    x0 = scenario.initial_state
    held, _ = sample_measurements(scenario, scenario.plant, x0, None, 0.0, jnp.asarray(0), key)
    carry = (
        x0,
        scenario.observer.init(_observed(scenario, held), scenario.initial_estimate),
        held,
        scenario.reference.init(),
        scenario.controller.init(),
        scenario.actuator.init(),
    )
    return jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype=jnp.result_type(leaf)), carry)


class Summary(eqx.Module):
    """What a run keeps instead of its records (:func:`~lookout.sim.batch.summarize_batch`).

    The engine calls :meth:`init` once with the shapes of a record, then, at every
    recorded sample i (in order), ``accumulated, series_i = update(accumulated, i,
    record)``, and keeps every ``series_i`` (None keeps nothing); ``record`` is
    ``(truth, estimate, measurement, reference, command, applied, actuation)`` of one run, as
    :class:`~lookout.Trajectory` holds them without the run and time axes.
    Subclasses hold only static configuration (one compiled program per
    configuration).
    """

    def init(self, record: Any) -> Any:
        raise NotImplementedError

    def update(self, accumulated: Any, index: Array, record: Any) -> tuple[Any, Any]:
        raise NotImplementedError


def segment(scenario: Scenario, key: Array, carry: Any, first_record: Array, n_records: int, summary: Summary | None = None) -> tuple[Any, Any]:
    """Run ``n_records`` recorded groups of ``record_every`` samples from ``first_record``.

    A scan runs over records and, inside, over the ``record_every`` samples of each
    record; only the first sample of each group is recorded. With a ``summary`` (a
    whole run in one segment) the scan keeps ``summary``'s accumulation and series
    instead of the records: returns ``(carry, (accumulated, series))``.
    """
    every = scenario.record_every
    plant = _realized_plant(scenario, key)

    def one(c, k):
        return _sample(scenario, plant, c, k, key)

    def group(carry, index):
        if summary is not None:
            carry, accumulated = carry
        first = index * every
        carry, record = one(carry, first)
        if every > 1:
            carry, _ = _static_scan(lambda c, k: (one(c, k)[0], None), carry, first + 1 + jnp.arange(every - 1), every - 1, RECORD_GROUP_UNROLL_LIMIT)
        if summary is not None:
            accumulated, series = summary.update(accumulated, index, record)
            return (carry, accumulated), series
        # one flat vector per record: a single write per record instead of one per leaf
        flat, unravel = ravel_pytree(record)
        unravels.append(unravel)
        return carry, flat

    indices = first_record + jnp.arange(n_records)
    if summary is not None:
        template = jax.eval_shape(lambda c: one(c, jnp.asarray(0))[1], carry)
        (carry, accumulated), series = jax.lax.scan(group, (carry, summary.init(template)), indices)
        return carry, (accumulated, series)
    # the record's structure comes out of the scan body's one trace (an unravel holds
    # shapes and dtypes, no tracer): a sample is traced once, not again for its shapes
    unravels: list = []
    carry, flat = jax.lax.scan(group, carry, indices)
    return carry, jax.vmap(unravels[-1])(flat)


_segment_jit = eqx.filter_jit(segment)
_initial_carry_jit = eqx.filter_jit(initial_carry)


def _segments(n_records: int, chunks: int) -> list[int]:
    """Split n_records into at most two distinct lengths (at most two compilations)."""
    size = max(1, n_records // max(1, chunks))
    lengths = [size] * (n_records // size)
    if n_records % size:
        lengths.append(n_records % size)
    return lengths


def run_segments(step: Callable, carry: Any, n_records: int, progress: Callable[[int, int], object] | None, chunks: int, time_axis: int) -> Any:
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


def make_trajectory(scenario: Scenario, records: Any, batched: bool) -> Trajectory:
    truth, estimate, measurement, reference, command, applied, actuation = records
    return Trajectory(
        scenario.record_times,
        truth,
        estimate,
        measurement,
        reference,
        command,
        applied,
        signals=scenario.record_signals,
        batched=batched,
        attrs=_attrs(scenario),
        actuation=actuation,
    )


def simulate(scenario: Scenario, key: Array, *, progress: Callable[[int, int], object] | None = None, chunks: int = 20) -> Trajectory:
    """Simulate one run.

    Parameters
    ----------
    scenario : Scenario
    key : jax.random key
        Seeds process noise, measurement noise, dropouts and the plant's realization.
    progress : callable, optional
        ``progress(done, total)`` called after each of about ``chunks`` segments;
        without it the run is a single jitted scan.
    chunks : int
        Number of segments when ``progress`` is given.

    Returns
    -------
    Trajectory
        Recorded truths, estimates, measurements, references and inputs, with time.
    """
    checked_scenario(scenario)
    key = checked_key(key)
    check_batch_memory(scenario, 1, "scenario")
    step = lambda carry, first, length: _segment_jit(scenario, key, carry, first, length)
    records = run_segments(step, _initial_carry_jit(scenario, key), scenario.n_records, progress, chunks, time_axis=0)
    return make_trajectory(scenario, records, batched=False)


def _attrs(scenario: Scenario) -> dict:
    return {
        "plant_step_s": scenario.plant_step,
        "sample_period_s": scenario.sample_period,
        "sensor_sample_period_s": list(scenario.sensor.sample_period),
        "record_every": scenario.record_every,
        "integrator": scenario.integrator,
        "observer_mode": scenario.observer_mode,
        "plant": type(scenario.plant).__name__,
        "sensor": type(scenario.sensor).__name__,
        "observer": type(scenario.observer).__name__,
        "controller": type(scenario.controller).__name__,
        "reference": type(scenario.reference).__name__,
        "actuator": type(scenario.actuator).__name__,
    }
