"""Calugi (2002), chapter 6: the Furuta pendulum experiments I–IV, rebuilt in simulation.

The thesis ran these on the Lund Furuta pendulum; here the same observer-controllers run
on a simulated pendulum (:class:`~lookout.models.furuta.FurutaPlant`: (6.1)–(6.4) with
(alpha, beta, gamma, delta) = (0.00354, 0.00384, 0.00258, 0.103) and a stick-slip
Coulomb friction tau_C = 0.028 N m on the arm). Common to all four, as printed: the
encoders quantize theta to 0.001 rad and phi to 0.01 rad before the observer; the
discrete adaptive observer (4.34)–(4.35) with resetting (4.45)
(:class:`~lookout.observers.adaptive_manipulator.AdaptiveManipulatorObserver`) and the
pendulum-angle law (6.9)–(6.11)
(:class:`~lookout.controllers.furuta.FurutaPendulumBackstepping`) at Delta = 7.5 ms;
K = 5 I, x1_hat(0) = 0, c1 = c2 = 10, d1 = 1, reference filter 27/(s + 3)^3.

===========  ==========================  ======  =========================  ======================  =========
experiment   estimated                   d2      Gamma                      theta_hat(0)            bounds, mu
===========  ==========================  ======  =========================  ======================  =========
I            none (tau_C = 0.028 known)  2       0 (the ch. 2 observer)     tau_C = 0.028           -
II           tau_C                       1       0.01                       0.001                   [0.001, 0.04], 1e-4
III          tau_C, alpha                1       diag(0.01, 0.001)          (0.001, 0.0001)         + alpha in [1e-4, 5e-3], mu = 1e-5
IV           tau_C                       1       0.003                      0.001                   as II
===========  ==========================  ======  =========================  ======================  =========

Exp. I runs (4.34) with Gamma = 0, which is the chapter-2 observer under the thesis's
Euler solver (derivations-thesis-ch3-6.md). Where a printed setting fails, the nearest
setting that works runs beside it:

* ``III-fixed``: the printed alpha_hat(0) = alpha_l = 1e-4 is below gamma^2/beta = 0.00173,
  so M_hat = M(q; alpha_hat) is indefinite at theta = 0 and theta = pi (det M_hat =
  alpha_hat beta - gamma^2 cos^2 theta there); the observer's construction check refuses the
  printed bounds (the printed run is built around it, to show what happens). The fix:
  alpha_hat(0) = alpha_l = 0.002 (bounds [0.002, 0.005]).
* ``IV-fixed``: tau_C_hat(0) = 0.026, the start that Fig. 6.18's axis shows (0.024–0.028),
  against the printed 0.001.

Chosen where the thesis is silent (derivations-thesis-ch3-6.md, "Reference"): I–III track
a hanging reference, theta_d = F(s) r with r = pi + 0.6 sgn(cos(2 pi t / 2.5)) (switches at
0.625 + 1.25 k s, taking effect at the next 7.5 ms sample), filter states at pi,
theta(0) = pi, phi(0) = 0, at rest; IV holds upright, r = 0, filter and theta(0) at 0.02 rad.
The plant by RK4 at 0.25 ms with tau_u held over each 7.5 ms sample; no saturation
(max |tau_u| is reported); the "analog" velocities of the figures are the true ones.
Durations: 30 s for I–III, 20 s for IV (from the figure axes; IV runs the whole 7.5 ms
samples that cover 20 s, 20.0025 s).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
from pydantic import Field, field_validator

from lookout.components import JOINT_SPACE, Signal
from lookout.controllers.furuta import PENDULUM_REFERENCE, FurutaPendulumBackstepping
from lookout.models.furuta import PRINTED_CONSTANTS, PRINTED_COULOMB_FRICTION, FurutaConstants, FurutaPlant
from lookout.models.parameters import ModelParameters
from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver, theta_signal_name
from lookout.settings import NoiseFreeConfig, finite_positive, whole_samples
from lookout.papers import CATALOG
from lookout.papers._report import Table, save_figures, write_summary
from lookout.reference import ReferenceFilter
from lookout.results import write_netcdf
from lookout.sensors import JointEncoder
from lookout.sim import Scenario, integer_ratio, simulate

NAME = "calugi-2002-furuta"
TITLE = CATALOG[NAME].title
SAMPLE_PERIOD = 0.0075
PLANT_STEP = 0.00025
#: Encoder resolution (rad): arm phi, pendulum theta (printed).
QUANTIZATION = (0.01, 0.001)
OBSERVER_GAIN = 5.0
FILTER_BANDWIDTH = 3.0
#: Hanging reference: r = pi + AMPLITUDE sgn(cos(2 pi t / PERIOD)).
AMPLITUDE, PERIOD = 0.6, 2.5
UPRIGHT_START = 0.02
IV_DURATION = 20.0
#: gamma^2 / beta: alpha_hat must exceed it for M_hat to be positive definite at every theta.
ALPHA_MINIMUM = PRINTED_CONSTANTS[2] ** 2 / PRINTED_CONSTANTS[1]
TRUTH = {"coulomb_friction[0]": PRINTED_COULOMB_FRICTION, "alpha": PRINTED_CONSTANTS[0]}
UNITS = {"coulomb_friction[0]": "N m", "alpha": "kg m2"}
SYMBOLS = {"coulomb_friction[0]": "tau_C", "alpha": "alpha"}


@dataclass(frozen=True)
class Experiment:
    """One row of the table in the module docstring."""

    name: str
    figures: str
    unknowns: tuple[str, ...]
    damping: float
    adaptation_gain: tuple[float, ...]
    initial: tuple[float, ...]
    lower: tuple[float, ...] | None
    upper: tuple[float, ...] | None
    margin: float
    upright: bool
    printed: bool
    note: str


EXPERIMENTS = {
    "I": Experiment("I", "6.2–6.5", ("coulomb_friction[0]",), 2.0, (0.0,), (PRINTED_COULOMB_FRICTION,), None, None, 0.0, False, True,
                    "ch. 2 observer (Gamma = 0), tau_C known"),
    "II": Experiment("II", "6.6–6.9", ("coulomb_friction[0]",), 1.0, (0.01,), (0.001,), (0.001,), (0.04,), 1e-4, False, True,
                     "tau_C adapted"),
    "III": Experiment("III", "6.10–6.14", ("coulomb_friction[0]", "alpha"), 1.0, (0.01, 0.001), (0.001, 1e-4), (0.001, 1e-4),
                      (0.04, 5e-3), 1e-5, False, True, "tau_C and alpha adapted, printed alpha_hat(0) = alpha_l = 1e-4"),
    "III-fixed": Experiment("III-fixed", "6.10–6.14", ("coulomb_friction[0]", "alpha"), 1.0, (0.01, 0.001), (0.001, 0.002), (0.001, 0.002),
                            (0.04, 5e-3), 1e-5, False, False, "as III with alpha_hat(0) = alpha_l = 0.002 > gamma^2/beta"),
    "IV": Experiment("IV", "6.15–6.18", ("coulomb_friction[0]",), 1.0, (0.003,), (0.001,), (0.001,), (0.04,), 1e-4, True, True,
                     "upright, printed tau_C_hat(0) = 0.001"),
    "IV-fixed": Experiment("IV-fixed", "6.15–6.18", ("coulomb_friction[0]",), 1.0, (0.003,), (0.026,), (0.001,), (0.04,), 1e-4, True, False,
                           "upright, tau_C_hat(0) = 0.026 (Fig. 6.18's axis)"),
}


class Config(NoiseFreeConfig):
    """Settings of the reproduction; every field has the thesis's value or a stated choice.
    The runs are noise-free (quantization only), so ``runs`` must be 1."""

    duration: float = Field(30.0, description="simulated time of I–III (s, figure axes); IV runs min(duration, 20 s)")
    experiments: tuple[str, ...] = Field(tuple(EXPERIMENTS), description="which experiments to run")
    plant_step: float = Field(PLANT_STEP, description="plant RK4 step (s), at most 0.25 ms, dividing 7.5 ms")

    @field_validator("duration")
    @classmethod
    def _duration(cls, value):
        finite_positive(value)
        return whole_samples(value, SAMPLE_PERIOD, "the 7.5 ms sample period")

    @field_validator("experiments")
    @classmethod
    def _experiments(cls, value):
        unknown = [name for name in value if name not in EXPERIMENTS]
        if unknown or not value or len(set(value)) != len(value):
            raise ValueError(f"must be distinct names among {', '.join(EXPERIMENTS)}; got {', '.join(value) or 'none'}")
        return value

    @field_validator("plant_step")
    @classmethod
    def _plant_step(cls, value):
        finite_positive(value)
        if value > PLANT_STEP * (1 + 1e-12) or integer_ratio(SAMPLE_PERIOD, value) is None:
            raise ValueError(f"must be at most 0.25 ms and divide the 7.5 ms sample period; got {value:g} s")
        return value


def experiment_duration(config: Config, name: str) -> float:
    """I–III: the configured duration; IV: the whole samples covering min(duration, 20 s)."""
    if not EXPERIMENTS[name].upright:
        return config.duration
    samples = math.ceil(min(config.duration, IV_DURATION) / SAMPLE_PERIOD - 1e-9)
    return samples * SAMPLE_PERIOD


@functools.lru_cache(maxsize=None)
def parameters(unknowns: tuple[str, ...]) -> ModelParameters:
    """The unknowns of the printed model (the truth is the reference); cached, since the
    affinity check of the construction costs about 0.6 s."""
    return ModelParameters(FurutaConstants(), unknowns, units=tuple(UNITS[name] for name in unknowns))


def reference(experiment: Experiment, duration: float) -> ReferenceFilter:
    """theta_d = 27/(s + 3)^3 r over an unwrapped scalar ``pendulum_angle`` (see the module docstring)."""
    signal = Signal(PENDULUM_REFERENCE, "rad", "pendulum angle from the upward vertical", JOINT_SPACE)
    if experiment.upright:
        return ReferenceFilter((signal,), FILTER_BANDWIDTH, [0.0], [[0.0]], initial=[UPRIGHT_START])
    quarter, half = PERIOD / 4.0, PERIOD / 2.0
    switches = int(math.ceil((duration - quarter) / half)) + 1
    times = [0.0] + [quarter + k * half for k in range(switches)]
    setpoints = [[math.pi + AMPLITUDE * (1 if k % 2 == 0 else -1)] for k in range(len(times))]
    return ReferenceFilter((signal,), FILTER_BANDWIDTH, times, setpoints, initial=[math.pi])


@functools.lru_cache(maxsize=None)
def observer(experiment: Experiment) -> AdaptiveManipulatorObserver:
    """(4.34)–(4.35) with (4.45) at the experiment's settings. Exp. III's printed bounds put
    M_hat outside the positive definite region, which the constructor refuses; they are set
    around it (``eqx.tree_at`` skips the check) to show what they do. Cached (the positive-
    definiteness check compiles)."""
    unknowns = parameters(experiment.unknowns)
    if experiment.name == "III":
        built = AdaptiveManipulatorObserver(unknowns, OBSERVER_GAIN, experiment.adaptation_gain, sample_period=SAMPLE_PERIOD,
                                            lower=(0.001, 0.002), upper=experiment.upper, margin=experiment.margin)
        return eqx.tree_at(lambda o: o.lower, built, jnp.asarray(experiment.lower, dtype=float))
    return AdaptiveManipulatorObserver(unknowns, OBSERVER_GAIN, experiment.adaptation_gain, sample_period=SAMPLE_PERIOD,
                                       lower=experiment.lower, upper=experiment.upper, margin=experiment.margin)


def build(config: Config, name: str) -> Scenario:
    """The closed loop of experiment ``name`` (a key of :data:`EXPERIMENTS`)."""
    if name not in EXPERIMENTS:
        raise ValueError(f"experiment must be one of {', '.join(EXPERIMENTS)}; got {name!r}")
    experiment = EXPERIMENTS[name]
    truth = FurutaConstants()
    plant = FurutaPlant(truth)
    watcher = observer(experiment)
    controller = FurutaPendulumBackstepping(parameters(experiment.unknowns), 10.0, 1.0, 10.0, experiment.damping)
    duration = experiment_duration(config, name)
    start = [0.0, UPRIGHT_START] if experiment.upright else [0.0, math.pi]
    return Scenario(
        plant, JointEncoder(truth, sample_period=SAMPLE_PERIOD, quantization=QUANTIZATION), watcher, controller,
        plant.state(start, [0.0, 0.0]), watcher.guess(0.0, experiment.initial),
        plant_step=config.plant_step, sample_period=SAMPLE_PERIOD, duration=duration,
        reference=reference(experiment, duration), record_every=1,
    )


#: The scenarios a scenario file can name as its ``case`` (one per experiment); the first is the
#: default. See :mod:`lookout.studies.scenario_file`.
CASES: tuple[str, ...] = tuple(EXPERIMENTS)


def case_scenario(config: Config, case: str) -> Scenario:
    """The scenario of ``case`` (one of :data:`CASES`) for ``config``, as :func:`run` simulates it."""
    return build(config, case)


def scenarios(config: Config) -> list[Scenario]:
    """The scenarios :func:`run` simulates, one per experiment in ``config.experiments``."""
    return [build(config, name) for name in config.experiments]


def _settling_time(time: np.ndarray, values: np.ndarray, target: float, tolerance: float = 0.05) -> float | None:
    """First time after which |value - target| <= tolerance |target| to the end; None if never."""
    inside = np.abs(values - target) <= tolerance * abs(target)
    if not inside.size or not inside[-1]:
        return None
    outside = np.flatnonzero(~inside)
    return float(time[0]) if not outside.size else float(time[outside[-1] + 1])


def summarize(ds: xr.Dataset, name: str) -> dict:
    """The numbers of the derivation notes' "what a reproduction should output" (ch. 6)."""
    experiment = EXPERIMENTS[name]
    time = ds.time.values
    angle, rate = ds.joint_angle.values, ds.joint_rate.values
    rate_hat = ds.joint_rate_hat.values
    tau = ds.joint_torque_applied.values[:, 0]
    desired = ds[f"{PENDULUM_REFERENCE}_desired"].values
    hats = {unknown: ds[theta_signal_name(unknown)].values for unknown in experiment.unknowns}
    finite = np.all(np.isfinite(angle), axis=1) & np.all(np.isfinite(rate_hat), axis=1) & np.isfinite(tau)
    for values in hats.values():
        finite &= np.isfinite(values)
    last = len(time) if finite.all() else int(np.argmin(finite))
    ok = slice(0, last)
    error = angle[ok, 1] - desired[ok]
    late = time[ok] >= 5.0
    # the pendulum leaves its half-plane: |theta| > pi/2 upright, |theta - pi| > pi/2 hanging
    offset = angle[ok, 1] - (0.0 if experiment.upright else math.pi)
    left = np.flatnonzero(np.abs(offset) > math.pi / 2)
    fell_at = float(time[left[0]]) if left.size else None
    # det M_hat(q; theta_hat) along the run, at the observer's q (the measurement) and theta_hat
    unknowns = parameters(experiment.unknowns)
    theta_hat = np.stack([hats[u][ok] for u in experiment.unknowns], axis=1)
    q_hat = ds.joint_angle_hat.values[ok]
    det = np.asarray(jax.jit(jax.vmap(lambda q, th: unknowns.model(th).determinant(q)))(jnp.asarray(q_hat), jnp.asarray(theta_hat)))
    dt = float(time[1] - time[0])
    status = str(ds.status.values)
    if status == "finite" and fell_at is not None:
        status = "fell"
    result = {
        "experiment": name,
        "figures": experiment.figures,
        "printed_setting": experiment.printed,
        "note": experiment.note,
        "duration_s": float(time[-1] + dt),
        "status": status,
        "finite_until_s": float(time[last - 1]) if last > 0 else 0.0,
        "pendulum_left_half_plane_at_s": fell_at,
        "rms_tracking_error_after_5s": float(np.sqrt(np.mean(error[late] ** 2))) if late.any() else None,
        "max_abs_tracking_error_after_5s": float(np.abs(error[late]).max()) if late.any() else None,
        "max_abs_tau_u": float(np.abs(tau[ok]).max()) if last > 0 else None,
        "max_abs_tau_u_after_1s": float(np.abs(tau[ok][time[ok] >= 1.0]).max()) if (time[ok] >= 1.0).any() else None,
        "arm_rate_range": [float(rate[ok, 0].min()), float(rate[ok, 0].max())],
        "pendulum_rate_range": [float(rate[ok, 1].min()), float(rate[ok, 1].max())],
        "arm_rate_hat_range": [float(rate_hat[ok, 0].min()), float(rate_hat[ok, 0].max())],
        "pendulum_rate_hat_range": [float(rate_hat[ok, 1].min()), float(rate_hat[ok, 1].max())],
        "arm_angle_final": float(angle[last - 1, 0]) if last > 0 else None,
        "arm_mean_rate": float((angle[last - 1, 0] - angle[0, 0]) / max(time[last - 1] - time[0], dt)) if last > 1 else None,
        "arm_stuck_time_s": float(ds.arm_stuck_time.values[last - 1]) if last > 0 else None,
        "det_m_hat_nonpositive_s": float(np.count_nonzero(det <= 0) * dt),
        "det_m_hat_min": float(det.min()) if det.size else None,
        "resets": int(ds.resets.values[last - 1]) if last > 0 else 0,
        "initial_estimates": dict(zip(experiment.unknowns, experiment.initial)),
        "final_estimates": {u: float(hats[u][last - 1]) if last > 0 else None for u in experiment.unknowns},
        "estimate_within_5pct_from_s": {u: _settling_time(time[ok], hats[u][ok], TRUTH[u]) for u in experiment.unknowns},
    }
    return result


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate the experiments; write one NetCDF and one figure each, and summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    results, per_experiment, files = {}, {}, []
    for index, name in enumerate(config.experiments):
        ds = simulate(build(config, name), jax.random.PRNGKey(config.seed)).to_xarray().isel(run=0)
        ds.attrs.update({"reproduction": NAME, "title": TITLE, "experiment": name, "config": config.model_dump_json()})
        filename = f"calugi_2002_furuta_{name.replace('-', '_')}.nc"
        write_netcdf(ds, out / filename, history=f"lookout reproduce {NAME} (experiment {name})")
        files.append(filename)
        results[name] = ds
        per_experiment[name] = summarize(ds, name)
        if progress is not None:
            progress(index + 1, len(config.experiments))
    files += _figures(results, out)
    summary = {
        "reproduction": NAME,
        "config": config.model_dump(),
        "seeds": [config.seed],
        "status": [values["status"] for values in per_experiment.values()],
        "alpha_minimum_for_positive_m_hat": ALPHA_MINIMUM,
        "experiments": per_experiment,
        "files": sorted([*files, "summary.json"]),
    }
    return write_summary(summary, out)


def _figures(results: dict, out: Path) -> list[str]:
    """Per experiment, the panels of Figs. 6.2–6.18: theta with theta_d, phi, x1_hat_2 with the
    true theta', x1_hat_1 with the true phi', tau_u and the estimates. A run that fails is drawn
    up to where the pendulum leaves its half-plane (or the numbers stop being finite)."""
    import matplotlib.pyplot as plt

    figures = {}
    for name, ds in results.items():
        experiment = EXPERIMENTS[name]
        time = ds.time.values
        upright = 0.0 if experiment.upright else math.pi
        bad = ~np.isfinite(ds.joint_torque_applied.values[:, 0]) | (np.abs(ds.joint_angle.values[:, 1] - upright) > math.pi / 2)
        end = len(time) if not bad.any() else max(1, int(np.argmax(bad)))
        window = slice(0, end)
        t = time[window]
        figure, grid = plt.subplots(6, 2, figsize=(12, 13), gridspec_kw={"width_ratios": (3, 1)})
        axes, zooms = grid[:, 0], grid[:, 1]
        for axis in axes[1:]:
            axis.sharex(axes[0])
        # the zoom: the last reference period drawn (2.5 s), or the last 0.5 s before a failure
        span = PERIOD if end == len(time) else 0.5
        tail = slice(max(0, end - int(round(span / SAMPLE_PERIOD))), end)
        angle, rate, rate_hat = ds.joint_angle.values, ds.joint_rate.values, ds.joint_rate_hat.values
        tau, desired = ds.joint_torque_applied.values[:, 0], ds[f"{PENDULUM_REFERENCE}_desired"].values
        axes[0].plot(t, desired[window], color="k", lw=1.2, label="theta_d")
        axes[0].plot(t, angle[window, 1], color="C0", lw=0.9, ls="--", label="theta")
        axes[0].set_ylabel("pendulum theta (rad)")
        zooms[0].plot(time[tail], angle[tail, 1] - desired[tail], color="C0", lw=0.9, label="theta - theta_d")
        zooms[0].set_ylabel("z1 (rad)")
        axes[1].plot(t, angle[window, 0], color="C4", lw=0.9, label="phi (arm, not controlled)")
        axes[1].set_ylabel("arm phi (rad)")
        for row, joint, truth_label, estimate_label, unit_label in (
            (2, 1, "theta' (true, the 'analog' signal)", "x1_hat_2 (observer)", "pendulum rate (rad/s)"),
            (3, 0, "phi' (true, the 'analog' signal)", "x1_hat_1 (observer)", "arm rate (rad/s)"),
        ):
            for axis, part in ((axes[row], window), (zooms[row], tail)):
                axis.plot(time[part], rate[part, joint], color="k", lw=1.2, label=truth_label)
                axis.plot(time[part], rate_hat[part, joint], color="C1", lw=0.7, ls="--", label=estimate_label)
            axes[row].set_ylabel(unit_label)
        for axis, part in ((axes[4], window), (zooms[4], tail)):
            axis.plot(time[part], tau[part], color="C2", lw=0.7, label="tau_u")
        axes[4].set_ylabel("arm torque (N m)")
        for k, unknown in enumerate(experiment.unknowns):
            symbol, color = SYMBOLS[unknown], ("C3", "C0")[k]
            axis = axes[5] if k == 0 else axes[5].twinx()
            axis.plot(t, ds[theta_signal_name(unknown)].values[window], color=color, lw=1.0, ls="--", label=f"{symbol}_hat")
            axis.axhline(TRUTH[unknown], color=color, lw=0.8, label=f"{symbol} (true)")
            axis.set_ylabel(f"{symbol} ({UNITS[unknown]})", color=color)
            axis.legend(fontsize=7, loc="lower right" if k == 0 else "center right")
        axes[5].set_xlabel("time (s)")
        for axis in axes[:5]:
            axis.legend(fontsize=7, loc="upper right")
        zooms[0].set_title(f"zoom: the last {time[tail][-1] - time[tail][0] + SAMPLE_PERIOD:.2f} s drawn", fontsize=8)
        for row in (1, 5):
            zooms[row].axis("off")
        for row in (2, 3):
            zooms[row].sharex(zooms[0])
        zooms[4].sharex(zooms[0])
        zooms[4].set_xlabel("time (s)")
        status = str(ds.status.values)
        ending = "" if end == len(time) else f"; the pendulum leaves its half-plane at {time[int(np.argmax(bad))]:.2f} s ({status})"
        figure.suptitle(f"Exp. {name} (cf. Figs. {experiment.figures}): {experiment.note}{ending}", fontsize=9)
        figure.tight_layout()
        figures[f"exp_{name.replace('-', '_')}.png"] = figure
    return save_figures(figures, out)


def _value(value, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(f"{v:.{digits}g}" for v in value) + "]"
    return f"{value:.{digits}g}"


def tables(summary: dict) -> list[Table]:
    """One column per experiment."""
    experiments = summary["experiments"]
    keys = (("status", "status"), ("finite until (s)", "finite_until_s"), ("fell at (s)", "pendulum_left_half_plane_at_s"),
            ("RMS z1, t>5 s (rad)", "rms_tracking_error_after_5s"), ("max |tau_u| (N m)", "max_abs_tau_u"),
            ("max |tau_u|, t>1 s", "max_abs_tau_u_after_1s"), ("phi' range (rad/s)", "arm_rate_range"),
            ("theta' range (rad/s)", "pendulum_rate_range"), ("mean phi' (rad/s)", "arm_mean_rate"),
            ("arm stuck (s)", "arm_stuck_time_s"), ("det M_hat <= 0 (s)", "det_m_hat_nonpositive_s"), ("resets", "resets"))
    rows = []
    for label, key in keys:
        if key == "status":
            rows.append((label, *(v["status"] for v in experiments.values())))
        elif key == "resets":
            rows.append((label, *(str(v["resets"]) for v in experiments.values())))
        else:
            rows.append((label, *(_value(v[key]) for v in experiments.values())))
    for unknown, truth in TRUTH.items():
        rows.append((f"final {SYMBOLS[unknown]}_hat ({truth:g})",
                     *(_value(v["final_estimates"].get(unknown), 4) for v in experiments.values())))
        rows.append((f"{SYMBOLS[unknown]}_hat in 5 % from (s)",
                     *(_value(v["estimate_within_5pct_from_s"].get(unknown)) for v in experiments.values())))
    return [Table("Calugi (2002) ch. 6: Furuta pendulum experiments in simulation", ("", *experiments), tuple(rows),
                  "z1 = theta - theta_d; fell: the pendulum left its half-plane; -fixed: the nearest working setting; M_hat is positive definite for all theta iff alpha_hat > gamma^2/beta = "
                  f"{summary['alpha_minimum_for_positive_m_hat']:.4g}")]


__all__ = ["Config", "EXPERIMENTS", "Experiment", "NAME", "TITLE", "build", "experiment_duration", "parameters", "reference", "run",
           "scenarios", "summarize", "tables"]
