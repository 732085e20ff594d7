"""Calugi et al. (2003), Section V as compositions: the closed loop with either gain set
(a case each), at any sample interval Delta, in the discrete or the continuous form."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from lookout.papers.calugi_2003.config import GAIN_SETS, PLANT_STEP, WAYPOINTS, Config, gains, m11, paper_vessel
from lookout.scenario.composition import compose
from lookout.sim import Scenario


def composition(
    config: Config,
    gain_set: str = "printed",
    *,
    sample_interval: float | None = None,
    duration: float | None = None,
    initial_theta: float | None = None,
    adaptation_gain: float | None = None,
    waypoints: Sequence[tuple[float, Sequence[float]]] = WAYPOINTS,
    form: str = "discrete",
    record_every: int = 1,
    plant_step: float = PLANT_STEP,
    observer_mode: str = "sampled",
) -> dict:
    """The closed loop of Section V with a gain set (``printed`` or ``satisfying``) as a
    composition: the vessel of (59), theta = m11 within the bounds, the observer of
    (65)-(67) (or (13)-(15) with ``form = "continuous"``, on the oracle velocity sensor),
    the vectorial backstepping (36), the reference filter F(s) of (60)."""
    vessel = paper_vessel()
    true_m11 = m11()
    chosen = gains(gain_set)
    interval = config.sample_interval if sample_interval is None else sample_interval
    low, high = config.theta_bounds
    if form == "discrete":
        sensor = {"kind": "position-heading", "noise_std": config.noise_std, "sample_period": interval}
    else:
        sensor = {"kind": "position-heading-velocity", "noise_std": [*config.noise_std, 0.0, 0.0, 0.0], "sample_period": interval}
    return {
        "simulation": {
            "runs": config.runs,
            "seed": config.seed,
            "plant_step": plant_step,
            "sample_period": interval,
            "duration": config.duration if duration is None else duration,
            "record_every": record_every,
            "batch": "stacked",
            "observer_mode": observer_mode,
        },
        "plant": {
            "kind": "dp-vessel",
            "vessel": {
                "kind": "custom",
                **{name: np.asarray(getattr(vessel, name)).tolist() for name in ("mass_matrix", "damping_matrix", "stiffness_matrix")},
            },
            "bias": {"kind": "gauss-markov", "time_constant": 1000.0, "std": 0.0},
            "waves": {"kind": "linear", "peak_frequency": 0.8976, "damping_ratio": 0.1, "amplitude": 0.0},
        },
        "sensor": sensor,
        "observer": {
            "kind": "adaptive-dp",
            "parametrization": {"kind": "inertia-entries", "unknowns": ["m11"], "lower": [low * true_m11], "upper": [high * true_m11]},
            "position_gain": chosen["K1"].tolist(),
            "velocity_gain": chosen["K2"].tolist(),
            "adaptation_gain": config.adaptation_gain if adaptation_gain is None else adaptation_gain,
            "form": form,
            "initial_theta": [(config.initial_theta if initial_theta is None else initial_theta) * true_m11],
            # eta_hat(0) at the vessel's true start, not its first (noisy) fix: the noise-drift
            # rate of the studies (analysis.adaptive_dp.noise_drift_rate) is derived from that start
            "initial": {"eta": [0.0, 0.0, 0.0]},
        },
        "reference": {
            "kind": "reference-filter",
            "signals": ["position", "heading"],
            "bandwidth": 0.1,
            "schedule_times": [t for t, _ in waypoints],
            "setpoints": [list(p) for _, p in waypoints],
        },
        "controller": {
            "kind": "vectorial-backstepping",
            "position_gain": chosen["C1"],
            "velocity_gain": chosen["C2"],
            "damping_weights": chosen["d"].tolist(),
        },
    }


def build(config: Config, gain_set: str = "printed", **changes: Any) -> Scenario:
    """The closed loop of Section V with a gain set; ``changes``: the keywords of :func:`composition`."""
    return compose(composition(config, gain_set, **changes)).scenario


#: The cases: one per gain set, in closed loop; the first is the default.
CASES: tuple[str, ...] = GAIN_SETS
