"""A rate gyro (lookout.sensing.rate_gyro) in a suite: a sample, its ROT sentences read
into it live, and a Kalman filter on the suite replaying a log lookout write-log wrote
with them as it ran in simulation (and the simulated samples' noise)."""

from __future__ import annotations

import math
import re
import tomllib
import warnings

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.io.geodesy import LocalFrame
from lookout.io.nmea import NmeaParser, Reading
from lookout.io.simulated_log import EPOCH, rot
from lookout.live.session import Session
from lookout.scenario.composition import compose
from lookout.sensing.rate_gyro import RateGyro

SCENARIO = """
[simulation]
duration = 60.0
plant_step = 0.1
sample_period = 0.1

[plant]
kind = "dp-vessel"

[plant.bias]
kind = "gauss-markov"
time_constant = 1000.0
std = [2000.0, 2000.0, 50000.0]

[plant.waves]
kind = "linear"
peak_frequency = 0.8976
damping_ratio = 0.1
amplitude = [2.0, 2.0, 0.005]

[sensors.dgnss1]
kind = "gnss"
lever_arm = [30.0, 5.0]
noise_std = 0.7
sample_period = 1.0
source = "GP"

[sensors.gyro1]
kind = "gyrocompass"
noise_std = 0.0017453292519943296
sample_period = 0.1
source = "HE"

[sensors.rot]
kind = "rate-gyro"
noise_std = 0.0005
sample_period = 0.1
source = "TI"

[references]
kind = "weighted-mean"

[observer]
kind = "ekf"

[reference]
kind = "reference-filter"
signals = ["position", "heading"]
bandwidth = 0.03
schedule_times = [0.0, 20.0]
setpoints = [[0.0, 0.0, 0.0], [10.0, -5.0, 0.3]]

[controller]
kind = "pid"
natural_frequency = 0.1
damping_ratio = 1.0
integral_ratio = 0.1
"""


# ---------------------------------------------------------------- the instrument
def test_a_sample_is_the_yaw_rate_its_drifting_bias_and_white_noise():
    gyro = RateGyro(noise_std=0.01, error_std=0.02, error_time_constant=100.0, sample_period=0.5)
    kinematics = {"yaw_rate": jnp.asarray(0.3)}
    memory, value, white = gyro.emit(jnp.asarray([0.05]), kinematics, jnp.asarray([1.5, 0.0]))
    np.testing.assert_allclose(value, [0.35])  # the rate and the bias held in memory
    np.testing.assert_allclose(white, [0.015])
    decay = math.exp(-0.5 / 100.0)
    np.testing.assert_allclose(memory, [0.05 * decay])  # a Gauss-Markov step without its normal
    np.testing.assert_allclose(gyro.expected(kinematics), [0.3])
    np.testing.assert_allclose(gyro.measurement_std(), [math.hypot(0.01, 0.02)])
    assert RateGyro().signals[0].name == "measured_yaw_rate" and RateGyro().signals[0].units == "rad/s"


@pytest.mark.parametrize(
    "options, message",
    [
        ({"noise_std": -0.1}, "noise_std"),
        ({"sample_period": 0.0}, "sample_period"),
        ({"error_std": -1.0}, "error_std"),
        ({"error_time_constant": math.inf}, "error_time_constant"),
        ({"source": "T I"}, "source"),
    ],
)
def test_a_bad_value_is_refused_naming_it(options, message):
    with pytest.raises(ValueError, match=message):
        RateGyro(**options)


# ---------------------------------------------------------------- live
def _session() -> Session:
    scenario = compose(tomllib.loads(SCENARIO)).scenario
    return Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=LocalFrame(63.44, 10.40), suite=scenario.sensor)


def test_a_rot_sentence_reaches_the_rate_gyro_in_radians_per_second():
    """ROT's degrees per minute (negative: the bow to port) become the sensor's rad/s; a
    rate beyond 30 deg/s is counted ``range`` and not used; the filter gates the rate
    gyro on its innovation as it gates the others."""
    session = _session()
    assert session.direct and set(session.channels) == {"dgnss1", "gyro1", "rot"}
    assert session.gate_tests["rot"] == "nis"
    parser = NmeaParser()
    for t, text in ((0.0, rot(-12.0)), (0.05, rot(2000.0)), (0.1, rot(30.0)), (0.15, rot(30.0, talker="GP"))):
        for reading in parser.line(text, t):
            session.feed(reading)
    assert session.channels["rot"].new == pytest.approx((math.radians(0.5),))
    assert session.channels["rot"].counts == {**session.channels["rot"].counts, "accepted": 2, "range": 1, "superseded": 1}
    # a GNSS talker is not of the rate gyro's family (TI, a heading talker): no sensor takes it
    assert session.channels["rot"].counts["other_source"] == 1
    session.feed(Reading(0.2, "TI", "rate_of_turn", (math.nan,), "ROT"))
    assert session.channels["rot"].counts["range"] == 2


# ---------------------------------------------------------------- replay of a written log
@pytest.mark.slow
def test_the_ekf_replays_a_log_with_rot_as_it_ran_in_simulation(tmp_path, capsys):
    """lookout write-log writes the rate gyro as ROT (three decimals of degrees per
    minute); replayed through the same filter, the estimates follow the simulation's to
    within 1 mm (measured 6e-5 m: the GGA's and the ROT's rounding), every ROT taken; the
    simulated rate gyro has its stated noise about the yaw rate."""
    scenario = tmp_path / "rot.toml"
    scenario.write_text(SCENARIO)
    assert main(["write-log", str(scenario), "--out", str(tmp_path / "log"), "--outage", "none"]) == 0
    err = capsys.readouterr().err
    assert "sensor rot: ROT as TI, every 0.1 s" in err
    log = tmp_path / "log"
    rows = (log / "dp-vessel.nmea").read_text().count("$TIROT,")
    out = tmp_path / "replay.nc"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        code = main(
            [
                "replay",
                str(log / "dp-vessel.nmea"),
                "--scenario",
                str(log / "dp-vessel-scenario.toml"),
                "--origin",
                "63.44,10.40",
                "--thrust",
                str(log / "dp-vessel-thrust.csv"),
                "--out",
                str(out),
            ]
        )
    assert code == 0
    err = capsys.readouterr().err
    assert re.search(r"rot 10\.0\d/s", err) and "ROT 600" in err, err
    with xr.open_dataset(out) as replayed, xr.open_dataset(log / "dp-vessel-truth.nc") as truth:
        replayed, simulated = replayed.isel(run=0), truth.isel(run=0)
        k = np.rint((replayed["clock_time"].values - EPOCH) / 0.1).astype(int)
        difference = np.linalg.norm(replayed["position_hat"].values - simulated["position_hat"].values[k], axis=1)
        assert k.size >= 590 and difference.max() < 1e-3, difference.max()
        taken = np.isfinite(replayed["rot.measured_yaw_rate"].values).sum()
        assert taken >= rows - 20  # the sentences the log corrupted aside (checksum)
        # the simulated samples: the yaw rate with the stated white noise (0.0005 rad/s), no mean
        error = simulated["rot.measured_yaw_rate"].values - simulated["yaw_rate"].values
        assert abs(np.std(error) - 0.0005) < 0.0001 and abs(np.mean(error)) < 0.0002
        assert np.ptp(simulated["yaw_rate"].values) > 0.001  # it turns (0.002 rad/s by 60 s, the turn to 0.3 rad begun)
        rate = replayed["rot.measured_yaw_rate"].values
        np.testing.assert_allclose(rate[np.isfinite(rate)], simulated["rot.measured_yaw_rate"].values[k][np.isfinite(rate)], atol=3e-7)
