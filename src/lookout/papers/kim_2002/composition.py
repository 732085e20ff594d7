"""Kim (2002), Section 5 as compositions: the closed loop with either observer of
Fig. 8 (a case each), any gain set and model error."""

from __future__ import annotations

from typing import Any

import numpy as np

from lookout.models.vessel import NORTHERN_CLIPPER_THRUST_LIMIT
from lookout.papers.kim_2002.config import (
    BIAS_TIME_CONSTANT,
    FORCE_LEVER_ARM,
    OBSERVERS,
    SWITCHING_GAIN,
    WAVE,
    WAYPOINTS,
    Config,
    ModelError,
    gain_sets,
)
from lookout.scenario.composition import compose
from lookout.sim import Scenario


def _vessel(config: Config, model_error: ModelError | None = None) -> dict:
    """The vessel table: the model, or the plant (the model with ``model_error``'s M and D)."""
    if model_error is None:
        return config.vessel.composition()
    scales = {"mass_scale": 1.0 + model_error.mass, "damping_scale": 1.0 + model_error.damping}
    if config.vessel.model == "custom":
        return {**config.vessel.composition(), **scales}
    return {"kind": config.vessel.model, **scales}


def composition(
    config: Config,
    case: str = "sliding-mode",
    *,
    model_error: ModelError | None = None,
    gains: str | None = None,
    duration: float | None = None,
    record_every: int = 1,
) -> dict:
    """The closed loop of Section 5 with the observer of ``case`` ("sliding-mode" or
    "conventional", the same observer without its switching term) as a composition."""
    if case not in OBSERVERS:
        raise ValueError(f"observer must be one of {', '.join(OBSERVERS)}; got {case!r}")
    model_error = config.model_error if model_error is None else model_error
    gains = config.gains if gains is None else gains
    switching = np.asarray(SWITCHING_GAIN) * (1.0 if case == "sliding-mode" else 0.0)
    half = 0.5 * model_error.force * np.array([1.0, 1.0, FORCE_LEVER_ARM])
    return {
        "simulation": {
            "runs": config.runs,
            "seed": config.seed,
            "plant_step": config.plant_step,
            "sample_period": config.sample_period,
            "duration": config.duration if duration is None else duration,
            "record_every": record_every,
            "batch": "stacked",
        },
        "plant": {
            "kind": "dp-vessel",
            "vessel": _vessel(config, model_error),
            "bias": {"kind": "gauss-markov", "time_constant": BIAS_TIME_CONSTANT, "std": config.bias_std},
            "waves": {
                "kind": "linear",
                "peak_frequency": WAVE["wave_frequency"],
                "damping_ratio": WAVE["wave_damping"],
                "amplitude": config.wave_amplitude,
            },
            "disturbance": {"kind": "body-force", "constant": half.tolist(), "amplitude": half.tolist(), "period": model_error.force_period},
            "initial": {"bias": config.bias_initial},
        },
        "sensor": {"kind": "position-heading", "noise_std": config.noise_std, "sample_period": config.measurement_period},
        "observer": {
            "kind": "sliding-mode",
            "design": "gains",
            "vessel": _vessel(config),
            **WAVE,
            **gain_sets(config.vessel.mass, config.vessel.length)[gains],
            "bias_time_constant": BIAS_TIME_CONSTANT,
            "switching_gain": switching.tolist(),
            "boundary_layer": config.boundary_layer,
        },
        "reference": {
            "kind": "reference-filter",
            "signals": ["position", "heading"],
            "bandwidth": config.reference_bandwidth,
            "schedule_times": [t for t, _ in WAYPOINTS],
            "setpoints": [list(p) for _, p in WAYPOINTS],
        },
        "controller": {
            "kind": "observer-backstepping",
            "integral_gain": config.integral_gain,
            "position_gain": config.position_gain,
            "velocity_gain": config.velocity_gain,
            "coupling_gain": config.coupling_gain,
            "damping_weights": config.damping_weights,
        },
        "actuator": {"kind": "thrust-limits", "limit": NORTHERN_CLIPPER_THRUST_LIMIT},
    }


def build(config: Config, observer: str = "sliding-mode", **changes: Any) -> Scenario:
    """The closed loop of Section 5 with ``observer`` ("sliding-mode" or "conventional");
    ``changes``: the keywords of :func:`composition`."""
    return compose(composition(config, observer, **changes)).scenario


#: The sweep records one sample in this many (1 s): its table uses the tracking error
#: of the true low-frequency position only, which decimation does not bias.
SWEEP_RECORD_EVERY = 10


#: The cases: one per observer, in closed loop; the first is the default.
CASES: tuple[str, ...] = OBSERVERS
