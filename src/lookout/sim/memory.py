"""What a run holds in memory (its records, its working memory while it takes a sample),
and the refusal of a batch that cannot fit, before anything is allocated."""

from __future__ import annotations

import jax.numpy as jnp

from lookout._resources import format_bytes, refuse_unless_it_fits
from lookout.sim.scenario import Scenario

#: A batch holds its records at least twice at its peak (the scan's output and the
#: joined or gathered copy); below that, a batch is refused before it starts.
RECORD_COPIES = 2
#: Bytes a run's scan holds per record whatever the number of runs (the record times
#: and indices, a metric window): measured about 20 B (a 3e7-record summary held
#: 0.55 GB above the runtime).
RECORD_OVERHEAD_BYTES = 32


def record_nbytes(scenario: Scenario) -> int:
    """Bytes that one recorded sample of one run takes in the results (truths,
    estimate, measurement, reference and inputs), from the signals the components
    declare (the fit check made sure the records have those shapes), without a trace."""
    signals = scenario.record_signals
    size = sum(s.size for s in (*signals.truth, *signals.estimate, *signals.extra, *signals.reference, *signals.actuation))
    return int((size + signals.measurement.size + 2 * signals.input.size) * jnp.zeros(()).dtype.itemsize)


def working_nbytes(scenario: Scenario) -> int:
    """Bytes one run holds while it takes a sample, beyond its records: the process noise
    of the sample's plant steps, and what its components declare (a component's
    ``working_nbytes``: a Kalman filter's Jacobians, a thruster allocation's matrices)."""
    own = scenario.substeps * scenario.plant.noise_size * jnp.zeros(()).dtype.itemsize
    parts = (scenario.plant, scenario.sensor, scenario.observer, scenario.reference, scenario.controller, scenario.actuator)
    return int(own + sum(int(getattr(part, "working_nbytes", 0)) for part in parts))


def check_batch_memory(scenario: Scenario, runs: int, argument: str = "keys", available: float | None = None) -> None:
    """Refuse (ValueError naming ``argument``) a batch of ``runs`` whose records and
    working memory cannot fit in the memory available now, before anything is allocated."""
    per_record = record_nbytes(scenario)
    working = working_nbytes(scenario)
    need = scenario.n_records * (RECORD_COPIES * runs * per_record + RECORD_OVERHEAD_BYTES) + runs * working
    refuse_unless_it_fits(
        need,
        f"{argument}: {runs} run(s) x {scenario.n_records} records x {per_record} B (x{RECORD_COPIES} at the peak, + {RECORD_OVERHEAD_BYTES} B per record)"
        + (f" + {runs} x {format_bytes(working)} while a sample is taken" if working > 2**20 else ""),
        "simulate fewer runs at a time, a shorter duration, or fewer records (record_every); a campaign (lookout.studies) runs them in chunks",
        available=available,
    )
