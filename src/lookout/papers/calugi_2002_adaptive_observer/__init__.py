"""Calugi (2002), Section 4.8: the adaptive observer on a pendulum of unknown mass (Figs 4.2, 4.3).

The free pendulum M = m l^2, G = m g l sin q, no friction, theta = m unknown (the
regressor is phi = l^2 psi + g l sin q = tau / theta_hat, :mod:`lookout.models.parameters`);
only q is measured. The discrete observer (4.34)–(4.35) with resetting (4.45),
:class:`~lookout.observers.adaptive_manipulator.AdaptiveManipulatorObserver`, at the
printed settings: K = 20, Gamma = 10, m = 1 kg, l = 1.5 m, theta_hat(0) = 0.1 kg,
q(0) = 0, q'(0) = -1 rad/s, x1_hat(0) = 0, Delta = 10 ms (and 1 ms).

Chosen where the thesis is silent (docs/reproductions.md):

* the input tau = sin t N m (the thesis gives none; with tau = 0 the mass cannot be
  identified, and the separate long-term Fig. 4.3 suggests slow convergence);
* the resetting bounds [0.05, 5] kg and mu = 0.01 kg (M = m l^2 is positive definite
  for every m > 0, so any mu < 0.05 keeps M_hat positive definite);
* the plant integrated by RK4 at the largest step <= 1 ms that divides Delta, tau held over each sample.

Beyond the thesis: the order of (4.34)–(4.35) against the continuous observer (4.5)–(4.7)
(given the true q'), and a run in which the resets fire (:data:`STRESS`: Gamma = 1000,
bounds [0.5, 1.5] kg, mu = 0.01 kg).

The package: :mod:`.config` (the settings), :mod:`.composition` (the closed loop as
compositions, and its simulation), :mod:`.analysis` (the studies, the metrics and the
tables), :mod:`.figures`; here, :func:`run` and the
:class:`~lookout.papers._reproduction.Reproduction`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from lookout.analysis.adaptive_manipulator import check_theorem_4_1
from lookout.papers._report import write_summary
from lookout.papers._reproduction import Reproduction
from lookout.results import write_netcdf
from lookout.scenario.composition import compose

from . import composition as _composition
from .analysis import continuous_reference, max_speed, order_study, summarize, tables
from .composition import build, closed_loop, order_composition, simulate_case, simulate_document, stress_composition, study_compositions
from .config import CASES, LENGTH, MASS, NAME, ORDER_DURATION, ORDER_PERIODS, REPORT_TIMES, SAMPLE_PERIODS, STRESS, TITLE, Config, parameters
from .figures import save_paper_figures


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate Delta = 10 ms and 1 ms (and the studies); write NetCDF, figures, summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    results, per_period, files = {}, {}, []
    parts = len(SAMPLE_PERIODS) + (2 if config.sweep else 0)
    for index, (case, period) in enumerate(zip(CASES, SAMPLE_PERIODS)):
        step = None if progress is None else (lambda done, total, i=index: progress(i + done / total, parts))
        ds = simulate_case(config, case, progress=step)
        filename = f"calugi_2002_adaptive_observer_{int(round(period * 1000))}ms.nc"
        write_netcdf(ds, out / filename, history=f"lookout reproduce {NAME} (Delta = {period:g} s)")
        files.append(filename)
        results[period] = ds.isel(run=0)
        per_period[f"{period:g}"] = summarize(results[period], config)
    study = {}
    if config.sweep:
        study["order"] = order_study(config)
        if progress is not None:
            progress(len(SAMPLE_PERIODS) + 1, parts)
        stress = simulate_document(stress_composition(config)).isel(run=0)
        study["stress"] = {**STRESS, **summarize(stress, config), "theta_hat_range": [float(stress.mass_hat.min()), float(stress.mass_hat.max())]}
        if progress is not None:
            progress(parts, parts)
    theorem = check_theorem_4_1(
        parameters(),
        config.gain,
        config.adaptation_gain,
        max_speed=max_speed(results),
        initial_error=(np.array([-1.0]), np.array([MASS - config.initial_mass])),
    )
    files += save_paper_figures(results, config, out)
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "seeds": [config.seed],
        "status": [s for values in per_period.values() for s in values["status"]],
        "sample_periods": per_period,
        "theorem_4_1": theorem.to_dict(),
        **study,
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def batches(config: Config) -> list[tuple]:
    """Each case, and with ``config.sweep`` the order study's and the stress run's scenarios."""
    documents = [_composition.composition(config, case) for case in CASES] + (study_compositions(config) if config.sweep else [])
    return [(compose(document).scenario, config.runs) for document in documents]


#: Calugi (2002), Section 4.8: the adaptive observer with resetting on a pendulum of unknown mass.
REPRODUCTION = Reproduction(NAME, Config, CASES, _composition.composition, run, tables, batches_of=batches)

__all__ = [
    "CASES",
    "Config",
    "LENGTH",
    "MASS",
    "NAME",
    "ORDER_DURATION",
    "ORDER_PERIODS",
    "REPORT_TIMES",
    "REPRODUCTION",
    "SAMPLE_PERIODS",
    "STRESS",
    "TITLE",
    "build",
    "closed_loop",
    "continuous_reference",
    "order_composition",
    "order_study",
    "parameters",
    "run",
    "simulate_case",
    "simulate_document",
    "stress_composition",
    "study_compositions",
    "summarize",
    "tables",
]
