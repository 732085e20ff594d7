"""Compositions: a scenario as registered components, one table each.

A composition is a document (a dict, or the TOML file of a scenario) with one table
per component and a ``[simulation]`` table::

    [simulation]                 # horizon, steps, runs and seed
    duration = 600.0
    plant_step = 0.1
    sample_period = 0.1

    [plant]                      # kind and parameters; sub-parts as nested tables
    kind = "dp-vessel"
    [plant.vessel]
    kind = "northern-clipper"
    [plant.initial]              # the plant's initial state (zeros where left out)
    bias = [1e4, 5e3, 1e5]

    [sensor]
    kind = "position-heading"
    noise_std = [0.5, 0.5, 0.0017]

    [observer]
    kind = "passive"
    design = "fossen-strand-1999"   # the gain-synthesis rule (a kind may have several)
    wave_frequency = 0.8976
    ...
    [observer.initial]           # the observer's initial guess (its guess())

    [controller]                 # optional, as [reference] and [actuator]
    kind = "sinusoidal"

Each table's keys are its kind's parameters (:mod:`lookout.scenario.registry`: names, types,
ranges and defaults from the component's own signature and docstring); a key left
out takes its default, and a part an observer or a controller needs from the plant
(the vessel model of a model-based observer) is the plant's unless the table gives
its own (a model error). ``preset = "NAME:CASE"`` starts from a reproduction's case;
the file's tables then override its keys, a table with another ``kind`` replaces
the preset's component, and a file's ``[sensors.NAME]`` tables replace the preset's
``[sensor]`` (its ``[sensor]``, the preset's suite).

:func:`compose` validates a document and builds its :class:`~lookout.sim.Scenario`;
every error is a :class:`CompositionError` with the key's location.
"""

from __future__ import annotations

import copy
import functools
import math
import operator
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, ValidationError, create_model, field_validator
from pydantic.functional_validators import AfterValidator

from lookout._validation import FitError, ParameterError, one_line, short
from lookout.scenario import registry
from lookout.scenario.settings import RunsConfig, Settings, explain, finite_positive, validate_strictly

if TYPE_CHECKING:
    from lookout.components import DivergenceBound
    from lookout.results import Trajectory

#: The top-level keys of a composition.
TOP_KEYS = ("plugins", "preset", "simulation", *registry.COMPONENT_ROLES, "sensors", "references")
#: Components of which another component may hold a model of its own (a Kalman filter's
#: ``[observer.plant]``): by default the composition's, else built from the table given.
MODEL_ROLES = ("plant", "sensor")


class CompositionError(ValueError):
    """A composition that cannot be built: ``location`` is the key (a tuple of table
    names, keys and indices), ``reason`` the condition; ``str()`` is one line."""

    def __init__(self, location: tuple, reason: str):
        self.location = tuple(location)
        self.reason = reason
        super().__init__(f"{key_text(self.location)}: {reason}" if self.location else reason)


def key_text(location: tuple) -> str:
    """``("observer", "wave_frequency", 2)`` -> ``observer.wave_frequency[2]``."""
    text = ""
    for part in location:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


class DivergenceSettings(Settings):
    """``[simulation] divergence``: when a run has failed (see
    :class:`lookout.components.DivergenceBound`)."""

    signal: str = Field(description="a plant variable whose estimation or tracking error is bounded")
    limit: float = Field(description="the bound, in the signal's units")

    @field_validator("limit")
    @classmethod
    def _finite_positive(cls, value):
        return finite_positive(value)


class SimulationSettings(RunsConfig):
    """The ``[simulation]`` table: the time grid, the integrator, runs and seeds."""

    runs: int = Field(default=1, description="Monte Carlo runs (vmapped); run i uses seed + i")
    seed: int = Field(default=0, description="PRNG seed of run 0 (run i uses seed + i)")
    plant_step: float = Field(default=0.1, description="integration step of the plant (s)")
    sample_period: float = Field(default=0.1, description="observer, reference and controller period (s), a multiple of plant_step")
    duration: float = Field(default=600.0, description="simulated time (s), a multiple of sample_period * record_every")
    record_every: int = Field(default=1, description="record one sample in this many")
    integrator: Literal["rk4", "euler"] = Field(default="rk4", description="the plant's integrator: 'rk4' or 'euler'")
    observer_mode: Literal["sampled", "continuous"] = Field(
        default="sampled", description="'sampled', or 'continuous': the observer integrated jointly with the plant on the noise-free measurement"
    )
    batch: Literal["shared", "stacked"] = Field(
        default="shared", description="runs vmapped over one shared scenario, or over a copy per run ('stacked'; equal to rounding)"
    )
    conditions: Literal["warn", "require", "ignore"] = Field(
        default="warn",
        description="the design conditions of the observer and controller (lookout design FILE) at lookout run: "
        "'warn' when one fails, 'require' them (refuse the run), or 'ignore' them",
    )
    divergence: DivergenceSettings | None = Field(
        default=None,
        description="a run has failed (status 'diverged') when the estimation or tracking error of signal exceeds limit, "
        "or a truth or estimate is not finite (default: the plant kind's)",
    )

    @field_validator("plant_step", "sample_period", "duration")
    @classmethod
    def _finite_positive(cls, value):
        return finite_positive(value)

    @field_validator("record_every")
    @classmethod
    def _positive(cls, value):
        if value < 1:
            raise ValueError(f"must be a positive integer; got {value}")
        return value


# ---------------------------------------------------------------- parameter schemas


def _in_range(bounds: tuple[float, float, bool, bool]):
    low, high, low_in, high_in = bounds

    def check(value):
        values = list(value.values()) if isinstance(value, dict) else [value]
        for number in np.concatenate([np.ravel(np.asarray(v, dtype=float)) for v in values] or [np.zeros(0)]):
            if not ((number >= low if low_in else number > low) and (number <= high if high_in else number < high)) or (
                np.isinf(number) and high == math.inf
            ):
                words = {(0.0, math.inf, False, False): "positive", (0.0, math.inf, True, False): "non-negative"}.get(bounds)
                if words and not np.isfinite(number):
                    words = f"finite and {words}"
                interval = f"{'[' if low_in else '('}{low:g}, {high:g}{']' if high_in else ')'}"
                raise ValueError(f"must be {words}; got {short(value)}" if words else f"must be in {interval}; got {short(value)}")
        return value

    return check


def _shaped(parameter: registry.Parameter):
    """The check of a value's declared shape and broadcasting (registry.Parameter.shape_refusal)."""

    def check(value):
        reason = parameter.shape_refusal(value)
        if reason is not None:
            raise ValueError(reason)
        return value

    return check


_ARRAY = float | tuple[float, ...] | tuple[tuple[float, ...], ...]


def _annotation(parameter: registry.Parameter):
    sort = parameter.value_type
    if parameter.choices is not None:
        annotation: Any = Literal[parameter.choices]
    else:
        annotation = {
            "float": float,
            "int": int,
            "bool": bool,
            "str": str,
            "strings": tuple[str, ...],
            "array": _ARRAY,
            "parts": _ARRAY | dict[str, float | list[float]],
        }.get(sort, _ARRAY)
    if sort in ("array", "parts") and (parameter.shape is not None or not parameter.broadcast):
        annotation = Annotated[annotation, AfterValidator(_shaped(parameter))]
    if parameter.range is not None and sort in ("float", "int", "array", "parts"):
        annotation = Annotated[annotation, AfterValidator(_in_range(parameter.range))]
    if parameter.default is None:
        annotation = annotation | None
    return annotation


def _default_value(default):
    if default is registry.REQUIRED:
        return ...
    return plain(default)


def plain(value: object) -> Any:
    """A default or a built value as file data: tuples of floats, Python scalars."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return tuple(plain(v) for v in value)
    array = np.asarray(value)
    if array.ndim == 0:
        return array.item()
    return plain(array.tolist())


_MODELS: dict = {}


def parameter_model(kind: registry.Kind, design: str | None) -> type[Settings]:
    """The pydantic model of a kind's value parameters (strict, every number finite)."""
    key = (kind.role, kind.name, design)
    if key not in _MODELS:
        fields: dict[str, Any] = {
            p.name: (_annotation(p), Field(default=_default_value(p.default), description=p.description))
            for p in kind.parameters(design)
            if p.sort == "value"
        }
        name = re.sub(r"\W", "_", f"{kind.role}_{kind.name}_{design or ''}")
        _MODELS[key] = create_model(name, __base__=Settings, **fields)
    return _MODELS[key]


def state_parameters(method: Callable[..., Any]) -> tuple[registry.Parameter, ...]:
    """The keys of a plant's ``state`` or an observer's ``guess`` method (bound, or as
    its class has it), as the method declares them."""
    return registry.initial_parameters(method)


@functools.cache
def _initial_model(functions: tuple):
    """The pydantic model of the keys a chain of ``state`` or ``guess`` methods takes
    (:func:`_chain_functions`; built once per chain)."""
    fields: dict[str, Any] = {
        p.name: (_annotation(p), Field(default=_default_value(p.default), description=p.description)) for p in _chain_parameters(functions)
    }
    last = functions[-1]
    return create_model(re.sub(r"\W", "_", f"initial_{last.__module__}_{last.__qualname__}_{len(functions)}"), __base__=Settings, **fields)


def _chain_parameters(functions: tuple) -> tuple[registry.Parameter, ...]:
    """The last method's declared keys, then each method's ``extra`` keys before it."""
    extra = tuple(p for function in functions[:-1] for p in registry.initial_extra(function))
    return registry.initial_parameters(functions[-1]) + extra


# ------------------------------------------------------------------------ building

#: Context parameters a component takes from the composition's [simulation] unless its
#: table gives them (a Kalman filter's propagation: the plant's own step and integrator).
SIMULATION_CONTEXT = {"plant_step": "plant_step", "filter_period": "sample_period", "integrator": "integrator"}


@dataclass
class _Context:
    """What later components may take from earlier ones."""

    objects: list
    plant: Any = None
    #: the composition's [simulation] (its steps and integrator, for a component that takes them)
    simulation: Any = None
    #: role -> kind name of the components built so far
    kinds: dict = field(default_factory=dict)

    def find(self, cls):
        if not cls:
            return None
        for each in self.objects:
            if isinstance(each, cls):
                return each
        return None

    def add(self, component):
        """``component`` and its parts (its fields that are modules: a plant's vessel, an
        observer's parameters), which later components may take."""
        import dataclasses

        import equinox as eqx

        self.objects.append(component)
        if hasattr(component, "models") and hasattr(component, "variable_signals"):  # a plant: the models it offers first
            self.objects.extend(component.models())
        for each in dataclasses.fields(component):
            value = getattr(component, each.name, None)
            if isinstance(value, eqx.Module):
                self.objects.append(value)


def _validate(model, values: dict, location: tuple):
    try:
        return validate_strictly(model, values)
    except ValidationError as error:
        where, reason = explain(error)
        if reason == "missing key" and where and isinstance(where[-1], str):  # a key not there has no line: name its table
            where, reason = where[:-1], f"missing key {where[-1]}"
        raise CompositionError(location + where, reason) from None


def _blamed(error: ValueError, table: dict, location: tuple, names, component: str = "") -> CompositionError:
    """A component's own refusal: at the key it concerns when it is a
    :class:`~lookout._validation.ParameterError` of a key the table gives, else at the
    table, naming the component."""
    reason = one_line(error)
    where = getattr(error, "location", ())
    if isinstance(error, ParameterError) and where and where[0] in names and where[0] in table:
        return CompositionError(location + where[:1], reason)
    return CompositionError(location, f"{component}: {reason}" if component and not reason.startswith(component) else reason)


def _table(document: dict, role: str) -> dict | None:
    table = document.get(role)
    if table is None:
        return {"kind": registry.DEFAULT_KINDS[role]} if role in registry.DEFAULT_KINDS else None
    if not isinstance(table, dict):
        raise CompositionError((role,), f"must be a table; got {type(table).__name__}")
    return table


def build_part(role: str, table: dict | None, location: tuple, context: _Context, *, defaults: bool = True) -> tuple[Any, dict]:
    """Build the component of ``table`` (its ``kind`` of ``role``): ``(component, the
    table with every parameter spelled out)``.

    A part the table does not give is taken from the components built before (an
    observer's vessel model is the plant's); with ``defaults`` (the plant, and any
    table the file gives) a part found nowhere is its role's first kind, built with
    its defaults, else it is refused (a controller for a ship on a plant with none)."""
    if not isinstance(table, dict):
        raise CompositionError(location, f"must be a table with a kind; got {type(table).__name__}")
    known = registry.names(role)
    name = table.get("kind", registry.default_kind(role))
    if name is None:
        raise CompositionError(location + ("kind",), f"missing key (one of {', '.join(known)}; `lookout components {role}` lists them)")
    if not isinstance(name, str):
        raise CompositionError(location + ("kind",), f"no {role} kind {name!r} (one of {', '.join(known)})")
    try:
        kind = registry.kind(role, name)  # a name lookout and the plugins do not declare: installed packages' too
    except ValueError as error:
        raise CompositionError(location + ("kind",), one_line(error)) from None
    design = table.get("design")
    if design is not None and design not in kind.designs:
        rules = f"one of {', '.join(kind.designs)}" if kind.designs else f"{role} {name} has no design rules"
        raise CompositionError(location + ("design",), f"no design {design!r} ({rules})")
    if design is None and kind.designs:
        design = kind.designs[0]
    parameters = kind.parameters(design)
    by_name = {p.name: p for p in parameters}
    allowed = set(by_name) | {"kind"} | ({"design"} if kind.designs else set()) | ({"initial"} if role in ("plant", "observer") else set())
    for key in table:
        if key not in allowed:
            listed = ", ".join(p.name for p in parameters) or "none"
            raise CompositionError(location + (key,), f"unknown key ({role} {name} takes: {listed})")

    # the parts first: a part that does not fit says more than a value left out
    arguments: dict = {}
    parts: dict = {}
    normal = parts
    for p in parameters:
        if p.sort == "part" and p.role in MODEL_ROLES and p.name in table:
            # a model of the plant or the sensor (a Kalman filter's), built as the composition
            # builds its own: from its table alone
            own = _Context([], simulation=context.simulation)
            arguments[p.name], normal[p.name] = build_part(p.role, table[p.name], location + (p.name,), own, defaults=True)
        elif p.sort == "part" and p.role in registry.COMPONENT_ROLES:  # another component of the composition
            found = context.find(_part_classes(p))
            if p.name in table:
                raise CompositionError(location + (p.name,), f"is the composition's [{p.role}] table, not a key of [{role}]")
            if found is None:
                wanted = " or ".join(c.__name__ for c in _part_classes(p)) or p.role
                other = context.kinds.get(p.role)
                reason = f"{p.role} {other} is not one" if other else f"there is no {p.role} before it"
                raise CompositionError(
                    location,
                    f"{role} {name} needs an {p.role} that is a {wanted}; {reason}"
                    if p.role[0] in "aeiou"
                    else f"{role} {name} needs a {p.role} that is a {wanted}; {reason}",
                )
            arguments[p.name] = found
        elif p.sort == "part":
            if p.role is None:  # the registry gives every part a role (its declaration's, else its name)
                raise CompositionError(location + (p.name,), f"{role} {name}: part {p.name} has no role")
            if p.name in table:
                arguments[p.name], normal[p.name] = build_part(p.role, table[p.name], location + (p.name,), context, defaults=defaults)
            elif p.from_plant and context.find(_part_classes(p)) is not None:
                arguments[p.name] = context.find(_part_classes(p))
            elif p.required and defaults:
                try:
                    arguments[p.name], normal[p.name] = build_part(p.role, {}, location + (p.name,), context, defaults=defaults)
                except CompositionError as error:  # the file has no such table: blame the table that lacks it
                    first = registry.default_kind(p.role)
                    raise CompositionError(
                        location, f"{role} {name} needs a {p.name}: give [{key_text(location + (p.name,))}] (kind {first}: {error.reason})"
                    ) from None
            elif p.required:
                wanted = " or ".join(c.__name__ for c in _part_classes(p)) or p.name
                raise CompositionError(
                    location,
                    f"{role} {name} needs a {p.name} ({wanted}), and plant {context.kinds.get('plant')} has none; give [{key_text(location + (p.name,))}]",
                )
        elif p.sort == "context":
            if p.name in table and p.name != "signals" and not p.own:  # signals: names the file gives, resolved here
                raise CompositionError(location + (p.name,), f"set by lookout from {registry.context_origin(p)}, never by the file; remove it")
            if p.name in SIMULATION_CONTEXT:
                arguments[p.name] = table.get(p.name, getattr(context.simulation, SIMULATION_CONTEXT[p.name]))
                if p.name in table:
                    normal[p.name] = table[p.name]
            elif p.name == "size" and p.name not in table:
                if context.plant is not None:
                    arguments["size"] = context.plant.input_layout.size
            elif p.name == "signals":
                arguments["signals"], normal["signals"] = _signals(table.get("signals"), location + ("signals",), context, p)
            else:
                found = context.find(p.context) if isinstance(p.context, type) else None
                if found is None and p.required:
                    wanted = p.context.__name__ if isinstance(p.context, type) else p.context
                    other = context.kinds.get(p.name)
                    if other is not None:  # that part is there, of a kind that does not fit
                        raise CompositionError(location, f"{role} {name} needs a {p.name} that is a {wanted}; {p.name} {other} is not one")
                    raise CompositionError(location, f"{role} {name} needs a {wanted} ({p.name}), which the composition has not built before it")
                if found is not None:
                    arguments[p.name] = found
    values = {key: value for key, value in table.items() if key in by_name and by_name[key].sort == "value"}
    validated = _validate(parameter_model(kind, design), values, location)
    given = {
        p.name: getattr(validated, p.name) for p in parameters if p.sort == "value" and not (p.default is None and getattr(validated, p.name) is None)
    }
    arguments.update(given)
    normal = {"kind": name, **({"design": design} if kind.designs else {}), **{key: plain(value) for key, value in given.items()}, **parts}
    try:
        component = kind.callable(design)(**arguments)
    except ValueError as error:
        raise _blamed(error, table, location, by_name, f"{role} {name}") from None
    expected = kind.component_class
    if isinstance(expected, type) and expected is not type(None) and not isinstance(component, expected):
        raise CompositionError(location, f"{role} {name} built a {type(component).__name__}, not a {expected.__name__}")
    return component, normal


def _part_classes(parameter: registry.Parameter) -> tuple:
    """The classes a part may be taken from the composition as: its annotation's, else
    the classes its role's kinds build."""
    if isinstance(parameter.context, type):
        return (parameter.context,)
    return tuple(c for c in (k.component_class for k in registry.kinds(parameter.role)) if isinstance(c, type) and c is not type(None))


def _signals(names, location, context: _Context, parameter):
    """The signals named: each a plant variable's name, or a table ``{name, units,
    long_name, frame}`` of a scalar signal of its own (a setpoint that is none of the
    plant's variables, such as the Furuta pendulum's unwrapped ``pendulum_angle``)."""
    variables = {s.name: s for s in context.plant.variable_signals} if context.plant is not None else {}
    if names is None:
        if parameter.required:
            raise CompositionError(location, f"missing key (names of the plant's variables: {', '.join(variables)})")
        return parameter.default, None
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, (str, dict)) for n in names):
        raise CompositionError(
            location, "must be an array of the plant's variable names (or tables {name, units, long_name, frame} of signals of their own)"
        )
    signals = []
    for index, each in enumerate(names):
        if isinstance(each, dict):
            signals.append(_own_signal(each, location + (index,)))
        elif each in variables:
            signals.append(variables[each])
        else:
            raise CompositionError(location + (index,), f"the plant has no variable {each!r} (its variables: {', '.join(variables)})")
    return tuple(signals), tuple(names)


#: The keys of a signal's own table in ``signals`` (frame optional).
SIGNAL_KEYS = ("name", "units", "long_name", "frame")


def _own_signal(table: dict, location: tuple):
    """A scalar :class:`~lookout.components.Signal` from a table of :data:`SIGNAL_KEYS`."""
    from lookout.components import Signal

    for key, value in table.items():
        if key not in SIGNAL_KEYS:
            raise CompositionError(location + (key,), f"unknown key (a signal has {', '.join(SIGNAL_KEYS)})")
        if not isinstance(value, str):
            raise CompositionError(location + (key,), f"must be a string; got {value!r}")
    for key in SIGNAL_KEYS[:3]:
        if key not in table:
            raise CompositionError(location, f"missing key {key} (a signal has {', '.join(SIGNAL_KEYS)})")
    try:
        return Signal(table["name"], table["units"], table["long_name"], table.get("frame", ""))
    except ValueError as error:
        raise CompositionError(location, one_line(error)) from None


def _keyword_chain(method: Callable[..., Any]) -> list[Callable[..., Any]]:
    """``method`` and each method whose keywords it declares to take in turn
    (``initial_values(same_as="model.state")``: a Kalman filter's ``guess`` takes its model
    plant's state keys; a model that wraps another takes that one's)."""
    chain = [method]
    for _ in range(8):
        path = registry.initial_same_as(chain[-1])
        if path is None or not hasattr(chain[-1], "__self__"):
            break
        chain.append(operator.attrgetter(path)(chain[-1].__self__))
    return chain


def keywords_of(method: Callable[..., Any]) -> Callable[..., Any]:
    """The method whose keywords a bound ``method`` takes: itself, or, for one declared
    to take another's (``initial_values(same_as="model.state")``: a Kalman filter's
    ``guess`` takes its model plant's state keys), that method of the same object."""
    return _keyword_chain(method)[-1]


def _chain_functions(method: Callable[..., Any]) -> tuple:
    """The functions of :func:`_keyword_chain`: a bound ``state`` or ``guess`` takes the
    keys of the last and the ``extra`` keys of each on the way (an extended Kalman filter
    with the IMU's biases as states takes ``imu_bias`` beside its plant's keys)."""
    return tuple(getattr(each, "__func__", each) for each in _keyword_chain(method))


def _initial(method, table, location: tuple):
    """``method(**table)`` (a plant's ``state`` or an observer's ``guess``), validated."""
    functions = _chain_functions(method)
    parameters = _chain_parameters(functions)
    if table is None:
        table = {}
    if not isinstance(table, dict):
        raise CompositionError(location, "must be a table")
    validated = _validate(_initial_model(functions), table, location)
    arguments = {p.name: getattr(validated, p.name) for p in parameters if p.sort == "value"}
    try:
        value = method(**arguments)
    except ValueError as error:
        raise _blamed(error, table, location, [p.name for p in parameters]) from None
    return value, {key: plain(value) for key, value in arguments.items()}


@dataclass(frozen=True)
class Composition:
    """A validated composition: its full document (every key spelled out), the
    simulation settings and the built scenario."""

    document: dict
    simulation: SimulationSettings
    scenario: Any
    kinds: dict

    @property
    def seeds(self) -> list[int]:
        return self.simulation.seeds

    @property
    def divergence(self) -> DivergenceBound | None:
        """When a run of this composition has failed: a
        :class:`~lookout.components.DivergenceBound` (``[simulation] divergence``, else the
        plant kind's), or None (a non-finite truth or estimate only)."""
        from lookout.components import DivergenceBound

        bound = self.document["simulation"].get("divergence")
        return None if bound is None else DivergenceBound(bound["signal"], float(bound["limit"]))

    def with_changes(self, changes: dict[str, Any]) -> Composition:
        """This composition with ``changes`` (dotted paths from the document's root, e.g.
        ``observer.velocity_injection_gain[2]``) applied, validated and built again."""
        document = copy.deepcopy(self.document)
        for path, value in changes.items():
            set_path(document, path, value)
        return compose(document)


def simulate(composition: Composition, *, progress: Callable[[int, int], object] | None = None) -> Trajectory:
    """The composition's runs (seeds ``seed .. seed + runs - 1``): one run alone, several
    vmapped over one shared scenario or, with ``simulation.batch = "stacked"``, over a
    copy per run. ``lookout run``, the campaigns' base and the reproductions simulate a
    composition through this one function, so the three agree to the bit."""
    from lookout.sim import keys_of_seeds, simulate_batch, stack_scenarios
    from lookout.sim import simulate as simulate_one

    scenario, seeds = composition.scenario, composition.seeds
    if len(seeds) == 1:
        return simulate_one(scenario, keys_of_seeds(seeds)[0], progress=progress)
    if composition.simulation.batch == "stacked":
        return simulate_batch(stack_scenarios([scenario] * len(seeds)), keys_of_seeds(seeds), batched_scenario=True, progress=progress)
    return simulate_batch(scenario, keys_of_seeds(seeds), progress=progress)


def merge(preset: dict, document: dict) -> dict:
    """``document`` over ``preset``: a table with the preset's kind (and design) is
    merged key by key (nested tables too), one with another kind replaces it."""
    merged = copy.deepcopy(preset)
    for key, value in document.items():
        if key == "preset":
            continue
        base = merged.get(key)
        if isinstance(value, dict) and isinstance(base, dict):
            if "kind" in value and value["kind"] != base.get("kind"):
                merged[key] = copy.deepcopy(value)
            elif "design" in value and value["design"] != base.get("design"):
                merged[key] = {**{k: v for k, v in base.items() if k in ("kind", "initial")}, **copy.deepcopy(value)}
            else:
                merged[key] = merge(base, value)
        else:
            merged[key] = copy.deepcopy(value)
    return merged


def load_plugins(plugins: object, location: tuple = ("plugins",)) -> list[str]:
    """Import a document's ``plugins`` (Python files, absolute or relative to the working
    folder, or modules by dotted name), whose declarations register kinds of their own
    (:func:`lookout.scenario.registry.load_plugin`); a :class:`CompositionError` names the entry."""
    if plugins is None:
        return []
    if not isinstance(plugins, list) or not all(isinstance(each, str) for each in plugins):
        raise CompositionError(location, f"must be an array of Python files or module names; got {short(plugins)}")
    for index, each in enumerate(plugins):
        try:
            registry.load_plugin(each)
        except ValueError as error:
            raise CompositionError(location + (index,), one_line(error)) from None
    return plugins


def compose(document: dict) -> Composition:
    """Validate ``document`` and build its scenario; a :class:`CompositionError` names the key."""
    from lookout.sim import Scenario

    if not isinstance(document, dict):
        raise CompositionError((), "a composition is a table of tables")
    for key in document:
        if key not in TOP_KEYS:
            raise CompositionError((key,), f"unknown key (a composition has {', '.join(TOP_KEYS)})")
    plugins = load_plugins(document.get("plugins"))
    if "preset" in document:
        preset = preset_document(document["preset"])
        # a file's [sensors.NAME] tables replace a preset's [sensor], and its [sensor] a preset's suite
        for given, replaced in (("sensors", ("sensor",)), ("sensor", ("sensors", "references"))):
            if given in document:
                for key in replaced:
                    preset.pop(key, None)
        document = merge(preset, document)
    simulation_table = document.get("simulation", {})
    if not isinstance(simulation_table, dict):
        raise CompositionError(("simulation",), "must be a table")
    simulation = _validate(SimulationSettings, simulation_table, ("simulation",))
    if "sensors" in document and "sensor" in document:
        raise CompositionError(("sensors",), "give one [sensor] table or named [sensors.NAME] tables, not both")
    if "references" in document and "sensors" not in document:
        raise CompositionError(("references",), "combines the references of [sensors.NAME] tables, and the composition has none")
    for role in ("plant", "sensor", "observer"):
        if role == "sensor" and "sensors" in document:
            continue
        if role not in document:
            raise CompositionError(
                (role,), f"missing table (a composition needs a plant, a sensor and an observer; `lookout components {role}` lists the kinds)"
            )

    context = _Context([], simulation=simulation)
    built, normal, kinds = {}, {"simulation": simulation.model_dump(mode="json")}, {}
    if plugins:
        normal["plugins"] = list(plugins)
    for role in registry.COMPONENT_ROLES:
        if role == "sensor" and "sensors" in document:
            built[role], normal["sensors"], normal["references"] = _suite(document, context, simulation.duration, simulation.sample_period)
            kinds[role] = context.kinds[role] = "suite"
            context.add(built[role])
            continue
        table = _table(document, role)
        listed = None
        if role == "actuator" and isinstance(table, dict) and "failures" in table:  # the thrusters' failures: data beside the kind's keys
            listed = table["failures"]
            table = {key: value for key, value in table.items() if key != "failures"}
        built[role], normal[role] = build_part(role, table, (role,), context, defaults=role == "plant")
        if listed is not None:
            built[role] = _thruster_failures(built[role], listed, normal[role]["kind"], simulation.duration)
            if listed:
                normal[role]["failures"] = copy.deepcopy(listed)
        kinds[role] = context.kinds[role] = normal[role]["kind"]
        if role == "plant":
            context.plant = built[role]
        context.add(built[role])
    plant_table, observer_table = document["plant"], document["observer"]
    initial_state, normal["plant"]["initial"] = _initial(built["plant"].state, plant_table.get("initial"), ("plant", "initial"))
    initial_estimate, normal["observer"]["initial"] = _initial(built["observer"].guess, observer_table.get("initial"), ("observer", "initial"))
    refusal = getattr(built["actuator"], "plant_input_refusal", None)  # an actuator that drives one kind of plant only
    reason = refusal(built["plant"].input_layout, kinds["plant"]) if refusal is not None else None
    if reason is not None:
        raise CompositionError(("actuator",), reason)
    hull = getattr(getattr(built["actuator"], "layout", None), "hull_refusal", None)  # thrusters: they must lie on the vessel
    mass = (
        next((float(np.asarray(m.mass_matrix)[0, 0]) for m in getattr(built["plant"], "models", tuple)() if hasattr(m, "mass_matrix")), None)
        if hull
        else None
    )
    reason = hull(mass) if hull is not None and mass is not None else None  # a mass is found only for a hull check
    if reason is not None:
        layout = normal["actuator"].get("layout", {}).get("kind", "given")
        raise CompositionError(("actuator", "layout"), f"layout {layout} does not fit plant {kinds['plant']}: {reason}")
    try:
        scenario = Scenario(
            plant=built["plant"],
            sensor=built["sensor"],
            observer=built["observer"],
            controller=built["controller"],
            reference=built["reference"],
            actuator=built["actuator"],
            initial_state=initial_state,
            initial_estimate=initial_estimate,
            plant_step=simulation.plant_step,
            sample_period=simulation.sample_period,
            duration=simulation.duration,
            record_every=simulation.record_every,
            integrator=simulation.integrator,
            observer_mode=simulation.observer_mode,
        )
    except ValueError as error:
        raise _scenario_error(error, kinds) from None
    bound = _divergence(simulation, built["plant"], kinds["plant"])
    if bound is None:
        normal["simulation"].pop("divergence", None)
    else:
        normal["simulation"]["divergence"] = {"signal": bound.signal, "limit": bound.limit}
    return Composition(normal, simulation, scenario, kinds)


def _thruster_failures(actuator: Any, listed: Any, kind: str, duration: float) -> Any:
    """``actuator`` (thrusters) with the failures of its ``[[actuator.failures]]`` tables
    (:mod:`lookout.actuators.failures`); a :class:`CompositionError` names the key."""
    from lookout.actuators.failures import failure_from_table

    location: tuple = ("actuator", "failures")
    layout = getattr(actuator, "layout", None)
    if not hasattr(actuator, "with_failures") or layout is None:
        raise CompositionError(location, f'only thrusters fail: actuator {kind} has none (give [actuator] kind = "thrusters" with a layout)')
    if not isinstance(listed, list):
        raise CompositionError(location, "must be an array of tables, [[actuator.failures]] with a thruster, a mode and a start")
    failures = []
    for index, each in enumerate(listed):
        try:
            failures.append(failure_from_table(each, layout.names, location + (index,), run_duration=duration))
        except ParameterError as error:
            raise CompositionError(error.location, one_line(error)) from None
    return actuator.with_failures(failures)


def _suite(document: dict, context: _Context, duration: float, sample_period: float) -> tuple[Any, dict, dict]:
    """The :class:`~lookout.sensing.suite.SensorSuite` of the ``[sensors.NAME]`` tables
    (each an instrument kind, with its ``[[sensors.NAME.failures]]``) and the
    ``[references]`` combining stage: ``(suite, sensors spelled out, references spelled out)``."""
    from lookout.sensing.failures import failure_from_table
    from lookout.sensing.suite import SensorSuite
    from lookout.sim import integer_ratio

    tables = document["sensors"]
    if not isinstance(tables, dict) or not tables:
        raise CompositionError(("sensors",), "must hold one table per sensor, [sensors.NAME] with its kind")
    instruments, failures, normal = {}, {}, {}
    for name, table in tables.items():
        location: tuple = ("sensors", name)
        if not name.isidentifier():
            raise CompositionError(location, "a sensor's name must be an identifier (letters, digits and _, not starting with a digit)")
        if not isinstance(table, dict):
            raise CompositionError(location, f"must be a table with a kind; got {type(table).__name__}")
        own = {key: value for key, value in table.items() if key != "failures"}
        if "kind" not in own:
            raise CompositionError(
                location + ("kind",), f"missing key (one of {', '.join(registry.names('instrument'))}; `lookout components instrument` lists them)"
            )
        instruments[name], normal[name] = build_part("instrument", own, location, context)
        period = instruments[name].sample_period
        if integer_ratio(period, sample_period) is None:  # blamed here, at the sensor's key
            raise CompositionError(
                location + ("sample_period",),
                f"sample_period ({period:g} s) must be an integer multiple of the simulation's sample_period ({sample_period:g} s)",
            )
        listed = table.get("failures", [])
        if not isinstance(listed, list):
            raise CompositionError(location + ("failures",), "must be an array of tables, [[sensors.NAME.failures]] with a mode and a start")
        built = []
        for index, each in enumerate(listed):
            try:
                built.append(
                    failure_from_table(
                        each, instruments[name].signals, instruments[name].sample_period, location + ("failures", index), run_duration=duration
                    )
                )
            except ParameterError as error:
                raise CompositionError(error.location, one_line(error)) from None
        failures[name] = built
        if listed:
            normal[name]["failures"] = copy.deepcopy(listed)
    references, normal_references = build_part(
        "references", document.get("references", {"kind": registry.default_kind("references")}), ("references",), context
    )
    try:
        suite = SensorSuite(instruments, failures, references)
    except ParameterError as error:
        raise CompositionError(("sensors", *error.location[1:]), one_line(error)) from None
    return suite, normal, normal_references


def _divergence(simulation: SimulationSettings, plant, kind: str):
    """The composition's divergence bound: the file's, else the plant kind's (or None)."""
    from lookout.components import DivergenceBound

    given = simulation.divergence
    if given is None:
        return type(plant).divergence
    names = [signal.name for signal in plant.variable_signals]
    if given.signal not in names:
        raise CompositionError(
            ("simulation", "divergence", "signal"), f"must be a variable of plant {kind} ({', '.join(names)}); got {given.signal!r}"
        )
    return DivergenceBound(given.signal, given.limit)


#: The Scenario's own settings, which a file gives in [simulation].
SIMULATION_KEYS = ("plant_step", "sample_period", "duration", "record_every", "integrator", "observer_mode")


def _scenario_error(error: ValueError, kinds: dict) -> CompositionError:
    """The Scenario's refusal at the file's key: a setting's under [simulation], a
    part's at its table; two parts that do not fit, named with their kinds."""
    reason = one_line(error)
    raised = error.__context__ if isinstance(error, FitError) else None  # what the fit check traced
    frame = registry.plugin_frame(raised) if raised is not None else None
    # a plugin's own code failed: the plugin's error, not a misfit of parts (a frame is found only in a FitError's context)
    if frame is not None and raised is not None and isinstance(error, FitError):
        role = next((role for role, name in kinds.items() if registry.kind(role, name).module == frame.module), error.parts[0])
        where = (role,) if role in kinds else ()
        owner = f"{role} {kinds[role]}" if role in kinds else f"the plugin {frame.module}"
        return CompositionError(where, f"{owner} (a plugin): {frame.describe(raised)}")
    if isinstance(error, ParameterError) and error.location:
        first = error.location[0]
        return CompositionError(("simulation", *error.location) if first in SIMULATION_KEYS else error.location, reason)
    if isinstance(error, FitError):
        first, second = error.parts
        detail = reason.split(": ", 1)[1] if ": " in reason else reason
        if second == "observer_mode 'continuous'":
            return CompositionError(
                ("simulation", "observer_mode"), f"observer {kinds['observer']} cannot run in observer_mode 'continuous': {detail}"
            )
        if first in kinds and second in kinds:
            return CompositionError((), f"{first} {kinds[first]} and {second} {kinds[second]} do not fit: {detail}")
    return CompositionError((), reason)


def preset_document(text: object) -> dict:
    """The composition of a reproduction's case, named ``"NAME:CASE"`` (or ``"NAME"``: its
    first case)."""
    if not isinstance(text, str):
        raise CompositionError(("preset",), f"must be a string NAME:CASE; got {text!r}")
    name, _, case = text.partition(":")
    try:
        return registry.preset(name, case or None)
    except ValueError as error:
        raise CompositionError(("preset",), one_line(error)) from None


# ------------------------------------------------------------------------- paths


def path_parts(path: str) -> list:
    """``"observer.wave_frequency[1]"`` -> ``["observer", "wave_frequency", 1]``."""
    parts: list = []
    for name in path.split("."):
        match = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)", name)
        if not match:
            raise CompositionError((), f"{path!r} is not a key path (names joined by '.', indices as [i])")
        parts.append(match.group(1))
        parts += [int(i) for i in re.findall(r"\[(\d+)\]", match.group(2))]
    return parts


def set_path(document: dict, path: str, value: Any) -> None:
    """Set the key at ``path`` of a full composition: the key must exist there, unless the
    value is a table (a part given where the composition took one from elsewhere, such as
    an observer's own vessel model; building the composition checks its keys)."""
    parts = path_parts(path)
    target: Any = document
    for depth, part in enumerate(parts):
        here = tuple(parts[: depth + 1])
        if isinstance(part, int):
            if not isinstance(target, (list, tuple)) or part >= len(target):
                raise CompositionError(
                    here, f"does not exist ({key_text(here[:-1])} has {len(target) if isinstance(target, (list, tuple)) else 'no'} entries)"
                )
        elif not isinstance(target, dict) or (part not in target and not (depth == len(parts) - 1 and isinstance(value, dict))):
            known = ", ".join(sorted(target)) if isinstance(target, dict) else "none"
            raise CompositionError(here, f"no such key (known here: {known})")
        if depth == len(parts) - 1:
            target[part] = value
        else:
            child = target[part]
            if isinstance(child, tuple):
                child = list(child)
                target[part] = child
            target = child


def get_path(document: dict, path: str) -> Any:
    """The value at ``path`` of a composition."""
    target: Any = document
    for part in path_parts(path):
        target = target[part]
    return target
