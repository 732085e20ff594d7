"""What a log tells of its own sensors: their rates, their noise and, for a vessel in
waves, the waves. The model-free observer of ``lookout replay LOG`` without a scenario
is designed from these alone (:class:`~lookout.observers.model_free.ModelFreeFilter`).

- **Rates**: the median step between the distinct times of the position lines and of
  the heading lines (:meth:`lookout.io.logs.LogScan.instant_step`), to two significant
  digits.
- **Spread**: each channel's standard deviation around its moving mean over
  :data:`WINDOW` seconds, the low-frequency motion: the sensor's noise and the
  wave-frequency motion together.
- **Waves** (when the user says the vessel is in waves): the spread's power spectral
  density (Welch's method, :func:`scipy.signal.welch`); its peak between
  :data:`WAVE_PERIODS` is the waves' peak period; over the top fifth of the
  frequencies, the density less the tail of the wave model's own spectrum (Fossen &
  Strand (1999), eq. (11), relative damping 0.1, scaled to the peak), times half the
  sampling rate, is the white noise's variance; the rest of the spread's variance is
  the waves'.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lookout.observers.model_free import WAVE_DAMPING

#: The window (s) of the moving mean taken as the low-frequency motion: longer than
#: wave periods, shorter than a manoeuvre.
WINDOW = 30.0
#: The periods (s) where a peak of the spread's spectrum is taken for waves.
WAVE_PERIODS = (3.0, 25.0)
#: The least noise taken (m, degrees): a quantized or smoothed log can show less
#: spread than its sensor's noise.
LEAST_POSITION_STD, LEAST_HEADING_STD = 0.05, 0.05


@dataclass(frozen=True)
class LogSensors:
    """A log's sensors as measured from it (module docstring).

    Attributes
    ----------
    position_period, heading_period : float
        Seconds between fixes and between headings.
    position_std, heading_std : float
        White noise (m per axis, degrees): the whole spread without ``waves``, the
        spread less the waves' share with it.
    wave_period : float or None
        The waves' peak period (s), with ``waves``; None without.
    wave_std : tuple of float or None
        The wave motion's standard deviation (m, m, degrees), with ``waves``.
    position_source, heading_source : str or None
        The source most of the positions and of the headings came from
        (:class:`~lookout.io.nmea.Reading`'s ``source``).
    """

    position_period: float
    heading_period: float
    position_std: float
    heading_std: float
    wave_period: float | None = None
    wave_std: tuple[float, float, float] | None = None
    position_source: str | None = None
    heading_source: str | None = None

    def describe(self) -> str:
        """One line: rates, noise and waves."""
        waves = (
            f", waves of {self.wave_period:.3g} s peak period and {self.wave_std[0]:.2g} m" if self.wave_std is not None and self.wave_period else ""
        )
        return (
            f"position at {1 / self.position_period:.3g} Hz (noise {self.position_std:.2g} m), "
            f"heading at {1 / self.heading_period:.3g} Hz (noise {self.heading_std:.2g} deg){waves}"
        )


def _period(times: list[float]) -> float:
    """The median step between distinct times, to two significant digits (1 Hz, 10 Hz)."""
    return float(f"{np.median(np.diff(times)):.2g}")


def _moving_residual(values: np.ndarray, period: float) -> np.ndarray:
    """``values`` (samples by columns) less their moving mean over :data:`WINDOW` s
    (the samples at either end that the window does not cover are left out)."""
    width = max(int(round(WINDOW / period)), 1)
    if values.shape[0] <= width:
        return values - values.mean(axis=0)
    kernel = np.ones(width) / width
    start = width // 2
    return np.stack([column[start : start + column.size - width + 1] - np.convolve(column, kernel, "valid") for column in values.T], axis=1)


def _waves(residual: np.ndarray, period: float) -> tuple[float, float, float]:
    """``(peak period, wave variance, noise variance)`` of a residual's columns (mean
    over the columns), NaN period when no peak lies within :data:`WAVE_PERIODS`."""
    from scipy.signal import welch

    rate = 1.0 / period
    frequency, density = welch(residual, fs=rate, nperseg=min(512, residual.shape[0]), axis=0)
    density = density.mean(axis=1)
    band = (frequency >= 1.0 / WAVE_PERIODS[1]) & (frequency <= min(1.0 / WAVE_PERIODS[0], 0.8 * rate / 2))
    top = frequency >= 0.8 * frequency[-1]
    total = float(np.mean(residual**2))
    if not np.any(band):
        return math.nan, 0.0, min(float(np.mean(density[top]) * rate / 2), total)
    index = int(np.argmax(np.where(band, density, -np.inf)))
    # the peak: the density's centroid within 30 % of its largest bin (one bin of a
    # Welch estimate is noisy; a narrow sea's centroid is its peak)
    near = band & (np.abs(frequency - frequency[index]) <= 0.3 * frequency[index])
    peak = float(np.sum(frequency[near] * density[near]) / np.sum(density[near]))
    # the wave model's own spectrum, c f^2 / ((f0^2 - f^2)^2 + (2 zeta f0 f)^2), scaled to
    # the peak: its tail is taken out of the top band before the rest is called noise
    shape = frequency**2 / ((peak**2 - frequency**2) ** 2 + (2 * WAVE_DAMPING * peak * frequency) ** 2)
    tail = density[index] / shape[index] * shape
    noise = float(max(np.mean(density[top] - tail[top]), 0.0) * rate / 2)
    return 1.0 / peak, max(total - noise, 0.0), min(noise, total)


def log_sensors(
    log: str | Path,
    fmt: str,
    position_period: float | None = None,
    heading_period: float | None = None,
    waves: bool = False,
    variation: float | None = None,
) -> LogSensors:
    """The log's sensors (module docstring) at the given periods. Of several sources of
    a kind (two receivers at their antennas, two gyros), the one most of its readings
    came from is measured: its rate, and its noise about its own motion.

    Parameters
    ----------
    log : path
    fmt : str
        As :func:`lookout.io.logs.log_format` names it.
    position_period, heading_period : float, optional
        Seconds between fixes and between headings; default the median step between
        the distinct times of the measured source's, to two significant digits.
    waves : bool
        Whether the vessel is in waves: the spread is split into waves and noise.
    variation : float, optional
        For magnetic headings without a variation of their own or an RMC's
        (:class:`~lookout.io.nmea.NmeaParser`).

    Raises
    ------
    ValueError
        Naming the log, when it gives fewer than three positions or headings (its
        magnetic headings without a variation: saying so).
    """
    from lookout.io.geodesy import LocalFrame
    from lookout.io.nmea import NmeaParser
    from lookout.live.run import log_readings

    parser = NmeaParser(variation=variation)
    readings, _ = log_readings(log, parser, fmt)
    frame = None
    # per kind and source: its distinct times and its values
    series: dict[str, dict[str, tuple[list[float], list]]] = {"position": {}, "heading": {}}
    for reading in readings:
        if reading.kind not in ("position", "local_position", "heading"):
            continue
        kind = "heading" if reading.kind == "heading" else "position"
        times, values = series[kind].setdefault(reading.source, ([], []))
        if times and times[-1] == reading.time:
            continue  # a fix told twice in one epoch (GGA and RMC)
        times.append(reading.time)
        if reading.kind == "heading":
            values.append(reading.values[0])
        elif reading.kind == "local_position":
            values.append((float(reading.values[0]), float(reading.values[1])))
        else:
            frame = frame or LocalFrame(reading.values[0], reading.values[1])
            north, east, _ = frame.ned(reading.values[0], reading.values[1])
            values.append((float(north), float(east)))
    most = {kind: max(by_source, key=lambda source: len(by_source[source][0])) if by_source else None for kind, by_source in series.items()}
    positions = series["position"][most["position"]][1] if most["position"] is not None else []
    headings = series["heading"][most["heading"]][1] if most["heading"] is not None else []
    for what, values in (("position", positions), ("heading", headings)):
        if len(values) < 3:
            hint = (
                f"; its {parser.counts['no_variation']} magnetic headings (HDG, HDM) carry no variation: give --variation"
                if what == "heading" and parser.counts["no_variation"]
                else ""
            )
            raise ValueError(f"LOG {log}: {len(values)} {what} readings, too few to measure its sensors from{hint}")
    main = {kind: source for kind, source in most.items() if source is not None}  # each kind's: checked above
    if position_period is None:
        position_period = _period(series["position"][main["position"]][0])
    if heading_period is None:
        heading_period = _period(series["heading"][main["heading"]][0])
    position = _moving_residual(np.asarray(positions, dtype=float).reshape(-1, 2), position_period)
    heading = _moving_residual(np.degrees(np.unwrap(np.radians(np.asarray(headings, dtype=float)))).reshape(-1, 1), heading_period)
    if not waves:
        return LogSensors(
            position_period,
            heading_period,
            max(float(np.sqrt(np.mean(position**2))), LEAST_POSITION_STD),
            max(float(np.sqrt(np.mean(heading**2))), LEAST_HEADING_STD),
            position_source=most["position"],
            heading_source=most["heading"],
        )
    peak, wave_position, noise_position = _waves(position, position_period)
    _, wave_heading, noise_heading = _waves(heading, heading_period)
    return LogSensors(
        position_period,
        heading_period,
        max(math.sqrt(noise_position), LEAST_POSITION_STD),
        max(math.sqrt(noise_heading), LEAST_HEADING_STD),
        None if math.isnan(peak) else peak,
        (math.sqrt(wave_position), math.sqrt(wave_position), math.sqrt(wave_heading)),
        most["position"],
        most["heading"],
    )


#: The least white noise taken for an IMU measured from its log: accelerometers (m/s2)
#: and gyro (rad/s) per sample, a navigation-grade unit's order (docs/sensors.md).
LEAST_ACCELEROMETER_STD, LEAST_GYRO_STD = 1e-5, 1e-6


@dataclass(frozen=True)
class ImuLog:
    """An IMU as measured from its CSV log (``time,fx,fy,r``).

    Attributes
    ----------
    sample_period : float
        The median step between its rows (s), to two significant digits.
    accelerometer_std, gyro_std : float
        Its white noise per sample (m/s2 per axis, rad/s): each channel's second
        differences' standard deviation over sqrt(6) (white noise of variance s^2 gives
        second differences of 6 s^2; a motion smooth over three samples is left out),
        the accelerometers' two averaged in variance.
    """

    sample_period: float
    accelerometer_std: float
    gyro_std: float

    def describe(self) -> str:
        return f"IMU at {1 / self.sample_period:.3g} Hz (noise {self.accelerometer_std:.2g} m/s2, {math.degrees(self.gyro_std):.2g} deg/s)"


def imu_log(path: str | Path) -> ImuLog:
    """The IMU of a CSV log ``time,fx,fy,r`` (:class:`ImuLog`).

    Raises
    ------
    ValueError
        Naming ``--imu`` and the file: fewer than four readings, or no step between them.
    """
    from lookout.io.logs import CsvLog

    rows = np.asarray([(r.time, *r.values) for r in CsvLog(path, source="imu", option="--imu")], dtype=float).reshape(-1, 4)
    if rows.shape[0] < 4:
        raise ValueError(f"--imu {path}: {rows.shape[0]} readings, too few to measure the IMU from")
    steps = np.diff(rows[:, 0])
    steps = steps[steps > 0]
    if steps.size == 0:
        raise ValueError(f"--imu {path}: every reading at one time; no rate to measure")
    period = float(f"{np.median(steps):.2g}")
    curvature = np.diff(rows[:, 1:], n=2, axis=0)
    std = np.sqrt(np.mean(curvature**2, axis=0) / 6.0)
    accelerometer = max(float(np.sqrt(np.mean(std[:2] ** 2))), LEAST_ACCELEROMETER_STD)
    gyro = max(math.radians(float(std[2])), LEAST_GYRO_STD)  # the log's rate in deg/s
    return ImuLog(period, accelerometer, gyro)


__all__ = ["LEAST_HEADING_STD", "LEAST_POSITION_STD", "WAVE_PERIODS", "WINDOW", "ImuLog", "LogSensors", "imu_log", "log_sensors"]
