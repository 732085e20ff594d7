"""The observer benchmark (lookout.studies.benchmark): its runs are the reproductions'
runs, every observer sees the same measurements bit for bit, a model error reaches the
plant alone, and the command writes its tables, figures and report or refuses bad input
in one line."""

from __future__ import annotations

import copy
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from lookout.cli import main
from lookout.composition import compose
from lookout.studies import benchmark as bench
from lookout.studies.campaign import campaign_from_document, compute_chunk

pytestmark = pytest.mark.xdist_group("benchmark")

DURATION = 120.0


def _small(plant: str, seeds: int = 2) -> bench.Benchmark:
    """A shipped benchmark with a quick size of ``DURATION`` s and ``seeds`` seeds."""
    loaded = bench.load_benchmark(bench.shipped_spec(plant))
    size = bench.Size(duration=DURATION, seeds=seeds, outage_start=60.0)
    return bench.Benchmark(loaded.spec.model_copy(update={"quick": size}), loaded.name, loaded.source, loaded.text, loaded.base)


def _kept(campaign, signals: list[str], condition: int) -> dict[str, np.ndarray]:
    """The campaign's runs at ``condition`` with ``signals`` kept at every record."""
    document = campaign.document()
    document["trajectories"] = {"signals": signals, "every": 1}
    kept = campaign_from_document(document, "<test>")
    result = compute_chunk(kept.canonical(), condition, kept.seeds)
    return {name: result[f"trajectory__{name}"] for name in signals}


def test_the_passive_observers_runs_are_its_reproductions_runs():
    """The DP benchmark's baseline is Fossen & Strand's case: the passive observer with
    the paper's gains, tuned to the same sea, on the same seeds, gives the reproduction's
    estimates bit for bit."""
    from lookout.papers import REPRODUCTIONS
    from lookout.sim import keys_of_seeds, simulate_batch

    benchmark = _small("dp-vessel")
    campaign = bench.observer_campaign(benchmark, "quick", "passive").campaign
    signals = ["position", "position_hat", "bias_force_hat", "wave_position_hat", "velocity_hat", "measured_position"]
    ours = _kept(campaign, signals, 0)
    reproduction = REPRODUCTIONS["fossen-strand-1999"]
    scenario = compose(reproduction.composition(reproduction.Config(duration=DURATION), "paper")).scenario
    theirs = simulate_batch(scenario, keys_of_seeds(list(campaign.seeds))).to_xarray()
    for name in signals:
        np.testing.assert_array_equal(ours[name], theirs[name].values, err_msg=name)


def test_every_observer_sees_the_same_measurements_bit_for_bit():
    benchmark = _small("dp-vessel")
    signals = ["measured_position", "measured_heading", "position"]
    lost = [c.name for c in benchmark.spec.conditions].index("50 % lost fixes")
    runs = {name: _kept(bench.observer_campaign(benchmark, "quick", name).campaign, signals, lost) for name in ("passive", "adaptive-dp", "ekf")}
    assert np.isnan(runs["passive"]["measured_position"]).any()  # the condition drops fixes
    for name in ("adaptive-dp", "ekf"):
        for signal in signals:
            np.testing.assert_array_equal(runs[name][signal], runs["passive"][signal], err_msg=f"{name} {signal}")


def test_a_model_error_reaches_the_plant_and_not_the_observers_model():
    benchmark = _small("dp-vessel")
    heavy = [c.name for c in benchmark.spec.conditions].index("mass +25 %")
    rough = [c.name for c in benchmark.spec.conditions].index("rough sea")
    for name, model in (("passive", lambda o: o.mass_matrix), ("ekf", lambda o: o.model.vessel.mass_matrix)):
        campaign = bench.observer_campaign(benchmark, "quick", name).campaign
        nominal = campaign.point_spec(0).build()
        error = campaign.point_spec(heavy).build()
        np.testing.assert_array_equal(np.asarray(error.plant.vessel.mass_matrix), 1.25 * np.asarray(nominal.plant.vessel.mass_matrix))
        np.testing.assert_array_equal(np.asarray(model(error.observer)), np.asarray(model(nominal.observer)))
        # a change of the sea is told: the observer's model follows it
        sea = campaign.point_spec(rough).build()
        if name == "ekf":
            np.testing.assert_array_equal(np.asarray(sea.observer.model.waves.peak_frequency), np.asarray(sea.plant.waves.peak_frequency))
        else:
            assert not np.allclose(np.asarray(sea.observer.wave_frequency), np.asarray(nominal.observer.wave_frequency))


def test_a_derived_model_cannot_be_pinned_and_the_spec_says_so():
    """The passive observer on Cybership II takes a DP-vessel form the plant derives from
    its ship: a model error needs the observer's own vessel table."""
    benchmark = _small("cybership-ii")
    observers = copy.deepcopy(benchmark.spec.observers)
    observers["passive"].pop("vessel")
    changed = bench.Benchmark(benchmark.spec.model_copy(update={"observers": observers}), benchmark.name, benchmark.source, benchmark.text, benchmark.base)
    with pytest.raises(Exception, match=r"conditions\[6\].*mass \+25 %: observer.vessel: the observer takes its vessel from plant cybership-ii, which derives it"):
        bench.observer_campaign(changed, "quick", "passive")


TINY = """
title = "tiny: two observers on the DP vessel"
scenario = {{ preset = "fossen-strand-1999:paper" }}
metrics = ["rms_error:position", "rms_error:bias_force", "settling_time:position", "outage_drift:position", "recovery_time:position"]
divergence = {{ signal = "position", limit = 100.0 }}
outage_signals = ["measured_position"]

[full]
duration = 200.0
seeds = 2
outage_start = 100.0

[quick]
duration = 100.0
seeds = 2
outage_start = 60.0

[observers.passive]
kind = "passive"

[observers.adaptive-dp]
kind = "adaptive-dp"
position_gain = [0.3, 0.3, 0.3]
velocity_gain = [0.001, 0.001, 0.001]
adaptation_gain = 1000.0
{extra}
[observers.adaptive-dp.parametrization]
kind = "inertia-entries"
unknowns = ["m11"]
lower = [2656100.0]
upper = [10624400.0]

[[conditions]]
name = "baseline"

[[conditions]]
name = "outage"
changes = {{ "sensor.outage_duration" = 20.0 }}

[[conditions]]
name = "mass +25 %"
truth_only = {{ "plant.vessel.mass_scale" = 1.25 }}
"""


def test_the_command_writes_tables_figures_and_reports(tmp_path, capsys):
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY.format(extra=""))
    out = tmp_path / "out"
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(out), "--quick", "--workers", "0"]) == 0
    folder = out / "tiny"
    for name in ("benchmark.nc", "table.md", "table.csv", "report.html", "summary.json", "figures/cost.png", "figures/rms_error__position.png",
                 "figures/outage.png", "reports/passive.html", "passive.zarr", "adaptive-dp.zarr"):
        assert (folder / name).exists(), name
    table = (folder / "table.md").read_text()
    assert "| adaptive-dp |" in table and "| observer | baseline | outage | mass +25 % |" in table
    assert "rms error of bias force" in table and "| adaptive-dp | — | — | — |" in table  # it estimates no bias
    import xarray as xr

    with xr.open_dataset(folder / "benchmark.nc") as ds:
        assert ds.rms_error__position.dims == ("observer", "condition", "seed") and ds.sizes["seed"] == 2
        assert np.isfinite(ds.cost.values).all() and (ds.cost.values > 0).all()
        outage = np.isfinite(ds.outage_drift__position.values).any(axis=(0, 2))
        assert outage.tolist() == [False, True, False]  # only the condition with an outage has one
    assert json.loads((folder / "summary.json").read_text())["cost_us"].keys() == {"passive", "adaptive-dp"}
    # a second call resumes the stores (nothing to compute) and gives the same numbers (the costs are timed again)
    before = [{k: v for k, v in row.items() if k != "cost_us"} for row in csv.DictReader(open(folder / "table.csv"))]
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(out), "--quick", "--workers", "0"]) == 0
    assert [{k: v for k, v in row.items() if k != "cost_us"} for row in csv.DictReader(open(folder / "table.csv"))] == before
    # the full size's stores would replace the quick ones: refused, naming the store
    capsys.readouterr()
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(out), "--workers", "0"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("error: --out: ") and "passive.zarr holds observer passive's benchmark with other settings (outage_start: 60.0 -> 100.0; duration: 100.0 -> 200.0)" in error and "\n" not in error, error


@pytest.mark.parametrize(
    "arguments, extra, message",
    [
        (["--plant", "submarine"], "", "--plant: no benchmark for 'submarine' (one of cybership-ii, dp-vessel, manipulator"),
        (["--plant", "dp-vessel", "--spec", "x.toml"], "", "give --plant (a shipped benchmark) or --spec (your own), not both"),
        (["--workers", "-1"], "", "--workers must be 0"),
        (["--spec", "missing.toml"], "", "--spec: no file missing.toml"),
        ([], "[observers.ekf]\nkind = \"ekf\"\nmeasurement_noise = [0.0, 1.0, 1.0]\n", "observers.ekf.measurement_noise"),
        ([], "[observers.nope]\nkind = \"kalman\"\n", "observers.nope.kind"),
        ([], "initial_theta = [1.0, 2.0]\n", "observers.adaptive-dp"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, arguments, extra, message):
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY.format(extra=extra))
    out = tmp_path / "out"
    given = arguments if any(a in ("--plant", "--spec") for a in arguments) else ["--spec", str(spec)] + arguments
    assert main(["benchmark", "observers", "--out", str(out), "--quick", *given]) == 2
    error = capsys.readouterr().err.strip()
    assert message in error and "\n" not in error, error
    assert not out.exists()


def test_the_shipped_specs_run_every_observer_that_fits_their_plant():
    """Each shipped spec names every registered observer that runs on its plant in the
    composition matrix (docs/architecture.md), except those that need another sensor."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "architecture.md").read_text()
    matrix = text.split("<!-- composition matrix: begin -->")[1].split("<!-- composition matrix: end -->")[0].strip().splitlines()
    header, rows = matrix[0], {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]] for line in matrix[2:] if line.startswith("| ")}
    plants = [c.strip() for c in header.split("|")[2:-1]]
    needs_another_sensor = {"parameter-estimator"}  # joint rates: not an encoder's
    for plant in bench.shipped_plants():
        spec = bench.load_benchmark(bench.shipped_spec(plant)).spec
        kinds = {table["kind"] for table in spec.observers.values()}
        fits = {observer for observer, cells in rows.items() if cells[plants.index(plant)] == "runs"} - needs_another_sensor
        assert fits <= kinds, (plant, fits - kinds)


def test_a_misspelled_metric_is_refused_not_left_out(tmp_path, capsys):
    """An observer that does not estimate a plant variable is not measured on it; a
    metric that is no metric of the plant is an error, not a silently empty column."""
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY.format(extra="").replace('"rms_error:bias_force"', '"rms_error:bias_forse"'))
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(tmp_path / "out"), "--quick"]) == 2
    error = capsys.readouterr().err.strip()
    assert "metrics" in error and "bias_forse" in error and "\n" not in error, error


def test_a_bad_condition_is_refused_at_the_condition(tmp_path, capsys):
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY.format(extra="").replace('"sensor.outage_duration" = 20.0', '"sensor.outage_duraton" = 20.0'))
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(tmp_path / "out"), "--quick"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.endswith("conditions[1]: outage (observer passive): the scenario has no setting 'sensor.outage_duraton'"), error


def test_an_outage_that_outlasts_the_run_is_refused(tmp_path, capsys):
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY.format(extra="").replace('"sensor.outage_duration" = 20.0', '"sensor.outage_duration" = 50.0'))
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(tmp_path / "out"), "--quick"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.endswith("conditions[1]: outage: the outage ends at 110 s, not before the quick run does (100 s): the recovery after it "
                          "cannot be measured; start it earlier (quick.outage_start)"), error
    assert not (tmp_path / "out").exists()
