"""Kinds declared in code (lookout.declare): what the registry reads, checked
against the builders' signatures and their docstrings, and what a declaration refuses."""

from __future__ import annotations

import inspect
import os
import re
from pathlib import Path

import pytest

from lookout import declare
from lookout.declare import POSITIVE, Part, Range, Rule, Value
from lookout.scenario import registry


def _numpydoc(doc: str | None) -> dict[str, tuple[str, str]]:
    """name -> (type, description) of a numpydoc Parameters section (for this test only:
    lookout itself never reads a docstring to build a component)."""
    if not doc:
        return {}
    lines, found, names, kind, text, inside = inspect.cleandoc(doc).splitlines(), {}, [], "", [], False

    def flush():
        for name in names:
            found[name] = (kind, " ".join(line.strip() for line in text).strip())

    for index, line in enumerate(lines):
        underlined = index + 1 < len(lines) and lines[index + 1].strip() and set(lines[index + 1].strip()) == {"-"}
        if line.strip() == "Parameters" and underlined:
            inside = True
            continue
        if not inside or (line.strip() and set(line.strip()) == {"-"}):
            continue
        if line and not line.startswith(" "):
            flush()
            if underlined:
                names, inside = [], False
                continue
            head, _, kind = line.partition(":")
            names, kind, text = [n.strip() for n in head.split(",") if n.strip()], kind.strip(), []
        elif line.strip():
            text.append(line)
    if inside:
        flush()
    return found


def _first_sentence(text: str) -> str:
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text).replace("``", "")
    match = re.match(r"(.+?\.)(\s+[A-Z]|$)", text)
    return match.group(1) if match else text


def _documented(builder, owner) -> dict[str, tuple[str, str]]:
    own = _numpydoc(inspect.getdoc(owner)) if isinstance(owner, type) else {}
    return {**own, **_numpydoc(inspect.getdoc(builder))}


def _cases():
    for each in registry.kinds():
        for design in each.designs or (None,):
            yield pytest.param(each, design, id=f"{each.role}-{each.name}-{design or ''}")


@pytest.mark.parametrize("each,design", list(_cases()))
def test_each_declared_parameter_is_documented_with_the_declared_sentence(each, design):
    """The docstring a user reads (help(), the API docs) and the declaration that builds
    the file agree: every declared parameter is in the builder's numpydoc Parameters with
    the declaration's sentence first, and every documented one is declared."""
    builder = each.callable(design)
    documented = _documented(builder, each.component_class)
    declared = {p.name: p for p in each.parameters(design)}
    for name, parameter in declared.items():
        assert name in documented, f"{each.role} {each.name} {design}: {name} is declared but not documented"
        assert _first_sentence(documented[name][1]) == parameter.description, (name, documented[name][1])
    signature = inspect.signature(builder).parameters
    undeclared = [name for name in documented if name in signature and name not in declared]
    assert undeclared == [], f"{each.role} {each.name} {design}: documented but not declared: {undeclared}"


def test_initial_values_are_documented_as_declared():
    for each in registry.kinds("plant") + registry.kinds("observer"):
        method = getattr(each.component_class, {"plant": "state", "observer": "guess"}[each.role])
        if registry.initial_same_as(method):
            continue
        documented = _numpydoc(inspect.getdoc(method))
        for parameter in registry.initial_parameters(method):
            assert _first_sentence(documented[parameter.name][1]) == parameter.description, (each.name, parameter.name)


def test_every_kind_has_a_summary_and_every_value_a_type():
    for each in registry.kinds():
        assert each.description and "\n" not in each.description, each.name
        for design in each.designs or (None,):
            for p in each.parameters(design):
                assert p.description and p.type, (each.name, p.name)
                assert p.sort != "value" or p.value_type in ("float", "int", "bool", "str", "array", "strings", "parts"), (each.name, p.name)


def _builder(position_gain, bias_gain=1.0, steps_per_sample: int = 1):
    """A builder for the refusals below."""


def _annotated_builder(ship: Cybership, spare: NotImportedAtRunTime = None, gain: NotImportedAtRunTime = 1.0):  # noqa: F821
    """A builder whose part is annotated with a class this module imports, and two
    parameters with a name imported nowhere (as under ``if TYPE_CHECKING``)."""


def test_a_parts_class_comes_from_its_own_annotation_and_one_that_does_not_resolve_is_refused():
    from lookout.models.cybership import Cybership

    globals()["Cybership"] = Cybership  # as the builder's module would import it
    try:
        # a value's annotation is never read: the unresolvable one beside the part is harmless
        (ship, gain) = registry._parameters(_annotated_builder, (Part("ship", "The model."), Value("gain", "float", "K.")), "observer test")
        assert ship.context is Cybership and gain.context is None
        with pytest.raises(ValueError, match=r"observer test: the annotation of spare \(NotImportedAtRunTime\) does not resolve"):
            registry._parameters(_annotated_builder, (Part("ship", "The model."), Part("spare", "Another.")), "observer test")
    finally:
        del globals()["Cybership"]


def test_a_declaration_the_builder_does_not_take_or_that_misses_a_required_argument_is_refused():
    with pytest.raises(ValueError, match="declares wave_gain, which its builder does not take"):
        registry._parameters(_builder, (Value("position_gain", "array", "L1."), Value("wave_gain", "array", "K.")), "observer test")
    with pytest.raises(ValueError, match="its builder requires position_gain, which it does not declare"):
        registry._parameters(_builder, (Value("bias_gain", "array", "L3."),), "observer test")
    internal = registry._parameters(_builder, (Value("position_gain", "array", "L1.", range=POSITIVE),), "observer test")
    assert [p.name for p in internal] == ["position_gain"]  # an undeclared argument with a default is internal
    assert internal[0].range == (0.0, float("inf"), False, False) and internal[0].type == "array_like, positive"


def test_register_refuses_an_unknown_role_an_empty_kind_and_rules_with_parameters():
    with pytest.raises(ValueError, match="role must be one of"):
        declare.register("estimator", "x", _builder, summary="s", parameters=())
    with pytest.raises(ValueError, match="kind must be a non-empty name"):
        declare.register("observer", " ", _builder, summary="s", parameters=())
    with pytest.raises(ValueError, match="give either parameters or rules"):
        declare.register("observer", "x", _builder, summary="s", parameters=(), rules={"a": Rule(None)})
    with pytest.raises(ValueError, match="must be Value, Part or Context"):
        declare.register("observer", "x", _builder, summary="s", parameters=("position_gain",))


class Stamped:
    """A class declared as a kind by the test below."""


def test_a_kind_is_stamped_on_its_class_when_it_is_registered():
    """kind_of reads the declaration on the class: the first one still registered, a
    function's from its return annotation (resolved when asked), none for a subclass."""
    count = len(declare.DECLARED)
    try:
        first = declare.register("observer", "stamped", Stamped, summary="s", parameters=())
        assert Stamped.__dict__[declare.STAMP] is first
        declare.register("observer", "stamped-again", Stamped, summary="s", parameters=())
        assert declare.kind_of(Stamped()) == registry.kind_of(Stamped()) == "stamped"
        assert declare.kind_of(type("Derived", (Stamped,), {})()) == "Derived"
        declare.DECLARED.remove(first)  # dropped, as a plugin that fails to import is
        assert declare.kind_of(Stamped()) == "stamped-again"
        module = {"__name__": "later"}
        exec("def build() -> 'Later':\n    return Later()", module)  # Later is defined after build is declared
        later = declare.register("observer", "later", module["build"], summary="s", parameters=())
        assert later in declare._UNSTAMPED
        exec("class Later:\n    pass", module)
        assert declare.kind_of(module["Later"]()) == "later" and declare.kind_of(object()) == "object"
    finally:
        del declare.DECLARED[count:]


def test_range_words_are_what_components_shows():
    assert POSITIVE.words() == "positive" and declare.NON_NEGATIVE.words() == "non-negative"
    assert Range(0.0, 1.0, True, False).words() == "in [0, 1)"
    assert Part("vessel").sort == "part" and Value("x", "float").sort == "value"


DOCS = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
BEGIN, END = "<!-- kinds: begin -->", "<!-- kinds: end -->"


def kinds_table() -> str:
    """The registered kinds of lookout's own modules, as docs/architecture.md shows them."""
    lines = ["| role | kind | rules | tuning family | declared in |", "|---|---|---|---|---|"]
    for each in registry.kinds():
        if not each.module.startswith("lookout."):
            continue
        family = each.family.rpartition(":")[2] if each.family else ""
        lines.append(f"| {each.role} | `{each.name}` | {', '.join(f'`{r}`' for r in each.designs)} | {family} | `{each.module}` |")
    return "\n".join(lines)


def test_the_docs_hold_the_kinds_as_declared():
    table, text = kinds_table(), DOCS.read_text()
    if os.environ.get("LOOKOUT_WRITE_KINDS"):
        before, _, rest = text.partition(BEGIN)
        _, _, after = rest.partition(END)
        DOCS.write_text(f"{before}{BEGIN}\n{table}\n{END}{after}")
        text = DOCS.read_text()
    found = re.search(re.escape(BEGIN) + r"\n(.*?)\n" + re.escape(END), text, re.DOTALL)
    assert found and found.group(1) == table, "docs/architecture.md's kinds table differs from the registry's: rerun with LOOKOUT_WRITE_KINDS=1"
