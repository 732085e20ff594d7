"""The worst single failure of a sensor suite and its thrusters: the intact case and
every single failure of every instrument and thruster, as one campaign over seeds
(``lookout failures``).

A DP vessel's redundancy is judged by what one failure does to its position (IMO
MSC/Circ.645 and MSC.1/Circ.1580, equipment classes 2 and 3: no single failure may
lose the position; a failure mode and effects analysis lists each component's ways of
failing). Each instrument of the scenario's suite is failed in each mode of
:data:`CANDIDATES` that applies to it, at one time, for the rest of the run; the
campaign's cases axis switches one failure on per case. Every candidate is written into
the scenario with ``start = inf`` (never), so that a case differs from another in
numbers only: the campaign compiles one program for them all. The scenario's own
failures are left out: each case fails one instrument of an intact suite.

Sizes (the stated sizes of the analysis; a jump and a drift act on north only, or on
the instrument's one channel):

==================  ==========================================================
position reference  dropout; freeze; jump of 10 m; drift of 0.05 m/s; noise x 5
gyrocompass         dropout; freeze; jump of 2 deg; drift of 0.01 deg/s; noise x 5
other instruments   dropout; freeze
thruster            stop; stuck (with ``[actuator] kind = "thrusters"``)
==================  ==========================================================

The 0.05 m/s drift is the slow drift the DP guidance warns about (a reference that walks
away slower than its noise hides it, IMCA M 252); 10 m and 2 deg are jumps well beyond
any one sample's noise.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

from lookout._validation import ParameterError

#: (mode, its parameters): a size or rate acts on north, or on the instrument's one channel
_POSITION: tuple[tuple[str, dict[str, Any]], ...] = (
    ("dropout", {}),
    ("freeze", {}),
    ("jump", {"size": [10.0, 0.0]}),
    ("drift", {"rate": [0.05, 0.0]}),
    ("noise", {"factor": 5.0}),
)
_HEADING: tuple[tuple[str, dict[str, Any]], ...] = (
    ("dropout", {}),
    ("freeze", {}),
    ("jump", {"size": math.radians(2.0)}),
    ("drift", {"rate": math.radians(0.01)}),
    ("noise", {"factor": 5.0}),
)
_OTHER: tuple[tuple[str, dict[str, Any]], ...] = (("dropout", {}), ("freeze", {}))

#: What each instrument fails in, by what it gives a combining stage
#: (:data:`lookout.sensing.instrument.POSITION`, ``HEADING``, ``OTHER``).
CANDIDATES: dict[str, tuple[tuple[str, dict[str, Any]], ...]] = {"position": _POSITION, "heading": _HEADING, "other": _OTHER}

#: How each thruster of a thruster actuator fails (:mod:`lookout.actuators.failures`).
THRUSTER_MODES = ("stop", "stuck")

#: The metrics of each case: how far the vessel strays, and the estimate's error.
TRACKING_METRICS = ("max_tracking:position", "max_tracking:heading", "rms_error:position", "max_error:position")
EXCURSION_METRICS = ("max_excursion:position", "max_excursion:heading", "rms_error:position", "max_error:position")

INTACT = "intact"


def failure_cases(document: dict, start: float) -> tuple[dict, list[dict[str, float]], list[str]]:
    """``(scenario document, cases, labels)``: the scenario with every candidate failure
    of every instrument written in at ``start = inf``, and one case per failure that
    sets its start to ``start`` (the first case, ``intact``, sets nothing)."""
    from lookout.scenario.composition import compose

    sensors = document.get("sensors")
    if not isinstance(sensors, dict) or not sensors:
        raise ParameterError("sensors", "lookout failures needs a scenario with a sensor suite ([sensors.NAME] tables; docs/sensors.md)")
    if not (math.isfinite(start) and start >= 0):
        raise ParameterError("start", f"--start must be a finite number of seconds >= 0; got {start}")
    composition = compose(document)
    duration = composition.simulation.duration
    if start >= duration:
        raise ParameterError("start", f"--start ({start:g} s) must be before the run's end (simulation.duration {duration:g} s)")
    suite = composition.scenario.sensor
    failed = copy.deepcopy(document)
    cases: list[dict[str, float]] = [{}]
    labels = [INTACT]
    for name, instrument in zip(suite.names, suite.instruments):
        table = failed["sensors"][name]
        listed = table["failures"] = []  # from an intact suite: the file's own failures are left out
        for mode, parameters in CANDIDATES[instrument.provides]:
            sized = {key: _sized(value, instrument.size) if key in ("size", "rate") else value for key, value in parameters.items()}
            listed.append({"mode": mode, "start": math.inf, **sized})
            cases.append({f"sensors.{name}.failures[{len(listed) - 1}].start": float(start)})
            labels.append(f"{name} {mode}")
    actuator = composition.scenario.actuator
    table = failed.get("actuator")
    if isinstance(table, dict) and hasattr(actuator, "with_failures") and getattr(actuator, "layout", None) is not None:
        listed = table["failures"] = []  # the thrusters' own failures are left out too
        for name in actuator.layout.names:
            for mode in THRUSTER_MODES:
                listed.append({"thruster": name, "mode": mode, "start": math.inf})
                cases.append({f"actuator.failures[{len(listed) - 1}].start": float(start)})
                labels.append(f"{name} {mode}")
    return failed, cases, labels


def _sized(value: Any, channels: int) -> Any:
    """A per-channel size for an instrument of ``channels`` channels: on the first only."""
    if isinstance(value, list):
        return [value[0]] + [0.0] * (channels - 1) if channels != len(value) else value
    return value if channels == 1 else [value] + [0.0] * (channels - 1)


def campaign_document(document: dict, *, start: float, seeds: int, seed: int = 0) -> tuple[dict, list[str]]:
    """The campaign of :func:`failure_cases` (``seeds`` runs per case from ``seed``) and
    its metrics: the largest tracking error of position and heading after ``start`` when
    the scenario has a reference of them, else the largest excursion over the run."""
    from lookout.scenario import metrics as metric_module
    from lookout.scenario.composition import compose

    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ParameterError("seeds", f"--seeds must be a whole number >= 1; got {seeds}")
    failed, cases, labels = failure_cases(document, start)
    scenario = compose(document).scenario
    try:
        metric_module.resolve(list(TRACKING_METRICS), scenario)
        metrics = list(TRACKING_METRICS)
    except ValueError:
        metrics = list(EXCURSION_METRICS)
    # with reference handling (dp-class): when each sensor was rejected, and for how long
    handled = [name for name in scenario.sensor.names if f"{name}.accepted" in scenario.sensor.measurement_layout.names]
    metrics += [f"rejected_after:{name}" for name in handled] + [f"rejected_time:{name}" for name in handled]
    campaign = {
        "scenario": failed,
        "seeds_per_point": seeds,
        "seed": seed,
        "metrics": metrics,
        "after": float(start),
        "sweep": {"kind": "grid", "axes": [{"name": "failure", "labels": labels, "cases": cases}]},
    }
    return campaign, metrics


def worst_table(ds: Any, metrics: list[str]) -> list[dict[str, Any]]:
    """Per case of a finished failures campaign (``ds``, the store's dataset): each
    metric's mean and largest over the seeds, and the diverged runs; with reference
    handling, the failed sensor's detection (the slowest run's ``rejected_after``, NaN
    when some run never rejects it) and the runs in which another sensor was rejected
    (in the intact case: the false rejections); sorted by the largest of the first
    metric, worst first, the intact case kept first."""
    rows = []
    for point, label in enumerate(str(each) for each in ds["failure"].values):
        diverged = np.asarray(ds["diverged"].values, dtype=float)[point]
        row: dict[str, Any] = {"failure": label, "runs": int(diverged.size), "diverged": int(np.sum(diverged > 0))}
        for metric in metrics:
            values = np.asarray(ds[metric.replace(":", "__")].values, dtype=float)[point]
            finite = values[np.isfinite(values)]
            row[f"{metric} mean"] = float(finite.mean()) if finite.size else math.nan
            row[f"{metric} max"] = float(finite.max()) if finite.size else math.nan
        handled = [metric.partition(":")[2] for metric in metrics if metric.startswith("rejected_time:")]
        if handled:
            # the failed sensor's detection: the slowest run's, NaN when a run never rejects it
            failed = label.split()[0]
            if failed in handled:
                after = np.asarray(ds[f"rejected_after__{failed}"].values, dtype=float)[point]
                row["detected after (s)"] = float(after.max()) if np.all(np.isfinite(after)) else math.nan
            else:  # a thruster, or a sensor the stage does not test
                row["detected after (s)"] = None
            rest = [name for name in handled if name != failed]
            rejected = np.stack([np.asarray(ds[f"rejected_time__{name}"].values, dtype=float)[point] for name in rest]) if rest else np.zeros((1, 0))
            row["runs rejecting another sensor"] = int(np.sum(np.any(rejected > 0, axis=0)))
        rows.append(row)
    key = f"{metrics[0]} max"
    intact = [row for row in rows if row["failure"] == INTACT]
    others = sorted((row for row in rows if row["failure"] != INTACT), key=lambda row: -np.nan_to_num(row[key], nan=np.inf))
    return intact + others


__all__ = ["CANDIDATES", "campaign_document", "failure_cases", "worst_table"]
