"""The scenario file layer enforces its declarations' own rules: a context value is the
composition's, not the file's; a component's own sample period is the loop's; declared
shapes and broadcasting are checked at the key; a thruster layout fits its vessel; a
campaign or benchmark spec is named as such."""

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
    assert str(caught.value) == (
        f"{path}: a campaign spec, not a scenario file: run it with lookout campaign run {path} (its scenario is {scenario})"
    )


def test_a_benchmark_spec_read_as_a_scenario_names_the_command_that_runs_it(tmp_path):
    path = tmp_path / "spec.toml"
    path.write_text('title = "mine"\nscenario = "dp.toml"\nobservers = []\n')
    with pytest.raises(
        FileError,
        match=r"spec.toml: a benchmark spec, not a scenario file: run it with lookout benchmark observers --spec .*spec.toml \(its scenario is dp.toml\)$",
    ):
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


EKF = """preset = "fossen-strand-1999:paper"

[simulation]
duration = 20.0

[observer]
kind = "ekf"
"""


@pytest.mark.parametrize(
    "table, key, line, origin",
    [
        ("", "observer.filter_period", 8, "[simulation] (the loop's sample period)"),
        ('[actuator]\nkind = "thrust-limits"\nlimit = 1e6\n', "actuator.size", 12, "the plant (its input size)"),
    ],
)
def test_a_context_value_in_the_file_is_refused_at_its_line(tmp_path, table, key, line, origin):
    given = EKF + "filter_period = 0.5\n" if key == "observer.filter_period" else EKF + "\n" + table + "size = 3\n"
    path = _scenario(tmp_path, given)
    with pytest.raises(FileError) as caught:
        load(path)
    assert str(caught.value) == f"{path}: {key} (line {line}): set by lookout from {origin}, never by the file; remove it"
    # a context value declared the component's own (a Kalman filter's propagation step) is the file's to give
    spec = load(_scenario(tmp_path, EKF.replace("duration = 20.0", "duration = 20.0\nplant_step = 0.05") + "plant_step = 0.1\n"))
    assert spec.composition.scenario.observer.plant_step == 0.1 and spec.composition.scenario.plant_step == 0.05


@pytest.mark.slow
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
    parts = dict(
        plant=built.plant,
        sensor=built.sensor,
        observer=ekf,
        controller=built.controller,
        initial_state=built.initial_state,
        initial_estimate=ekf.guess(),
        plant_step=0.1,
        duration=20.0,
    )
    with pytest.raises(
        ValueError,
        match=r"^observer filter_period \(0.5 s\) must equal the loop's sample_period \(0.1 s\): the observer is built "
        r"for one sample period; build it for 0.1 s, or run the loop at 0.5 s$",
    ):
        Scenario(**parts, sample_period=0.1)
    assert Scenario(**parts, sample_period=0.5).sample_period == 0.5


def test_a_discrete_observers_sample_period_in_a_file_must_be_the_loops(tmp_path):
    """The adaptive manipulator observer's Delta is a file key: another loop period is refused at it."""
    from lookout.scenario._toml import write
    from lookout.scenario.registry import preset

    document = preset("calugi-2002-backstepping")
    document["simulation"].update(duration=0.1)
    document["observer"]["sample_period"] = 2 * document["simulation"]["sample_period"]
    path = write(tmp_path / "arm.toml", document)
    with pytest.raises(
        FileError, match=r"observer.sample_period \(line \d+\): observer sample_period \(0.02 s\) must equal the loop's sample_period \(0.01 s\)"
    ):
        load(path)


# ------------------------------------------------------------ declared shapes and broadcasting

PASSIVE = """preset = "fossen-strand-1999:paper"

[simulation]
duration = 20.0

[observer]
kind = "passive"

[observer.initial]
eta = {eta}
"""


@pytest.mark.parametrize(
    "eta, message",
    [
        ("[1.0, 2.0]", "must be one number or have 3 entries; got 2 entries"),
        ("[[1.0, 2.0, 0.1]]", "must be an array of shape (3,) or one number; got an array of shape (1, 3)"),
    ],
)
def test_an_initial_value_of_another_shape_is_refused_at_its_key(tmp_path, eta, message):
    path = _scenario(tmp_path, PASSIVE.format(eta=eta))
    with pytest.raises(FileError) as caught:
        load(path)
    assert str(caught.value) == f"{path}: observer.initial.eta (line 10): {message}"


def test_a_parameter_of_another_declared_shape_is_refused_at_its_key(tmp_path):
    path = _scenario(tmp_path, PASSIVE.format(eta="[0.0, 0.0, 0.0]").replace('kind = "passive"', 'kind = "passive"\nwave_frequency = [0.8, 0.9]'))
    with pytest.raises(FileError, match=r"observer.wave_frequency \(line 8\): must be one number or have 3 entries; got 2 entries$"):
        load(path)


LAYOUT = """preset = "fossen-strand-1999:paper"

[simulation]
duration = 20.0

[observer]
kind = "passive"
wave_frequency = 0.8

[actuator]
kind = "thrusters"

[actuator.layout]
kind = "custom"
names = ["bow", "port", "starboard"]
kinds = ["tunnel", "azimuth", "azimuth"]
x = {x}
y = [0.0, -6.0, 6.0]
direction = [1.5708, 0.0, 0.0]
max_thrust = [1.3e5, 3.0e5, 3.0e5]
min_thrust = -1.3e5
"""


def test_one_number_for_the_thrusters_positions_is_refused_where_the_declaration_does_not_broadcast(tmp_path):
    path = _scenario(tmp_path, LAYOUT.format(x="30.0"))
    with pytest.raises(FileError) as caught:
        load(path)
    assert str(caught.value) == (
        f"{path}: actuator.layout.x (line 17): must be an array, shape (n,): one number does not stand for every entry here; got 30.0"
    )
    from lookout.actuators.layout import ThrusterLayout

    with pytest.raises(ValueError, match=r"^x must have one entry per thruster \(3\), not one number for all; got one number$"):
        ThrusterLayout(names=["a", "b", "c"], kinds=["tunnel", "azimuth", "azimuth"], x=30.0, y=[0.0, -6.0, 6.0], direction=0.0, max_thrust=1e5)
    # a key that does broadcast takes one number for every thruster
    assert load(_scenario(tmp_path, LAYOUT.format(x="[30.0, -33.0, -33.0]"))).build().actuator.layout.min_thrust.tolist() == [-1.3e5, 0.0, 0.0]


def test_one_process_noise_intensity_is_every_inputs_as_its_siblings_take_one_number(tmp_path):
    """process_noise = 0 is one intensity (zero) for every noise input, not a refusal of 0."""
    spec = load(_scenario(tmp_path, EKF + "process_noise = 0.0\ninitial_std = { eta = 1.0, nu = 0.1, bias = 1e4, wave_state = 0.01 }\n"))
    assert spec.build().observer.process_noise.tolist() == [0.0] * spec.build().plant.noise_size
    with pytest.raises(FileError, match=r"observer.process_noise \(line 8\): must be non-negative; got -1"):
        load(_scenario(tmp_path, EKF + "process_noise = -1.0\n"))
    # a state's entries have units of their own (m, m/s, N): one number is refused at the key, as declared
    with pytest.raises(
        FileError,
        match=r"observer.state_noise \(line 8\): must be an array, one entry each: one number does not stand for every entry here; got 0.5$",
    ):
        load(_scenario(tmp_path, EKF + "state_noise = 0.5\n"))


# ------------------------------------------------------------ a layout of another vessel

CYBERSHIP = """[simulation]
duration = 20.0
plant_step = 0.01
sample_period = 0.1

[plant]
kind = "cybership-ii"

[sensor]
kind = "position-heading"

[observer]
kind = "passive"
wave_frequency = 0.8

[actuator]
kind = "thrusters"

[actuator.layout]
kind = "{layout}"
"""


def test_a_layout_far_larger_than_the_vessel_is_refused_naming_both(tmp_path):
    """The 76 m supply vessel's thrusters on the 1.26 m Cybership II: they lie 33.5 m from
    its origin, and a hull of its 25.8 kg is about 1.4 m long."""
    path = _scenario(tmp_path, CYBERSHIP.format(layout="supply-vessel"))
    with pytest.raises(FileError) as caught:
        load(path)
    assert str(caught.value) == (
        f"{path}: actuator.layout (line 19): layout supply-vessel does not fit plant cybership-ii: its thrusters reach 33.5 m "
        "from the origin, and a vessel of 25.8 kg is a hull of about 1.4 m: the layout is another vessel's; "
        "give [actuator.layout] this vessel's thrusters"
    )
    assert load(_scenario(tmp_path, CYBERSHIP.format(layout="cybership-ii"))).build().actuator.layout.size == 3


def test_the_lengths_of_the_shipped_vessels_from_their_mass():
    from lookout.actuators.layout import hull_length

    assert 70.0 < hull_length(5.3e6) < 90.0  # Northern Clipper, 76 m
    assert 1.1 < hull_length(25.8) < 1.5  # Cybership II, 1.255 m
