"""Every public function of lookout is annotated: its parameters (but ``self`` and ``cls``)
and its return (but ``__init__``'s). mypy, at its default level (``make types``), checks
the body of an annotated function only, so an unannotated public function is one the
type check never reads.

Public: a function of a module whose path has no part starting with ``_`` (a package's
``__init__`` aside), whose name does not start with ``_``; a method of such a module's
class of a public name, whose name does not start with ``_`` (``__init__`` included).
"""

from __future__ import annotations

import ast
from pathlib import Path

import lookout

ROOT = Path(lookout.__file__).parent


def _public_functions() -> list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    found = []
    for path in sorted(ROOT.rglob("*.py")):
        parts = path.relative_to(ROOT).parts
        if any(part.startswith("_") and part != "__init__.py" for part in parts):
            continue
        where = "/".join(parts)
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_"):
                found.append((where, node))
            elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                for method in node.body:
                    if isinstance(method, (ast.FunctionDef, ast.AsyncFunctionDef)) and (not method.name.startswith("_") or method.name == "__init__"):
                        found.append((f"{where}:{node.name}", method))
    return found


def _unannotated(function: ast.FunctionDef | ast.AsyncFunctionDef) -> list[str]:
    arguments = function.args
    missing = [a.arg for a in arguments.posonlyargs + arguments.args + arguments.kwonlyargs if a.annotation is None and a.arg not in ("self", "cls")]
    missing += [f"*{a.arg}" for a in (arguments.vararg,) if a is not None and a.annotation is None]
    missing += [f"**{a.arg}" for a in (arguments.kwarg,) if a is not None and a.annotation is None]
    if function.returns is None and function.name != "__init__":
        missing.append("return")
    return missing


def test_every_public_function_is_annotated():
    functions = _public_functions()
    assert len(functions) > 1000  # the walk found the package
    missing = [f"{where}:{function.name} ({', '.join(names)})" for where, function in functions if (names := _unannotated(function))]
    assert missing == [], f"{len(missing)} public functions lack annotations:\n" + "\n".join(missing)


def test_the_check_finds_a_missing_annotation():
    tree = ast.parse("def f(x, y: int, *args, **kw) -> int: ...\ndef g(self, z: int): ...\ndef __init__(self, a: int): ...")
    f, g, init = tree.body
    assert _unannotated(f) == ["x", "*args", "**kw"]
    assert _unannotated(g) == ["return"]
    assert _unannotated(init) == []
