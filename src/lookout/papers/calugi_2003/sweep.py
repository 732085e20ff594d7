"""Calugi et al. (2003), the open question of Section VI measured: the closed loop
against the sample interval Delta, for both gain sets, as a campaign
(:mod:`lookout.studies`).

The campaign's base is the printed case; two axes of cases: Delta (the observer's and
controller's period and the fixes', with a record about once a second,
:func:`sweep_record_every`) and the gain set (K1, K2 and d). Its metrics are the
campaign vocabulary's ``rms_tracking:position`` over the whole run (``after = 0``)
and ``final:theta_m11`` (theta_hat at the end, kg); a run counts as diverged when it
is not finite or when the vessel or its estimate is more than
:data:`~lookout.papers.calugi_2003.config.DIVERGED_DISTANCE` off.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from lookout.papers._sweep import run_sweep, whole_run_campaign
from lookout.papers.calugi_2003.composition import composition
from lookout.papers.calugi_2003.config import DIVERGED_DISTANCE, GAIN_SETS, INTERVALS, NAME, Config, gains, m11
from lookout.sim import integer_ratio

#: The file of the sweep's campaign store in a reproduction's folder.
STORE = "calugi_2003_interval_sweep.zarr"


def sweep_record_every(interval: float, duration: float) -> int:
    """Record about once a second in the sweeps (their metrics use the true motion only):
    the largest number of samples k with k Delta <= 1 s that divides the run."""
    samples = integer_ratio(duration, interval)
    if samples is None:
        raise ValueError(f"duration ({duration:g} s) must be a whole multiple of the sample interval ({interval:g} s)")
    return max(k for k in range(1, max(1, int(1.0 / interval + 1e-9)) + 1) if samples % k == 0)


def interval_document(config: Config, intervals: Sequence[float] = INTERVALS) -> dict:
    """The Delta sweep as a campaign document."""
    for interval in intervals:
        if integer_ratio(config.sweep_duration, interval) is None:
            raise ValueError(f"sweep_duration ({config.sweep_duration:g} s) must be a whole multiple of every interval; {interval:g} s is not")
    base = composition(
        config, GAIN_SETS[0], duration=config.sweep_duration, record_every=sweep_record_every(config.sample_interval, config.sweep_duration)
    )
    return whole_run_campaign(
        base,
        seeds=config.sweep_seeds,
        seed=config.seed,
        metrics=["rms_tracking:position", "final:theta_m11"],
        divergence=("position", DIVERGED_DISTANCE),
        axes={
            "sample_interval": {
                float(interval): {
                    "simulation.sample_period": float(interval),
                    "sensor.sample_period": float(interval),
                    "simulation.record_every": sweep_record_every(interval, config.sweep_duration),
                }
                for interval in intervals
            },
            "gains": {
                name: {
                    "observer.position_gain": gains(name)["K1"].tolist(),
                    "observer.velocity_gain": gains(name)["K2"].tolist(),
                    "controller.damping_weights": gains(name)["d"].tolist(),
                }
                for name in GAIN_SETS
            },
        },
    )


def interval_sweep(config: Config, out: Path, intervals: Sequence[float] = INTERVALS, progress: Callable | None = None) -> xr.Dataset:
    """The campaign of :func:`interval_document`, computed into ``out /`` :data:`STORE`;
    returns ``rms_tracking__position`` (m), ``final__theta_m11`` (kg),
    ``theta_relative_error`` (theta_hat(T) / m11 - 1) and ``diverged`` over
    (sample_interval, gains, seed)."""
    sweep = run_sweep(interval_document(config, intervals), out / STORE, source=f"{NAME} Delta sweep", progress=progress)
    sweep["theta_relative_error"] = (sweep.final__theta_m11 / m11() - 1.0).assign_attrs(units="1", long_name="theta_hat(T) / m11 - 1")
    sweep.attrs.update({"title": f"{NAME}: closed loop against the sample interval Delta", "duration_s": config.sweep_duration})
    return sweep


def sweep_summary(sweep: xr.Dataset) -> dict:
    """Per gain set and Delta: mean RMS tracking error, mean |theta_hat(T) / m11 - 1| and
    diverged runs."""
    result = {}
    for name in sweep.gains.values.tolist():
        rows = {}
        for interval in sweep.sample_interval.values.tolist():
            cell = sweep.sel(gains=name, sample_interval=interval)
            diverged = cell.diverged.values.astype(bool)
            kept = ~diverged
            rows[f"{interval:g}"] = {
                "tracking_rms_m": float(cell.rms_tracking__position.values[kept].mean()) if kept.any() else None,
                "theta_relative_error": float(np.abs(cell.theta_relative_error.values[kept]).mean()) if kept.any() else None,
                "diverged": int(diverged.sum()),
                "seeds": int(diverged.size),
            }
        result[name] = rows
    return result
