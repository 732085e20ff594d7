"""What a replay makes of real-looking logs: the talkers of one receiver are one source,
every line and reading it does not use is counted and printed by its cause, a UTF-8
byte-order mark is skipped and said, an origin far from the log is refused, and the
options a run cannot use are refused before any step."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.io.geodesy import LocalFrame
from lookout.io.logs import UTF8_BOM, log_format, nmea_log, scan_log
from lookout.io.nmea import NmeaParser, Reading, checksum, receiver, sentence
from lookout.io.simulated_log import gga
from lookout.live.run import replay
from lookout.live.session import Gates, OriginError, Session

ROOT = Path(__file__).parents[1]
LOGS = ROOT / "examples" / "logs"
SCENARIO = ROOT / "examples" / "live-dp.toml"


def _rows(seconds: float):
    """The example log's (time, sentence) rows of its first ``seconds``."""
    rows = []
    for line in (LOGS / "dp-vessel.nmea").read_text().splitlines():
        if line and not line.startswith("#"):
            stamp, text = line.split(" ", 1)
            rows.append((float(stamp), text))
    return [(t, text) for t, text in rows if t - rows[0][0] < seconds]


def _talker(text: str, talker: str) -> str:
    """``text`` sent under another talker ID (its checksum recomputed)."""
    body = talker + text[3 : text.index("*")]
    return f"${body}*{checksum(body.encode()):02X}"


def _write(path: Path, rows, prefix: bytes = b"") -> Path:
    path.write_bytes(prefix + "".join(f"{t:.6f} {text}\n" for t, text in rows).encode())
    return path


def _session(**options):
    import tomllib

    from lookout.scenario.composition import compose

    scenario = compose(tomllib.loads(SCENARIO.read_text())).scenario
    return Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, batch=4096, **options)


def _replayed(session, log):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return replay(session, log)


def _cli(arguments, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    code = main([str(a) for a in arguments])
    return code, capsys.readouterr().err.strip()


# ---------------------------------------------------------------- one receiver, one source
def test_a_multi_constellation_receivers_talkers_are_one_source(tmp_path):
    """GGA alternating GP/GN and THS alternating HE/HC, as a multi-constellation receiver
    and a gyro send them: every fix and heading is used, none is other_source."""
    rows = _rows(60.0)
    fixes = [i for i, (_, text) in enumerate(rows) if "GGA" in text]
    headings = [i for i, (_, text) in enumerate(rows) if "THS" in text]
    for n, i in enumerate(fixes):
        rows[i] = (rows[i][0], _talker(rows[i][1], ("GP", "GN")[n % 2]))
    for n, i in enumerate(headings):
        rows[i] = (rows[i][0], _talker(rows[i][1], ("HE", "HC")[n % 2]))
    session = _session(frame=LocalFrame(63.44, 10.40))
    _replayed(session, _write(tmp_path / "talkers.nmea", rows))
    position, heading = session.channels["position"].counts, session.channels["heading"].counts
    assert position["other_source"] == heading["other_source"] == 0
    assert position["accepted"] == len(fixes) and heading["accepted"] == len(headings)
    assert session.channels["position"].source == "GNSS" and session.channels["heading"].source == "heading"
    assert session.event_counts["source"] == 2  # one per channel, at its first reading


def test_the_receiver_binding():
    """lookout.io.nmea.receiver: a talker family per sender; two senders stay apart;
    a user's binding (a source, or a talker alone) names what it binds."""
    assert receiver("GN@10.0.0.5") == receiver("GP@10.0.0.5") == "GNSS@10.0.0.5"
    assert receiver("GP@10.0.0.5") != receiver("GP@10.0.0.6")
    assert receiver("HC") == receiver("TI") == "heading" and receiver("IN") == "IN"
    bindings = {"GP": "dgps", "GN@10.0.0.5": "rtk"}
    assert receiver("GP@10.0.0.5", bindings) == "dgps" and receiver("GN@10.0.0.5", bindings) == "rtk"
    assert receiver("GN@10.0.0.6", bindings) == "GNSS@10.0.0.6"
    # two receivers the user keeps apart: the second is another source while the first speaks
    session = _session(sources={"GP": "dgps", "GN": "rtk"})
    session.feed(Reading(0.01, "GP", "position", (63.44, 10.40, 2.0, 0.8), "GGA"))
    session.feed(Reading(0.02, "GN", "position", (63.44, 10.40, 2.0, 0.8), "GGA"))
    assert session.channels["position"].counts["other_source"] == 1 and session.channels["position"].source == "dgps"
    with pytest.raises(ValueError, match="sources must map sources or talkers"):
        _session(sources={"GP": 3})


# ---------------------------------------------------------------- every unused reading counted
def _every_unused_kind(rows):
    """The rows with one line or reading of each cause a replay does not use them for."""
    extra = []
    t0 = rows[0][0]
    lat, lon = 63.44, 10.40
    ths_row = next(text for _, text in rows if "THS" in text)
    extra += [
        (t0 + 20.001, ths_row[:-2] + ("00" if not ths_row.endswith("00") else "11")),  # checksum
        (t0 + 20.002, "GPGGA,not a sentence"),  # malformed: no start character
        (t0 + 20.003, sentence("HE", "THS", ["400.0", "A"])),  # out_of_range
        (t0 + 20.004, gga(0.0, lat, lon, quality=0)),  # no_fix
        (t0 + 20.005, sentence("II", "XDR", ["A", "1.0", "D", "PITCH"])),  # unsupported
        (t0 + 20.006, sentence("TI", "ROT", ["1.0", "A"])),  # not_read
        (t0 + 20.507, gga(0.0, lat, lon, quality=6)),  # quality: the receiver's dead reckoning
        (t0 + 20.508, gga(0.0, lat, lon, hdop=9.9)),  # hdop
        (t0 + 20.509, _talker(gga(0.0, lat, lon), "IN")),  # other_source: an integrated navigation system's fix
    ]
    rows = sorted(rows + extra, key=lambda row: row[0])
    # superseded: a second fix of the receiver in use before the step that takes the first
    fix = next(i for i, (t, text) in enumerate(rows) if "GGA" in text and t > t0 + 30.0)
    rows.insert(fix + 1, (rows[fix][0] + 1e-4, rows[fix][1]))
    # gated: a fix 500 m off, after the estimate settled
    wild = next(i for i, (t, text) in enumerate(rows) if "GGA" in text and t > t0 + 40.0)
    north_off = LocalFrame(63.44, 10.40).geodetic(500.0, 0.0, 0.0)
    rows[wild] = (rows[wild][0], gga(0.0, float(north_off[0]), float(north_off[1])))
    # late: one line stamped before the line above it
    late = next(i for i, (t, _) in enumerate(rows) if t > t0 + 50.0)
    rows[late], rows[late + 1] = rows[late + 1], rows[late]
    return rows


def test_every_unused_line_and_reading_is_printed_by_its_cause(tmp_path, capsys, monkeypatch):
    log = _write(tmp_path / "unused.nmea", _every_unused_kind(_rows(60.0)))
    code, err = _cli(["replay", log, "--scenario", SCENARIO], capsys, monkeypatch)
    assert code == 0, err
    done = next(line for line in err.splitlines() if line.startswith("done:"))
    counts = dict((name, int(n)) for name, n in re.findall(r"(\w+) (\d+)", done.split("not used", 1)[1].split(";", 1)[0]))
    assert counts == {
        "checksum": 1,
        "malformed": 1,
        "out_of_range": 1,
        "no_fix": 1,
        "unsupported": 1,
        "late": 1,
        "not_read": 1,
        "quality": 1,
        "hdop": 1,
        "other_source": 1,
        "superseded": 1,
        "gated": 1,
    }, done
    assert f"not used {sum(counts.values())} (" in done


# ---------------------------------------------------------------- a UTF-8 byte-order mark
def test_an_nmea_log_with_a_byte_order_mark_loses_nothing(tmp_path):
    rows = _rows(20.0)
    plain, marked = _write(tmp_path / "plain.nmea", rows), _write(tmp_path / "bom.nmea", rows, UTF8_BOM)
    parsers = NmeaParser(), NmeaParser()
    assert list(nmea_log(marked, parsers[1])) == list(nmea_log(plain, parsers[0]))
    assert parsers[1].counts == parsers[0].counts and parsers[1].counts["malformed"] == 0
    scans = scan_log(plain), scan_log(marked)
    assert scans[1].bom and not scans[0].bom
    assert (scans[1].first, scans[1].timed, scans[1].usable) == (scans[0].first, scans[0].timed, scans[0].usable)


def test_a_csv_log_from_excel_with_a_byte_order_mark_is_read(tmp_path, capsys, monkeypatch):
    lines = (LOGS / "dp-vessel.csv").read_text().splitlines()[:400]
    log = tmp_path / "excel.csv"
    log.write_bytes(UTF8_BOM + "\r\n".join(lines).encode() + b"\r\n")
    assert log_format(log) == "csv-position"
    code, err = _cli(["replay", log, "--scenario", SCENARIO], capsys, monkeypatch)
    assert code == 0, err
    assert err.count("a UTF-8 byte-order mark at the start was skipped") == 1
    assert re.search(r"done: \d+ steps, 399 readings", err), err


# ---------------------------------------------------------------- an origin far from the log
def test_an_origin_far_from_the_logs_first_fix_is_refused_before_any_step(tmp_path, capsys, monkeypatch):
    import lookout.live.run

    monkeypatch.setattr(lookout.live.run, "replay", lambda *a, **k: pytest.fail("the replay started"))
    out = tmp_path / "new" / "r.nc"
    code, err = _cli(["replay", LOGS / "dp-vessel.nmea", "--scenario", SCENARIO, "--origin", "0,0", "--out", out], capsys, monkeypatch)
    assert code == 2 and "\n" not in err
    assert re.fullmatch(
        r"error: --origin 0,0 lies 7106 km from the log's first fix, 63.43999\d,10.40000\d \(degrees\), more than 100 km: "
        r".*omit --origin to take the first fix as the origin, or give one within 100 km of it",
        err,
    ), err
    assert not out.parent.exists()


def test_a_live_sessions_first_fix_far_from_its_origin():
    """The session refuses the first fix it would use (not one it refuses for quality)
    when the origin it was given lies over 100 km away; an origin 6.7 km away is kept."""
    far = _session(frame=LocalFrame(0.0, 0.0))
    far.feed(Reading(0.0, "GP", "position", (63.44, 10.40, 0.0 + 6.0, 0.8), "GGA"))  # quality 6: not used, not checked
    with pytest.raises(OriginError, match=r"^frame 0,0 lies 7106 km from the first fix, 63.440000,10.400000 \(degrees\), more than 100 km"):
        far.feed(Reading(0.1, "GP", "position", (63.44, 10.40, 2.0, 0.8), "GGA"))
    near = _session(frame=LocalFrame(63.5, 10.4))
    near.feed(Reading(0.1, "GP", "position", (63.44, 10.40, 2.0, 0.8), "GGA"))
    assert near.channels["position"].counts["accepted"] == 1


# ---------------------------------------------------------------- options the run cannot use
def _ekf_scenario(tmp_path: Path) -> Path:
    path = tmp_path / "ekf.toml"
    path.write_text(SCENARIO.read_text() + '\n[observer]\nkind = "ekf"\n')
    return path


def test_a_gate_option_the_observer_does_not_use_is_refused(tmp_path, capsys, monkeypatch):
    code, err = _cli(["replay", LOGS / "dp-vessel.nmea", "--scenario", SCENARIO, "--gate-probability", "0.999"], capsys, monkeypatch)
    assert code == 2 and "\n" not in err
    assert err.startswith("error: --gate-probability applies to observers with an innovation covariance (") and "ekf" in err
    assert "is gated on its innovations' length (--position-gate, --heading-gate): leave --gate-probability out" in err
    code, err = _cli(["replay", LOGS / "dp-vessel.nmea", "--scenario", _ekf_scenario(tmp_path), "--position-gate", "20"], capsys, monkeypatch)
    assert code == 2 and "\n" not in err
    assert re.fullmatch(
        r"error: --position-gate applies to observers gated on the length of their innovation_position output; "
        r"the observer of .*ekf.toml, ekf, is gated on its normalized innovation squared \(--gate-probability\): leave --position-gate out",
        err,
    ), err


def test_the_nis_label_carries_every_digit_of_the_probability():
    import tomllib

    from lookout.scenario.composition import compose

    document = tomllib.loads(SCENARIO.read_text())
    document["observer"] = {"kind": "ekf"}
    scenario = compose(document).scenario
    for probability, label in ((0.999999, "99.9999"), (0.9999999, "99.99999"), (0.9999, "99.99"), (0.5, "50")):
        session = Session(scenario.observer, scenario.sample_period, gates=Gates(gate_probability=probability))
        assert session.gate_rule == f"NIS > chi-square {label} %"


def test_write_log_without_outage_names_the_scenario_it_was_given(tmp_path, capsys, monkeypatch):
    short = tmp_path / "short.toml"
    short.write_text(SCENARIO.read_text().replace("duration = 600.0", "duration = 100.0"))
    code, err = _cli(["write-log", short, "--out", tmp_path / "log"], capsys, monkeypatch)
    assert code == 2 and "\n" not in err
    assert re.fullmatch(
        r"error: .*short.toml: its run lasts 100 s \(simulation.duration\), shorter than the default outage, 300,30 "
        r"\(from 300 to 330 s\): give --outage START,LENGTH within the run, or --outage none",
        err,
    ), err
    assert not (tmp_path / "log").exists()


def test_a_truth_that_does_not_cover_the_log_is_refused_before_any_step(tmp_path, capsys, monkeypatch):
    import lookout.live.run

    truth = xr.open_dataset(LOGS / "dp-vessel-truth.nc").isel(time=slice(0, 600))  # 60 s of a 600 s log
    truth.to_netcdf(tmp_path / "short-truth.nc")
    monkeypatch.setattr(lookout.live.run, "replay", lambda *a, **k: pytest.fail("the replay started"))
    results = tmp_path / "results"
    code, err = _cli(
        [
            "replay",
            LOGS / "dp-vessel.nmea",
            "--scenario",
            SCENARIO,
            "--out",
            results / "r.nc",
            "--figure",
            results / "r.png",
            "--truth",
            tmp_path / "short-truth.nc",
        ],
        capsys,
        monkeypatch,
    )
    assert code == 2 and "\n" not in err
    assert re.fullmatch(
        r"error: --truth .*short-truth.nc covers 0 to 59.9 s \(every 0.1 s\); LOG .*dp-vessel.nmea runs from 1796083199.928152 "
        r"to 1796083799.\d+ s, -0.072 to 599.877 s on the truth's clock, steps 0 to 599.9 s of a session: give the truth of the run behind this log.*",
        err,
    ), err
    assert not results.exists()


# ---------------------------------------------------------------- progress
def test_a_replay_reports_its_progress_through_the_log(tmp_path, monkeypatch):
    import lookout.live.run

    monkeypatch.setattr(lookout.live.run, "PROGRESS_EVERY", 0.0)
    log = _write(tmp_path / "a.nmea", _rows(30.0))
    calls = []
    session = _session()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        replay(session, log, progress=lambda done, total: calls.append((done, total)))
    done, total = np.array(calls).T
    assert np.all(np.diff(done) >= 0) and np.all(total == total[-1]) and done[-1] == total[-1] == scan_log(log).span
    assert len(calls) > 100


def test_the_progress_line_shows_on_a_terminal_only(monkeypatch):
    """On a terminal the line says the share of the log replayed once the replay has run
    PROGRESS_AFTER seconds; elsewhere (a pipe, a test's capture) it writes nothing."""
    import io

    from rich.console import Console
    from rich.progress import Progress

    import lookout.live.cli as live_cli
    from lookout._commandline import progress_bar

    screen = io.StringIO()

    def terminal_bar(*columns):
        return Progress(*columns, console=Console(file=screen, force_terminal=True, width=100), transient=False, auto_refresh=False)

    monkeypatch.setattr(live_cli, "PROGRESS_AFTER", 0.0)
    with live_cli._replay_progress(terminal_bar) as progress:
        progress(30.0, 120.0)
    assert "replaying" in screen.getvalue() and " 25.0% of the log" in screen.getvalue()
    piped = io.StringIO()
    monkeypatch.setattr("sys.stderr", piped)
    with live_cli._replay_progress(progress_bar) as progress:
        progress(30.0, 120.0)
    assert piped.getvalue() == ""


def test_lookout_live_stops_at_a_first_fix_far_from_its_origin(tmp_path, capsys, monkeypatch):
    """lookout live --origin 0,0 on a stream at 63 N: one line, exit 2, at its first fix;
    no step was taken and --out is not created."""
    import io
    import os
    import sys

    read, write = os.pipe()
    os.write(write, "".join(f"{text}\r\n" for _, text in _rows(2.0)).encode())
    os.close(write)
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(os.fdopen(read, "rb")))
    out = tmp_path / "new" / "live.nc"
    code, err = _cli(["live", SCENARIO, "--nmea", "-", "--origin", "0,0", "--out", out, "--quiet"], capsys, monkeypatch)
    assert code == 2 and "\n" not in err
    assert re.fullmatch(r"error: --origin 0,0 lies 7106 km from the first fix, 63.43999\d,10.40000\d \(degrees\), more than 100 km: .*", err), err
    assert not out.parent.exists()
