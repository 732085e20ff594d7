"""Live data (lookout.live): replay equals the simulation on its own samples, the
example log, a position outage, live over UDP, 24 hours in flat memory, and the CLI's
refusals."""

from __future__ import annotations

import json
import math
import re
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
from lookout.io.geodesy import LocalFrame
from lookout.io.nmea import Reading
from lookout.io.simulated_log import EPOCH, write_simulated_log
from lookout.live.run import Latencies, live, open_source, replay
from lookout.live.session import Gates, Session
from lookout.scenario.composition import compose, simulate

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


@pytest.mark.slow
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


@pytest.mark.slow
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
    bound = _dead_reckoning_bound(composition, ds, estimates["velocity"], estimates["bias_force"], error, start, length)
    assert error[outage].max() <= bound, f"drift to {error[outage].max():.2f} m; dead reckoning's bound {bound:.2f} m"
    # back inside the band before the outage, for good, within one time constant of the observer
    tau = _dominant_time_constant(composition.scenario.observer)
    after = t >= 180.0
    outside = np.flatnonzero(after & (error > band))
    recovered = (t[outside[-1]] if outside.size else 180.0) - 180.0
    assert recovered < tau, f"recovered after {recovered:.1f} s; the observer's time constant is {tau:.0f} s"
    assert session.event_counts == {"outage": 1, "recovered": 1, "gated": 0, "source": 2, "refused": 0, "gap": 0}


@pytest.mark.slow
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


@pytest.mark.slow
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
                Reading(t + 0.01, "HE", "heading", (rng.normal(0, 0.1),), "CSV")
            ]:
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
    assert session.channels["position"].source == "GNSS@b"  # GP, GN, ... of one sender: one GNSS receiver
    late = session.late
    assert session.feed(Reading(2.5, "HE", "heading", (11.0,), "THS")) == []  # before the reading before it
    assert session.late == late + 1


# ---------------------------------------------------------------- the command line
def test_replay_cli_writes_the_session(tmp_path, capsys):
    out = tmp_path / "replay.nc"
    code = main(
        [
            "replay",
            str(LOGS / "dp-vessel.csv"),
            "--scenario",
            str(EXAMPLE / "live-dp.toml"),
            "--thrust",
            str(LOGS / "dp-vessel-thrust.csv"),
            "--out",
            str(out),
            "--quiet",
        ]
    )
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
        (
            ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--speed", "0"],
            "--speed must be a finite positive factor",
        ),
        (
            ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--speed", "2", "--fast"],
            "--speed and --fast exclude each other",
        ),
        (
            ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--position-gate", "-1"],
            "--position-gate must be a finite positive number",
        ),
        (
            ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--origin", "95,10"],
            "--origin must be LAT,LON in degrees (latitude must be",
        ),
        (
            ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--out", "x.txt"],
            "--out must name a NetCDF file ending in .nc",
        ),
        (
            ["replay", "examples/logs/dp-vessel-thrust.csv", "--scenario", "examples/live-dp.toml"],
            "is a thrust log (time,surge,sway,yaw): give it with --thrust",
        ),
        (["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/velocity-two-link-arm.toml"], "live data fills measured_position"),
        (
            ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--format", "nmea"],
            "--format must be auto, raw, timed or csv",
        ),
        (
            ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--format", "csv"],
            "a CSV log's first line must be time,north,east,heading, time,surge,sway,yaw or time,fx,fy,r; this is a TIME SENTENCE NMEA log: leave the format out (auto), or give timed",
        ),
        (
            ["replay", "examples/logs/dp-vessel-raw.nmea", "--scenario", "examples/live-dp.toml", "--variation", "200"],
            "--variation must be degrees within -180 to 180",
        ),
        (
            ["replay", "examples/logs/dp-vessel-raw.nmea", "--scenario", "examples/live-dp.toml", "--format", "timed"],
            "no line has a time",
        ),
        (["write-log", "examples/dp-suite.toml", "--raw"], "--raw writes the log of one receiver and one gyro"),
        (
            ["replay", "examples/logs/dp-vessel-raw.nmea", "--scenario", "examples/live-dp.toml", "--waves"],
            "--waves is for a replay without --scenario",
        ),
        (["live", "examples/live-dp.toml", "--nmea", "udp://127.0.0.1:99999"], "--nmea must be udp://HOST:PORT with a port in 0..65535"),
        (
            ["live", "examples/live-dp.toml", "--nmea", "/no/such/device"],
            "--nmea must be udp://HOST:PORT, - (stdin) or an existing serial device or FIFO",
        ),
        (["live", "examples/live-dp.toml", "--publish", "tcp://x:1"], "--publish must be udp://HOST:PORT"),
        (["live", "examples/live-dp.toml", "--nmea", "examples/logs/dp-vessel.nmea"], "is a regular file: its lines have no arrival times live"),
        (["live", "examples/live-dp.toml", "--idle", "-2"], "--idle must be a finite positive number of seconds"),
        (["live", "examples/live-dp.toml", "--variation", "nan"], "--variation must be degrees within -180 to 180"),
        (["write-log", "examples/live-dp.toml", "--outage", "1"], "--outage must be START,LENGTH in seconds"),
        (["write-log", "examples/velocity-two-link-arm.toml"], "the sensor must measure position and heading"),
    ],
)
def test_cli_refusals_are_one_line(arguments, message, capsys, monkeypatch):
    monkeypatch.chdir(Path(__file__).parents[1])
    assert main(arguments) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err


# ---------------------------------------------------------------- what replay refuses, before any step
def _nmea_rows():
    """The example log's (time, sentence) rows, without its comments."""
    rows = []
    for line in (LOGS / "dp-vessel.nmea").read_text().splitlines():
        if line and not line.startswith("#"):
            stamp, sentence = line.split(" ", 1)
            rows.append((float(stamp), sentence))
    return rows


def _written(path: Path, rows) -> Path:
    path.write_text("".join(f"{t:.6f} {sentence}\n" for t, sentence in rows))
    return path


def _start(rows) -> float:
    return rows[0][0]


#: Logs made from the example log that a replay refuses, and the refusal: its times run
#: backwards (reversed, a clock stepped back, shuffled), are not in seconds, stop for a
#: day, or it has nothing to give (every checksum fails, no fix sentence, empty, comments).
BAD_LOGS = {
    "reversed": (lambda rows: rows[::-1], r"its times run backwards: line \d+ is stamped 599.9\d* s before line 1 \(more than 2.5 s"),
    "clock stepped back": (
        lambda rows: [(t - 60.0 if t - _start(rows) > 300.0 else t, s) for t, s in rows],
        r"its times run backwards: line \d+ is stamped 59.\d+ s before line \d+ \(more than 2.5 s: a clock that stepped back",
    ),
    "shuffled": (
        lambda rows: [rows[i + 1 - 2 * (i % 2)] if i + 1 - 2 * (i % 2) < len(rows) else rows[i] for i in range(len(rows))],
        r"its times run backwards: \d+ of its 6579 timed lines are stamped before a line above them \(up to 1 % are replayed as reordered lines",
    ),
    "milliseconds": (
        lambda rows: [(1000.0 * t, s) for t, s in rows],
        r"its typical step between lines, 9\d.\d* s is too long for this observer: one prediction step multiplies a state error by .*are the times in seconds\?",
    ),
    "a day's gap": (
        lambda rows: [(t + (86400.0 if t - _start(rows) > 100.0 else 0.0), s) for t, s in rows],
        r"no line for 86400.\d* s before line 1101 \(99.9\d* s into the log\), longer than max_gap 60 s",
    ),
    "every checksum fails": (
        lambda rows: [(t, s[:-2] + ("00" if not s.endswith("00") else "11")) for t, s in rows],
        r"no line gives a position reading \(6579 lines: checksum 657\d, malformed \d\); the observer needs position and heading",
    ),
    "headings only": (lambda rows: [(t, s) for t, s in rows if "THS" in s], r"no line gives a position reading \(\d+ lines: heading 6000"),
    "comments only": (lambda rows: [], r"no line but comments and blank lines: nothing to replay"),
}


@pytest.fixture(scope="module")
def live_session_factory():
    composition = _composition(600.0)
    scenario = composition.scenario
    return lambda **options: Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN, batch=4096, **options)


@pytest.mark.parametrize("name", list(BAD_LOGS))
def test_replay_checks_a_logs_times_and_lines_before_any_step(tmp_path, live_session_factory, name):
    """check_replay (run by replay before its first step) refuses each, naming the log;
    nothing is stepped (no block is emitted)."""
    from lookout.live.run import check_replay

    change, message = BAD_LOGS[name]
    log = _written(tmp_path / "bad.nmea", change(_nmea_rows()))
    if name == "comments only":
        log.write_text("# a log of comments\n# and nothing else\n")
    session = live_session_factory()
    with pytest.raises(ValueError, match=message) as raised:
        check_replay(session, log)
    assert str(raised.value).startswith(f"LOG {log}") and "\n" not in str(raised.value)
    blocks = []
    with pytest.raises(ValueError):
        replay(session, log, emit=blocks.append)
    assert blocks == [] and session.steps == 0 and session.stepper is None  # nothing compiled, nothing stepped


def test_the_time_scale_test_is_lookout_filters(tmp_path, live_session_factory):
    """The milliseconds test of a replay is lookout.filter's step-amplification test at the
    log's typical step; a log in seconds whose lines are sparse (1 Hz, a step the observer
    cannot take in one prediction but shorter than the channels' timeouts) is replayed."""
    from lookout.io.logs import scan_log
    from lookout.live.run import check_replay
    from lookout.sim.filtering import MAX_STEP_AMPLIFICATION, step_amplification

    rows = _nmea_rows()
    milliseconds = _written(tmp_path / "ms.nmea", [(1000.0 * t, s) for t, s in rows])
    session = live_session_factory()
    observer = session.observer
    typical = scan_log(milliseconds).typical_step
    radius = step_amplification(observer, session.guess, np.zeros(3), np.zeros(3), typical)
    assert radius > MAX_STEP_AMPLIFICATION
    with pytest.raises(ValueError, match=re.escape(f"one prediction step multiplies a state error by {radius:.3g} ")):
        check_replay(session, milliseconds)
    # the same observer on a log whose rows are that far apart: lookout.filter's refusal, its words
    with pytest.raises(
        ValueError, match=r"too long for this observer: one prediction step multiplies a state error by .* are the times in seconds\?"
    ):
        lookout_filter(observer, [0.0, typical, 2 * typical], np.zeros((3, 3)))
    # a fix a second and a heading a second half a second later, in seconds: replayed
    sparse = _written(tmp_path / "sparse.nmea", [(t, s) for t, s in rows if "GGA" in s or round(10 * (t - _start(rows))) % 10 == 5])
    assert 0.2 < scan_log(sparse).typical_step < session.gap_after
    assert check_replay(session, sparse).log.usable["heading"] > 500


def lookout_filter(*args, **kwargs):
    import lookout

    return lookout.filter(*args, **kwargs)


def test_a_few_reordered_lines_are_replayed_and_counted_late(tmp_path, live_session_factory):
    from lookout.live.run import check_replay

    rows = _nmea_rows()
    for i in (100, 2000, 4000):  # three pairs of lines swapped by the logger
        rows[i], rows[i + 1] = rows[i + 1], rows[i]
    log = _written(tmp_path / "reordered.nmea", rows)
    check = check_replay(live_session_factory(), log)
    assert check.log.late == 3 and check.log.back < 0.2


def _cli(arguments, capsys, monkeypatch):
    monkeypatch.chdir(Path(__file__).parents[1])
    code = main([str(a) for a in arguments])
    err = capsys.readouterr().err.strip()
    return code, err


def _nothing_under(folder: Path) -> list:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("name", ["reversed", "milliseconds", "a day's gap", "every checksum fails"])
def test_a_refused_replay_leaves_nothing_behind(tmp_path, capsys, monkeypatch, name):
    change, message = BAD_LOGS[name]
    log = _written(tmp_path / "bad.nmea", change(_nmea_rows()))
    results = tmp_path / "results"
    code, err = _cli(
        [
            "replay",
            log,
            "--scenario",
            "examples/live-dp.toml",
            "--thrust",
            LOGS / "dp-vessel-thrust.csv",
            "--out",
            results / "new" / "r.nc",
            "--figure",
            results / "new" / "r.png",
        ],
        capsys,
        monkeypatch,
    )
    assert code == 2 and "\n" not in err and "Traceback" not in err
    assert re.search(message.replace("max_gap", "--max-gap"), err), err
    assert not results.exists()


def _bad_input_files(tmp_path: Path) -> dict:
    tmp_path.mkdir()
    files = {}
    files["binary"] = tmp_path / "image.nmea"
    files["binary"].write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 8)
    files["empty"] = tmp_path / "empty.nmea"
    files["empty"].write_bytes(b"")
    files["text"] = tmp_path / "truth.nc"
    files["text"].write_text("not NetCDF\n")
    thrust = (LOGS / "dp-vessel-thrust.csv").read_text().splitlines()
    files["thrust_ms"] = tmp_path / "thrust-ms.csv"
    files["thrust_ms"].write_text("\n".join([thrust[0]] + [f"{1000 * float(r.split(',')[0])!r}," + r.split(",", 1)[1] for r in thrust[1:]]) + "\n")
    files["thrust_nan"] = tmp_path / "thrust-nan.csv"
    files["thrust_nan"].write_text("\n".join([thrust[0]] + [r.split(",")[0] + ",nan,nan,nan" for r in thrust[1:]]) + "\n")
    session_file = tmp_path / "session.nc"  # a NetCDF without the truth's variables
    xr.Dataset({"position_hat": (("run", "time"), np.zeros((1, 3)))}, coords={"time": [0.0, 0.1, 0.2]}).to_netcdf(session_file)
    files["not_a_run"] = session_file
    return files


REFUSED = [
    # (arguments with {name} for the files above, the message)
    (
        ["replay", "{binary}", "--scenario", "examples/live-dp.toml"],
        r"^error: LOG .*image.nmea is not a text log: it holds binary data \(a log is text",
    ),
    (["replay", "{empty}", "--scenario", "examples/live-dp.toml"], r"^error: LOG .*empty.nmea is empty$"),
    (
        ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--thrust", "{binary}"],
        r"^error: --thrust .*image.nmea is not a text log",
    ),
    (
        ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--thrust", "{thrust_ms}"],
        r"^error: --thrust .*thrust-ms.csv: its times \(1796083\d+\.\d{3} to 1796083\d+\.\d{3} s\) do not overlap the log's \(1796083\d{3}\.\d{3} to 1796083\d{3}\.\d{3} s\); are both in seconds",
    ),
    (
        ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--thrust", "{thrust_nan}"],
        r"^error: --thrust .*thrust-nan.csv: no row gives a thrust \(6000 lines: missing 6000\)",
    ),
    (
        ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--figure", "{out}.png", "--truth", "{text}"],
        r"^error: --truth .*truth.nc: not a NetCDF file lookout can read",
    ),
    (
        ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--figure", "{out}.png", "--truth", "{not_a_run}"],
        r"^error: --truth .*session.nc has no heading, position, velocity: it must be a run of a vessel scenario",
    ),
    (
        ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--max-gap", "0"],
        r"^error: --max-gap must be a finite positive number of seconds; got 0$",
    ),
    (
        ["replay", "examples/logs/dp-vessel.nmea", "--scenario", "examples/live-dp.toml", "--gate-probability", "1"],
        r"^error: --gate-probability must be a probability strictly between 0 and 1; got 1.0$",
    ),
    (["live", "examples/live-dp.toml", "--nmea", "udp://127.0.0.1:99999"], r"^error: --nmea must be udp://HOST:PORT with a port in 0..65535"),
    (
        ["live", "examples/live-dp.toml", "--nmea", "udp://127.0.0.1:0", "--thrust", "tcp://127.0.0.1:5"],
        r"^error: --thrust must be udp://HOST:PORT, - \(stdin\) or an existing serial device or FIFO",
    ),
    (
        ["live", "examples/live-dp.toml", "--nmea", "udp://127.0.0.1:0", "--thrust", "examples/logs/dp-vessel-thrust.csv"],
        r"^error: --thrust .* is a regular file",
    ),
    (
        ["live", "examples/live-dp.toml", "--nmea", "examples/logs/dp-vessel.nmea"],
        r"^error: --nmea .* is a regular file: its lines have no arrival times live",
    ),
    (["live", "examples/live-dp.toml", "--nmea", "-", "--thrust", "-"], r"^error: --thrust and --nmea must be two sources; both are -$"),
    (
        ["write-log", "examples/live-dp.toml", "--outage", "700,30"],
        r"^error: --outage 700,30 ends at 730 s, after the run's end: its duration is 600 s \(give START \+ LENGTH <= 600, or none\)$",
    ),
    (["write-log", "examples/live-dp.toml", "--outage", "590,30"], r"^error: --outage 590,30 ends at 620 s, after the run's end"),
    (["write-log", "examples/live-dp.toml", "--outage", "100,0"], r"^error: --outage LENGTH must be positive \(none: no outage\)"),
    (["write-log", "examples/live-dp.toml", "--seed", "-1"], r"^error: --seed must be a non-negative integer; got -1$"),
    (["play", "{binary}", "--to", "udp://127.0.0.1:9"], r"^error: LOG .*image.nmea is not a text log"),
    (["play", "examples/logs/dp-vessel.csv", "--to", "udp://127.0.0.1:9"], r"^error: LOG .*dp-vessel.csv is a CSV log: play sends NMEA sentences"),
    (
        ["play", "examples/logs/dp-vessel.nmea", "--to", "udp://nosuchhost.invalid:9"],
        r"^error: --to udp://nosuchhost.invalid:9: cannot resolve the host",
    ),
]


@pytest.mark.parametrize("arguments, message", REFUSED, ids=[f"{a[0]}-{i}" for i, (a, _) in enumerate(REFUSED)])
def test_every_refusal_is_one_line_and_leaves_nothing_behind(tmp_path, capsys, monkeypatch, arguments, message):
    """Each command refuses bad files and values in one line, exit 2, before creating
    anything: --out (a file in new folders) and --figure are never made."""
    files = _bad_input_files(tmp_path / "inputs")
    results = tmp_path / "results"
    out = results / "new" / "r"
    arguments = [a.format(out=out, **{k: str(v) for k, v in files.items()}) for a in arguments]
    if arguments[0] in ("replay", "live"):
        arguments += ["--out", f"{out}.nc"]
    elif arguments[0] == "write-log":
        arguments += ["--out", str(results / "new" / "log")]
    code, err = _cli(arguments, capsys, monkeypatch)
    assert code == 2 and "\n" not in err and "Traceback" not in err, err
    assert re.search(message, err), err
    assert len(err) < 400  # no bytes or arrays dumped
    assert not results.exists()


@pytest.mark.xdist_group("live replay")
def test_a_silence_a_missing_thrust_and_reordered_lines(simulated, tmp_path, capsys, monkeypatch):
    """A 20 s silence of every channel is replayed and reported (where, how long); two
    swapped lines are counted late; thrust rows with a missing value are rejected, the
    previous thrust held, and the status line says so."""
    composition, ds, paths = simulated
    header, *rows = paths["csv"].read_text().splitlines()
    rows = [r for r in rows if not (EPOCH + 120.0 <= float(r.split(",")[0]) < EPOCH + 140.0)]
    for i in (500, 1500):
        rows[i], rows[i + 1] = rows[i + 1], rows[i]
    log = tmp_path / "log.csv"
    log.write_text("\n".join([header, *rows]) + "\n")
    thrust_header, *thrust_rows = paths["thrust"].read_text().splitlines()
    missing = range(600, 700)  # the thrust of steps 600..699 (60 to 70 s)
    thrust_rows = [r.split(",")[0] + ",nan,,nan" if k in missing else r for k, r in enumerate(thrust_rows)]
    thrust = tmp_path / "thrust.csv"
    thrust.write_text("\n".join([thrust_header, *thrust_rows]) + "\n")
    out = tmp_path / "replay.nc"
    code, err = _cli(
        ["replay", log, "--scenario", "examples/live-dp.toml", "--thrust", thrust, "--out", out, "--origin", "63.44,10.40"], capsys, monkeypatch
    )
    assert code == 0, err
    assert re.search(r"^gap at 1[12]\d.\d s into the session: no reading for 20.\d s \(every channel dead-reckoned\)$", err, re.M), err
    done = [line for line in err.splitlines() if line.startswith("done:")][0]
    assert (
        "thrust rejected 100 (missing 100: the previous thrust held)" in done
        and "; gaps 1;" in done
        and re.search(r"not used \d+ \(.*\blate 2\b", done)
    ), done
    session = xr.open_dataset(out)
    applied = session["force_applied"].values[0]
    np.testing.assert_array_equal(applied[missing.start : missing.stop], np.repeat(applied[missing.start - 1][None], len(missing), axis=0))
    assert np.abs(np.diff(ds["force_applied"].values[0, missing.start - 1 : missing.stop], axis=0)).max() > 0  # the run's own thrust did change
    # dead reckoning through the silence: within the bound from the errors where it starts
    t = session["time"].values
    error = np.linalg.norm(session["position_hat"].values[0] - ds["position"].values[0, : t.size], axis=1)
    silent = (t >= 122.5) & (t < 140.0)  # the fixes held 2.5 s, then nothing
    start = int(np.flatnonzero(silent)[0])
    bound = _dead_reckoning_bound(
        composition, ds, session["velocity_hat"].values[0], session["bias_force_hat"].values[0], error, start, 140.0 - t[start]
    )
    assert error[silent].max() <= bound, f"drift to {error[silent].max():.2f} m; dead reckoning's bound {bound:.2f} m"


def _dead_reckoning_bound(composition, ds, velocity_hat, bias_force_hat, error, start: int, length: float) -> float:
    """|v~0| T + a T^2 / 2 on the errors at step ``start``: a the bias force error plus 3
    sigma of the Gauss-Markov bias's change over T, over the smaller mass (damping, which
    only slows the drift, left out)."""
    plant = composition.scenario.plant
    velocity_error = np.linalg.norm(ds["velocity"].values[0, start] - velocity_hat[start])
    bias_std = np.asarray(plant.bias.noise_gain)[:2] * np.sqrt(np.asarray(plant.bias.time_constant)[:2] / 2)
    change = 3 * np.linalg.norm(bias_std * np.sqrt(2 * length / np.asarray(plant.bias.time_constant)[:2]))
    acceleration = (np.linalg.norm(ds["bias_force"].values[0, start] - bias_force_hat[start]) + change) / np.diag(plant.vessel.mass_matrix)[:2].min()
    return float(error[start] + velocity_error * length + acceleration * length**2 / 2)


def _wild_fix_arrivals() -> list[float]:
    """Arrival times of the example log's fixes that are 60 m off the run's own samples."""
    from lookout.io.nmea import NmeaParser

    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc").isel(run=0)
    times, measured = truth["time"].values, truth["measured_position"].values
    parser, wild = NmeaParser(), []
    for t, sentence in _nmea_rows():
        for reading in parser.line(sentence, t):
            if reading.kind == "position":
                north, east, _ = ORIGIN.ned(reading.values[0], reading.values[1])
                k = min(int(np.searchsorted(times, t - 1796083200.0)), times.size - 1)
                if np.hypot(north - measured[k, 0], east - measured[k, 1]) > 30.0:
                    wild.append(t)
    return wild


@pytest.mark.slow
def test_a_kalman_filter_gates_the_example_logs_wild_fixes_on_nis():
    """Replaying the example log with the scenario's observer an EKF: the gate tests each
    reading's normalized innovation squared against the chi-square bound; the two wild
    fixes (60 m off) are gated, and no good fix or heading is."""
    document = tomllib.loads((EXAMPLE / "live-dp.toml").read_text())
    document["observer"] = {"kind": "ekf"}
    composition = compose(document)
    session, outcome, t, estimates, _ = _replay(composition, LOGS / "dp-vessel.nmea", LOGS / "dp-vessel-thrust.csv")
    assert session.gate_tests == {"position": "nis", "heading": "nis"} and session.ungated == ()
    assert session.gate_rule == "NIS > chi-square 99.99 %"
    wild = _wild_fix_arrivals()
    assert len(wild) == 2
    gated = [event["time"] for event in session.events if event["event"] == "gated"]
    assert session.channels["position"].counts["gated"] == 2 and session.channels["heading"].counts["gated"] == 0
    # each gated step is the one that took a wild fix: the first step at or after its arrival
    for arrival, step in zip(sorted(wild), sorted(gated)):
        assert 0.0 <= step - arrival < composition.scenario.sample_period
    assert np.all(np.isfinite(estimates["position"]))


def _kalman(kind: str):
    document = tomllib.loads((EXAMPLE / "live-dp.toml").read_text())
    document["observer"] = {"kind": kind}
    document["simulation"]["duration"] = 1.0
    return compose(document).scenario


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_a_kalman_filters_innovation_statistics(kind):
    """innovation_statistics at the prior: nu = y - h(x) (heading wrapped) and S = H P H^T + R
    (the sensor is linear in the state, so the unscented S is the same to rounding); a
    missing channel has zero innovation and unit variance. The gate's NIS of a fix 60 m
    off is far above the chi-square bound, that of the prediction itself zero."""
    import jax
    from scipy.stats import chi2

    from lookout.live.gate import GatedObserver

    scenario = _kalman(kind)
    observer = scenario.observer
    state = observer.init(jnp_zeros(3), scenario.initial_estimate)
    predicted = np.asarray(observer.measurement(state.mean))
    y = predicted + np.array([3.0, -4.0, 2 * np.pi + 0.01])
    nu, S = (np.asarray(a) for a in observer.innovation_statistics(state, y))
    np.testing.assert_allclose(nu, [3.0, -4.0, 0.01], rtol=0, atol=1e-9)
    H = np.asarray(jax.jacfwd(observer.measurement)(state.mean))
    expected = H @ np.asarray(state.covariance) @ H.T + np.asarray(observer.measurement_covariance)
    np.testing.assert_allclose(S, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
    nu, S = (np.asarray(a) for a in observer.innovation_statistics(state, np.array([np.nan, np.nan, predicted[2]])))
    np.testing.assert_array_equal(nu[:2], 0.0)
    np.testing.assert_array_equal(S[:2, :2], np.eye(2))
    # the gate: a fix 60 m north and 20 m west of the prediction is wild, the prediction is not
    gated = GatedObserver(observer, ("measured_position", "measured_heading"), [chi2.ppf(0.9999, 2), chi2.ppf(0.9999, 1)], [2.5, 1.0], 5)
    assert gated.tests == ("nis", "nis")
    start = gated.init(np.concatenate([predicted, [0.0, 0.0]]), scenario.initial_estimate)
    for offset, wild in (([60.0, -20.0], 1.0), ([0.0, 0.0], 0.0)):
        reading = np.concatenate([predicted[:2] + offset, [np.nan, 0.05, np.nan]])
        assert float(gated.update(start, 0.05, reading).gated[0]) == wild


def jnp_zeros(n):
    import jax.numpy as jnp

    return jnp.zeros(n)


def test_an_observer_the_gate_cannot_gate_is_said_so():
    """An observer with neither innovation statistics nor innovation outputs: its channels
    are not gated, and the session says so (a warning, Session.ungated, the status
    line's rule) instead of reporting "gated 0"."""
    import equinox as eqx
    import jax.numpy as jnp

    from lookout.components import Observer
    from lookout.models.vessel import VESSEL_INPUT
    from lookout.sensors import POSITION_HEADING

    passive = _composition(1.0).scenario.observer

    class Held(Observer):
        """The last measurement as the estimate: no innovation output."""

        estimate_signals: tuple = eqx.field(static=True, default=tuple(s for s in passive.estimate_signals if s.name in ("position", "heading")))
        extra_signals: tuple = eqx.field(static=True, default=())
        measurement_layout: object = eqx.field(static=True, default=POSITION_HEADING)
        input_layout: object = eqx.field(static=True, default=VESSEL_INPUT)
        sample_period: None = eqx.field(static=True, default=None)

        def guess(self):
            return jnp.zeros(3)

        def init(self, y0, guess):
            return guess

        def update(self, state, t, y):
            return jnp.where(jnp.isfinite(y), y, state)

        def output(self, state, y):
            return {"position": state[:2], "heading": state[2]}

        def predict(self, state, t, y, u, dt):
            return state

    with pytest.warns(UserWarning, match=r"observer Held gives no innovation for position, heading: wild points there are not gated"):
        session = Session(Held(), 0.1)
    assert session.ungated == ("position", "heading") and session.gate_rule == "off"
    # the passive observer's channels are gated on its innovation outputs
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        session = Session(passive, 0.1)
    assert session.gate_tests == {"position": "innovation", "heading": "innovation"}


def test_write_simulated_log_refuses_an_outage_outside_the_run(simulated, tmp_path):
    _, ds, _ = simulated  # a 240 s run
    for outage, message in (
        ((300.0, 30.0), r"outage \(300, 30\) ends at 330 s, after the run's end: its duration is 240 s"),
        ((230.0, 30.0), r"ends at 260 s, after the run's end"),
        ((10.0, 0.0), r"outage must be \(start, length\) with start >= 0 and length > 0"),
        ((float("nan"), 5.0), r"outage must be \(start, length\)"),
        ((1.0,), r"outage must be \(start, length\) in seconds, or None"),
    ):
        folder = tmp_path / "new"
        with pytest.raises(ValueError, match=message):
            write_simulated_log(ds, folder, outage=outage)
        assert not folder.exists()


def test_the_live_clock_never_steps_back():
    from lookout.live.run import unix_clock

    clock = unix_clock()
    readings = [clock() for _ in range(1000)]
    assert all(b >= a for a, b in zip(readings, readings[1:]))
    assert abs(readings[0] - time.time()) < 1.0


@pytest.mark.xdist_group("live replay")
def test_a_figure_refused_after_the_replay_takes_the_session_file_back(simulated, tmp_path, capsys, monkeypatch):
    """A truth short of the log's last step by one step (what the check before the replay
    lets through: it knows the session's steps to a step) is found when the figure is
    drawn: the command is refused and the session's file, written by then, is removed
    with its new folders."""
    _, ds, paths = simulated
    truth = tmp_path / "short-truth.nc"
    ds.isel(time=slice(0, -1)).to_netcdf(truth)
    results = tmp_path / "results"
    code, err = _cli(
        [
            "replay",
            paths["csv"],
            "--scenario",
            "examples/live-dp.toml",
            "--thrust",
            paths["thrust"],
            "--out",
            results / "a" / "r.nc",
            "--figure",
            results / "a" / "r.png",
            "--truth",
            truth,
            "--quiet",
        ],
        capsys,
        monkeypatch,
    )
    assert code == 2 and re.search(r"^error: --truth .*short-truth.nc: truth does not have the session's times", err), err
    assert not results.exists()
