"""How a component declares itself to lookout: its role, kind name, parameters, rules.

A component is registered once, next to its class, by :func:`component` (a class
decorator) or :func:`register` (a statement, for a kind built by a function or a
classmethod of a class declared elsewhere). A declaration carries everything a scenario
file needs to build the kind and everything ``lookout components`` shows of it:

* :class:`Value`: a key of the kind's table (a number, an array, a string, a flag),
  with its type, shape, range, choices and a one-sentence description with its units;
* :class:`Part`: a nested table with its own ``kind`` (a vessel, a sea, a layout), of a
  role; ``from_plant`` says whether the composition takes it from the components built
  before when the table does not give it;
* :class:`Context`: taken from the composition (the plant's input size, the simulation's
  step, the plant's variables by name), never given in the file;
* a kind's gain-synthesis **rules** (``design = "..."`` in a file), each with its own
  parameters; its tuning **family** and its **checks** (the conditions ``lookout
  design`` verifies), as ``"module:attribute"`` strings resolved only when used, so a
  component never imports the design code that checks it.

Defaults come from the callable's signature; parts' accepted classes from its
annotations. Registering a kind stamps its declaration on the class it builds (the
declared class, or the class a declared function's return annotation names), so that
:func:`kind_of` names a built component's kind without the registry. This module
imports nothing of lookout: any component module may import it.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar

#: The roles of a composition's tables and of the parts inside them, in the order
#: ``lookout components`` lists them.
ROLES = (
    "plant",
    "vessel",
    "ship",
    "model",
    "bias",
    "waves",
    "disturbance",
    "parameters",
    "parametrization",
    "sensor",
    "instrument",
    "references",
    "observer",
    "controller",
    "reference",
    "actuator",
    "layout",
)

ValueType = Literal["float", "int", "bool", "str", "array", "strings", "parts"]


@dataclass(frozen=True)
class Range:
    """An interval a number (every entry of an array) must lie in."""

    low: float = -math.inf
    high: float = math.inf
    low_closed: bool = True
    high_closed: bool = True

    def words(self) -> str:
        """``"positive"``, ``"non-negative"`` or ``"in [a, b)"``."""
        if (self.low, self.high, self.high_closed) == (0.0, math.inf, False):
            return "non-negative" if self.low_closed else "positive"
        return f"in {'[' if self.low_closed else '('}{_number(self.low)}, {_number(self.high)}{']' if self.high_closed else ')'}"


def _number(value: float) -> str:
    if value == math.pi:
        return "pi"
    if value == -math.pi:
        return "-pi"
    return f"{value:g}"


#: x > 0 (and finite).
POSITIVE = Range(0.0, math.inf, False, False)
#: x >= 0 (and finite).
NON_NEGATIVE = Range(0.0, math.inf, True, False)


@dataclass(frozen=True)
class Value:
    """A value parameter: a key of the kind's table.

    ``type`` is what the file gives: ``"float"``, ``"int"``, ``"bool"``, ``"str"``,
    ``"array"`` (a number or an array), ``"strings"`` (an array of strings) or
    ``"parts"`` (an array, or a table of named arrays). ``shape`` is checked when the
    file is read where its sizes are numbers (``"(3,)"``, ``"(3, 3)"``); sizes named by a
    letter (``"(n,)"``, the plant's) the component checks against its model.
    ``broadcast``: one number stands for every entry (a gain per axis); without it an
    array-valued key takes an array only (a thruster's position: one number would put
    every thruster at one place). ``choices`` and ``range`` are checked when the file
    is read.
    """

    name: str
    type: ValueType
    doc: str = ""
    shape: str | None = None
    choices: tuple | None = None
    range: Range | None = None
    broadcast: bool = True

    sort = "value"

    def shape_refusal(self, value: object) -> str | None:
        """Why ``value`` (as a file gives it: a number, or nested lists or tuples of
        numbers) does not have the declared shape, or None when it has it (or the shape
        is not one of numbers)."""
        return shape_refusal(value, self.shape, self.broadcast)


def fixed_shape(shape: str | None) -> tuple[int, ...] | None:
    """The sizes of a shape text of numbers (``"(3,)"`` -> ``(3,)``); None for one with
    a size named by a letter, or with alternatives (``"(n,) or scalar"``)."""
    if shape is None:
        return None
    text = shape.strip()
    if not (text.startswith("(") and text.endswith(")")):
        return None
    parts = [part.strip() for part in text[1:-1].split(",") if part.strip()]
    return tuple(int(part) for part in parts) if parts and all(part.isdigit() for part in parts) else None


def _array_shape(value) -> tuple[int, ...] | None:
    """The shape of nested lists or tuples of equal lengths; None when ragged."""
    if not isinstance(value, (list, tuple)):
        return ()
    inner = [_array_shape(item) for item in value]
    if any(each is None for each in inner) or len(set(inner)) > 1:
        return None
    first = inner[0] if inner else ()
    assert first is not None  # a ragged item returned None above
    return (len(value),) + first


def shape_refusal(value: object, shape: str | None, broadcast: bool = True) -> str | None:
    """Why ``value`` does not fit the declared ``shape`` (see :meth:`Value.shape_refusal`)."""
    if isinstance(value, dict) or isinstance(value, (str, bool)):
        return None
    given = _array_shape(value)
    if given == ():
        if broadcast:
            return None
        return f"must be an array, {f'shape {shape}' if shape else 'one entry each'}: one number does not stand for every entry here; got {value!r}"
    sizes = fixed_shape(shape)
    if sizes is None or given == sizes:
        return None
    if len(sizes) == 1 and given is not None and len(given) == 1:
        return ("must be one number or have" if broadcast else "must have") + f" {sizes[0]} entries; got {given[0]} entries"
    found = "a ragged array" if given is None else f"an array of shape {given}"
    return f"must be an array of shape {shape}" + (" or one number" if broadcast else "") + f"; got {found}"


@dataclass(frozen=True)
class Part:
    """A part: a nested table of ``role`` (the parameter's name unless given) with its
    own ``kind``; with ``from_plant``, a table the file leaves out is taken from the
    components built before (the plant's vessel, its sea), else it is required or
    absent."""

    name: str
    doc: str = ""
    role: str | None = None
    from_plant: bool = False

    sort = "part"


@dataclass(frozen=True)
class Context:
    """A parameter the composition fills, never the file: ``source`` is one of
    ``size``, ``plant_step``, ``filter_period``, ``integrator``, ``signals`` (see
    :data:`lookout.scenario.registry.CONTEXT_NAMES`), or a class of component found
    among those built before. A file that gives it is refused at the key, unless
    ``own``: a value of the component's own that defaults to the composition's (a
    Kalman filter's propagation step, which may be coarser than the plant's)."""

    name: str
    doc: str = ""
    source: Any = None
    own: bool = False

    sort = "context"


Declared = Value | Part | Context


@dataclass(frozen=True)
class Rule:
    """How a kind is built: ``build`` names the classmethod of the declared class
    (``None``: the class itself), or is a ``"module:function"`` string or a callable;
    ``parameters`` are the file's keys for it."""

    build: str | Callable | None
    parameters: tuple[Declared, ...] = ()


@dataclass(frozen=True)
class Declaration:
    """One registered kind."""

    role: str
    kind: str
    target: Any  # the declared class or function
    rules: tuple[tuple[str, Rule], ...]  # (rule name, rule); one ("", rule) for a kind without rules
    summary: str
    family: str | None = None
    checks: str | None = None
    module: str = field(default="")


#: Every declaration made so far, in the order made.
DECLARED: list[Declaration] = []
#: The attribute of a class that holds the declaration of its kind (set by :func:`register`).
#: What :func:`component` decorates and returns unchanged: a class or a function.
_Target = TypeVar("_Target", bound=type | Callable[..., Any])

STAMP = "__lookout_declaration__"
#: Declarations of functions whose return annotation named no class yet when they were
#: registered (a class defined further down the module): stamped when :func:`kind_of` asks.
_UNSTAMPED: list[Declaration] = []


def register(
    role: str,
    kind: str,
    target: Any,
    *,
    summary: str,
    parameters: tuple[Declared, ...] | None = None,
    build: str | Callable | None = None,
    rules: dict[str, Rule] | None = None,
    family: str | None = None,
    checks: str | None = None,
) -> Declaration:
    """Register the kind ``kind`` of ``role``, built by ``target`` (a class, with
    ``build`` one of its classmethods, or a function).

    Give either ``parameters`` (and ``build``) for a kind with one way to build it, or
    ``rules``: rule name -> :class:`Rule`, the first the default. ``summary`` is the
    one sentence ``lookout components`` shows; ``family`` (``"module:Family"``) makes
    the kind tunable by ``lookout tune``; ``checks`` (``"module:function"``) is what
    ``lookout design`` calls with the built composition.
    """
    if role not in ROLES:
        raise ValueError(f"role must be one of {', '.join(ROLES)}; got {role!r}")
    if not isinstance(kind, str) or not kind or kind != kind.strip():
        raise ValueError(f"kind must be a non-empty name; got {kind!r}")
    if (rules is None) == (parameters is None):
        raise ValueError(f"{role} {kind}: give either parameters or rules")
    if rules is not None:
        if build is not None:
            raise ValueError(f"{role} {kind}: build goes inside each Rule when rules are given")
        if not rules or not all(isinstance(r, Rule) for r in rules.values()):
            raise ValueError(f"{role} {kind}: rules must map each rule's name to a Rule")
        pairs = tuple(rules.items())
    else:
        assert parameters is not None  # either parameters or rules (checked above)
        pairs = (("", Rule(build, tuple(parameters))),)
    for _, rule in pairs:
        for each in rule.parameters:
            if not isinstance(each, (Value, Part, Context)):
                raise ValueError(f"{role} {kind}: parameters must be Value, Part or Context; got {each!r}")
    declaration = Declaration(role, kind, target, pairs, " ".join(summary.split()), family, checks, getattr(target, "__module__", ""))
    DECLARED.append(declaration)
    if not _stamp(declaration):
        _UNSTAMPED.append(declaration)
    return declaration


def built_class(target: type | Callable[..., Any]) -> type | None:
    """The class a declared ``target`` builds: the class itself, or the class a function's
    return annotation names (None: it names none). A NameError while the annotation's
    class is not defined yet."""
    if isinstance(target, type):
        return target
    returned = typing.get_type_hints(target).get("return")
    return returned if isinstance(returned, type) else None


def _registered(declaration: Declaration) -> bool:
    """Whether ``declaration`` is still registered (a failed plugin's are dropped)."""
    return any(each is declaration for each in DECLARED)


def _stamp(declaration: Declaration) -> bool:
    """Stamp ``declaration`` on the class it builds unless a registered declaration is
    stamped there already (a class's kind is that of its first declaration); False when
    the class cannot be known yet."""
    try:
        built = built_class(declaration.target)
    except Exception:
        return False
    if built is not None:
        stamped = built.__dict__.get(STAMP)
        if stamped is None or not _registered(stamped):
            setattr(built, STAMP, declaration)
    return True


def kind_of(component: object) -> str:
    """The kind of a built component: that of the declaration stamped on its class (the
    class's first registered declaration), else the class's name. A subclass of a
    declared class is of no kind until it is declared itself."""
    for waiting in list(_UNSTAMPED):
        if not _registered(waiting) or _stamp(waiting):
            _UNSTAMPED.remove(waiting)
    built = type(component)
    stamped = built.__dict__.get(STAMP)
    if stamped is not None and not _registered(stamped):  # its declaration was dropped: the next one, if any
        stamped = next((each for each in DECLARED if _builds(each, built)), None)
        setattr(built, STAMP, stamped)
    return stamped.kind if stamped is not None else built.__name__


def _builds(declaration: Declaration, built: type) -> bool:
    try:
        return built_class(declaration.target) is built
    except Exception:
        return False


def component(role: str, kind: str, **details: Any) -> Callable[[_Target], _Target]:
    """Class (or function) decorator: :func:`register` the decorated object as the kind
    ``kind`` of ``role``; it is returned unchanged."""

    def decorate(target: _Target) -> _Target:
        register(role, kind, target, **details)
        return target

    return decorate


def initial_values(*values: Value, same_as: str | None = None, extra: tuple[Value, ...] = ()) -> Callable:
    """Method decorator for a plant's ``state`` or an observer's ``guess``: the keys of
    the file's ``[... .initial]`` table it takes (``values``), or, with ``same_as``
    (``"model.state"``), those of the method of that attribute path of the same object
    (a Kalman filter's guess takes its model plant's state keys), plus ``extra`` keys of
    its own (a model that wraps a plant and adds states to it)."""

    def decorate(function):
        function.__lookout_initial__ = tuple(values)
        function.__lookout_initial_same_as__ = same_as
        function.__lookout_initial_extra__ = tuple(extra)
        return function

    return decorate
