"""Position-reference handling (``[references] kind = "dp-class"``,
lookout.sensing.handling): each failure of one reference out of three rejected by its
test within a stated time, a recovered one reinstated after the healthy time and not
before, a drift that drags the weighted mean kept out of the combined position, the
intact suite never rejected, two references or two gyros only alarmed, and bad tables
refused in one line at their key.

Every run is one program: the suite with all its failures, each scenario the failures
it does not use moved past the run's end (a failure's start is an array), four seeds
vmapped. The weighted mean of the same suite is the other program."""

from __future__ import annotations

import copy
import tomllib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout.cli import main
from lookout.scenario.composition import CompositionError, compose
from lookout.sensing.combining import WeightedMean
from lookout.sensing.handling import REASONS, ReferenceHandler
from lookout.sensing.heading import Gyrocompass
from lookout.sensing.position import GnssReceiver
from lookout.sensing.suite import SensorSuite
from lookout.sim import keys_of_seeds, simulate_batch

DT = 0.1
DURATION = 300.0
SEEDS = [0, 1, 2, 3]
HANDLER = ReferenceHandler()
HEALTHY = float(HANDLER.healthy_time)

#: the failures of the suite, each used by one scenario (sensor, index in its list)
DRIFT = {"mode": "drift", "start": 50.0, "rate": [0.05, 0.0]}
JUMP = {"mode": "jump", "start": 100.0, "duration": 60.0, "size": [8.0, -6.0]}
DROPOUT = {"mode": "dropout", "start": 60.0, "duration": 20.0}
FREEZE = {"mode": "freeze", "start": 150.0}
GYRO_JUMP = {"mode": "jump", "start": 100.0, "duration": 50.0, "size": 0.05}
GYRO_FREEZE = {"mode": "freeze", "start": 200.0}
GNSS = {"kind": "gnss", "noise_std": 0.7, "error_std": 0.5, "error_time_constant": 300.0}
GYRO = {"kind": "gyrocompass", "noise_std": 0.0017, "error_std": 0.0017}
SENSORS = {
    "dgnss1": {**GNSS, "lever_arm": [30.0, 5.0], "failures": [JUMP, DROPOUT]},
    "dgnss2": {**GNSS, "lever_arm": [-25.0, -4.0], "failures": [DRIFT]},
    "hpr": {"kind": "hydroacoustic", "lever_arm": [5.0, 0.0], "depth": 100.0, "failures": [FREEZE]},
    "gyro1": GYRO,
    "gyro2": {**GYRO, "failures": [GYRO_FREEZE]},
    "gyro3": {**GYRO, "failures": [GYRO_JUMP]},
}
#: scenario -> the failures it keeps, (sensor, index)
SCENARIOS = {
    "intact": (),
    "drift": (("dgnss2", 0),),
    "jump": (("dgnss1", 0),),
    "dropout": (("dgnss1", 1),),
    "freeze": (("hpr", 0),),
    "gyros": (("gyro2", 0), ("gyro3", 0)),
}


def _document(references: dict) -> dict:
    """The vessel adrift (no controller) in a sea that moves it by about a metre (waves
    of 1 m and 0.1 deg at 3 sigma, a 7 s period), three position references and three
    gyrocompasses."""
    return {
        "simulation": {"duration": DURATION, "plant_step": DT, "sample_period": DT},
        "plant": {
            "kind": "dp-vessel",
            "bias": {"time_constant": 1000.0, "std": [2000.0, 2000.0, 50000.0]},
            "waves": {"kind": "linear", "peak_frequency": 0.8976, "damping_ratio": 0.1, "amplitude": [1.0, 1.0, 0.0017]},
            "initial": {"bias": [1e4, 5e3, 1e5]},
        },
        "sensors": copy.deepcopy(SENSORS),
        "references": references,
        "observer": {"kind": "passive"},
    }


def _keeping(scenario, kept):
    """The scenario with every failure but ``kept`` starting at infinity: never active."""
    suite = scenario.sensor
    where = [(i, j) for i, (name, listed) in enumerate(zip(suite.names, suite.failures)) for j in range(len(listed)) if (name, j) not in kept]
    return eqx.tree_at(lambda s: [s.sensor.failures[i][j].start for i, j in where], scenario, [jnp.asarray(np.inf)] * len(where))


@pytest.fixture(scope="module")
def handled():
    """scenario -> its dataset (run, time): one program, four seeds each."""
    composition = compose(_document({"kind": "dp-class"}))
    keys = keys_of_seeds(SEEDS)
    return {name: simulate_batch(_keeping(composition.scenario, kept), keys).to_xarray() for name, kept in SCENARIOS.items()}


@pytest.fixture(scope="module")
def weighted_drift():
    composition = compose(_document({"kind": "weighted-mean"}))
    return simulate_batch(_keeping(composition.scenario, SCENARIOS["drift"]), keys_of_seeds(SEEDS)).to_xarray()


def _changes(ds, name: str, run: int) -> list[tuple[float, int, int]]:
    """``(time, accepted, rejected_by)`` at each change of ``name``'s state in ``run``."""
    accepted = ds[f"{name}.accepted"].values[run]
    reason = ds[f"{name}.rejected_by"].values[run]
    time = ds.time.values
    return [(float(time[k + 1]), int(accepted[k + 1]), int(reason[k + 1])) for k in np.flatnonzero(np.diff(accepted) != 0)]


def _block_means(ds, name: str, block: int = 20) -> np.ndarray:
    """The norm of ``name``'s error against the reference point's true position (with
    the waves), at each whole second, averaged over consecutive ``block``-second blocks:
    (run, block)."""
    time = ds.time.values
    whole = np.abs(time - np.round(time)) < 1e-9
    error = (ds[name].values - ds["position"].values - ds["wave_position"].values)[:, whole]
    n = error.shape[1] // block * block
    means = error[:, :n].reshape(error.shape[0], -1, block, 2).mean(axis=2)
    return np.hypot(means[..., 0], means[..., 1])


# ----------------------------------------------------------------------------------
# the layout


@pytest.mark.slow
def test_the_stage_adds_each_references_state_and_statistics_after_the_combined_channels(handled):
    composition = compose(_document({"kind": "dp-class"}))
    suite = composition.scenario.sensor
    names = suite.measurement_layout.names
    combined = names[names.index("measured_position") :]
    assert combined[:2] == ("measured_position", "measured_heading")
    statistics = ("accepted", "rejected_by", "weight", "repeated_samples", "noise_ratio", "prediction_distance", "divergence", "drift_rate")
    assert combined[2:10] == tuple(f"dgnss1.{s}" for s in statistics)
    assert combined[-2:] == ("references.position_alarm", "references.heading_alarm")
    assert "gyro1.divergence" in combined and "gyro1.weight" not in combined
    period = dict(zip(suite.measurement_layout.names, np.cumsum([0] + [s.size for s in suite.measurement_layout.signals])))
    # taken as the combined channel of what they concern: the references' fastest period, the gyros'
    assert suite.sample_period[period["hpr.accepted"]] == 1.0 and suite.sample_period[period["gyro3.accepted"]] == DT
    assert suite.sample_period[period["references.position_alarm"]] == 1.0 and suite.sample_period[period["references.heading_alarm"]] == DT
    assert set(REASONS) == {0, 1, 2, 3, 4, 5, 6}


# ----------------------------------------------------------------------------------
# the intact suite


def test_the_intact_suite_is_never_rejected_nor_alarmed(handled):
    """Seeds 0 to 3, 300 s in a sea of about a metre: every reference and gyro accepted
    at every sample, no alarm; the combined position's error at each second is that of
    the weighted mean of three references (below 1 m rms per axis)."""
    ds = handled["intact"]
    for name in SENSORS:
        assert np.all(ds[f"{name}.accepted"].values == 1.0), (name, [_changes(ds, name, run) for run in range(len(SEEDS))])
        assert np.all(ds[f"{name}.rejected_by"].values == 0.0), name
    assert not np.any(ds["references.position_alarm"].values) and not np.any(ds["references.heading_alarm"].values)
    time = ds.time.values
    whole = np.abs(time - np.round(time)) < 1e-9
    error = (ds["measured_position"].values - ds["position"].values - ds["wave_position"].values)[:, whole]
    assert np.all(np.sqrt(np.mean(error**2, axis=1)) < 1.0), np.sqrt(np.mean(error**2, axis=1))
    weights = sum(ds[f"{name}.weight"].values for name in ("dgnss1", "dgnss2", "hpr"))
    np.testing.assert_allclose(weights, 1.0, rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------------
# one reference out of three fails


@pytest.mark.slow
def test_a_slow_drift_is_rejected_and_kept_out_of_the_combined_position(handled, weighted_drift):
    """dgnss2 drifts 0.05 m/s north from 50 s. The statistic: the combined position's
    error against the true reference point (waves included), at each second, averaged
    over 20 s blocks (the noise of one fix averaged down). dp-class: every block below
    2 m in every run, and dgnss2 rejected by the drift test within 120 s of the onset
    (6 m of drift) and kept out to the end. The weighted mean: dragged by its weight's
    share of the drift, 0.365 (1/0.74 against 2/0.74 + 1/1.0), 4.4 m in the last block,
    and above 3.5 m there in every run."""
    ds = handled["drift"]
    handled_error, dragged = _block_means(ds, "measured_position"), _block_means(weighted_drift, "measured_position")
    assert np.all(handled_error < 2.0), handled_error.max(axis=1)
    share = (1 / 0.74) / (2 / 0.74 + 1 / 1.0)
    drift_at_last_block = 0.05 * (DURATION - 10.0 - DRIFT["start"])
    assert np.all(dragged[:, -1] > 3.5), dragged[:, -1]
    assert np.all(np.abs(dragged[:, -1] - share * drift_at_last_block) < 1.0), (dragged[:, -1], share * drift_at_last_block)
    for run in range(len(SEEDS)):
        changes = _changes(ds, "dgnss2", run)
        assert len(changes) == 1 and changes[0][1:] == (0, 5), changes
        assert DRIFT["start"] < changes[0][0] <= DRIFT["start"] + 120.0, changes
        for name in ("dgnss1", "hpr"):
            assert _changes(ds, name, run) == [], (name, _changes(ds, name, run))


def test_a_jump_is_rejected_at_its_first_fix_and_reinstated_after_the_healthy_time(handled):
    """dgnss1 jumps 10 m (8 north, -6 east) from 100 s to 160 s: rejected by the
    prediction or the divergence test within 2 s (its first fix is at 100 s), and
    reinstated after its tests have passed for the healthy time: not before 160 + 30 s,
    and by 160 + 30 + 60 s (the variance window forgets the jump within a minute)."""
    ds = handled["jump"]
    end = JUMP["start"] + JUMP["duration"]
    for run in range(len(SEEDS)):
        changes = _changes(ds, "dgnss1", run)
        assert len(changes) == 2, changes
        (rejected, _, reason), (back, accepted, _) = changes
        assert JUMP["start"] <= rejected <= JUMP["start"] + 2.0 and reason in (3, 4), changes
        assert accepted == 1 and end + HEALTHY <= back <= end + HEALTHY + 60.0, changes
        assert _changes(ds, "dgnss2", run) == [] and _changes(ds, "hpr", run) == []
    assert np.all(_block_means(ds, "measured_position") < 2.0)


def test_a_dropout_is_rejected_at_once_and_reinstated_exactly_after_the_healthy_time(handled):
    """dgnss1 gives no fix from 60 s to 80 s: rejected as missing (6) at 60 s, and back
    at 80 + 30 s, the healthy time after its first fix again (its tests pass at once)."""
    ds = handled["dropout"]
    end = DROPOUT["start"] + DROPOUT["duration"]
    for run in range(len(SEEDS)):
        assert _changes(ds, "dgnss1", run) == [(DROPOUT["start"], 0, 6), (end + HEALTHY, 1, 0)]


def test_a_frozen_reference_is_rejected_after_its_freeze_window(handled):
    """hpr (a fix every 2 s) freezes from 150 s: its sample at 150 s repeats the one at
    148 s, and the tenth repeat (168 s) rejects it (1, freeze), to the end."""
    ds = handled["freeze"]
    samples = float(HANDLER.freeze_samples)
    for run in range(len(SEEDS)):
        assert _changes(ds, "hpr", run) == [(FREEZE["start"] + 2.0 * (samples - 1), 0, 1)]
        assert _changes(ds, "dgnss1", run) == [] and _changes(ds, "dgnss2", run) == []


def test_a_diverging_gyro_is_voted_out_and_a_frozen_one_rejected(handled):
    """gyro3 reads 0.05 rad (2.9 deg) high from 100 s to 150 s: rejected by the
    divergence test (4) at its first sample, reinstated 30 s after the jump's end, and
    the combined heading never moves by more than its noise; gyro2 freezes from 200 s
    and is rejected (1) at its tenth repeated sample, 0.9 s later."""
    ds = handled["gyros"]
    end = GYRO_JUMP["start"] + GYRO_JUMP["duration"]
    time = ds.time.values
    for run in range(len(SEEDS)):
        changes = _changes(ds, "gyro3", run)
        assert [(round(t, 6), a, r) for t, a, r in changes] == [(GYRO_JUMP["start"], 0, 4), (end + HEALTHY, 1, 0)], changes
        frozen = _changes(ds, "gyro2", run)
        assert [(round(t, 6), a, r) for t, a, r in frozen] == [(GYRO_FREEZE["start"] + 0.9, 0, 1)], frozen
    error = np.angle(np.exp(1j * (ds["measured_heading"].values - ds["heading"].values)))
    window = (time >= GYRO_JUMP["start"]) & (time < end)
    assert np.abs(error[:, window]).max() < 0.01, np.abs(error[:, window]).max()


# ----------------------------------------------------------------------------------
# the stage stepped directly: two references, two gyros, one rejection per step


def _step_through(handler, instruments, samples, fresh, times, memory_too=False):
    """Step ``handler`` over ``samples`` (time, instrument, ...) in one scan: the
    channels at each step (and the last memory)."""

    def step(memory, inputs):
        each, now, t = inputs
        memory, out = handler.step(memory, instruments, each, now, jnp.asarray(0.0), t)
        return memory, out

    memory = handler.initial_memory(instruments)
    memory, out = jax.lax.scan(step, memory, (samples, fresh, times))
    return (np.asarray(out), memory) if memory_too else np.asarray(out)


def _channels(handler, instruments, names) -> dict[str, int]:
    layout = handler.signals(instruments, names)
    return dict(zip((s.name for s in layout), np.cumsum([0] + [s.size for s in layout])))


def test_two_references_that_part_raise_an_alarm_and_neither_is_rejected():
    """Two receivers at 1 Hz (0.5 m) that part from 60 s, each 0.1 m/s away from where
    both were: at 10 m apart neither the divergence nor the drift test can say which
    one is wrong, nor can the tracker (each is half the gap from it); the alarm is
    raised, and both stay accepted."""
    instruments = [GnssReceiver(noise_std=0.5), GnssReceiver(noise_std=0.5), Gyrocompass(noise_std=0.0)]
    names = ["a", "b", "gyro"]
    n = 200
    times = jnp.arange(n, dtype=float)
    rng = np.random.default_rng(0)
    apart = np.where(times > 60, 0.1 * (times - 60), 0.0)
    a = rng.normal(0, 0.5, (n, 2)) + np.stack([apart, 0 * apart], axis=1)
    b = rng.normal(0, 0.5, (n, 2)) - np.stack([apart, 0 * apart], axis=1)
    samples = [jnp.asarray(a), jnp.asarray(b), jnp.zeros((n, 1))]
    out = _step_through(HANDLER, instruments, samples, jnp.ones((n, 3), dtype=bool), times)
    at = _channels(HANDLER, instruments, names)
    assert np.all(out[:, at["a.accepted"]] == 1) and np.all(out[:, at["b.accepted"]] == 1)
    alarm = out[:, at["references.position_alarm"]]
    assert alarm[:60].sum() == 0 and alarm[-20:].all()
    assert out[-1, at["a.divergence"]] > float(HANDLER.divergence_limit)


def test_two_gyros_that_part_raise_an_alarm_and_their_heading_is_their_mean():
    instruments = [GnssReceiver(), Gyrocompass(), Gyrocompass()]
    names = ["dgnss", "gyro1", "gyro2"]
    n = 50
    times = jnp.arange(n, dtype=float) * DT
    rng = np.random.default_rng(1)
    one = rng.normal(0, 0.002, (n, 1))
    two = rng.normal(0, 0.002, (n, 1)) + np.where(np.arange(n)[:, None] >= 20, 0.05, 0.0)
    samples = [jnp.zeros((n, 2)), jnp.asarray(one), jnp.asarray(two)]
    out = _step_through(HANDLER, instruments, samples, jnp.ones((n, 3), dtype=bool), times)
    at = _channels(HANDLER, instruments, names)
    assert np.all(out[:, at["gyro1.accepted"]] == 1) and np.all(out[:, at["gyro2.accepted"]] == 1)
    heading_alarm = out[:, at["references.heading_alarm"]]
    assert not heading_alarm[:20].any() and heading_alarm[20:].all()
    np.testing.assert_allclose(out[:, at["measured_heading"]], (one[:, 0] + two[:, 0]) / 2, rtol=0, atol=1e-15)


def test_at_most_one_reference_is_rejected_per_step():
    """Five receivers, two of which freeze at the same fix: the one furthest beyond its
    threshold goes first (here equal: the first by name), the other at the next fix."""
    instruments = [GnssReceiver(noise_std=0.5) for _ in range(5)] + [Gyrocompass(noise_std=0.0)]
    names = [f"r{i}" for i in range(5)] + ["gyro"]
    n = 60
    times = jnp.arange(n, dtype=float)
    rng = np.random.default_rng(2)
    fixes = rng.normal(0, 0.5, (5, n, 2))
    fixes[1, 20:] = fixes[1, 19]
    fixes[3, 20:] = fixes[3, 19]
    samples = [jnp.asarray(each) for each in fixes] + [jnp.zeros((n, 1))]
    out = _step_through(HANDLER, instruments, samples, jnp.ones((n, 6), dtype=bool), times)
    at = _channels(HANDLER, instruments, names)
    first = {name: int(np.argmax(out[:, at[f"{name}.accepted"]] == 0)) for name in ("r1", "r3")}
    samples_needed = int(HANDLER.freeze_samples)
    assert first == {"r1": 19 + samples_needed, "r3": 20 + samples_needed}
    assert out[first["r3"], at["r3.rejected_by"]] == 1 and out[-1, at["r1.rejected_by"]] == 1
    for name in ("r0", "r2", "r4"):
        assert np.all(out[:, at[f"{name}.accepted"]] == 1)


def test_the_memory_stays_finite_through_missing_samples():
    """A reference and a gyro that give nothing for their first second (as at the start
    of lookout live) and a reference that drops out: every leaf of the memory stays
    finite (lookout live's stepper keeps a state only when it is), and a reference is
    taken from its first sample, not rejected for the samples it never gave."""
    instruments = [GnssReceiver(noise_std=0.5), GnssReceiver(noise_std=0.5), Gyrocompass(noise_std=0.001), Gyrocompass(noise_std=0.001)]
    names = ["a", "b", "gyro1", "gyro2"]
    n = 100
    rng = np.random.default_rng(3)
    a, b = rng.normal(0, 0.5, (n, 2)), rng.normal(0, 0.5, (n, 2))
    one, two = rng.normal(0, 0.001, (n, 1)), rng.normal(0, 0.001, (n, 1))
    a[:10], one[:10], b[50:60] = np.nan, np.nan, np.nan
    samples = [jnp.asarray(each) for each in (a, b, one, two)]
    out, memory = _step_through(HANDLER, instruments, samples, jnp.ones((n, 4), dtype=bool), jnp.arange(n, dtype=float), memory_too=True)
    for leaf in jax.tree.leaves(memory):
        assert np.all(np.isfinite(np.asarray(leaf, dtype=float))), leaf
    at = _channels(HANDLER, instruments, names)
    assert np.all(out[:, at["a.accepted"]] == 1) and np.all(out[:, at["gyro1.accepted"]] == 1)
    assert np.isfinite(out[:, at["measured_position"]]).all() and np.isfinite(out[:, at["measured_heading"]]).all()
    dropped = out[:, at["b.rejected_by"]]
    assert np.all(dropped[50:60] == 6) and out[59, at["b.accepted"]] == 0 and out[-1, at["b.accepted"]] == 1


def test_the_weighted_mean_steps_as_it_combines():
    """The plain stage through the stage protocol: no memory, the very numbers of its combine."""
    instruments = [GnssReceiver(lever_arm=[30.0, 5.0]), Gyrocompass()]
    samples = [jnp.asarray([3.0, -4.0]), jnp.asarray([0.3])]
    memory, out = WeightedMean().step(
        WeightedMean().initial_memory(instruments), instruments, samples, jnp.asarray([True, False]), jnp.asarray(0.0), 1.0
    )
    assert memory == ()
    np.testing.assert_array_equal(np.asarray(out), np.asarray(WeightedMean().combine(instruments, samples, jnp.asarray(0.0))))
    suite = SensorSuite({"dgnss": instruments[0], "gyro": instruments[1]}, combining=ReferenceHandler())
    assert suite.measurement_layout.names[2:4] == ("measured_position", "measured_heading")


# ----------------------------------------------------------------------------------
# bad [references] tables: one line at the key

SUITE = """\
[simulation]
duration = 20.0
plant_step = 0.1
sample_period = 0.1

[plant]
kind = "dp-vessel"
[plant.bias]
time_constant = 1000.0
std = [2000.0, 2000.0, 50000.0]
[plant.waves]
kind = "linear"
peak_frequency = 0.8976
damping_ratio = 0.1
amplitude = [1.0, 1.0, 0.0017]

[sensors.dgnss1]
kind = "gnss"
lever_arm = [30.0, 5.0]

[sensors.gyro1]
kind = "gyrocompass"

[references]
kind = "dp-class"
drift_limit = 0.02

[observer]
kind = "passive"
"""

#: (replaced, replacement, the key blamed, the message, the line it points to)
BAD_TABLES = [
    ("drift_limit = 0.02", "drift_limit = -0.02", "references.drift_limit", "must be positive; got -0.02", "drift_limit = -0.02"),
    (
        "drift_limit = 0.02",
        "drift_rate = 0.02",
        "references.drift_rate",
        "unknown key (references dp-class takes: freeze_samples,",
        "drift_rate = 0.02",
    ),
    ("drift_limit = 0.02", "healthy_time = 0.0", "references.healthy_time", "must be positive; got 0.0", "healthy_time = 0.0"),
    ("drift_limit = 0.02", "freeze_samples = 2.5", "references.freeze_samples", "", "freeze_samples = 2.5"),
    ('kind = "dp-class"', 'kind = "dp"', "references.kind", "no references kind 'dp' (one of weighted-mean, dp-class", 'kind = "dp"'),
]


def test_the_file_composes_with_the_handler_spelled_out():
    composition = compose(tomllib.loads(SUITE))
    assert isinstance(composition.scenario.sensor.combining, ReferenceHandler)
    table = composition.document["references"]
    assert table["kind"] == "dp-class" and table["drift_limit"] == 0.02 and table["healthy_time"] == 30.0


@pytest.mark.parametrize(("old", "new", "key", "message", "at"), BAD_TABLES, ids=[case[2] for case in BAD_TABLES])
def test_a_bad_references_table_is_one_line_at_its_key(old, new, key, message, at, tmp_path, capsys):
    assert SUITE.count(old) == 1
    text = SUITE.replace(old, new)
    with pytest.raises(CompositionError) as raised:
        compose(tomllib.loads(text))
    assert str(raised.value).startswith(f"{key}: ") and message in str(raised.value), str(raised.value)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"error: {path}: {key} (line {text.splitlines().index(at) + 1}): ") and message in err, err
    assert not out.exists()


def test_a_bad_threshold_given_in_python_is_one_line_naming_it():
    with pytest.raises(ValueError, match=r"^prediction_gate must be a finite number > 0; got -1.0$"):
        ReferenceHandler(prediction_gate=-1.0)
    with pytest.raises(ValueError, match=r"^variance_samples must be a whole number >= 1; got 0.5"):
        ReferenceHandler(variance_samples=0.5)


# ----------------------------------------------------------------------------------
# campaign metrics of the stage: rejected_after and rejected_time


@pytest.mark.slow
def test_the_rejection_metrics_in_the_scan_and_from_the_records_equal_numpy(handled):
    """``rejected_after:dgnss1`` (time from ``after`` to its first rejection) and
    ``rejected_time:dgnss1`` (fraction of the window rejected) on the jump of dgnss1 at
    100 s, accumulated in the scan and reduced from the records, equal the same numbers
    taken with NumPy from the recorded ``dgnss1.accepted``; a sensor never rejected
    gives NaN and 0."""
    from lookout.scenario import metrics as metric_module

    scenario = _keeping(compose(_document({"kind": "dp-class"})).scenario, SCENARIOS["jump"])
    names = ["rejected_after:dgnss1", "rejected_time:dgnss1", "rejected_after:gyro1", "rejected_time:gyro1"]
    metrics = metric_module.resolve(names, scenario)
    keys = keys_of_seeds(SEEDS)
    after = 90.0
    in_scan = metric_module.summarize(scenario, keys, metrics, after=after)
    recorded = metric_module.reduce(simulate_batch(scenario, keys), metrics, after=after)
    ds = handled["jump"]
    time = ds.time.values
    window = time >= after
    rejected = (ds["dgnss1.accepted"].values < 0.5) & window
    first = np.argmax(rejected, axis=1)
    expected_after = np.where(rejected.any(axis=1), time[first] - time[np.argmax(window)], np.nan)
    expected_time = rejected.sum(axis=1) / window.sum()
    for found in (in_scan, recorded):
        np.testing.assert_allclose(found["rejected_after__dgnss1"], expected_after, rtol=0, atol=1e-9)
        np.testing.assert_allclose(found["rejected_time__dgnss1"], expected_time, rtol=1e-12)
        assert np.all(np.isnan(found["rejected_after__gyro1"])) and np.all(found["rejected_time__gyro1"] == 0.0)
    assert np.all(np.abs(expected_after - 10.0) < 1.0)  # the jump at 100 s, rejected at its first fix
    with pytest.raises(ValueError, match="the sensor records no 'dgnss1.accepted'"):
        metric_module.resolve(["rejected_after:dgnss1"], compose(_document({"kind": "weighted-mean"})).scenario)
