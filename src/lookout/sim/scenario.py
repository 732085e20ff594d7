"""The scenario of a run and the check that its parts fit one another.

A :class:`Scenario` holds the components of :mod:`lookout.components` (plant,
sensor, observer, reference, controller, actuator), the initial plant state, the
observer's initial guess and the time grid; building one checks the time grid (every
period a whole multiple of the one below it) and, with :func:`check_fit`, that the
components fit: each one's signals, layouts and shapes, traced with
``jax.eval_shape`` on one sample.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Literal, cast

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lookout._random import MAX_COUNT
from lookout._validation import FitError, ParameterError, is_concrete, key
from lookout.components import (
    Actuator,
    ContinuousObserver,
    Controller,
    KinematicSensor,
    Layout,
    Observer,
    Plant,
    Reference,
    Sensor,
    Signal,
    kinematics_of,
)
from lookout.declare import kind_of
from lookout.null_components import IdealActuator, NoReference
from lookout.results import RecordSignals
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
    actuator: Actuator = IdealActuator()  # type: ignore[call-arg]  # output_signals is StatelessActuator's property, not a field; mypy keeps Actuator's AbstractVar as an __init__ argument
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
        if self.observer_mode == "continuous" and isinstance(self.sensor, KinematicSensor):
            raise ParameterError(
                "observer_mode",
                f"observer_mode 'continuous' needs a sensor of the state alone; {sensor_words(self.sensor)} has a memory",
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
    def observer_channels(self) -> tuple[int, ...] | None:
        """The sensor's channels that the observer and the controller read, in the
        order of the observer's measurement layout (its signals found by name); None
        when the observer reads the sensor's measurement as it is."""
        return observer_channels(self.sensor.measurement_layout, self.observer.measurement_layout)

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


def observer_channels(measured: Layout, needed: Layout) -> tuple[int, ...] | None:
    """The channels of ``measured`` that make up ``needed``, signal by signal by name
    (None when they are the same layout); a signal ``needed`` names that ``measured``
    lacks is left out (the fit check refuses it first)."""
    if measured.names == needed.names:
        return None
    starts, offset = {}, 0
    for signal in measured.signals:
        starts[signal.name] = offset
        offset += signal.size
    return tuple(starts[signal.name] + i for signal in needed.signals if signal.name in starts for i in range(signal.size))


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


def structure_key(scenario: Scenario) -> tuple[Any, tuple[tuple[type, tuple[int, ...], np.dtype], ...]] | None:
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


def sensor_words(sensor: object) -> str:
    """How a refusal names a sensor: ``sensor KIND``, or ``the sensor suite (NAME, ...)``
    for a suite of named instruments."""
    names = getattr(sensor, "names", None)
    if isinstance(names, tuple) and names and all(isinstance(name, str) for name in names):
        return f"the sensor suite ({', '.join(names)})"
    return f"sensor {kind_of(sensor)}"


def _check_fit(scenario: Scenario) -> None:
    plant, sensor, observer = scenario.plant, scenario.sensor, scenario.observer
    x0 = scenario.initial_state
    layout = plant.input_layout
    u0 = jnp.zeros(layout.size)
    w0 = jnp.zeros(plant.noise_size)

    truth = _evaluate(("plant", "initial_state"), plant.variables, x0)
    _compare("plant", "initial_state", "plant.variables(initial_state)", {k: _shape_of(v) for k, v in truth.items()}, plant.variable_signals)
    derivative = _evaluate(("plant", "initial_state"), lambda x: plant.vector_field(0.0, x, u0, w0), x0)
    same_tree = jax.tree.structure(derivative) == jax.tree.structure(x0)  # type: ignore[operator]  # jaxlib ships no stub for PyTreeDef, so mypy cannot resolve jax.tree.structure's return type
    if not same_tree or [_shape_of(a) for a in jax.tree.leaves(derivative)] != [_shape_of(a) for a in jax.tree.leaves(x0)]:
        raise FitError(("plant", "initial_state"), "plant and initial_state disagree: plant.vector_field returns a state shaped unlike initial_state")

    check_sensor_fit(sensor, x0, plant)
    # the observer reads the signals it declares, found by name in the sensor's measurement
    measured_signals = {signal.name: signal for signal in sensor.measurement_layout.signals}
    missing = [name for name in observer.measurement_layout.names if name not in measured_signals]
    if missing:
        raise ParameterError(
            "observer",
            f"observer {kind_of(observer)} needs measurement {', '.join(missing)}, which {sensor_words(sensor)} does not measure "
            f"(it measures {', '.join(sensor.measurement_layout.names)})",
        )
    y = jnp.zeros(observer.measurement_layout.size)
    measured = set(observer.measurement_layout.names)

    state = _evaluate(("observer", "initial_estimate"), observer.init, y, scenario.initial_estimate)
    estimate = _evaluate(("observer", "sensor"), lambda s: observer.output(observer.update(s, 0.0, y), y), state)
    signals = tuple(observer.estimate_signals) + tuple(observer.extra_signals)
    _compare("observer", "its signals", "observer.output", {k: _shape_of(v) for k, v in estimate.items()}, signals)
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
    for signal in observer.measurement_layout.signals:
        given = measured_signals[signal.name]
        if (given.shape, given.units) != (signal.shape, signal.units):
            raise FitError(
                ("observer", "sensor"),
                f"observer and sensor disagree: the observer reads {signal.name!r} as {signal.shape} in {signal.units}, "
                f"the sensor measures it as {given.shape} in {given.units}",
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
        continuous = cast(ContinuousObserver, observer)  # Scenario takes "continuous" with a ContinuousObserver only
        _evaluate(("observer", "observer_mode 'continuous'"), lambda s: continuous.vector_field(0.0, s, y, u0), state)
    if jax.tree.structure(predicted) != jax.tree.structure(state):  # type: ignore[operator]  # jaxlib ships no stub for PyTreeDef, so mypy cannot resolve jax.tree.structure's return type
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
    zero_estimate = {k: jnp.zeros(_shape_of(v)) for k, v in estimate.items()}
    _, u = _evaluate(("controller", "plant"), lambda: controller.step(controller.init(), 0.0, y, zero_estimate, sample, scenario.sample_period))
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


def check_sensor_fit(sensor: Sensor, state: Any, plant: Plant | None = None) -> None:
    """Check with ``jax.eval_shape`` that ``sensor`` measures a plant whose state is
    ``state`` (a state or its ``jax.eval_shape``): a :class:`FitError` of the sensor
    and the plant otherwise (the check :func:`check_fit` makes of a scenario's). A
    :class:`~lookout.components.KinematicSensor` measures ``plant``'s kinematics."""
    if isinstance(sensor, KinematicSensor):
        if plant is None or getattr(plant, "kinematics", None) is None:
            raise FitError(("sensor", "plant"), f"{sensor_words(sensor)} measures a plant's kinematics, and plant {kind_of(plant)} gives none")
        size = sensor.measurement_layout.size

        def read(x):
            kinematics = kinematics_of(plant, 0.0, x, jnp.zeros(plant.input_layout.size))
            memory = sensor.initial_memory(kinematics)
            return sensor.read(memory, 0.0, kinematics, jnp.zeros(sensor.noise_size), jnp.ones(size, dtype=bool), jnp.zeros(size))[1]

        y = _evaluate(("sensor", "plant"), read, state)
    else:
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
            which = sensor_words(component) if role == "sensor" else f"{role} {kind_of(component)}"
            raise ParameterError("controller", f"controller {kind_of(controller)} needs {what} {name}, which {which} {verb} (it gives {given})")


def checked_scenario(scenario: object, batched_runs: int | None = None) -> None:
    """Refuse, in one line, a scenario that is not one, a scenario batched over
    ``batched_runs`` runs (one per key; None: a scenario every run shares) whose arrays do
    not all lead with that run axis, and a scenario stacked per run given as a shared one."""
    if not isinstance(scenario, Scenario):
        raise ValueError(f"scenario must be a lookout Scenario (lookout.sim.Scenario, or a paper's build(config)); got {type(scenario).__name__}")
    arrays = [leaf for leaf in jax.tree.leaves(eqx.filter(scenario, eqx.is_array))]
    leading = {int(leaf.shape[0]) if leaf.ndim else None for leaf in arrays}
    if batched_runs is not None:
        runs = batched_runs
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
