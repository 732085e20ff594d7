"""NMEA 0183 parsing (lookout.io.nmea) and logs (lookout.io.logs): the sentences a DP
system reads, checksums, IEC 61162-450 framing, sources, and fuzzing: no line raises,
every line is counted once, memory stays bounded."""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lookout.io.logs import CsvLog, log_format, nmea_log, nmea_log_line, scan_log
from lookout.io.nmea import CAUSES, MAX_LINE, LineSplitter, NmeaParser, checksum, sentence
from lookout.io.simulated_log import gga, ths

# published examples (checksums recomputed where the source's was for other fields)
GGA = sentence("GP", "GGA", ["123519.00", "4807.0381234", "S", "01131.0001234", "W", 4, "08", "0.9", "545.4", "M", "46.9", "M", "", ""])
RMC = sentence("GP", "RMC", ["123519", "A", "4807.038", "N", "01131.000", "E", "022.4", "084.4", "230394", "003.1", "W"])
GLL = sentence("GN", "GLL", ["4916.45", "N", "12311.12", "W", "225444", "A", "A"])
HDT = sentence("HE", "HDT", ["274.07", "T"])
THS = sentence("IN", "THS", ["77.52", "A"])
ROT = sentence("TI", "ROT", ["-0.3", "A"])
GST = sentence("GP", "GST", ["172814.0", "0.006", "0.023", "0.020", "273.6", "0.023", "0.020", "0.031"])
GNS = sentence("GN", "GNS", ["123519.00", "4807.038", "N", "01131.000", "E", "DRN", "14", "0.8", "545.4", "46.9", "", "", "S"])
HDG = sentence("HC", "HDG", ["98.3", "1.5", "W", "12.6", "E"])
HDM = sentence("HC", "HDM", ["98.3", "M"])
VTG = sentence("GP", "VTG", ["054.7", "T", "034.4", "M", "005.5", "N", "010.2", "K", "A"])
VHW = sentence("VW", "VHW", ["245.1", "T", "", "M", "10.1", "N", "18.7", "K"])
ZDA = sentence("GP", "ZDA", ["201530.00", "04", "07", "2002", "00", "00"])
AIS = "!AIVDM,1,1,,B,177KQJ5000G?tO`K>RA1wUbN0TKH,0*5C"
PROPRIETARY = sentence("P", "GRME", ["15.0", "M", "45.0", "M", "25.0", "M"])


def test_the_bridge_sentences():
    """GNS, HDG, HDM, VTG, VHW, ZDA and RMC's speed: each field in its unit, magnetic
    heading turned to true (true = magnetic + deviation + variation, east positive)."""
    parser = NmeaParser()
    (fix,) = parser.line(GNS, 0.0)
    assert fix.values[:2] == pytest.approx((48 + 7.038 / 60, 11 + 31 / 60))
    assert fix.values[2:] == (4.0, 0.8)  # "DRN": differential, RTK fixed, no fix: the best, RTK (GGA's 4)
    (heading,) = parser.line(HDG, 0.0)
    assert heading.kind == "heading" and heading.sentence == "HDG"
    assert heading.values[0] == pytest.approx(98.3 - 1.5 + 12.6)
    assert parser.line(HDM, 0.0) == [] and parser.counts["no_variation"] == 1  # no variation known yet
    position, velocity = parser.line(RMC, 0.0)  # variation 3.1 W
    assert velocity.kind == "ground_velocity" and velocity.values == pytest.approx((22.4 * 1852 / 3600, 84.4))
    (heading,) = parser.line(HDM, 0.0)
    assert heading.values[0] == pytest.approx(98.3 - 3.1)
    assert NmeaParser(variation=-7.5).line(HDM, 0.0)[0].values[0] == pytest.approx(90.8)
    (over_ground,) = parser.line(VTG, 0.0)
    assert over_ground.values == pytest.approx((5.5 * 1852 / 3600, 54.7))
    (water,) = parser.line(VHW, 0.0)
    assert water.kind == "water_speed" and water.values == pytest.approx((10.1 * 1852 / 3600,))
    assert parser.line(ZDA, 0.0) == [] and parser.counts["time_only"] == 1
    assert parser.line(AIS, 0.0) == [] and parser.counts["ais"] == 1
    assert parser.line(PROPRIETARY, 0.0) == [] and parser.counts["proprietary"] == 1
    assert parser.sentences[("HDM", "no_variation")] == 1 and parser.sentences[("HDM", "accepted")] == 1
    wrapped = sentence("HC", "HDG", ["359.0", "", "", "2.0", "E"])  # an empty deviation is 0; 361 wraps to 1
    assert NmeaParser().line(wrapped, 0.0)[0].values[0] == pytest.approx(1.0)
    for bad in (float("nan"), 181.0, "3", True):
        with pytest.raises(ValueError, match="variation must be degrees"):
            NmeaParser(variation=bad)


def test_checksum_of_a_published_sentence():
    # NMEA's own example: $GPGLL,5300.97914,N,00259.98174,E,125926,A*28
    assert checksum(b"GPGLL,5300.97914,N,00259.98174,E,125926,A") == 0x28


def test_the_seven_sentences():
    parser = NmeaParser()
    got = {s.split(",")[0][3:]: parser.line(s, 10.0, "10.0.0.5:10110") for s in (GGA, RMC, GLL, HDT, THS, ROT, GST)}
    assert parser.counts["accepted"] == 7 and parser.lines == 7
    (fix,) = got["GGA"]
    assert fix.kind == "position" and fix.source == "GP@10.0.0.5:10110" and fix.time == 10.0
    assert fix.values[0] == pytest.approx(-(48 + 7.0381234 / 60), abs=1e-9)  # S and W are negative
    assert fix.values[1] == pytest.approx(-(11 + 31.0001234 / 60), abs=1e-9)
    assert fix.values[2:] == (4.0, 0.9)
    assert got["RMC"][0].values[:2] == pytest.approx((48 + 7.038 / 60, 11 + 31 / 60))
    assert got["GLL"][0].values[:2] == pytest.approx((49 + 16.45 / 60, -(123 + 11.12 / 60)))
    assert got["HDT"][0].values == (274.07,) and got["THS"][0].values == (77.52,)
    assert got["THS"][0].source == "IN@10.0.0.5:10110"
    assert got["ROT"][0].kind == "rate_of_turn" and got["ROT"][0].values == (-0.3,)
    assert got["GST"][0].kind == "position_error" and got["GST"][0].values == (0.023, 0.020)


@pytest.mark.parametrize(
    "line, cause",
    [
        (GGA[:-2] + "00", "checksum"),
        (GGA.replace("4807", "4817"), "checksum"),
        (GGA.split("*")[0], "checksum"),  # no checksum
        (sentence("GP", "GGA", ["", "", "", "", "", 0, "00", "99.9", "", "", "", "", "", ""]), "no_fix"),
        (sentence("GP", "RMC", ["123519", "V", "", "", "", "", "", "", "230394", "", ""]), "no_fix"),
        (sentence("HE", "THS", ["", "V"]), "no_fix"),
        (sentence("HE", "THS", ["12.0", "M"]), "no_fix"),  # manual input: not a measurement
        (sentence("TI", "ROT", ["1.0", "V"]), "no_fix"),
        (sentence("GP", "GGA", ["1200"]), "malformed"),  # truncated before the position
        (sentence("GP", "GGA", ["120000", "9107.0", "N", "01131.0", "E", 1, "08", "0.9", "", "", "", "", "", ""]), "out_of_range"),
        (sentence("HE", "HDT", ["abc", "T"]), "malformed"),
        (sentence("HE", "THS", ["400.0", "A"]), "out_of_range"),
        (sentence("II", "XDR", ["A", "1.0", "D", "PITCH"]), "unsupported"),
        (sentence("GN", "GNS", ["123519.00", "", "", "", "", "NN", "00", "", "", "", "", "", "V"]), "no_fix"),
        (sentence("GP", "VTG", ["", "T", "", "M", "", "N", "", "K", "N"]), "no_fix"),
        (sentence("HC", "HDG", ["98.3", "1.5", "W", "212.6", "E"]), "out_of_range"),
        (sentence("HC", "HDG", ["98.3", "1.5", "W", "12.6", "Q"]), "out_of_range"),
        (sentence("GP", "VTG", ["054.7", "T", "", "M", "-5.5", "N", "", "K", "A"]), "malformed"),
        ("garbage", "malformed"),
        ("", "empty"),
        ("$" + "A" * (MAX_LINE + 5), "too_long"),
    ],
)
def test_each_bad_line_is_counted_under_its_cause(line, cause):
    parser = NmeaParser()
    assert parser.line(line, 0.0) == []
    assert parser.counts[cause] == 1 and parser.lines == 1


def test_a_sentence_without_checksum_when_allowed():
    parser = NmeaParser(require_checksum=False)
    assert parser.line(HDT.split("*")[0], 0.0)[0].values == (274.07,)
    with pytest.raises(ValueError, match="require_checksum must be True or False"):
        NmeaParser(require_checksum="yes")


def test_iec_61162_450_datagram_with_tag_blocks_and_two_receivers():
    def tagged(source, body):
        tags = f"s:{source},c:1796083200".encode()
        return b"\\" + tags + b"*%02X\\" % checksum(tags) + body.encode()

    datagram = b"UdPbC\x00" + tagged("GP0001", GGA) + b"\r\n" + tagged("GP0002", GGA) + b"\r\n" + THS.encode() + b"\r\n"
    parser = NmeaParser()
    readings = parser.datagram(datagram, 5.0, "192.168.1.7:60001")
    assert [r.source for r in readings] == ["GP@GP0001", "GP@GP0002", "IN@192.168.1.7:60001"]
    assert parser.sources[("GP@GP0001", "position")] == 1 and parser.sources[("GP@GP0002", "position")] == 1
    bad_tag = b"\\s:GP0001*00\\" + GGA.encode()
    assert parser.datagram(bad_tag, 6.0) == [] and parser.counts["checksum"] == 1


def test_the_example_logs_sentences_round_trip():
    parser = NmeaParser()
    (fix,) = parser.line(gga(3600.5, 63.4412345678, -10.4012345678), 0.0)
    assert fix.values[0] == pytest.approx(63.4412345678, abs=2e-9)  # 7 decimals of minutes: 1.7e-9 degrees
    assert fix.values[1] == pytest.approx(-10.4012345678, abs=2e-9)
    (heading,) = parser.line(ths(-0.25), 0.0)
    assert heading.values == (359.75,)


def test_line_splitter_keeps_lines_across_chunks_and_drops_huge_ones():
    splitter = LineSplitter()
    assert splitter.feed(b"$GPHDT,1") == []
    assert splitter.feed(b"2.0,T*2F\r") == [b"$GPHDT,12.0,T*2F"]
    assert splitter.feed(b"\n") == []
    assert splitter.feed(b"x" * (3 * MAX_LINE)) == []
    lines = splitter.feed(b"yyy\nok\n")
    assert len(lines) == 2 and len(lines[0]) > MAX_LINE and lines[1] == b"ok"
    assert splitter.feed(b"tail") == [] and splitter.flush() == [b"tail"]
    parser = NmeaParser()
    parser.line(lines[0], 0.0)
    assert parser.counts["too_long"] == 1


# ---------------------------------------------------------------- fuzzing
_good = st.sampled_from([GGA, RMC, GLL, HDT, THS, ROT, GST, GNS, HDG, HDM, VTG, VHW, ZDA, AIS, PROPRIETARY])


@st.composite
def _damaged(draw):
    line = draw(_good)
    how = draw(st.sampled_from(["truncate", "flip", "insert", "checksum", "fields"]))
    if how == "truncate":
        return line[: draw(st.integers(0, len(line)))]
    if how == "flip":
        i = draw(st.integers(0, len(line) - 1))
        return line[:i] + draw(st.characters(codec="ascii")) + line[i + 1 :]
    if how == "insert":
        i = draw(st.integers(0, len(line)))
        return line[:i] + draw(st.text(min_size=1, max_size=20)) + line[i:]
    if how == "checksum":
        return line.split("*")[0] + "*" + draw(st.text(alphabet="0123456789ABCDEFxyz", min_size=0, max_size=3))
    # well-framed sentences with random fields (valid checksums, nonsense content)
    fields = draw(st.lists(st.text(alphabet=st.characters(codec="ascii", exclude_characters="*$\r\n,"), max_size=12), max_size=15))
    return sentence(line[1:3], line[3:6], fields)


_lines = st.one_of(_good, _damaged(), st.binary(max_size=200), st.text(max_size=200), st.binary(min_size=MAX_LINE, max_size=MAX_LINE + 200))


@settings(max_examples=300)
@given(st.lists(_lines, max_size=30))
def test_fuzzed_lines_never_raise_and_each_is_counted_once(lines):
    parser = NmeaParser()
    readings = 0
    for line in lines:
        got = parser.line(line, 1.0)
        assert len(got) <= (2 if len(got) == 2 and got[0].sentence == "RMC" else 1)  # an RMC: a position and a velocity
        readings += bool(got)
        for reading in got:
            assert all(isinstance(v, float) for v in reading.values) and all(not math.isinf(v) for v in reading.values)
    assert parser.lines == len(lines)
    assert parser.counts["accepted"] == readings
    assert set(parser.counts) == set(CAUSES)


@settings(max_examples=300)
@given(_lines)
def test_framing_alone_agrees_with_the_full_parse(line):
    """NmeaParser.frame (the cheap pre-scan of a log) refuses a line for the cause the
    full parse counts it under; a line it lets through is one the fields decide."""
    cause, formatter = NmeaParser().frame(line)
    full = NmeaParser()
    full.line(line, 1.0)
    (counted,) = [name for name, n in full.counts.items() if n]
    if cause == "accepted":
        assert counted in ("accepted", "time_only", "no_fix", "no_variation", "malformed", "out_of_range") and formatter
    else:
        assert counted == cause and formatter == ""


def _pynmeagps_fields(line: bytes, formatter: str):
    """What pynmeagps's own parse gives, as (attribute, value) pairs, or its exception's type."""
    from pynmeagps import NMEAReader
    from pynmeagps.nmeatypes_core import VALNONE
    from pynmeagps.nmeatypes_get import NMEA_PAYLOADS_GET

    try:
        message = NMEAReader.parse(line, validate=VALNONE)
    except Exception:  # noqa: BLE001 - compared by kind: both readers refuse the line
        return "raises"
    if message is None:
        return None
    return {name: getattr(message, name) for name in NMEA_PAYLOADS_GET[formatter] if hasattr(message, name)}


def _fast_fields(line: bytes, formatter: str):
    from lookout.io.nmea import _message

    try:
        message = _message(line, formatter)
    except Exception:  # noqa: BLE001
        return "raises"
    return None if message is None else dict(vars(message))


def _same(a, b) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


@settings(max_examples=400)
@given(st.one_of(_good, _damaged()))
def test_the_field_reader_gives_what_pynmeagps_gives(line):
    """The sentences' fields are read in one pass over pynmeagps's own definitions and
    conversions: the same attributes and values as its parse (or both refuse the line),
    on every sentence kind, damaged or not."""
    cause, formatter, _ = NmeaParser().framed(line)
    if cause != "accepted":
        return
    framed = NmeaParser()._frame(line)[1][0]
    assert _same(_fast_fields(framed, formatter), _pynmeagps_fields(framed, formatter))


def test_the_field_reader_on_the_example_logs_and_hemispheres():
    lines = [
        sentence("GP", "GGA", ["120000.00", "6326.4000", "S", "01024.0000", "W", "2", "9", "0.8", "12.0", "M", "40.0", "M", "", ""]),
        sentence("GP", "GLL", ["6326.4000", "N", "01024.0000", "W", "120000.00", "A", "D"]),
        sentence("GP", "RMC", ["120000.00", "A", "6326.4000", "N", "01024.0000", "E", "0.5", "90.0", "071226", "3.5", "W", "A"]),
        sentence("HC", "HDG", ["101.5", "1.2", "E", "3.5", "W"]),
        sentence("HC", "HDG", ["101.5", "1.2"]),  # fewer fields than the definition
        sentence("HE", "HDT", ["101.5", "T", "extra"]),
        sentence("GP", "ZDA", ["120000.00", "07", "12", "2026", "", ""]),
    ]
    root = Path(__file__).parents[1] / "examples" / "logs"
    for name in ("dp-vessel-raw.nmea", "identify-vessel-raw.nmea"):
        lines += (root / name).read_text().splitlines()[:3000]
    compared = 0
    for line in lines:
        cause, formatter, _ = NmeaParser().framed(line)
        if cause == "accepted":
            framed = NmeaParser()._frame(line)[1][0]
            assert _same(_fast_fields(framed, formatter), _pynmeagps_fields(framed, formatter)), line
            compared += 1
    assert compared > 5000


@settings(max_examples=150)
@given(st.lists(st.one_of(_good, _damaged()), max_size=20), st.randoms(use_true_random=False))
def test_fuzzed_datagrams_and_reordered_streams(lines, random):
    random.shuffle(lines)
    parser = NmeaParser()
    payload = b"\r\n".join(line.encode("utf-8", "replace") if isinstance(line, str) else line for line in lines)
    parser.datagram(b"UdPbC\x00" + payload, 0.0, "x")
    assert parser.lines == sum(1 for piece in payload.splitlines() if piece.strip())
    # the same bytes as a stream in random chunks: the same counts
    stream, splitter = NmeaParser(), LineSplitter()
    cut = sorted(random.sample(range(len(payload) + 1), k=min(5, len(payload) + 1)))
    for a, b in zip([0, *cut], [*cut, len(payload)]):
        for line in splitter.feed(payload[a:b]):
            stream.line(line, 0.0)
    for line in splitter.flush():
        stream.line(line, 0.0)
    assert stream.counts["accepted"] == parser.counts["accepted"]


def test_parser_memory_stays_flat_over_many_bad_lines():
    parser, splitter = NmeaParser(), LineSplitter()
    junk = [b"$GPGGA,garbage*00\r\n", b"\x00\xff" * 300 + b"\n", GGA.encode() + b"\r\n", b"y" * 5000]

    def churn(n):
        for i in range(n):
            for line in splitter.feed(junk[i % len(junk)]):
                parser.line(line, float(i))

    churn(2000)
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    churn(20000)
    grown = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    assert grown < 64 * 1024, f"the parser kept {grown} bytes over 20000 lines"
    assert parser.lines == sum(parser.counts.values())


# ---------------------------------------------------------------- logs
def test_logs_of_both_formats(tmp_path):
    text = tmp_path / "a.nmea"
    text.write_text(f"# comment\n10.5 {GGA}\n10.6 {THS}\nnot-a-time {HDT}\n\n11.0 {HDT[:-2]}00\n")
    assert log_format(text) == "nmea"
    parser = NmeaParser()
    readings = list(nmea_log(text, parser))
    assert [r.time for r in readings] == [10.5, 10.6]
    assert parser.counts["malformed"] == 1 and parser.counts["checksum"] == 1
    assert nmea_log_line(b"   ", parser) == []

    csv = tmp_path / "a.csv"
    csv.write_text("time,north,east,heading\n0.0,1.5,-2.5,10.0\n0.1,,,11.0\n0.2,1,2,3,4\nx,1,2,3\ninf,1,2,3\n0.3,inf,1,\n")
    assert log_format(csv) == "csv-position"
    log = CsvLog(csv)
    readings = list(log)
    assert [(r.kind, r.values) for r in readings] == [("local_position", (1.5, -2.5)), ("heading", (10.0,)), ("heading", (11.0,))]
    assert log.counts == {"accepted": 2, "malformed": 4}
    thrust = tmp_path / "t.csv"
    thrust.write_text("time,surge,sway,yaw\n0.0,1,2,3\n")
    assert [r.values for r in CsvLog(thrust)] == [(1.0, 2.0, 3.0)]


def test_log_format_errors_name_the_file(tmp_path):
    bad = tmp_path / "b.csv"
    bad.write_text("t,x,y\n1,2,3\n")
    with pytest.raises(ValueError, match=r"LOG .*b.csv: a CSV log's first line must be time,north,east,heading, time,surge,sway,yaw or time,fx,fy,r"):
        log_format(bad, "LOG")
    with pytest.raises(ValueError, match="cannot be read"):
        log_format(tmp_path / "missing.nmea")


BINARY = [
    bytes(range(256)) * 20,  # every byte value: NUL among them
    b"\x89PNG\r\n\x1a\n" + bytes(64),  # an image
    b"time,north,east,heading\n" + bytes([0xC3, 0x28, 0xA0, 0xA1]) * 200,  # a CSV header, then bytes that are not UTF-8
    b"1.0 $GPGGA," + b"\x01\x02\x03\x1b" * 50 + b"\n",  # control characters
]


@pytest.mark.parametrize("content", BINARY, ids=["all-bytes", "png", "not-utf8", "control"])
def test_a_binary_file_is_not_a_text_log_and_its_bytes_are_not_printed(tmp_path, content):
    path = tmp_path / "x.log"
    path.write_bytes(content)
    with pytest.raises(ValueError) as raised:
        log_format(path, "--thrust")
    message = str(raised.value)
    assert message == f"--thrust {path} is not a text log: it holds binary data (a log is text: NMEA sentences, TIME SENTENCE lines, or CSV)"


def test_an_empty_log_and_text_with_a_few_non_ascii_characters(tmp_path):
    empty = tmp_path / "e.nmea"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match=r"LOG .*e.nmea is empty$"):
        log_format(empty, "LOG")
    blank = tmp_path / "b.nmea"
    blank.write_bytes(b"\n\n  \n")
    with pytest.raises(ValueError, match=r"is empty \(only blank lines\)"):
        log_format(blank, "LOG")
    text = tmp_path / "t.nmea"
    text.write_text(f"# origin 63.44\u00b0 N, logged at S\u00f8rbukta\n10.0 {GGA}\n")
    assert log_format(text) == "nmea"


def _log_of(tmp_path, times, lines=None) -> Path:
    path = tmp_path / "times.nmea"
    lines = lines or [THS] * len(times)
    path.write_text("# a comment\n" + "".join(f"{t!r} {line}\n" for t, line in zip(times, lines)))
    return path


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(-(10**6), 10**6).map(lambda k: k / 100), min_size=1, max_size=60))
def test_the_scan_of_a_logs_times_against_numpy(tmp_path_factory, times):
    """scan_log's order, gaps and typical step, against a direct computation on the times."""
    scan = scan_log(_log_of(tmp_path_factory.mktemp("scan"), times))
    times = np.asarray(times)
    newest = np.maximum.accumulate(times)
    behind = np.concatenate([[0.0], newest[:-1] - times[1:]])  # how far each line is stamped before the latest above it
    assert scan.timed == scan.lines == times.size
    assert scan.late == int(np.sum(behind > 0))
    assert scan.back == pytest.approx(max(behind.max(), 0.0), abs=0)
    if scan.back > 0:
        assert scan.back_line == int(np.argmax(behind)) + 2  # 1-based, after the comment
    steps = np.diff(newest)
    forward = steps[steps > 0]
    assert scan.longest_gap == (forward.max() if forward.size else 0.0)
    assert (scan.first, scan.newest) == (times[0], times.max())
    if forward.size:
        # the median of the forward steps, from a histogram of 100 bins a decade: within 2.4 %
        lower, upper = np.sort(forward)[(forward.size - 1) // 2], np.sort(forward)[forward.size // 2]
        assert lower / 1.024 <= scan.typical_step <= upper * 1.024
        # steps longer than x, to the histogram's bin: between those above x * 1.024 and those above x
        x = float(np.median(forward))
        assert np.sum(forward > 1.024 * x) <= scan.gaps_longer_than(x) <= np.sum(forward > x)
    else:
        assert math.isnan(scan.typical_step)


def test_the_scan_counts_what_each_line_can_give(tmp_path):
    bad = THS[:-2] + ("00" if not THS.endswith("00") else "11")
    path = _log_of(tmp_path, [1.0, 1.1, 1.2, 1.3, 1.4, 1.5], [GGA, THS, bad, ROT, "$GPZDA,1*00", "junk"])
    with path.open("a") as handle:
        handle.write("not-a-time " + THS + "\n")
    scan = scan_log(path, "LOG")
    # the corrupted THS and the ZDA fail their checksums; "junk" and the line without a time are malformed
    assert dict(scan.usable) == {"position": 1, "heading": 1, "checksum": 2, "other": 1, "malformed": 2}
    assert scan.lines == 7 and scan.timed == 6
    thrust = tmp_path / "t.csv"
    thrust.write_text("time,surge,sway,yaw\n0.0,1,2,3\n0.1,nan,2,3\n0.2,,2,3\n0.3,x,2,3\n0.4,1,2,3\n")
    scan = scan_log(thrust, "--thrust")
    assert dict(scan.usable) == {"thrust": 2, "missing": 2, "malformed": 1} and scan.timed == 4
