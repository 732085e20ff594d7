"""The package's import graph: no cycle among lookout's modules (counting imports inside
functions, and the package ``__init__`` a submodule import runs), no observer imports
the design and analysis code (:mod:`lookout.analysis`) that checks it, and imports only
go down the stated layers (:data:`LAYERS`), the registry's imports of lookout's own
kinds included."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
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


#: The layers of the package, bottom first: a module imports only modules of its own
#: layer and of the layers below it (imports inside functions count). An entry names a
#: folder (every module under it) or a module, relative to ``lookout``; a module takes
#: the layer of the longest entry that names it or a folder above it; ``lookout`` is the
#: package's own ``__init__``.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    # the contract, the declaration machinery, the null components and shared helpers
    ("floor", ("_math", "_random", "_json", "_validation", "_resources", "components", "declare", "null_components", "vessel_signals", "results")),
    # the sample loop, which knows only the contract; the per-run metrics its scan
    # accumulates; the commands' plumbing, which sizes runs
    ("engine", ("sim", "scenario.metrics", "_commandline")),
    # the parts that know no plant model
    ("parts", ("environment", "reference", "actuators", "io")),
    ("models", ("models",)),
    ("sensors", ("sensors", "sensing")),
    ("observers", ("observers",)),
    # the design and analysis code that checks observers (and the figures, which use it)
    ("analysis", ("analysis", "plotting")),
    # controllers, whose design rules may call the analysis code
    ("controllers", ("controllers",)),
    ("scenario", ("scenario", "control_systems")),
    ("applications", ("studies", "tuning", "live", "design")),
    # the reproductions, and the tuning family that takes a reproduction's design speed
    ("papers", ("papers", "tuning.families.adaptive_dp")),
    # what a user runs or imports: the commands, the plugin module, the package's names
    ("commands", ("cli", "cli_components", "cli_design", "plugin", "lookout")),
)


def _layer_finder(layers) -> callable:
    """``layer(module)``: the index and name of the layer of a module (None: in none)."""
    table = {entry: (index, name) for index, (name, entries) in enumerate(layers) for entry in entries}

    def layer(module: str):
        relative = "lookout" if module == "lookout" else module.removeprefix("lookout.")
        while relative:
            if relative in table:
                return table[relative]
            relative = relative.rpartition(".")[0] if relative != "lookout" else ""
        return None

    return layer


def _upward_imports(edges: dict[str, set[str]], layers) -> list[str]:
    """Each import from a module to a module of a higher layer, in words."""
    layer = _layer_finder(layers)
    found = []
    for importer in sorted(edges):
        for imported in sorted(edges[importer]):
            low, high = layer(importer), layer(imported)
            if low is not None and high is not None and high[0] > low[0]:
                found.append(f"{importer} (layer {low[1]}) imports {imported} (layer {high[1]}, higher)")
    return found


def test_no_module_imports_a_module_of_a_higher_layer():
    assert _upward_imports(_edges(_modules()), LAYERS) == []


def test_every_module_is_in_a_layer_and_every_entry_names_a_module():
    modules = _modules()
    layer = _layer_finder(LAYERS)
    assert [name for name in sorted(modules) if layer(name) is None] == []
    entries = [entry for _, names in LAYERS for entry in names]
    assert len(entries) == len(set(entries))
    assert [entry for entry in entries if entry != "lookout" and f"lookout.{entry}" not in modules] == []


def test_loading_the_built_in_kinds_imports_no_module_above_the_registry():
    """The registry imports the modules of lookout's own kinds by name: each is in the
    registry's layer or below it, and so is every module their imports load."""
    from lookout.scenario import registry

    layer = _layer_finder(LAYERS)
    own = layer("lookout.scenario.registry")
    assert [name for name in registry.BUILTIN_MODULES if layer(name)[0] > own[0]] == []
    script = "import sys; from lookout.scenario import registry; registry.kinds(); print(' '.join(sorted(m for m in sys.modules if m.startswith('lookout'))))"
    loaded = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, env=os.environ | {"LOOKOUT_ENTRY_POINTS": "0"}
    ).stdout.split()
    assert "lookout.scenario.registry" in loaded
    assert [name for name in loaded if name != "lookout" and layer(name)[0] > own[0]] == []  # every import runs lookout's __init__


def test_the_layer_checker_finds_an_import_upward():
    layers = (("low", ("a",)), ("high", ("b", "b.c.d")), ("top", ("b.c",)))
    edges = {
        "lookout.a.x": {"lookout.a.y", "lookout.b.c.d"},
        "lookout.a.y": set(),
        "lookout.b.c.d": {"lookout.a.x"},
        "lookout.b.c": {"lookout.b.c.d"},
    }
    assert _upward_imports(edges, layers) == ["lookout.a.x (layer low) imports lookout.b.c.d (layer high, higher)"]
    assert _layer_finder(layers)("lookout.b.c.e") == (2, "top") and _layer_finder(layers)("lookout.e") is None
