"""The observer benchmark (lookout.studies.benchmark): its runs are the reproductions'
runs, every observer sees the same measurements bit for bit, a model error reaches the
plant alone, and the command writes its tables, figures and report or refuses bad input
in one line."""

from __future__ import annotations

import copy
import csv
import html
import json
from pathlib import Path

import numpy as np
import pytest
from xla_emitters import ran_with_fusion_emitters

from lookout.cli import main
from lookout.scenario.composition import compose
from lookout.studies import benchmark as bench
from lookout.studies.campaign import campaign_from_document, compute_chunk

pytestmark = pytest.mark.xdist_group("benchmark")

DURATION = 120.0


def _small(plant: str, seeds: int = 2) -> bench.Benchmark:
    """A shipped benchmark with a quick size of ``DURATION`` s and ``seeds`` seeds."""
    loaded = bench.load_benchmark(bench.shipped_spec(plant))
    size = bench.Size(duration=DURATION, seeds=seeds, outage_start=40.0)
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


def test_every_observer_sees_the_same_measurements_bit_for_bit(request):
    if ran_with_fusion_emitters(request.node.nodeid):  # the claim is about XLA's default programs
        return
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
    changed = bench.Benchmark(
        benchmark.spec.model_copy(update={"observers": observers}), benchmark.name, benchmark.source, benchmark.text, benchmark.base
    )
    with pytest.raises(
        Exception,
        match=r"conditions\[6\].*mass \+25 % \(observer passive\): observer.vessel: the observer takes its vessel from plant cybership-ii, which derives it",
    ):
        bench.observer_campaign(changed, "quick", "passive")


TINY = """
title = "tiny: two observers on the DP vessel"
scenario = {{ preset = "fossen-strand-1999:paper" }}
metrics = ["rms_error:position", "rms_error:bias_force", "settling_time:position", "outage_drift:position", "recovery_time:position",
           "rms_tracking:position"]
divergence = {{ signal = "position", limit = 100.0 }}
outage_signals = ["measured_position"]

[full]
duration = 200.0
seeds = 4
outage_start = 100.0

[quick]
duration = 100.0
seeds = 4
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

# a closed loop: the controller and a reference replaced as whole tables; Kim's observer
# backstepping needs a wave-filtering observer (the passive one), the adaptive observer is
# not one and is not run here
[[conditions]]
name = "closed loop"
[conditions.changes.controller]
kind = "observer-backstepping"
integral_gain = 0.01
position_gain = 0.1
velocity_gain = 0.1
coupling_gain = 0.01
damping_weights = [0.001, 0.001, 0.001, 0.01, 0.01, 0.01]
[conditions.changes.reference]
kind = "reference-filter"
signals = ["position", "heading"]
bandwidth = 0.05
schedule_times = [0.0, 30.0]
setpoints = [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]]
"""


def _tiny(tmp_path, extra: str = "", edit=None) -> Path:
    text = TINY.format(extra=extra)
    spec = tmp_path / "tiny.toml"
    spec.write_text(edit(text) if edit else text)
    return spec


def test_the_command_writes_tables_figures_reports_and_which_observer_to_pick(tmp_path, capsys):
    """A quick real run: the tables, figures and reports; the closed-loop condition as a
    campaign of its own (with the tracking metric, the observer that cannot drive the
    loop skipped in one line); the recommendation printed, and the same lines in
    table.md, report.html and summary.json, computed from the stored metrics by the rule
    (checked against an independent implementation of it); a resumed run gives the same
    numbers; the full size's stores are refused over the quick ones."""
    import xarray as xr

    from lookout.studies import benchmark_report

    spec = _tiny(tmp_path)
    out = tmp_path / "out"
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(out), "--quick", "--workers", "0"]) == 0
    printed = capsys.readouterr().out
    folder = out / "tiny"
    for name in (
        "benchmark.nc",
        "table.md",
        "table.csv",
        "report.html",
        "summary.json",
        "figures/cost.png",
        "figures/rms_error__position.png",
        "figures/rms_tracking__position.png",
        "figures/outage.png",
        "reports/passive.html",
        "reports/passive.closed-loop.html",
        "passive.zarr",
        "passive.closed-loop.zarr",
        "adaptive-dp.zarr",
    ):
        assert (folder / name).exists(), name
    assert not (folder / "adaptive-dp.closed-loop.zarr").exists()
    assert (
        "  adaptive-dp not run at 'closed loop': controller: controller observer-backstepping needs an observer that is a WaveFilteringObserver"
        in printed
    )
    table = (folder / "table.md").read_text()
    assert "| adaptive-dp |" in table and "| observer | baseline | outage | mass +25 % | closed loop |" in table
    assert "rms error of bias force" in table and "| adaptive-dp | — | — | — | — |" in table  # it estimates no bias
    assert "| passive | — | — | — | " in table.split("rms tracking of position")[1]  # tracked only where the loop is closed
    with xr.open_dataset(folder / "benchmark.nc") as ds:
        ds = ds.load()
    assert ds.rms_error__position.dims == ("observer", "condition", "seed") and ds.sizes["seed"] == 4
    assert np.isfinite(ds.cost.values).all() and (ds.cost.values > 0).all()
    outage = np.isfinite(ds.outage_drift__position.values).any(axis=(0, 2))
    assert outage.tolist() == [False, True, False, False]  # only the condition with an outage has one
    assert np.isfinite(ds.rms_tracking__position.values[0, 3]).all() and np.isnan(ds.rms_tracking__position.values[:, :3]).all()
    assert np.isnan(ds.diverged.values[1, 3]).all()  # adaptive-dp: not run in the closed loop
    recommendations = benchmark_report.recommend(ds)
    assert [r.condition for r in recommendations] == ["baseline", "outage", "mass +25 %", "closed loop"]
    assert (
        recommendations[3].metric == "rms_tracking__position"
        and recommendations[3].observer == "passive"
        and recommendations[0].metric == "rms_error__position"
    )
    for recommendation in recommendations:
        _check_against_the_rule(ds, recommendation)
        assert f"  {recommendation.text()}\n" in printed and f"- {recommendation.text()}\n" in table
        assert html.escape(recommendation.text()) in (folder / "report.html").read_text()
    assert [r["text"] for r in json.loads((folder / "summary.json").read_text())["recommendations"]] == [r.text() for r in recommendations]
    assert json.loads((folder / "summary.json").read_text())["cost_us"].keys() == {"passive", "adaptive-dp"}
    # a second call resumes the stores (nothing to compute) and gives the same numbers (the costs are timed again)
    before = [{k: v for k, v in row.items() if k != "cost_us"} for row in csv.DictReader(open(folder / "table.csv"))]
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(out), "--quick", "--workers", "0"]) == 0
    assert [{k: v for k, v in row.items() if k != "cost_us"} for row in csv.DictReader(open(folder / "table.csv"))] == before
    # the full size's stores would replace the quick ones: refused, naming the store
    capsys.readouterr()
    assert main(["benchmark", "observers", "--spec", str(spec), "--out", str(out), "--workers", "0"]) == 2
    error = capsys.readouterr().err.strip()
    assert (
        error.startswith("error: --out: ")
        and "passive.zarr holds observer passive's benchmark with other settings (outage_start: 60.0 -> 100.0; duration: 100.0 -> 200.0)" in error
        and "\n" not in error
    ), error


# ------------------------------------------------------------------ which observer to pick


def _sign_test_p(wins: int, n: int) -> float:
    """P(Binomial(n, 1/2) >= wins), by SciPy (the reference of the rule's sign test)."""
    from scipy import stats

    return float(stats.binomtest(wins, n, 0.5, alternative="greater").pvalue)


def _check_against_the_rule(ds, recommendation) -> None:
    """The recommendation at its condition, checked against the rule written out again
    (docs/choosing-an-observer.md) with SciPy's binomial test."""
    from lookout.studies import benchmark_report as report

    j = [str(c) for c in ds.condition.values].index(recommendation.condition)
    observers = [str(o) for o in ds.observer.values]
    diverged = ds.diverged.values[:, j]
    candidates = [i for i in range(len(observers)) if np.isfinite(diverged[i]).any() and not (diverged[i][np.isfinite(diverged[i])] > 0.5).any()]
    values = ds[recommendation.metric].values[:, j]
    medians = {i: np.median(values[i][np.isfinite(values[i])]) for i in candidates if np.isfinite(values[i]).any()}
    ranking = sorted(medians, key=lambda i: (medians[i], observers[i]))
    best = ranking[0]

    def clearly_worse(i):
        both = np.isfinite(values[best]) & np.isfinite(values[i])
        wins = int(np.sum(values[best][both] < values[i][both]))
        return medians[i] > (1 + report.MARGIN) * medians[best] and _sign_test_p(wins, int(both.sum())) <= report.SIGN_LEVEL

    if recommendation.provisional:
        assert observers[best] == recommendation.observer
        return
    worse = [i for i in ranking[1:] if clearly_worse(i)]
    group = ranking[: ranking.index(worse[0])] if worse else ranking
    lowest = min(ds.cost.values[i] for i in group)
    cheapest = min(group, key=lambda i: (ds.cost.values[i] > (1 + report.COST_TIE) * lowest, medians[i]))
    assert recommendation.observer == observers[cheapest], (recommendation, [observers[i] for i in group])
    assert recommendation.next == (observers[worse[0]] if worse else None)
    assert sorted(recommendation.tied) == sorted(observers[i] for i in group if i != cheapest)
    assert recommendation.value == pytest.approx(medians[cheapest], rel=1e-12)
    if worse:
        assert recommendation.ratio == pytest.approx(medians[worse[0]] / medians[cheapest], rel=1e-12) and recommendation.ratio >= 1.0


def _table(columns: dict[str, dict[str, np.ndarray]], costs: dict[str, float], diverged: dict | None = None, tracking: dict | None = None):
    """A benchmark Dataset as :func:`benchmark_report.collect` makes it: ``columns``
    condition -> observer -> RMS position error per seed (NaN: not run there)."""
    import xarray as xr

    conditions, observers = list(columns), list(costs)
    seeds = len(next(iter(next(iter(columns.values())).values())))
    error = np.full((len(observers), len(conditions), seeds), np.nan)
    flags = np.full_like(error, np.nan)
    for j, condition in enumerate(conditions):
        for i, observer in enumerate(observers):
            if observer in columns[condition]:
                error[i, j] = columns[condition][observer]
                flags[i, j] = 0.0
    for (observer, condition), seeds_diverged in (diverged or {}).items():
        i, j = observers.index(observer), conditions.index(condition)
        flags[i, j, seeds_diverged] = 1.0
        error[i, j, seeds_diverged] = np.nan
    data = {"rms_error__position": (("observer", "condition", "seed"), error, {"units": "m"})}
    if tracking is not None:
        values = np.full_like(error, np.nan)
        for (observer, condition), row in tracking.items():
            values[observers.index(observer), conditions.index(condition)] = row
        data["rms_tracking__position"] = (("observer", "condition", "seed"), values, {"units": "m"})
    data["diverged"] = (("observer", "condition", "seed"), flags, {})
    data["cost"] = (("observer",), np.asarray([costs[o] for o in observers]), {"units": "us"})
    metrics = ["rms_error:position"] + (["rms_tracking:position"] if tracking is not None else [])
    from lookout.studies.benchmark_report import lead_metrics

    return xr.Dataset(
        data,
        coords={"observer": observers, "condition": conditions, "seed": np.arange(seeds)},
        attrs={"recommend_by": json.dumps(lead_metrics(metrics)), "skipped": "[]"},
    )


def test_the_recommendation_of_a_table_whose_answer_is_known():
    """Each clause of the rule on a table built for it: a clear winner and by how much;
    a tie within the margin broken by cost; a lower median that the seeds do not confirm
    (a tie); a diverged observer not considered; too few seeds; an observer not run; a
    closed loop led by its tracking error."""
    from lookout.studies.benchmark_report import recommend

    rng = np.random.default_rng(0)
    sea = rng.lognormal(0.0, 0.3, 16)  # the seeds' seas: every observer sees the same
    halves = np.where(np.arange(16) % 2 == 0, 0.7, 1.02)
    costs = {"ekf": 18.4, "ukf": 18.5, "passive": 0.13, "adaptive-dp": 0.07}
    columns = {
        "rough sea": {"ekf": 0.4 * sea, "ukf": 0.4004 * sea, "passive": 0.75 * sea, "adaptive-dp": 0.1 * sea},
        "calm sea": {"ekf": 0.30 * sea, "ukf": 0.30 * sea, "passive": 0.306 * sea, "adaptive-dp": 2.0 * sea},
        "coin flip": {"ekf": 0.5 * halves, "passive": 0.5 * np.ones(16), "adaptive-dp": 3.0 * np.ones(16)},
        "ekf alone": {"ekf": 0.2 * sea},
    }
    ds = _table(columns, costs, diverged={("adaptive-dp", "rough sea"): [3, 7]})
    rough, calm, flip, alone = recommend(ds)
    # the EKF and the UKF tie (0.1 % apart) at the same cost (within 10 %): the lower median, the EKF; the passive observer is
    # 1.875 times worse on every seed
    assert (rough.observer, rough.tied, rough.next) == ("ekf", ("ukf",), "passive")
    assert rough.ratio == pytest.approx(0.75 / 0.4) and rough.value == pytest.approx(0.4 * np.median(sea))
    assert rough.excluded == ("adaptive-dp (2 of 16 runs diverged)",)  # the lowest values, but it diverged
    assert rough.text() == (
        f"rough sea: ekf (tied with ukf; as cheap (within 10%), the lower median), RMS position error {rough.value:.3g} m, "
        "1.9x better than passive (next), "
        "at 18.4 us per sample against 0.13 us; not considered: adaptive-dp (2 of 16 runs diverged)"
    )
    # the passive observer is 2 % worse on every seed: within the margin, a tie, and the cheapest of the three
    assert (calm.observer, set(calm.tied), calm.next) == ("passive", {"ekf", "ukf"}, "adaptive-dp")
    # the EKF's median is 14 % lower, but it is lower on 8 seeds of 16 only: a tie, and the cheaper wins
    assert (flip.observer, flip.tied, flip.next) == ("passive", ("ekf",), "adaptive-dp")
    assert alone.observer == "ekf" and alone.next is None and alone.text().endswith("(the only observer measured)")
    for recommendation in (rough, calm, flip, alone):
        _check_against_the_rule(ds, recommendation)

    # four seeds separate when the best wins all four; three never do (provisional: the lowest median)
    four = recommend(
        _table({"c": {"ekf": np.array([1.0, 1.1, 0.9, 1.2]), "passive": np.array([1.5, 1.6, 1.4, 1.7])}}, {"ekf": 10.0, "passive": 1.0})
    )[0]
    assert (four.observer, four.next, four.provisional) == ("ekf", "passive", False)
    three = recommend(_table({"c": {"ekf": np.array([1.0, 1.1, 0.9]), "passive": np.array([1.5, 1.6, 1.4])}}, {"ekf": 10.0, "passive": 1.0}))[0]
    assert (three.observer, three.next, three.provisional) == ("ekf", "passive", True)
    assert "provisional: 3 seeds cannot separate observers (a sign test at 10% needs 4)" in three.text()

    # a closed loop is led by its tracking error, the open-loop conditions by the estimation error
    ds = _table(
        {"open": {"ekf": 0.2 * sea, "passive": 0.5 * sea}, "closed": {"ekf": 0.2 * sea, "passive": 0.5 * sea}},
        {"ekf": 18.0, "passive": 0.1},
        tracking={("ekf", "closed"): 3.0 * sea, ("passive", "closed"): 1.0 * sea},
    )
    open_loop, closed = recommend(ds)
    assert (open_loop.metric, open_loop.observer) == ("rms_error__position", "ekf")
    assert (closed.metric, closed.observer, closed.label) == ("rms_tracking__position", "passive", "RMS position tracking error")


def test_the_recommendation_follows_the_rule_on_random_tables():
    """Property: on random tables (random medians, spreads, seeds, costs, divergences), the
    recommendation is what the rule written out again with SciPy's binomial test gives."""
    from lookout.studies.benchmark_report import recommend

    rng = np.random.default_rng(7)
    for _ in range(60):
        seeds = int(rng.integers(2, 20))
        observers = [f"o{i}" for i in range(int(rng.integers(1, 6)))]
        common = rng.lognormal(0.0, 0.5, seeds)
        columns = {
            f"c{j}": {
                o: rng.lognormal(rng.normal(0.0, 0.3), 0.1, 1) * common * rng.lognormal(0.0, rng.uniform(0.0, 0.5), seeds)
                for o in observers
                if rng.random() > 0.1
            }
            for j in range(3)
        }
        columns = {c: v for c, v in columns.items() if v} or {"c0": {observers[0]: common}}
        costs = {o: float(rng.choice([0.1, 1.0, 10.0])) for o in observers}
        diverged = {(o, c): [int(rng.integers(0, seeds))] for c in columns for o in columns[c] if rng.random() < 0.15}
        ds = _table(columns, costs, diverged)
        for recommendation in recommend(ds):
            if recommendation.observer is not None:
                _check_against_the_rule(ds, recommendation)


def test_the_sign_test_matches_scipy():
    from lookout.studies.benchmark_report import SIGN_LEVEL, sign_test_wins

    for n in range(1, 41):
        k = sign_test_wins(n)
        if k is None:
            assert _sign_test_p(n, n) > SIGN_LEVEL, n
        else:
            assert _sign_test_p(k, n) <= SIGN_LEVEL < _sign_test_p(k - 1, n), n
    assert (sign_test_wins(3), sign_test_wins(4), sign_test_wins(16)) == (None, 4, 12)


# ------------------------------------------------------------------ a scenario file as the spec


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_every_example_is_read_as_what_it_is():
    """A scenario file given to --spec is a scenario file (never "title: missing key"), a
    campaign spec is named as one, and a file that mixes a spec's keys with a scenario's
    tables is refused saying so."""
    import tomllib

    forms = {path.name: bench.file_form(tomllib.loads(path.read_text())) for path in sorted(EXAMPLES.glob("*.toml"))}
    assert {name for name, form in forms.items() if form == "campaign"} == {"dp-study.toml", "kim-model-error.toml", "own-vessel-study.toml"}
    assert all(form == "scenario" for name, form in forms.items() if name not in {"dp-study.toml", "kim-model-error.toml", "own-vessel-study.toml"})
    for name in ("dp-study.toml",):
        with pytest.raises(
            bench.FileError,
            match=rf"{name}: is a campaign spec \(.*\): run it with lookout campaign run .*{name}; --spec takes a benchmark spec or a scenario file",
        ):
            bench.load_benchmark(EXAMPLES / name)
    with pytest.raises(
        ValueError, match=r"mixes a benchmark spec's keys \(title\) with a scenario's tables \(plant\): put the scenario under \[scenario\]"
    ):
        bench.file_form({"title": "x", "plant": {"kind": "dp-vessel"}})


def test_a_scenario_file_is_benchmarked_with_every_observer_that_composes_on_it():
    """examples/sliding-mode-own-vessel.toml: a 60 m vessel of its own, Kim's loop. Its
    plant, sensor and sea; every registered observer kind that composes (those that do
    not are skipped, one line each, saying why); its own observer as given; the shipped
    DP conditions; its loop as a condition of its own, where the observers that cannot
    drive Kim's controller are skipped; runs open loop otherwise."""
    import tomllib

    from lookout.scenario import registry

    benchmark = bench.load_benchmark(EXAMPLES / "sliding-mode-own-vessel.toml")
    spec = benchmark.spec
    file = tomllib.loads((EXAMPLES / "sliding-mode-own-vessel.toml").read_text())
    assert list(spec.observers) == ["sliding-mode-as-given", "passive", "sliding-mode", "earth-fixed", "adaptive-dp", "ekf", "ukf", "model-free"]
    assert spec.observers["sliding-mode-as-given"] == file["observer"]
    # another vessel than the shipped one: the shipped tables' gains are not taken, the design rules make them
    assert spec.observers["passive"] == {"kind": "passive", "design": "fossen-strand-1999"}
    assert spec.observers["earth-fixed"] == {"kind": "earth-fixed", "position_gain": 0.4, "velocity_gain": 0.04, "ship": {"kind": "dp-vessel"}}
    skipped = [note for note in benchmark.notes if note.startswith("skipped ")]
    assert {note.split(":")[0] for note in skipped} == {f"skipped {k.name}" for k in registry.kinds("observer")} - {
        f"skipped {n}" for n in spec.observers
    }
    assert all("\n" not in note and len(note) < 300 for note in benchmark.notes)
    assert benchmark.base["plant"] == file["plant"] and benchmark.base["sensor"] == file["sensor"]
    assert benchmark.base["controller"]["kind"] == "sinusoidal" and benchmark.base["reference"] == {"kind": "none"}  # open loop
    shipped = bench.load_benchmark(bench.shipped_spec("dp-vessel")).spec
    assert [c.name for c in spec.conditions] == [c.name for c in shipped.conditions] + ["closed loop (observer-backstepping)"]
    assert spec.conditions[-1].changes == {"controller": file["controller"], "reference": file["reference"]}
    assert "rms_tracking:position" in spec.metrics and spec.full == shipped.full
    planned = bench.plan(benchmark, "quick", ["sliding-mode-as-given", "passive", "ekf"])
    runs = {(each.name, condition) for each in planned.campaigns for condition in each.conditions}
    loop = "closed loop (observer-backstepping)"
    assert {name for name, condition in runs if condition == loop} == {"sliding-mode-as-given", "passive"}
    assert {name for name, condition in runs if condition == "baseline"} == {"sliding-mode-as-given", "passive", "ekf"}
    assert planned.skipped == [
        f"ekf not run at '{loop}': controller: controller observer-backstepping needs an observer that is a "
        "WaveFilteringObserver; observer ekf is not one"
    ]
    assert {each.store for each in planned.campaigns if each.conditions == (loop,)} == {
        "passive.closed-loop-observer-backstepping",
        "sliding-mode-as-given.closed-loop-observer-backstepping",
    }


def test_a_scenario_files_model_errors_are_relative_to_its_own_model():
    """examples/kim-closed-loop.toml has a vessel 20 % heavier than the Northern Clipper
    with 50 % more damping: "mass +25 %" is 25 % on its own mass."""
    spec = bench.load_benchmark(EXAMPLES / "kim-closed-loop.toml").spec
    errors = {c.name: c.truth_only for c in spec.conditions if c.truth_only}
    assert errors == {
        "mass +25 %": {"plant.vessel.mass_scale": 1.5},
        "mass -25 %": {"plant.vessel.mass_scale": 0.9},
        "damping +25 %": {"plant.vessel.damping_scale": 1.875},
        "damping -25 %": {"plant.vessel.damping_scale": 1.125},
    }


FURUTA = """
# the Furuta pendulum of Calugi (2002), swinging free (no input), 100 samples
preset = "calugi-2002-furuta:I"
[simulation]
duration = 0.75
[controller]
kind = "none"
"""


def test_a_scenario_file_of_a_plant_without_a_shipped_benchmark_runs_generic_conditions(tmp_path, capsys):
    """The command on a scenario file whose plant kind has no shipped benchmark: generic
    conditions (lost samples, an outage inside the run, ±25 % on the model's friction),
    its observer as given and the velocity observer; the skipped observers said in one
    line each; the recommendation printed and written, led by the error both observers
    have."""
    scenario = tmp_path / "furuta.toml"
    scenario.write_text(FURUTA)
    benchmark = bench.load_benchmark(scenario)
    assert [c.name for c in benchmark.spec.conditions] == [
        "baseline",
        "10 % lost samples",
        "50 % lost samples",
        "0.03 s joint angle outage",
        "coulomb friction +25 %",
        "coulomb friction -25 %",
    ]
    assert list(benchmark.spec.observers) == ["adaptive-manipulator-as-given", "velocity"]
    assert 0 < benchmark.spec.quick.outage_start and benchmark.spec.quick.outage_start + 0.03 < benchmark.spec.quick.duration
    out = tmp_path / "out"
    assert main(["benchmark", "observers", "--spec", str(scenario), "--out", str(out), "--quick", "--workers", "0"]) == 0
    printed = capsys.readouterr().out
    assert "  skipped ekf: observer: observer ekf: measurement_noise: the sensor's own noise is zero" in printed
    table = (out / "furuta" / "table.md").read_text()
    assert "| observer | baseline | 10 % lost samples |" in table and "| adaptive-manipulator-as-given |" in table and "| velocity |" in table
    recommendations = table.split("#### Which observer")[1].split("over 6 conditions")[0].strip().splitlines()
    assert len(recommendations) == 6 and all("RMS joint rate error" in line for line in recommendations)  # the one both observers estimate


# ------------------------------------------------------------------ refusals: one line, exit 2, nothing left behind


def _replace(old: str, new: str):
    def edit(text: str) -> str:
        assert old in text, old
        return text.replace(old, new)

    return edit


@pytest.mark.parametrize(
    "arguments, extra, edit, message",
    [
        # options
        (["--plant", "submarine"], "", None, "--plant: no benchmark for 'submarine' (one of cybership-ii, dp-vessel, manipulator"),
        (["--plant", "dp-vessel", "--spec", "x.toml"], "", None, "give --plant (a shipped benchmark) or --spec (your own), not both"),
        (["--workers", "-1"], "", None, "--workers must be 0"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], "", None, "give --workers or --scheduler, not both"),
        (["--scheduler", "localhost"], "", None, "--scheduler must be an address with a port"),
        (["--spec", "missing.toml"], "", None, "--spec: no file missing.toml"),
        (["--spec", ""], "", None, "--spec must name a file; got an empty path"),
        (["--spec", "{tmp}"], "", None, "is a folder, not a benchmark spec"),
        (["--out", "{tmp}/tiny.toml"], "", None, "--out must be a folder;"),
        (["--out", "{tmp}/tiny.toml/out"], "", None, "is a file, not a folder"),
        (["--out", ""], "", None, "--out must name a folder; got an empty path"),
        # the file
        ([], "", lambda text: text + "\n[[conditions\n", "not valid TOML"),
        ([], "", lambda text: text.replace('title = "tiny: two observers on the DP vessel"', ""), "title: missing key"),
        ([], "", lambda text: 'title = "x"\n[plant]\nkind = "dp-vessel"\n', "mixes a benchmark spec's keys (title) with a scenario's tables (plant)"),
        # spec keys
        ([], '[observers.ekf]\nkind = "ekf"\nmeasurement_noise = [0.0, 1.0, 1.0]\n', None, "observers.ekf.measurement_noise"),
        ([], '[observers.nope]\nkind = "kalman"\n', None, "observers.nope.kind"),
        ([], "initial_theta = [1.0, 2.0]\n", None, "observers.adaptive-dp"),
        ([], "", _replace('title = "tiny: two observers on the DP vessel"', 'title = " "'), "title (line 2): must not be empty"),
        ([], "", _replace("metrics = [", "seedx = 1\nmetrics = ["), "seedx (line 4): unknown key"),
        ([], "", _replace("metrics = [", "seed = -1\nmetrics = ["), "seed (line 4): must be an integer from 0 to"),
        ([], "", _replace("outage_start = 60.0", "outage_start = 150.0"), "quick.outage_start (line 17): must be in [0, duration = 100 s); got 150"),
        (
            [],
            "",
            _replace('outage_signals = ["measured_position"]', "outage_signals = []"),
            "full.outage_start (line 12): no outage starts: outage_signals names none",
        ),
        (
            [],
            "",
            _replace('changes = {{ "sensor.outage_duration" = 20.0 }}'.replace("{{", "{").replace("}}", "}"), ""),
            'outage_signals (line 7): no condition has an outage (changes with "sensor.outage_duration" > 0): the outage would measure nothing',
        ),
        (
            [],
            "",
            _replace('"sensor.outage_duration" = 20.0', '"sensor.outage_start" = 30.0'),
            "conditions[1]: outage: sets sensor.outage_start, but the condition has no outage",
        ),
        (
            [],
            "",
            _replace('"sensor.outage_duration" = 20.0', '"sensor.outage_duration" = 0.5, "sensor.outage_start" = 60.2'),
            "conditions[1]: outage: the outage of 0.5 s from 60.2 s silences no sample of a signal sampled every 1 s: it would measure nothing",
        ),
        (
            [],
            "",
            _replace('"sensor.outage_duration" = 20.0', '"sensor.outage_duration" = 50.0'),
            "conditions[1]: outage: the outage ends at 110 s, not before the quick run",
        ),
        (
            [],
            "",
            _replace("outage_start = 60.0", "outage_start = 60.0\nafter = 100.0"),
            "quick.after (line 18): must be in [0, duration = 100 s): the metrics need records after it; got 100",
        ),
        (
            [],
            "",
            _replace('"sensor.outage_duration" = 20.0', '"sensor.outage_duration" = 20.0, "simulation.seed" = 3'),
            "conditions[1].changes (line 39): 'simulation.seed': the benchmark sets it (the spec's seed); a condition cannot change it",
        ),
        (
            [],
            "",
            _replace('"plant.vessel.mass_scale" = 1.25', '"sensor.noise_std" = 1.0'),
            "'sensor.noise_std': a model error changes the plant (keys plant.*)",
        ),
        (
            [],
            "",
            _replace(
                'scenario = {{ preset = "fossen-strand-1999:paper" }}'.replace("{{", "{").replace("}}", "}"),
                'scenario = { preset = "fossen-strand-1999:paper", simulation = { duration = 50.0 } }',
            ),
            "scenario.simulation.duration (line 3): the benchmark sets it (full.duration and quick.duration); drop it here",
        ),
        (
            [],
            "",
            _replace(
                'scenario = {{ preset = "fossen-strand-1999:paper" }}'.replace("{{", "{").replace("}}", "}"),
                'scenario = { preset = "fossen-strand-1999:paper", observer = { kind = "ekf" } }',
            ),
            "scenario.observer (line 3): the benchmark sets it (the [observers.NAME] tables); drop it here",
        ),
        (
            [],
            "",
            _replace('scenario = {{ preset = "fossen-strand-1999:paper" }}'.replace("{{", "{").replace("}}", "}"), 'scenario = "nowhere.toml"'),
            "scenario (line 3): ",
        ),
        (
            [],
            "",
            _replace("metrics = [", 'recommend_by = ["rms_error:velocity"]\nmetrics = ['),
            "recommend_by (line 4): 'rms_error:velocity' is not one of the metrics",
        ),
        ([], "", _replace('"rms_tracking:position"]', '"rms_tracking:velocity"]'), "'rms_tracking:velocity' applies to no observer at any condition"),
        ([], "", _replace('"rms_error:bias_force"', '"rms_error:bias_forse"'), "'rms_error:bias_forse' applies to no observer at any condition"),
        (
            [],
            "",
            _replace('signal = "position", limit = 100.0', 'signal = "positon", limit = 100.0'),
            "divergence.signal (line 6): the plant has no variable 'positon' (it has position, heading,",
        ),
        ([], "", _replace('signal = "position", limit = 100.0', 'signal = "position", limit = -1.0'), "divergence.limit"),
        ([], "", _replace("seeds = 4\noutage_start = 60.0", "seeds = 0\noutage_start = 60.0"), "quick.seeds"),
        ([], "", _replace("duration = 100.0", "duration = -100.0"), "quick.duration"),
        (
            [],
            "",
            _replace('"sensor.outage_duration" = 20.0', '"sensor.outage_duration" = 20.0, "sensor.dropout_probabilty" = 0.1'),
            "conditions[1]: outage (observer passive): the scenario has no setting 'sensor.dropout_probabilty' (sensor has ",
        ),
        (
            [],
            "",
            _replace('kind = "observer-backstepping"', 'kind = "observer-backstepping"\nbogus = 1'),
            "conditions[3]: closed loop (observer passive): controller.bogus: unknown key",
        ),
        ([], "", _replace('name = "outage"', 'name = "baseline"'), "condition names repeat"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, arguments, extra, edit, message):
    spec = _tiny(tmp_path, extra, edit)
    out = tmp_path / "out"
    arguments = [a.replace("{tmp}", str(tmp_path)) for a in arguments]
    given = arguments if any(a in ("--plant", "--spec") for a in arguments) else ["--spec", str(spec)] + arguments
    given = given if "--out" in given else ["--out", str(out)] + given
    before = sorted(tmp_path.rglob("*"))
    assert main(["benchmark", "observers", "--quick", *given]) == 2
    error = capsys.readouterr().err.strip()
    assert message in error and "\n" not in error and error.startswith("error: "), error
    assert sorted(tmp_path.rglob("*")) == before  # nothing written, nothing created


def test_what_the_machine_cannot_hold_or_reach_is_refused_before_anything_is_written(tmp_path, capsys, monkeypatch):
    """A scheduler that does not answer, a disk too small for the stores, a worker's
    memory too small for a chunk: refused before the output folder exists."""
    from lookout import _resources
    from lookout.studies import execute

    spec = _tiny(tmp_path)
    out = tmp_path / "out"
    monkeypatch.setattr(execute, "SCHEDULER_TIMEOUT", "1s")
    cases = [
        (["--scheduler", "tcp://127.0.0.1:1"], {}, "--scheduler tcp://127.0.0.1:1: cannot reach the scheduler ("),
        (["--workers", "0"], {"free_disk": lambda path: 1000}, f"--out {out}: the benchmark's stores in {out} would need about"),
        (
            ["--workers", "0"],
            {"available_memory": lambda: 1000},
            "quick.seeds (line 16): (observer passive) 3 point(s) x 4 seeds in 3 chunks would need about",
        ),
        (["--workers", "0"], {"available_memory": lambda: 1e6}, "quick.seeds = 4: a chunk (the 4 runs of a condition, 100 s each) needs about"),
    ]
    for arguments, patches, message in cases:
        with monkeypatch.context() as patch:
            for name, value in patches.items():
                patch.setattr(_resources, name, value)
            assert main(["benchmark", "observers", "--quick", "--spec", str(spec), "--out", str(out), *arguments]) == 2
        error = capsys.readouterr().err.strip()
        assert message in error and "\n" not in error, error
        assert not out.exists()


def test_the_shipped_specs_run_every_observer_that_fits_their_plant():
    """Each shipped spec names every observer of lookout's own that runs on its plant in
    the composition matrix (docs/architecture.md; the example plugin's row is not
    lookout's), except those that need another sensor."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "architecture.md").read_text()
    matrix = text.split("<!-- composition matrix: begin -->")[1].split("<!-- composition matrix: end -->")[0].strip().splitlines()
    header, rows = matrix[0], {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]] for line in matrix[2:] if line.startswith("| ")}
    plants = [c.strip() for c in header.split("|")[2:-1]]
    # joint rates: not an encoder's; a suite with an IMU (lookout benchmark dead-reckoning has one)
    needs_another_sensor = {"parameter-estimator", "ins"}
    from lookout.scenario import registry

    own = {k.name for k in registry.kinds("observer") if k.module.startswith("lookout.")}
    rows = {observer: cells for observer, cells in rows.items() if observer in own}
    for plant in bench.shipped_plants():
        spec = bench.load_benchmark(bench.shipped_spec(plant)).spec
        kinds = {table["kind"] for table in spec.observers.values()}
        fits = {observer for observer, cells in rows.items() if cells[plants.index(plant)] == "runs"} - needs_another_sensor
        assert fits <= kinds, (plant, fits - kinds)
