"""Named sensors live (lookout.live.sensors): a scenario's [sensors.NAME] each fed by
its own source, held apart, combined by the suite's own combining stage; a silent
source is a dropout the observer rides through; a bad source is refused at its key."""

from __future__ import annotations

import copy
import math
import re
import tomllib
import warnings
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.io.geodesy import LocalFrame
from lookout.io.nmea import Reading, checksum, sentence, source_rank, source_spec
from lookout.io.simulated_log import EPOCH, gga
from lookout.live.run import replay
from lookout.live.sensors import route
from lookout.live.session import Session
from lookout.scenario.composition import CompositionError, compose, simulate
from lookout.sensing.instrument import at_lever_arm

ORIGIN = LocalFrame(63.44, 10.40)
START = 1000.0  # the log's clock at its first line (s)
LEVER_ARMS = {"dgnss1": (30.0, 5.0), "dgnss2": (-20.0, -4.0)}
GYRO_OFFSETS = {"gyro1": 0.001, "gyro2": -0.001}  # rad: their median is the true heading

SCENARIO = """
[simulation]
sample_period = 0.1
plant_step = 0.1
duration = 60.0

[plant]
kind = "dp-vessel"
vessel = { kind = "northern-clipper" }
bias = { kind = "gauss-markov", time_constant = 1000.0, std = [2000.0, 2000.0, 50000.0] }
waves = { kind = "linear", peak_frequency = 0.8976, damping_ratio = 0.1, amplitude = [10.0, 10.0, 0.0175], sigmas = 3.0 }

[sensors.dgnss1]
kind = "gnss"
lever_arm = [30.0, 5.0]
noise_std = 0.5
source = "GP@dgps1"

[sensors.dgnss2]
kind = "gnss"
lever_arm = [-20.0, -4.0]
noise_std = 1.0
source = "GP@dgps2"

[sensors.hpr]
kind = "hydroacoustic"
lever_arm = [0.0, 0.0]
source = "@hipap"

[sensors.gyro1]
kind = "gyrocompass"
source = "HE"

[sensors.gyro2]
kind = "gyrocompass"
source = "HC"

[observer]
kind = "passive"
design = "fossen-strand-1999"
wave_frequency = 0.8976
"""


def _document() -> dict:
    return tomllib.loads(SCENARIO)


def _truth(t: float) -> tuple[np.ndarray, float]:
    """The reference point (north, east; m) and heading (rad) at ``t`` s into the log."""
    return np.array([12.0 + 0.05 * t, -7.0 + 0.02 * t]), 0.3 + 0.05 * math.sin(0.05 * t)


def _tagged(source: str, text: str) -> str:
    """``text`` behind a tag block naming its source (``s:``)."""
    block = f"s:{source}"
    return f"\\{block}*{checksum(block.encode()):02X}\\{text}"


def _hdt(talker: str, heading: float) -> str:
    return sentence(talker, "HDT", [f"{math.degrees(heading) % 360.0:.5f}", "T"])


def _log(path: Path, seconds: float = 40.0) -> Path:
    """Two receivers (tag blocks dgps1 and dgps2, 1 Hz) at their lever arms and two gyros
    (talkers HE and HC, 10 Hz); the hydroacoustic reference never speaks."""
    rows = []
    for k in range(int(seconds)):
        for name, source, offset in (("dgnss1", "dgps1", 0.03), ("dgnss2", "dgps2", 0.53)):
            t = k + offset
            point, heading = _truth(t)
            north, east = np.asarray(at_lever_arm(jnp.asarray(point), heading, jnp.asarray(LEVER_ARMS[name])))
            latitude, longitude, _ = ORIGIN.geodetic(float(north), float(east), 0.0)
            rows.append((START + t, _tagged(source, gga(t, float(latitude), float(longitude)))))
    for k in range(int(seconds * 10)):
        for name, talker, offset in (("gyro1", "HE", 0.01), ("gyro2", "HC", 0.06)):
            t = k / 10 + offset
            rows.append((START + t, _hdt(talker, _truth(t)[1] + GYRO_OFFSETS[name])))
    rows.sort()
    path.write_text("".join(f"{t:.6f} {text}\n" for t, text in rows))
    return path


def _columns(session: Session) -> dict[str, np.ndarray]:
    """The columns of each signal of a session's recorded measurement."""
    sizes = [signal.size for signal in session.record_layout.signals]
    return dict(zip(session.record_layout.names, np.split(np.arange(sum(sizes)), np.cumsum(sizes)[:-1])))


def _session(document: dict | None = None, batch: int = 4096, **options) -> tuple[Session, object]:
    scenario = compose(document or _document()).scenario
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the passive observer's, and silent sensors'
        session = Session(
            scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN, batch=batch, suite=scenario.sensor, **options
        )
    return session, scenario


def _replayed(session: Session, log: Path):
    blocks = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # no thrust
        outcome = replay(session, log, emit=blocks.append)
    measurement = np.concatenate([b.measurement for b in blocks])
    times = np.concatenate([b.time for b in blocks]) - START
    estimates = {name: np.concatenate([b.estimate[name] for b in blocks]) for name in blocks[0].estimate}
    return outcome, times, measurement, estimates


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    log = _log(tmp_path_factory.mktemp("sensors") / "bridge.nmea")
    session, scenario = _session()
    return session, scenario, log, *_replayed(session, log)


# ---------------------------------------------------------------- sources
def test_a_source_is_a_talker_a_sender_or_both():
    assert source_spec("GP") == ("GP", None) and source_spec("@10.0.0.5") == ("", "10.0.0.5")
    assert source_spec("GP@10.0.0.5") == ("GP", "10.0.0.5")
    for bad in ("", "gp", "GPS", "GP@", "GP@a b", "@", 3):
        with pytest.raises(ValueError, match="must be"):
            source_spec(bad)
    # a named sender before a talker alone; the talker itself before another of its family
    assert source_rank("GP@10.0.0.5", "GP", "10.0.0.5") == (1, 2)
    assert source_rank("GN@10.0.0.5", "GP", "10.0.0.5") == (1, 1)  # a multi-constellation receiver's GN
    assert source_rank("GP@10.0.0.6", "GP", "10.0.0.5") is None
    assert source_rank("GP@10.0.0.6", "", "10.0.0.6") == (1, 0) and source_rank("GP", "HE", None) is None


@pytest.mark.slow
def test_a_reading_goes_to_the_sensor_whose_source_it_comes_from(replayed):
    session = replayed[0]
    sensors = session.sensors
    assert route(sensors, "GP@dgps1", "position").name == "dgnss1" and route(sensors, "GN@dgps2", "position").name == "dgnss2"
    assert route(sensors, "GP@hipap", "position").name == "hpr" and route(sensors, "GP@dgps3", "position") is None
    # HE and HC are one family: each gyro takes its own talker; a third talker of the family matches both equally
    assert route(sensors, "HE", "heading").name == "gyro1" and route(sensors, "HC@x", "heading").name == "gyro2"
    assert route(sensors, "HN", "heading") is None


# ---------------------------------------------------------------- replay with named sensors
def test_replay_gives_each_sensor_its_channel(replayed):
    session, scenario, _, outcome, t, measurement, _ = replayed
    names = session.record_layout.names
    assert names == (
        "dgnss1.measured_position",
        "dgnss2.measured_position",
        "hpr.measured_position",
        "gyro1.measured_heading",
        "gyro2.measured_heading",
        "measured_position",
        "measured_heading",
    )
    counts = {name: sensor.counts["accepted"] for name, sensor in session.sensors.items()}
    assert counts == {"dgnss1": 40, "dgnss2": 40, "hpr": 0, "gyro1": 400, "gyro2": 400}
    assert session.unused == {} and outcome.rejected == {}
    # each receiver's channel is its antenna, each gyro's its own heading
    columns = _columns(session)
    for name, arm in LEVER_ARMS.items():
        sample = measurement[:, columns[f"{name}.measured_position"]]
        held = np.isfinite(sample).all(axis=1)
        assert held.mean() > 0.9
        row = np.flatnonzero(held)[len(np.flatnonzero(held)) // 2]
        point, heading = _truth(t[row])
        # held since its fix, up to a step before: within the motion of a step
        expected = point + np.array([[math.cos(heading), -math.sin(heading)], [math.sin(heading), math.cos(heading)]]) @ np.array(arm)
        assert np.abs(sample[row] - expected).max() < 0.2
    for name, offset in GYRO_OFFSETS.items():
        sample = measurement[:, columns[f"{name}.measured_heading"]][:, 0]
        truths = np.array([_truth(each)[1] for each in t])
        assert np.nanmax(np.abs(sample - truths - offset)) < 1e-3
    assert np.isnan(measurement[:, columns["hpr.measured_position"]]).all()  # never spoke


@pytest.mark.slow
def test_the_combined_position_is_the_simulations_combining_stage(replayed):
    """At each step a receiver's fix came, the combined channels the observer read are
    the suite's own combine of the held samples (the stage a simulation runs), and its
    position is the vessel's reference point, the lever arms taken back."""
    session, scenario, _, _, t, measurement, _ = replayed
    suite = scenario.sensor
    columns = _columns(session)
    position, heading = measurement[:, columns["measured_position"]], measurement[:, columns["measured_heading"]]
    fresh = [i for i in range(1, t.size) if not np.array_equal(position[i], position[i - 1], equal_nan=True)]
    assert len(fresh) > 70  # both receivers' fixes, 2 a second
    for i in fresh:
        samples = [
            jnp.asarray(measurement[i, columns[f"{name}.{signal.name}"]])
            for name, each in zip(suite.names, suite.instruments)
            for signal in each.signals
        ]
        combined = np.asarray(suite.combining.combine(suite.instruments, samples, jnp.asarray(heading[i - 1, 0])))
        np.testing.assert_allclose(np.concatenate([position[i], heading[i]]), combined, rtol=0, atol=1e-12)
        # each receiver's fix held since it came, less than a second: the reference point within its motion
        assert np.abs(position[i] - _truth(t[i])[0]).max() < 0.06


def test_a_silent_source_is_a_dropout_the_observer_rides_through(replayed):
    session, _, _, outcome, t, measurement, estimates = replayed
    assert session.refused == 0 and outcome.failure is None
    assert outcome.steps == t.size and t.size > 390
    settled = t > 20.0
    error = np.array([np.abs(estimates["position"][i][:2] - _truth(t[i])[0]).max() for i in np.flatnonzero(settled)])
    assert error.max() < 1.0
    assert not np.asarray(estimates["outage_position"]).any()


def test_one_receiver_silent_the_other_carries_the_position(tmp_path):
    """The log without dgnss2: the combined position is dgnss1's alone, and no outage."""
    log = _log(tmp_path / "full.nmea", seconds=20.0)
    kept = [line for line in log.read_text().splitlines() if "s:dgps2" not in line]
    one = tmp_path / "one.nmea"
    one.write_text("\n".join(kept) + "\n")
    session, scenario = _session()
    outcome, t, measurement, estimates = _replayed(session, one)
    assert session.sensors["dgnss2"].counts["accepted"] == 0
    assert np.isnan(measurement[:, 2:4]).all() and np.isfinite(measurement[5:, 7:9]).all()
    assert not np.asarray(estimates["outage_position"][5:]).any()


def test_one_step_per_call_equals_the_scan(replayed):
    """The live path (one compiled call per step, each heading stepping at once) gives the fast replay's estimates."""
    *_, log, _, t, measurement, estimates = replayed
    session, _ = _session(batch=1)
    outcome, stepped_t, stepped_measurement, stepped = _replayed(session, log)
    assert session.refused == 0
    np.testing.assert_array_equal(stepped_t, t)
    np.testing.assert_array_equal(stepped_measurement, measurement)
    for name in ("position", "velocity", "bias_force"):
        np.testing.assert_allclose(stepped[name], estimates[name], rtol=1e-12, atol=1e-12 * np.abs(estimates[name]).max())


# ---------------------------------------------------------------- what is refused
def test_a_bad_source_is_refused_at_its_key():
    document = _document()
    document["sensors"]["gyro1"]["source"] = "he"
    with pytest.raises(CompositionError, match=r"^sensors\.gyro1\.source: source must be TALKER"):
        compose(document)
    document = _document()
    document["sensors"]["dgnss2"]["source"] = "HE"
    with pytest.raises(ValueError, match=r"sensors\.dgnss2\.source: 'HE' is a heading talker"):
        _session(document)
    document = _document()
    document["sensors"]["dgnss2"]["source"] = "GP@dgps1"
    with pytest.raises(ValueError, match=r"sensors\.dgnss2\.source: 'GP@dgps1' is sensor dgnss1's source too"):
        _session(document)
    document = _document()
    for table in document["sensors"].values():
        table.pop("source")
    with pytest.raises(ValueError, match="no sensor names a source"):
        _session(document)
    with pytest.raises(ValueError, match="a scenario's named sensors each name their own source"):
        _session(sources={"GP": "dgps"})


def test_an_observer_of_an_instruments_channel_is_refused():
    """Live data feeds the combined channels alone: an observer that reads a sensor's own is refused, not fed zeros."""
    from lookout.components import Layout

    scenario = compose(_document()).scenario
    suite = scenario.sensor
    signals = {signal.name: signal for signal in suite.measurement_layout.signals}
    observer = copy.copy(scenario.observer)  # the passive observer, reading a receiver's own channel
    object.__setattr__(observer, "measurement_layout", Layout((signals["dgnss1.measured_position"], signals["measured_heading"])))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        with pytest.raises(ValueError, match=r"reads dgnss1\.measured_position; live data feeds it the combining stage's"):
            Session(observer, scenario.sample_period, suite=suite)


@pytest.mark.slow
def test_the_source_key_leaves_the_simulation_as_it_was():
    document = _document()
    document["simulation"]["duration"] = 3.0
    plain = copy.deepcopy(document)
    for table in plain["sensors"].values():
        table.pop("source")
    sourced, unsourced = compose(document), compose(plain)
    assert sourced.document["sensors"]["gyro1"]["source"] == "HE" and "source" not in unsourced.document["sensors"]["gyro1"]
    ours, theirs = simulate(sourced).to_xarray(), simulate(unsourced).to_xarray()
    for name in ("measured_position", "dgnss1.measured_position", "gyro2.measured_heading", "position_hat"):
        np.testing.assert_array_equal(ours[name].values, theirs[name].values)


def test_a_session_reads_a_fix_of_no_sensor_as_other_source():
    session, _ = _session()
    assert session.feed(Reading(0.01, "GP@dgps9", "position", (63.44, 10.40, 2.0, 0.8), "GGA")) == []
    assert session.channels["position"].counts["other_source"] == 1 and session.frame == ORIGIN


# ---------------------------------------------------------------- the command line
def _cli(arguments, capsys, monkeypatch, folder: Path):
    monkeypatch.chdir(folder)
    code = main([str(a) for a in arguments])
    return code, capsys.readouterr().err.strip()


def test_replay_cli_records_each_sensor(tmp_path, capsys, monkeypatch):
    scenario = tmp_path / "bridge.toml"
    scenario.write_text(SCENARIO)
    log = _log(tmp_path / "bridge.nmea", seconds=20.0)
    out = tmp_path / "out" / "bridge.nc"
    code, err = _cli(["replay", log, "--scenario", scenario, "--origin", "63.44,10.40", "--out", out], capsys, monkeypatch, tmp_path)
    assert code == 0, err
    assert "dgnss1 1.00/s" in err and "hpr 0.00/s" in err
    with xr.open_dataset(out) as ds:
        for name in ("dgnss1.measured_position", "dgnss2.measured_position", "gyro1.measured_heading", "measured_position", "position_hat"):
            assert name in ds, name
        assert ds["dgnss1.measured_position"].attrs["units"] == "m"


def test_a_bad_source_is_one_line_and_nothing_written(tmp_path, capsys, monkeypatch):
    scenario = tmp_path / "bridge.toml"
    scenario.write_text(SCENARIO.replace('source = "HC"', 'source = "HC@"'))
    log = _log(tmp_path / "bridge.nmea", seconds=5.0)
    out = tmp_path / "out" / "bridge.nc"
    code, err = _cli(["replay", log, "--scenario", scenario, "--out", out], capsys, monkeypatch, tmp_path)
    assert code == 2
    assert re.search(r"bridge\.toml: sensors\.gyro2\.source \(line \d+\): source must be TALKER, @SENDER or TALKER@SENDER", err), err
    assert "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- write-log of a suite
#: The fixture's position references and gyros, each with its channel.
CHANNELS = {name: f"{name}.measured_position" for name in ("dgnss1", "dgnss2", "hpr")} | {
    name: f"{name}.measured_heading" for name in ("gyro1", "gyro2")
}


def _write_log(tmp_path, capsys, monkeypatch, text: str, *options):
    scenario = tmp_path / "bridge.toml"
    scenario.write_text(text)
    return _cli(["write-log", scenario, "--out", tmp_path / "log", *options], capsys, monkeypatch, tmp_path)


def _quantum(frame: LocalFrame) -> np.ndarray:
    """The largest error (m, north and east) of a fix that made a GGA and was read back:
    half a step of its 7 decimals of minutes, and half of the 1e-10 degrees that
    pynmeagps rounds its degrees to."""
    step = 0.5 * (1e-7 / 60.0 + 1e-10)  # degrees
    north = frame.ned(frame.latitude + 1e-3, frame.longitude)[0] / 1e-3
    east = frame.ned(frame.latitude, frame.longitude + 1e-3)[1] / 1e-3
    return step * np.array([north, east])


@pytest.mark.slow
def test_write_log_of_a_suite_replays_into_each_sensor(tmp_path, capsys, monkeypatch):
    """lookout write-log of a suite writes each position reference's GGA and each gyro's
    THS with its own stamps (hpr names no source: @hpr is assumed), and the IMU's
    samples to a CSV log beside it; a replay with the scenario it writes gives every sentence to its sensor and
    records each sensor's simulated samples to the sentences' precision."""
    text = SCENARIO.replace('lever_arm = [0.0, 0.0]\nsource = "@hipap"', "lever_arm = [0.0, 0.0]")
    text = text.replace("[observer]", '[sensors.imu]\nkind = "imu"\n\n[observer]')
    code, err = _write_log(tmp_path, capsys, monkeypatch, text, "--outage", "20,10")
    assert code == 0, err
    lines = err.splitlines()
    assert "sensor imu: time,fx,fy,r to dp-vessel-imu.csv, every 0.1 s" in lines and not any("not written" in line for line in lines)
    assert "sensor hpr: GGA as GP, tag block s:hpr, every 2 s (it names no source: source '@hpr' assumed)" in lines
    assert "sensor gyro2: THS as HC, every 0.1 s" in lines
    folder = tmp_path / "log"
    written = tomllib.loads((folder / "dp-vessel-scenario.toml").read_text())
    assert {name: table.get("source") for name, table in written["sensors"].items()} == {
        "dgnss1": "GP@dgps1",
        "dgnss2": "GP@dgps2",
        "hpr": "@hpr",
        "gyro1": "HE",
        "gyro2": "HC",
        "imu": None,
    }
    log = (folder / "dp-vessel.nmea").read_text()
    assert set(re.findall(r"\\s:(\w+)\*", log)) == {"dgps1", "dgps2", "hpr"} and "sensor imu" not in log
    header = (folder / "dp-vessel.csv").read_text().splitlines()[0]
    assert header == "time,dgnss1.north,dgnss1.east,dgnss2.north,dgnss2.east,hpr.north,hpr.east,gyro1.heading,gyro2.heading"

    session, scenario = _session(written)
    blocks = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        outcome = replay(session, folder / "dp-vessel.nmea", thrust=folder / "dp-vessel-thrust.csv", emit=blocks.append)
    h = scenario.sample_period
    k = np.rint((np.concatenate([b.time for b in blocks]) - EPOCH) / h).astype(int)  # the simulation's step of each replayed step
    measurement = np.concatenate([b.measurement for b in blocks])
    columns = _columns(session)
    with xr.open_dataset(folder / "dp-vessel-truth.nc") as truth:
        simulated = {name: truth[channel].values[0] for name, channel in CHANNELS.items()}
        imu = np.column_stack([truth["imu.measured_specific_force"].values[0], np.degrees(truth["imu.measured_yaw_rate"].values[0])])
    # the IMU's samples, one row each, within the step before the record that holds it, bit for bit
    rows = np.loadtxt(folder / "dp-vessel-imu.csv", delimiter=",", skiprows=1)
    assert rows.shape == (600, 4) and np.array_equal(rows[:, 1:], imu)
    assert np.all((rows[:, 0] - EPOCH <= np.arange(600) * h) & (rows[:, 0] - EPOCH > (np.arange(600) - 1) * h))
    # every sentence went to its sensor: the samples written (outside the outage for a fix, finite), and 2 wild fixes each
    outage = (np.arange(600) * h >= 20.0) & (np.arange(600) * h < 30.0)
    expected = {}
    for name, sample in simulated.items():
        every = round(scenario.sensor.instruments[scenario.sensor.names.index(name)].sample_period / h)
        due = (np.arange(600) % every == 0) & np.isfinite(sample.reshape(600, -1)).all(axis=1)
        expected[name] = int((due & ~outage).sum()) + 2 if sample.ndim == 2 else int(due.sum())
    assert {name: sensor.counts["accepted"] for name, sensor in session.sensors.items()} == expected
    assert "other_source" not in session.unused and outcome.rejected == {"checksum": 30, "malformed": 1}  # 6 corrupted of each sensor
    # each sensor's record where its sample arrived: the simulated sample, to the sentence's precision
    bound = _quantum(ORIGIN) * (1 + 1e-6)
    for name in ("dgnss1", "dgnss2", "hpr"):
        every = round(scenario.sensor.instruments[scenario.sensor.names.index(name)].sample_period / h)
        fresh = (k % every == 0) & ~outage[k]
        error = np.abs(measurement[fresh][:, columns[f"{name}.measured_position"]] - simulated[name][k[fresh]])
        assert fresh.sum() >= 40 // (every // 10) and (error.max(axis=0) <= bound).all(), (name, error.max(axis=0), bound)
    # THS has 5 decimals of degrees; the replay steps at gyro1's heading (each instant's first), so gyro2's lands a step later
    for name, late in (("gyro1", 0), ("gyro2", 1)):
        recorded = measurement[1:, columns[f"{name}.measured_heading"]][:, 0]
        error = np.abs(np.angle(np.exp(1j * (recorded - simulated[name][k[1:] - late]))))
        assert error.max() <= math.radians(0.5e-5) * (1 + 1e-6), (name, error.max())
    assert np.asarray(np.concatenate([b.estimate["outage_position"] for b in blocks]))[(k * h > 23.0) & (k * h < 30.0)].all()


def test_write_log_refuses_a_suite_it_cannot_log(tmp_path, capsys, monkeypatch):
    """Two sensors a replay could not tell apart, and a suite without a gyro: one line, exit 2, nothing written."""
    code, err = _write_log(tmp_path, capsys, monkeypatch, SCENARIO.replace('source = "@hipap"', 'source = "@dgps1"'))
    assert code == 2 and "\n" not in err, err
    assert re.search(
        r"^error: \S*bridge\.toml: sensors\.hpr\.source: '@dgps1': its sentences, written GGA as GP with tag block s:dgps1, would go to sensor dgnss1",
        err,
    )
    assert not (tmp_path / "log").exists()
    from lookout.live.suite_log import suite_log
    from lookout.sensing.motion import InertialUnit
    from lookout.sensing.position import GnssReceiver
    from lookout.sensing.suite import SensorSuite

    with pytest.raises(ValueError, match=r"it has no gyrocompass \(sensors: dgnss1 gnss, imu imu\)$"):
        suite_log(SensorSuite({"dgnss1": GnssReceiver(), "imu": InertialUnit()}))
