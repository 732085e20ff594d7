"""Live data (lookout.live): replay equals the simulation on its own samples, the
example log, a position outage, live over UDP, 24 hours in flat memory, and the CLI's
refusals."""

from __future__ import annotations

import json
import math
import socket
import threading
import time
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.composition import compose, simulate
from lookout.io.geodesy import LocalFrame
from lookout.io.nmea import Reading
from lookout.io.simulated_log import write_simulated_log
from lookout.live.run import Latencies, live, open_source, replay
from lookout.live.session import Gates, Session


EXAMPLE = Path(__file__).parents[1] / "examples"
LOGS = EXAMPLE / "logs"
ORIGIN = LocalFrame(63.44, 10.40)  # the example log's (lookout write-log's default)
# the GGA fields' quantization: 7 decimals of arc minutes, 1e-7 * 1852 m of latitude
GGA_STEP = 1e-7 * 1852.0
# THS's: 5 decimals of degrees
THS_STEP = math.radians(1e-5)


def _composition(duration: float):
    document = tomllib.loads((EXAMPLE / "live-dp.toml").read_text())
    document["simulation"]["duration"] = duration
    return compose(document)


def _replay(composition, log, thrust, batch=4096, **gates):
    scenario = composition.scenario
    session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN, batch=batch, gates=Gates(**gates))
    blocks = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        outcome = replay(session, log, thrust=thrust, emit=blocks.append)
    estimates = {name: np.concatenate([b.estimate[name] for b in blocks]) for name in blocks[0].estimate}
    return session, outcome, np.concatenate([b.session_time for b in blocks]), estimates, np.concatenate([b.measurement for b in blocks])


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """A 240 s run of the example scenario, its logs with no outage and no corruption."""
    composition = _composition(240.0)
    ds = simulate(composition).to_xarray()
    folder = tmp_path_factory.mktemp("log")
    paths = write_simulated_log(ds, folder, outage=None, corrupted=0, wild_points=0)
    return composition, ds, paths


@pytest.mark.xdist_group("live replay")
def test_replay_of_a_full_precision_log_equals_the_simulation(simulated):
    composition, ds, paths = simulated
    session, outcome, t, estimates, measurement = _replay(composition, paths["csv"], paths["thrust"])
    assert session.steps == ds.sizes["time"] and outcome.steps == ds.sizes["time"]
    np.testing.assert_array_equal(t, ds["time"].values)
    # the samples the observer used are the simulation's, bit for bit but for the degree round trip of heading
    np.testing.assert_array_equal(measurement[:, :2], ds["measured_position"].values[0])
    np.testing.assert_allclose(measurement[:, 2], ds["measured_heading"].values[0], rtol=0, atol=1e-15)
    for name in ("position", "heading", "velocity", "yaw_rate", "wave_position", "bias_force"):
        scale = max(1.0, float(np.abs(ds[f"{name}_hat"].values).max()))
        np.testing.assert_allclose(estimates[name], ds[f"{name}_hat"].values[0], rtol=0, atol=1e-9 * scale, err_msg=name)


@pytest.mark.xdist_group("live replay")
def test_one_step_per_call_equals_the_scan(simulated):
    composition, _, paths = simulated
    *_, scanned, _ = _replay(composition, paths["csv"], paths["thrust"])
    session, _, _, stepped, _ = _replay(composition, paths["csv"], paths["thrust"], batch=1)
    assert session.refused == 0
    for name in ("position", "velocity", "bias_force"):
        np.testing.assert_allclose(stepped[name], scanned[name], rtol=1e-12, atol=1e-12 * np.abs(scanned[name]).max())


def test_the_example_log(tmp_path):
    """examples/logs/dp-vessel.nmea: the estimates of the run behind it within the NMEA
    fields' quantization before the outage; the corrupted lines counted, the two wild
    points gated, the outage reported."""
    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc")
    composition = _composition(float(truth["time"].values[-1]) + 0.1)
    session, outcome, t, estimates, _ = _replay(composition, LOGS / "dp-vessel.nmea", LOGS / "dp-vessel-thrust.csv")
    before = t < 300.0  # the log's outage starts at 300 s
    np.testing.assert_array_equal(t, truth["time"].values[: t.size])
    # a low-pass of samples each off by at most half a step: within one step
    assert np.abs(estimates["position"][before] - truth["position_hat"].values[0, : t.size][before]).max() < GGA_STEP
    assert np.abs(estimates["heading"][before] - truth["heading_hat"].values[0, : t.size][before]).max() < THS_STEP
    assert session.channels["position"].counts["gated"] == 2
    assert outcome.rejected == {"checksum": 6, "malformed": 1}
    assert session.event_counts["outage"] == 1 and session.event_counts["recovered"] == 1


def _dominant_time_constant(observer) -> float:
    """1 / the slowest decay rate of the observer's linearized dynamics (its dominant pole)."""
    import jax
    import jax.numpy as jnp
    from jax.flatten_util import ravel_pytree

    y = jnp.zeros(observer.measurement_layout.size)
    flat, unravel = ravel_pytree(observer.init(y, observer.guess()))
    jacobian = jax.jacobian(lambda v: ravel_pytree(observer.vector_field(0.0, unravel(v), y, jnp.zeros(3)))[0])(flat)
    return 1.0 / float(np.min(-np.linalg.eigvals(np.asarray(jacobian)).real))


@pytest.mark.xdist_group("live replay")
def test_a_60_s_position_outage(simulated, tmp_path):
    composition, ds, _ = simulated
    paths = write_simulated_log(ds, tmp_path, outage=(120.0, 60.0), corrupted=0, wild_points=0)
    session, _, t, estimates, measurement = _replay(composition, paths["csv"], paths["thrust"])
    error = np.linalg.norm(estimates["position"] - ds["position"].values[0], axis=1)
    outage = np.isnan(measurement[:, 0])
    # the fix is held for the timeout (2.5 s) after the last one at 119 s, then dead reckoning to the first at 180 s
    np.testing.assert_array_equal(np.flatnonzero(outage)[[0, -1]], [np.searchsorted(t, 121.5), np.searchsorted(t, 179.9)])
    band = error[(t >= 40.0) & (t < 120.0)].max()
    # drift: at most dead reckoning's from the errors where it starts (the fix held
    # 2.5 s has added to them): |v~0| T + a T^2 / 2, a the bias force error plus 3 sigma
    # of the Gauss-Markov bias's change over T, over the smaller of the masses
    # (damping, which only slows the drift, left out)
    start, length = np.searchsorted(t, 121.5), 179.9 - 121.5
    plant = composition.scenario.plant
    velocity_error = np.linalg.norm(ds["velocity"].values[0, start] - estimates["velocity"][start])
    bias_std = np.asarray(plant.bias.noise_gain)[:2] * np.sqrt(np.asarray(plant.bias.time_constant)[:2] / 2)
    change = 3 * np.linalg.norm(bias_std * np.sqrt(2 * length / np.asarray(plant.bias.time_constant)[:2]))
    acceleration = (np.linalg.norm(ds["bias_force"].values[0, start] - estimates["bias_force"][start]) + change) / np.diag(plant.vessel.mass_matrix)[:2].min()
    bound = error[start] + velocity_error * length + acceleration * length**2 / 2
    assert error[outage].max() <= bound, f"drift to {error[outage].max():.2f} m; dead reckoning's bound {bound:.2f} m"
    # back inside the band before the outage, for good, within one time constant of the observer
    tau = _dominant_time_constant(composition.scenario.observer)
    after = t >= 180.0
    outside = np.flatnonzero(after & (error > band))
    recovered = (t[outside[-1]] if outside.size else 180.0) - 180.0
    assert recovered < tau, f"recovered after {recovered:.1f} s; the observer's time constant is {tau:.0f} s"
    assert session.event_counts == {"outage": 1, "recovered": 1, "gated": 0, "source": 2, "refused": 0}


def test_live_over_udp(tmp_path):
    """A bounded sender on 127.0.0.1, the estimates back over UDP, latency measured, and
    the session stops by itself when the sender stops."""
    composition = _composition(1.0)
    scenario = composition.scenario
    session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN)
    session.warm_up()
    source = open_source("udp://127.0.0.1:0")
    port = source[1].getsockname()[1]
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(0.1)
    from lookout.io.simulated_log import gga, ths
    from lookout.live.output import Publisher

    publisher = Publisher(f"udp://127.0.0.1:{receiver.getsockname()[1]}", frame_of=lambda: session.frame)
    rng = np.random.default_rng(1)
    position, heading = rng.normal(0.0, 0.5, (40, 2)), rng.normal(0.0, 0.002, 40)

    def send():
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for k in range(40):  # 4 s at 10 Hz: THS every step, GGA every tenth, the two in one datagram
            lines = [ths(math.degrees(heading[k]))]
            if k % 10 == 0:
                latitude, longitude, _ = ORIGIN.geodetic(position[k, 0], position[k, 1], 0.0)
                lines.append(gga(k * 0.1, float(latitude), float(longitude)))
            sender.sendto(("\r\n".join(lines) + "\r\n").encode(), ("127.0.0.1", port))
            time.sleep(0.1)
        sender.close()

    thread = threading.Thread(target=send)
    thread.start()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        outcome = live(session, source, emit=publisher, idle=1.5)
    thread.join()
    source[1].close()
    received = []
    while True:
        try:
            received.append(json.loads(receiver.recv(65536)))
        except TimeoutError:
            break
    receiver.close()
    assert outcome.readings == 44
    # steps from the first complete measurement to 1.5 s after the last datagram
    assert 35 <= outcome.steps <= 60 and len(received) == outcome.steps
    assert all(np.isfinite(r["position"]).all() for r in received)
    assert set(received[0]) >= {"time", "session_time", "position", "velocity", "bias_force", "latitude_hat", "longitude_hat"}
    latency = outcome.latency.percentiles()
    assert 0 < latency[50] <= latency[99] < 0.5  # measured; at most one sample period of waiting plus the step


def test_a_day_of_10_hz_data_in_flat_memory():
    """24 h of position (1 Hz) and heading (10 Hz) readings: the session's memory does
    not grow with the readings (resident set measured after 2 h and after 24 h)."""
    import resource  # noqa: F401  (POSIX: the test needs /proc or ru_maxrss)

    composition = _composition(1.0)
    scenario = composition.scenario
    session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN, batch=4096)
    steps = []

    def resident() -> int:
        with open("/proc/self/statm") as handle:
            return int(handle.read().split()[1]) * 4096

    rng = np.random.default_rng(0)
    marks = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for k in range(24 * 36000):
            t = 1e6 + k * 0.1 - 0.03
            for reading in ([Reading(t, "GP", "local_position", (rng.normal(0, 0.5), rng.normal(0, 0.5)), "CSV")] if k % 10 == 0 else []) + [
                    Reading(t + 0.01, "HE", "heading", (rng.normal(0, 0.1),), "CSV")]:
                steps.extend(len(block) for block in session.advance(reading.time))
                steps.extend(len(block) for block in session.feed(reading))
            if k == 2 * 36000:
                marks["2 h"] = resident()
        steps.extend(len(block) for block in session.advance(1e6 + 24 * 3600.0))
        steps.extend(len(block) for block in session.finish())
        marks["24 h"] = resident()
    assert sum(steps) == session.steps == 24 * 36000
    assert len(session.events) <= 1000
    grown = marks["24 h"] - marks["2 h"]
    assert grown < 16e6, f"memory grew {grown / 1e6:.1f} MB from 2 h to 24 h"


def test_a_refused_steps_row_publishes_without_a_position():
    from lookout.live.output import json_line
    from lookout.live.session import Block

    block = Block(np.array([1.0]), np.array([0.0]), {"position": np.full((1, 2), np.nan)}, np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1))
    line = json.loads(json_line(block, 0, ORIGIN))
    assert line["position"] == [None, None] and "latitude_hat" not in line


def test_latencies_keep_a_fixed_window():
    latencies = Latencies(size=4)
    assert latencies.percentiles() == {}
    for value in (1.0, 2.0, 3.0, 4.0, 100.0, 100.0, 100.0, 100.0):
        latencies.add(value)
    assert latencies.percentiles() == {50: 100.0, 99: 100.0, 100: 100.0}
    latencies.add(7.0)
    np.testing.assert_array_equal(latencies.values(), [100.0, 100.0, 100.0, 7.0])


def test_session_refusals():
    composition = _composition(1.0)
    observer = composition.scenario.observer
    with pytest.raises(ValueError, match="sample_period must be a finite positive number"):
        Session(observer, 0.0)
    with pytest.raises(ValueError, match="batch must be a positive integer"):
        Session(observer, 0.1, batch=0)
    with pytest.raises(ValueError, match="position_gate must be a finite positive number; got nan"):
        Gates(position_gate=float("nan"))
    with pytest.raises(ValueError, match="min_quality must be an integer GGA fix quality in 0..9"):
        Gates(min_quality=12)
    arm = compose(tomllib.loads((EXAMPLE / "velocity-two-link-arm.toml").read_text())).scenario.observer
    with pytest.raises(ValueError, match="live data fills measured_position"):
        Session(arm, 0.001)


def test_fix_quality_hdop_and_a_second_receiver():
    composition = _composition(1.0)
    scenario = composition.scenario
    session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, gates=Gates(min_quality=2, max_hdop=2.0))
    lat, lon = 63.44, 10.40
    session.feed(Reading(0.01, "GP@a", "position", (lat, lon, 1.0, 0.8), "GGA"))  # GPS only: refused
    session.feed(Reading(0.02, "GP@a", "position", (lat, lon, 2.0, 3.5), "GGA"))  # HDOP: refused
    session.feed(Reading(0.025, "GP@a", "position", (lat, lon, 6.0, 0.8), "GGA"))  # the receiver's own dead reckoning: refused
    session.feed(Reading(0.03, "GP@a", "position", (lat, lon, 2.0, 0.8), "GGA"))
    session.feed(Reading(0.04, "GP@b", "position", (lat + 1e-5, lon, 2.0, 0.8), "GGA"))  # the other receiver, while a speaks
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        (block,) = session.feed(Reading(0.05, "HE", "heading", (10.0,), "THS"))  # the step at 0.1 s, at once
    counts = session.channels["position"].counts
    assert (counts["quality"], counts["hdop"], counts["accepted"], counts["other_source"]) == (2, 1, 1, 1)
    # a second gyro while the first speaks: counted, and it takes no step
    assert session.feed(Reading(0.11, "HE@b", "heading", (12.0,), "THS")) == []
    assert session.channels["heading"].counts["other_source"] == 1
    assert session.frame == LocalFrame(lat, lon)
    assert block.time[0] == pytest.approx(0.1)
    np.testing.assert_allclose(block.measurement[0], [0.0, 0.0, math.radians(10.0)], atol=1e-12)
    # a is silent past the timeout: b takes over
    session.feed(Reading(3.0, "GP@b", "position", (lat + 1e-5, lon, 2.0, 0.8), "GGA"))
    assert session.channels["position"].source == "GP@b"
    late = session.late
    assert session.feed(Reading(2.5, "HE", "heading", (11.0,), "THS")) == []  # before the reading before it
    assert session.late == late + 1


# ---------------------------------------------------------------- the command line
def test_replay_cli_writes_the_session(tmp_path, capsys):
    out = tmp_path / "replay.nc"
    code = main(["replay", str(LOGS / "dp-vessel.csv"), "--scenario", str(EXAMPLE / "live-dp.toml"), "--thrust", str(LOGS / "dp-vessel-thrust.csv"),
                 "--out", str(out), "--quiet"])
    assert code == 0
    ds = xr.open_dataset(out)
    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc")
    assert ds.sizes["time"] == truth.sizes["time"]
    for name in ("position_hat", "velocity_hat", "innovation_position", "measured_position", "force_applied", "gated_position", "outage_position"):
        assert name in ds
    assert ds["position_hat"].attrs["units"] == "m" and ds.attrs["Conventions"].startswith("CF")
    assert int(ds["outage_position"].sum()) > 250


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["replay", "missing.nmea", "--scenario", "examples/live-dp.toml"], "LOG must be an existing file; got missing.nmea"),
        (["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--speed", "0"], "--speed must be a finite positive factor"),
        (["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--speed", "2", "--fast"], "--speed and --fast exclude each other"),
        (["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--position-gate", "-1"], "--position-gate must be a finite positive number"),
        (["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--origin", "95,10"], "--origin must be LAT,LON in degrees (latitude must be"),
        (["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--out", "x.txt"], "--out must name a NetCDF file ending in .nc"),
        (["replay", "examples/logs/dp-vessel-thrust.csv", "--scenario", "examples/live-dp.toml"], "is a thrust log (time,surge,sway,yaw): give it with --thrust"),
        (["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/velocity-two-link-arm.toml"], "live data fills measured_position"),
        (["live", "examples/live-dp.toml", "--nmea", "udp://127.0.0.1:99999"], "--nmea must be udp://HOST:PORT with a port in 0..65535"),
        (["live", "examples/live-dp.toml", "--nmea", "/no/such/device"], "--nmea must be udp://HOST:PORT, - (stdin) or an existing device or file"),
        (["live", "examples/live-dp.toml", "--publish", "tcp://x:1"], "--publish must be udp://HOST:PORT"),
        (["live", "examples/live-dp.toml", "--nmea", "examples/logs/dp-vessel.nmea"], "is a regular file: its lines have no arrival times live"),
        (["live", "examples/live-dp.toml", "--idle", "-2"], "--idle must be a finite positive number of seconds"),
        (["write-log", "examples/live-dp.toml", "--outage", "1"], "--outage must be START,LENGTH in seconds"),
        (["write-log", "examples/velocity-two-link-arm.toml"], "the sensor must measure position and heading"),
    ],
)
def test_cli_refusals_are_one_line(arguments, message, capsys, monkeypatch):
    monkeypatch.chdir(Path(__file__).parents[1])
    assert main(arguments) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err
