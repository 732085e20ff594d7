"""Wondergem, Lefeber, Pettersen & Nijmeijer (2009): output-feedback tracking of Cybership II
around an ellipse (Section 5, Table 1).

Three conditions, each a case (a composition, :mod:`.composition`):

* ``simulation``: the paper's initial conditions and gains, plant and scheme with the
  same model (39) (D_n in both), no noise, the observer integrated with the plant and
  the controller sampled at 0.01 s; Table 1's simulation row (9.3056e-2 over 714.2 s).
* ``basin-calm``: the basin as we rebuild it in simulation: D_n in the plant only (the
  basin scheme used linear damping), thrust limits 2 N, 1.5 N, 1.5 N m, observer and
  controller by forward Euler at 0.05 s (20 Hz), position and heading measured at
  10 Hz (the basin's 9 Hz rounded to a multiple of 0.05 s) with noise; Table 1's
  experiment without waves (0.11145 over 715.1 s).
* ``basin-waves``: the same plus JONSWAP waves (Hs = 0.01 m, mean period 0.75 s,
  gamma = 3.3) as first-order motion added to the measurement; Table 1's experiment
  with waves (0.12686 over 730.6 s).

Chosen where the paper is silent (docs/reproductions.md): the ellipse a = 3.5 m,
b = 1.823 m (perimeter 17.14 m, so four laps at 0.05, 0.1, 0.15, 0.2 m/s take 714.2 s),
centre (0, 0), start at theta_0 = 0 with the yaw rate positive (psi_ref(0) = pi/2 =
psi_0); the printed initial velocity estimate [0.5, 0.5, -0.5] taken as v_hat(0) =
eta_hat'(0); measurement noise 2 mm and 0.1 deg; waves travelling along +x. The paper's
"time mean period of 0.75 seconds" (gamma = 3.3) is read as the JONSWAP period
parameter T1 (:mod:`lookout.environment.jonswap`), so that Tp = T1 / 0.834 = 0.899 s and
wp = 6.99 rad/s; read as the zero-crossing period Tz it would be T1 = 1.073 Tz
(Tp = 0.964 s), read as Tp itself wp = 8.38 rad/s.

The package: :mod:`.config` (the paper's numbers and the settings), :mod:`.composition`
(the cases), :mod:`.analysis` (the error index (43), the reference's bounds and thrust,
the gain conditions), :mod:`.studies` (the choice sweep and the hold study),
:mod:`.figures`, :mod:`.run` and :mod:`.tables`.
"""

from __future__ import annotations

from lookout.papers._reproduction import Reproduction
from lookout.papers.wondergem_2009.analysis import (
    error_index,
    gain_conditions,
    gain_study,
    lap_times,
    loop_metrics,
    proposed_gains,
    reference_bounds,
    reference_thrust,
    tracking_errors,
)
from lookout.papers.wondergem_2009.composition import composition, scenario
from lookout.papers.wondergem_2009.config import CONDITIONS, NAME, TABLE_1, TITLE, Config
from lookout.papers.wondergem_2009.run import run, simulate_condition
from lookout.papers.wondergem_2009.studies import HOLD_CASES, batches_of, choice_sweep, hold_documents, hold_study, sweep_documents
from lookout.papers.wondergem_2009.tables import tables


def batches(config: Config) -> list[tuple]:
    """The configured conditions with ``config.runs`` runs each, then, with
    ``config.sweep``, the batches of the choice sweep and of the hold study."""
    conditions = [(scenario(config, condition), config.runs) for condition in config.conditions]
    if not config.sweep:
        return conditions
    studies = batches_of(sweep_documents(config)) + batches_of(hold_documents(config))
    return conditions + [(scenarios[0], len(scenarios)) for scenarios, _ in studies]


#: Wondergem et al. (2009), Section 5: the observer (6) and the tracking scheme (23) on
REPRODUCTION = Reproduction(NAME, Config, CONDITIONS, composition, run, tables, batches_of=batches)

__all__ = [
    "CONDITIONS",
    "Config",
    "HOLD_CASES",
    "NAME",
    "REPRODUCTION",
    "TABLE_1",
    "TITLE",
    "Wondergem2009",
    "choice_sweep",
    "composition",
    "error_index",
    "gain_conditions",
    "gain_study",
    "hold_study",
    "lap_times",
    "loop_metrics",
    "proposed_gains",
    "reference_bounds",
    "reference_thrust",
    "run",
    "scenario",
    "simulate_condition",
    "tables",
    "tracking_errors",
]
