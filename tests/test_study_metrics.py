"""Campaign metrics: accumulated in the engine's scan (summarize) and reduced from the
records (reduce), both against the same numbers computed with NumPy from a recorded
batch of the Kim (2002) closed loop (it has estimates, angles, a reference and inputs)."""

from __future__ import annotations

import numpy as np
import pytest

from lookout._math import ssa
from lookout.analysis import settling_time
from lookout.papers import kim_2002
from lookout.scenario import metrics as metric_module
from lookout.sim import keys_of_seeds, simulate_batch

NAMES = [
    "rms_error:position",
    "rms_error:heading",
    "max_error:heading",
    "settling_time:position",
    "rms_tracking:position",
    "max_tracking:heading",
    "max_excursion:position",
    "max_excursion:velocity",
    "rms_input:force",
    "max_input:moment",
    "final:position",
    "final:bias_force",
]
AFTER = 40.0


@pytest.fixture(scope="module")
def kim():
    scenario = kim_2002.REPRODUCTION.scenario(kim_2002.Config(duration=100.0), "sliding-mode")
    keys = keys_of_seeds([11, 12, 13, 14])
    return scenario, keys, simulate_batch(scenario, keys)


def _norm(values, vector):
    return np.sqrt((values**2).sum(-1)) if vector else np.abs(values)


def _expected(trajectory, limit):
    """Every metric of NAMES per run, with NumPy, from the recorded arrays."""
    truth = {k: np.asarray(v) for k, v in trajectory.truth.items()}
    estimate = {k: np.asarray(v) for k, v in trajectory.estimate.items()}
    reference = {k: np.asarray(v) for k, v in trajectory.reference.items()}
    applied = np.asarray(trajectory.applied)
    time = np.asarray(trajectory.time)
    window = time >= AFTER
    rms = lambda norm: np.sqrt((norm[:, window] ** 2).mean(-1))
    position_error = _norm(truth["position"] - estimate["position"], True)
    out = {
        "rms_error__position": rms(position_error),
        "rms_error__heading": rms(np.abs(np.asarray(ssa(truth["heading"] - estimate["heading"])))),
        "max_error__heading": np.abs(np.asarray(ssa(truth["heading"] - estimate["heading"])))[:, window].max(-1),
        "settling_time__position": settling_time(position_error, time, rms(position_error)),
        "rms_tracking__position": rms(_norm(truth["position"] - reference["position_desired"], True)),
        "max_tracking__heading": np.abs(np.asarray(ssa(truth["heading"] - reference["heading_desired"])))[:, window].max(-1),
        "max_excursion__position": _norm(truth["position"] - reference["position_desired"], True).max(-1),
        "max_excursion__velocity": _norm(truth["velocity"] - truth["velocity"][:, :1], True).max(-1),
        "rms_input__force": rms(_norm(applied[..., :2], True)),
        "max_input__moment": np.abs(applied[..., 2])[:, window].max(-1),
        "final__position": _norm(truth["position"][:, -1], True),
        "final__bias_force": _norm(truth["bias_force"][:, -1], True),
    }
    diverged = np.maximum(position_error.max(-1), _norm(truth["position"] - reference["position_desired"], True).max(-1)) > limit
    return {k: np.where(diverged, np.nan, v) for k, v in out.items()}, diverged


@pytest.mark.slow
@pytest.mark.parametrize("path", ["summarize", "reduce"])
def test_metrics_equal_numpy_on_the_recorded_runs(kim, path):
    scenario, keys, trajectory = kim
    metrics = metric_module.resolve(NAMES, scenario)
    # a limit between the runs' largest position errors: some runs diverge, some do not
    largest = np.sort(
        np.maximum(
            _norm(np.asarray(trajectory.truth["position"]) - np.asarray(trajectory.estimate["position"]), True).max(-1),
            _norm(np.asarray(trajectory.truth["position"]) - np.asarray(trajectory.reference["position_desired"]), True).max(-1),
        )
    )
    limit = float(largest[1:3].mean())
    expected, diverged = _expected(trajectory, limit)
    assert 0 < diverged.sum() < len(diverged)
    options = {"after": AFTER, "divergence": ("position", limit)}
    got = metric_module.summarize(scenario, keys, metrics, **options) if path == "summarize" else metric_module.reduce(trajectory, metrics, **options)
    np.testing.assert_array_equal(got["diverged"], diverged)
    for name, values in expected.items():
        np.testing.assert_allclose(got[name], values, rtol=1e-12, atol=0, err_msg=name)
    if path == "reduce":  # without a limit no run diverges: every metric is a number
        free = metric_module.reduce(trajectory, metrics, after=AFTER)
        assert not free["diverged"].any() and all(np.isfinite(free[name]).all() for name in expected)


def test_a_window_past_the_end_is_refused(kim):
    scenario, keys, trajectory = kim
    with pytest.raises(ValueError, match=r"after \(200 s\) is past the end of the run \(99.9 s\)"):
        metric_module.reduce(trajectory, metric_module.resolve(NAMES[:1], scenario), after=200.0)


@pytest.mark.slow
def test_an_outage_silences_its_channels_and_its_metrics_equal_numpy():
    """A 60 s position outage (the sensor's outage_*): the position fixes are NaN from its
    start until its end, the heading is not; outage_drift and recovery_time equal NumPy's
    reading of the recorded runs, and are NaN without an outage."""
    from lookout.scenario.composition import compose
    from lookout.scenario.registry import preset

    document = preset("fossen-strand-1999", "paper")
    document["simulation"]["duration"] = 300.0
    document["sensor"].update(outage_signals=["measured_position"], outage_start=120.0, outage_duration=60.0)
    scenario = compose(document).scenario
    keys = keys_of_seeds([0, 1, 2])
    metrics = metric_module.resolve(["outage_drift:position", "recovery_time:position", "rms_error:position"], scenario)
    assert [m.units for m in metrics] == ["m", "s", "m"]
    summarized = metric_module.summarize(scenario, keys, metrics)
    trajectory = simulate_batch(scenario, keys)
    time = np.asarray(trajectory.time)
    measured = np.asarray(trajectory.measurement)
    lost = np.isnan(measured[0, :, 0])
    assert time[lost].min() == 120.0 and time[lost].max() == pytest.approx(179.9) and not np.isnan(measured[..., 2]).any()
    error = np.linalg.norm(np.asarray(trajectory.truth["position"]) - np.asarray(trajectory.estimate["position"]), axis=-1)
    inside = (time >= 120.0) & (time < 180.0)
    np.testing.assert_allclose(summarized["outage_drift__position"], error[:, inside].max(axis=1), rtol=1e-14)
    level = np.sqrt((error[:, (time >= 60.0) & (time < 120.0)] ** 2).mean(axis=1))
    expected = []
    for run in range(3):
        back = [t - 180.0 for i, t in enumerate(time) if t >= 180.0 and np.sqrt((error[run, i : i + 600] ** 2).mean()) <= 1.25 * level[run]]
        expected.append(back[0] if back else np.nan)
    np.testing.assert_allclose(summarized["recovery_time__position"], expected, rtol=1e-12, atol=1e-9)
    reduced = metric_module.reduce(trajectory, metrics, outage=metric_module.outage_of(scenario))
    for name in ("outage_drift__position", "recovery_time__position", "rms_error__position"):
        np.testing.assert_allclose(reduced[name], summarized[name], rtol=1e-12, equal_nan=True)
    # no outage: NaN, not a number that looks measured
    quiet = metric_module.reduce(trajectory, metrics)
    assert np.isnan(quiet["outage_drift__position"]).all() and np.isnan(quiet["recovery_time__position"]).all()


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"outage_signals": ["measured_speed"]}, "outage_signals: the sensor measures no 'measured_speed'"),
        ({"outage_duration": 10.0}, "outage_duration needs outage_signals"),
        ({"outage_signals": ["measured_position"], "outage_start": -1.0}, "outage_start"),
    ],
)
def test_a_bad_outage_is_refused_in_one_line(changes, message):
    from lookout.sensors import PositionHeadingSensor

    with pytest.raises(ValueError) as error:
        PositionHeadingSensor(**changes)
    assert message in str(error.value) and "\n" not in str(error.value)
