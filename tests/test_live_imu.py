"""An IMU as its own stream (lookout.io.logs' time,fx,fy,r; lookout.live.session's
direct path): a Kalman filter on a suite's instruments, the IMU-aided observer among
them, replays a written log as it ran in simulation; a reading out of range or a log
of the wrong kind is refused in one line."""

from __future__ import annotations

import math
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.io.geodesy import LocalFrame
from lookout.io.logs import CsvLog, log_format, scan_log
from lookout.io.nmea import Reading
from lookout.io.simulated_log import EPOCH
from lookout.live.run import replay
from lookout.live.session import Session
from lookout.scenario.composition import compose

ORIGIN = LocalFrame(63.44, 10.40)
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "imu-dp.toml"
LOSS = (120.0, 60.0)  # every position reference silent (s of run time)


def _scenario_text() -> str:
    """examples/imu-dp.toml over 240 s, its ten-minute loss made one minute from 120 s."""
    text = EXAMPLE.read_text().replace("duration = 1800.0", "duration = 240.0")
    text = text.replace("start = 600.0                                   # s", f"start = {LOSS[0]}")
    text = text.replace("duration = 600.0                                # s", f"duration = {LOSS[1]}")
    text = text.replace("start = 600.0\nduration = 600.0", f"start = {LOSS[0]}\nduration = {LOSS[1]}")
    assert text.count(f"start = {LOSS[0]}") == 2 and "start = 600.0" not in text and "duration = 600.0" not in text
    return text


# ---------------------------------------------------------------- the CSV log
def test_an_imu_csv_log_gives_imu_readings(tmp_path):
    """time,fx,fy,r rows are IMU readings (the yaw rate kept in deg/s, as the heading's
    degrees); a row with an empty cell is missing, one that is not numbers malformed."""
    path = tmp_path / "imu.csv"
    path.write_text("time,fx,fy,r\n0.0,0.1,-0.2,1.5\n0.1,,0.0,0.0\n0.2,a,b,c\n0.3,0.05,0.0,-2.0\n")
    assert log_format(path) == "csv-imu"
    log = CsvLog(path, source="imu")
    readings = list(log)
    assert readings == [Reading(0.0, "imu", "imu", (0.1, -0.2, 1.5), "CSV"), Reading(0.3, "imu", "imu", (0.05, 0.0, -2.0), "CSV")]
    assert dict(log.counts) == {"accepted": 2, "malformed": 1, "missing": 1}
    scan = scan_log(path)
    assert scan.usable["imu"] == 2 and scan.usable["missing"] == 1 and scan.usable["malformed"] == 1


# ---------------------------------------------------------------- the session
def _imu_session(text: str | None = None, **options) -> Session:
    document = tomllib.loads(text or _scenario_text())
    for name in ("dgnss1", "dgnss2", "gyro1", "gyro2"):
        document["sensors"][name]["source"] = f"@{name}"
    scenario = compose(document).scenario
    return Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN, suite=scenario.sensor, **options)


def test_an_imu_reading_out_of_range_is_not_used():
    """The IMU is the integrating observer's input: a reading beyond 2 g or 30 deg/s is
    counted ``range`` and never reaches a step; readings within are taken."""
    session = _imu_session()
    assert session.direct and session.gate_tests["imu"] == "range" and not session.ungated
    assert session.gate_rule == "NIS > chi-square 99.99 %, imu beyond 19.6133 m/s2 or 30 deg/s"
    for t, values in (
        (0.0, (0.1, 0.0, 1.0)),
        (0.1, (25.0, 0.0, 0.0)),
        (0.2, (0.0, 0.0, -31.0)),
        (0.3, (0.0, 0.0, math.nan)),
        (0.4, (0.0, -0.3, 29.0)),
    ):
        session.feed(Reading(t, "imu", "imu", values, "CSV"))
    assert session.unused == {"range": 3, "superseded": 1}
    assert session.channels["imu"].new == pytest.approx((0.0, -0.3, math.radians(29.0)))


def test_a_suite_with_two_imus_is_refused_live():
    text = _scenario_text().replace("[references]", '[sensors.imu2]\nkind = "imu"\n\n[references]')
    text = text.replace('kind = "ins"', 'kind = "ins"\nimu = "imu"')  # the observer integrates one of them
    with pytest.raises(ValueError, match=r"^sensors\.imu2: one IMU stream feeds one IMU; the suite has 2 \(imu, imu2\)$"):
        _imu_session(text)


# ---------------------------------------------------------------- replay of a written log
@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """``lookout write-log`` of the shortened example: its NMEA log, thrust, IMU and truth."""
    folder = tmp_path_factory.mktemp("imu-log")
    scenario = folder / "imu-dp.toml"
    scenario.write_text(_scenario_text())
    assert main(["write-log", str(scenario), "--out", str(folder / "log"), "--outage", "none"]) == 0
    return folder / "log"


def _replay_arguments(folder: Path, *options) -> list[str]:
    return [
        "replay",
        str(folder / "dp-vessel.nmea"),
        "--scenario",
        str(folder / "dp-vessel-scenario.toml"),
        "--origin",
        "63.44,10.40",
        *options,
    ]


@pytest.mark.slow
def test_the_imu_aided_observer_replays_its_log_as_it_ran_in_simulation(written):
    """Replayed from its NMEA log, thrust and IMU log, the IMU-aided observer's position
    estimate follows the one it gave in simulation to within 0.1 m over the whole run,
    the minute without references included (measured: 0.05 m at most; what differs is
    the GGA's rounding, the second gyro's heading a step late and the wild fixes, which
    the gate drops); each reference is an outage through the loss, the IMU never."""
    session = _imu_session()
    assert set(session.channels) == {"dgnss1", "dgnss2", "gyro1", "gyro2", "imu"}
    blocks = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        outcome = replay(
            session, written / "dp-vessel.nmea", thrust=written / "dp-vessel-thrust.csv", imu=written / "dp-vessel-imu.csv", emit=blocks.append
        )
    times = np.concatenate([b.time for b in blocks]) - EPOCH
    estimate = {name: np.concatenate([b.estimate[name] for b in blocks]) for name in blocks[0].estimate}
    with xr.open_dataset(written / "dp-vessel-truth.nc") as truth:
        run = truth.isel(run=0)
        k = np.rint(times / 0.1).astype(int)
        simulated, position = run["position_hat"].values[k], run["position"].values[k]
    difference = np.linalg.norm(estimate["position"] - simulated, axis=1)
    assert times.size >= 2390 and difference.max() < 0.1, difference.max()
    lost = (times >= LOSS[0] + 3.0) & (times < LOSS[0] + LOSS[1])  # past the 2.5 s timeout
    error = np.linalg.norm(estimate["position"] - position, axis=1)
    assert error[lost].max() < 5.0  # dead reckoning on a navigation-grade IMU for a minute
    for name in ("dgnss1", "dgnss2"):
        outage = estimate[f"outage_{name}_position"] > 0
        assert outage[lost].all() and not outage[(times > LOSS[0] + LOSS[1] + 2.0)].any()
        assert session.channels[name].counts["gated"] == 2  # the log's two wild fixes of each
    assert not (estimate["outage_imu_specific_force"] > 0).any()
    rows = sum(1 for _ in open(written / "dp-vessel-imu.csv")) - 1
    assert session.channels["imu"].counts["accepted"] == rows and outcome.imu_rejected == {}
    assert "range" not in session.unused and "other_source" not in session.unused


@pytest.mark.slow
@pytest.mark.parametrize(
    "options, message",
    [
        ((), "the observer reads sensor imu, an IMU: give --imu IMU.csv, the CSV log of its readings (time,fx,fy,r)"),
        (("--imu", "{thrust}"), "--imu {thrust} must be a CSV log whose first line is time,fx,fy,r"),
        (("--imu", "{imu}", "--thrust", "{imu}"), "--thrust {imu} must be a CSV log whose first line is time,surge,sway,yaw"),
        (("--imu", "{shifted}"), "--imu {shifted}: its times (1796183199.9"),
    ],
)
def test_replay_refuses_an_imu_log_it_cannot_use(written, options, message, capsys, tmp_path):
    """Without the IMU log, with a log of another kind, or one on another clock: one
    line, exit 2, nothing written."""
    shifted = tmp_path / "shifted.csv"
    lines = (written / "dp-vessel-imu.csv").read_text().splitlines()
    shifted.write_text("\n".join([lines[0]] + [f"{float(line.split(',', 1)[0]) + 1e5!r},{line.split(',', 1)[1]}" for line in lines[1:]]) + "\n")
    paths = {"thrust": written / "dp-vessel-thrust.csv", "imu": written / "dp-vessel-imu.csv", "shifted": shifted}
    out = tmp_path / "out.nc"
    arguments = _replay_arguments(written, *(option.format(**paths) for option in options), "--out", str(out))
    assert main(arguments) == 2
    err = capsys.readouterr().err.strip()
    assert message.format(**paths) in err and "\n" not in err and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.slow
def test_replay_refuses_an_imu_log_for_an_observer_without_imu(written, capsys, tmp_path):
    scenario = tmp_path / "passive.toml"
    text = _scenario_text()
    start = text.index('kind = "ins"')
    end = text.index("\n\n", start)
    text = text[:start] + 'kind = "passive"\ndesign = "fossen-strand-1999"\nwave_frequency = 0.8976' + text[end:]
    for name in ("dgnss1", "dgnss2", "gyro1", "gyro2"):
        text = text.replace(f"[sensors.{name}]\n", f'[sensors.{name}]\nsource = "@{name}"\n')
    scenario.write_text(text)
    arguments = ["replay", str(written / "dp-vessel.nmea"), "--scenario", str(scenario), "--imu", str(written / "dp-vessel-imu.csv")]
    assert main(arguments) == 2
    err = capsys.readouterr().err.strip()
    assert "the observer reads no IMU" in err and f"leave --imu ({written / 'dp-vessel-imu.csv'}) out" in err and "\n" not in err, err
    assert main(["replay", str(written / "dp-vessel-imu.csv"), "--scenario", str(scenario)]) == 2
    assert "is an IMU log (time,fx,fy,r): give it with --imu, and a position log as LOG" in capsys.readouterr().err


# ---------------------------------------------------------------- live
@pytest.mark.slow
def test_the_imu_aided_observer_live_over_udp():
    """NMEA (each sensor's sentences with its tag block) on one UDP port and the IMU's
    fx,fy,r lines on another: every reading reaches its sensor, the IMU's included, and
    each step's estimate is finite."""
    import socket
    import threading
    import time

    from lookout.io.nmea import tag_block
    from lookout.io.simulated_log import gga, ths
    from lookout.live.run import live, open_source

    session = _imu_session()
    session.warm_up()
    nmea, imu = open_source("udp://127.0.0.1:0"), open_source("udp://127.0.0.1:0", "--imu")
    ports = nmea[1].getsockname()[1], imu[1].getsockname()[1]
    rng = np.random.default_rng(2)

    def send():
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for k in range(40):  # 4 s at 10 Hz: each gyro's THS and the IMU every step, each receiver's GGA every tenth
            sender.sendto(f"{rng.normal(0.0, 0.01)!r},{rng.normal(0.0, 0.01)!r},{rng.normal(0.0, 0.05)!r}\n".encode(), ("127.0.0.1", ports[1]))
            lines = [tag_block(name) + ths(float(rng.normal(0.0, 0.1)), talker="HE") for name in ("gyro1", "gyro2")]
            if k % 10 == 0:
                for name, (north, east) in (("dgnss1", (5.0, 30.0)), ("dgnss2", (-4.0, -25.0))):  # the antennas at their lever arms
                    latitude, longitude, _ = ORIGIN.geodetic(north + rng.normal(0.0, 0.7), east + rng.normal(0.0, 0.7), 0.0)
                    lines.append(tag_block(name) + gga(k * 0.1, float(latitude), float(longitude), talker="GP"))
            sender.sendto(("\r\n".join(lines) + "\r\n").encode(), ("127.0.0.1", ports[0]))
            time.sleep(0.1)
        sender.close()

    thread = threading.Thread(target=send)
    thread.start()
    steps = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        outcome = live(session, nmea, imu=imu, emit=steps.append, idle=1.5)
    thread.join()
    nmea[1].close()
    imu[1].close()
    accepted = {name: channel.counts["accepted"] for name, channel in session.channels.items()}
    assert accepted == {"dgnss1": 4, "dgnss2": 4, "gyro1": 40, "gyro2": 40, "imu": 40} and outcome.imu_counts == {"accepted": 40}
    assert 30 <= outcome.steps <= 60
    assert all(np.isfinite(block.estimate["position"]).all() and np.isfinite(block.estimate["velocity"]).all() for block in steps)


def test_speeds_over_ground_and_through_the_water_reach_their_sensors():
    """With the observer reading each instrument, an RMC's or VTG's speed and course
    over ground go to the suite's gnss-velocity whose source they come from (m/s, the
    course in radians wrapped as a simulated one's), a VHW's speed through the water to
    the speed log's surge (its sway not measured); another source's is other_source. The
    first step waits for the position, heading and IMU only."""
    text = _scenario_text().replace(
        "[references]",
        '[sensors.vel]\nkind = "gnss-velocity"\nlever_arm = [30.0, 5.0]\nsource = "GP@vel"\n\n'
        '[sensors.log]\nkind = "speed-log"\nsource = "VW"\n\n[references]',
    )
    session = _imu_session(text)
    assert {name: channel.kind for name, channel in session.channels.items() if name in ("vel", "log")} == {
        "vel": "ground_velocity",
        "log": "water_speed",
    }
    assert session.kinds == ("position", "heading")
    readings = [
        Reading(0.0, "GP@vel", "ground_velocity", (1.5, 270.0), "VTG"),
        Reading(0.0, "GN@other", "ground_velocity", (9.0, 10.0), "VTG"),
        Reading(0.0, "VW", "water_speed", (0.5,), "VHW"),
        Reading(0.01, "GP@dgnss1", "local_position", (1.0, 2.0), "CSV"),
        Reading(0.01, "HE@gyro1", "heading", (10.0,), "THS"),
    ]
    for reading in readings:
        session.feed(reading)
    assert session.channels["vel"].new == pytest.approx((1.5, -math.pi / 2))
    assert session.channels["log"].new[0] == 0.5 and math.isnan(session.channels["log"].new[1])
    assert session.unused == {"other_source": 1}
    session._start()
    assert session.step_index is None  # no IMU reading yet
    session.feed(Reading(0.02, "imu", "imu", (0.0, 0.0, 0.0), "CSV"))
    session._start()
    assert session.step_index == 1  # the step of the last of the three kinds (0.02 s), at 0.1 s


@pytest.mark.slow
def test_replay_without_a_scenario_runs_the_imu_aided_observer_on_the_logs_own_sensors(written, capsys, tmp_path):
    """lookout replay LOG --imu IMU.csv without --scenario: the IMU-aided observer on a
    suite of the log's main receiver and gyro (the sources most readings came from: the
    second receiver's and gyro's are other_source) and the IMU measured from its log. No
    hull model and nothing told: within 1.5 m RMS of the truth over 30-120 s (measured
    0.79 m), 10 m after the minute without fixes (4.3 m), 2 m 20 s after (1.05 m)."""
    out = tmp_path / "replay.nc"
    arguments = ["replay", str(written / "dp-vessel.nmea"), "--imu", str(written / "dp-vessel-imu.csv"), "--out", str(out)]
    assert main(arguments) == 0
    err = capsys.readouterr().err
    assert "no --scenario: the IMU-aided observer (no hull model" in err and "positions from GP@dgnss1, headings from HE@gyro1" in err
    assert "IMU at 10 Hz" in err
    with xr.open_dataset(out) as replayed, xr.open_dataset(written / "dp-vessel-truth.nc") as truth:
        t = replayed["time"].values
        # the frame's origin is the first fix of the forward antenna: the estimate is its displacement
        error = np.linalg.norm(replayed["position_hat"].values[0] - truth["position"].values[0][np.rint(t / 0.1).astype(int)], axis=1)
    before = (t > 30.0) & (t < LOSS[0])
    assert np.sqrt(np.mean(error[before] ** 2)) < 1.5
    assert error[np.searchsorted(t, LOSS[0] + LOSS[1] - 1.0)] < 10.0 and error[np.searchsorted(t, LOSS[0] + LOSS[1] + 20.0)] < 2.0
    # its figure zooms on the loss, told by the receiver's own flag (outage_gnss_position)
    import matplotlib.pyplot as plt

    from lookout.live.figures import plot_session

    with xr.open_dataset(out) as replayed, xr.open_dataset(written / "dp-vessel-truth.nc") as truth:
        figure = plot_session(replayed.load(), truth.load())
    assert figure is not None and "no position fix used from 121.5 to 179.9 s" in figure.get_suptitle()
    plt.close(figure)
