"""lookout plants and observers as python-control input/output systems.

python-control (``pip install control``) is the library control engineers use for
linear analysis: linearization, transfer functions, Bode plots, interconnections by
signal name. This module turns a lookout :class:`~lookout.components.Plant` and a
:class:`~lookout.components.ContinuousObserver` into ``control.NonlinearIOSystem``
objects whose update and output functions are lookout's own, jitted:

- :func:`plant_system`: states are the plant's state, flattened; inputs its
  ``input_layout`` (``force[surge]``, ``force[sway]``, ``moment``); outputs its
  variables (``position[north]``, ..., ``heading``, ``velocity[surge]``, ...) and,
  when a sensor is given, the sensor's noise-free measurement
  (``measured_position[north]``, ...). ``updfcn`` is ``plant.vector_field`` with the
  process noise zero.
- :func:`observer_system`: states are the observer's state, flattened; inputs the
  measurement it reads then the applied input (``measured_position[north]``, ...,
  ``force[surge]``, ...); outputs its estimates (``position_hat[north]``, ...) and its
  extra outputs (``innovation_position[north]``, ...). ``updfcn`` is
  ``ContinuousObserver.vector_field`` with the measurement held at the input.

The names are the ones of lookout's :class:`~lookout.components.Signal` labels, so
``control.interconnect`` connects a plant and an observer by name. A state is named
after the plant variable (or estimate) it equals where there is one (the vessel's
``eta[0]`` is ``position[north]``), and by its place in the state otherwise
(``wave_state[0]``, the wave filter's xi1).

``control.linearize(system, x0, u0)`` linearizes by finite differences;
:func:`linearize_exact` does it with JAX's forward-mode Jacobians (``jax.jacfwd``,
exact to rounding) and returns a ``control.StateSpace`` with the same names.

The gains are the component's array fields and enter the jitted functions as
arguments, so two systems of one structure with other gains compile once.
python-control's ``params`` are not used: build a new system for new gains.

Refused, each in one line naming the component: an observer that is not a
continuous-time vector field (a discrete-time observer, a Kalman filter, an observer
in its discrete form), a plant that draws randomness per run that cannot be set to
zero (JONSWAP wave phases drawn by ``realize``) and a sensor that does not measure the
plant (the fit check of a scenario, naming both); a plant's white process noise is set
to zero.

An observer's state given as a state PyTree (``observer.guess()``) starts as the
observer starts a run: a guess that leaves entries to the first measurement (NaN, the
default position of most guesses) goes through ``observer.init(y, guess)`` with the
measurement ``y`` of the operating point (the first inputs of ``u0``), so
``linearize_exact(system, observer.guess(), 0)`` linearizes at the guess started from
a zero measurement.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt

from lookout.components import ContinuousObserver, Layout, Observer, Plant, Sensor, Signal

try:  # python-control is optional: only this module needs it
    import control
except ImportError:  # pragma: no cover - exercised only without the package
    control = None


def _require_control():
    if control is None:
        raise ImportError("lookout.control_systems needs python-control: pip install control")


def signal_names(signals: Layout | Iterable[Signal], suffix: str = "") -> list[str]:
    """Flat names of signals laid end to end: ``name[label]`` per component of a
    vector, ``name`` for a scalar, each name with ``suffix`` appended.

    Parameters
    ----------
    signals : Layout or sequence of Signal
        In order.
    suffix : str
        Appended to each signal's name (``"_hat"`` for an estimate).

    Returns
    -------
    list of str
        One name per entry of the flat vector.

    Examples
    --------
    >>> from lookout.models.vessel import VESSEL_INPUT
    >>> signal_names(VESSEL_INPUT)
    ['force[surge]', 'force[sway]', 'moment']
    """
    signals = signals.signals if isinstance(signals, Layout) else tuple(signals)
    names: list[str] = []
    for signal in signals:
        if signal.labels:
            names.extend(f"{signal.name}{suffix}[{label}]" for label in signal.labels)
        else:
            names.append(f"{signal.name}{suffix}")
    return names


def _kind(component) -> str:
    """The component's registered kind for messages, or its class name."""
    try:
        from lookout.declare import kind_of

        return kind_of(component)
    except Exception:  # the kind is only for the message
        return type(component).__name__


def _path_name(path) -> str:
    parts = []
    for key in path:
        if isinstance(key, jax.tree_util.GetAttrKey):
            parts.append(key.name)
        elif isinstance(key, jax.tree_util.DictKey):
            parts.append(str(key.key))
        elif isinstance(key, jax.tree_util.SequenceKey):
            parts.append(str(key.idx))
        else:  # pragma: no cover - other key types
            parts.append(str(key))
    return ".".join(parts) or "state"


@dataclass(frozen=True)
class StateLayout:
    """How a component's state PyTree is laid out as a flat vector (hashable: it is a
    static argument of the jitted functions).

    Parameters
    ----------
    treedef : jax.tree_util.PyTreeDef
        Structure of the state.
    shapes : tuple of tuple of int
        Shape of each leaf, in the order of ``jax.tree_util.tree_leaves``.
    paths : tuple of str
        Each leaf's place in the state (``eta``, ``wave_state``).
    """

    treedef: jax.tree_util.PyTreeDef
    shapes: tuple[tuple[int, ...], ...]
    paths: tuple[str, ...]

    @classmethod
    def of(cls, template: Any, role: str, component: Plant | Observer) -> StateLayout:
        """The layout of ``template`` (a state or its ``jax.eval_shape``) of ``component``
        (a ``role``); refused when a leaf is not floating point (a counter or a flag has no
        linearization)."""
        leaves_with_paths, treedef = jax.tree_util.tree_flatten_with_path(template)
        for path, leaf in leaves_with_paths:
            if not jnp.issubdtype(leaf.dtype, jnp.floating):
                raise ValueError(
                    f"{role} {_kind(component)}: state entry {_path_name(path)} is {leaf.dtype}, not floating point, so it has no linearization"
                )
        return cls(treedef, tuple(tuple(leaf.shape) for _, leaf in leaves_with_paths), tuple(_path_name(path) for path, _ in leaves_with_paths))

    @property
    def size(self) -> int:
        """Length of the flat vector."""
        return int(sum(int(np.prod(shape)) for shape in self.shapes))

    def flatten(self, state: Any) -> jax.Array:
        """The state (a PyTree of this layout) as a flat vector."""
        leaves = jax.tree_util.tree_leaves(state)
        return jnp.concatenate([jnp.ravel(jnp.asarray(leaf, dtype=float)) for leaf in leaves]) if leaves else jnp.zeros(0)

    def unflatten(self, vector: jax.Array | np.ndarray) -> object:
        """The flat vector as a state PyTree."""
        leaves, start = [], 0
        for shape in self.shapes:
            count = int(np.prod(shape))
            leaves.append(jnp.reshape(vector[start : start + count], shape))
            start += count
        return jax.tree_util.tree_unflatten(self.treedef, leaves)

    def entry_names(self) -> list[str]:
        """``path[i]`` per entry of a vector leaf, ``path`` for a scalar leaf."""
        names = []
        for path, shape in zip(self.paths, self.shapes):
            if shape == ():
                names.append(path)
            else:
                names.extend(f"{path}[{index}]" for index in range(int(np.prod(shape))))
        return names


# The jitted functions take the component's arrays (gains, parameters) as traced
# arguments and its static part and the state layout as static ones (hashed), so a
# gain change does not compile again, and each call costs one jax.jit dispatch
# (python-control calls them once per solver stage).
@functools.partial(jax.jit, static_argnums=(1, 2))
def _plant_rates(arrays, static, layout: StateLayout, t, x, u):
    plant, _ = eqx.combine(arrays, static.static)
    rates = plant.vector_field(t, layout.unflatten(x), u, jnp.zeros(plant.noise_size))
    return layout.flatten(rates)


@functools.partial(jax.jit, static_argnums=(1, 2))
def _plant_outputs(arrays, static, layout: StateLayout, t, x, u):
    del t, u
    plant, sensor = eqx.combine(arrays, static.static)
    state = layout.unflatten(x)
    variables = plant.variables(state)
    parts = [jnp.ravel(jnp.asarray(variables[signal.name], dtype=float)) for signal in plant.variable_signals]
    if sensor is not None:
        parts.append(jnp.asarray(sensor.ideal(state), dtype=float))
    return jnp.concatenate(parts)


@functools.partial(jax.jit, static_argnums=(1, 2))
def _observer_rates(arrays, static, layout: StateLayout, t, x, u):
    observer = eqx.combine(arrays, static.static)
    measurements = observer.measurement_layout.size
    rates = observer.vector_field(t, layout.unflatten(x), u[:measurements], u[measurements:])
    return layout.flatten(rates)


@functools.partial(jax.jit, static_argnums=(1, 2))
def _observer_outputs(arrays, static, layout: StateLayout, t, x, u):
    del t
    observer = eqx.combine(arrays, static.static)
    outputs = observer.output(layout.unflatten(x), u[: observer.measurement_layout.size])
    signals = observer.estimate_signals + observer.extra_signals
    return jnp.concatenate([jnp.ravel(jnp.asarray(outputs[signal.name], dtype=float)) for signal in signals])


class _Static:
    """A component's static part, hashed once: ``jax.jit`` hashes a static argument on
    every call, and hashing the signals and layouts of a component each time costs more
    than the call itself."""

    def __init__(self, static):
        self.static = static
        self._hash = hash(static)

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        return isinstance(other, _Static) and (self.static is other.static or (self._hash == other._hash and self.static == other.static))


def _array(value):
    """A float64 array of ``value``, never weakly typed (a weak and a strong float would be
    two compilations): a traced value stays a JAX array, anything else becomes a NumPy
    array (no device copy here: ``jax.jit`` takes NumPy arguments)."""
    return jnp.asarray(value, dtype=float) if isinstance(value, jax.core.Tracer) else np.asarray(value, dtype=float)


def _bind(function, component, layout: StateLayout):
    """``(t, x, u) -> function(arrays, static, layout, t, x, u)`` for ``component``."""
    arrays, static = eqx.partition(component, eqx.is_array)
    static = _Static(static)

    def bound(t, x, u):
        return function(arrays, static, layout, _array(t), _array(x), _array(u))

    return bound


def _state_names(layout: StateLayout, outputs, template_vector, output_names: list[str]) -> list[str]:
    """A state's name is the output it equals (its row of d outputs / d x is a unit
    vector and the output's value is the state's), else its place in the state."""
    names = layout.entry_names()
    jacobian = np.asarray(jax.jacfwd(outputs)(template_vector))
    values_out = np.asarray(outputs(template_vector))
    values_x = np.asarray(template_vector)
    taken: dict[int, str] = {}
    for row, name in enumerate(output_names):
        nonzero = np.flatnonzero(jacobian[row])
        if nonzero.size == 1 and jacobian[row, nonzero[0]] == 1.0 and values_out[row] == values_x[nonzero[0]]:
            column = int(nonzero[0])
            if column not in taken:
                taken[column] = name
    chosen = [taken.get(i, name) for i, name in enumerate(names)]
    return chosen if len(set(chosen)) == len(chosen) else names


def _probe_state(layout: StateLayout) -> jax.Array:
    """A generic point for naming the states (not the origin, where many maps agree)."""
    return jnp.asarray(0.1 + 0.01 * np.arange(layout.size), dtype=float)


class ComponentSystem(control.NonlinearIOSystem if control is not None else object):  # type: ignore[misc]  # python-control is optional: the base is chosen at import
    """A ``control.NonlinearIOSystem`` whose update and output functions are a lookout
    component's (built by :func:`plant_system` or :func:`observer_system`).

    Parameters
    ----------
    component : Plant or ContinuousObserver
        The component.
    layout : StateLayout
        How its state is flattened.
    rates, outputs : callable
        ``(t, x, u) -> jax.Array``: the flat state derivative and the flat output.
    inputs, output_names, states : list of str
        Signal names.
    name : str
        The system's name.

    Attributes
    ----------
    component : Plant or ContinuousObserver
    state_layout : StateLayout
    """

    def __init__(
        self,
        component: Plant | ContinuousObserver,
        layout: StateLayout,
        rates: Callable[[Any, Any, Any], jax.Array],
        outputs: Callable[[Any, Any, Any], jax.Array],
        *,
        inputs: list[str],
        output_names: list[str],
        states: list[str],
        name: str,
    ):
        _require_control()
        self.component = component
        self.state_layout = layout
        self._jax_rates = rates
        self._jax_outputs = outputs
        super().__init__(
            lambda t, x, u, params: np.asarray(rates(t, x, u)),
            lambda t, x, u, params: np.asarray(outputs(t, x, u)),
            inputs=inputs,
            outputs=output_names,
            states=states,
            name=name,
            dt=0,
        )

    def state_vector(self, state: Any, measurement: npt.ArrayLike | None = None) -> np.ndarray:
        """A state of the component (a PyTree, e.g. ``plant.state(eta=[0, 0, 0.5])``) as
        this system's flat state vector, in the order of ``state_labels``.

        Parameters
        ----------
        state : PyTree
            A state of the component; of an observer, also a guess (``observer.guess()``).
        measurement : array_like, optional
            Of an observer's system only: the measurement it starts from. A guess that is
            not a state, or that leaves entries to the first measurement (NaN), becomes
            ``observer.init(measurement, state)``, as at the start of a run.

        Returns
        -------
        numpy.ndarray
            ``nstates`` numbers.
        """
        component = type(self.component).__name__
        leaves = jax.tree_util.tree_leaves(state)
        if any(np.iscomplexobj(leaf) for leaf in leaves):
            raise ValueError(f"state must be real; got a {type(state).__name__} with complex entries")
        if measurement is not None and isinstance(self.component, Observer):
            structure = jax.tree_util.tree_structure(state)
            started = structure == self.state_layout.treedef and all(np.all(np.isfinite(np.asarray(leaf))) for leaf in leaves)
            # a guess: start it
            if not started and structure == jax.tree_util.tree_structure(self.component.guess()):  # type: ignore[operator]  # jaxlib's PyTreeDef stub does not resolve for mypy ("PyTreeDef?"); it compares with ==
                state = self.component.init(jnp.asarray(measurement, dtype=float), state)
        if jax.tree_util.tree_structure(state) != self.state_layout.treedef:
            raise ValueError(f"state must be a state of {component} (parts {', '.join(self.state_layout.paths)}); got a {type(state).__name__}")
        shapes = tuple(tuple(np.shape(leaf)) for leaf in jax.tree_util.tree_leaves(state))
        if shapes != self.state_layout.shapes:
            raise ValueError(f"state must be a state of {component} with parts of shapes {self.state_layout.shapes}; got shapes {shapes}")
        return np.asarray(self.state_layout.flatten(state))


def _check_deterministic(plant: Plant) -> None:
    """Refuse a plant whose ``realize`` draws randomness per run (it cannot be zeroed)."""
    first, second = plant.realize(jax.random.PRNGKey(0)), plant.realize(jax.random.PRNGKey(1))
    for (path, a), b in zip(jax.tree_util.tree_leaves_with_path(first), jax.tree_util.tree_leaves(second)):
        if not np.array_equal(np.asarray(a), np.asarray(b)):
            raise ValueError(
                f"plant {_kind(plant)} draws randomness per run ({_path_name(path)} by realize), which cannot be set to zero: "
                "a python-control system needs a deterministic vector field; build the plant without that part (calm water)"
            )


def _check_sensor_fit(plant: Plant, sensor: Sensor, template) -> None:
    """Refuse a sensor that does not measure the plant, naming both (the fit check of a
    scenario, :func:`lookout.sim.scenario.check_sensor_fit`)."""
    from lookout._validation import FitError
    from lookout.scenario.registry import plugin_frame
    from lookout.sim.scenario import check_sensor_fit

    try:
        check_sensor_fit(sensor, template)
    except FitError as error:
        raised = error.__context__
        frame = plugin_frame(raised) if raised is not None else None
        if frame is not None and raised is not None:  # the plugin's own code failed, not the fit (a frame comes from a raised error)
            raise ValueError(f"sensor {_kind(sensor)} on plant {_kind(plant)}: {frame.describe(raised)}") from None
        detail = str(error).split(": ", 1)[-1]
        raise ValueError(f"sensor {_kind(sensor)} and plant {_kind(plant)} do not fit: {detail}") from None


def plant_system(plant: Plant, *, sensor: Sensor | None = None, name: str = "plant") -> ComponentSystem:
    """The plant as a continuous-time ``control.NonlinearIOSystem`` with named signals.

    Parameters
    ----------
    plant : Plant
        A lookout plant; its white process noise is set to zero. A plant whose
        ``realize`` draws randomness per run (JONSWAP wave phases) is refused.
    sensor : Sensor, optional
        When given, its noise-free measurement ``sensor.ideal(x)`` is appended to the
        outputs under the sensor's channel names (what an observer reads), so that
        ``control.interconnect`` connects the plant to an observer by name. A sensor
        that does not measure the plant (a joint encoder on a vessel) is refused,
        naming both.
    name : str
        The system's name.

    Returns
    -------
    ComponentSystem
        ``updfcn(t, x, u, params) = plant.vector_field(t, x, u, 0)`` on the flattened
        state; ``outfcn`` the plant's variables (and the sensor's measurement).
        Inputs are named by ``plant.input_layout``, outputs by
        ``plant.variable_signals`` (and ``sensor.measurement_layout``).

    Examples
    --------
    >>> import lookout
    >>> from lookout.environment import GaussMarkovBias, LinearWaveModel
    >>> plant = lookout.VesselPlant(lookout.northern_clipper(), GaussMarkovBias(1000.0), LinearWaveModel(0.8976, 0.1))
    >>> system = plant_system(plant)
    >>> system.input_labels
    ['force[surge]', 'force[sway]', 'moment']
    >>> system.state_labels[:4]
    ['position[north]', 'position[east]', 'heading', 'velocity[surge]']
    """
    _require_control()
    if not isinstance(plant, Plant):
        raise ValueError(f"plant must be a lookout Plant; got {type(plant).__name__}")
    if sensor is not None and not isinstance(sensor, Sensor):
        raise ValueError(f"sensor must be a lookout Sensor or None; got {type(sensor).__name__}")
    _check_deterministic(plant)
    template = jax.eval_shape(plant.state)
    layout = StateLayout.of(template, "plant", plant)
    if sensor is not None:
        _check_sensor_fit(plant, sensor, template)

    rates = _bind(_plant_rates, (plant, None), layout)
    outputs = _bind(_plant_outputs, (plant, sensor), layout)

    output_names = signal_names(plant.variable_signals)
    if sensor is not None:
        output_names += signal_names(sensor.measurement_layout)
    input_names = signal_names(plant.input_layout)
    zero_input = jnp.zeros(len(input_names))
    states = _state_names(layout, lambda x: outputs(0.0, x, zero_input), _probe_state(layout), output_names)
    return ComponentSystem(plant, layout, rates, outputs, inputs=input_names, output_names=output_names, states=states, name=name)


def _check_continuous(observer: Observer) -> None:
    kind = _kind(observer)
    if observer.sample_period is not None:
        raise ValueError(
            f"observer {kind} is discrete-time (sample_period = {observer.sample_period:g} s): "
            "only a continuous-time observer (a ContinuousObserver) becomes a python-control system here"
        )
    if not isinstance(observer, ContinuousObserver):
        raise ValueError(
            f"observer {kind} is not a continuous-time observer (a ContinuousObserver with a vector field): "
            "only one becomes a python-control system here"
        )


def observer_system(observer: ContinuousObserver, *, name: str = "observer") -> ComponentSystem:
    """The observer as a continuous-time ``control.NonlinearIOSystem`` with named signals.

    Parameters
    ----------
    observer : ContinuousObserver
        A continuous-time lookout observer. A discrete-time one (``sample_period``),
        one without a vector field (a Kalman filter) or one built in a discrete form
        is refused.
    name : str
        The system's name.

    Returns
    -------
    ComponentSystem
        ``updfcn(t, x, u, params) = observer.vector_field(t, x, y, tau)`` on the
        flattened state, where the input ``u = [y, tau]`` is the measurement (named by
        ``observer.measurement_layout``) then the applied input (``input_layout``);
        ``outfcn`` is ``observer.output(x, y)``: the estimates (``<name>_hat``) then
        the extra outputs (innovations).

    Examples
    --------
    >>> import lookout
    >>> observer = lookout.PassiveObserver.design(lookout.northern_clipper(), wave_frequency=0.8976)
    >>> system = observer_system(observer)
    >>> system.input_labels
    ['measured_position[north]', 'measured_position[east]', 'measured_heading', 'force[surge]', 'force[sway]', 'moment']
    >>> system.state_labels[:3]
    ['position_hat[north]', 'position_hat[east]', 'heading_hat']
    """
    _require_control()
    if not isinstance(observer, Observer):
        raise ValueError(f"observer must be a lookout Observer; got {type(observer).__name__}")
    _check_continuous(observer)
    measurements = observer.measurement_layout.size
    template = jax.eval_shape(lambda: observer.init(jnp.zeros(measurements), observer.guess()))
    layout = StateLayout.of(template, "observer", observer)
    input_size = measurements + observer.input_layout.size
    rates = _bind(_observer_rates, observer, layout)
    outputs = _bind(_observer_outputs, observer, layout)
    try:
        jax.eval_shape(lambda: rates(0.0, np.zeros(layout.size), np.zeros(input_size)))
    except ValueError as error:  # an observer built in a discrete form says so from its vector field
        first_line = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ValueError(f"observer {_kind(observer)} has no continuous-time vector field: {first_line}") from None

    input_names = signal_names(observer.measurement_layout) + signal_names(observer.input_layout)
    output_names = signal_names(observer.estimate_signals, "_hat") + signal_names(observer.extra_signals)
    zero_input = jnp.zeros(input_size)
    states = _state_names(layout, lambda x: outputs(0.0, x, zero_input), _probe_state(layout), output_names)
    return ComponentSystem(observer, layout, rates, outputs, inputs=input_names, output_names=output_names, states=states, name=name)


def _operating_vector(argument: str, value, size: int, system: ComponentSystem, state: bool, measurement=None) -> np.ndarray:
    """``value`` as a finite real vector of ``size`` entries (a scalar broadcast; for a
    state, a state PyTree of the component too, an observer's guess started from
    ``measurement``), or a one-line refusal naming ``argument``."""
    what = f"an array of {size} numbers" + (" or a state of the component" if state else "")
    if value is None:
        raise ValueError(f"{argument} must be {what}; got None")
    if state and (isinstance(value, eqx.Module) or jax.tree_util.tree_structure(value) == system.state_layout.treedef):
        try:
            value = system.state_vector(value, measurement)
        except ValueError as error:
            raise ValueError(f"{argument}: {error}") from None
    if np.iscomplexobj(value):
        raise ValueError(f"{argument} must be real; got complex values")
    raw = np.asarray(value, dtype=object)
    if raw.ndim and any(entry is None for entry in raw.ravel()):  # NumPy would read None as NaN
        raise ValueError(f"{argument} must be {what}; entry {next(i for i, e in enumerate(raw.ravel()) if e is None)} is None")
    try:
        vector = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{argument} must be {what}; got {type(value).__name__}") from None
    if vector.ndim == 0:
        vector = np.full(size, float(vector))
    if vector.shape != (size,):
        raise ValueError(f"{argument} must have shape ({size},) ({'states' if state else 'inputs'} of {system.name}); got shape {vector.shape}")
    if not np.all(np.isfinite(vector)):
        bad = int(np.flatnonzero(~np.isfinite(vector))[0])
        labels = system.state_labels if state else system.input_labels
        raise ValueError(f"{argument} must be finite; entry {bad} ({labels[bad]}) is {vector[bad]}")
    return vector


def linearize_exact(system: ComponentSystem, x0: Any, u0: npt.ArrayLike = 0.0, t: float = 0.0, *, name: str | None = None) -> control.StateSpace:
    """Linearize a component's system at an operating point with JAX's exact Jacobians.

    ``A = df/dx``, ``B = df/du``, ``C = dh/dx``, ``D = dh/du`` at ``(t, x0, u0)``, by
    ``jax.jacfwd`` of the component's own functions: exact to rounding, where
    ``control.linearize`` takes finite differences of step 1e-6 in every state and
    input whatever its scale.

    Parameters
    ----------
    system : ComponentSystem
        Built by :func:`plant_system` or :func:`observer_system`.
    x0 : array_like or state PyTree
        The state (``system.nstates`` numbers in the order of ``system.state_labels``,
        a scalar for all of them, or a state of the component, e.g.
        ``plant.state(eta=[0, 0, 0.5])``). Of an observer, a guess too
        (``observer.guess()``): one that leaves entries to the first measurement starts
        from the measurement in ``u0``, as :meth:`ComponentSystem.state_vector` says.
    u0 : array_like
        The input (``system.ninputs`` numbers, or a scalar for all of them); of an
        observer, the measurement then the applied input.
    t : float
        The time (for a time-varying component).
    name : str, optional
        The linear system's name; default the system's with ``$linearized``.

    Returns
    -------
    control.StateSpace
        (A, B, C, D), with the system's input, output and state names.
    """
    _require_control()
    if not isinstance(system, ComponentSystem):
        raise ValueError(
            f"system must be built by lookout.control_systems.plant_system or observer_system; got {type(system).__name__} "
            "(for an interconnection use control.linearize)"
        )
    if isinstance(t, bool) or not isinstance(t, (int, float, np.integer, np.floating)) or not np.isfinite(t):
        raise ValueError(f"t must be a finite real number; got {t!r}")
    t = float(t)
    u: np.ndarray | jax.Array = _operating_vector("u0", u0, system.ninputs, system, state=False)
    measurement = u[: system.component.measurement_layout.size] if isinstance(system.component, Observer) else None
    x = jnp.asarray(_operating_vector("x0", x0, system.nstates, system, state=True, measurement=measurement))
    u = jnp.asarray(u)
    rates, outputs = system._jax_rates, system._jax_outputs
    A, B = (np.asarray(m) for m in jax.jacfwd(lambda x, u: rates(t, x, u), argnums=(0, 1))(x, u))
    C, D = (np.asarray(m) for m in jax.jacfwd(lambda x, u: outputs(t, x, u), argnums=(0, 1))(x, u))
    for symbol, matrix in (("A", A), ("B", B), ("C", C), ("D", D)):
        if not np.all(np.isfinite(matrix)):
            raise ValueError(f"x0, u0: the Jacobian {symbol} is not finite at this operating point of {system.name}")
    return control.ss(
        A,
        B,
        C,
        D,
        inputs=system.input_labels,
        outputs=system.output_labels,
        states=system.state_labels,
        name=name or f"{system.name}$linearized",
        remove_useless_states=False,
    )


__all__ = ["ComponentSystem", "StateLayout", "linearize_exact", "observer_system", "plant_system", "signal_names"]
