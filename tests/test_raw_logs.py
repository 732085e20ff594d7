"""Raw NMEA logs (lookout.io.sentence_time, lookout.io.logs): the time read from inside
the sentences (midnight rollover, dates, lines between timed sentences), the format told
from the first line or named, a log without a time refused, fuzzed logs counted line by
line, and a raw log written from a simulated run replayed to its timed twin's estimates."""

from __future__ import annotations

import math
import re
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from lookout.io.logs import log_format, nmea_log, scan_log
from lookout.io.nmea import NmeaParser, sentence
from lookout.io.sentence_time import SentenceClock, anchor_day, sentence_date, time_of_day
from lookout.io.simulated_log import EPOCH, gga, ths, write_raw_log
from lookout.live.run import check_log_order, replay
from lookout.live.session import Session
from lookout.scenario.composition import compose

EXAMPLE = Path(__file__).parents[1] / "examples"
LOGS = EXAMPLE / "logs"


def _hdt(degrees: float) -> str:
    return sentence("HE", "HDT", [f"{degrees:.2f}", "T"])


def _rmc(clock: str, date: str) -> str:
    return sentence("GP", "RMC", [clock, "A", "6326.4000", "N", "01024.0000", "E", "0.5", "90.0", date, "", ""])


def test_time_of_day_fields():
    assert time_of_day(b"123519") == 12 * 3600 + 35 * 60 + 19
    assert time_of_day(b"235959.75") == 86399.75
    assert time_of_day(b"235960.5") == 86400.5  # a leap second
    for bad in (b"", b"12351", b"246000", b"126000", b"1235a9", b"123519.x", b"-12351"):
        assert math.isnan(time_of_day(bad)), bad
    assert sentence_date("RMC", b"GPRMC,1,A,,,,,,,010126".split(b",")) == 20454  # 2026-01-01
    assert sentence_date("RMC", b"GPRMC,1,A,,,,,,,010199".split(b",")) == 10592  # 1999: 80-99 are the 1900s
    assert sentence_date("RMC", b"GPRMC,1,A,,,,,,,310226".split(b",")) is None  # 31 February
    assert sentence_date("ZDA", b"GPZDA,1,01,12,2026,00,00".split(b",")) == 20788


def test_the_clock_rolls_over_at_midnight_and_spreads_the_lines_between_two_times(tmp_path):
    lines = [
        _hdt(1.0),  # before any time: untimed
        gga(86398.0, 63.44, 10.40),
        _hdt(2.0),  # spread evenly to the next time: 86398.0 and 86398.75
        _hdt(2.5),
        gga(86399.5, 63.44, 10.40),
        gga(0.5, 63.44, 10.40),  # midnight: the next day
        _hdt(3.0),  # the next time steps back: at the latest, 86400.5
        gga(86399.9, 63.44, 10.40),  # a late line of the day before, not a step forward
        _hdt(4.0),  # from the latest, 86400.5, to 86401.5: at 86400.5
        gga(1.5, 63.44, 10.40),
        ths(5.0),  # after the last time: at it
    ]
    log = tmp_path / "raw.nmea"
    log.write_text("\n".join(lines) + "\n")
    parser = NmeaParser()
    times = [r.time for r in nmea_log(log, parser, "nmea-raw")]
    assert times == [86398.0, 86398.0, 86398.75, 86399.5, 86400.5, 86400.5, 86399.9, 86400.5, 86401.5, 86401.5]
    assert parser.counts["untimed"] == 1 and parser.counts["accepted"] == 10 and parser.lines == 11
    scan = scan_log(log)
    assert scan.late == 1 and scan.first == 86398.0 and scan.newest == 86401.5 and scan.usable["untimed"] == 1
    clock = SentenceClock()
    assert [clock.tick("GGA", b"GPGGA,235959.00") for _ in range(1)] == [86399.0] and clock.tick("HDT", b"HEHDT,1,T") == 86399.0


def test_the_first_date_anchors_unix_time_and_a_wrong_date_is_ignored(tmp_path):
    log = tmp_path / "raw.nmea"
    lines = [
        "# a logger's header",
        gga(86399.0, 63.44, 10.40),  # 2026-11-30 23:59:59, its date known only from the RMC below
        _rmc("000001.00", "011226"),  # 2026-12-01 00:00:01
        _hdt(5.0),
        _rmc("000002.00", "050326"),  # a wrong date: counted, ignored
        gga(3.0, 63.44, 10.40),
    ]
    log.write_text("\r\n".join(lines) + "\r\n")  # CR LF line ends
    assert log_format(log) == "nmea-raw"
    parser = NmeaParser()
    times = [r.time for r in nmea_log(log, parser, "nmea-raw")]
    assert times == [EPOCH - 1.0, EPOCH + 1.0, EPOCH + 1.0, EPOCH + 1.0, EPOCH + 2.0, EPOCH + 2.0, EPOCH + 3.0]  # an RMC: position and speed
    scan = scan_log(log)
    assert scan.format == "nmea-raw" and scan.first == EPOCH - 1.0 and scan.newest == EPOCH + 3.0 and scan.ignored_dates == 1
    assert scan.usable["position"] == 4 and scan.usable["heading"] == 1
    # CR alone as line end reads the same
    log.write_text("\r".join(lines) + "\r")
    assert [r.time for r in nmea_log(log, NmeaParser(), "nmea-raw")] == times
    assert anchor_day([("HDT", b"HEHDT,1,T")]) == 0  # no date: seconds from the first day's midnight


def test_a_raw_log_without_a_time_is_refused_in_one_line(tmp_path):
    log = tmp_path / "headings.nmea"
    log.write_text("\n".join(_hdt(k) for k in range(5)) + "\n")
    scan = scan_log(log, "LOG")
    assert scan.format == "nmea-raw" and scan.timed == 0 and scan.usable["untimed"] == 5
    with pytest.raises(ValueError) as error:
        check_log_order(scan, 1.0)
    assert str(error.value) == (
        f"LOG {log}: no sentence gives a time (5 lines: untimed 5); a raw NMEA log is timed by its GGA, GNS, GLL, RMC or ZDA sentences' UTC times"
    )


def test_the_format_is_told_from_the_first_line_or_named(tmp_path):
    raw = tmp_path / "raw.txt"
    raw.write_text("# comment\n\n\\s:GP01*3B\\" + gga(1.0, 63.44, 10.4) + "\n")
    timed = tmp_path / "timed.txt"
    timed.write_text("# comment\n12.5 " + gga(1.0, 63.44, 10.4) + "\n")
    assert log_format(raw) == "nmea-raw" and log_format(timed) == "nmea"
    assert log_format(timed, forced="raw") == "nmea-raw" and log_format(raw, forced="timed") == "nmea"
    with pytest.raises(ValueError, match="format must be one of raw, timed, csv; got 'nmea'"):
        log_format(raw, forced="nmea")
    with pytest.raises(ValueError, match=r"a CSV log's first line must be .*; this is a raw NMEA log: leave the format out \(auto\), or give raw$"):
        log_format(raw, "LOG", forced="csv")
    other = tmp_path / "other.txt"
    other.write_text("# comment\nnot, a, header\n")
    with pytest.raises(ValueError, match="a CSV log's first line must be .*; its first line is a comment \\(a CSV log starts with its header\\)"):
        log_format(other, "LOG", forced="csv")


# ---------------------------------------------------------------- fuzzing
_sentences = st.sampled_from(
    [
        gga(43200.0, 63.44, 10.40),
        gga(10.0, 63.44, 10.40, talker="GN"),
        gga(86399.0, -63.44, -10.40, talker="GL"),  # three talkers
        _rmc("120000.00", "011226"),
        _rmc("120001.00", "999999"),  # a date that is none
        _rmc("000000.00", "290201"),  # a wrong date
        _hdt(12.0),
        ths(100.0),
        sentence("HC", "HDG", ["98.3", "1.5", "W", "", ""]),
        sentence("GP", "ZDA", ["235959.99", "31", "12", "2026", "00", "00"]),
        "!AIVDM,1,1,,B,177KQJ5000G?tO`K>RA1wUbN0TKH,0*5C",
        sentence("P", "GRME", ["15.0", "M"]),
        "# a comment",
    ]
)
_raw_lines = st.one_of(_sentences, st.text(max_size=120), st.binary(max_size=120).map(lambda b: b.decode("latin-1")))


@settings(max_examples=60, deadline=None)
@given(st.lists(_raw_lines, min_size=1, max_size=40), st.booleans())
def test_fuzzed_raw_logs_never_raise_and_count_each_line_once(tmp_path_factory, lines, huge):
    folder = tmp_path_factory.mktemp("fuzz")
    log = folder / "raw.nmea"
    body = "\n".join(line.replace("\r", " ").replace("\n", " ") for line in lines)
    if huge:  # a 10 MB line among them
        body = gga(5.0, 63.44, 10.4) + "\n" + "x" * 10_000_000 + "\n" + body
    log.write_bytes(body.encode("utf-8", "replace") + b"\n")
    expected = sum(1 for line in log.read_bytes().splitlines() if line.strip() and not line.strip().startswith(b"#"))
    parser = NmeaParser()
    readings = list(nmea_log(log, parser, "nmea-raw"))
    assert parser.lines == expected
    assert all(math.isfinite(r.time) for r in readings)
    try:
        scan = scan_log(log, fmt="raw")
    except ValueError as error:  # refused whole, in one line naming the log: empty, or binary data
        assert str(log) in str(error) and "\n" not in str(error)
        assert "empty" in str(error) or "binary" in str(error)
    else:
        assert scan.lines == expected and sum(scan.usable.values()) == expected


# ---------------------------------------------------------------- a simulated raw log
def _session(duration: float):
    document = tomllib.loads((EXAMPLE / "live-dp.toml").read_text())
    document["simulation"]["duration"] = duration
    scenario = compose(document).scenario
    from lookout.io.geodesy import LocalFrame

    return Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=LocalFrame(63.44, 10.40), batch=4096)


def _replayed(log: Path, duration: float, **options):
    session = _session(duration)
    blocks = []
    parser = NmeaParser()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        outcome = replay(session, log, emit=blocks.append, parser=parser, **options)
    estimates = {name: np.concatenate([b.estimate[name] for b in blocks]) for name in blocks[0].estimate}
    return parser, outcome, np.concatenate([b.session_time for b in blocks]), estimates


@pytest.mark.slow
@pytest.mark.xdist_group("live replay")
def test_a_raw_log_replays_to_its_timed_twins_estimates_across_midnight(tmp_path):
    """A raw log of 60 s of the example run that starts 30 s before midnight UTC (GGA,
    RMC, VTG, HDG with 3.5 W variation and 1.2 E deviation, AIS and proprietary lines):
    its replay equals the replay of its TIME SENTENCE twin (THS headings, times written
    by the writer) to the HDG field's quantization (0.005 degrees)."""
    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc").isel(time=slice(0, 600))
    raw, twin = tmp_path / "raw.nmea", tmp_path / "twin.nmea"
    write_raw_log(truth, raw, epoch=EPOCH - 30.0, twin=twin)
    assert log_format(raw) == "nmea-raw" and log_format(twin) == "nmea"
    parser, outcome, t, estimates = _replayed(raw, 60.0)
    twin_parser, twin_outcome, twin_t, twin_estimates = _replayed(twin, 60.0)
    np.testing.assert_array_equal(t, twin_t)
    assert outcome.check.log.first == EPOCH - 30.0 and outcome.check.log.ignored_dates == 0  # the RMC dates agree across midnight
    assert parser.sentences[("HDG", "accepted")] == 600 and parser.counts["ais"] == parser.counts["proprietary"] == 0  # under 100 fixes
    assert parser.sentences[("RMC", "accepted")] == parser.sentences[("VTG", "accepted")] == 60
    quantum = math.radians(0.005)
    assert np.abs(estimates["heading"] - twin_estimates["heading"]).max() <= quantum
    # position: the heading's quantization enters through the lever-arm-free model only: far below a GGA quantum
    assert np.abs(estimates["position"] - twin_estimates["position"]).max() < 1e-7 * 1852.0


def test_write_raw_log_refuses_a_variation_outside_90_degrees(tmp_path):
    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc").isel(time=slice(0, 10))
    for bad in (91.0, math.nan):
        with pytest.raises(ValueError, match="variation must be degrees within -90 to 90"):
            write_raw_log(truth, tmp_path / "x.nmea", variation=bad)
    assert not (tmp_path / "x.nmea").exists()


@pytest.mark.slow
def test_replay_without_a_scenario_runs_the_model_free_observer_on_the_logs_sensors(tmp_path, capsys):
    """lookout replay LOG with no --scenario: one line says which observer and what it
    measured of the log (rates; noise around the 30 s moving mean), and the session is
    written; a log without positions is refused in one line."""
    from lookout.cli import main

    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc").isel(time=slice(0, 600))
    raw = tmp_path / "raw.nmea"
    write_raw_log(truth, raw)
    out = tmp_path / "session.nc"
    assert main(["replay", str(raw), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "no --scenario: the model-free observer (no hull model, settling 20 s) on the log's sensors: position at 1 Hz" in err
    assert "heading at 10 Hz" in err and "no --thrust" not in err
    # a GGA and an RMC of one epoch are one fix: the rate counts the readings a step used
    assert re.search(r"done: .*; position 1\.0\d/s, heading 10\.0\d/s; .*superseded \d+.*compute - \(one block, which compiled\)", err)
    with xr.open_dataset(out) as session:
        assert session["velocity_hat"].shape[-2] > 580 and bool(np.all(np.isfinite(session["position_hat"].values)))
    headings = tmp_path / "headings.nmea"
    headings.write_text("".join(line + "\n" for line in [sentence("GP", "ZDA", ["000000.00", "01", "12", "2026", "00", "00"]), _hdt(1.0), _hdt(2.0)]))
    assert main(["replay", str(headings)]) == 2
    message = capsys.readouterr().err.strip()
    assert "without --scenario the observer without a hull model reads the log's positions and headings" in message and "\n" not in message


def test_the_logs_own_sensors_and_waves_measured_from_the_example_raw_log():
    """examples/logs/dp-vessel-raw.nmea (the example run: fixes of 0.5 m at 1 Hz, heading
    of 0.1 deg at 10 Hz, Fossen & Strand's sea: peak 0.8976 rad/s, 7.0 s, motion 10 m
    in amplitude, 3.33 m standard deviation): rates, noise and waves measured from it
    within 5 to 15 % of the run's own."""
    from lookout.live.log_sensors import log_sensors

    measured = log_sensors(LOGS / "dp-vessel-raw.nmea", "nmea-raw", 1.0, 0.1, waves=True)
    assert measured.wave_period == pytest.approx(2 * math.pi / 0.8976, rel=0.05)
    assert measured.wave_std is not None and measured.wave_std[0] == pytest.approx(10.0 / 3.0, rel=0.1)
    assert measured.position_std == pytest.approx(0.5, rel=0.1)
    assert measured.heading_std == pytest.approx(0.1, rel=0.15)
    calm = log_sensors(LOGS / "dp-vessel-raw.nmea", "nmea-raw", 1.0, 0.1)
    assert calm.position_std > 3.0 and calm.wave_period is None  # the waves counted as noise


@pytest.mark.slow
def test_replay_without_a_scenario_in_waves_estimates_the_velocity_as_a_scenario_with_the_sea_does(tmp_path, capsys):
    """The example raw log replayed without --scenario: with --waves the RMS velocity
    error after 60 s is under 0.1 m/s (measured 0.072, as the model-free observer given
    the run's sea in a scenario: 0.073); without, the wave motion leaks into the
    velocity (measured 0.42 m/s)."""
    from lookout.cli import main

    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc")
    errors = {}
    for waves in (True, False):
        out = tmp_path / f"waves-{waves}.nc"
        assert main(["replay", str(LOGS / "dp-vessel-raw.nmea"), "--out", str(out)] + (["--waves"] if waves else [])) == 0
        with xr.open_dataset(out) as session:
            t = session["time"].values
            index = np.searchsorted(truth["time"].values, t - 1e-9)
            error = session["velocity_hat"].values[0] - truth["velocity"].values[0][index]
            errors[waves] = float(np.sqrt(np.mean(np.sum(error[t >= 60.0] ** 2, axis=1))))
    capsys.readouterr()
    assert errors[True] < 0.1 < 0.3 < errors[False], errors


@pytest.mark.slow
def test_replay_smooth_writes_the_smoothed_estimates_beside_the_filtered_ones(tmp_path, capsys):
    """--smooth: the RTS smoother over the session (its forward pass the session's own
    filter, to rounding), written beside the filtered estimates; refused in one line
    without --out or for an observer that is not Kalman-type."""

    from lookout.cli import main

    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc").isel(time=slice(0, 600))
    raw = tmp_path / "raw.nmea"
    write_raw_log(truth, raw)
    out = tmp_path / "session.nc"
    assert main(["replay", str(raw), "--smooth", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    gap = float(re.search(r"its forward pass within (\S+) of the session's filter", err).group(1))
    assert gap < 1e-9
    with xr.open_dataset(out) as session:
        assert session["velocity_smoothed"].shape == session["velocity_hat"].shape
        assert not np.allclose(session["velocity_smoothed"].values, session["velocity_hat"].values)
    for arguments, message in (
        (["--smooth"], "--smooth needs --out"),
        (["--smooth", "--out", str(tmp_path / "p.nc"), "--scenario", str(EXAMPLE / "live-dp.toml")], "--smooth needs a Kalman-type observer"),
    ):
        assert main(["replay", str(raw), *arguments]) == 2
        text = capsys.readouterr().err.strip()
        assert message in text and "\n" not in text
    assert not (tmp_path / "p.nc").exists()


def _hdm_log(path: Path, seconds: float = 60.0) -> Path:
    """The example raw log's first ``seconds`` with its headings as HDM and no variation
    anywhere: the magnetic heading (the HDG's sensor heading plus its deviation), and
    the RMCs' variation fields empty."""
    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc").isel(time=slice(0, round(seconds * 10)))
    raw = write_raw_log(truth, path.with_suffix(".hdg"))
    lines = []
    for line in raw.read_text().splitlines():
        if line.startswith("$HCHDG"):
            fields = line.split("*")[0].split(",")
            lines.append(sentence("HC", "HDM", [f"{float(fields[1]) + float(fields[2]):.2f}", "M"]))
        elif line.startswith("$GPRMC"):
            fields = line.split("*")[0].split(",")
            lines.append(sentence("GP", "RMC", fields[1:10] + ["", "", "D"]))
        else:
            lines.append(line)
    path.write_text("\n".join(lines) + "\n")
    return path


def test_magnetic_headings_without_a_variation_are_named_and_taken_with_one(tmp_path, capsys):
    """A log whose headings are HDM and that carries no variation: without --scenario the
    refusal names --variation; with it, the log's own sensors are measured (10 Hz of
    headings, 0.1 degree of noise and the run's turning left in the spread)."""
    from lookout.cli import main
    from lookout.live.log_sensors import log_sensors

    log = _hdm_log(tmp_path / "hdm.nmea")
    assert main(["replay", str(log)]) == 2
    message = capsys.readouterr().err.strip()
    assert "600 magnetic headings (HDG, HDM) carry no variation: give --variation" in message and "\n" not in message
    measured = log_sensors(log, "nmea-raw", 1.0, 0.1, variation=-3.5)
    assert 0.05 <= measured.heading_std < 0.5
