"""Kinds of one's own: a plugin file named in a scenario (examples/plugins/luenberger.py),
a module under the entry-point group lookout.components, and what is refused."""

from __future__ import annotations

import importlib.metadata
import json
import textwrap
from pathlib import Path

import jax
import numpy as np
import pytest

from lookout.cli import main
from lookout.models.vessel import DPVessel, northern_clipper
from lookout.scenario import registry
from lookout.scenario.composition import CompositionError, compose
from lookout.scenario.file import load
from lookout.sim import simulate

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


PLUGIN = EXAMPLES / "plugins" / "luenberger.py"


def _plugin_declaring(kind: str) -> str:
    """The example plugin's text with its observer declared under another kind name."""
    text = PLUGIN.read_text()
    renamed = text.replace('@component(\n    "observer",\n    "luenberger",', f'@component(\n    "observer",\n    "{kind}",', 1)
    assert renamed != text, "the example plugin's @component declaration is not where the tests expect it"
    return renamed


def test_the_example_plugin_runs_from_its_scenario_and_is_listed(tmp_path, capsys):
    spec = load(EXAMPLES / "luenberger-dp.toml", runs=1)
    assert registry.kind_of(spec.composition.scenario.observer) == "luenberger"
    assert "luenberger" in registry.names("observer")
    short = {**spec.composition.document, "simulation": {**spec.composition.document["simulation"], "duration": 60.0}}
    result = simulate(compose(short).scenario, jax.random.key(0))
    error = np.asarray(result.estimate["position"]) - np.asarray(result.truth["position"])
    assert np.all(np.isfinite(error)) and np.sqrt(np.mean(error[-100:] ** 2)) < 5.0  # m, on a 10 m sea
    capsys.readouterr()
    assert main(["components", "--plugin", str(PLUGIN), "observer", "--json"]) == 0
    assert "luenberger" in [entry["kind"] for entry in json.loads(capsys.readouterr().out)]
    assert main(["components", "--plugin", "nowhere.py", "observer"]) == 2
    assert (
        capsys.readouterr().err.strip()
        == "error: --plugin nowhere.py: plugin 'nowhere.py': no such file (looked for " + str(Path.cwd() / "nowhere.py") + ")"
    )


def test_the_example_plugins_pole_rule_places_each_dofs_error_poles_at_minus_the_bandwidth():
    """Its module docstring's claim: with the error linearized at psi = 0, per DOF the
    three poles are at -w (M, D diagonal: the Northern Clipper's without its sway-yaw
    coupling)."""
    registry.load_plugin(PLUGIN)
    clipper = northern_clipper()
    vessel = DPVessel(np.diag(np.diag(clipper.mass_matrix)), np.diag(np.diag(clipper.damping_matrix)))
    w = np.array([0.05, 0.045, 0.06])
    observer = registry.kind("observer", "luenberger").callable("poles")(vessel, bandwidth=w)
    zero = np.zeros(3)
    guess = observer.guess(eta=zero)

    A = np.asarray(
        jax.jacfwd(
            lambda x: jax.numpy.concatenate(
                jax.tree.leaves(observer.vector_field(0.0, type(guess)(x[:3], x[3:6], x[6:]), jax.numpy.zeros(3), jax.numpy.zeros(3)))
            )
        )(jax.numpy.zeros(9))
    )
    # leaves are ordered eta, nu, bias: the estimate's dynamics about rest; error = -estimate
    poles = np.sort_complex(np.linalg.eigvals(A))
    expected = np.sort_complex(np.repeat(-w, 3).astype(complex))
    assert np.allclose(poles, expected, atol=2e-4 * w.max()), (poles, expected)


def test_a_plugin_that_redeclares_a_kind_a_file_that_fails_and_a_missing_file_are_refused_in_one_line(tmp_path):
    twice = tmp_path / "twice.py"
    twice.write_text(
        textwrap.dedent("""
        from lookout.observers.passive import PassiveObserver
        from lookout.declare import register
        register("observer", "passive", PassiveObserver, summary="again", parameters=())
    """)
    )
    with pytest.raises(CompositionError) as raised:
        compose({"plugins": [str(twice)], "preset": "fossen-strand-1999"})
    assert raised.value.location == ("plugins", 0)
    assert "observer kind 'passive' is declared twice" in str(raised.value)
    assert registry.names("observer").count("passive") == 1  # the bad declaration does not stay
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('no licence')\n")
    with pytest.raises(CompositionError, match=r"plugins\[0\]: plugin '.*broken.py' does not import: RuntimeError: no licence"):
        compose({"plugins": [str(broken)], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match=r"plugins\[0\]: plugin 'nowhere.py': no such file"):
        compose({"plugins": ["nowhere.py"], "preset": "fossen-strand-1999"})
    notes = tmp_path / "notes.txt"
    notes.write_text("not python")
    with pytest.raises(
        CompositionError, match=r"plugins\[0\]: plugin '.*notes.txt': must be a Python file \(.py\) or a module's dotted name; got a .txt"
    ):
        compose({"plugins": [str(notes)], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match=r"plugins\[0\]: plugin 'no such module': must be a Python file \(.py\) or a module's dotted name"):
        compose({"plugins": ["no such module"], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match=r"plugins\[0\]: plugin 'no_such_package.observers': no such module"):
        compose({"plugins": ["no_such_package.observers"], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match="plugins: must be an array of Python files or module names"):
        compose({"plugins": "luenberger.py", "preset": "fossen-strand-1999"})


def test_a_scenario_files_plugins_are_relative_to_it_and_a_bad_one_is_named_at_its_line(tmp_path, capsys):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "own.py").write_text(_plugin_declaring("own-luenberger"))
    good = tmp_path / "good.toml"
    good.write_text('plugins = ["sub/own.py"]\npreset = "fossen-strand-1999"\n[observer]\nkind = "own-luenberger"\n')
    assert registry.kind_of(load(good).composition.scenario.observer) == "own-luenberger"
    bad = tmp_path / "bad.toml"
    bad.write_text('preset = "fossen-strand-1999"\nplugins = ["sub/missing.py"]\n')
    capsys.readouterr()
    assert main(["run", str(bad), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip() == f"error: {bad}: plugins[0] (line 2): plugin '{tmp_path / 'sub' / 'missing.py'}': no such file"
    assert not (tmp_path / "out").exists()


def test_an_installed_packages_entry_point_registers_its_kinds(tmp_path, monkeypatch, fresh_registry):
    module = tmp_path / "vendor_observers.py"
    module.write_text(_plugin_declaring("vendor-luenberger"))
    monkeypatch.syspath_prepend(str(tmp_path))
    point = importlib.metadata.EntryPoint("vendor", "vendor_observers", registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group=None: [point] if group == registry.ENTRY_POINT_GROUP else [])
    registry.load_entry_points()
    assert "vendor-luenberger" in registry.names("observer")
    assert registry.kind("observer", "vendor-luenberger").module == "vendor_observers"


@pytest.fixture
def fresh_registry(monkeypatch):
    """The registry as a new process finds it (lookout's modules are imported already, so
    loading them again costs nothing): installed packages' kinds not yet looked for."""
    monkeypatch.setattr(registry, "_LOADED", {})
    monkeypatch.delenv(registry.ENTRY_POINTS_SWITCH, raising=False)


def _installed(monkeypatch, tmp_path, name: str, text: str):
    """An installed package whose entry point names the module ``name`` of ``text``."""
    (tmp_path / f"{name}.py").write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    point = importlib.metadata.EntryPoint(name, name, registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group=None: [point] if group == registry.ENTRY_POINT_GROUP else [])


def test_a_broken_installed_package_fails_only_the_command_that_needs_its_kinds(tmp_path, monkeypatch, capsys, fresh_registry):
    _installed(monkeypatch, tmp_path, "broken_vendor", "raise ImportError('no module named vendor_sdk')\n")
    named = "the entry point broken_vendor = 'broken_vendor' (group lookout.components; LOOKOUT_ENTRY_POINTS=0 leaves installed packages' kinds out) does not import: ImportError: no module named vendor_sdk"
    assert compose({"preset": "fossen-strand-1999"}).kinds["observer"] == "passive"  # lookout's kinds only: not imported
    with pytest.raises(CompositionError) as raised:  # a kind lookout does not declare: it may be the package's
        compose({"preset": "fossen-strand-1999", "observer": {"kind": "vendor-observer"}})
    assert raised.value.location == ("observer", "kind")
    assert raised.value.reason == "no observer kind 'vendor-observer' among lookout's and the plugins' kinds, and " + named
    capsys.readouterr()
    assert main(["components", "observer"]) == 2  # a listing of every kind needs it
    assert capsys.readouterr().err.strip() == "error: " + named
    monkeypatch.setenv(registry.ENTRY_POINTS_SWITCH, "0")
    assert main(["components", "observer"]) == 0
    with pytest.raises(CompositionError, match=r"^observer\.kind: no observer kind 'vendor-observer' \(one of passive, "):
        compose({"preset": "fossen-strand-1999", "observer": {"kind": "vendor-observer"}})
    monkeypatch.setenv(registry.ENTRY_POINTS_SWITCH, "no")
    capsys.readouterr()
    assert main(["components", "observer"]) == 2
    assert capsys.readouterr().err.strip() == "error: LOOKOUT_ENTRY_POINTS must be 0 (leave installed packages' kinds out) or 1; got 'no'"


def test_an_installed_packages_kind_is_found_when_a_file_names_it(tmp_path, monkeypatch, fresh_registry):
    _installed(monkeypatch, tmp_path, "vendor_named", _plugin_declaring("named-luenberger"))
    assert "named-luenberger" not in registry.names("observer")  # not imported until needed
    composition = compose({"preset": "fossen-strand-1999", "observer": {"kind": "named-luenberger"}})
    assert registry.kind_of(composition.scenario.observer) == "named-luenberger"


def test_a_plugin_that_exits_or_raises_any_base_exception_is_named_in_one_line(tmp_path, capsys):
    (tmp_path / "exits.py").write_text("import sys\nsys.exit(3)\n")
    scenario = tmp_path / "exits.toml"
    scenario.write_text('preset = "fossen-strand-1999"\nplugins = ["exits.py"]\n')
    capsys.readouterr()
    assert main(["run", str(scenario), "--out", str(tmp_path / "out")]) == 2
    assert (
        capsys.readouterr().err.strip()
        == f"error: {scenario}: plugins[0] (line 2): plugin '{tmp_path / 'exits.py'}' exited (SystemExit 3) while being imported"
    )
    assert not (tmp_path / "out").exists()
    (tmp_path / "aborts.py").write_text("class Abort(BaseException):\n    pass\nraise Abort('licence check')\n")
    with pytest.raises(CompositionError, match=r"^plugins\[0\]: plugin '.*aborts.py' does not import: Abort: licence check$"):
        compose({"plugins": [str(tmp_path / "aborts.py")], "preset": "fossen-strand-1999"})
    (tmp_path / "interrupted.py").write_text("raise KeyboardInterrupt\n")
    with pytest.raises(KeyboardInterrupt):  # Ctrl-C still stops lookout
        registry.load_plugin(tmp_path / "interrupted.py")
    assert registry._plugin_module_name(tmp_path / "interrupted.py") not in __import__("sys").modules


def test_a_plugin_that_declares_no_kind_is_refused(tmp_path):
    (tmp_path / "nothing.py").write_text("import lookout.plugin\n\nclass Observer:\n    pass\n")
    with pytest.raises(
        CompositionError,
        match=r"^plugins\[0\]: plugin '.*nothing.py' declares no kind: decorate a class with @component\(\.\.\.\) \(lookout.plugin\)$",
    ):
        compose({"plugins": [str(tmp_path / "nothing.py")], "preset": "fossen-strand-1999"})
    assert registry._plugin_module_name(tmp_path / "nothing.py") not in __import__("sys").modules


def test_a_folder_and_an_empty_entry_are_refused_as_such(tmp_path, capsys):
    (tmp_path / "plugins").mkdir()
    with pytest.raises(CompositionError, match=r"^plugins\[0\]: plugin '.*plugins': is a folder, not a Python file$"):
        compose({"plugins": [str(tmp_path / "plugins")], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match=r"^plugins\[0\]: plugin '': an empty entry; give a Python file \(\.py\) or a module's dotted name$"):
        compose({"plugins": [""], "preset": "fossen-strand-1999"})
    for entry, reason in (
        ("plugins", f"plugin '{tmp_path / 'plugins'}': is a folder, not a Python file"),
        ("", "plugin '': an empty entry; give a Python file (.py) or a module's dotted name"),
    ):
        scenario = tmp_path / "s.toml"
        scenario.write_text(f'preset = "fossen-strand-1999"\nplugins = ["{entry}"]\n')
        capsys.readouterr()
        assert main(["run", str(scenario), "--out", str(tmp_path / "out")]) == 2
        assert capsys.readouterr().err.strip() == f"error: {scenario}: plugins[0] (line 2): {reason}"


def test_an_exception_in_a_plugins_method_is_the_plugins_not_a_misfit(tmp_path):
    text = _plugin_declaring("failing-luenberger")
    correction = '        """No discrete correction: the measurement enters the vector field."""\n        return estimate'
    assert correction in text
    text = text.replace(
        correction,
        '        """No discrete correction: the measurement enters the vector field."""\n        raise RuntimeError("licence server down")',
    )
    failing = tmp_path / "failing.py"
    failing.write_text(text)
    line = text.splitlines().index('        raise RuntimeError("licence server down")') + 1
    with pytest.raises(CompositionError) as raised:
        compose({"plugins": [str(failing)], "preset": "fossen-strand-1999", "observer": {"kind": "failing-luenberger"}})
    assert raised.value.location == ("observer",)
    assert (
        raised.value.reason
        == f"observer failing-luenberger (a plugin): LuenbergerObserver.update raised RuntimeError: licence server down ({failing}, line {line})"
    )


def test_the_example_plugin_imports_only_lookouts_public_names():
    """Plugins copy the example: it imports no private module of lookout, and of
    lookout.plugin only what that module exports, each the object lookout itself uses."""
    import ast

    import lookout.plugin as plugin
    from lookout import _math, _validation, declare

    imported = []
    for node in ast.walk(ast.parse(PLUGIN.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "lookout":
            imported += [(node.module, alias.name) for alias in node.names]
        elif isinstance(node, ast.Import):
            imported += [(alias.name, None) for alias in node.names if alias.name.split(".")[0] == "lookout"]
    assert imported and ("lookout.plugin", "check") in imported
    for module, name in imported:
        assert not any(part.startswith("_") for part in module.split(".")), module
        assert name is None or not name.startswith("_"), (module, name)
        if module == "lookout.plugin":
            assert name in plugin.__all__, name
    assert plugin.ssa is _math.ssa and plugin.rotation is _math.rotation and plugin.ParameterError is _validation.ParameterError
    assert plugin.check.vector is _validation.vector and plugin.check.ParameterError is _validation.ParameterError
    assert plugin.component is declare.component and plugin.Value is declare.Value and plugin.initial_values is declare.initial_values
    assert all(getattr(plugin, name).__doc__ for name in plugin.__all__ if callable(getattr(plugin, name)))
