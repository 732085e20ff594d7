"""Scenario files and campaigns: round trips, one-line errors, resume, dask execution."""

from __future__ import annotations

import copy
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.papers import REPRODUCTIONS, fossen_strand_1999
from lookout.scenario import _toml
from lookout.scenario import metrics as metric_module
from lookout.scenario.composition import compose, set_path
from lookout.scenario.file import CompositionSpec, load, save
from lookout.sim import keys_of_seeds, simulate_batch
from lookout.studies.campaign import campaign_from_document, load_campaign
from lookout.studies.execute import run_campaign
from lookout.studies.store import CampaignStore

# no xdist group: the tests spread over the workers (each builds the session fixtures it needs)


def _run_cli(args, capsys):
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# ----------------------------------------------------------------------------------
# scenario files


def test_toml_writer_round_trips_every_value_to_the_bit(tmp_path):
    document = {"a": 0.1 + 0.2, "b": [1e-300, -2.5e17, float("inf")], "c": {"d": [[1.0, 2.0], [3.0, 4.0]], "e": 'x"y', "f": True, "g": 3}}
    path = _toml.write(tmp_path / "x.toml", document, comments={"c.d": "a matrix"}, header="head")
    parsed, text = _toml.read(path)
    assert parsed == document
    assert "# a matrix" in text and text.startswith("# head")


@pytest.mark.slow
def test_a_scenario_file_written_by_the_reproduction_gives_its_numbers_exactly(tmp_path, capsys):
    scenario = tmp_path / "fs.toml"
    code, out, err = _run_cli(
        ["reproduce", "fossen-strand-1999", "--duration", "20", "--runs", "2", "--seed", "3", "--write-scenario", str(scenario)], capsys
    )
    assert code == 0, err
    assert f"scenario written to {scenario}" in out
    assert not (tmp_path / "out").exists()
    code, out, err = _run_cli(["run", str(scenario), "--out", str(tmp_path / "run")], capsys)
    assert code == 0, err
    ran = xr.open_dataset(tmp_path / "run" / "run.nc")
    # the reproduction's own NetCDF, from its run() path
    reproduced = fossen_strand_1999.simulate_runs(fossen_strand_1999.Config(duration=20.0, runs=2, seed=3))
    compared = 0
    for name, variable in reproduced.data_vars.items():
        if variable.dtype.kind == "f":
            np.testing.assert_array_equal(ran[name].values, variable.values, err_msg=name)
            compared += 1
    assert compared > 20
    assert list(ran.seed.values) == [3, 4]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    rms = np.sqrt((ran.position - ran.position_hat).sel(time=ran.time >= 10.0).pipe(lambda e: (e**2).sum("earth_axis").mean("time")))
    np.testing.assert_allclose(summary["metrics"]["rms_error:position"]["per_run"], rms.values, rtol=1e-12)
    # the copy in the folder runs again and says so
    assert load(tmp_path / "run" / "scenario.toml").document() == load(scenario).document()


@pytest.mark.parametrize("name", list(REPRODUCTIONS))
@pytest.mark.slow
def test_every_reproduction_writes_a_scenario_file_that_loads_and_builds(name, tmp_path):
    reproduction = REPRODUCTIONS[name]
    for case in reproduction.cases:
        composition = compose(reproduction.composition(reproduction.Config(), case))
        path = save(CompositionSpec(composition), tmp_path / f"{name}-{case}.toml")
        spec = load(path)
        assert spec.document() == composition.document and spec.build().n_records > 0


def _scenario_text(tmp_path, capsys) -> str:
    scenario = tmp_path / "base.toml"
    code, _, err = _run_cli(["reproduce", "fossen-strand-1999", "--duration", "30", "--write-scenario", str(scenario)], capsys)
    assert code == 0, err
    return scenario.read_text()


def _line_of(text: str, key: str | None) -> int | None:
    """The line where ``key = ...`` is first set in ``text``; a dotted key
    (``sensor.sample_period``) is looked for after its table's header."""
    if not key:
        return None
    lines = text.splitlines()
    *tables, name = re.sub(r"\[\d+\]", "", key).split(".")
    start = 0
    if tables:
        header = f"[{'.'.join(tables)}]"
        start = next((n for n, content in enumerate(lines) if content.strip() == header), None)
        if start is None:
            return None
    found = next((n for n, content in enumerate(lines[start:], start + 1) if content.startswith(f"{name} =") or content.strip() == f"[{key}]"), None)
    return found


CUSTOM_VESSEL = 'kind = "custom"\nmass_matrix = [[5.3e6, 0, 0], [0, 8.3e6, 0], [0, 0, 3.7e9]]\ndamping_matrix = '


@pytest.mark.parametrize(
    "old, new, expected",
    [
        ("duration = 30.0", "durration = 30.0", "simulation.durration (line {line}): unknown key"),
        ("duration = 30.0", 'duration = "long"', 'simulation.duration (line {line}): must be a number; got "long" (a string)'),
        # strictly typed: a boolean or a string is not a number, a float is not a count
        ("duration = 30.0", "duration = true", "simulation.duration (line {line}): must be a number; got true (a boolean)"),
        ("duration = 30.0", 'duration = "100"', 'simulation.duration (line {line}): must be a number; got "100" (a string)'),
        ("runs = 1", "runs = 2.0", "simulation.runs (line {line}): must be an integer (no decimal point); got 2.0 (a number with a decimal point)"),
        (
            "noise_std = [0.5, 0.5, 0.0017453292519943296]",
            "noise_std = [0.5, false, 0.1]",
            "sensor.noise_std[1] (line {line}): must be a number; got false (a boolean)",
        ),
        (
            "dropout_probability = 0.0",
            "dropout_probability = 1979-05-27",
            "sensor.dropout_probability (line {line}): must be a number; got a TOML date: 1979-05-27",
        ),
        ("bias = [10000.0, 5000.0, 100000.0]", "bias = [inf, 5000.0, 100000.0]", "plant.initial.bias[0] (line {line}): must be finite; got inf"),
        ("runs = 1", "runs = 99999999999999999999", "simulation.runs (line {line}): must be at most 9223372036854775808"),
        ("sample_period = 1.0", "sample_period = -1.0", "sensor.sample_period (line {line}): must be positive; got -1.0"),
        # damping that feeds energy in is no vessel
        (
            'kind = "northern-clipper"',
            CUSTOM_VESSEL + "[[5.0e4, 0, 0], [0, 2.7e5, -4.4e7], [0, -4.4e7, 4.2e8]]",
            "plant.vessel.damping_matrix (line {line}): damping_matrix must have a positive semi-definite symmetric part (damping dissipates energy: nu^T D nu >= 0); the smallest eigenvalue of (D + D^T)/2 is -4.29e+06",
        ),
        # the engine's rules under the file's names
        (
            "sample_period = 1.0",
            "sample_period = 0.15",
            "sensor.sample_period (line {line}): sensor sample_period[0] (0.15 s) must be an integer multiple of sample_period (0.1 s)",
        ),
        ("duration = 30.0", "duration = 1e12", "simulation.duration (line {line}): must be below 4.295e+09 samples of sample_period (0.1 s)"),
        # a value only the component can refuse: the key its message names
        ("cutoff_frequency = 1.1", "cutoff_frequency = 0.5", "observer.cutoff_frequency (line {line}): cutoff_frequency must exceed wave_frequency"),
        (
            'kind = "northern-clipper"',
            'kind = "custom"\nmass_matrix = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, -2.0]]\ndamping_matrix = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]',
            "plant.vessel.mass_matrix (line {line}): mass_matrix must be symmetric positive definite; its smallest eigenvalue is -2",
        ),
        ('kind = "northern-clipper"', 'kind = "custom"', "plant.vessel (line {line}): missing key mass_matrix"),  # the table's header line
        ('kind = "dp-vessel"', 'kind = "nope"', "plant.kind (line {line}): no plant kind 'nope' (one of "),
        ('design = "fossen-strand-1999"', 'design = "other"', "observer.design (line {line}): no design 'other' (one of fossen-strand-1999, gains)"),
        ("dropout_probability = 0.0", "dropout_probability = 1.5", "sensor.dropout_probability (line {line}): must be in [0, 1); got 1.5"),
        (
            "noise_std = [0.5, 0.5, 0.0017453292519943296]",
            "noise_std = [0.5, 0.5]",
            "sensor.noise_std (line {line}): must be one number or have 3 entries; got 2 entries",
        ),
        ('hold = "measurement"', 'hold = "both"', "observer.hold (line {line}): Input should be 'measurement' or 'innovation'"),
        ("[simulation]", "[simulation", "not valid TOML"),
    ],
)
def test_a_bad_scenario_file_is_one_line_naming_file_key_and_line(old, new, expected, tmp_path, capsys):
    text = _scenario_text(tmp_path, capsys)
    assert old in text
    bad = text.replace(old, new, 1)
    path = tmp_path / "bad.toml"
    path.write_text(bad)
    key = expected.split(" (line")[0] if "(line" in expected else None
    code, out, err = _run_cli(["run", str(path), "--out", str(tmp_path / "x")], capsys)
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"error: {path}: ")
    assert expected.format(line=_line_of(bad, key)) in err, err
    assert err.count("; got") <= 1, err  # what was given, said once
    assert not (tmp_path / "x").exists()


def test_run_options_are_checked_before_the_file(tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(_scenario_text(tmp_path, capsys))
    for args, message in (
        (["--runs", "0"], "error: --runs must be a positive integer; got 0"),
        (["--seed", "-1"], "error: --seed must be an integer from 0 to"),
    ):
        code, _, err = _run_cli(["run", str(scenario), "--out", str(tmp_path / "x"), *args], capsys)
        assert code == 2 and err.startswith(message), err
    code, _, err = _run_cli(["run", str(tmp_path / "missing.toml")], capsys)
    assert code == 2 and err == f"error: {tmp_path / 'missing.toml'}: no such file\n"
    code, _, err = _run_cli(["reproduce", "fossen-strand-1999", "--write-scenario", str(tmp_path / "s.txt")], capsys)
    assert code == 2 and err == f"error: --write-scenario must end in .toml; got {tmp_path / 's.txt'}\n"


@pytest.mark.parametrize("name, case", [("fossen-strand-1999", "paper"), ("kim-2002", "sliding-mode")])
def test_a_custom_vessel_is_simulated_with_its_own_matrices(name, case, tmp_path):
    from lookout.models.vessel import NORTHERN_CLIPPER_D, NORTHERN_CLIPPER_M

    reproduction = REPRODUCTIONS[name]
    heavier = (NORTHERN_CLIPPER_M * 2.0).tolist()
    extra = {"model_error": {"mass": 0.1, "damping": 0.0}} if name == "kim-2002" else {}
    config = reproduction.Config(
        duration=100.0, vessel={"model": "custom", "mass_matrix": heavier, "damping_matrix": NORTHERN_CLIPPER_D.tolist()}, **extra
    )
    path = save(CompositionSpec(compose(reproduction.composition(config, case))), tmp_path / "custom.toml")
    scenario = load(path).build()
    # the plant is the user's vessel (with Kim's model error on top); every model-based part uses its M
    truth = np.asarray(heavier) * (1.1 if name == "kim-2002" else 1.0)
    np.testing.assert_allclose(np.asarray(scenario.plant.vessel.mass_matrix), truth, rtol=1e-15)
    models = [scenario.observer] if name == "fossen-strand-1999" else [scenario.observer.passive, scenario.controller]
    for part in models:
        np.testing.assert_array_equal(np.asarray(part.mass_matrix), np.asarray(heavier), err_msg=type(part).__name__)


# ----------------------------------------------------------------------------------
# campaign specs

# Chunks of 3 runs: not a multiple of the 2 devices conftest exposes, so this process
# runs them unsharded, as a 1-device dask worker does, and the workers load the program
# this process compiled from the persistent compilation cache.
CAMPAIGN = {
    "seeds_per_point": 6,
    "chunk_runs": 3,
    "metrics": ["rms_error:position", "max_excursion:position", "rms_input:force", "settling_time:bias_force"],
    "divergence": {"signal": "position", "limit": 1000.0},
    "trajectories": {"signals": ["position", "position_hat", "measured_heading"], "every": 10},
    "sweep": {
        "kind": "grid",
        "axes": [
            {"field": ["plant.waves.peak_frequency", "observer.wave_frequency"], "values": [0.7, 1.0], "name": "wave_frequency"},
            {"field": ["plant.bias.std[0]", "plant.bias.std[1]", "plant.bias.std[2]"], "values": [0.5, 2.0], "scale": True, "name": "bias_scale"},
            {"field": "sensor.dropout_probability", "values": [0.0, 0.3], "name": "dropout_probability"},
        ],
    },
}


def _write_campaign(folder: Path, scenario_text: str, **changes) -> Path:
    (folder / "base.toml").write_text(scenario_text)
    document = {"scenario": "base.toml", **CAMPAIGN, **changes}
    return _toml.write(folder / "campaign.toml", document)


def test_campaign_points_are_the_grid_and_scale_multiplies_the_base(tmp_path, capsys):
    spec = _write_campaign(tmp_path, _scenario_text(tmp_path, capsys))
    campaign = load_campaign(spec)
    assert len(campaign.points) == 8 and len(campaign.chunks()) == 16
    assert campaign.points[5] == {"wave_frequency": 1.0, "bias_scale": 0.5, "dropout_probability": 0.3}
    changes = campaign.changes(5)
    assert changes["plant.bias.std[2]"] == 0.5 * 5e4 and changes["observer.wave_frequency"] == changes["plant.waves.peak_frequency"] == 1.0
    values = campaign.point_spec(5).values()
    assert values["plant"]["bias"]["std"] == (1e3, 1e3, 2.5e4) and values["sensor"]["dropout_probability"] == 0.3
    assert float(campaign.point_spec(5).build().observer.wave_frequency[0]) == 1.0
    # a Latin hypercube: one point per stratum of each axis
    lhs = campaign_from_document(
        {
            "scenario": campaign.base.document(),
            "seeds_per_point": 2,
            "metrics": ["rms_error:position"],
            "sweep": {
                "kind": "latin-hypercube",
                "points": 10,
                "seed": 3,
                "axes": [
                    {"field": "observer.wave_frequency", "range": [0.5, 1.0], "name": "wave_frequency"},
                    {"field": "sensor.dropout_probability", "range": [0.0, 0.5], "name": "dropout_probability"},
                ],
            },
        },
        "<lhs>",
    )
    for label, (low, high) in (("wave_frequency", (0.5, 1.0)), ("dropout_probability", (0.0, 0.5))):
        strata = np.floor((np.array([p[label] for p in lhs.points]) - low) / (high - low) * 10).astype(int)
        assert sorted(strata) == list(range(10))


@pytest.mark.slow
def test_an_axis_may_replace_a_component_and_sweep_a_model_error(tmp_path):
    """Kim's two observers of Fig. 8 in one campaign: an axis whose values are observer
    tables (the conventional one is the sliding-mode observer without its switching
    term), crossed with the plant's mass error."""
    base = compose({"preset": "kim-2002", "simulation": {"duration": 100.0}}).document
    conventional = {**base["observer"], "switching_gain": [0.0, 0.0, 0.0]}
    document = {
        "scenario": base,
        "seeds_per_point": 2,
        "chunk_runs": 2,
        "metrics": ["rms_tracking:position"],
        "sweep": {
            "axes": [
                {"field": "observer", "values": [base["observer"], conventional], "name": "observer"},
                {"field": "plant.vessel.mass_scale", "values": [1.0, 1.2]},
            ]
        },
    }
    campaign = campaign_from_document(document, "<kim>")
    scenarios = [campaign.point_spec(point).build() for point in range(len(campaign.points))]
    switching = [np.asarray(s.observer.switching_gain) for s in scenarios]
    assert np.all(switching[0] > 0) and np.all(switching[1] > 0) and np.all(switching[2] == 0) and np.all(switching[3] == 0)
    nominal = np.asarray(scenarios[0].observer.passive.mass_matrix)
    for point, scale in enumerate([1.0, 1.2, 1.0, 1.2]):
        np.testing.assert_allclose(np.asarray(scenarios[point].plant.vessel.mass_matrix), scale * nominal, rtol=1e-15)
        np.testing.assert_array_equal(np.asarray(scenarios[point].observer.passive.mass_matrix), nominal)  # the model stays
    # the store names a replaced component by its kind, numbered when two share one
    store = tmp_path / "kim.zarr"
    run_campaign(campaign, store, workers=0, say=lambda text: None)
    ds = CampaignStore(store).open().load()
    assert list(ds.observer.values) == ["sliding-mode 1", "sliding-mode 1", "sliding-mode 2", "sliding-mode 2"]
    assert np.isfinite(ds.rms_tracking__position).all()


@pytest.mark.slow
def test_a_cases_axis_sets_several_keys_per_value(tmp_path):
    """A gain set (two keys) crossed with a model error one kind at a time: each case
    sets its own keys, the store names it by its label, and a point's metrics equal
    those of the same composition changed by hand and reduced from its records."""
    base = compose({"preset": "kim-2002", "simulation": {"duration": 50.0, "record_every": 10}}).document
    low = {"observer.bias_injection_gain": [1e4, 1e4, 1e7], "observer.velocity_injection_gain": [1e3, 1e3, 1e6]}
    document = {
        "scenario": base,
        "seeds_per_point": 2,
        "metrics": ["rms_tracking:position"],
        "after": 0.0,
        "divergence": {"signal": "position", "limit": 100.0},
        "sweep": {
            "axes": [
                {"name": "gains", "labels": ["printed", "low"], "cases": [{}, low]},
                {"name": "model_error", "cases": [{}, {"plant.vessel.mass_scale": 1.25}]},
            ]
        },
    }
    campaign = campaign_from_document(document, "<cases>")
    assert len(campaign.points) == 4
    assert [p["model_error"] for p in campaign.points[:2]] == ["base", "plant.vessel.mass_scale=1.25"]
    changes = campaign.changes(3)
    assert changes == {**low, "plant.vessel.mass_scale": 1.25}
    scenario = campaign.point_spec(3).build()
    np.testing.assert_array_equal(np.asarray(scenario.observer.passive.bias_injection_gain), low["observer.bias_injection_gain"])
    assert float(scenario.plant.vessel.mass_matrix[0, 0]) == pytest.approx(
        1.25 / 1.2 * float(campaign.point_spec(0).build().plant.vessel.mass_matrix[0, 0])
    )
    store = tmp_path / "cases.zarr"
    run_campaign(campaign, store, workers=0, say=lambda text: None)
    ds = CampaignStore(store).open().load()
    assert list(ds.gains.values) == ["printed"] * 2 + ["low"] * 2 and ds.model_error.values[3] == "plant.vessel.mass_scale=1.25"
    # the reference: the point's composition written out by hand, simulated with its records kept
    by_hand = copy.deepcopy(base)
    for path, value in {**low, "plant.vessel.mass_scale": 1.25}.items():
        set_path(by_hand, path, value)
    reference = compose(by_hand).scenario
    metrics = metric_module.resolve(["rms_tracking:position"], reference)
    expected = metric_module.reduce(simulate_batch(reference, keys_of_seeds([0, 1])), metrics, after=0.0, divergence=("position", 100.0))
    np.testing.assert_allclose(ds.rms_tracking__position.values[3], expected["rms_tracking__position"], rtol=1e-6)


@pytest.mark.parametrize(
    "changes, expected",
    [
        (
            {"sweep": {"axes": [{"field": "observer.wave_freqency", "values": [1.0]}]}},
            "sweep.axes[0].field (line {line}): the scenario has no setting 'observer.wave_freqency'",
        ),
        (
            {"sweep": {"axes": [{"field": "sensor.noise_std[3]", "values": [1.0]}]}},
            "sweep.axes[0].field (line {line}): the scenario has no setting 'sensor.noise_std[3]'",
        ),
        (
            {"sweep": {"axes": [{"field": "sensor.dropout_probability", "values": [0.1, 1.5]}]}},
            "sweep.axes[0].values (line {line}): value 1.5: sensor.dropout_probability: must be in [0, 1); got 1.5",
        ),
        ({"metrics": ["rms_tracking:position"]}, "metrics (line {line}): 'rms_tracking:position': the reference gives no desired 'position'"),
        ({"seeds_per_point": 4, "chunk_runs": 3}, "chunk_runs (line {line}): must be a positive divisor of seeds_per_point (4)"),
        ({"seed_per_point": 4}, "seed_per_point (line {line}): unknown key"),
        (
            {"sweep": {"kind": "latin-hypercube", "axes": [{"field": "observer.wave_frequency", "range": [0.5, 1.0]}]}},
            "sweep (line {line}): a latin-hypercube needs points >= 1",
        ),
        (
            {"sweep": {"axes": [{"field": "observer.wave_frequency", "values": [0.5, 1.1]}]}},
            "sweep.axes[0].values (line {line}): value 1.1: observer.cutoff_frequency: cutoff_frequency must exceed wave_frequency",
        ),
        (
            {"sweep": {"axes": [{"field": "case", "values": ["paper", "papers"]}]}},
            "sweep.axes[0].field (line {line}): the scenario has no setting 'case'",
        ),
        # a cases axis
        (
            {"sweep": {"axes": [{"name": "gains", "cases": [{"observer.wave_freqency": 1.0}]}]}},
            "sweep.axes[0].cases (line {line}): the scenario has no setting 'observer.wave_freqency'",
        ),
        (
            {"sweep": {"axes": [{"name": "gains", "cases": [{}, {"sensor.dropout_probability": 1.5}]}]}},
            "sweep.axes[0].cases (line {line}): case 'sensor.dropout_probability=1.5': sensor.dropout_probability: must be in [0, 1); got 1.5",
        ),
        ({"sweep": {"axes": [{"cases": [{}]}]}}, "sweep.axes[0] (line {line}): an axis with cases needs a name"),
        (
            {"sweep": {"axes": [{"name": "g", "field": "sensor.dropout_probability", "cases": [{}]}]}},
            "sweep.axes[0] (line {line}): an axis with cases sets its keys per case: drop field",
        ),
        (
            {"sweep": {"axes": [{"name": "g", "labels": ["a"], "cases": [{}, {"sensor.dropout_probability": 0.1}]}]}},
            "sweep.axes[0] (line {line}): labels must name each of the 2 cases; got 1 label(s)",
        ),
        (
            {"sweep": {"kind": "latin-hypercube", "points": 3, "axes": [{"name": "g", "cases": [{}]}]}},
            "sweep (line {line}): axes[0]: cases are for a grid",
        ),
        # a whole component replaced by a table that is none
        (
            {"sweep": {"axes": [{"field": "observer", "values": [{"kind": "passive"}, {"kind": "nope"}]}]}},
            "sweep.axes[0].values (line {line}): value {{'kind': 'nope'}}: observer.kind: no observer kind 'nope'",
        ),
        ({"seeds_per_point": "8"}, 'seeds_per_point (line {line}): must be an integer (no decimal point); got "8" (a string)'),
        ({"scenario": 5}, "scenario (line {line}): must be a string (in quotes); got 5"),
        (
            {"sweep": {"axes": [{"field": "seed", "values": [1, 2]}]}},
            "sweep (line {line}): axes[0]: a campaign runs seeds_per_point seeds from seed at every point; 'seed' cannot be swept",
        ),
        (
            {"sweep": {"points": 5, "axes": [{"field": "observer.wave_frequency", "values": [0.6, 0.8]}]}},
            "sweep (line {line}): points is for a latin-hypercube",
        ),
        (
            {"sweep": {"axes": [{"field": "observer.wave_frequency", "values": [0.6, 0.8], "name": "point"}]}},
            "sweep (line {line}): axis name 'point' is taken by the store",
        ),
        (
            {"sweep": {"axes": [{"field": "observer.wave_frequency", "values": [0.6, 0.8], "name": "rms_error__position"}]}},
            "sweep (line {line}): axis name 'rms_error__position' is taken by the store",
        ),
        ({"after": 100.0}, "after (line {line}): 100 s is past the end of the run (29.9 s): the metrics would have no record"),
        (
            {"sweep": {"axes": [{"field": "simulation.duration", "values": [200.0, 20.0]}]}, "after": 25.0},
            "sweep.axes[0].values (line {line}): value 20.0: after (25 s) is past the end of that run (19.9 s)",
        ),
        # sizes before allocation: neither the seeds nor the points are made
        (
            {"seeds_per_point": 10**12, "chunk_runs": 4},
            "seeds_per_point (line {line}): 8 point(s) x 1000000000000 seeds in 2000000000000 chunks would need about",
        ),
        (
            {"sweep": {"kind": "latin-hypercube", "points": 10**12, "axes": [{"field": "observer.wave_frequency", "range": [0.5, 1.0]}]}},
            "sweep (line {line}): 1000000000000 point(s) x 6 seeds in 2000000000000 chunks would need about",
        ),
    ],
)
def test_a_bad_campaign_spec_is_one_line_with_exit_code_2(changes, expected, tmp_path, capsys):
    spec = _write_campaign(tmp_path, _scenario_text(tmp_path, capsys), **changes)
    key = expected.split(" (line")[0] if "(line" in expected else None
    key = "axes" if key and key.startswith("sweep.axes") else key
    line = _line_of(spec.read_text(), key)
    code, _, err = _run_cli(["campaign", "run", str(spec), "--out", str(tmp_path / "store"), "--workers", "0"], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: {spec}: ") and expected.format(line=line) in err, err
    assert not (tmp_path / "store").exists()


@pytest.mark.parametrize(
    "table, expected",
    [
        # a value the file's schema refuses
        (
            "[observer]\nswitching_gain = [{many}, -1.0]\n",
            "observer.switching_gain (line 5): must be one number or have 3 entries; got 100000 entries",
        ),
        # a value only the component can refuse
        (
            '[reference]\nkind = "reference-filter"\nsignals = ["position", "heading"]\nschedule_times = [{many}, 0.0]\nsetpoints = [{setpoints}]\n',
            "reference.schedule_times (line 7): schedule_times must be strictly increasing; got [1., 1., 1., 1., ..., 1., 1., 1., 0.]",
        ),
    ],
)
@pytest.mark.slow
def test_a_refused_array_of_any_size_is_one_short_line(table, expected, tmp_path, capsys):
    path = tmp_path / "big.toml"
    path.write_text(
        'preset = "kim-2002"\n[simulation]\nduration = 60.0\n'
        + table.format(many=", ".join(["1.0"] * 99999), setpoints=", ".join(["[0.0, 0.0, 0.0]"] * 100000))
    )
    code, _, err = _run_cli(["run", str(path), "--out", str(tmp_path / "x")], capsys)
    assert code == 2 and err.count("\n") == 1 and expected in err, err[:500]
    assert len(err) < 400, len(err)
    assert not (tmp_path / "x").exists()


def test_a_scenario_file_given_as_a_campaign_spec_says_what_it_is(tmp_path, capsys):
    scenario = tmp_path / "base.toml"
    scenario.write_text(_scenario_text(tmp_path, capsys))
    code, _, err = _run_cli(["campaign", "run", str(scenario), "--out", str(tmp_path / "store"), "--workers", "0"], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: {scenario}: a scenario file, not a campaign spec: run it with lookout run {scenario}, or sweep it"), err
    assert not (tmp_path / "store").exists()


# ----------------------------------------------------------------------------------
# running, resuming, dask


# session scope: xdist may interleave this module's tests with others on one worker,
# and a module fixture would then be built again
@pytest.fixture(scope="session")
def campaign_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("campaign")
    composition = compose(fossen_strand_1999.composition(fossen_strand_1999.Config(duration=30.0)))
    save(CompositionSpec(composition), folder / "base.toml")
    spec = _toml.write(folder / "campaign.toml", {"scenario": "base.toml", **CAMPAIGN})
    return folder, spec


@pytest.fixture(scope="session")
def reference_store(campaign_files):
    """The campaign computed in this process, uninterrupted."""
    folder, spec = campaign_files
    store = folder / "reference.zarr"
    run_campaign(load_campaign(spec), store, workers=0, say=lambda text: None)
    return store


def _assert_same_store(a: Path, b: Path) -> None:
    first, second = CampaignStore(a).open().load(), CampaignStore(b).open().load()
    assert set(first.data_vars) == set(second.data_vars)
    for name in first.data_vars:
        np.testing.assert_array_equal(first[name].values, second[name].values, err_msg=name)
    for name in first.coords:
        np.testing.assert_array_equal(first[name].values, second[name].values, err_msg=name)
    assert len(CampaignStore(a).done()) == len(CampaignStore(b).done())


@pytest.mark.slow
def test_the_store_holds_every_metric_of_every_run(reference_store, campaign_files):
    ds = CampaignStore(reference_store).open().load()
    assert dict(ds.sizes) == {"point": 8, "seed": 6, "kept_time": 30, "earth_axis": 2}
    assert np.isfinite(ds.rms_error__position).all() and (ds.diverged == 0).all()
    assert ds.rms_error__position.attrs["units"] == "m" and ds.settling_time__bias_force.attrs["units"] == "s"
    # point 5, seeds 3..5, recomputed directly: same metric
    campaign = load_campaign(campaign_files[1])
    scenario = campaign.point_spec(5).build()
    from lookout.sim import keys_of_seeds, simulate_batch

    trajectory = simulate_batch(scenario, keys_of_seeds([3, 4, 5]))
    error = np.asarray(trajectory.truth["position"]) - np.asarray(trajectory.estimate["position"])
    rms = np.sqrt((error[:, 150:] ** 2).sum(-1).mean(-1))
    np.testing.assert_allclose(ds.rms_error__position.values[5, 3:], rms, rtol=1e-12)
    # kept trajectories: every 10th record of the same runs, truths, estimates and measurements
    np.testing.assert_array_equal(ds.trajectory__position.values[5, 3:], np.asarray(trajectory.truth["position"])[:, ::10])
    np.testing.assert_array_equal(ds.trajectory__position_hat.values[5, 3:], np.asarray(trajectory.estimate["position"])[:, ::10])
    np.testing.assert_array_equal(ds.trajectory__measured_heading.values[5, 3:], trajectory.to_xarray().measured_heading.values[:, ::10])
    assert ds.kept_time.values.tolist() == np.asarray(trajectory.time)[::10].tolist() and ds.trajectory__position.attrs["units"] == "m"
    # dropouts raise the error: the 0.3 points against the 0.0 ones, seeds alike
    noisy = ds.rms_error__position.where(ds.dropout_probability == 0.3, drop=True).values
    clean = ds.rms_error__position.where(ds.dropout_probability == 0.0, drop=True).values
    assert np.median(noisy) > np.median(clean)
    code = main(["campaign", "status", str(reference_store)])
    assert code == 0


@pytest.mark.slow
def test_without_trajectories_the_metrics_accumulate_in_the_scan_and_equal_the_reduced_ones(reference_store, campaign_files, tmp_path):
    """No kept trajectories: each chunk runs summarize_batch (no records held); its
    metrics equal those reduced from the records of the reference store's runs."""
    folder, spec = campaign_files
    document = json.loads(json.dumps(load_campaign(spec).document()))
    del document["trajectories"]
    campaign = campaign_from_document(document, "<no trajectories>")
    run_campaign(campaign, tmp_path / "summarized.zarr", workers=0, say=lambda text: None)
    got, reference = CampaignStore(tmp_path / "summarized.zarr").open().load(), CampaignStore(reference_store).open().load()
    assert not any(name.startswith("trajectory__") for name in got.data_vars)
    for name in got.data_vars:
        np.testing.assert_allclose(got[name].values, reference[name].values, rtol=1e-12, atol=0, err_msg=name)


@pytest.mark.slow
def test_a_campaign_killed_mid_way_resumes_to_the_uninterrupted_store(reference_store, campaign_files, tmp_path):
    folder, spec = campaign_files
    store = tmp_path / "killed.zarr"
    process = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from lookout.cli import main; sys.exit(main(sys.argv[1:]))",
            "campaign",
            "run",
            str(spec),
            "--out",
            str(store),
            "--workers",
            "0",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env={**os.environ},
    )
    records = store / "_lookout" / "chunks"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and process.poll() is None:
        if records.exists() and len(list(records.glob("chunk-*.json"))) >= 3:
            break
        time.sleep(0.05)
    assert process.poll() is None, process.stderr.read().decode()
    process.send_signal(signal.SIGKILL)
    process.wait()
    process.stderr.close()
    before = {path.name: path.read_text() for path in records.glob("chunk-*.json")}
    assert 3 <= len(before) < 16
    messages = []
    result = run_campaign(load_campaign(spec), store, workers=0, say=messages.append)
    assert result["computed"] == 16 - len(before)
    assert any(f"resuming: {len(before)} of 16 chunks done" in m for m in messages)
    # a recorded chunk is never written again: its record is untouched
    for name, text in before.items():
        assert (records / name).read_text() == text
    _assert_same_store(store, reference_store)
    # resuming a complete store computes nothing; another spec is refused
    assert run_campaign(load_campaign(spec), store, workers=0, say=lambda text: None)["computed"] == 0
    other = campaign_from_document({**json.loads(json.dumps(load_campaign(spec).document())), "seeds_per_point": 3, "chunk_runs": 3}, "<other>")
    with pytest.raises(ValueError, match="holds another campaign"):
        run_campaign(other, store, workers=0, say=lambda text: None)


@pytest.mark.slow
def test_two_local_workers_give_the_one_process_store_even_when_a_worker_is_killed_mid_chunk(reference_store, campaign_files, tmp_path):
    """The default: lookout starts a 2-worker LocalCluster. A watcher connects to its
    scheduler, waits until a worker is running a chunk (after the calibration chunk
    is stored) and SIGKILLs that worker's process; the campaign still completes, and
    its store equals the one computed in a single process. The cluster runs in a
    process of its own (tests/_campaign_worker_kill.py), so its threads never share a
    pytest worker with the tests that follow."""
    folder, spec = campaign_files
    store = tmp_path / "dask.zarr"
    script = Path(__file__).with_name("_campaign_worker_kill.py")
    process = subprocess.run([sys.executable, str(script), str(spec), str(store)], capture_output=True, text=True, timeout=720, env={**os.environ})
    assert process.returncode == 0, process.stderr[-4000:]
    outcome = json.loads(process.stdout.strip().splitlines()[-1])
    assert outcome.get("error") is None, (outcome.get("error"), process.stderr[-4000:])
    killed, messages = outcome["killed"], outcome["messages"]
    assert killed, "no worker was caught mid-chunk"
    assert killed["recorded"] < 16
    assert outcome["result"]["done"] == 16
    assert any(m.startswith("calibration: ") for m in messages)
    assert any("dashboard: http://127.0.0.1:" in m for m in messages)
    _assert_same_store(store, reference_store)


def test_a_chunk_that_does_not_fit_a_worker_is_refused_with_the_numbers(campaign_files, tmp_path):
    folder, spec = campaign_files
    campaign = load_campaign(spec)
    with pytest.raises(
        ValueError,
        match=r"chunk_runs 3 needs about .* per chunk \(300 records x \(3 runs x 296 B x 4 \+ 32 B\), \+ 600 MB runtime\), and a worker has 100 MB",
    ):
        run_campaign(campaign, tmp_path / "small.zarr", workers=0, say=lambda text: None, available_memory=lambda: 100e6)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--workers", "-1"], "error: --workers must be 0 (this process) or a positive number of workers; got -1"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "error: give --workers or --scheduler, not both"),
    ],
)
def test_campaign_options_are_checked_first(args, message, campaign_files, tmp_path, capsys):
    folder, spec = campaign_files
    code, _, err = _run_cli(["campaign", "run", str(spec), "--out", str(tmp_path / "s.zarr"), *args], capsys)
    assert code == 2 and err.startswith(message), err
    assert not (tmp_path / "s.zarr").exists()


def test_status_and_report_name_a_folder_that_is_no_store(tmp_path, capsys):
    for command in (["campaign", "status", str(tmp_path)], ["campaign", "report", str(tmp_path)]):
        code, _, err = _run_cli(command, capsys)
        assert code == 2 and "is not a campaign store" in err and err.count("\n") == 1, err


def test_status_says_what_is_done(reference_store, capsys):
    code, out, err = _run_cli(["campaign", "status", str(reference_store), "--json"], capsys)
    assert code == 0, err
    info = json.loads(out)
    assert info["chunks"] == info["chunks_done"] == 16 and info["runs_done"] == 48 and info["complete"]
    assert info["axes"] == ["wave_frequency", "bias_scale", "dropout_probability"] and info["diverged"] == 0


# ----------------------------------------------------------------------------------
# sizes before allocation, and a refused or failed start leaves nothing behind


def test_lookout_run_refuses_a_billion_runs_before_making_anything(tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(_scenario_text(tmp_path, capsys))
    code, _, err = _run_cli(["run", str(scenario), "--out", str(tmp_path / "x"), "--runs", "1000000000"], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: {scenario}: --runs 1000000000 over simulation.duration 30 would need about ") and "use fewer --runs" in err, err
    assert not (tmp_path / "x").exists()


def test_a_folder_in_the_way_of_an_output_is_found_before_simulating(tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(_scenario_text(tmp_path, capsys))
    (tmp_path / "out" / "summary.json").mkdir(parents=True)
    code, _, err = _run_cli(["run", str(scenario), "--out", str(tmp_path / "out")], capsys)
    assert (
        code == 2
        and err
        == f"error: --out: {tmp_path / 'out' / 'summary.json'} is a folder, and lookout run writes the file summary.json there; give another --out\n"
    ), err
    assert _tree_of(tmp_path / "out") == ["summary.json"]


def _tree_of(folder: Path) -> list[str]:
    return sorted(str(path.relative_to(folder)) for path in folder.rglob("*"))


def test_a_scheduler_address_without_a_port_blames_the_option(campaign_files, tmp_path, capsys):
    folder, spec = campaign_files
    code, _, err = _run_cli(["campaign", "run", str(spec), "--out", str(tmp_path / "s.zarr"), "--scheduler", "localhost"], capsys)
    assert code == 2 and err == "error: --scheduler must be an address with a port, such as tcp://10.0.0.5:8786; got 'localhost'\n", err
    assert not (tmp_path / "s.zarr").exists()


@pytest.mark.slow
def test_an_unreachable_scheduler_blames_the_option_and_leaves_no_store(campaign_files, tmp_path):
    """In a process of its own: the client's event-loop thread stays out of the pytest worker."""
    folder, spec = campaign_files
    code = (
        "import sys; from lookout.studies import execute; execute.SCHEDULER_TIMEOUT = '1s'; "
        "from lookout.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    arguments = ["campaign", "run", str(spec), "--out", str(tmp_path / "s.zarr"), "--scheduler", "tcp://127.0.0.1:1"]
    process = subprocess.run([sys.executable, "-c", code, *arguments], capture_output=True, text=True, timeout=300, env={**os.environ})
    err = process.stderr
    assert process.returncode == 2 and err.count("\n") == 1, err
    assert err.startswith("error: --scheduler tcp://127.0.0.1:1: cannot reach the scheduler ("), err
    assert not (tmp_path / "s.zarr").exists()


def test_a_store_that_does_not_fit_the_disk_is_refused_before_it_exists(campaign_files, tmp_path):
    folder, spec = campaign_files
    with pytest.raises(
        ValueError, match=r"the store .*s.zarr \(16 chunks x 3 runs\) would need about .* of disk space, and 1 kB are available: free some space"
    ):
        run_campaign(load_campaign(spec), tmp_path / "s.zarr", workers=0, say=lambda text: None, free_disk=lambda path: 1000)
    assert not (tmp_path / "s.zarr").exists()


def test_a_write_error_names_the_store_and_leaves_no_empty_store(campaign_files, tmp_path, capsys, monkeypatch):
    import errno

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(CampaignStore, "_write_record", full)
    folder, spec = campaign_files
    store = tmp_path / "s.zarr"
    code, _, err = _run_cli(["campaign", "run", str(spec), "--out", str(store), "--workers", "0"], capsys)
    assert code == 1 and err.count("\n") == 1, err
    assert err == f"error: cannot write chunk-000000 into the campaign store {store}: No space left on device\n", err
    assert not store.exists()  # nothing of value was in it: it would block the corrected run


def test_a_changed_spec_is_refused_naming_the_keys_that_differ(campaign_files, tmp_path):
    folder, spec = campaign_files
    campaign = load_campaign(spec)
    store = tmp_path / "s.zarr"
    CampaignStore.open_or_create(store, campaign)
    document = json.loads(campaign.canonical())
    document["seeds_per_point"], document["chunk_runs"] = 9, 3
    document["scenario"]["simulation"]["duration"] = 20.0
    changed = campaign_from_document(document, "<changed>")
    with pytest.raises(
        ValueError,
        match=r"holds another campaign \(fingerprint \w+, this spec's is \w+\): "
        r"scenario.simulation.duration: 30.0 -> 20.0; seeds_per_point: 6 -> 9; resume it with its own spec",
    ):
        CampaignStore.open_or_create(store, changed)


def test_a_store_opens_with_xarray_without_a_warning(campaign_files, tmp_path):
    import warnings

    folder, spec = campaign_files
    store = tmp_path / "s.zarr"
    CampaignStore.open_or_create(store, load_campaign(spec))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = xr.open_zarr(store)
    assert "rms_error__position" in ds


def test_settings_are_as_strict_in_python_as_in_a_file():
    from pydantic import ValidationError

    for changes, message in (
        ({"duration": "100"}, "Input should be a valid number"),
        ({"duration": True}, "Input should be a valid number"),
        ({"runs": 2.0}, "Input should be a valid integer"),
        ({"bias_initial": (float("inf"), 0.0, 0.0)}, "must be finite; got inf"),
    ):
        with pytest.raises(ValidationError, match=message):
            fossen_strand_1999.Config(**changes)
    # arrays may be lists or NumPy arrays, numbers NumPy scalars
    config = fossen_strand_1999.Config(noise_std=np.array([0.1, 0.2, 0.3]), duration=np.float64(100.0), runs=np.int64(2))
    assert config.noise_std == (0.1, 0.2, 0.3) and config.duration == 100.0 and config.runs == 2
