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

from lookout.scenario import registry
from lookout.cli import main
from lookout.scenario.composition import CompositionError, compose
from lookout.models.vessel import DPVessel, northern_clipper
from lookout.sim import simulate
from lookout.scenario.file import load

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


PLUGIN = EXAMPLES / "plugins" / "luenberger.py"


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
    assert capsys.readouterr().err.strip() == "error: --plugin nowhere.py: plugin 'nowhere.py': no such file (looked for " + str(Path.cwd() / "nowhere.py") + ")"


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

    A = np.asarray(jax.jacfwd(lambda x: jax.numpy.concatenate(jax.tree.leaves(observer.vector_field(
        0.0, type(guess)(x[:3], x[3:6], x[6:]), jax.numpy.zeros(3), jax.numpy.zeros(3)))))(jax.numpy.zeros(9)))
    # leaves are ordered eta, nu, bias: the estimate's dynamics about rest; error = -estimate
    poles = np.sort_complex(np.linalg.eigvals(A))
    expected = np.sort_complex(np.repeat(-w, 3).astype(complex))
    assert np.allclose(poles, expected, atol=2e-4 * w.max()), (poles, expected)


def test_a_plugin_that_redeclares_a_kind_a_file_that_fails_and_a_missing_file_are_refused_in_one_line(tmp_path):
    twice = tmp_path / "twice.py"
    twice.write_text(textwrap.dedent('''
        from lookout.observers.passive import PassiveObserver
        from lookout.scenario.declare import register
        register("observer", "passive", PassiveObserver, summary="again", parameters=())
    '''))
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
    with pytest.raises(CompositionError, match=r"plugins\[0\]: plugin '.*notes.txt': must be a Python file \(.py\) or a module's dotted name; got a .txt"):
        compose({"plugins": [str(notes)], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match=r"plugins\[0\]: plugin 'no such module': must be a Python file \(.py\) or a module's dotted name"):
        compose({"plugins": ["no such module"], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match=r"plugins\[0\]: plugin 'no_such_package.observers': no such module"):
        compose({"plugins": ["no_such_package.observers"], "preset": "fossen-strand-1999"})
    with pytest.raises(CompositionError, match="plugins: must be an array of Python files or module names"):
        compose({"plugins": "luenberger.py", "preset": "fossen-strand-1999"})


def test_a_scenario_files_plugins_are_relative_to_it_and_a_bad_one_is_named_at_its_line(tmp_path, capsys):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "own.py").write_text(PLUGIN.read_text().replace('"observer", "luenberger"', '"observer", "own-luenberger"'))
    good = tmp_path / "good.toml"
    good.write_text('plugins = ["sub/own.py"]\npreset = "fossen-strand-1999"\n[observer]\nkind = "own-luenberger"\n')
    assert registry.kind_of(load(good).composition.scenario.observer) == "own-luenberger"
    bad = tmp_path / "bad.toml"
    bad.write_text('preset = "fossen-strand-1999"\nplugins = ["sub/missing.py"]\n')
    capsys.readouterr()
    assert main(["run", str(bad), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip() == f"error: {bad}: plugins[0] (line 2): plugin '{tmp_path / 'sub' / 'missing.py'}': no such file"
    assert not (tmp_path / "out").exists()


def test_an_installed_packages_entry_point_registers_its_kinds(tmp_path, monkeypatch):
    module = tmp_path / "vendor_observers.py"
    module.write_text(PLUGIN.read_text().replace('"observer", "luenberger"', '"observer", "vendor-luenberger"'))
    monkeypatch.syspath_prepend(str(tmp_path))
    point = importlib.metadata.EntryPoint("vendor", "vendor_observers", registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group=None: [point] if group == registry.ENTRY_POINT_GROUP else [])
    registry.load_entry_points()
    assert "vendor-luenberger" in registry.names("observer")
    assert registry.kind("observer", "vendor-luenberger").module == "vendor_observers"
