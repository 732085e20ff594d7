"""The sampled-data simulation engine: one jitted nested ``lax.scan`` per run.

A :class:`Scenario` holds the components of :mod:`lookout.components` (plant,
sensor, observer, reference, controller, actuator), the initial plant state, the
observer's initial guess and the time grid. Sample k (``t_k = k * sample_period``)
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
continuous-time Lyapunov analyses).

Randomness. Every random number of a run is a function of the run's key and of
integer counters: process noise and sensor noise of sample k come from separate
streams of :func:`lookout._random.standard_normal` (``PROCESS_STREAM``,
``SENSOR_STREAM``, ``REFERENCE_STREAM``), and ``plant.realize`` draws the plant's
per-run randomness (wave phases, parameter errors) from a key folded from the run's
key. So batching, chunking and decimation never change a run.

Time is computed from integer indices, never accumulated. Batches are ``jax.vmap``
of the same function over keys (and optionally over the leading axis of every array
in the scenario), with the run axis sharded across devices when there are several.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.flatten_util import ravel_pytree

from lookout._math import computed_once
from lookout._random import MAX_COUNT, standard_normal
from lookout._resources import format_bytes, refuse_unless_it_fits
from lookout._validation import FitError, ParameterError, is_concrete, key
from lookout.components import Actuator, ContinuousObserver, Controller, Observer, Plant, Reference, Sensor, Signal
from lookout.declare import kind_of
from lookout.null_components import IdealActuator, NoReference
from lookout.results import RecordSignals, Trajectory
from lookout.sim.integrators import INTEGRATORS


def integer_ratio(value: float, base: float) -> int | None:
    """``value / base`` when it is a positive whole number (to 1e-9 relative), else None."""
    ratio = value / base
    steps = int(round(ratio))
    if steps < 1 or abs(ratio - steps) > 1e-9 * max(1.0, ratio):
        return None
    return steps


def _ratio(name: str, period: float, base_name: str, base: float, location: tuple = ()) -> int:
    steps = integer_ratio(period, base)
    if steps is None:
        raise ParameterError(location or (key(name),), f"{name} ({period:g} s) must be an integer multiple of {base_name} ({base:g} s)")
    return steps


#: The fields in which a component carries the loop's sample period it was built for: a
#: discrete-time observer's ``sample_period`` (the Observer contract), a Kalman filter's
#: ``filter_period`` (the composition's context of that name).
OWN_PERIODS = ("sample_period", "filter_period")


def _same_period(role: str, component, sample_period: float) -> None:
    """Refuse a component built for another loop period than the scenario's."""
    for name in OWN_PERIODS:
        period = getattr(component, name, None)
        if isinstance(period, (int, float)) and not isinstance(period, bool) and abs(period - sample_period) > 1e-9 * sample_period:
            raise ParameterError(
                (role, name),
                f"{role} {name} ({period:g} s) must equal the loop's sample_period ({sample_period:g} s): "
                f"the {role} is built for one sample period; build it for {sample_period:g} s, or run the loop at {period:g} s",
            )


def _first_line(error: Exception) -> str:
    text = str(error).strip().splitlines()
    return text[0] if text else type(error).__name__


def _shape_of(value) -> tuple[int, ...]:
    return tuple(getattr(value, "shape", np.shape(value)))


class Scenario(eqx.Module):
    """Everything one run needs: components, initial conditions and time grid.

    Parameters
    ----------
    plant : Plant
    sensor : Sensor
    observer : Observer
    controller : Controller
        Computes the plant's input at each sample (an open-loop input or
        :class:`~lookout.controllers.NoControl` for none).
    initial_state : PyTree
        Plant state at t = 0.
    initial_estimate : PyTree
        The observer's initial guess, turned into its state by ``observer.init``.
    plant_step : float
        Integration step of the plant (s).
    sample_period : float
        Observer, reference and controller period (s), a multiple of ``plant_step``.
    duration : float
        Simulated time (s), a multiple of ``sample_period * record_every``.
    reference : Reference
        Default :class:`~lookout.reference.NoReference`.
    actuator : Actuator
        Default :class:`~lookout.actuators.IdealActuator`.
    record_every : int
        Record one sample in this many.
    integrator : {"rk4", "euler"}
        The plant's integrator.
    observer_mode : {"sampled", "continuous"}
        ``"continuous"`` integrates a ContinuousObserver jointly with the plant on
        the noise-free measurement.

    Raises
    ------
    ValueError
        When the time grid is inconsistent, or two components do not fit (the
        message names both), checked with ``jax.eval_shape`` on one sample.
    """

    plant: Plant
    sensor: Sensor
    observer: Observer
    controller: Controller
    initial_state: Any
    initial_estimate: Any
    plant_step: float = eqx.field(static=True)
    sample_period: float = eqx.field(static=True)
    duration: float = eqx.field(static=True)
    reference: Reference = NoReference()
    actuator: Actuator = IdealActuator()
    record_every: int = eqx.field(static=True, default=1)
    integrator: Literal["rk4", "euler"] = eqx.field(static=True, default="rk4")
    observer_mode: Literal["sampled", "continuous"] = eqx.field(static=True, default="sampled")

    def __check_init__(self):
        for name, kind in (
            ("plant", Plant),
            ("sensor", Sensor),
            ("observer", Observer),
            ("controller", Controller),
            ("reference", Reference),
            ("actuator", Actuator),
        ):
            value = getattr(self, name)
            if not isinstance(value, kind):
                raise ValueError(f"{name} must be a lookout {kind.__name__}; got {type(value).__name__}")
        if not (math.isfinite(self.plant_step) and self.plant_step > 0):
            raise ParameterError("plant_step", f"plant_step must be positive; got {self.plant_step}")
        if not (math.isfinite(self.sample_period) and self.sample_period > 0):
            raise ParameterError("sample_period", f"sample_period must be positive; got {self.sample_period}")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ParameterError("duration", f"duration must be positive; got {self.duration}")
        if not (isinstance(self.record_every, int) and self.record_every >= 1):
            raise ParameterError("record_every", f"record_every must be a positive integer; got {self.record_every}")
        if self.integrator not in INTEGRATORS:
            raise ParameterError("integrator", f"integrator must be one of {sorted(INTEGRATORS)}; got {self.integrator!r}")
        if self.observer_mode not in ("sampled", "continuous"):
            raise ParameterError("observer_mode", f"observer_mode must be 'sampled' or 'continuous'; got {self.observer_mode!r}")
        if self.observer_mode == "continuous" and not isinstance(self.observer, ContinuousObserver):
            raise ParameterError(
                "observer_mode", f"observer_mode 'continuous' needs a ContinuousObserver; observer {kind_of(self.observer)} is not one"
            )
        substeps = _ratio("sample_period", self.sample_period, "plant_step", self.plant_step)
        if substeps * self.plant.noise_size > MAX_COUNT:  # the process noise of a sample is one draw
            most = MAX_COUNT // max(1, self.plant.noise_size)
            raise ParameterError(
                "plant_step",
                f"plant_step ({self.plant_step:g} s) makes {substeps} plant steps per sample of {self.sample_period:g} s; at most {most} "
                f"({self.plant.noise_size} process noise inputs each): a plant_step of at least {self.sample_period / most:.3g} s",
            )
        for role in ("observer", "controller"):
            _same_period(role, getattr(self, role), self.sample_period)
        if len(self.sensor.sample_period) != self.sensor.measurement_layout.size:
            raise ValueError(f"sensor has {len(self.sensor.sample_period)} sample periods for {self.sensor.measurement_layout.size} channels")
        for channel, period in enumerate(self.sensor.sample_period):
            _ratio(f"sensor sample_period[{channel}]", period, "sample_period", self.sample_period, ("sensor", "sample_period"))
        outage = getattr(self.sensor, "outage", None)
        if outage is not None and is_concrete(outage.start) and is_concrete(outage.duration):
            start, length = np.asarray(outage.start, dtype=float), np.asarray(outage.duration, dtype=float)
            if np.any((length > 0) & (start >= self.duration)):  # it would silence nothing
                raise ParameterError(
                    ("sensor", "outage_start"),
                    f"sensor outage_start ({float(np.max(start)):g} s) must be before the run's end (duration {self.duration:g} s) for an outage to happen",
                )
        _ratio("duration", self.duration, "sample_period * record_every", self.sample_period * self.record_every)
        if self.duration / self.sample_period >= 2**32:
            raise ParameterError(
                "duration", f"duration / sample_period must be below 2**32 samples (noise counters); got {self.duration / self.sample_period:.3g}"
            )
        check_fit(self)

    @property
    def substeps(self) -> int:
        """Plant integration steps per sample period."""
        return _ratio("sample_period", self.sample_period, "plant_step", self.plant_step)

    @property
    def n_records(self) -> int:
        """Number of recorded samples."""
        return _ratio("duration", self.duration, "sample_period * record_every", self.sample_period * self.record_every)

    @property
    def sensor_steps(self) -> tuple[int, ...]:
        """Sample periods of the sensor channels, in observer samples."""
        return tuple(_ratio("sensor", p, "sample_period", self.sample_period) for p in self.sensor.sample_period)

    @property
    def record_times(self) -> np.ndarray:
        """Times of the recorded samples (s), from their integer indices."""
        return np.arange(self.n_records) * self.record_every * self.sample_period

    @property
    def record_signals(self) -> RecordSignals:
        """Names, units and frames of everything a run records."""
        return RecordSignals(
            truth=tuple(self.plant.variable_signals),
            estimate=tuple(self.observer.estimate_signals),
            extra=tuple(self.observer.extra_signals),
            measurement=self.sensor.measurement_layout,
            reference=tuple(self.reference.reference_signals),
            input=self.plant.input_layout,
            actuation=tuple(self.actuator.output_signals),
        )


def _compare(part: str, other: str, what: str, got: dict, signals: tuple[Signal, ...]) -> None:
    """Fail unless ``got`` (name -> shape) has exactly the names and shapes of ``signals``."""
    expected = {s.name: s.shape for s in signals}
    if set(got) != set(expected):
        raise FitError((part, other), f"{part} and {other} disagree: {what} gives {sorted(got)}, its signals declare {sorted(expected)}")
    for name, shape in expected.items():
        if tuple(got[name]) != shape:
            raise FitError((part, other), f"{part} and {other} disagree: {what} {name!r} has shape {tuple(got[name])}, its signal says {shape}")


def _evaluate(parts: tuple[str, str], function: Callable, *args):
    """``jax.eval_shape(function, *args)``; any failure deep in the trace becomes one
    line that names the two parts."""
    try:
        return jax.eval_shape(function, *args)
    except Exception as error:
        raise FitError(parts, f"{parts[0]} and {parts[1]} do not fit: {_first_line(error)}") from None


#: Scenarios that fit, by :func:`structure_key`: the points of a sweep (the same
#: components with other numbers) are traced once, not once each.
_FITTING: set = set()


def structure_key(scenario: Scenario):
    """What a scenario is apart from its numbers: the tree's structure (component
    types and static fields) and each leaf's type, shape and dtype. It decides
    :func:`check_fit` (which traces shapes only) and, for array leaves, which
    compiled program a batch runs. None when a static field cannot be hashed."""
    leaves, treedef = jax.tree.flatten(scenario)
    key = (treedef, tuple((type(leaf), np.shape(leaf), jnp.result_type(leaf)) for leaf in leaves))
    try:
        hash(key)
    except TypeError:
        return None
    return key


def check_fit(scenario: Scenario) -> None:
    """Check with ``jax.eval_shape`` that the scenario's components fit one another.

    Each failure is one ``ValueError`` line that names the two parts that disagree:
    the plant and its initial state, the sensor and the plant, the observer and the
    sensor or the plant, the reference, the controller and the plant's input, the
    actuator. A scenario that differs from one found fitting only in its numbers is
    not traced again.
    """
    key = structure_key(scenario)
    if key is not None and key in _FITTING:
        return
    _check_fit(scenario)
    if key is not None:
        _FITTING.add(key)


def _check_fit(scenario: Scenario) -> None:
    plant, sensor, observer = scenario.plant, scenario.sensor, scenario.observer
    x0 = scenario.initial_state
    layout = plant.input_layout
    u0 = jnp.zeros(layout.size)
    w0 = jnp.zeros(plant.noise_size)

    truth = _evaluate(("plant", "initial_state"), plant.variables, x0)
    _compare("plant", "initial_state", "plant.variables(initial_state)", {k: _shape_of(v) for k, v in truth.items()}, plant.variable_signals)
    derivative = _evaluate(("plant", "initial_state"), lambda x: plant.vector_field(0.0, x, u0, w0), x0)
    if jax.tree.structure(derivative) != jax.tree.structure(x0) or [_shape_of(a) for a in jax.tree.leaves(derivative)] != [
        _shape_of(a) for a in jax.tree.leaves(x0)
    ]:
        raise FitError(("plant", "initial_state"), "plant and initial_state disagree: plant.vector_field returns a state shaped unlike initial_state")

    check_sensor_fit(sensor, x0)
    y = jnp.zeros(sensor.measurement_layout.size)
    measured = set(sensor.measurement_layout.names)
    for name in observer.measurement_layout.names:
        if name not in measured:
            raise ParameterError(
                "observer",
                f"observer {kind_of(observer)} needs measurement {name}, which sensor {kind_of(sensor)} does not measure (it measures {', '.join(sensor.measurement_layout.names)})",
            )
    if observer.measurement_layout.names != sensor.measurement_layout.names:  # observers read y by position
        raise ValueError(
            f"observer {kind_of(observer)} reads the measurement ({', '.join(observer.measurement_layout.names)}), "
            f"and sensor {kind_of(sensor)} gives ({', '.join(sensor.measurement_layout.names)}): a sensor of exactly these channels is needed"
        )

    state = _evaluate(("observer", "initial_estimate"), observer.init, y, scenario.initial_estimate)
    estimate = _evaluate(("observer", "sensor"), lambda s: observer.output(observer.update(s, 0.0, y), y), state)
    outputs = tuple(observer.estimate_signals) + tuple(observer.extra_signals)
    _compare("observer", "its signals", "observer.output", {k: _shape_of(v) for k, v in estimate.items()}, outputs)
    plant_signals = {s.name: s for s in plant.variable_signals}
    for signal in observer.estimate_signals:
        truth_signal = plant_signals.get(signal.name)
        if truth_signal is None:
            # a quantity the plant does not model (a bias estimate on a plant without a
            # bias): recorded as an estimate without a truth, and no error is taken of it
            continue
        if (truth_signal.shape, truth_signal.units, truth_signal.labels) != (signal.shape, signal.units, signal.labels):
            raise FitError(
                ("observer", "plant"),
                f"observer and plant disagree: the estimate {signal.name!r} is {signal.shape} in {signal.units} over {signal.labels}, "
                f"the plant's is {truth_signal.shape} in {truth_signal.units} over {truth_signal.labels}",
            )
    inputs = set(layout.names)
    for name in observer.input_layout.names:
        if name not in inputs:
            raise ParameterError(
                "observer",
                f"observer {kind_of(observer)} needs input {name}, which plant {kind_of(plant)} does not take (it takes {', '.join(layout.names)})",
            )
    predicted = _evaluate(("observer", "plant"), lambda s: observer.predict(s, 0.0, y, u0, scenario.sample_period), state)
    if scenario.observer_mode == "continuous":
        _evaluate(("observer", "observer_mode 'continuous'"), lambda s: observer.vector_field(0.0, s, y, u0), state)
    if jax.tree.structure(predicted) != jax.tree.structure(state):
        raise FitError(("observer", "plant"), "observer and plant disagree: observer.predict returns a state shaped unlike observer.init's")

    reference = scenario.reference
    _, sample = _evaluate(
        ("reference", "scenario"), lambda: reference.step(reference.init(), 0.0, scenario.sample_period, jnp.zeros(reference.noise_size))
    )
    _compare("reference", "its signals", "reference.step", {k: _shape_of(v) for k, v in sample.items()}, reference.reference_signals)
    sample = {s.name: jnp.zeros(s.shape) for s in reference.reference_signals}

    controller = scenario.controller
    _check_needs(controller, "estimate", controller.estimate_needs, set(estimate), ("observer", observer, "does not provide"))
    _check_needs(controller, "measurement", controller.measurement_needs, measured, ("sensor", sensor, "does not measure"))
    _check_needs(controller, "reference", controller.reference_needs, set(sample), ("reference", reference, "does not provide"))
    outputs = {k: jnp.zeros(_shape_of(v)) for k, v in estimate.items()}
    _, u = _evaluate(("controller", "plant"), lambda: controller.step(controller.init(), 0.0, y, outputs, sample, scenario.sample_period))
    if _shape_of(u) != (layout.size,):
        raise FitError(
            ("controller", "plant"),
            f"controller and plant disagree: the controller's input has shape {_shape_of(u)}, the plant takes ({layout.size},)",
        )
    actuator = scenario.actuator
    _, applied, outputs = _evaluate(("actuator", "plant"), lambda: actuator.step(actuator.init(), 0.0, u0, scenario.sample_period))
    _compare("actuator", "its signals", "actuator.step", {k: _shape_of(v) for k, v in outputs.items()}, actuator.output_signals)
    if _shape_of(applied) != (layout.size,):
        raise FitError(
            ("actuator", "plant"), f"actuator and plant disagree: the applied input has shape {_shape_of(applied)}, the plant takes ({layout.size},)"
        )


def check_sensor_fit(sensor, state) -> None:
    """Check with ``jax.eval_shape`` that ``sensor`` measures a plant whose state is
    ``state`` (a state or its ``jax.eval_shape``): a :class:`FitError` of the sensor
    and the plant otherwise (the check :func:`check_fit` makes of a scenario's)."""
    y = _evaluate(("sensor", "plant"), lambda x: sensor.measure(x, jnp.zeros(sensor.noise_size)), state)
    if _shape_of(y) != (sensor.measurement_layout.size,):
        raise FitError(
            ("sensor", "plant"),
            f"sensor and plant disagree: the measurement has shape {_shape_of(y)}, the sensor's layout says ({sensor.measurement_layout.size},)",
        )


def _check_needs(controller, what: str, needs, provided: set, provider: tuple) -> None:
    """Fail, naming the signal and both parts, unless every signal the controller needs is
    provided; ``provider`` is (its role, the component, the verb of a refusal)."""
    for name in needs:
        if name not in provided:
            role, component, verb = provider
            given = ", ".join(sorted(provided)) or "nothing"
            raise ParameterError(
                "controller", f"controller {kind_of(controller)} needs {what} {name}, which {role} {kind_of(component)} {verb} (it gives {given})"
            )


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
    size = scenario.sensor.noise_size
    return jax.lax.cond(
        jnp.any(due),
        lambda: standard_normal(key, k, size, stream=SENSOR_STREAM),
        lambda: jnp.zeros(size),
    )


def _sample_time(scenario: Scenario, k):
    """t_k from the integer sample index (never accumulated)."""
    return (k * scenario.substeps) * scenario.plant_step


def _realized_plant(scenario: Scenario, key: Array) -> Plant:
    return scenario.plant.realize(jax.random.fold_in(key, REALIZATION_KEY))


def _sample(scenario: Scenario, plant: Plant, carry, k: Array, key: Array):
    """One sample period in the order of the module docstring; returns (carry, record)."""
    sensor, observer, reference, controller = scenario.sensor, scenario.observer, scenario.reference, scenario.controller
    h, substeps, dt = scenario.plant_step, scenario.substeps, scenario.sample_period
    integrate = INTEGRATORS[scenario.integrator]
    state, estimate_state, held, reference_state, control_state, actuator_state = carry
    t = _sample_time(scenario, k)
    noise = _process_noise(scenario, key, k)

    if scenario.observer_mode == "sampled":
        due = (k % jnp.asarray(scenario.sensor_steps)) == 0
        measured = sensor.sample(t, state, _sensor_noise(scenario, key, k, due))
        y = jnp.where(due, measured, held)
    else:
        y = sensor.ideal(state)
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
    record = (plant.variables(state), estimate, y, reference_sample, command, applied, actuation)

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
                return plant.vector_field(s, x, applied, noise[j]), observer.vector_field(s, xhat, sensor.ideal(x), applied)

            return integrate(field, (k * substeps + j) * h, pair, h), None

        (state, estimate_state), _ = _static_scan(substep, (state, estimate_state), jnp.arange(substeps), substeps)
        estimate_state = observer.normalize(estimate_state)
    return (plant.normalize(state), estimate_state, y, reference_state, control_state, actuator_state), record


def _initial_carry(scenario: Scenario, key: Array):
    """Plant state, observer state, held sensor samples, reference, controller and actuator state.

    The observer starts from ``observer.init(y_0, initial_estimate)`` with y_0 the
    sample that sample 0 takes (the same numbers: the noise is a function of the
    key and the sample index). Every leaf gets its own (strong) dtype: a weakly
    typed leaf would come back strongly typed from the first segment and make
    ``jit`` compile the segment a second time.
    """
    x0 = scenario.initial_state
    if scenario.observer_mode == "sampled":
        y0 = scenario.sensor.sample(0.0, x0, _sensor_noise(scenario, key, jnp.asarray(0), jnp.asarray(True)))
    else:
        y0 = scenario.sensor.ideal(x0)
    carry = (
        x0,
        scenario.observer.init(y0, scenario.initial_estimate),
        y0,
        scenario.reference.init(),
        scenario.controller.init(),
        scenario.actuator.init(),
    )
    return jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype=jnp.result_type(leaf)), carry)


class Summary(eqx.Module):
    """What a run keeps instead of its records (:func:`summarize_batch`).

    The engine calls :meth:`init` once with the shapes of a record, then, at every
    recorded sample i (in order), ``accumulated, series_i = update(accumulated, i,
    record)``, and keeps every ``series_i`` (None keeps nothing); ``record`` is
    ``(truth, estimate, measurement, reference, command, applied, actuation)`` of one run, as
    :class:`~lookout.Trajectory` holds them without the run and time axes.
    Subclasses hold only static configuration (one compiled program per
    configuration).
    """

    def init(self, record) -> Any:
        raise NotImplementedError

    def update(self, accumulated, index: Array, record) -> tuple[Any, Any]:
        raise NotImplementedError


def _segment(scenario: Scenario, key: Array, carry, first_record: Array, n_records: int, summary: Summary | None = None):
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


_segment_jit = eqx.filter_jit(_segment)
_initial_carry_jit = eqx.filter_jit(_initial_carry)


@eqx.filter_jit
def _initial_carry_batch(scenario, keys, batched_scenario: bool):
    axes = eqx.if_array(0) if batched_scenario else None
    return eqx.filter_vmap(_initial_carry, in_axes=(axes, 0))(scenario, keys)


@eqx.filter_jit
def _segment_batch(scenario, keys, carry, first_record, n_records: int, batched_scenario: bool, summary: Summary | None = None):
    axes = eqx.if_array(0) if batched_scenario else None
    run = eqx.filter_vmap(lambda s, k, c, f: _segment(s, k, c, f, n_records, summary), in_axes=(axes, 0, 0, None))
    return run(scenario, keys, carry, first_record)


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


def _trajectory(scenario: Scenario, records, batched: bool) -> Trajectory:
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


def simulate(scenario: Scenario, key: Array, *, progress=None, chunks: int = 20) -> Trajectory:
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
    _checked_scenario(scenario)
    key = checked_key(key)
    check_batch_memory(scenario, 1, "scenario")
    step = lambda carry, first, length: _segment_jit(scenario, key, carry, first, length)
    records = _run(step, _initial_carry_jit(scenario, key), scenario.n_records, progress, chunks, time_axis=0)
    return _trajectory(scenario, records, batched=False)


#: Largest seed a JAX key accepts (it converts the seed to a signed 64-bit integer).
MAX_SEED = 2**63 - 1


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
        if jax.tree.structure(scenario) != first or [np.shape(a) for a in jax.tree.leaves(scenario)] != [
            np.shape(a) for a in jax.tree.leaves(scenarios[0])
        ]:
            raise ValueError(
                f"scenarios[{index}] differs from scenarios[0] in its structure (periods, durations, component types or sizes): "
                "stacked scenarios may differ in their numbers only"
            )
    leaves = [leaf for leaf in jax.tree.leaves(scenarios[0]) if eqx.is_array_like(leaf)]
    per_run = sum(np.asarray(leaf).nbytes for leaf in leaves)
    refuse_unless_it_fits(len(scenarios) * per_run, f"scenarios: {len(scenarios)} stacked x {per_run} B of arrays", "stack fewer scenarios at a time")
    return jax.tree.map(lambda *leaves: jnp.stack([jnp.asarray(leaf) for leaf in leaves]), *scenarios)


def keys_of_seeds(seeds) -> Array:
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


def record_nbytes(scenario: Scenario) -> int:
    """Bytes that one recorded sample of one run takes in the results (truths,
    estimate, measurement, reference and inputs), from the signals the components
    declare (the fit check made sure the records have those shapes), without a trace."""
    signals = scenario.record_signals
    size = sum(s.size for s in (*signals.truth, *signals.estimate, *signals.extra, *signals.reference, *signals.actuation))
    return int((size + signals.measurement.size + 2 * signals.input.size) * jnp.zeros(()).dtype.itemsize)


#: A batch holds its records at least twice at its peak (the scan's output and the
#: joined or gathered copy); below that, a batch is refused before it starts.
RECORD_COPIES = 2
#: Bytes a key and its seed take while :func:`seed_keys` makes them.
KEY_BYTES = 16
#: Bytes a run's scan holds per record whatever the number of runs (the record times
#: and indices, a metric window): measured about 20 B (a 3e7-record summary held
#: 0.55 GB above the runtime).
RECORD_OVERHEAD_BYTES = 32


def _describe_key(value) -> str:
    if isinstance(value, jax.Array):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    return type(value).__name__


def _is_typed_key(value) -> bool:
    return isinstance(value, jax.Array) and jnp.issubdtype(value.dtype, jax.dtypes.prng_key)


def _is_raw_key(value, batch: bool) -> bool:
    return isinstance(value, jax.Array) and value.dtype == jnp.uint32 and value.ndim == (2 if batch else 1) and value.shape[-1] == 2


def checked_key(key) -> Array:
    """``key`` if it is one PRNG key (typed, or a raw uint32 pair); else a ValueError."""
    if (_is_typed_key(key) and key.ndim == 0) or _is_raw_key(key, batch=False):
        return key
    hint = ": a batch of keys goes to simulate_batch" if (_is_typed_key(key) and key.ndim == 1) or _is_raw_key(key, batch=True) else ""
    raise ValueError(f"key must be one JAX PRNG key (jax.random.key(seed), or lookout.seed_keys(seed, 1)[0]); got {_describe_key(key)}{hint}")


def checked_keys(keys) -> Array:
    """``keys`` if it is a 1-D batch of PRNG keys; else a ValueError."""
    if (_is_typed_key(keys) and keys.ndim == 1 and keys.shape[0] >= 1) or (_is_raw_key(keys, batch=True) and keys.shape[0] >= 1):
        return keys
    raise ValueError(f"keys must be a 1-D batch of JAX PRNG keys, one per run (lookout.seed_keys(seed, runs)); got {_describe_key(keys)}")


def _checked_scenario(scenario, keys: Array | None = None, batched_scenario: bool = False) -> None:
    """Refuse, in one line, a scenario that is not one, a batched scenario whose run axis
    is not the keys', and a scenario stacked per run given without ``batched_scenario``."""
    if not isinstance(scenario, Scenario):
        raise ValueError(f"scenario must be a lookout Scenario (lookout.sim.Scenario, or a paper's build(config)); got {type(scenario).__name__}")
    arrays = [leaf for leaf in jax.tree.leaves(eqx.filter(scenario, eqx.is_array))]
    leading = {int(leaf.shape[0]) if leaf.ndim else None for leaf in arrays}
    if batched_scenario:
        runs = int(keys.shape[0])
        if leading != {runs}:
            shown = ", ".join("scalars" if size is None else str(size) for size in sorted(leading, key=lambda size: -1 if size is None else size))
            raise ValueError(
                f"scenario: with batched_scenario=True every array of the scenario needs a leading run axis of {runs} (one per key); its arrays lead with {shown}"
            )
        check_fit(jax.tree.map(lambda leaf: leaf[0], scenario))
        return
    try:
        check_fit(scenario)
    except ValueError as error:
        stacked = len(leading) == 1 and None not in leading and len(arrays) > 1
        raise ValueError(
            f"scenario: {error}" + ("; a scenario stacked per run (stack_scenarios) needs batched_scenario=True" if stacked else "")
        ) from None


def working_nbytes(scenario: Scenario) -> int:
    """Bytes one run holds while it takes a sample, beyond its records: the process noise
    of the sample's plant steps, and what its components declare (a component's
    ``working_nbytes``: a Kalman filter's Jacobians, a thruster allocation's matrices)."""
    own = scenario.substeps * scenario.plant.noise_size * jnp.zeros(()).dtype.itemsize
    parts = (scenario.plant, scenario.sensor, scenario.observer, scenario.reference, scenario.controller, scenario.actuator)
    return int(own + sum(int(getattr(part, "working_nbytes", 0)) for part in parts))


def check_batch_memory(scenario: Scenario, runs: int, argument: str = "keys", available: float | None = None) -> None:
    """Refuse (ValueError naming ``argument``) a batch of ``runs`` whose records and
    working memory cannot fit in the memory available now, before anything is allocated."""
    per_record = record_nbytes(scenario)
    working = working_nbytes(scenario)
    need = scenario.n_records * (RECORD_COPIES * runs * per_record + RECORD_OVERHEAD_BYTES) + runs * working
    refuse_unless_it_fits(
        need,
        f"{argument}: {runs} run(s) x {scenario.n_records} records x {per_record} B (x{RECORD_COPIES} at the peak, + {RECORD_OVERHEAD_BYTES} B per record)"
        + (f" + {runs} x {format_bytes(working)} while a sample is taken" if working > 2**20 else ""),
        "simulate fewer runs at a time, a shorter duration, or fewer records (record_every); a campaign (lookout.studies) runs them in chunks",
        available=available,
    )


def _shard_runs(tree, n_runs: int):
    """Place the run axis across all devices when it divides evenly (else leave as is).

    Computation follows the data under ``jit``: each device (each CPU core with
    :func:`lookout.configure_cpu`, or each GPU) simulates its share of the runs.
    Results do not depend on the placement.
    """
    devices = jax.devices()
    if len(devices) < 2 or n_runs % len(devices):
        return tree
    mesh = jax.make_mesh((len(devices),), ("run",), axis_types=(jax.sharding.AxisType.Auto,))
    return jax.device_put(tree, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("run")))


def _sharded_batch(scenario: Scenario, keys: Array, batched_scenario: bool):
    """The batch's scenario, keys and initial carry, with the run axis across devices."""
    n_runs = keys.shape[0]
    keys = _shard_runs(keys, n_runs)
    if batched_scenario:
        scenario = eqx.combine(_shard_runs(eqx.filter(scenario, eqx.is_array), n_runs), eqx.filter(scenario, eqx.is_array, inverse=True))
    return scenario, keys, _shard_runs(_initial_carry_batch(scenario, keys, batched_scenario), n_runs)


def summarize_batch(scenario: Scenario, keys: Array, summary: Summary, *, batched_scenario: bool = False):
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
    _checked_scenario(scenario, keys, batched_scenario)
    scenario, keys, carry = _sharded_batch(scenario, keys, batched_scenario)
    return _segment_batch(scenario, keys, carry, jnp.asarray(0), scenario.n_records, batched_scenario, summary)[1]


def simulate_batch(scenario: Scenario, keys: Array, *, batched_scenario: bool = False, progress=None, chunks: int = 20) -> Trajectory:
    """Simulate a batch of runs with ``jax.vmap``: one run per key.

    Parameters
    ----------
    scenario : Scenario
        Shared by all runs, or, with ``batched_scenario=True``, every array in it
        has a leading axis of length ``len(keys)`` (parameters, initial
        conditions) built e.g. with ``jax.vmap`` or ``jax.tree.map(jnp.stack, ...)``.
    keys : Array
        Batch of PRNG keys, e.g. :func:`seed_keys`.
    batched_scenario : bool
        Map over the leading axis of the scenario's arrays too.
    progress, chunks
        As in :func:`simulate`.

    Returns
    -------
    Trajectory
        With a leading run axis on every recorded array.
    """
    keys = checked_keys(keys)
    _checked_scenario(scenario, keys, batched_scenario)
    check_batch_memory(scenario, int(keys.shape[0]))
    scenario, keys, carry = _sharded_batch(scenario, keys, batched_scenario)

    def step(carry, first, length):
        return _segment_batch(scenario, keys, carry, first, length, batched_scenario)

    records = _run(step, carry, scenario.n_records, progress, chunks, time_axis=1)
    # gather the shards onto one device so results index like ordinary arrays
    records = jax.device_put(records, jax.devices()[0])
    return _trajectory(scenario, records, batched=True)


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
