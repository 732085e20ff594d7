"""Calugi et al. (2003): the closed loop's metrics per run."""

from __future__ import annotations

import numpy as np
import xarray as xr

from lookout.analysis import estimation_errors
from lookout.papers.calugi_2003.config import DIVERGED_DISTANCE, m11


def loop_metrics(ds: xr.Dataset) -> dict[str, np.ndarray]:
    """Per run: RMS tracking error (horizontal m, heading rad), RMS velocity estimation error,
    final theta_hat / m11 and its relative error, and whether the run diverged."""
    distance = np.sqrt(((ds.position - ds.position_desired) ** 2).sum("earth_axis"))
    heading = np.arctan2(np.sin(ds.heading - ds.heading_desired), np.cos(ds.heading - ds.heading_desired))
    errors = estimation_errors(ds)
    theta = ds.theta_m11.isel(time=-1).values / m11()
    worst = np.where(np.isfinite(distance.values), distance.values, np.inf).max(axis=-1)
    return {
        "tracking_rms_m": np.sqrt((distance**2).mean("time")).values,
        "heading_tracking_rms_rad": np.sqrt((heading**2).mean("time")).values,
        "velocity_error_rms_m_s": np.sqrt((errors.velocity**2).sum("body_axis").mean("time")).values,
        "final_theta_ratio": theta,
        "theta_relative_error": theta - 1.0,
        "thrust_peak_n": np.abs(ds.force_applied).max("time").values.max(axis=-1),
        "diverged": ~np.isfinite(distance.values).all(axis=-1) | (worst > DIVERGED_DISTANCE),
    }
