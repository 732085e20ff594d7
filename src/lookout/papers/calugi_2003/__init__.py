"""Reproduction of Calugi, Robertsson & Johansson (2003), Section V: adaptive observer
(unknown m11) with vectorial observer backstepping on a supply vessel, and the
questions the paper leaves open, answered with numbers.

From the paper: the supply vessel (59) with K = 0, theta = m11 unknown, K1 = K2 =
1e-3 I, Gamma = 1e3, C1 = C2 = 0.1 I, d_i = 0.1, the reference filter
F(s) = 0.1^3 / (s + 0.1)^3 (60), Delta = 0.1 s, white measurement noise (DGPS "1-3 m",
gyro "less than 0.1 deg", Section I).

Chosen here (docs/reproductions.md): noise std 1 m, 1 m, 0.1 deg; theta_hat(0) =
0.8 m11 in the bounds [0.5, 2] m11 (projection); the setpoint schedule
:data:`WAYPOINTS` (north moves of 20 m for surge excitation, peak reference speed
about 0.55 m/s); the plant integrated by
RK4 at 0.01 s whatever Delta (so that only the observer and controller are sampled);
no bias or waves (the model (1)-(2) has none); the controller's coupling weight
P1 = 1 (the paper's law). Two gain sets: the printed one, and
:func:`lookout.analysis.adaptive_dp.satisfying_gains` (which satisfies (57)-(58)).

The package: :mod:`.config` (the paper's numbers, the gain sets and the settings),
:mod:`.composition` (the cases), :mod:`.analysis` (the closed loop's metrics),
:mod:`.sweep` (the Delta sweep, a campaign), :mod:`.studies` (theta_hat's convergence,
the discretization order, the noise drift), :mod:`.figures` and :mod:`.tables`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lookout.analysis.adaptive_dp import check_calugi_2003
from lookout.papers._report import summary_header, write_summary
from lookout.papers._reproduction import Reproduction, simulate_cases
from lookout.papers.calugi_2003.analysis import loop_metrics
from lookout.papers.calugi_2003.composition import CASES, build, composition
from lookout.papers.calugi_2003.config import (
    CALUGI_2003_D,
    CALUGI_2003_M,
    DESIGN_SPEED,
    DIVERGED_DISTANCE,
    GAIN_SETS,
    INTERVALS,
    NAME,
    NOISE_LEVELS,
    PLANT_STEP,
    PRINTED_GAINS,
    TITLE,
    WAYPOINTS,
    Config,
    gains,
    m11,
    paper_vessel,
)
from lookout.papers.calugi_2003.figures import _figures, _forces_and_theta_figure
from lookout.papers.calugi_2003.studies import (
    _convergence_summary,
    _drift_summary,
    _order_summary,
    convergence_study,
    discretization_order,
    noise_drift,
)
from lookout.papers.calugi_2003.sweep import STORE, interval_document, interval_sweep, sweep_record_every, sweep_summary
from lookout.papers.calugi_2003.tables import tables
from lookout.results import write_netcdf
from lookout.sim import Scenario


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate both gain sets in closed loop (and the sweeps); write NetCDF, figures and summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    parts = len(GAIN_SETS) + (4 if config.sweep else 0)
    # each gain set as `lookout run` of its case's file simulates it: the same numbers to the bit
    ds = simulate_cases(REPRODUCTION, config, GAIN_SETS, "gains", progress=progress, parts=parts)
    ds.attrs.update({"reproduction": NAME, "title": TITLE, "config": config.model_dump_json(), "true_m11": m11()})
    write_netcdf(ds, out / "calugi_2003.nc", history=f"lookout reproduce {NAME} (seeds {config.seeds[0]}..{config.seeds[-1]}, both gain sets)")
    files = ["calugi_2003.nc"]
    metrics = loop_metrics(ds)
    per_set = {}
    vessel = paper_vessel()
    bounds = [config.theta_bounds[0] * m11(), config.theta_bounds[1] * m11()]
    for name in GAIN_SETS:
        chosen = ds.gains.values == name
        summary: dict[str, Any] = {key: [float(v) for v in np.asarray(values)[chosen]] for key, values in metrics.items() if key != "diverged"}
        summary["diverged"] = int(np.asarray(metrics["diverged"])[chosen].sum())
        gain = gains(name)
        report = check_calugi_2003(vessel, K1=gain["K1"], K2=gain["K2"], d=gain["d"], theta_bounds=bounds)
        summary["gains"] = {"K1": gain["K1"].tolist(), "K2": gain["K2"].tolist(), "d": gain["d"].tolist(), "C1": gain["C1"], "C2": gain["C2"]}
        if "reason" in gain:
            summary["gains"]["reason"] = gain["reason"]
        summary["conditions"] = report.to_dict()
        per_set[name] = summary
    sweep = convergence = drift = order = None
    if config.sweep:
        sweep = interval_sweep(
            config, out, progress=None if progress is None else (lambda done, total: progress(len(GAIN_SETS) + done / total, parts))
        )
        convergence = convergence_study(config)
        if progress is not None:
            progress(len(GAIN_SETS) + 2.0, parts)
        convergence.to_netcdf(out / "calugi_2003_theta_convergence.nc")
        drift = noise_drift(config)
        if progress is not None:
            progress(len(GAIN_SETS) + 3.0, parts)
        drift.to_netcdf(out / "calugi_2003_noise_drift.nc")
        order = discretization_order(config)
        if progress is not None:
            progress(len(GAIN_SETS) + 4.0, parts)
        order.to_netcdf(out / "calugi_2003_discretization_order.nc")
        files += [STORE, "calugi_2003_theta_convergence.nc", "calugi_2003_noise_drift.nc", "calugi_2003_discretization_order.nc"]
    files += _figures(ds, sweep, convergence, out, config)
    summary = {
        **summary_header(NAME, config, ds.status.values.tolist()),
        "true_m11": m11(),
        "gain_sets": per_set,
        "interval_sweep": None if sweep is None else sweep_summary(sweep),
        "theta_convergence": None if convergence is None else _convergence_summary(convergence),
        "noise_drift": None if drift is None else _drift_summary(drift),
        "discretization_order": None if order is None else _order_summary(order),
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def batches(config: Config) -> list[tuple[Scenario, int]]:
    """Each gain set's runs, and the Delta sweep's largest batch (a chunk: one point's
    seeds at Delta = 0.01 s)."""
    result = [(build(config, case), config.runs) for case in CASES]
    if config.sweep:
        interval = min(INTERVALS)
        result.append(
            (
                build(
                    config, sample_interval=interval, duration=config.sweep_duration, record_every=sweep_record_every(interval, config.sweep_duration)
                ),
                config.sweep_seeds,
            )
        )
    return result


#: Calugi, Robertsson & Johansson (2003), Section V: the adaptive observer and vectorial backstepping.
REPRODUCTION = Reproduction(NAME, Config, CASES, composition, run, tables, batches_of=batches)

__all__ = [
    "CALUGI_2003_D",
    "CALUGI_2003_M",
    "CASES",
    "DESIGN_SPEED",
    "DIVERGED_DISTANCE",
    "GAIN_SETS",
    "INTERVALS",
    "NAME",
    "NOISE_LEVELS",
    "PLANT_STEP",
    "PRINTED_GAINS",
    "REPRODUCTION",
    "STORE",
    "TITLE",
    "WAYPOINTS",
    "Config",
    "batches",
    "build",
    "composition",
    "convergence_study",
    "discretization_order",
    "gains",
    "interval_document",
    "interval_sweep",
    "loop_metrics",
    "m11",
    "noise_drift",
    "paper_vessel",
    "run",
    "sweep_record_every",
    "sweep_summary",
    "tables",
    "_figures",
    "_forces_and_theta_figure",
]
