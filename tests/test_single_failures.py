"""lookout failures (lookout.studies.single_failures): every single failure of a suite's
instruments as one campaign, against the same failure written into the scenario by
hand; the table, a resumed store, and bad input refused in one line."""

from __future__ import annotations

import copy
import csv
import math
from pathlib import Path

import numpy as np
import pytest

from lookout.cli import main
from lookout.scenario import metrics as metric_module
from lookout.scenario.composition import compose
from lookout.sim import keys_of_seeds, simulate_batch
from lookout.studies.single_failures import CANDIDATES, INTACT, failure_cases

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "dp-suite.toml"
DURATION, START = 60.0, 30.0


def _text() -> str:
    """examples/dp-suite.toml for 60 s, without its failures and its second gyro,
    hydroacoustic reference and IMU (fewer cases)."""
    lines, skip = [], False
    for line in EXAMPLE.read_text().replace("duration = 1200.0", f"duration = {DURATION}").splitlines():
        if line.startswith("[") and ("failures" in line or line.strip() in ("[sensors.gyro2]", "[sensors.hpr]", "[sensors.imu]")):
            skip = True
            continue
        if skip and line.startswith("["):
            skip = False
        if not skip:
            lines.append(line)
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def analysis(tmp_path_factory):
    """The command's store, table and output on the shortened example, 2 seeds."""
    folder = tmp_path_factory.mktemp("failures")
    scenario = folder / "suite.toml"
    scenario.write_text(_text())
    store, table = folder / "failures.zarr", folder / "table.csv"
    argv = ["failures", str(scenario), "--out", str(store), "--start", str(START), "--seeds", "2", "--workers", "0", "--table", str(table)]
    assert main(argv) == 0
    with table.open() as handle:
        rows = list(csv.DictReader(handle))
    return scenario, store, rows, argv


def test_every_instrument_fails_in_each_of_its_modes_switched_on_by_one_case():
    document = read_document()
    failed, cases, labels = failure_cases(document, START)
    suite = compose(document).scenario.sensor
    expected = [INTACT] + [f"{name} {mode}" for name, each in zip(suite.names, suite.instruments) for mode, _ in CANDIDATES[each.provides]]
    assert labels == expected and cases[0] == {}
    for case, label in zip(cases[1:], labels[1:]):
        ((path, value),) = case.items()
        name = label.split()[0]
        assert path.startswith(f"sensors.{name}.failures[") and value == START
    # written in, never active: the scenario with them all runs as the one without
    for name in suite.names:
        assert all(math.isinf(each["start"]) for each in failed["sensors"][name]["failures"])


def read_document() -> dict:
    import tomllib

    return tomllib.loads(_text())


@pytest.mark.slow
def test_the_table_has_each_case_worst_first_and_its_numbers_are_the_failure_written_by_hand(analysis):
    """The jump of dgnss1 (10 m north at 30 s): the campaign's largest tracking error
    equals that of the scenario with that one failure written into its table by hand,
    simulated over the same seeds; the intact case comes first and the rest are sorted."""
    _, _, rows, _ = analysis
    assert rows[0]["failure"] == INTACT and len(rows) == 1 + 5 + 5 + 5
    worst = [float(row["max_tracking:position max"]) for row in rows[1:]]
    assert worst == sorted(worst, reverse=True)
    jump = next(row for row in rows if row["failure"] == "dgnss1 jump")
    assert float(jump["max_tracking:position max"]) > float(rows[0]["max_tracking:position max"]) + 1.0
    document = read_document()
    document["sensors"]["dgnss1"]["failures"] = [{"mode": "jump", "start": START, "size": [10.0, 0.0]}]
    scenario = compose(document).scenario
    metrics = metric_module.resolve(["max_tracking:position"], scenario)
    seed = compose(document).simulation.seed
    expected = metric_module.reduce(simulate_batch(scenario, keys_of_seeds([seed, seed + 1])), metrics, after=START)
    np.testing.assert_allclose(float(jump["max_tracking:position max"]), np.max(expected["max_tracking__position"]), rtol=1e-9)
    np.testing.assert_allclose(float(jump["max_tracking:position mean"]), np.mean(expected["max_tracking__position"]), rtol=1e-9)


@pytest.mark.slow
def test_a_second_run_resumes_the_store_and_computes_nothing(analysis, capsys):
    _, _, rows, argv = analysis
    capsys.readouterr()
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "all 16 chunks are done; nothing to compute" in out and "worst single failure: dgnss" in out
    with Path(argv[argv.index("--table") + 1]).open() as handle:
        assert list(csv.DictReader(handle)) == rows


@pytest.mark.parametrize(
    ("change", "option", "message"),
    [
        (None, ["--seeds", "0"], "--seeds must be a whole number >= 1; got 0"),
        (None, ["--start", "60"], "--start (60 s) must be before the run's end (simulation.duration 60 s)"),
        (None, ["--start", "nan"], "--start must be a finite number of seconds >= 0"),
        ("single", [], "lookout failures needs a scenario with a sensor suite"),
    ],
)
def test_bad_input_is_one_line_and_nothing_is_written(change, option, message, tmp_path, capsys):
    scenario = tmp_path / "suite.toml"
    text = _text()
    if change == "single":
        text = 'preset = "fossen-strand-1999"\n'
    scenario.write_text(text)
    store = tmp_path / "store.zarr"
    assert main(["failures", str(scenario), "--out", str(store), "--workers", "0", *option]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert not store.exists()


def test_a_failure_that_never_starts_is_inf_and_a_finite_one_after_the_end_is_refused():
    document = read_document()
    never = copy.deepcopy(document)
    never["sensors"]["dgnss1"]["failures"] = [{"mode": "dropout", "start": math.inf}]
    assert math.isinf(float(compose(never).scenario.sensor.failures[0][0].start))
    late = copy.deepcopy(document)
    late["sensors"]["dgnss1"]["failures"] = [{"mode": "dropout", "start": DURATION}]
    with pytest.raises(ValueError, match=r"start \(60 s\) must be before the run's end"):
        compose(late)


def _block(text: str, header: str) -> str:
    """The lines of ``text`` from ``header`` to the next table that is not its own."""
    lines, inside = [], False
    for line in text.splitlines():
        if line.startswith("["):
            inside = line.strip() == header or (inside and line.strip().startswith(header[:-1] + "."))
        if inside:
            lines.append(line)
    return "\n".join(lines) + "\n"


@pytest.mark.slow
def test_with_thrusters_each_one_stops_and_sticks_in_a_case_of_its_own(tmp_path):
    """The suite's vessel on the supply vessel's thrusters: a case per thruster and mode
    after the instruments', and the port azimuth's stop gives what the scenario with
    that one failure written into its [[actuator.failures]] gives, run by hand."""
    import tomllib

    thrusters = (Path(__file__).resolve().parents[1] / "examples" / "thrusters-dp.toml").read_text()
    text = _text().replace(_block(_text(), "[actuator]"), _block(thrusters, "[actuator]"))
    assert 'kind = "thrusters"' in text
    scenario = tmp_path / "suite-thrusters.toml"
    scenario.write_text(text)
    table = tmp_path / "table.csv"
    argv = ["failures", str(scenario), "--out", str(tmp_path / "store.zarr"), "--start", str(START), "--seeds", "1", "--workers", "0"]
    assert main([*argv, "--table", str(table)]) == 0
    with table.open() as handle:
        rows = {row["failure"]: row for row in csv.DictReader(handle)}
    names = ("bow-tunnel-1", "bow-tunnel-2", "port-azimuth", "starboard-azimuth")
    assert {f"{name} {mode}" for name in names for mode in ("stop", "stuck")} <= set(rows) and len(rows) == 1 + 15 + 8
    document = tomllib.loads(text)
    document["actuator"]["failures"] = [{"thruster": "port-azimuth", "mode": "stop", "start": START}]
    composition = compose(document)
    metrics = metric_module.resolve(["max_tracking:position"], composition.scenario)
    seed = composition.simulation.seed
    expected = metric_module.reduce(simulate_batch(composition.scenario, keys_of_seeds([seed])), metrics, after=START)
    found = float(rows["port-azimuth stop"]["max_tracking:position max"])
    np.testing.assert_allclose(found, float(expected["max_tracking__position"][0]), rtol=1e-9)
    assert found != float(rows[INTACT]["max_tracking:position max"])


@pytest.mark.slow
def test_with_reference_handling_the_table_says_when_each_failure_was_detected(tmp_path):
    """The shortened example with ``[references] kind = "dp-class"``: a receiver's dropout
    is rejected at once and its freeze at the fix that makes ``freeze_samples`` repeats,
    in every run, and the intact suite rejects nothing. The detection is the campaign's
    ``rejected_after`` metric, whose numbers tests/test_reference_handling.py checks
    against the records."""
    from lookout.sensing.handling import ReferenceHandler

    assert _text().count('[references]\nkind = "weighted-mean"') == 1
    scenario = tmp_path / "suite-handled.toml"
    scenario.write_text(_text().replace('[references]\nkind = "weighted-mean"', '[references]\nkind = "dp-class"'))
    table = tmp_path / "table.csv"
    argv = ["failures", str(scenario), "--out", str(tmp_path / "store.zarr"), "--start", str(START), "--seeds", "2", "--workers", "0"]
    assert main([*argv, "--table", str(table)]) == 0
    with table.open() as handle:
        rows = {row["failure"]: row for row in csv.DictReader(handle)}
    assert rows[INTACT]["runs rejecting another sensor"] == "0" and rows[INTACT]["detected after (s)"] == ""
    repeats = int(ReferenceHandler().freeze_samples)
    for name in ("dgnss1", "dgnss2"):  # 1 s fixes
        assert float(rows[f"{name} dropout"]["detected after (s)"]) == 0.0
        assert float(rows[f"{name} freeze"]["detected after (s)"]) == pytest.approx(repeats - 1.0, abs=1e-9)
