"""Kim (2002), the claim of Fig. 8 measured: tracking error against model error, for
both observers and both gain sets, as a campaign (:mod:`lookout.studies`).

The campaign's base is the sliding-mode case without model error; three axes of
cases: the observer gains (printed (A.4), or Fossen & Strand's (60) in SI), the
observer (with and without its switching term) and the model error, one kind at a
time (:func:`sweep_points`). Its metrics are the campaign vocabulary's
``rms_tracking:position`` and ``max_error:position`` (the position estimate's largest
error) over the whole run (``after = 0``); a run counts as diverged
when it is not finite or when the vessel or its estimate is more than
:data:`~lookout.papers.kim_2002.config.DIVERGED_DISTANCE` off (the campaign's
divergence limit on ``position``, which tests both), as the closed-loop table counts it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import xarray as xr

from lookout.papers._sweep import run_sweep as run_campaign_sweep
from lookout.papers._sweep import whole_run_campaign
from lookout.papers.kim_2002.composition import composition
from lookout.papers.kim_2002.config import DIVERGED_DISTANCE, FORCE_LEVER_ARM, NAME, OBSERVERS, SWITCHING_GAIN, Config, ModelError, gain_sets

#: The sweep records one sample in this many (1 s): its metric is the tracking error
#: of the true low-frequency position only, which decimation does not bias.
SWEEP_RECORD_EVERY = 10
#: The gain sets the sweep crosses.
GAIN_SETS = ("printed", "kyp")
#: The file of the sweep's campaign store in a reproduction's folder.
STORE = "kim_2002_sweep.zarr"


def sweep_points() -> list[tuple[str, ModelError]]:
    """(label, model error): one axis at a time around no error; forces up to 8 x the bias std."""
    points = [("none", ModelError(mass=0.0, damping=0.0, force=0.0))]
    for value in (-0.5, -0.25, 0.25, 0.5):
        points.append((f"mass {value:+.0%}", ModelError(mass=value, damping=0.0, force=0.0)))
    for value in (-0.5, -0.25, 0.25, 0.5):
        points.append((f"damping {value:+.0%}", ModelError(mass=0.0, damping=value, force=0.0)))
    for value in (2e3, 4e3, 8e3, 16e3):
        points.append((f"force {value / 1e3:g} kN", ModelError(mass=0.0, damping=0.0, force=value)))
    return points


def model_error_changes(error: ModelError) -> dict:
    """The keys of the composition (:func:`~lookout.papers.kim_2002.composition.composition`)
    that ``error`` changes from a plant without model error."""
    changes = {}
    if error.mass:
        changes["plant.vessel.mass_scale"] = 1.0 + error.mass
    if error.damping:
        changes["plant.vessel.damping_scale"] = 1.0 + error.damping
    if error.force:
        half = (0.5 * error.force * np.array([1.0, 1.0, FORCE_LEVER_ARM])).tolist()
        changes.update({"plant.disturbance.constant": half, "plant.disturbance.amplitude": half})
    if error.force_period != ModelError.model_fields["force_period"].default:
        changes["plant.disturbance.period"] = error.force_period
    return changes


def sweep_document(config: Config, points: list[tuple[str, ModelError]] | None = None) -> dict:
    """The sweep as a campaign document; ``points`` default to :func:`sweep_points`."""
    points = sweep_points() if points is None else points
    base = composition(
        config,
        OBSERVERS[0],
        model_error=ModelError(mass=0.0, damping=0.0, force=0.0),
        duration=config.sweep_duration,
        record_every=SWEEP_RECORD_EVERY,
    )
    gains = gain_sets(config.vessel.mass, config.vessel.length)
    return whole_run_campaign(
        base,
        seeds=config.sweep_seeds,
        seed=config.seed,
        metrics=["rms_tracking:position", "max_error:position"],
        divergence=("position", DIVERGED_DISTANCE),
        axes={
            "gains": {name: {f"observer.{key}": list(value) for key, value in gains[name].items()} for name in GAIN_SETS},
            "observer": {
                observer: {"observer.switching_gain": list(SWITCHING_GAIN) if observer == "sliding-mode" else [0.0, 0.0, 0.0]}
                for observer in OBSERVERS
            },
            "model_error": {label: model_error_changes(error) for label, error in points},
        },
    )


def run_sweep(config: Config, out: Path, progress: Callable | None = None, points: list[tuple[str, ModelError]] | None = None) -> xr.Dataset:
    """The campaign of :func:`sweep_document`, computed into ``out /`` :data:`STORE`;
    returns ``rms_tracking__position``, ``max_error__position`` (m) and ``diverged`` over (gains, observer,
    model_error, seed)."""
    sweep = run_campaign_sweep(sweep_document(config, points), out / STORE, source=f"{NAME} sweep", progress=progress)
    sweep.attrs.update({"title": f"{NAME}: tracking error over model error", "duration_s": config.sweep_duration})
    return sweep


def sweep_summary(sweep: xr.Dataset) -> dict:
    """Per gain set, observer and model error: mean RMS tracking error and diverged runs."""
    result: dict[str, dict[str, dict]] = {}
    for gains in sweep.gains.values.tolist():
        result[gains] = {}
        for observer in sweep.observer.values.tolist():
            rows = {}
            for label in sweep.model_error.values.tolist():
                cell = sweep.sel(gains=gains, observer=observer, model_error=label)
                diverged = cell.diverged.values.astype(bool)
                kept = cell.rms_tracking__position.values[~diverged]
                rows[label] = {
                    "tracking_rms_m": float(kept.mean()) if kept.size else None,
                    "diverged": int(diverged.sum()),
                    "seeds": int(diverged.size),
                }
            result[gains][observer] = rows
    return result
