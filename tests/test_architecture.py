"""The package's import graph: no cycle among lookout's modules (counting imports inside
functions, and the package ``__init__`` a submodule import runs), and no observer imports
the design and analysis code (:mod:`lookout.analysis`) that checks it."""

from __future__ import annotations

import ast
from pathlib import Path

import lookout

ROOT = Path(lookout.__file__).parent


def _modules() -> dict[str, Path]:
    found = {}
    for path in ROOT.rglob("*.py"):
        name = ".".join(path.relative_to(ROOT.parent).with_suffix("").parts)
        found[name.removesuffix(".__init__")] = path
    return found


def _edges(modules: dict[str, Path]) -> dict[str, set[str]]:
    def owner(name: str) -> str:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name

    edges: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets |= {owner(alias.name) for alias in node.names if alias.name.startswith("lookout.")}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
                if base.startswith("lookout"):
                    targets |= {owner(f"{base}.{alias.name}") if f"{base}.{alias.name}" in modules else owner(base) for alias in node.names}
        for target in list(targets):  # importing a.b.c runs a.b's __init__ (the root's is every module's)
            parts = target.split(".")
            targets |= {".".join(parts[:k]) for k in range(2, len(parts)) if not name.startswith(".".join(parts[:k]) + ".")}
        edges[name] = {t for t in targets if t and t != name and t in modules and t != "lookout"}
    return edges


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in edges:
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle_among_lookouts_modules():
    assert _cycles(_edges(_modules())) == []


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_observer_imports_the_design_and_analysis_code():
    edges = _edges(_modules())
    importing = {
        name: sorted(t for t in targets if t.startswith("lookout.analysis"))
        for name, targets in edges.items()
        if name.startswith("lookout.observers")
    }
    assert {name: targets for name, targets in importing.items() if targets} == {}
