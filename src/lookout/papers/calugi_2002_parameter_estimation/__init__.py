"""Reproduction of Calugi (2002), master thesis, chapter 3: on-line parameter estimation
(Middleton–Goodwin, (3.9) with (3.13)–(3.16)) on the frictionless pendulum, Figs. 3.2 and 3.3.

Printed: the pendulum M = m l^2, G = m g l sin q; Sim 1, theta = m, piecewise
constant, l = 1.5 m, h = 10, q(0) = 1 rad, q'(0) = 0, m_hat(0) = 1 kg; Sim 2,
theta = (m l^2, m l), h = 100, q(0) = q'(0) = 0, theta_hat(0) = (4.5, 2); the filter
1/(s + 1).

Not printed, chosen here (docs/reproductions.md): the input tau = 5 sin t N m in both
simulations; T = 60 s; Sim 1's mass m = 2 kg on [0, 20) s, 3 kg on [20, 40) s and
1.5 kg from 40 s; Sim 2's m = 1 kg and l = 1.5 m, so theta = (2.25 kg m^2, 1.5 kg m);
no friction. The estimator (:class:`lookout.observers.parameter_estimator.ParameterEstimator`)
is integrated jointly with the plant on the exact q and q' (``observer_mode="continuous"``),
RK4 at 0.2 ms (Sim 2 is stiff: h |phi_f|^2 reaches about 1.3e3 1/s), the input held
over 10 ms samples, recorded every 10 ms.

Two runs without excitation: Sim 2 with tau = 0 at rest (nothing moves), and Sim 1
with tau = 0 from q(0) = 1 rad (the pendulum swings, but phi = l^2 q'' + g l sin q is
zero along the free motion, so phi_f is zero and m_hat must stay at 1 kg: this holds
only with the q'(0) e^{-t} term of the filtered acceleration).

Reported: Sim 1, the estimate 1, 2 and 10 s after the start and after each jump and the
time to settle within 1 %; Sim 2, the time to settle within 1 %, the final estimates
and errors; for both, persistence of excitation as the smallest windowed
lambda_min(int_{t-T}^t phi_f^T phi_f) over the run, the stiffness h lambda_max(phi_f^T phi_f),
and whether V = 1/2 |theta~|^2 ever increases while theta is constant; the
no-excitation runs' largest change of the estimate.

The package: :mod:`.config` (the settings and the runs' numbers), :mod:`.composition`
(each run as a composition, and its simulation), :mod:`.analysis` (the metrics and the
tables), :mod:`.figures`; here, :func:`run` and the :class:`~lookout.papers._reproduction.Reproduction`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from lookout.papers._report import save_figures, summary_header, write_summary
from lookout.papers._reproduction import Reproduction, simulate_each

from . import composition as _composition
from .analysis import settle_time, summarize, tables
from .composition import build, simulate_run
from .config import CASES, LENGTH, NAME, REPORT_DELAYS, SETTLE_BAND, SIM1_MASSES, SIM1_SWITCH_TIMES, SIM2_MASS, SIMULATIONS, TITLE, Config, Simulation
from .figures import input_text, paper_figures


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate the four runs; write NetCDF, figures and summary.json under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    results, estimators, files, status = {}, {}, [], []
    each = simulate_each(
        SIMULATIONS,
        lambda name, progress: simulate_run(config, name, progress=progress),
        out,
        "calugi_2002_ch3_{case}.nc",
        lambda name: f"lookout reproduce {NAME}: {SIMULATIONS[name].label}",
        progress=progress,
    )
    for name, scenario, ds, filename in each:
        files.append(filename)
        status += ds.status.values.tolist()
        results[name], estimators[name] = ds, scenario.observer
    summary = {
        **summary_header(NAME, config, status, runs=1, seeds=[config.seed]),
        "input": f"{input_text(config)} (chosen), held over {config.sample_period:g} s",
        **summarize(config, results, estimators),
    }
    files += save_figures(paper_figures(results, estimators, config), out)
    summary["files"] = sorted([*files, "summary.json"])
    return write_summary(summary, out)


#: Calugi (2002), Section 3.2: the Middleton–Goodwin estimator on the pendulum, Sims 1 and 2.
REPRODUCTION = Reproduction(NAME, Config, CASES, _composition.composition, run, tables)

__all__ = [
    "CASES",
    "Config",
    "LENGTH",
    "NAME",
    "REPORT_DELAYS",
    "REPRODUCTION",
    "SETTLE_BAND",
    "SIM1_MASSES",
    "SIM1_SWITCH_TIMES",
    "SIM2_MASS",
    "SIMULATIONS",
    "Simulation",
    "TITLE",
    "build",
    "run",
    "settle_time",
    "simulate_run",
    "summarize",
    "tables",
]
