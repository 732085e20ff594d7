"""Logs written from a simulated run, with the truth beside them.

A run's sensor samples become what a bridge computer would have recorded: a GGA
sentence for each position fix and a THS sentence for each heading sample, each
stamped with the time it arrived. The arrival jitters within the sample period
before the observer's step that first uses the sample (a simulated sensor samples at
the step; the log says when its sentence came in): the fix and the thrust 40-90 ms
before, the heading, which a live session steps on (:class:`~lookout.live.Session`),
5-35 ms before. Replaying the log steps the observer on the run's own samples. On top of the samples the log carries what a real
one does:

- an outage: no fix for a while (the receiver lost its correction or its antenna);
- corrupted copies of a few sentences (a character flipped on the wire: the
  checksum fails) and a few lines that are not NMEA;
- wild points: extra fixes far off, between the samples, with good checksums.

The same samples go to a CSV log (``time,north,east,heading``) at full precision, the
applied thrust to ``time,surge,sway,yaw``, and the run to NetCDF.
"""

from __future__ import annotations

import datetime
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from lookout.io.geodesy import LocalFrame
from lookout.io.nmea import sentence

if TYPE_CHECKING:
    import xarray as xr

#: 2026-12-01T00:00:00Z: the Unix time of the example log's step 0.
EPOCH = 1796083200.0
#: The outage a log has unless told otherwise: (start, length) in seconds of run time.
DEFAULT_OUTAGE = (300.0, 30.0)


def _minutes(value: float, degree_digits: int, hemispheres: str) -> tuple[str, str]:
    """``(dddmm.mmmmmmm, hemisphere)`` with seven decimals of minutes (0.19 mm)."""
    hemisphere = hemispheres[0] if value >= 0 else hemispheres[1]
    value = abs(value)
    degrees = int(value)
    minutes = (value - degrees) * 60.0
    if round(minutes, 7) >= 60.0:
        degrees, minutes = degrees + 1, 0.0
    return f"{degrees:0{degree_digits}d}{minutes:010.7f}", hemisphere


def gga(time_of_day: float, latitude: float, longitude: float, quality: int = 2, satellites: int = 12, hdop: float = 0.8) -> str:
    """A GGA sentence (talker GP) with seven decimals of minutes."""
    hours, rest = divmod(time_of_day % 86400.0, 3600.0)
    minutes, seconds = divmod(rest, 60.0)
    lat, ns = _minutes(latitude, 2, "NS")
    lon, ew = _minutes(longitude, 3, "EW")
    return sentence(
        "GP",
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


def ths(heading_degrees: float) -> str:
    """A THS sentence (talker HE, mode A) with five decimals of degrees."""
    return sentence("HE", "THS", [f"{heading_degrees % 360.0:.5f}", "A"])


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
) -> dict:
    """Write the NMEA log, the CSV logs and the truth of one simulated run.

    Parameters
    ----------
    ds : xarray.Dataset
        One run of a vessel scenario (``lookout run``): ``measured_position``,
        ``measured_heading``, ``force_applied``, ``moment_applied``, and the attributes
        ``sample_period_s`` and ``sensor_sample_period_s``.
    folder : path
        Where ``<name>.nmea``, ``<name>.csv``, ``<name>-thrust.csv`` and
        ``<name>-truth.nc`` go (created).
    frame : LocalFrame, optional
        Where north = east = 0 lies; default 63.44 N, 10.40 E.
    epoch : float
        Unix time of the run's t = 0.
    outage : (start, length), optional
        Seconds of run time without fixes: finite, ``length`` positive, and within the
        run (``start + length`` at most its duration); default :data:`DEFAULT_OUTAGE`,
        None for no outage.
    corrupted, wild_points : int
        Corrupted copies of sentences, and fixes 60 m off, added to the log.
    seed : int
        Of the arrival jitter and the corruptions.

    Returns
    -------
    dict
        The written paths by role (``nmea``, ``csv``, ``thrust``, ``truth``).

    Raises
    ------
    ValueError
        Naming ``outage`` when it is not a window within the run, before anything is
        written.
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
    folder.mkdir(parents=True, exist_ok=True)
    periods = [float(p) for p in str(ds.attrs["sensor_sample_period_s"]).strip("[]").split(",")]
    every_position, every_heading = round(periods[0] / step), round(periods[2] / step)
    times = np.asarray(ds["time"].values, dtype=float)
    position = np.asarray(ds["measured_position"].values, dtype=float)
    heading = np.asarray(ds["measured_heading"].values, dtype=float)
    thrust = np.column_stack([ds["force_applied"].values, ds["moment_applied"].values])
    rng = np.random.default_rng(seed)
    nmea, csv, thrust_rows = [], [], []
    for k, t in enumerate(times):
        fix = k % every_position == 0 and np.all(np.isfinite(position[k])) and not (outage and outage[0] <= t < outage[0] + outage[1])
        sample = k % every_heading == 0 and np.isfinite(heading[k])
        arrival_fix = epoch + t - step * rng.uniform(0.4, 0.9)
        arrival_heading = epoch + t - step * rng.uniform(0.05, 0.35)
        if fix:
            latitude, longitude, _ = frame.geodetic(position[k, 0], position[k, 1], 0.0)
            nmea.append((arrival_fix, gga(epoch + t, float(latitude), float(longitude))))
        if sample:
            nmea.append((arrival_heading, ths(math.degrees(heading[k]))))
        if fix:  # each reading on its own row, at its own arrival
            csv.append(f"{float(arrival_fix)!r},{float(position[k, 0])!r},{float(position[k, 1])!r},")
        if sample:
            csv.append(f"{float(arrival_heading)!r},,,{math.degrees(float(heading[k]))!r}")
        surge, sway, yaw = (repr(float(value)) for value in thrust[k])
        thrust_rows.append(f"{float(epoch + t - step * rng.uniform(0.4, 0.95))!r},{surge},{sway},{yaw}")
    fixes = [i for i, (_, text) in enumerate(nmea) if "GGA" in text]
    for i in rng.choice(len(nmea), size=min(corrupted, len(nmea)), replace=False):
        arrival, text = nmea[i]
        where = int(rng.integers(7, len(text) - 4))
        flipped = text[:where] + ("7" if text[where] != "7" else "3") + text[where + 1 :]
        nmea.append((arrival + 1e-4, flipped))
    nmea.append((nmea[len(nmea) // 3][0] + 2e-4, "GPGGA,not a sentence"))
    for i in rng.choice(fixes[5:], size=min(wild_points, max(len(fixes) - 5, 0)), replace=False):
        k = int(round((nmea[i][0] - epoch) / step + 0.5))  # the step that used the fix
        t = times[min(k, len(times) - 1)]
        latitude, longitude, _ = frame.geodetic(position[k, 0] + 60.0, position[k, 1] - 20.0, 0.0)
        nmea.append((epoch + t + 0.5 * periods[0] - step * 0.5, gga(epoch + t, float(latitude), float(longitude))))
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
    paths["nmea"].write_text(header + "".join(f"{arrival:.6f} {text}\n" for arrival, text in nmea))
    paths["csv"].write_text("time,north,east,heading\n" + "\n".join(csv) + "\n")
    paths["thrust"].write_text("time,surge,sway,yaw\n" + "\n".join(thrust_rows) + "\n")
    truth = ds.expand_dims("run") if "run" not in ds.dims else ds
    truth.attrs.update({"log_epoch_unix_s": epoch, "origin_latitude": frame.latitude, "origin_longitude": frame.longitude})
    write_netcdf(truth, paths["truth"], history=f"truth of the simulated log {paths['nmea'].name}")
    return paths
