"""Observers over a recorded log (lookout.filter) and live (lookout.Stepper)."""

import jax
import numpy as np
import pytest

import lookout
from lookout.papers import fossen_strand_1999 as fs
from lookout.sensors import POSITION_HEADING
from lookout.models.vessel import VESSEL_INPUT
from lookout.sim import simulate


#: one worker computes the module's fixture once (make test runs pytest --dist loadgroup)
pytestmark = pytest.mark.xdist_group("filtering")


@pytest.fixture(scope="module")
def recorded():
    scenario = fs.build(fs.Config(duration=120.0))
    trajectory = simulate(scenario, jax.random.key(6))
    return scenario, trajectory, trajectory.to_xarray()


def test_filtering_a_simulation_log_gives_the_simulation_estimates(recorded):
    scenario, trajectory, ds = recorded
    log = lookout.filter(
        scenario.observer, trajectory.time, trajectory.measurement, trajectory.applied, guess=scenario.initial_estimate,
        measurement_layout=POSITION_HEADING, input_layout=VESSEL_INPUT,
    )
    assert set(log.data_vars) >= {"position_hat", "heading_hat", "innovation_position", "measured_position", "force_applied"}
    for name in ("position_hat", "heading_hat", "velocity_hat", "bias_force_hat", "wave_position_hat", "innovation_heading"):
        assert log[name].dims == ds[name].dims and log[name].attrs["units"] == ds[name].attrs["units"]
        # the row steps t_{k+1} - t_k equal the sample period to rounding
        np.testing.assert_allclose(log[name].values, ds[name].values, rtol=1e-9, atol=1e-9 * float(np.abs(ds[name]).max()))


def test_filter_rides_through_missing_channels_and_irregular_times(recorded):
    scenario, trajectory, _ = recorded
    rng = np.random.default_rng(0)
    times = np.cumsum(rng.uniform(0.05, 0.2, 400))
    measurements = np.asarray(trajectory.measurement)[: times.size].copy()
    measurements[rng.random(measurements.shape) < 0.3] = np.nan
    log = lookout.filter(scenario.observer, times, measurements, np.zeros((times.size, 3)), guess=scenario.initial_estimate)
    for name in log.data_vars:
        if name.endswith("_hat"):
            assert np.all(np.isfinite(log[name].values)), name
    assert log.y_channel.values.tolist() == ["y0", "y1", "y2"] and log.status.values.tolist() == ["finite"]


def test_stepper_gives_the_filter_row_by_row(recorded):
    scenario, trajectory, _ = recorded
    rows = 50
    times, ys, us = np.asarray(trajectory.time)[:rows], np.asarray(trajectory.measurement)[:rows], np.asarray(trajectory.applied)[:rows]
    log = lookout.filter(scenario.observer, times, ys, us, guess=scenario.initial_estimate)
    stepper = lookout.Stepper(scenario.observer, scenario.initial_estimate, ys[0], input_size=3)
    steps = np.diff(times, append=times[-1])
    for k in range(rows):
        estimate = stepper(times[k], ys[k], us[k], steps[k])
        np.testing.assert_allclose(np.asarray(estimate["position"]), log.position_hat.values[0, k], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"times": [0.0, 0.1, 0.1]}, "times must be finite and strictly increasing"),
        ({"measurements": np.zeros((3, 2))}, r"observer and log do not fit \(2 measurement and 3 input columns\): "),
        ({"inputs": np.full((3, 3), np.nan)}, "inputs must be finite"),
    ],
)
def test_filter_rejects_a_malformed_log(recorded, kwargs, message):
    scenario, _, _ = recorded
    args = {"times": [0.0, 0.1, 0.2], "measurements": np.zeros((3, 3)), "inputs": np.zeros((3, 3))} | kwargs
    layout = POSITION_HEADING if "measurements" not in kwargs else None
    with pytest.raises(ValueError, match=message):
        lookout.filter(scenario.observer, args["times"], args["measurements"], args["inputs"], guess=scenario.initial_estimate, measurement_layout=layout)
