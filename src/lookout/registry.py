"""The component registry: every plant, sensor, observer, controller, reference,
actuator and environment part lookout can compose, by role and kind name.

A kind is one line of :data:`KINDS`: the role, the kind's name and the callable that
builds it (``"module:Class"`` or ``"module:Class.classmethod"``), imported only when the
kind is used. A kind with several gain-synthesis rules (``design`` in a file) maps
each rule's name to its own callable; the first is the default. Nothing else is
written for a kind: its parameter schema (names, defaults, types, ranges, a
one-line description with the units) is read from the callable's signature and its
numpydoc ``Parameters`` section (the callable's own, then its class's), so the
documentation and the file format cannot disagree.

Parameters of a kind are of three sorts:

* **values** (numbers, vectors, matrices, strings, flags) given in the file's table;
  the numpydoc type says what is taken: ``float``, ``int``, ``bool``, ``str``,
  ``{"a", "b"}`` (one of), ``array_like`` / ``sequence`` (a number or an array), and
  may add a range: ``positive``, ``non-negative``, ``in [a, b)``;
* **parts** (a parameter named after a role of :data:`KINDS`, e.g. a plant's
  ``vessel``, ``bias``, ``waves``): a nested table with its own ``kind``;
* **context** (a parameter annotated with a component class, e.g. an observer's
  ``vessel: DPVessel`` or a controller's ``observer``): taken from the parts already
  built (the plant's own vessel, the composition's observer) unless the file gives a
  table for it. ``size`` is the plant's input size and ``signals`` the plant's
  variables named in the file.

``lookout components`` lists the kinds (:func:`describe_kind`); the composition
(:mod:`lookout.composition`) builds them.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import math
import re
import typing
from dataclasses import dataclass
from typing import Any, Literal

#: role -> kind -> callable ("module:qualname"), or -> {design rule: callable} (first
#: rule the default). One line per kind: a new component is its file plus its line here.
KINDS: dict[str, dict[str, Any]] = {
    "plant": {
        "dp-vessel": "lookout.models.vessel:VesselPlant",
        "cybership-ii": "lookout.models.cybership:CybershipPlant",
        "manipulator": "lookout.models.manipulators:ManipulatorPlant",
        "furuta": "lookout.models.furuta:FurutaPlant",
        "scheduled-parameters": "lookout.models.scheduled_parameters:ScheduledParameterPlant",
    },
    # parts of plants (and the models of observers and controllers)
    "vessel": {
        "northern-clipper": "lookout.models.vessel:northern_clipper",
        "custom": "lookout.models.vessel:scaled_vessel",
    },
    "ship": {
        "cybership-ii": "lookout.models.cybership:Cybership",
        "dp-vessel": "lookout.models.cybership:Cybership.from_dp_vessel",
    },
    "model": {
        "two-link-arm": "lookout.models.manipulators:TwoLinkArm",
        "pendulum": "lookout.models.manipulators:FreePendulum",
        "cart-pendulum": "lookout.models.manipulators:CartPendulum",
        "furuta-pendulum": "lookout.models.manipulators:FurutaPendulum",
        "furuta-constants": "lookout.models.furuta:FurutaConstants",
        "printed-inertia-arm": "lookout.papers.calugi_2002_backstepping:PrintedInertiaArm",
    },
    "bias": {
        "gauss-markov": "lookout.environment.bias:GaussMarkovBias.from_stationary_std",
    },
    "waves": {
        "linear": "lookout.environment.waves:LinearWaveModel.from_amplitude",
        "jonswap": "lookout.environment.jonswap:JonswapWaves",
    },
    "disturbance": {
        "body-force": "lookout.environment.disturbance:BodyDisturbance",
    },
    "parameters": {
        "model-fields": "lookout.models.parameters:ModelParameters",
        "pendulum-inertia": "lookout.models.parameters:PendulumInertia",
    },
    "parametrization": {
        "inertia-entries": "lookout.observers.adaptive_dp:InertiaParametrization",
    },
    "sensor": {
        "position-heading": "lookout.sensors:PositionHeadingSensor",
        "position-heading-velocity": "lookout.sensors:PositionHeadingVelocitySensor",
        "joint-encoder": "lookout.sensors:JointEncoder",
        "joint-state": "lookout.sensors:JointStateSensor",
    },
    "observer": {
        "passive": {
            "fossen-strand-1999": "lookout.observers.passive:PassiveObserver.design",
            "gains": "lookout.observers.passive:PassiveObserver",
        },
        "sliding-mode": {
            "kim-2002": "lookout.observers.sliding_mode:SlidingModeObserver.design",
            "gains": "lookout.observers.sliding_mode:SlidingModeObserver.from_gains",
        },
        "earth-fixed": {
            "gains": "lookout.observers.earth_fixed:EarthFixedObserver",
            "wondergem-2009": "lookout.observers.earth_fixed:EarthFixedObserver.design",
        },
        "velocity": "lookout.observers.velocity:VelocityObserver",
        "adaptive-dp": "lookout.observers.adaptive_dp:AdaptiveObserver",
        "adaptive-manipulator": "lookout.observers.adaptive_manipulator:AdaptiveManipulatorObserver",
        "parameter-estimator": "lookout.observers.parameter_estimator:ParameterEstimator",
        "ekf": "lookout.observers.ekf:ExtendedKalmanFilter",
        "ukf": "lookout.observers.ukf:UnscentedKalmanFilter",
    },
    "controller": {
        "none": "lookout.controllers.open_loop:NoControl",
        "sinusoidal": "lookout.controllers.open_loop:SinusoidalInput",
        "observer-backstepping": "lookout.controllers.backstepping:ObserverBackstepping.for_observer",
        "vectorial-backstepping": "lookout.controllers.backstepping:VectorialBackstepping.for_observer",
        "tracking": {
            "gains": "lookout.controllers.tracking:TrackingController",
            "wondergem-2009": "lookout.controllers.tracking:TrackingController.design",
        },
        "adaptive-backstepping": "lookout.controllers.adaptive_backstepping:AdaptiveObserverBackstepping",
        "furuta-backstepping": "lookout.controllers.furuta:FurutaPendulumBackstepping",
        "pid": {"pole-placement": "lookout.controllers.pid:PidController.design", "gains": "lookout.controllers.pid:PidController"},
    },
    "reference": {
        "none": "lookout.reference:NoReference",
        "reference-filter": "lookout.reference:ReferenceFilter",
        "ellipse": "lookout.reference:EllipseReference",
    },
    "actuator": {
        "ideal": "lookout.actuators.limits:IdealActuator",
        "thrust-limits": "lookout.actuators.limits:SaturatingActuator",
        "thrusters": "lookout.actuators.thrusters:ThrusterSystem",
    },
    "layout": {
        "supply-vessel": "lookout.actuators.layout:ThrusterLayout.supply_vessel",
        "cybership-ii": "lookout.actuators.layout:ThrusterLayout.cybership_ii",
        "custom": "lookout.actuators.layout:ThrusterLayout",
    },
}

#: The tables of a composition, in the order they are built.
COMPONENT_ROLES = ("plant", "sensor", "observer", "reference", "controller", "actuator")
#: The kind a composition takes when it has no table for a role.
DEFAULT_KINDS = {"controller": "none", "reference": "none", "actuator": "ideal"}
#: Context parameters that are not components: filled by the composition by name.
CONTEXT_NAMES = {
    "size": "the plant's input size",
    "plant_step": "the composition's simulation.plant_step",
    "filter_period": "the composition's simulation.sample_period",
    "integrator": "the composition's simulation.integrator",
    "signals": "the plant's variables of these names, or tables {name, units, long_name, frame} of signals of their own",
}


class _NoDefault:
    def __repr__(self):
        return "required"


#: A parameter that the file must give.
REQUIRED = _NoDefault()


@dataclass(frozen=True)
class Parameter:
    """One parameter of a kind, as the file gives it.

    ``sort`` is ``"value"``, ``"part"`` (a nested table of role ``name``) or
    ``"context"`` (taken from the composition unless given; ``context`` is the class or
    the name looked for).
    """

    name: str
    sort: Literal["value", "part", "context"]
    type: str
    description: str
    default: Any = REQUIRED
    context: Any = None
    #: the role of a part (its name, or the role whose kinds build its annotated class)
    role: str | None = None

    @property
    def from_plant(self) -> bool:
        """A part taken from the components built before when the table does not give
        it: a required one always, an optional one when its description says so
        ("the plant's")."""
        return self.required or "the plant's" in self.description

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    @property
    def choices(self) -> tuple | None:
        """The values taken, for a ``{"a", "b"}`` (or ``{1, -1}``) type."""
        match = re.match(r"\s*\{(.*)\}", self.type)
        if not match:
            return None
        quoted = re.findall(r"['\"]([^'\"]+)['\"]", match.group(1))
        return tuple(quoted) if quoted else tuple(int(v) for v in re.findall(r"-?\d+", match.group(1)))

    @property
    def range(self) -> tuple[float, float, bool, bool] | None:
        """(low, high, low included, high included) from the type's range words."""
        text = self.type.lower()
        match = re.search(r"in\s*([\[(])\s*([^,]+),\s*([^\])]+)([\])])", text)
        if match:
            low, high = _number(match.group(2)), _number(match.group(3))
            return low, high, match.group(1) == "[", match.group(4) == "]"
        if re.search(r"\bnon-negative\b", text):
            return 0.0, math.inf, True, False
        if re.search(r"\bpositive\b", text):
            return 0.0, math.inf, False, False
        return None

    @property
    def value_type(self) -> str:
        """``"float"``, ``"int"``, ``"bool"``, ``"str"``, ``"array"``, ``"strings"``, or
        ``"parts"`` (an array, or a table of named arrays: "array_like or table")."""
        text = self.type.lower()
        if self.choices is not None:
            return "str"
        if re.search(r"\bor table\b", text):
            return "parts"
        if re.search(r"(sequence|tuple|list) of str", text):
            return "strings"
        if "array" in text or "sequence" in text:
            return "array"
        first = re.split(r"[,\s]", text.strip(), maxsplit=1)[0]
        return {"float": "float", "int": "int", "bool": "bool", "str": "str"}.get(first, "array" if "float" in text else "")


def _number(text: str) -> float:
    text = text.strip()
    return {"inf": math.inf, "-inf": -math.inf, "pi": math.pi}.get(text, None) or float(text)


@dataclass(frozen=True)
class Kind:
    """A registered component kind: its role, name, design rules and parameters."""

    role: str
    name: str
    #: design rule -> "module:qualname"; one entry (named "") when the kind has no rules
    targets: tuple[tuple[str, str], ...]

    @property
    def designs(self) -> tuple[str, ...]:
        """The design rules' names (empty when the kind has none)."""
        return tuple(name for name, _ in self.targets if name)

    def target(self, design: str | None = None) -> str:
        if design is None:
            return self.targets[0][1]
        for name, target in self.targets:
            if name == design:
                return target
        raise KeyError(design)

    def callable(self, design: str | None = None):
        """The callable that builds the kind (with ``design``'s rule)."""
        return _resolve(self.target(design))

    def parameters(self, design: str | None = None) -> tuple[Parameter, ...]:
        """The kind's parameters, from the callable's signature and numpydoc."""
        return _parameters(self.target(design))

    @property
    def description(self) -> str:
        """The first line of the built class's docstring (or the callable's)."""
        target = self.target()
        owner = _owner(target)
        doc = inspect.getdoc(owner) or inspect.getdoc(_resolve(target)) or ""
        paragraph = " ".join(doc.strip().split("\n\n")[0].split())
        return _first_sentence(paragraph)

    @property
    def component_class(self) -> type:
        """The class the kind builds (the callable's class, or its return annotation's)."""
        return _owner(self.target())


def _resolve(target: str):
    module, _, qualname = target.partition(":")
    value: Any = importlib.import_module(module)
    for part in qualname.split("."):
        value = getattr(value, part)
    return value


@functools.cache
def _owner(target: str) -> type:
    module, _, qualname = target.partition(":")
    parts = qualname.split(".")
    value: Any = importlib.import_module(module)
    value = getattr(value, parts[0])
    if isinstance(value, type):
        return value
    hints = typing.get_type_hints(value)
    returned = hints.get("return")
    return returned if isinstance(returned, type) else type(None)


def kinds(role: str | None = None) -> list[Kind]:
    """The registered kinds (of one role), in :data:`KINDS`'s order."""
    found = []
    for each_role, entries in KINDS.items():
        if role is not None and each_role != role:
            continue
        for name, targets in entries.items():
            pairs = tuple(targets.items()) if isinstance(targets, dict) else (("", targets),)
            found.append(Kind(each_role, name, pairs))
    return found


def kind(role: str, name: str) -> Kind:
    """The kind ``name`` of ``role``; a ``ValueError`` lists the known ones."""
    if role not in KINDS:
        raise ValueError(f"no role {role!r} (roles: {', '.join(KINDS)})")
    if name not in KINDS[role]:
        raise ValueError(f"no {role} kind {name!r} (one of {', '.join(KINDS[role])})")
    return next(k for k in kinds(role) if k.name == name)


def kind_of(component) -> str:
    """The registered kind name of a built component (its class's), else its class name."""
    for each in kinds():
        try:
            if type(component) is each.component_class:
                return each.name
        except Exception:
            continue
    return type(component).__name__


def _numpydoc_parameters(doc: str | None) -> dict[str, tuple[str, str]]:
    """name -> (type, description) from a numpydoc ``Parameters`` section."""
    if not doc:
        return {}
    lines = inspect.cleandoc(doc).splitlines()
    found: dict[str, tuple[str, str]] = {}
    inside, names, kind_text, description = False, [], "", []

    def flush():
        if names:
            text = " ".join(line.strip() for line in description).strip()
            for name in names:
                found[name] = (kind_text, text)

    for index, line in enumerate(lines):
        if line.strip() == "Parameters" and index + 1 < len(lines) and set(lines[index + 1].strip()) == {"-"}:
            inside = True
            continue
        if not inside:
            continue
        if set(line.strip()) == {"-"} and line.strip():
            continue
        if line and not line.startswith(" "):
            if index + 1 < len(lines) and set(lines[index + 1].strip()) == {"-"} and lines[index + 1].strip():
                flush()
                names = []
                inside = False
                continue
            flush()
            head, _, kind_text = line.partition(":")
            names = [name.strip() for name in head.split(",") if name.strip()]
            kind_text = kind_text.strip()
            description = []
        elif line.strip():
            description.append(line)
    if inside:
        flush()
    return found


def _first_sentence(text: str) -> str:
    """The first sentence (up to a full stop before a capital letter or the end), with
    reStructuredText roles and literals as plain text."""
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text).replace("``", "")
    match = re.match(r"(.+?\.)(\s+[A-Z]|$)", text)
    return match.group(1) if match else text


@functools.cache
def _parameters(target: str, values_only: bool = False) -> tuple[Parameter, ...]:
    """The parameters of ``target``; with ``values_only`` every one is a value (a
    plant's ``state``, an observer's ``guess``: no parts, no context)."""
    function = _resolve(target)
    owner = _owner(target)
    signature = inspect.signature(function)
    docs = {**_numpydoc_parameters(inspect.getdoc(owner) if isinstance(owner, type) else None), **_numpydoc_parameters(inspect.getdoc(function))}
    try:
        hints = typing.get_type_hints(function.__init__ if isinstance(function, type) else function)
    except Exception:
        hints = {}
    parameters = []
    for name, parameter in signature.parameters.items():
        if name in ("self", "cls") or parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
            continue
        default = REQUIRED if parameter.default is inspect.Parameter.empty else parameter.default
        if name not in docs and default is not REQUIRED:
            continue  # undocumented with a default: internal (a field's static default), not a file key
        type_text, description = docs.get(name, ("", ""))
        annotation = hints.get(name)
        component_type = _component_type(annotation)
        role = None if values_only else (_role_of_class(component_type) or (name if name in KINDS else None))
        if values_only:
            sort = "value"
        elif role is not None:
            sort = "part"
        elif component_type is not None or name in CONTEXT_NAMES:
            sort = "context"
        else:
            sort = "value"
        parameters.append(Parameter(name, sort, type_text, _first_sentence(description), default, component_type or CONTEXT_NAMES.get(name), role))
    return tuple(parameters)


def _role_of_class(cls) -> str | None:
    """The role whose kinds build instances of ``cls`` (a ManipulatorModel: ``model``)."""
    if not isinstance(cls, type):
        return None
    for role, entries in KINDS.items():
        for each in kinds(role):
            built = each.component_class
            if isinstance(built, type) and issubclass(built, cls):
                return role
    return None


def _component_type(annotation) -> type | None:
    """The equinox Module class an annotation names (``X`` or ``X | None``), else None."""
    import equinox as eqx

    candidates = typing.get_args(annotation) if typing.get_origin(annotation) in (typing.Union, getattr(__import__("types"), "UnionType", None)) else (annotation,)
    for candidate in candidates:
        if isinstance(candidate, type) and issubclass(candidate, eqx.Module):
            return candidate
    return None


#: Where the presets live: the reproductions (resolved by name when asked for, as the
#: kinds are, so that the registry imports none of the modules it names).
PRESETS = "lookout.papers"


def _reproductions():
    papers = importlib.import_module(PRESETS)
    return papers.CATALOG, papers.REPRODUCTIONS


def preset(name: str, case: str | None = None) -> dict:
    """The composition of a reproduction's case (its first case when ``case`` is None),
    with the reproduction's default settings."""
    CATALOG, REPRODUCTIONS = _reproductions()
    if name not in CATALOG:
        raise ValueError(f"no preset {name!r} (one of {', '.join(CATALOG)}, each with :CASE)")
    reproduction = REPRODUCTIONS[name]
    cases = reproduction.cases
    if case is None:
        case = cases[0]
    if case not in cases:
        raise ValueError(f"{name} has no case {case!r} (one of {', '.join(cases)})")
    return reproduction.composition(reproduction.Config(), case)


def presets() -> list[tuple[str, str]]:
    """Every reproduction's case, as (name, case)."""
    CATALOG, REPRODUCTIONS = _reproductions()
    return [(name, case) for name in CATALOG for case in REPRODUCTIONS[name].cases]


def describe_kind(each: Kind, design: str | None = None) -> dict:
    """A kind as plain data (for ``lookout components --json`` and the docs): with its
    design rules, the one described (``design``: the default when None; None for a kind
    without rules) and that rule's parameters."""
    return {
        "role": each.role,
        "kind": each.name,
        "description": each.description,
        "designs": list(each.designs),
        "design": design if design is not None else (each.designs[0] if each.designs else None),
        "parameters": [
            {
                "name": p.name,
                "sort": p.sort,
                "type": p.type,
                "default": None if p.required else _plain(p.default),
                "required": p.required and p.sort == "value",
                "role": p.role,
                "from_plant": p.sort == "part" and p.from_plant,
                "description": p.description,
            }
            for p in each.parameters(design)
        ],
    }


def _plain(value):
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, (int, float, str, bool)) or value is None:
        return value
    try:
        import numpy as np

        return np.asarray(value).tolist()
    except Exception:
        return repr(value)
