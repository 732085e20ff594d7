"""Simulating the conditions and the studies, and writing the results."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import xarray as xr

from lookout.papers._report import write_summary
from lookout.papers.wondergem_2009.analysis import gain_study, lap_times, loop_metrics
from lookout.papers.wondergem_2009.composition import composition
from lookout.papers.wondergem_2009.config import LAP_SPEEDS, NAME, TABLE_1, TITLE, Config
from lookout.papers.wondergem_2009.figures import figures
from lookout.papers.wondergem_2009.studies import choice_sweep, hold_study
from lookout.reference import EllipseReference
from lookout.results import write_netcdf
from lookout.scenario.composition import compose


def simulate_condition(config: Config, condition: str) -> xr.Dataset:
    """The runs of ``condition`` (seeds ``config.seeds``), simulated as ``lookout run``
    simulates the condition's composition written as a scenario file."""
    from lookout.scenario.file import CompositionSpec, simulate_trajectory

    ds = simulate_trajectory(CompositionSpec(compose(composition(config, condition)))).to_xarray()
    ds.attrs.update({"reproduction": NAME, "title": TITLE, "condition": condition, "config": config.model_dump_json()})
    return ds


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate each condition (``runs`` seeds each) and the choice sweep; write NetCDF,
    figures and summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    results, per_condition, files = {}, {}, []
    parts = len(config.conditions) + (1 if config.sweep else 0)
    for index, condition in enumerate(config.conditions):
        ds = simulate_condition(config, condition)
        filename = f"wondergem_2009_{condition.replace('-', '_')}.nc"
        write_netcdf(ds, out / filename, history=f"lookout reproduce {NAME} ({condition}, seeds {config.seeds[0]}..{config.seeds[-1]})")
        files.append(filename)
        results[condition] = ds
        metrics = loop_metrics(ds, config)
        paper_value, paper_horizon = TABLE_1[condition]
        per_condition[condition] = {
            "error_index": metrics["error_index"].tolist(),
            "table_1": paper_value,
            "table_1_horizon_s": paper_horizon,
            "lap_position_rms_m": metrics["lap_position_rms_m"].tolist(),
            "time_saturated_s": metrics["time_saturated_s"].tolist(),
            "thrust_peak_commanded": metrics["thrust_peak_commanded"].tolist(),
            "thrust_peak_applied": metrics["thrust_peak_applied"].tolist(),
            "status": ds.status.values.tolist(),
        }
        if progress is not None:
            progress(index + 1, parts)
    sweep = None
    if config.sweep:
        sweep = choice_sweep(config)
        sweep.to_netcdf(out / "wondergem_2009_choice_sweep.nc")
        files.append("wondergem_2009_choice_sweep.nc")
        if progress is not None:
            progress(parts, parts)
    hold = hold_study(config) if config.sweep else None
    files += figures(results, config, out)
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "seeds": config.seeds,
        "ellipse_perimeter_m": EllipseReference(config.semi_axes, LAP_SPEEDS).perimeter(),
        "lap_end_times_s": lap_times(config).tolist(),
        "status": [status for condition in config.conditions for status in per_condition[condition]["status"]],
        "conditions": per_condition,
        "choice_sweep": None if sweep is None else sweep_summary(sweep),
        "hold_study": hold,
        **gain_study(config),
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def sweep_summary(sweep: xr.Dataset) -> dict:
    """The choice sweep for summary.json: the EI range (overall and with and without the
    thrust limits) and every run's EI and time beyond a limit."""
    index = sweep.error_index
    result = {
        "condition": sweep.attrs["condition"],
        "min": float(index.min()),
        "max": float(index.max()),
        "by_saturation": {s: {"min": float(index.sel(saturation=s).min()), "max": float(index.sel(saturation=s).max())} for s in ("off", "on")},
        "runs": [],
    }
    for start in sweep.start_angle.values:
        for direction in sweep.direction.values:
            for velocity in sweep.initial_velocity.values:
                for saturation in sweep.saturation.values:
                    cell = dict(start_angle=start, direction=direction, initial_velocity=velocity, saturation=saturation)
                    result["runs"].append(
                        {
                            **{k: (v.item() if hasattr(v, "item") else v) for k, v in cell.items()},
                            "error_index": float(index.sel(**cell)),
                            "time_saturated_s": float(sweep.time_saturated_s.sel(**cell)),
                        }
                    )
    return result
