"""The dead-reckoning benchmark: how far each observer's position drifts when every
position reference is lost for ten minutes, and how soon it recovers.

The DP vessel of Fossen & Strand (1999) in their sea (the Northern Clipper, the
Gauss-Markov bias of their Section 6.1, linear waves of a 7 s peak period, their
sinusoidal thrust (61): open loop, so that every observer sees the same vessel), measured
by a DP vessel's suite: two DGNSS receivers at their antennas' lever arms (0.7 m of
white noise and a 0.5 m, 5 min Gauss-Markov error each, 1 Hz), two gyrocompasses
(0.1 deg and a slow 0.1 deg error, 10 Hz) and an IMU 10 m ahead of the reference point
(10 Hz). After :data:`LOSS_START` seconds (every observer has converged) both receivers
fall silent for :data:`LOSS_DURATION` seconds; the gyrocompasses and the IMU go on.

Per observer, over the seeds: the low-frequency position error before the loss (its
RMS over the 300 s before it), the error at the last sample before 60, 300 and 600 s
into the loss (median and 95th percentile), and the time from the receivers' return until the error's RMS over
the next 60 s is back within 1.25 times its level before the loss (the recovery; none
when it is not back by the run's end). The observers: the passive observer on the
combining stage's position and heading (its hull model and bias estimate carry it),
the extended Kalman filter on the instruments with and without the IMU (with it, the
IMU's specific force is a measurement of the hull model's acceleration: acceleration
feedback; once with the IMU's biases as states, :mod:`lookout.models.imu_biases`), the observer without a hull model, and the IMU-aided observer on an IMU of
each grade (:mod:`lookout.sensing.imu_grades`). Every observer but the IMU-aided ones
reads a tactical-grade IMU where it reads one.

Three conditions (:data:`CONDITIONS`), each a change to the plant alone that the
observers' models do not get: none (the observers' hull model the vessel's own); a hull
model error, the vessel 25 % heavier and 25 % more damped than the model the observers
are given (``plant.vessel.mass_scale`` and ``damping_scale`` 1.25, the largest of the
observer benchmark's model errors, together): the owner of a DP vessel rarely has its
hull model, and a model-based observer dead reckons on it; and the environment changing,
a body-fixed force sinusoid of the paper's bias spread (2000 N, 2000 N, 50 kN m) and a
2400 s period, so that over the ten minutes of the loss, a quarter period, it swings by
1.4 times that spread: the weather a model-based observer's frozen bias estimate does
not follow, and an IMU feels.
"""

from __future__ import annotations

import copy
import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

#: When the receivers fall silent (s): the passive observer's bias estimate has settled.
LOSS_START = 900.0
#: How long they stay silent (s): the ten minutes DP evaluations score dead reckoning over.
LOSS_DURATION = 600.0
#: What follows their return (s).
RECOVERY = 300.0
#: The times into the loss at which the drift is reported (s).
DRIFT_TIMES = (60.0, 300.0, 600.0)
#: Seconds before the loss over which the error's level is taken.
BEFORE = 300.0
#: The window after the return over which the error's RMS must be back within
#: :data:`RECOVERED` times its level before the loss (s).
RECOVERY_WINDOW = 60.0
RECOVERED = 1.25
#: Condition name -> the plant's changes, which the observers' models do not get (key
#: path -> value; :func:`document`).
CONDITIONS: dict[str, dict[str, Any]] = {
    "exact hull model": {},
    "hull model 25 % off": {"plant.vessel.mass_scale": 1.25, "plant.vessel.damping_scale": 1.25},
    "environment changing": {"plant.disturbance": {"kind": "body-force", "amplitude": [2000.0, 2000.0, 50000.0], "period": 2400.0}},
}
#: Seeds per observer: the full size, and ``--quick``.
SEEDS = {"full": 8, "quick": 2}
#: The sea's peak period (s) and the wave motion's standard deviation (m, m, rad): the
#: paper's 3-sigma amplitudes of 10 m, 10 m and 1 deg over 3, as the observers are told.
WAVE_PERIOD = 2.0 * math.pi / 0.8976
WAVE_STD = [10.0 / 3.0, 10.0 / 3.0, math.radians(1.0) / 3.0]


def _sensors(grade: str, imu: bool = True) -> dict:
    gnss = {"kind": "gnss", "noise_std": 0.7, "error_std": 0.5, "error_time_constant": 300.0, "sample_period": 1.0}
    gyro = {"kind": "gyrocompass", "noise_std": math.radians(0.1), "error_std": math.radians(0.1), "error_time_constant": 600.0, "sample_period": 0.1}
    lost = [{"mode": "dropout", "start": LOSS_START, "duration": LOSS_DURATION}]
    sensors = {
        "dgnss1": {**gnss, "lever_arm": [30.0, 5.0], "failures": copy.deepcopy(lost)},
        "dgnss2": {**gnss, "lever_arm": [-25.0, -4.0], "failures": copy.deepcopy(lost)},
        "gyro1": dict(gyro),
        "gyro2": dict(gyro),
    }
    if imu:
        sensors["imu"] = {"kind": "imu", "grade": grade, "lever_arm": [10.0, 0.0], "sample_period": 0.1}
    return sensors


@dataclass(frozen=True)
class Entry:
    """One row of the benchmark: an observer table, on a suite with an IMU of ``grade``
    (or none)."""

    name: str
    observer: dict
    grade: str = "tactical"
    imu: bool = True


def _tactical_bias_walk() -> list[float]:
    """The tactical grade's bias drift as the random walk of its intensity (the IMU-aided
    observer's default model of it, :func:`lookout.observers.ins.random_walk_std`)."""
    from lookout.observers.ins import random_walk_std
    from lookout.sensing.imu_grades import GRADES

    grade = GRADES["tactical"]
    spread = np.array([grade.accelerometer_bias_instability] * 2 + [grade.gyro_bias_instability])
    return [float(each) for each in random_walk_std(spread, grade.bias_time_constant)]


ENTRIES = (
    Entry("passive", {"kind": "passive", "design": "fossen-strand-1999"}),
    Entry("ekf", {"kind": "ekf"}),
    Entry("ekf, IMU biases as states", {"kind": "ekf", "imu_bias": _tactical_bias_walk()}),
    Entry("ekf, no IMU", {"kind": "ekf"}, imu=False),
    Entry("model-free", {"kind": "model-free", "wave_period": WAVE_PERIOD, "wave_std": WAVE_STD}, imu=False),
    *(
        Entry(f"ins, {grade}", {"kind": "ins", "wave_period": WAVE_PERIOD, "wave_std": WAVE_STD}, grade=grade)
        for grade in ("consumer", "industrial", "tactical", "navigation")
    ),
)


def document(entry: Entry, seeds: int, condition: str = "exact hull model", after: float = RECOVERY) -> dict:
    """The scenario document of ``entry`` over ``seeds`` runs under ``condition`` (one of
    :data:`CONDITIONS`: the plant's changes, with the observer's models pinned to the
    unchanged plant's; module docstring), ``after`` seconds simulated after the return."""
    from lookout.scenario import registry
    from lookout.scenario.composition import compose, set_path
    from lookout.studies.benchmark.run import model_pins

    paper = registry.preset("fossen-strand-1999", "paper")
    built = {
        "simulation": {
            "plant_step": 0.1,
            "sample_period": 0.1,
            "duration": LOSS_START + LOSS_DURATION + after,
            "runs": seeds,
            "seed": 0,
        },
        "plant": copy.deepcopy(paper["plant"]),
        "sensors": _sensors(entry.grade, entry.imu),
        "references": {"kind": "weighted-mean"},
        "observer": copy.deepcopy(entry.observer),
        "controller": copy.deepcopy(paper["controller"]),
    }
    changes = CONDITIONS[condition]
    if changes:  # on the composition spelled out, as a campaign's case is
        built = copy.deepcopy(compose(built).document)
        for path, table in model_pins(built).items():
            set_path(built, path, table)
        for path, value in changes.items():
            set_path(built, path, value)
    return built


@dataclass(frozen=True)
class Row:
    """The measured drift of one entry under one condition (m, s): per seed."""

    name: str
    condition: str
    before: np.ndarray  # RMS error over the BEFORE seconds before the loss
    drift: dict[float, np.ndarray]  # error at each DRIFT_TIMES into the loss
    recovery: np.ndarray  # seconds from the return to recovery (NaN: not recovered)
    diverged: int


def measure(times: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, dict[float, np.ndarray], np.ndarray]:
    """(level before, drift at DRIFT_TIMES, recovery time) per run from the position
    error's norm ``error`` (runs x times) on the grid ``times`` (module docstring)."""
    before = (times >= LOSS_START - BEFORE) & (times < LOSS_START)
    level = np.sqrt(np.mean(error[:, before] ** 2, axis=1))
    # the last sample before LOSS_START + each: at the end of the loss, the one before the fix
    drift = {each: error[:, int(np.searchsorted(times, LOSS_START + each - 1e-9)) - 1] for each in DRIFT_TIMES}
    back = LOSS_START + LOSS_DURATION
    step = float(times[1] - times[0])
    window = int(round(RECOVERY_WINDOW / step))
    recovery = np.full(error.shape[0], np.nan)
    starts = np.flatnonzero(times >= back)
    for run in range(error.shape[0]):
        squared = error[run] ** 2
        for index in starts:
            if index + window > times.size:
                break
            if math.sqrt(float(np.mean(squared[index : index + window]))) <= RECOVERED * level[run]:
                recovery[run] = times[index] - back
                break
    return level, drift, recovery


def run_entry(entry: Entry, seeds: int, condition: str = "exact hull model", after: float = RECOVERY) -> Row:
    """Simulate ``entry`` over ``seeds`` runs (seeds 0 to ``seeds`` - 1) under
    ``condition``, ``after`` seconds after the return, and measure it."""
    from lookout.scenario.composition import compose, simulate

    trajectory = simulate(compose(document(entry, seeds, condition, after)))
    times = np.asarray(trajectory.time)
    truth, estimate = np.asarray(trajectory.truth["position"]), np.asarray(trajectory.estimate["position"])
    error = np.linalg.norm(truth - estimate, axis=-1).reshape(seeds, times.size)
    finite = np.all(np.isfinite(error), axis=1)
    error = np.where(np.isfinite(error), error, np.inf)
    level, drift, recovery = measure(times, error)
    return Row(entry.name, condition, level, drift, recovery, int(np.sum(~finite)))


def _number(value: float) -> str:
    if not math.isfinite(value):
        return "-"
    return f"{value:.3g}" if abs(value) < 1000 else f"{value:.0f}"


def table(rows: list[Row]) -> str:
    """The markdown table of ``rows``."""
    head = (
        ["observer", "condition", "before the loss (m)"]
        + [f"after {t:g} s: median, 95 % (m)" for t in DRIFT_TIMES]
        + ["recovery (s): median", "diverged"]
    )
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for row in rows:
        cells = [row.name, row.condition, _number(float(np.median(row.before)))]
        cells += [f"{_number(float(np.median(row.drift[t])))}, {_number(float(np.percentile(row.drift[t], 95)))}" for t in DRIFT_TIMES]
        recovered = row.recovery[np.isfinite(row.recovery)]
        cells += [
            _number(float(np.median(row.recovery))) if recovered.size == row.recovery.size else f"{recovered.size} of {row.recovery.size} recover",
            str(row.diverged),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_csv(rows: list[Row], path: Path) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["observer", "condition", "seed", "before_m"] + [f"drift_{t:g}s_m" for t in DRIFT_TIMES] + ["recovery_s"])
        for row in rows:
            for seed in range(row.before.size):
                writer.writerow([row.name, row.condition, seed, row.before[seed]] + [row.drift[t][seed] for t in DRIFT_TIMES] + [row.recovery[seed]])


def figure(rows: list[Row], path: Path, seeds: int) -> None:
    """Median drift (and 95th percentile) at the reported times, per observer, log scale:
    one panel a condition."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    conditions = [name for name in CONDITIONS if any(row.condition == name for row in rows)]
    fig, axes = plt.subplots(1, len(conditions), figsize=(5.5 * len(conditions), 4.8), layout="constrained", sharey=True, squeeze=False)
    x = np.arange(len(DRIFT_TIMES))
    for ax, condition in zip(axes[0], conditions):
        these = [row for row in rows if row.condition == condition]
        width = 0.8 / len(these)
        for i, row in enumerate(these):
            median = [float(np.median(row.drift[t])) for t in DRIFT_TIMES]
            high = [float(np.percentile(row.drift[t], 95)) for t in DRIFT_TIMES]
            offset = x + (i - (len(these) - 1) / 2) * width
            ax.bar(offset, median, width, label=row.name, color=f"C{i}")
            ax.errorbar(offset, median, yerr=[np.zeros(len(median)), np.subtract(high, median)], fmt="none", ecolor="black", lw=0.8)
        ax.set_yscale("log")
        ax.set_xticks(x, [f"{t:g} s" for t in DRIFT_TIMES])
        ax.set_xlabel("time without position references")
        ax.set_title(condition)
        ax.grid(True, axis="y", which="both", alpha=0.3)
    axes[0][0].set_ylabel("low-frequency position error (m)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8)
    fig.suptitle(f"Dead reckoning on the Northern Clipper: median over {seeds} seeds, bar to the 95th percentile")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run(out: Path, size: str = "full", say: Callable[[str], Any] = print) -> dict[str, Path]:
    """Every entry over the size's seeds; writes table.md, table.csv and drift.png in
    ``out`` and returns their paths."""
    seeds = SEEDS[size]
    rows = []
    for condition in CONDITIONS:
        for entry in ENTRIES:
            rows.append(run_entry(entry, seeds, condition))
            median = _number(float(np.median(rows[-1].drift[LOSS_DURATION])))
            say(f"{entry.name}, {condition}: {median} m after {LOSS_DURATION:g} s (median of {seeds} seeds)")
    out.mkdir(parents=True, exist_ok=True)
    written = {"table": out / "table.md", "csv": out / "table.csv", "figure": out / "drift.png"}
    written["table"].write_text(table(rows) + "\n")
    write_csv(rows, written["csv"])
    figure(rows, written["figure"], seeds)
    return written


__all__ = ["CONDITIONS", "DRIFT_TIMES", "ENTRIES", "LOSS_DURATION", "LOSS_START", "Entry", "Row", "document", "measure", "run", "table"]
