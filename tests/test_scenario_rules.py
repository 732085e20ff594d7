"""The scenario file layer enforces its declarations' own rules: a context value is the
composition's, not the file's; a component's own sample period is the loop's; declared
shapes and broadcasting are checked at the key; a thruster layout fits its vessel and a
setpoint falls inside the run; a campaign or benchmark spec is named as such."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lookout.cli import main
from lookout.scenario._toml import FileError
from lookout.scenario.file import load

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


# ------------------------------------------------------------ a spec given as a scenario


@pytest.mark.parametrize("name, scenario", [("dp-study", "dp-observer.toml"), ("kim-model-error", "kim-closed-loop.toml")])
def test_a_campaign_spec_read_as_a_scenario_names_the_command_that_runs_it(name, scenario):
    path = EXAMPLES / f"{name}.toml"
    with pytest.raises(FileError) as caught:
        load(path)
    assert str(caught.value) == (f"{path}: a campaign spec, not a scenario file: run it with lookout campaign run {path} "
                                 f"(its scenario is {scenario})")


def test_a_benchmark_spec_read_as_a_scenario_names_the_command_that_runs_it(tmp_path):
    path = tmp_path / "spec.toml"
    path.write_text('title = "mine"\nscenario = "dp.toml"\nobservers = []\n')
    with pytest.raises(FileError, match=r"spec.toml: a benchmark spec, not a scenario file: run it with lookout benchmark observers --spec .*spec.toml \(its scenario is dp.toml\)$"):
        load(path)


def test_design_json_of_a_refused_file_prints_one_object_with_the_error_and_exits_2(capsys):
    path = str(EXAMPLES / "dp-study.toml")
    assert main(["design", path, "--json"]) == 2
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    assert printed["error"].startswith(f"{path}: a campaign spec, not a scenario file: run it with lookout campaign run {path}")
    assert printed["inputs"]["scenario"] == path
    assert captured.err.startswith("error: ")
