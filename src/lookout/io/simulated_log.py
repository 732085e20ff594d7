"""Logs written from a simulated run, with the truth beside them.

A run's sensor samples become what a bridge computer would have recorded: a GGA
sentence for each position fix and a THS sentence for each heading sample, each
stamped with the time it arrived. The arrival jitters within the sample period
before the observer's step that first uses the sample (a simulated sensor samples at
the step; the log says when its sentence came in): the fix and the thrust 40-90 ms
before, the heading, which a live session steps on (:class:`~lookout.live.Session`),
5-35 ms before. Replaying the log steps the observer on the run's own samples. On top
of the samples the log carries what a real one does:

- an outage: no fix for a while (the receiver lost its correction or its antenna);
- corrupted copies of a few sentences (a character flipped on the wire: the
  checksum fails) and a few lines that are not NMEA;
- wild points: extra fixes far off, between the samples, with good checksums.

The same samples go to a CSV log (``time,north,east,heading``) at full precision, the
applied thrust to ``time,surge,sway,yaw``, and the run to NetCDF.

A run of a sensor suite is logged as its bridge logs it (``sensors``, a
:class:`LoggedSensor` each): every position reference its own GGA at its own sample
instants, every gyrocompass its own THS, a rate gyro its ROT, each sentence stamped with the talker and
the tag block (``\\s:SOURCE*hh\\``) that name its source. The outage silences every
position reference; the corruptions and the wild points are drawn per sensor; the
headings of one instant arrive in the order of ``sensors``. The CSV then has a column
per sensor channel (``dgnss1.north``, ``gyro1.heading``, ``rot.rate_of_turn`` in degrees
per minute as ROT gives it), a row per sample.
"""

from __future__ import annotations

import datetime
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from lookout.io.geodesy import LocalFrame
from lookout.io.nmea import sentence, tag_block

if TYPE_CHECKING:
    import xarray as xr

#: 2026-12-01T00:00:00Z: the Unix time of the example log's step 0.
EPOCH = 1796083200.0
#: The outage a log has unless told otherwise: (start, length) in seconds of run time.
DEFAULT_OUTAGE = (300.0, 30.0)
#: Before the step that uses it, the part of a sample period within which a sample's
#: sentence arrives, by what it measures (uniform).
ARRIVAL = {"position": (0.4, 0.9), "heading": (0.05, 0.35), "rate_of_turn": (0.4, 0.9)}
#: The same for an IMU's samples (its CSV log): before the headings, on which a replay
#: steps, so that each step integrates the sample of its own instant, as a simulation does.
IMU_ARRIVAL = (0.4, 0.95)


def _minutes(value: float, degree_digits: int, hemispheres: str) -> tuple[str, str]:
    """``(dddmm.mmmmmmm, hemisphere)`` with seven decimals of minutes (0.19 mm)."""
    hemisphere = hemispheres[0] if value >= 0 else hemispheres[1]
    value = abs(value)
    degrees = int(value)
    minutes = (value - degrees) * 60.0
    if round(minutes, 7) >= 60.0:
        degrees, minutes = degrees + 1, 0.0
    return f"{degrees:0{degree_digits}d}{minutes:010.7f}", hemisphere


def gga(time_of_day: float, latitude: float, longitude: float, quality: int = 2, satellites: int = 12, hdop: float = 0.8, talker: str = "GP") -> str:
    """A GGA sentence (talker GP unless told) with seven decimals of minutes."""
    hours, rest = divmod(time_of_day % 86400.0, 3600.0)
    minutes, seconds = divmod(rest, 60.0)
    lat, ns = _minutes(latitude, 2, "NS")
    lon, ew = _minutes(longitude, 3, "EW")
    return sentence(
        talker,
        "GGA",
        [
            f"{int(hours):02d}{int(minutes):02d}{seconds:05.2f}",
            lat,
            ns,
            lon,
            ew,
            quality,
            f"{satellites:02d}",
            f"{hdop:.1f}",
            "0.0",
            "M",
            "40.0",
            "M",
            "1.0",
            "0001",
        ],
    )


def ths(heading_degrees: float, talker: str = "HE") -> str:
    """A THS sentence (talker HE unless told, mode A) with five decimals of degrees."""
    return sentence(talker, "THS", [f"{heading_degrees % 360.0:.5f}", "A"])


def rot(degrees_per_minute: float, talker: str = "TI") -> str:
    """A ROT sentence (talker TI unless told, status A): the rate of turn in degrees per
    minute, negative when the bow turns to port, with three decimals."""
    return sentence(talker, "ROT", [f"{degrees_per_minute:.3f}", "A"])


@dataclass(frozen=True)
class LoggedSensor:
    """One instrument of a run written to its log: where its samples are, the sentence
    they become, and the stamps that name its source.

    Attributes
    ----------
    name : str
        The sensor's name: its columns' prefix in the CSV (``dgnss1.north``).
    kind : {"position", "heading", "rate_of_turn"}
        GGA fixes of ``channel`` (north, east; m), THS headings (rad) or ROT rates of
        turn (rad/s).
    channel : str
        Its samples in the run's dataset, held between them (``dgnss1.measured_position``).
    sample_period : float
        Seconds between its samples: a whole number of the run's sample periods.
    talker : str
        The sentences' talker ID (``GP``, ``HE``).
    sender : str or None
        The source in the tag block in front of each sentence (``\\s:SENDER*hh\\``,
        :func:`lookout.io.nmea.tag_block`); None for none.
    """

    name: str
    kind: str
    channel: str
    sample_period: float
    talker: str
    sender: str | None = None

    def __post_init__(self):
        if self.kind not in ARRIVAL:
            raise ValueError(f"LoggedSensor {self.name}: kind must be 'position', 'heading' or 'rate_of_turn'; got {self.kind!r}")
        if not re.fullmatch(r"[A-Z][A-Z0-9]", self.talker):
            raise ValueError(f"LoggedSensor {self.name}: talker must be two capital letters or digits; got {self.talker!r}")
        if not (math.isfinite(self.sample_period) and self.sample_period > 0):
            raise ValueError(f"LoggedSensor {self.name}: sample_period must be a positive number of seconds; got {self.sample_period!r}")
        if self.sender is not None:
            tag_block(self.sender)  # raises for a source a tag block cannot carry

    @property
    def stamp(self) -> str:
        """What goes in front of its sentences: the tag block, or nothing."""
        return tag_block(self.sender) if self.sender is not None else ""

    @property
    def columns(self) -> tuple[str, ...]:
        """Its columns in the CSV of a suite's log."""
        return (f"{self.name}.north", f"{self.name}.east") if self.kind == "position" else (f"{self.name}.{self.kind}",)

    def describe(self) -> str:
        """How its sentences are written, in words: ``GGA as GP, tag block s:dgps1, every 1 s``."""
        tag = f", tag block s:{self.sender}" if self.sender is not None else ""
        written = {"position": "GGA", "heading": "THS", "rate_of_turn": "ROT"}[self.kind]
        return f"{written} as {self.talker}{tag}, every {self.sample_period:g} s"


def write_simulated_log(
    ds: xr.Dataset,
    folder: str | Path,
    *,
    name: str = "dp-vessel",
    frame: LocalFrame | None = None,
    epoch: float = EPOCH,
    outage: tuple[float, float] | None = DEFAULT_OUTAGE,
    corrupted: int = 6,
    wild_points: int = 2,
    seed: int = 0,
    sensors: Sequence[LoggedSensor] | None = None,
    imu: tuple[str, float] | None = None,
) -> dict:
    """Write the NMEA log, the CSV logs and the truth of one simulated run.

    Parameters
    ----------
    ds : xarray.Dataset
        One run of a vessel scenario (``lookout run``): ``measured_position``,
        ``measured_heading`` (or the channels ``sensors`` name), ``force_applied``,
        ``moment_applied``, and the attributes ``sample_period_s`` and
        ``sensor_sample_period_s``.
    folder : path
        Where ``<name>.nmea``, ``<name>.csv``, ``<name>-thrust.csv`` and
        ``<name>-truth.nc`` go (created).
    frame : LocalFrame, optional
        Where north = east = 0 lies; default 63.44 N, 10.40 E.
    epoch : float
        Unix time of the run's t = 0.
    outage : (start, length), optional
        Seconds of run time without fixes (of every position reference): finite,
        ``length`` positive, and within the run (``start + length`` at most its
        duration); default :data:`DEFAULT_OUTAGE`, None for no outage.
    corrupted, wild_points : int
        Corrupted copies of sentences, and fixes 60 m off, added to the log (with
        ``sensors``: to each sensor's sentences, the wild points to each position
        reference's).
    seed : int
        Of the arrival jitter and the corruptions.
    sensors : sequence of LoggedSensor, optional
        The instruments of a sensor suite, each written with its own stamps (module
        docstring); the CSV then has a column per sensor channel. Default: one receiver
        (``measured_position``, GGA as GP) and one gyro (``measured_heading``, THS as
        HE), at the first and third periods of ``sensor_sample_period_s``, and the CSV
        ``time,north,east,heading``.
    imu : (str, float), optional
        ``(name, sample_period)`` of a suite's IMU: its samples (``NAME.measured_specific_force``,
        ``NAME.measured_yaw_rate``) go to ``<name>-imu.csv`` as ``time,fx,fy,r``
        (m/s2, m/s2, deg/s; :mod:`lookout.io.logs`), each arriving within the step
        before the record that holds it (:data:`IMU_ARRIVAL`); a missing sample (a
        dropout) gives no row.

    Returns
    -------
    dict
        The written paths by role (``nmea``, ``csv``, ``thrust``, ``truth``, and with
        ``imu`` ``imu``).

    Raises
    ------
    ValueError
        Naming ``outage`` when it is not a window within the run, or ``sensors`` when
        it is empty, names a channel the run has not, or a period not a whole number of
        the run's; before anything is written.
    """
    from lookout.results import write_netcdf

    frame = frame or LocalFrame(63.44, 10.40)
    folder = Path(folder)
    ds = ds.isel(run=0) if "run" in ds.dims else ds
    step = float(ds.attrs["sample_period_s"])
    default = outage is DEFAULT_OUTAGE  # not chosen by the caller: a refusal says so
    if outage is not None:
        try:
            start, length = (float(value) for value in outage)
        except (TypeError, ValueError):
            raise ValueError(f"outage must be (start, length) in seconds, or None; got {outage!r}") from None
        end = float(ds["time"].values[-1]) + step  # the run's duration
        if not (math.isfinite(start) and math.isfinite(length) and start >= 0 and length > 0):
            raise ValueError(f"outage must be (start, length) with start >= 0 and length > 0 (s); got ({start:g}, {length:g})")
        if start + length > end + 1e-9 * end:
            raise ValueError(
                f"outage ({start:g}, {length:g}){' (the default)' if default else ''} ends at {start + length:g} s, after the run's end: "
                f"its duration is {end:g} s" + ("; give an outage within the run, or None" if default else "")
            )
        outage = (start, length)
    suite = sensors is not None
    streams: tuple[LoggedSensor, ...]
    if sensors is None:
        periods = [float(p) for p in str(ds.attrs["sensor_sample_period_s"]).strip("[]").split(",")]
        streams = (
            LoggedSensor("position", "position", "measured_position", periods[0], "GP"),
            LoggedSensor("heading", "heading", "measured_heading", periods[2], "HE"),
        )
    else:
        streams = tuple(sensors)
        if not streams:
            raise ValueError("sensors must name at least one sensor to log; got none")
        for each in streams:
            if not isinstance(each, LoggedSensor):
                raise ValueError(f"sensors must be LoggedSensor objects; got {type(each).__name__}")
            if each.channel not in ds:
                raise ValueError(f"sensors: the run has no {each.channel} (sensor {each.name})")
    every = []
    for each in streams:
        ratio = each.sample_period / step
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise ValueError(f"sensors: {each.name}'s sample period, {each.sample_period:g} s, is not a whole number of the run's {step:g} s")
        every.append(round(ratio))
    imu_rows = _imu_rows(ds, imu, step, epoch, seed) if imu is not None else None
    folder.mkdir(parents=True, exist_ok=True)
    times = np.asarray(ds["time"].values, dtype=float)
    samples = [np.asarray(ds[each.channel].values, dtype=float).reshape(times.size, -1) for each in streams]
    thrust = np.column_stack([ds["force_applied"].values, ds["moment_applied"].values])
    heading_streams = [i for i, each in enumerate(streams) if each.kind == "heading"]
    rng = np.random.default_rng(seed)
    # (arrival, text, the stream it is a sample of (-1: none), the record it was sampled at)
    nmea: list[tuple[float, str, int, int]] = []
    csv: list[tuple[float, str]] = []
    thrust_rows = []
    columns = [column for each in streams for column in each.columns]
    for k, t in enumerate(times):
        index = round(t / step)  # the sample's number: time from integer indices
        offsets = [step * rng.uniform(*ARRIVAL[each.kind]) for each in streams]
        # the headings of one instant arrive in the order of the sensors (a replay steps on the first)
        for i, offset in zip(heading_streams, sorted((offsets[i] for i in heading_streams), reverse=True)):
            offsets[i] = offset
        rows: list[tuple[float, int, tuple[str, ...]]] = []
        for i, (each, values) in enumerate(zip(streams, samples)):
            value = values[k]
            due = index % every[i] == 0 and bool(np.all(np.isfinite(value)))
            if each.kind == "position" and outage and outage[0] <= t < outage[0] + outage[1]:
                due = False
            if not due:
                continue
            arrival = epoch + t - offsets[i]
            cells: tuple[str, ...]
            if each.kind == "position":
                latitude, longitude, _ = frame.geodetic(value[0], value[1], 0.0)
                nmea.append((arrival, each.stamp + gga(epoch + t, float(latitude), float(longitude), talker=each.talker), i, k))
                cells = (repr(float(value[0])), repr(float(value[1])))
            elif each.kind == "rate_of_turn":
                per_minute = 60.0 * math.degrees(float(value[0]))
                nmea.append((arrival, each.stamp + rot(per_minute, talker=each.talker), i, k))
                cells = (repr(per_minute),)
            else:
                nmea.append((arrival, each.stamp + ths(math.degrees(value[0]), talker=each.talker), i, k))
                cells = (repr(math.degrees(float(value[0]))),)
            rows.append((float(arrival), i, cells))
        for arrival, i, cells in rows:  # each reading on its own row, at its own arrival
            if suite:
                row = [""] * len(columns)
                first = columns.index(streams[i].columns[0])
                row[first : first + len(cells)] = cells
                csv.append((arrival, ",".join([repr(arrival), *row])))
            else:
                csv.append((arrival, f"{arrival!r}," + (f"{cells[0]},{cells[1]}," if len(cells) == 2 else f",,{cells[0]}")))
        surge, sway, yaw = (repr(float(value)) for value in thrust[k])
        thrust_rows.append(f"{float(epoch + t - step * rng.uniform(0.4, 0.95))!r},{surge},{sway},{yaw}")
    groups = [range(len(streams))] if not suite else [(i,) for i in range(len(streams))]
    fixes = {i: [j for j, row in enumerate(nmea) if row[2] == i] for i, each in enumerate(streams) if each.kind == "position"}
    for group in groups:  # one log's, or each sensor's, sentences
        members = [j for j, row in enumerate(nmea) if row[2] in group]
        for j in rng.choice(len(members), size=min(corrupted, len(members)), replace=False):
            arrival, text, i, _ = nmea[members[j]]
            tag = len(streams[i].stamp)  # the flip lands in the sentence, after its address
            where = int(rng.integers(tag + 7, len(text) - 4))
            flipped = text[:where] + ("7" if text[where] != "7" else "3") + text[where + 1 :]
            nmea.append((arrival + 1e-4, flipped, -1, -1))
    nmea.append((nmea[len(nmea) // 3][0] + 2e-4, "GPGGA,not a sentence", -1, -1))
    for i, own in fixes.items():
        each = streams[i]
        for j in rng.choice(own[5:], size=min(wild_points, max(len(own) - 5, 0)), replace=False):
            k = nmea[j][3]  # the record that used the fix
            t = times[k]
            latitude, longitude, _ = frame.geodetic(samples[i][k, 0] + 60.0, samples[i][k, 1] - 20.0, 0.0)
            text = each.stamp + gga(epoch + t, float(latitude), float(longitude), talker=each.talker)
            nmea.append((epoch + t + 0.5 * each.sample_period - step * 0.5, text, -1, -1))
    nmea.sort(key=lambda row: row[0])
    paths = {
        "nmea": folder / f"{name}.nmea",
        "csv": folder / f"{name}.csv",
        "thrust": folder / f"{name}-thrust.csv",
        "truth": folder / f"{name}-truth.nc",
    }
    began = datetime.datetime.fromtimestamp(epoch, datetime.UTC).isoformat()
    header = (
        f"# lookout simulated log: {ds.attrs.get('scenario', 'a simulated run')}; t = 0 at {began} (Unix {epoch:.1f} s)\n"
        f"# origin of north/east: {frame.latitude} N, {frame.longitude} E; TIME is the Unix time each sentence arrived\n"
    )
    if suite:
        header += "".join(f"# sensor {each.name}: {each.describe()}\n" for each in streams)
    paths["nmea"].write_text(header + "".join(f"{arrival:.6f} {text}\n" for arrival, text, _, _ in nmea))
    if suite:
        csv.sort(key=lambda row: row[0])
    paths["csv"].write_text(
        ",".join(["time", *columns] if suite else ["time", "north", "east", "heading"]) + "\n" + "\n".join(row for _, row in csv) + "\n"
    )
    paths["thrust"].write_text("time,surge,sway,yaw\n" + "\n".join(thrust_rows) + "\n")
    if imu_rows is not None:
        paths["imu"] = folder / f"{name}-imu.csv"
        paths["imu"].write_text("time,fx,fy,r\n" + "\n".join(imu_rows) + "\n")
    truth = ds.expand_dims("run") if "run" not in ds.dims else ds
    truth.attrs.update({"log_epoch_unix_s": epoch, "origin_latitude": frame.latitude, "origin_longitude": frame.longitude})
    write_netcdf(truth, paths["truth"], history=f"truth of the simulated log {paths['nmea'].name}")
    return paths


def _imu_rows(ds: xr.Dataset, imu: tuple[str, float], step: float, epoch: float, seed: int) -> list[str]:
    """The rows ``time,fx,fy,r`` of a suite's IMU (:func:`write_simulated_log`)."""
    name, period = imu
    channels = (f"{name}.measured_specific_force", f"{name}.measured_yaw_rate")
    for channel in channels:
        if channel not in ds:
            raise ValueError(f"imu: the run has no {channel} (sensor {name})")
    ratio = period / step
    if not (math.isfinite(ratio) and abs(ratio - round(ratio)) <= 1e-9 * ratio and round(ratio) >= 1):
        raise ValueError(f"imu: {name}'s sample period, {period:g} s, is not a whole number of the run's {step:g} s")
    every = round(ratio)
    times = np.asarray(ds["time"].values, dtype=float)
    force = np.asarray(ds[channels[0]].values, dtype=float).reshape(times.size, 2)
    rate = np.asarray(ds[channels[1]].values, dtype=float).reshape(times.size)
    rng = np.random.default_rng([seed, 1])  # apart from the log's draws, which stay as without an IMU
    rows = []
    for k, t in enumerate(times):
        arrival = epoch + t - step * rng.uniform(*IMU_ARRIVAL)
        if round(t / step) % every or not (np.all(np.isfinite(force[k])) and math.isfinite(rate[k])):
            continue
        rows.append(f"{float(arrival)!r},{float(force[k, 0])!r},{float(force[k, 1])!r},{math.degrees(float(rate[k]))!r}")
    return rows


#: The magnetic variation (degrees, east positive) and the compass's deviation a raw
#: log's HDG sentences carry unless told: 3.5 W and 1.2 E, of the size a compass in
#: northern Europe shows.
RAW_VARIATION, RAW_DEVIATION = -3.5, 1.2


def _hemisphere(angle: float) -> tuple[str, str]:
    """An angle east positive as (degrees, E or W), two decimals."""
    return f"{abs(angle):.2f}", ("E" if angle >= 0 else "W")


def _utc_fields(unix: float) -> tuple[str, str]:
    """(hhmmss.ss, ddmmyy) of a Unix time."""
    moment = datetime.datetime.fromtimestamp(round(unix, 2), datetime.UTC)
    return f"{moment:%H%M%S}.{moment.microsecond // 10000:02d}", f"{moment:%d%m%y}"


def write_raw_log(
    ds: xr.Dataset,
    path: str | Path,
    *,
    frame: LocalFrame | None = None,
    epoch: float = EPOCH,
    variation: float = RAW_VARIATION,
    deviation: float = RAW_DEVIATION,
    twin: str | Path | None = None,
) -> Path:
    """Write one simulated run as a chart plotter or a VDR logs it: raw NMEA 0183, one
    sentence a line, no time column (:mod:`lookout.io.sentence_time`).

    At each position sample (``measured_position``, the first period of
    ``sensor_sample_period_s``) a GGA, an RMC (with the date, the speed and course over
    ground of the run's true velocity, and ``variation``) and a VTG, stamped with the
    sample's UTC time; at each heading sample an HDG: the magnetic sensor's heading,
    ``true - variation - deviation``, with its deviation and variation, two decimals.
    After a ``#`` header a ZDA gives the date; every 100th fix an AIS line and a
    proprietary ``$P`` line are mixed in (a replay counts and skips them).

    Parameters
    ----------
    ds : xarray.Dataset
        One run of a vessel scenario with a position-heading sensor.
    path : path
        The raw log to write.
    frame, epoch
        As :func:`write_simulated_log`.
    variation, deviation : float
        Degrees, east positive, within +-90.
    twin : path, optional
        Also write the same samples as ``TIME SENTENCE`` lines: each line at the time a
        raw log's reader gives it (a fix's sentences at their UTC, the headings spread
        evenly from one fix to the next, :mod:`lookout.io.sentence_time`), the heading
        as THS (true, five decimals): the raw log's readings, timed by the writer rather
        than by the reader.

    Raises
    ------
    ValueError
        Naming ``variation`` or ``deviation`` outside +-90, before anything is written.
    """
    for label, value in (("variation", variation), ("deviation", deviation)):
        if not (math.isfinite(value) and abs(value) <= 90.0):
            raise ValueError(f"{label} must be degrees within -90 to 90 (east positive); got {value!r}")
    frame = frame or LocalFrame(63.44, 10.40)
    ds = ds.isel(run=0) if "run" in ds.dims else ds
    step = float(ds.attrs["sample_period_s"])
    periods = [float(p) for p in str(ds.attrs["sensor_sample_period_s"]).strip("[]").split(",")]
    every_fix, every_heading = (max(round(periods[i] / step), 1) for i in (0, 2))
    times = np.asarray(ds["time"].values, dtype=float)
    fixes = np.asarray(ds["measured_position"].values, dtype=float).reshape(times.size, -1)
    headings = np.asarray(ds["measured_heading"].values, dtype=float).reshape(times.size)
    psi = np.asarray(ds["heading"].values, dtype=float).reshape(times.size)
    body = np.asarray(ds["velocity"].values, dtype=float).reshape(times.size, -1)
    north = np.cos(psi) * body[:, 0] - np.sin(psi) * body[:, 1]
    east = np.sin(psi) * body[:, 0] + np.cos(psi) * body[:, 1]
    variation_fields = _hemisphere(variation)
    raw = [f"# lookout raw NMEA log: {ds.attrs.get('scenario', 'a simulated run')}; no time column: the time is in the sentences\n"]
    timed: list[str] = []
    _, date = _utc_fields(epoch)
    day = datetime.datetime.fromtimestamp(epoch, datetime.UTC)
    raw.append(sentence("GP", "ZDA", [_utc_fields(epoch)[0], f"{day:%d}", f"{day:%m}", f"{day:%Y}", "00", "00"]) + "\n")
    # segments: the sentences of one fix, then the headings up to the next fix
    segments: list[tuple[float, list[str], list[tuple[str, float]]]] = []
    fix_count = 0
    for k, t in enumerate(times):
        index = round(t / step)
        unix = epoch + index * step
        if index % every_fix == 0 and np.all(np.isfinite(fixes[k])):
            latitude, longitude, _ = frame.geodetic(fixes[k, 0], fixes[k, 1], 0.0)
            clock, date = _utc_fields(unix)
            lat, ns = _minutes(float(latitude), 2, "NS")
            lon, ew = _minutes(float(longitude), 3, "EW")
            knots = math.hypot(north[k], east[k]) / (1852.0 / 3600.0)
            course = math.degrees(math.atan2(east[k], north[k])) % 360.0
            lines = [
                gga(unix, float(latitude), float(longitude)),
                sentence("GP", "RMC", [clock, "A", lat, ns, lon, ew, f"{knots:.3f}", f"{course:.2f}", date, *variation_fields, "D"]),
                sentence(
                    "GP",
                    "VTG",
                    [f"{course:.2f}", "T", f"{(course - variation) % 360.0:.2f}", "M", f"{knots:.3f}", "N", f"{knots * 1.852:.3f}", "K", "D"],
                ),
            ]
            fix_count += 1
            if fix_count % 100 == 0:
                lines += ["!AIVDM,1,1,,B,177KQJ5000G?tO`K>RA1wUbN0TKH,0*5C", sentence("P", "GRME", ["15.0", "M", "45.0", "M", "25.0", "M"])]
            segments.append((unix, lines, []))
        if index % every_heading == 0 and math.isfinite(headings[k]) and segments:
            true = math.degrees(headings[k]) % 360.0
            sensor = (true - variation - deviation) % 360.0
            segments[-1][2].append((sentence("HC", "HDG", [f"{sensor:.2f}", *_hemisphere(deviation), *variation_fields]), true))
    for j, (start, lines, headed) in enumerate(segments):
        raw += [line + "\n" for line in lines + [text for text, _ in headed]]
        # the twin: the fix's sentences at its time; the VTG alone of its kind, at the
        # fix's; the headings spread evenly to the next fix (at the fix's after the last)
        end = segments[j + 1][0] if j + 1 < len(segments) else start
        timed += [f"{start:.6f} {line}\n" for line in lines]
        timed += [f"{start + i * (end - start) / len(headed):.6f} {ths(true)}\n" for i, (_, true) in enumerate(headed)]
    path = Path(path)
    path.write_text("".join(raw))
    if twin is not None:
        Path(twin).write_text("# the raw log's twin: each line at the time its reader gives it, headings as THS\n" + "".join(timed))
    return path
