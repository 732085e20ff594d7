"""The component registry: every plant, sensor, observer, controller, reference,
actuator and environment part lookout can compose, by role and kind name.

A kind is declared once, next to the class that builds it, with
:func:`lookout.declare.component` (see that module): its role, name, summary,
its parameters as typed declarations (values with their types, shapes, ranges and
choices; parts and whether the plant may give them; context the composition fills),
its gain-synthesis rules, tuning family and condition checks. This module collects
the declarations of lookout's own modules (:data:`BUILTIN_MODULES`), of plugin files a
scenario names (:func:`load_plugin`) and of installed packages (the entry-point group
``lookout.components``: each entry point names a module to import). Installed packages
are imported only when they are needed: when a file names a kind that neither lookout
nor its plugins declare (:func:`kind`), and when ``lookout components`` lists every
kind; ``LOOKOUT_ENTRY_POINTS=0`` leaves them out (:data:`ENTRY_POINTS_SWITCH`). Defaults
come from the builder's signature and the classes a part accepts from its annotations;
nothing is read from a docstring.

``lookout components`` lists the kinds (:func:`describe_kind`); the composition
(:mod:`lookout.scenario.composition`) builds them.
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import importlib.util
import inspect
import os
import sys
import typing
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from lookout import declare
from lookout.declare import ROLES, Declaration, Part, Range, Value
from lookout.declare import kind_of as kind_of  # a component's kind, stamped on its class when declared

#: The modules whose declarations are lookout's own kinds, in the order each role's
#: kinds are listed (the first kind of a role is its default).
BUILTIN_MODULES = (
    "lookout.models.vessel",
    "lookout.models.cybership",
    "lookout.models.manipulators",
    "lookout.models.furuta",
    "lookout.models.scheduled_parameters",
    "lookout.environment.bias",
    "lookout.environment.waves",
    "lookout.environment.jonswap",
    "lookout.environment.disturbance",
    "lookout.models.parameters",
    "lookout.sensors",
    "lookout.sensing.position",
    "lookout.sensing.heading",
    "lookout.sensing.motion",
    "lookout.sensing.rate_gyro",
    "lookout.sensing.combining",
    "lookout.sensing.handling",
    "lookout.observers.passive",
    "lookout.observers.sliding_mode",
    "lookout.observers.earth_fixed",
    "lookout.observers.velocity",
    "lookout.observers.adaptive_dp",
    "lookout.observers.adaptive_manipulator",
    "lookout.observers.parameter_estimator",
    "lookout.observers.ekf",
    "lookout.observers.ukf",
    "lookout.observers.model_free",
    "lookout.observers.ins",
    "lookout.controllers.open_loop",
    "lookout.controllers.backstepping",
    "lookout.controllers.tracking",
    "lookout.controllers.adaptive_backstepping",
    "lookout.controllers.furuta",
    "lookout.controllers.pid",
    "lookout.null_components",
    "lookout.reference",
    "lookout.actuators.limits",
    "lookout.actuators.thrusters",
    "lookout.actuators.layout",
)
#: The entry-point group under which an installed package names modules of its own kinds.
ENTRY_POINT_GROUP = "lookout.components"
#: The environment variable that, set to 0, leaves installed packages' kinds out (1 or
#: unset: they are imported when needed).
ENTRY_POINTS_SWITCH = "LOOKOUT_ENTRY_POINTS"

#: The tables of a composition, in the order they are built.
COMPONENT_ROLES = ("plant", "sensor", "observer", "reference", "controller", "actuator")
#: The kind a composition takes when it has no table for a role.
DEFAULT_KINDS = {"controller": "none", "reference": "none", "actuator": "ideal"}
#: The kind of a part's table that names none, and of a required part found nowhere.
DEFAULT_PART_KINDS = {
    "vessel": "northern-clipper",
    "ship": "cybership-ii",
    "model": "two-link-arm",
    "bias": "gauss-markov",
    "waves": "linear",
    "disturbance": "body-force",
    "parameters": "model-fields",
    "parametrization": "inertia-entries",
    "layout": "supply-vessel",
    "references": "weighted-mean",
}
#: Context parameters that are not components: filled by the composition by name.
CONTEXT_NAMES = {
    "size": "the plant's input size",
    "plant_step": "the composition's simulation.plant_step",
    "filter_period": "the composition's simulation.sample_period",
    "integrator": "the composition's simulation.integrator",
    "signals": "the plant's variables of these names, or tables {name, units, long_name, frame} of signals of their own",
}
#: Where the composition takes each context value from, as a refusal of the file's value says it.
CONTEXT_ORIGINS = {
    "size": "the plant (its input size)",
    "plant_step": "[simulation] (the plant's integration step)",
    "filter_period": "[simulation] (the loop's sample period)",
    "integrator": "[simulation] (the plant's integrator)",
}


def context_origin(parameter: Parameter) -> str:
    """Where the composition takes the context ``parameter`` from, in words."""
    if parameter.name in CONTEXT_ORIGINS:
        return CONTEXT_ORIGINS[parameter.name]
    source = parameter.context
    return f"the {source.__name__} built before it" if isinstance(source, type) else f"the composition ({source or parameter.name})"


class _NoDefault:
    def __repr__(self):
        return "required"


#: A parameter that the file must give.
REQUIRED = _NoDefault()


@dataclass(frozen=True)
class Parameter:
    """One parameter of a kind, as the file gives it: its declaration with the
    builder's default (and, for a part, the class its annotation names).

    ``sort`` is ``"value"``, ``"part"`` (a nested table of role ``role``) or
    ``"context"`` (taken from the composition; ``context`` is the class or the name
    looked for).
    """

    name: str
    sort: Literal["value", "part", "context"]
    type: str
    description: str
    default: Any = REQUIRED
    context: Any = None
    #: the role of a part
    role: str | None = None
    #: what a value takes: "float", "int", "bool", "str", "array", "strings", "parts"
    value_type: str = ""
    #: the values taken, for a value of a few choices
    choices: tuple | None = None
    #: (low, high, low included, high included)
    range: tuple[float, float, bool, bool] | None = None
    #: a part the composition takes from the components built before when not given
    declared_from_plant: bool = False
    #: a context value the file may give in place of the composition's (declare.Context.own)
    own: bool = False
    #: a value's declared shape (``"(3,)"``), and whether one number stands for every entry
    shape: str | None = None
    broadcast: bool = True

    def shape_refusal(self, value: object) -> str | None:
        """Why ``value`` does not have the declared shape (None: it has it, or none is declared)."""
        return declare.shape_refusal(value, self.shape, self.broadcast)

    @property
    def from_plant(self) -> bool:
        """A part taken from the components built before when the table does not give
        it: a required one always, an optional one when declared so."""
        return self.required or self.declared_from_plant

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@dataclass(frozen=True)
class Kind:
    """A registered component kind: its role, name, rules and parameters."""

    role: str
    name: str
    declaration: Declaration

    @property
    def designs(self) -> tuple[str, ...]:
        """The design rules' names (empty when the kind has none)."""
        return tuple(name for name, _ in self.declaration.rules if name)

    def _rule(self, design: str | None):
        rules = self.declaration.rules
        if design is None:
            return rules[0][1]
        for name, rule in rules:
            if name == design:
                return rule
        raise KeyError(design)

    def callable(self, design: str | None = None) -> Callable[..., Any]:
        """The callable that builds the kind (with ``design``'s rule)."""
        return _builder(self.declaration.target, self._rule(design).build)

    def parameters(self, design: str | None = None) -> tuple[Parameter, ...]:
        """The kind's parameters: its declarations, with the builder's defaults."""
        return _kind_parameters(self, design)

    @property
    def description(self) -> str:
        """The kind's one-sentence summary, as declared."""
        return self.declaration.summary

    @property
    def component_class(self) -> type:
        """The class the kind builds (the declared class, or the function's return annotation's)."""
        target = self.declaration.target
        if isinstance(target, type):
            return target
        returned = typing.get_type_hints(target).get("return")
        return returned if isinstance(returned, type) else type(None)

    @property
    def family(self) -> str | None:
        """The kind's tuning family, ``"module:attribute"`` (None: not tunable)."""
        return self.declaration.family

    @property
    def checks(self) -> str | None:
        """The function ``lookout design`` calls for the kind's conditions (None: it has none)."""
        return self.declaration.checks

    @property
    def module(self) -> str:
        """The module that declared the kind."""
        return self.declaration.module


@functools.cache
def _kind_parameters(each: Kind, design: str | None) -> tuple[Parameter, ...]:
    return _parameters(each.callable(design), each._rule(design).parameters, f"{each.role} {each.name}")


def _builder(target, build):
    if build is None:
        return target
    if callable(build):
        return build
    if ":" in build:
        return resolve(build)
    return getattr(target, build)


def resolve(path: str) -> Any:
    """The object a ``"module:qualname"`` string names (imported when asked for)."""
    module, _, qualname = path.partition(":")
    value: Any = importlib.import_module(module)
    for part in qualname.split("."):
        value = getattr(value, part)
    return value


_LOADED: dict[str, Any] = {}


def _ensure_loaded() -> None:
    if "builtin" in _LOADED:
        return
    _LOADED["builtin"] = True
    for module in BUILTIN_MODULES:
        importlib.import_module(module)


class DuplicateKindError(ValueError):
    """Two declarations of one kind of one role."""


def _import_declaring(load, what: str, module: str) -> None:
    """``load()`` (an import that must declare kinds), kept only when it imports, declares
    at least one kind and declares no kind twice; else its declarations and ``module`` are
    dropped and a ValueError says why, beginning with ``what``. Whatever the import raises
    is caught (``sys.exit`` included), except a KeyboardInterrupt."""
    before = len(declare.DECLARED)
    try:
        load()
        if len(declare.DECLARED) == before:
            raise _DeclaresNothing()
        _index(len(declare.DECLARED), id(declare.DECLARED[-1]))
    except KeyboardInterrupt:
        del declare.DECLARED[before:]
        sys.modules.pop(module, None)
        raise
    except BaseException as error:
        del declare.DECLARED[before:]
        sys.modules.pop(module, None)
        raise ValueError(what + _import_failure(error)) from None


class _DeclaresNothing(Exception):
    """A plugin that imports and registers no kind."""


def _import_failure(error: BaseException) -> str:
    """Why a plugin's import is refused, as the end of a sentence that names the plugin."""
    if isinstance(error, DuplicateKindError):
        return f": {error}"
    if isinstance(error, _DeclaresNothing):
        return " declares no kind: decorate a class with @component(...) (lookout.plugin)"
    if isinstance(error, SystemExit):
        return f" exited (SystemExit {error.code}) while being imported"
    message = " ".join(str(error).split())
    return f" does not import: {type(error).__name__}" + (f": {message}" if message else "")


def entry_points_enabled() -> bool:
    """Whether installed packages' kinds are imported when needed: :data:`ENTRY_POINTS_SWITCH`
    unset or ``1`` (``0`` leaves them out); any other value is a ValueError naming it."""
    value = os.environ.get(ENTRY_POINTS_SWITCH, "1").strip()
    if value not in ("0", "1"):
        raise ValueError(f"{ENTRY_POINTS_SWITCH} must be 0 (leave installed packages' kinds out) or 1; got {value!r}")
    return value == "1"


def load_entry_points() -> None:
    """Import the modules installed packages name under :data:`ENTRY_POINT_GROUP` (each
    once), so that their declarations are registered; nothing with
    ``LOOKOUT_ENTRY_POINTS=0``. One that does not import (or declares nothing, or a kind
    twice) is a ValueError naming the entry point and its package."""
    if "entry_points" in _LOADED or not entry_points_enabled():
        return
    _ensure_loaded()
    for entry in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        module = entry.value.partition(":")[0]
        if module not in sys.modules:
            package = getattr(getattr(entry, "dist", None), "name", None)
            _import_declaring(
                lambda: importlib.import_module(module),
                f"the entry point {entry.name} = {entry.value!r} (group {ENTRY_POINT_GROUP}"
                + (f", package {package}" if package else "")
                + f"; {ENTRY_POINTS_SWITCH}=0 leaves installed packages' kinds out)",
                module,
            )
    _LOADED["entry_points"] = True


def plugin_file(text: str, base: str | Path | None = None) -> Path | None:
    """The file a plugin entry names (relative to ``base``), or None for a module's dotted
    name (and for an empty entry): an entry is a file when it ends in ``.py``, holds a
    path separator, or names a file or a folder that exists."""
    if not text.strip():
        return None
    file = Path(text) if base is None or Path(text).is_absolute() else Path(base) / text
    return file.resolve() if text.endswith(".py") or "/" in text or "\\" in text or file.exists() else None


def load_plugin(path: str | Path, base: str | Path | None = None) -> str:
    """Import the Python file ``path`` (relative to ``base``, a scenario file's folder),
    so that the kinds it declares are registered; each file is imported once. A dotted
    name (``my_package.observers``) is imported as a module. Returns the module's name.
    """
    text = str(path)
    if not text.strip():
        raise ValueError(f"plugin {text!r}: an empty entry; give a Python file (.py) or a module's dotted name")
    file = plugin_file(text, base)
    _ensure_loaded()
    if file is None:
        if not all(part.isidentifier() for part in text.split(".")):
            raise ValueError(f"plugin {text!r}: must be a Python file (.py) or a module's dotted name")
        if text not in sys.modules:
            try:
                found = importlib.util.find_spec(text) is not None
            except ModuleNotFoundError:
                found = False
            if not found:
                raise ValueError(f"plugin {text!r}: no such module")
            _import_declaring(lambda: importlib.import_module(text), f"plugin {text!r}", text)
        return text
    if file.is_dir():
        raise ValueError(f"plugin {text!r}: is a folder, not a Python file" + ("" if str(file) == text else f" ({file})"))
    if not file.is_file():
        raise ValueError(f"plugin {text!r}: no such file" + ("" if str(file) == text else f" (looked for {file})"))
    if file.suffix != ".py":
        raise ValueError(f"plugin {text!r}: must be a Python file (.py) or a module's dotted name; got a {file.suffix or 'file without a suffix'}")
    name = _plugin_module_name(file)
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, file)
        if spec is None or spec.loader is None:
            raise ValueError(f"plugin {text!r}: Python cannot load it as a module" + ("" if str(file) == text else f" ({file})"))
        module = importlib.util.module_from_spec(spec)

        def load():
            sys.modules[name] = module
            spec.loader.exec_module(module)

        _import_declaring(load, f"plugin {text!r}", name)
    return name


@functools.lru_cache(maxsize=8)
def _index(count: int, last: int = 0) -> dict[str, dict[str, Kind]]:
    """The kinds of the first ``count`` declarations (``last``: the id of the last one, so
    that declarations dropped and others made do not find a stale index)."""
    order = {module: index for index, module in enumerate(BUILTIN_MODULES)}
    found: dict[str, dict[str, Kind]] = {role: {} for role in ROLES}
    ranked = sorted(enumerate(declare.DECLARED[:count]), key=lambda pair: (order.get(pair[1].module, len(order)), pair[0]))
    for _, each in ranked:
        known = found[each.role]
        if each.kind in known:
            first = _where(known[each.kind].declaration.module)
            raise DuplicateKindError(f"{each.role} kind {each.kind!r} is declared twice: by {first} and by {_where(each.module)}")
        known[each.kind] = Kind(each.role, each.kind, each)
    return found


def _where(module: str) -> str:
    """A module by name, a plugin file by its path."""
    loaded = sys.modules.get(module)
    return str(getattr(loaded, "__file__", module)) if module.startswith("lookout_plugin_") else module


@dataclass(frozen=True)
class PluginFrame:
    """Where in a plugin's code an exception was raised: the plugin's module, its file,
    the line and the function (``LuenbergerObserver.update``)."""

    module: str
    file: str
    line: int
    function: str

    def describe(self, error: BaseException) -> str:
        """``"LuenbergerObserver.update raised RuntimeError: ... (file, line 169)"``."""
        message = " ".join(str(error).split())
        return f"{self.function} raised {type(error).__name__}" + (f": {message}" if message else "") + f" ({self.file}, line {self.line})"


def plugin_frame(error: BaseException) -> PluginFrame | None:
    """The innermost frame of a plugin's code (a module outside lookout that declared
    kinds: a plugin file, a plugin module, an installed package's) that ``error``'s
    traceback passes through; None when it passes through none (the error is lookout's,
    or a misfit of parts)."""
    modules = {each.module for each in declare.DECLARED if each.module != "lookout" and not each.module.startswith("lookout.")}
    found = None
    trace = error.__traceback__
    while trace is not None:
        frame = trace.tb_frame
        module = frame.f_globals.get("__name__")
        if module in modules:
            code = frame.f_code
            found = PluginFrame(module, code.co_filename, trace.tb_lineno, code.co_qualname)
        trace = trace.tb_next
    return found


def _kinds() -> dict[str, dict[str, Kind]]:
    _ensure_loaded()
    return _index(len(declare.DECLARED), id(declare.DECLARED[-1]) if declare.DECLARED else 0)


def roles() -> tuple[str, ...]:
    """Every role, in the order kinds are listed."""
    return ROLES


def names(role: str) -> tuple[str, ...]:
    """The names of ``role``'s kinds, in the order listed."""
    return tuple(_kinds()[role])


def default_kind(role: str) -> str | None:
    """The kind a part's table of ``role`` takes when it names none (None: it must name one)."""
    return DEFAULT_PART_KINDS.get(role)


def kinds(role: str | None = None, *, plugins: Iterable[str] | None = None) -> list[Kind]:
    """The registered kinds (of one role), role by role: lookout's, the plugins' loaded
    and installed packages' once imported (:func:`load_entry_points`); with ``plugins``
    (files or modules, as a scenario's ``plugins`` gives them), of the plugin files only
    those named."""
    table = _kinds()
    found = [each for each_role in ROLES if role is None or each_role == role for each in table[each_role].values()]
    if plugins is None:
        return found
    named = {_plugin_module_name(file) for each in plugins if (file := plugin_file(str(each))) is not None}
    return [each for each in found if not each.module.startswith("lookout_plugin_") or each.module in named]


def _plugin_module_name(file: Path) -> str:
    """The module name a plugin file is imported under."""
    return "lookout_plugin_" + "".join(c if c.isalnum() else "_" for c in str(file))


def kind(role: str, name: str) -> Kind:
    """The kind ``name`` of ``role``; a ``ValueError`` lists the known ones. A name that
    neither lookout nor a plugin loaded declares is looked for among installed packages'
    kinds (:func:`load_entry_points`), whose import errors are then this call's."""
    if role not in ROLES:
        raise ValueError(f"no role {role!r} (roles: {', '.join(ROLES)})")
    table = _kinds()[role]
    if name not in table and "entry_points" not in _LOADED:
        try:
            load_entry_points()
        except ValueError as error:
            raise ValueError(f"no {role} kind {name!r} among lookout's and the plugins' kinds, and {error}") from None
        table = _kinds()[role]
    if name not in table:
        raise ValueError(f"no {role} kind {name!r} (one of {', '.join(table)})")
    return table[name]


def _type_text(each, default, annotation_class) -> str:
    """What ``lookout components`` shows as a parameter's type, from its declaration."""
    if isinstance(each, Value):
        if each.choices is not None:
            text = "{" + ", ".join(repr(c) if isinstance(c, str) else str(c) for c in each.choices) + "}"
            text = text.replace("'", '"')
        else:
            text = {"array": "array_like", "strings": "sequence of str", "parts": "array_like or table"}.get(each.type, each.type)
        if each.shape:
            text += f", shape {each.shape}" + ("" if each.broadcast else ", not one number")
        if each.range is not None:  # "float in [0, 1)", "array_like, shape (3,), positive"
            words = each.range.words()
            text += f" {words}" if each.type == "float" and words.startswith("in ") else f", {words}"
        return text + (", optional" if default is None else "")
    if isinstance(each, Part):
        text = annotation_class.__name__ if isinstance(annotation_class, type) else f"a {each.role or each.name} table"
        return text + (", optional" if default is None else "")
    return annotation_class.__name__ if isinstance(annotation_class, type) else "context"


def _range_tuple(value: Range | None):
    return None if value is None else (value.low, value.high, value.low_closed, value.high_closed)


def _parameters(builder, declared, owner: str) -> tuple[Parameter, ...]:
    """The parameters of ``builder`` as ``declared`` (defaults from its signature; the
    class a part or context accepts from its annotation). A declared name the builder
    does not take, or a required argument not declared, is an error in the declaration."""
    signature = inspect.signature(builder)
    taken = {name: p for name, p in signature.parameters.items() if name not in ("self", "cls") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
    names = [each.name for each in declared]
    unknown = [name for name in names if name not in taken]
    if unknown:
        raise ValueError(f"{owner}: declares {', '.join(unknown)}, which its builder does not take")
    undeclared = [name for name, p in taken.items() if p.default is inspect.Parameter.empty and name not in names]
    if undeclared:
        raise ValueError(f"{owner}: its builder requires {', '.join(undeclared)}, which it does not declare")
    parameters = []
    for each in declared:
        default = taken[each.name].default
        default = REQUIRED if default is inspect.Parameter.empty else default
        needs_class = isinstance(each, Part) or (not isinstance(each, Value) and each.source is None)
        accepted = _component_type(_annotation(builder, each.name, owner)) if needs_class else None
        if isinstance(each, Value):
            parameters.append(
                Parameter(
                    each.name,
                    "value",
                    _type_text(each, default, None),
                    each.doc,
                    default,
                    value_type=each.type,
                    choices=each.choices,
                    range=_range_tuple(each.range),
                    shape=each.shape,
                    broadcast=each.broadcast,
                )
            )
        elif isinstance(each, Part):
            parameters.append(
                Parameter(
                    each.name,
                    "part",
                    _type_text(each, default, accepted),
                    each.doc,
                    default,
                    accepted,
                    each.role or each.name,
                    declared_from_plant=each.from_plant,
                )
            )
        else:
            source = each.source if each.source is not None else (accepted or CONTEXT_NAMES.get(each.name))
            parameters.append(
                Parameter(
                    each.name,
                    "context",
                    _type_text(each, default, source if isinstance(source, type) else None),
                    each.doc,
                    default,
                    source,
                    own=each.own,
                )
            )
    return tuple(parameters)


def initial_parameters(method: Callable[..., Any]) -> tuple[Parameter, ...]:
    """The keys a plant's ``state`` or an observer's ``guess`` takes, as declared by
    :func:`lookout.declare.initial_values` on it."""
    function = getattr(method, "__func__", method)
    declared = getattr(function, "__lookout_initial__", None)
    if declared is None:
        raise ValueError(f"{function.__qualname__} declares no initial values (lookout.declare.initial_values)")
    return _parameters(function, declared, function.__qualname__)


def initial_extra(method: Callable[..., Any]) -> tuple[Parameter, ...]:
    """The keys ``method`` takes beyond those of the method it declares the keys of
    (:func:`lookout.declare.initial_values`'s ``extra``)."""
    function = getattr(method, "__func__", method)
    declared = getattr(function, "__lookout_initial_extra__", ())
    return _parameters(function, declared, function.__qualname__) if declared else ()


def initial_same_as(method: Callable[..., Any]) -> str | None:
    """The attribute path whose method's keys ``method`` takes (``"model.state"``), if declared."""
    return getattr(getattr(method, "__func__", method), "__lookout_initial_same_as__", None)


def _annotation(builder: Callable, name: str, owner: str) -> Any:
    """The annotation of ``builder``'s parameter ``name``, evaluated where the builder is
    defined (None when it has none). Each parameter is resolved on its own: an annotation
    that names something imported only for type checkers is an error in the declaration
    of a part or a context (the registry could not know the class it accepts), and leaves
    the other parameters alone."""
    function = builder.__init__ if isinstance(builder, type) else builder  # type: ignore[misc]  # a class's __init__, read for its annotations
    raw = inspect.get_annotations(function).get(name)
    if not isinstance(raw, str):
        return raw
    try:
        return eval(raw, getattr(function, "__globals__", {}))  # what typing.get_type_hints does with a string annotation
    except Exception as error:
        raise ValueError(
            f"{owner}: the annotation of {name} ({raw}) does not resolve where the builder is defined ({error}); "
            "a part's or a context's class must be imported at run time"
        ) from None


def _component_type(annotation) -> type | None:
    """The equinox Module class an annotation names (``X`` or ``X | None``), else None."""
    import equinox as eqx

    candidates = (
        typing.get_args(annotation)
        if typing.get_origin(annotation) in (typing.Union, getattr(__import__("types"), "UnionType", None))
        else (annotation,)
    )
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
