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


# ------------------------------------------------------------ context and sample periods


def _scenario(tmp_path, text: str) -> Path:
    path = tmp_path / "scenario.toml"
    path.write_text(text)
    return path


EKF = '''preset = "fossen-strand-1999:paper"

[simulation]
duration = 20.0

[observer]
kind = "ekf"
'''


@pytest.mark.parametrize("table, key, line, origin", [
    ("", "observer.filter_period", 8, "[simulation] (the loop's sample period)"),
    ('[actuator]\nkind = "thrust-limits"\nlimit = 1e6\n', "actuator.size", 12, "the plant (its input size)"),
])
def test_a_context_value_in_the_file_is_refused_at_its_line(tmp_path, table, key, line, origin):
    given = EKF + "filter_period = 0.5\n" if key == "observer.filter_period" else EKF + "\n" + table + "size = 3\n"
    path = _scenario(tmp_path, given)
    with pytest.raises(FileError) as caught:
        load(path)
    assert str(caught.value) == f"{path}: {key} (line {line}): set by lookout from {origin}, never by the file; remove it"
    # a context value declared the component's own (a Kalman filter's propagation step) is the file's to give
    spec = load(_scenario(tmp_path, EKF.replace("duration = 20.0", "duration = 20.0\nplant_step = 0.05") + "plant_step = 0.1\n"))
    assert spec.composition.scenario.observer.plant_step == 0.1 and spec.composition.scenario.plant_step == 0.05


def test_an_observer_built_for_another_sample_period_is_refused_with_both_periods():
    """The Python API: a Scenario whose observer was built for 0.5 s in a 0.1 s loop."""
    from lookout.observers.ekf import ExtendedKalmanFilter
    from lookout.scenario.composition import compose
    from lookout.scenario.registry import preset
    from lookout.sim import Scenario

    document = preset("fossen-strand-1999", "paper")
    document["simulation"]["duration"] = 20.0
    built = compose(document).scenario
    ekf = ExtendedKalmanFilter(built.plant, built.sensor, plant_step=0.1, filter_period=0.5)
    parts = dict(plant=built.plant, sensor=built.sensor, observer=ekf, controller=built.controller, initial_state=built.initial_state,
                 initial_estimate=ekf.guess(), plant_step=0.1, duration=20.0)
    with pytest.raises(ValueError, match=r"^observer filter_period \(0.5 s\) must equal the loop's sample_period \(0.1 s\): the observer is built "
                                         r"for one sample period; build it for 0.1 s, or run the loop at 0.5 s$"):
        Scenario(**parts, sample_period=0.1)
    assert Scenario(**parts, sample_period=0.5).sample_period == 0.5


def test_a_discrete_observers_sample_period_in_a_file_must_be_the_loops(tmp_path):
    """The adaptive manipulator observer's Delta is a file key: another loop period is refused at it."""
    from lookout.scenario.registry import preset
    from lookout.scenario._toml import write

    document = preset("calugi-2002-backstepping")
    document["simulation"].update(duration=0.1)
    document["observer"]["sample_period"] = 2 * document["simulation"]["sample_period"]
    path = write(tmp_path / "arm.toml", document)
    with pytest.raises(FileError, match=r"observer.sample_period \(line \d+\): observer sample_period \(0.02 s\) must equal the loop's sample_period \(0.01 s\)"):
        load(path)
