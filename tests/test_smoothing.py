"""The Rauch-Tung-Striebel smoother after a Kalman-type filter (lookout.observers.smoothing):
the exact linear RTS smoother on a linear plant (the recursion written here), and a
smoothed log closer to the truth than the filtered one on a simulated vessel."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from test_kalman import NOISE_STD, SAMPLE, STEP, C, LinearPlant, LinearSensor, _discrete_model, _linear_data

from lookout.observers.ekf import ExtendedKalmanFilter
from lookout.observers.passive import PassiveObserver
from lookout.observers.smoothing import smooth
from lookout.observers.ukf import UnscentedKalmanFilter
from lookout.scenario.composition import compose, simulate


def _exact_rts(ys, us, x0, P0):
    """The exact Kalman filter of the discrete model, then the RTS recursion backward."""
    F, Bd, Q = _discrete_model()
    R = np.array([[NOISE_STD**2]])
    x, P = x0.copy(), P0.copy()
    posterior, priors = [], []
    for y, u in zip(ys, us):
        if np.all(np.isfinite(y)):
            K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
            x = x + K @ (y - C @ x)
            P = (np.eye(2) - K @ C) @ P @ (np.eye(2) - K @ C).T + K @ R @ K.T
        posterior.append((x.copy(), P.copy()))
        x, P = F @ x + Bd @ u, F @ P @ F.T + Q
        priors.append((x.copy(), P.copy()))
    xs, Ps = posterior[-1]
    smoothed = [(xs, Ps)]
    for k in range(len(ys) - 2, -1, -1):
        (xf, Pf), (xp, Pp) = posterior[k], priors[k]
        gain = Pf @ F.T @ np.linalg.inv(Pp)
        xs, Ps = xf + gain @ (xs - xp), Pf + gain @ (Ps - Pp) @ gain.T
        smoothed.append((xs, Ps))
    smoothed.reverse()
    return np.asarray([x for x, _ in posterior]), np.asarray([x for x, _ in smoothed]), np.asarray([np.sqrt(np.diag(P)) for _, P in smoothed])


@pytest.mark.slow
@pytest.mark.parametrize("kind", [ExtendedKalmanFilter, UnscentedKalmanFilter])
def test_on_a_linear_plant_the_smoother_is_the_exact_rts_smoother(kind):
    """On a linear plant both filters are the exact Kalman filter (tests/test_kalman.py),
    and the smoother after either the exact RTS smoother: 1e-10 after the extended, 1e-8
    after the unscented (its filter's own tolerance there)."""
    ys, us = _linear_data()
    ys[7] = np.nan  # a dropout
    filter_ = kind(LinearPlant(), LinearSensor(), initial_std=[2.0, 1.0], plant_step=STEP, filter_period=SAMPLE)
    tolerance = 1e-10 if kind is ExtendedKalmanFilter else 1e-8
    times = SAMPLE * np.arange(len(ys))
    ds = smooth(filter_, times, ys, us, guess=filter_.guess(position=0.5))
    filtered, smoothed, std = _exact_rts(ys, us, np.array([0.5, 0.0]), np.diag([4.0, 1.0]))
    np.testing.assert_allclose(ds["state_hat"].values[0], filtered, rtol=0, atol=tolerance)
    np.testing.assert_allclose(ds["state_smoothed"].values[0], smoothed, rtol=0, atol=tolerance)
    np.testing.assert_allclose(ds["state_std_smoothed"].values, std, rtol=0, atol=tolerance)
    assert np.all(std <= np.sqrt(np.diagonal(np.diag([4.0, 1.0]))) + 1e-12)


@pytest.mark.slow
def test_smoothing_a_simulated_log_beats_the_filter():
    """The model-free filter over 300 s of the Northern Clipper in the paper's sea
    (tests/test_model_free.py's scenario, seed 0): the smoothed velocity's RMS error
    (after the first 30 s and before the last 30) is below 0.6 of the filtered one's
    (measured 0.034 against 0.071 m/s: 0.48), the position's too (0.31 against 0.70 m:
    0.44)."""
    from test_model_free import SCENARIO

    document = tomllib.loads(SCENARIO)
    document["simulation"]["runs"] = 1
    scenario = compose(document)
    ds = simulate(scenario).to_xarray()
    observer = scenario.scenario.observer
    measured = np.concatenate([ds["measured_position"].values[0], ds["measured_heading"].values[0][:, None]], axis=1)
    times = ds["time"].values
    # the sensor holds a fix between its samples: only a fix's own sample is new
    fresh = np.isclose(times % 1.0, 0.0) | np.isclose(times % 1.0, 1.0)
    measured[~fresh, :2] = np.nan
    smoothed = smooth(observer, times, measured, np.zeros((times.size, 3)))
    inside = (times >= 30.0) & (times <= times[-1] - 30.0)

    def rms(name, suffix):
        error = smoothed[f"{name}_{suffix}"].values[0] - ds[name].values[0]
        return float(np.sqrt(np.mean(np.sum(error.reshape(times.size, -1)[inside] ** 2, axis=1))))

    ratios = {name: rms(name, "smoothed") / rms(name, "hat") for name in ("velocity", "position")}
    assert ratios["velocity"] < 0.6 and ratios["position"] < 0.6, ratios


def test_an_observer_that_is_not_a_kalman_filter_is_refused():
    from pathlib import Path

    scenario = compose(tomllib.loads((Path(__file__).parents[1] / "examples" / "live-dp.toml").read_text())).scenario
    assert isinstance(scenario.observer, PassiveObserver)
    with pytest.raises(ValueError, match="observer must be a Kalman-type filter .ekf, ukf, model-free. to be smoothed; got PassiveObserver"):
        smooth(scenario.observer, [0.0, 1.0], [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
