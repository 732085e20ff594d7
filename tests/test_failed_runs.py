"""One notion of a failed run: a non-finite truth or estimate, or an estimation or
tracking error beyond the divergence limit (the plant kind's, or [simulation]
divergence), with the first record where it failed and why; lookout run exits 3."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from lookout._commandline import DIVERGED_EXIT_CODE
from lookout.cli import main
from lookout.scenario import metrics as metric_module
from lookout.scenario.composition import CompositionError, compose
from lookout.scenario.file import load
from lookout.sim import keys_of_seeds, simulate_batch

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _diverging_file(folder: Path, extra: str = "") -> Path:
    """The example Luenberger observer with 40 rad/s poles: RK4 at 0.1 s is unstable
    there (|lambda dt| = 4 > 2.8), so its estimate grows without bound."""
    shutil.copytree(EXAMPLES / "plugins", folder / "plugins", dirs_exist_ok=True)
    text = (EXAMPLES / "luenberger-dp.toml").read_text()
    text = text.replace("bandwidth = [0.05, 0.05, 0.05]", "bandwidth = [40.0, 40.0, 40.0]").replace("duration = 600.0", f"duration = 30.0\n{extra}")
    path = folder / "diverging.toml"
    path.write_text(text)
    return path


def _first_failure(ds: xr.Dataset, limit: float) -> int:
    """The first record whose position estimate is not finite or beyond ``limit`` m of the
    truth, computed here from the written NetCDF."""
    error = np.linalg.norm(ds.position_hat.values[0] - ds.position.values[0], axis=-1)
    bad = ~np.isfinite(error) | (error > limit)
    return int(np.argmax(bad)) if bad.any() else -1


@pytest.mark.slow
def test_a_diverging_observer_makes_lookout_run_exit_3_naming_the_first_record_and_why(tmp_path, capsys):
    path = _diverging_file(tmp_path)
    code = main(["run", str(path), "--out", str(tmp_path / "out")])
    out = capsys.readouterr()
    assert code == DIVERGED_EXIT_CODE
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == ["diverged"] and summary["divergence"] == {"signal": "position", "limit": 100.0}
    with xr.open_dataset(tmp_path / "out" / "run.nc") as ds:
        first = _first_failure(ds, 100.0)
        time = float(ds.time.values[first])
        assert list(ds.status.values) == ["diverged"] and str(ds.failure.values[0]).startswith(f"at t = {time:g} s (record {first})")
    failure = summary["failures"][0]
    assert first > 0 and failure["record"] == first and failure["time"] == pytest.approx(time)
    assert failure["cause"] == "the estimation error of position is beyond the divergence limit 100 m"
    assert f"diverged: run 0 (seed 0) at t = {time:g} s (record {first}): the estimation error of position" in out.err
    assert f"exit code {DIVERGED_EXIT_CODE}" in out.err and "0/1 runs finite" in out.out


@pytest.mark.slow
def test_the_files_divergence_limit_overrides_the_plant_kinds_and_a_bad_signal_is_refused_at_its_key(tmp_path):
    path = _diverging_file(tmp_path, 'divergence = { signal = "position", limit = 1.0e6 }')
    spec = load(path)
    assert spec.composition.divergence == ("position", 1.0e6)
    trajectory = simulate_batch(spec.build(), keys_of_seeds([0]))
    wide = metric_module.failures(trajectory, spec.composition.divergence)[0]
    narrow = metric_module.failures(trajectory, ("position", 100.0))[0]
    assert wide.record > narrow.record
    error = np.linalg.norm(np.asarray(trajectory.estimate["position"][0]) - np.asarray(trajectory.truth["position"][0]), axis=-1)
    assert error[wide.record] > 1.0e6 or not np.isfinite(error[wide.record])
    assert np.all(error[: wide.record] <= 1.0e6)
    document = dict(spec.composition.document)
    document["simulation"] = {**document["simulation"], "divergence": {"signal": "speed", "limit": 1.0}}
    with pytest.raises(CompositionError, match=r"^simulation\.divergence\.signal: must be a variable of plant dp-vessel \(position, heading"):
        compose(document)
    document["simulation"]["divergence"] = {"signal": "position", "limit": -1.0}
    with pytest.raises(CompositionError, match=r"^simulation\.divergence\.limit"):
        compose(document)


@pytest.mark.slow
def test_the_first_failure_accumulated_in_the_scan_equals_the_one_reduced_from_the_records(tmp_path):
    """summarize (in the engine's scan, what campaigns use) and reduce (on records, what
    lookout run uses) give the same first failed record and cause."""
    spec = load(_diverging_file(tmp_path))
    scenario, keys = spec.build(), keys_of_seeds([0, 1])
    bound = spec.composition.divergence
    scanned = metric_module.summarize(scenario, keys, [], divergence=bound, where=True)
    reduced = metric_module.reduce(simulate_batch(scenario, keys), [], divergence=bound, where=True)
    assert scanned["diverged"].all() and reduced["diverged"].all()
    np.testing.assert_array_equal(scanned["diverged_at"], reduced["diverged_at"])
    np.testing.assert_array_equal(scanned["diverged_cause"], reduced["diverged_cause"])


@pytest.mark.slow
def test_a_run_that_holds_has_no_failure_and_a_limit_below_its_error_fails_it_at_the_first_record():
    spec = load(EXAMPLES / "luenberger-dp.toml")
    document = dict(spec.composition.document)
    document["simulation"] = {**document["simulation"], "duration": 30.0}
    trajectory = simulate_batch(compose(document).scenario, keys_of_seeds([0]))
    assert metric_module.failures(trajectory, ("position", 100.0)) == [None]
    # the observer starts at the first (noisy) fix: its error is above 1e-9 m at once
    failure = metric_module.failures(trajectory, ("position", 1e-9))[0]
    assert (failure.record, failure.time) == (0, 0.0) and failure.cause == "the estimation error of position is beyond the divergence limit 1e-09 m"


def test_every_plant_kind_states_a_divergence_limit_on_one_of_its_variables():
    from lookout.scenario import registry

    for name in registry.names("plant"):
        cls = registry.kind("plant", name).component_class
        assert cls.divergence is not None and cls.divergence.limit > 0, name


@pytest.mark.slow
def test_a_replay_whose_estimates_go_non_finite_exits_3_naming_the_step(tmp_path, capsys):
    """A replay has no truth: its run fails where an estimate is not finite. 29 rad/s poles
    pass the replay's step check (one step amplifies an error by less than 2) and still
    diverge."""
    shutil.copytree(EXAMPLES / "plugins", tmp_path / "plugins")
    scenario = tmp_path / "unstable.toml"
    scenario.write_text(
        'plugins = ["plugins/luenberger.py"]\n'
        + (EXAMPLES / "live-dp.toml").read_text()
        + '\n[observer]\nkind = "luenberger"\ndesign = "poles"\nbandwidth = [29.0, 29.0, 29.0]\n'
    )
    out = tmp_path / "replay.nc"
    code = main(["replay", str(EXAMPLES / "logs" / "dp-vessel.csv"), "--scenario", str(scenario), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == DIVERGED_EXIT_CODE
    with xr.open_dataset(out) as ds:
        estimates = [ds[name].values.reshape(ds.sizes["time"], -1) for name in ds.data_vars if name.endswith("_hat")]
        bad = ~np.isfinite(np.concatenate(estimates, axis=1)).all(axis=1)
        first = int(np.argmax(bad))
    assert bad.any() and f"(step {first}):" in err and "_hat is not finite; exit code 3" in err


@pytest.mark.slow
def test_lookout_run_warns_of_failing_conditions_a_limited_actuator_and_a_setpoint_after_the_end(tmp_path, capsys):
    """The PID at 40 rad/s: its sampled loop fails (spectral radius above 1) and it asks the
    thrusters for far more than they give; the file's second setpoint (600 s) is after a
    60 s run's end. Each is a warning line; conditions = "require" refuses the run."""
    text = (
        (EXAMPLES / "ekf-pid-dp.toml")
        .read_text()
        .replace("natural_frequency = 0.1 ", "natural_frequency = 40.0")
        .replace("duration = 1800.0", "duration = 60.0")
    )
    path = tmp_path / "fast-pid.toml"
    path.write_text(text)
    code = main(["run", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code in (0, DIVERGED_EXIT_CODE)
    warnings = [line for line in err.splitlines() if line.startswith("warning: ")]
    assert any("design condition(s) of" in line and "controller pid: sampled loop" in line and "spectral radius" in line for line in warnings), (
        warnings
    )
    assert any("the actuator limited the command longer than 10% of the time: force (surge)" in line for line in warnings), warnings
    assert any("reference.schedule_times[1] = 600 s at or after the run's end (simulation.duration 60 s)" in line for line in warnings), warnings
    required = tmp_path / "required.toml"
    required.write_text(text.replace("duration = 60.0", 'duration = 60.0\nconditions = "require"'))
    assert main(["run", str(required), "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "simulation.conditions is 'require', and 1 design condition(s) fail: controller pid: sampled loop" in err
    assert not (tmp_path / "refused").exists()
