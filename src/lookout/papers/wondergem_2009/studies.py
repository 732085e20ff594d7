"""The studies beyond Table 1, each a set of the conditions' compositions changed key by
key: the choices the paper leaves open, and the basin's 10 Hz measurement held over the
scheme's 20 Hz steps."""

from __future__ import annotations

import math

import jax
import numpy as np
import xarray as xr

from lookout.papers.wondergem_2009.analysis import lap_times, loop_metrics, tracking_errors
from lookout.papers.wondergem_2009.composition import NO_LIMITS, THRUST_LIMITS, changed, composition
from lookout.papers.wondergem_2009.config import BASIN_MEASUREMENT_PERIOD, BASIN_PERIOD, NAME, Config
from lookout.scenario.composition import compose
from lookout.sim import keys_of_seeds, simulate_batch, stack_scenarios

#: The starts on the ellipse theta_0 (rad) the choice sweep tries.
SWEEP_STARTS = (0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi)
#: The hold study: (label, measurement period (s), noise on, thrust limits on).
HOLD_CASES = (
    ("10 Hz held", BASIN_MEASUREMENT_PERIOD, False, True),
    ("10 Hz held, noise", BASIN_MEASUREMENT_PERIOD, True, True),
    ("10 Hz held, no limits", BASIN_MEASUREMENT_PERIOD, False, False),
    ("20 Hz", BASIN_PERIOD, False, True),
    ("20 Hz, noise", BASIN_PERIOD, True, True),
)


def batches_of(documents: list[dict]) -> list[tuple[list, list[int]]]:
    """The compositions' scenarios as the vmapped batches that simulate them: (the
    scenarios, their indices in ``documents``), one batch per structure (scenarios that
    differ in their numbers only share a batch)."""
    scenarios = [compose(document).scenario for document in documents]
    groups: dict = {}
    for index, each in enumerate(scenarios):
        groups.setdefault(jax.tree.structure(each), []).append(index)
    return [([scenarios[i] for i in indices], indices) for indices in groups.values()]


def simulate_documents(documents: list[dict], seeds: list[int]) -> xr.Dataset:
    """Run i is ``documents[i]`` with seed ``seeds[i]``, each of :func:`batches_of` stacked and
    vmapped; the runs in the order given."""
    parts, order = [], []
    for scenarios, indices in batches_of(documents):
        keys = keys_of_seeds([seeds[i] for i in indices])
        parts.append(simulate_batch(stack_scenarios(scenarios), keys, batched_scenario=True).to_xarray())
        order += indices
    ds = parts[0] if len(parts) == 1 else xr.concat(parts, dim="run")
    return ds.isel(run=np.argsort(order))


def sweep_cases() -> list[tuple]:
    """The choice sweep's (start angle, direction, initial velocity, thrust limits) in the
    order of its Dataset's dimensions."""
    return [
        (start, direction, velocity, saturate)
        for start in SWEEP_STARTS
        for direction in (1, -1)
        for velocity in ("estimate", "state")
        for saturate in (False, True)
    ]


def sweep_documents(config: Config, condition: str = "simulation") -> list[dict]:
    """``condition``'s composition for each of :func:`sweep_cases`."""
    base = composition(config, condition)
    return [
        changed(
            base,
            {
                "reference.start_angle": start,
                "reference.direction": direction,
                "observer.initial_velocity": velocity,
                "actuator": THRUST_LIMITS if saturate else NO_LIMITS,
            },
        )
        for start, direction, velocity, saturate in sweep_cases()
    ]


def choice_sweep(config: Config, condition: str = "simulation") -> xr.Dataset:
    """EI over the choices the paper does not give (seed ``config.seed``): start angle on the
    ellipse, direction, which state receives the printed velocity estimate, and the thrust
    limits on or off."""
    documents = sweep_documents(config, condition)
    ds = simulate_documents(documents, [config.seed] * len(documents))
    metrics = loop_metrics(ds, config)
    dims = ("start_angle", "direction", "initial_velocity", "saturation")
    shape = (len(SWEEP_STARTS), 2, 2, 2)
    return xr.Dataset(
        {
            "error_index": (dims, metrics["error_index"].reshape(shape)),
            "time_saturated_s": (dims, metrics["time_saturated_s"].reshape(shape)),
        },
        coords={"start_angle": list(SWEEP_STARTS), "direction": [1, -1], "initial_velocity": ["estimate", "state"], "saturation": ["off", "on"]},
        attrs={
            "title": f"{NAME}: error index (43) over the choices the paper leaves open ({condition})",
            "condition": condition,
            "duration_s": config.duration,
        },
    )


def hold_documents(config: Config) -> list[dict]:
    """basin-calm's composition for each of :data:`HOLD_CASES`."""
    base = composition(config, "basin-calm")
    return [
        changed(
            base,
            {
                "sensor.sample_period": period,
                "sensor.noise_std": list(config.noise_std) if noisy else [0.0, 0.0, 0.0],
                "actuator": THRUST_LIMITS if limited else NO_LIMITS,
            },
        )
        for _, period, noisy, limited in HOLD_CASES
    ]


def hold_study(config: Config) -> list[dict]:
    """basin-calm with the 10 Hz measurement held over the scheme's two 20 Hz steps, against
    20 Hz measurements, with and without noise and thrust limits (seed ``config.seed``): the
    lap-4 mean body-frame errors (after its first 20 s; None when the run ends before), EI,
    time beyond a limit, and the mean step-to-step change of the commanded surge force after
    t = 20 s (large when it alternates at 10 Hz)."""
    ds = simulate_documents(hold_documents(config), [config.seed] * len(HOLD_CASES))
    errors = tracking_errors(ds)
    metrics = loop_metrics(ds, config)
    time = ds.time.values
    laps = lap_times(config)
    lap4 = (time > laps[-2] + 20.0) & (time < laps[-1])
    rows = []
    for i, (label, period, noisy, limited) in enumerate(HOLD_CASES):
        surge_force = ds.force_commanded.values[i, time > 20.0, 0]
        rows.append(
            {
                "case": label,
                "measurement_period_s": period,
                "noise": noisy,
                "thrust_limits": limited,
                "lap4_surge_error_m": float(errors.surge_error.values[i, lap4].mean()) if lap4.any() else None,
                "lap4_sway_error_m": float(errors.sway_error.values[i, lap4].mean()) if lap4.any() else None,
                "surge_command_step_N": float(np.abs(np.diff(surge_force)).mean()),
                "error_index": float(metrics["error_index"][i]),
                "time_beyond_limit_s": float(metrics["time_saturated_s"][i]),
            }
        )
    return rows
