"""Calugi (2002), Section 5.3: adaptive observer backstepping on a two-link arm (Figs 5.1, 5.2).

The two-link arm of chapter 2 (angles from the horizontal, point masses, no friction) with
m1 = 1 kg, m2 = 1.5 kg unknown (theta = m2), l1 = l2 = 1 m; the discrete adaptive observer
(4.34)–(4.35) and the control law (5.9)
(:class:`~lookout.controllers.adaptive_backstepping.AdaptiveObserverBackstepping`) at the
printed settings: K = 5 I, Delta = 0.01 s, Gamma = 0.1, C1 = C2 = 2 I, d_i = 1 (so
p = 4, Omega = 8 I, D2 = 64 I), reference filter F = 8/(s + 2)^3, q(0) = q'(0) = 0,
x1_hat(0) = (1, 1), theta_hat(0) = 0.7.

Two runs:

* ``corrected``: M_hat = M(q; theta_hat), so M_hat_22 = theta_hat l2^2 (what (4.20) needs,
  and what row 2 of (5.41) implies);
* ``printed``: (5.37) as printed, M_hat_22 = m2 l2^2 with the unknown m2, in psi and tau;
  the regressor stays (5.41)'s, which has l2^2 psi_2 in row 2 — expected to diverge (derivations-thesis-ch3-6.md): theta_hat overshoots past 1.72, where M_hat(q2 = 0)
  = [[4 theta_hat + 1, 2 theta_hat], [2 theta_hat, 1.5]] is indefinite.

Chosen where the thesis is silent: the filter input is a +-1 rad square wave on each joint,
+1 first, period 20 s, over 40 s; no resetting (the thesis uses none in ch. 5); the plant
by RK4 at 1 ms with tau held over each 10 ms sample.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from pydantic import Field, field_validator

from lookout.analysis.adaptive_manipulator import check_5_28
from lookout.analysis.conditions import inequalities_in
from lookout.models.manipulators import PrintedInertiaArm
from lookout.models.parameters import ModelParameters
from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver
from lookout.papers import CATALOG
from lookout.papers._report import Table, save_figures, write_summary
from lookout.papers._reproduction import Reproduction, built_as, simulate_each
from lookout.reference import ReferenceFilter
from lookout.scenario.composition import compose
from lookout.scenario.settings import NoiseFreeConfig, PositiveFloat, finite_positive, whole_samples
from lookout.sim import Scenario, seed_keys, simulate

NAME = "calugi-2002-backstepping"
TITLE = CATALOG[NAME].title
MASSES, LENGTHS = (1.0, 1.5), (1.0, 1.0)
SAMPLE_PERIOD = 0.01
PLANT_STEP = 0.001
VARIANTS = ("corrected", "printed")


class Config(NoiseFreeConfig):
    """Settings of the reproduction; every field has the thesis's value or a stated choice."""

    duration: float = Field(default=40.0, description="simulated time (s); two periods of the square wave (chosen)")
    amplitude: PositiveFloat = Field(default=1.0, description="square wave amplitude (rad), chosen")
    period: PositiveFloat = Field(default=20.0, description="square wave period (s), chosen")
    initial_theta: PositiveFloat = Field(default=0.7, description="theta_hat(0) (kg), printed")

    @field_validator("duration")
    @classmethod
    def _duration(cls, value):
        finite_positive(value)
        whole_samples(value, SAMPLE_PERIOD, "the 0.01 s sample period")
        if value < 11.0:
            raise ValueError(f"must be at least 11 s (the summary reports theta_hat at 10 s); got {value:g} s")
        return value


#: The cases: M_hat as (4.20) needs it, and (5.37) as printed.
CASES: tuple[str, ...] = VARIANTS
#: The true arm of Section 5.3 (a ``model`` table): m1 = 1 kg, m2 = 1.5 kg, l1 = l2 = 1 m, no friction.
ARM = {"kind": "two-link-arm", "masses": list(MASSES), "lengths": list(LENGTHS), "friction": [0.0, 0.0]}
#: (5.37) as printed (a ``model`` table of :class:`~lookout.models.manipulators.PrintedInertiaArm`): M_22 at the true m2.
PRINTED_ARM = {"kind": "printed-inertia-arm", "masses": list(MASSES), "lengths": list(LENGTHS), "friction": [0.0, 0.0], "printed_mass": MASSES[1]}
#: theta = m2 (a ``parameters`` table), of the plant's arm unless a ``base`` is added.
UNKNOWN_MASS = {"kind": "model-fields", "fields": ["masses[1]"], "units": ["kg"]}
#: The printed gains: K = 5 I, Gamma = 0.1, C1 = C2 = 2 I, d_i = 1.
OBSERVER_GAIN, ADAPTATION_GAIN, POSITION_GAIN, VELOCITY_GAIN, DAMPING_WEIGHT = 5.0, 0.1, 2.0, 2.0, 1.0
#: The reference filter F = (w / (s + w))^3 with w = 2 rad/s, so F = 8/(s + 2)^3.
FILTER_BANDWIDTH = 2.0


def reference_table(config: Config) -> dict:
    """F = 8/(s + 2)^3 on a +-amplitude square wave per joint, +1 first, from rest at q = 0,
    over the plant's ``joint_angle`` (a ``reference`` table)."""
    half = config.period / 2.0
    switches = int(math.ceil(config.duration / half))
    return {
        "kind": "reference-filter",
        "signals": ["joint_angle"],
        "bandwidth": FILTER_BANDWIDTH,
        "schedule_times": [k * half for k in range(switches)],
        "setpoints": [[config.amplitude * (1 if k % 2 == 0 else -1)] * 2 for k in range(switches)],
        "initial": [0.0, 0.0],
    }


def composition(config: Config, case: str) -> dict:
    """The closed loop of Section 5.3 as a composition (:mod:`lookout.scenario.composition`), with
    (5.37) ``case`` "corrected" (M_hat = M(q; theta_hat)) or "printed" (M_hat_22 = m2 l2^2
    at the true m2, in psi and tau): the arm, the encoder of q, the observer (4.34)–(4.35)
    and the law (5.9) on the same model, tracking :func:`reference_table`. The printed run
    keeps (5.41)'s regressor (it has l2^2 psi_2 in row 2), of the true arm: only M_hat is
    printed wrong."""
    if case not in CASES:
        raise ValueError(f"case must be one of {', '.join(CASES)}; got {case!r}")
    observer = {
        "kind": "adaptive-manipulator",
        "parameters": UNKNOWN_MASS if case == "corrected" else {**UNKNOWN_MASS, "base": PRINTED_ARM},
        "gain": OBSERVER_GAIN,
        "adaptation_gain": ADAPTATION_GAIN,
        "sample_period": SAMPLE_PERIOD,
        "initial": {"velocity": [1.0, 1.0], "theta": [config.initial_theta]},
    }
    if case == "printed":
        observer["regressor"] = UNKNOWN_MASS
    return copy.deepcopy(
        {  # the document is the caller's: the module's tables stay as they are
            "simulation": {
                "runs": config.runs,
                "seed": config.seed,
                "plant_step": PLANT_STEP,
                "sample_period": SAMPLE_PERIOD,
                "duration": config.duration,
            },
            "plant": {"kind": "manipulator", "model": ARM, "initial": {"q": [0.0, 0.0], "qdot": [0.0, 0.0]}},
            "sensor": {"kind": "joint-encoder", "sample_period": SAMPLE_PERIOD},
            "observer": observer,
            "reference": reference_table(config),
            "controller": {
                "kind": "adaptive-backstepping",
                "observer_gain": OBSERVER_GAIN,
                "position_gain": POSITION_GAIN,
                "velocity_gain": VELOCITY_GAIN,
                "damping_weights": DAMPING_WEIGHT,
            },
        }
    )


def build(config: Config, variant: str = "corrected") -> Scenario:
    """The closed loop of Section 5.3, ``variant`` "corrected" or "printed" (5.37)."""
    return compose(composition(config, variant)).scenario


def parameters(variant: str = "corrected") -> ModelParameters:
    """theta = m2 of the arm: the observer's and the controller's model of ``variant``."""
    observer = built_as(build(Config(), variant).observer, AdaptiveManipulatorObserver, f"the observer of {variant!r}")
    return built_as(observer.parameters, ModelParameters, f"the parameters of the observer of {variant!r}")


def reference(config: Config) -> ReferenceFilter:
    """The reference filter of :func:`reference_table`."""
    return built_as(build(config).reference, ReferenceFilter, "the reference")


def simulate_case(config: Config, case: str, *, progress: Callable | None = None) -> tuple[Scenario, xr.Dataset]:
    """Simulate case ``case``: its scenario and the Dataset :func:`run` writes."""
    scenario = build(config, case)
    ds = simulate(scenario, seed_keys(config.seed, 1)[0], progress=progress).to_xarray()
    ds.attrs.update({"reproduction": NAME, "title": TITLE, "variant": case, "config": config.model_dump_json()})
    return scenario, ds


def summarize(ds: xr.Dataset, unknowns: ModelParameters) -> dict:
    """tau(0), theta_hat's extremes and values at 5 and 10 s, the tracking error after 10 s,
    max |tau| after 1 s, where the run stopped being finite, and where M_hat = ``unknowns``'
    M(q; theta_hat) first lost positive definiteness."""
    time = ds.time.values
    theta = ds.masses_1_hat.values
    tau = ds.joint_torque_applied.values
    angle = ds.joint_angle.values
    desired = ds.joint_angle_desired.values
    finite = np.all(np.isfinite(angle), axis=1) & np.isfinite(theta) & np.all(np.isfinite(tau), axis=1)
    last = int(np.argmin(finite)) if not finite.all() else len(time)
    ok = slice(0, last)
    late = (time >= 10.0) & finite
    ok_theta = theta[ok]
    result = {
        "status": str(ds.status.values),
        "finite_until_s": float(time[last - 1]) if last > 0 else 0.0,
        "tau_0": tau[0].tolist(),
        "theta_hat_min": float(ok_theta.min()),
        "theta_hat_min_time_s": float(time[ok][np.argmin(ok_theta)]),
        "theta_hat_max": float(ok_theta.max()),
        "theta_hat_max_time_s": float(time[ok][np.argmax(ok_theta)]),
        "theta_hat_at_5s": float(theta[np.argmin(abs(time - 5.0))]) if last > np.argmin(abs(time - 5.0)) else None,
        "theta_hat_at_10s": float(theta[np.argmin(abs(time - 10.0))]) if last > np.argmin(abs(time - 10.0)) else None,
        "theta_hat_final": float(theta[last - 1]) if last > 0 else None,
        "tracking_error_max_after_10s": float(np.abs(angle[late] - desired[late]).max()) if late.any() else None,
        "tracking_error_final": np.abs(angle[last - 1] - desired[last - 1]).tolist() if last > 0 else None,
        "tau_max_after_1s": float(np.abs(tau[(time >= 1.0) & finite]).max()) if ((time >= 1.0) & finite).any() else None,
    }
    # where M_hat(q) first loses positive definiteness (the printed run)
    eig = np.asarray(
        jax.jit(jax.vmap(lambda q, th: jnp.linalg.eigvalsh(unknowns.model(jnp.atleast_1d(th)).mass_matrix(q))[0]))(
            jnp.asarray(np.nan_to_num(angle[ok])), jnp.asarray(ok_theta)
        )
    )
    indefinite = np.flatnonzero(eig <= 0)
    result["m_hat_indefinite_from_s"] = float(time[indefinite[0]]) if indefinite.size else None
    result["m_hat_indefinite_total_s"] = float(indefinite.size * (time[1] - time[0]))
    return result


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate both variants; write NetCDF, figures and summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    results, per_variant, unknowns, files = {}, {}, {}, []
    each = simulate_each(
        VARIANTS,
        lambda variant, progress: simulate_case(config, variant, progress=progress),
        out,
        "calugi_2002_backstepping_{case}.nc",
        lambda variant: f"lookout reproduce {NAME} ({variant} (5.37))",
        progress=progress,
    )
    for variant, scenario, ds, filename in each:
        files.append(filename)
        results[variant] = ds.isel(run=0)
        unknowns[variant] = scenario.observer.parameters
        per_variant[variant] = summarize(results[variant], unknowns[variant])
    corrected = results["corrected"]
    condition = check_5_28(
        unknowns["corrected"],
        OBSERVER_GAIN,
        DAMPING_WEIGHT,
        max_speed=float(np.linalg.norm(corrected.joint_rate.values, axis=1).max()),
        initial_error=np.array([1.0, 1.0]),
    )
    files += _figures(results, out)
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "seeds": [config.seed],
        "status": [values["status"] for values in per_variant.values()],
        "variants": per_variant,
        "condition_5_28": condition.to_dict(),
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def _figures(results: dict, out: Path) -> list[str]:
    import matplotlib.pyplot as plt

    figures = {}
    ds = results["corrected"]
    for k, joint in enumerate(ds.revolute_joint.values):
        figure, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
        axes[0].plot(ds.time, ds.joint_angle_desired.values[:, k], color="k", lw=1.2, label="q_d")
        axes[0].plot(ds.time, ds.joint_angle.values[:, k], color="C0", lw=0.9, label="q")
        axes[0].set_ylabel("angle (rad)")
        axes[1].plot(ds.time, ds.joint_rate.values[:, k], color="k", lw=1.2, label="q' (true)")
        axes[1].plot(ds.time, ds.joint_rate_hat.values[:, k], color="C1", lw=0.9, ls="--", label="x1_hat")
        axes[1].set_ylabel("velocity (rad/s)")
        axes[2].plot(ds.time, ds.joint_torque_applied.values[:, k], color="C2", lw=0.9, label="tau")
        axes[2].set_ylabel("torque (N m)")
        axes[2].set_xlabel("time (s)")
        for axis in axes:
            axis.legend(fontsize=8)
        figure.suptitle(f"Fig. 5.{k + 1}: link {k + 1} ({joint}), corrected (5.37)", fontsize=10)
        figure.tight_layout()
        figures[f"fig_5_{k + 1}.png"] = figure
    figure, axis = plt.subplots(figsize=(9, 3.5))
    for variant, color in (("corrected", "C0"), ("printed", "C3")):
        run_ = results[variant]
        axis.plot(run_.time, run_.masses_1_hat, color=color, lw=0.9, label=f"theta_hat, (5.37) {variant}")
    axis.axhline(MASSES[1], color="k", lw=1.2, label="m2 (true)")
    axis.axhline(1.72, color="C3", lw=0.6, ls=":", label="M_hat(q2 = 0) indefinite above (printed)")
    axis.set_ylim(0.0, 3.0)
    axis.set_xlabel("time (s)")
    axis.set_ylabel("mass (kg)")
    axis.legend(fontsize=8)
    figure.suptitle("The estimate of m2 (the thesis cites a Fig. 5.3 it does not contain)", fontsize=10)
    figure.tight_layout()
    figures["theta_hat.png"] = figure
    return save_figures(figures, out)


def _value(value, digits: int = 4) -> str:
    return "-" if value is None else f"{value:.{digits}g}"


def tables(summary: dict) -> list[Table]:
    """Both variants side by side; (5.28)."""
    rows = []
    keys = (
        ("status", "status"),
        ("finite until (s)", "finite_until_s"),
        ("theta_hat at 5 s", "theta_hat_at_5s"),
        ("theta_hat at 10 s", "theta_hat_at_10s"),
        ("theta_hat final", "theta_hat_final"),
        ("theta_hat min (at s)", "min"),
        ("theta_hat max (at s)", None),
        ("max |q - q_d| after 10 s (rad)", "tracking_error_max_after_10s"),
        ("max |tau| after 1 s (N m)", "tau_max_after_1s"),
        ("M_hat indefinite from (s)", "m_hat_indefinite_from_s"),
        ("M_hat indefinite, total (s)", "m_hat_indefinite_total_s"),
    )
    variants = summary["variants"]
    for label, key in keys:
        if key is None:
            rows.append((label, *(f"{v['theta_hat_max']:.4g} ({v['theta_hat_max_time_s']:.2f})" for v in variants.values())))
        elif key == "min":
            rows.append((label, *(f"{v['theta_hat_min']:.4g} ({v['theta_hat_min_time_s']:.2f})" for v in variants.values())))
        elif key == "status":
            rows.append((label, *(v["status"] for v in variants.values())))
        else:
            rows.append((label, *(_value(v[key]) for v in variants.values())))
    result = [
        Table(
            "Section 5.3: m2 = 1.5 kg, theta_hat(0) = 0.7 kg",
            ("", *(f"(5.37) {v}" for v in variants)),
            tuple(rows),
            "tau(0) = " + str([round(x, 3) for x in variants["corrected"]["tau_0"]]) + " N m (corrected)",
        )
    ]
    condition = summary["condition_5_28"]
    result.append(
        Table(
            "(5.28) for the printed gains (K = 5, d_i = 1)",
            ("", "condition", "left", "right", "verdict"),
            tuple(
                (item["name"], item["relation"], f"{item['left']:.4g}", f"{item['right']:.4g}", item["verdict"])
                for item in inequalities_in(condition)
            ),
            f"sigma = inf lambda_min(KM + MK)/2; C_M = {condition['quantities']['C_M']:.3g} (Christoffel); w_max from the corrected run",
        )
    )
    return result


#: Calugi (2002), Section 5.3: adaptive observer backstepping on the two-link arm, m2 unknown.
REPRODUCTION = Reproduction(NAME, Config, CASES, composition, run, tables)

__all__ = [
    "CASES",
    "Config",
    "NAME",
    "PrintedInertiaArm",
    "REPRODUCTION",
    "TITLE",
    "VARIANTS",
    "build",
    "composition",
    "parameters",
    "reference",
    "reference_table",
    "run",
    "simulate_case",
    "summarize",
    "tables",
]
