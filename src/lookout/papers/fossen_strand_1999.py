"""Reproduction of Fossen & Strand (1999), Section 6.1: the simulation study.

Northern Clipper (eqs. 56–57), bias time constants T = 1000 s (eq. 58), wave and
notch parameters w_o = 0.8976 rad/s, zeta = 0.1, zeta_n = 1.0, w_c = 1.1 rad/s
(eq. 59), Kappa = diag(0.1, 0.1, 0.01) and Lambda = 0.1 Kappa (eq. 60, read as
normalized "bis" gains and converted to SI), gamma = 1, tau of eq. (61), 1 Hz
position and heading measurements, first-order wave motion "limited to" 10 m,
10 m and 1.0 deg.

Not given by the paper and chosen here (see docs/reproductions.md): the wave
amplitude is read as 3 standard deviations; the bias is the Gauss–Markov process
(7) with T = 1000 s, stationary std 2 kN, 2 kN, 50 kN m, starting at
[10 kN, 5 kN, 100 kN m]; measurement noise std 0.5 m (DGPS) and 0.1 deg (gyro);
the observer runs at 10 Hz and holds the latest fix between fixes; the vessel
starts at rest at the origin and the observer at zero.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import cast

import numpy as np
import xarray as xr
from pydantic import Field, ValidationInfo, field_validator

from lookout.analysis import check_spr, check_tuning_rule, estimation_errors, frequency_response, settling_time
from lookout.observers import PassiveObserver, injection_gains_from_normalized
from lookout.papers import CATALOG
from lookout.papers._config import VesselSettings
from lookout.papers._report import Table, mean_and_spread, significant, write_summary
from lookout.papers._reproduction import Reproduction, built_as
from lookout.results import write_netcdf
from lookout.scenario.composition import compose
from lookout.scenario.settings import PositiveFloat, RunsConfig, whole_samples
from lookout.sim import Scenario, seed_keys, simulate, simulate_batch

NAME = "fossen-strand-1999"
TITLE = CATALOG[NAME].title
STATES = ("eta", "nu", "bias", "wave")
#: A run must span at least this many position fixes (see Config.duration).
MINIMUM_FIXES = 10


class Config(RunsConfig):
    """Settings of the reproduction; every field has the paper's value or a stated choice.

    Validation messages name the field and read as "<field>: <condition>"; the CLI
    shows them under the option's name (``--duration``).
    """

    seed: int = Field(default=0, description="PRNG seed of run 0 (run i uses seed + i)")
    plant_step: PositiveFloat = Field(default=0.1, description="RK4 step of the plant (s)")
    sample_period: PositiveFloat = Field(default=0.1, description="observer period (s)")
    measurement_period: PositiveFloat = Field(default=1.0, description="position and heading sample period (s), paper: 1 Hz")
    duration: PositiveFloat = Field(default=3000.0, description="simulated time (s), a multiple of sample_period, at least 10 measurement periods")
    wave_frequency: PositiveFloat = Field(default=0.8976, description="w_o (rad/s), eq. (59)")
    wave_damping: PositiveFloat = Field(default=0.1, description="zeta, eq. (59)")
    notch_damping: PositiveFloat = Field(default=1.0, description="zeta_n, eq. (59)")
    cutoff_frequency: PositiveFloat = Field(default=1.1, description="w_c (rad/s), eq. (59)")
    bias_time_constant: PositiveFloat = Field(default=1000.0, description="T (s), eq. (58)")
    velocity_gain_normalized: tuple[float, float, float] = (0.1, 0.1, 0.01)
    bias_gain_normalized: tuple[float, float, float] = (0.01, 0.01, 0.001)
    wave_amplitude: tuple[float, float, float] = (10.0, 10.0, float(np.radians(1.0)))
    wave_amplitude_sigmas: PositiveFloat = 3.0
    bias_std: tuple[float, float, float] = (2e3, 2e3, 5e4)
    bias_initial: tuple[float, float, float] = (1e4, 5e3, 1e5)
    noise_std: tuple[float, float, float] = (0.5, 0.5, float(np.radians(0.1)))
    dropout_probability: float = Field(
        default=0.0, description="probability that a position and heading fix is lost (the observer holds the last one)"
    )
    vessel: VesselSettings = Field(default=VesselSettings(), description="the vessel: Northern Clipper (the paper's) or your own M and D")

    @field_validator("dropout_probability")
    @classmethod
    def _probability(cls, value):
        if not (0.0 <= value < 1.0):
            raise ValueError(f"must be in [0, 1); got {value:g}")
        return value

    @field_validator("duration")
    @classmethod
    def _whole_samples_and_enough_fixes(cls, value, info: ValidationInfo):
        fixes = info.data.get("measurement_period")
        whole_samples(value, info.data.get("sample_period"))
        if fixes is not None and value < MINIMUM_FIXES * fixes:
            raise ValueError(
                f"must be at least {MINIMUM_FIXES * fixes:g} s ({MINIMUM_FIXES} position fixes, so that the second half, "
                f"over which the errors are summarized, holds {MINIMUM_FIXES // 2}); got {value:g} s"
            )
        return value

    @field_validator("wave_amplitude", "bias_std", "noise_std", "velocity_gain_normalized", "bias_gain_normalized")
    @classmethod
    def _non_negative(cls, value):
        if any(not np.isfinite(v) or v < 0 for v in value):
            raise ValueError("entries must be finite and non-negative")
        return value


#: The paper's tau, eq. (61): amplitude (N, N, N m) and frequencies (rad/s) of the sinusoids.
INPUT_AMPLITUDE = 1000.0
INPUT_FREQUENCIES = (0.05, 0.1, 0.07)


def composition(config: Config, case: str = "paper") -> dict:
    """The scenario of Section 6.1 for ``config`` as a composition (:mod:`lookout.scenario.composition`):
    the normalized gains of (60) in SI, the bias of (7) and (58), the waves of (11) and (59)."""
    del case
    velocity_gain, bias_gain = injection_gains_from_normalized(
        config.velocity_gain_normalized, config.bias_gain_normalized, mass=config.vessel.mass, length=config.vessel.length
    )
    return {
        "simulation": {
            "runs": config.runs,
            "seed": config.seed,
            "plant_step": config.plant_step,
            "sample_period": config.sample_period,
            "duration": config.duration,
        },
        "plant": {
            "kind": "dp-vessel",
            "vessel": config.vessel.composition(),
            "bias": {"kind": "gauss-markov", "time_constant": config.bias_time_constant, "std": config.bias_std},
            "waves": {
                "kind": "linear",
                "peak_frequency": config.wave_frequency,
                "damping_ratio": config.wave_damping,
                "amplitude": config.wave_amplitude,
                "sigmas": config.wave_amplitude_sigmas,
            },
            "initial": {"bias": config.bias_initial},
        },
        "sensor": {
            "kind": "position-heading",
            "noise_std": config.noise_std,
            "sample_period": config.measurement_period,
            "dropout_probability": config.dropout_probability,
        },
        "observer": {
            "kind": "passive",
            "design": "fossen-strand-1999",
            "wave_frequency": config.wave_frequency,
            "wave_damping": config.wave_damping,
            "notch_damping": config.notch_damping,
            "cutoff_frequency": config.cutoff_frequency,
            "velocity_injection_gain": velocity_gain.tolist(),
            "bias_injection_gain": bias_gain.tolist(),
            "bias_time_constant": config.bias_time_constant,
        },
        "controller": {"kind": "sinusoidal", "amplitude": INPUT_AMPLITUDE, "frequency": INPUT_FREQUENCIES},
    }


def build(config: Config) -> Scenario:
    """The simulation scenario of Section 6.1 for ``config``."""
    return compose(composition(config)).scenario


#: The paper's vectors over (surge, sway, yaw) from the recorded quantities, as
#: (variable, component) per DOF: eta, nu, b, eta_w of eqs. (1)–(12), y and tau.
PAPER_VECTORS = {
    "eta": (("position", "north"), ("position", "east"), ("heading", None)),
    "nu": (("velocity", "surge"), ("velocity", "sway"), ("yaw_rate", None)),
    "bias": (("bias_force", "north"), ("bias_force", "east"), ("bias_moment", None)),
    "wave": (("wave_position", "north"), ("wave_position", "east"), ("wave_heading", None)),
    "measurement": (("measured_position", "north"), ("measured_position", "east"), ("measured_heading", None)),
    "tau": (("force_applied", "surge"), ("force_applied", "sway"), ("moment_applied", None)),
}
DOF = ("surge", "sway", "yaw")


def paper_vector(data: xr.Dataset, name: str, suffix: str = "") -> xr.DataArray:
    """The paper's vector ``name`` (eta, nu, bias, wave, measurement, tau) over dim ``dof``.

    ``suffix`` picks estimates (``"_hat"``). Works on a simulation Dataset and on
    :func:`lookout.analysis.estimation_errors` of one. The units attribute lists the
    unit per DOF (``surge: m, sway: m, yaw: rad``): for reading, not for NetCDF.
    """
    parts, units = [], []
    for (variable, label), dof in zip(PAPER_VECTORS[name], DOF):
        array = data[variable + suffix]
        for dim in ("earth_axis", "body_axis"):
            if label is not None and dim in array.dims:
                array = array.sel({dim: label}, drop=True)
        parts.append(array)
        units.append(f"{dof}: {data[variable + suffix].attrs.get('units', '')}")
    return xr.concat(parts, dim=xr.DataArray(list(DOF), dims="dof", name="dof")).transpose(..., "dof").assign_attrs(units=", ".join(units))


def paper_view(ds: xr.Dataset) -> xr.Dataset:
    """The results in the paper's notation: eta, nu, bias, wave (and ``_hat``), the
    measurement y and tau, each over ``dof`` = (surge, sway, yaw), with ``status``."""
    data = {}
    for name in PAPER_VECTORS:
        data[name] = paper_vector(ds, name)
        if name in STATES:
            data[f"{name}_hat"] = paper_vector(ds, name, "_hat")
    view = xr.Dataset(data)
    if "status" in ds:
        view["status"] = ds.status
    return view


def summarize(ds: xr.Dataset) -> dict:
    """RMS error per state and DOF over the second half, and settling times.

    With several runs, ``rms_second_half`` is the mean over runs, ``rms_second_half_std``
    its standard deviation across runs, and settling times are medians over runs.
    """
    errors = estimation_errors(ds)
    half = float(ds.time[-1]) / 2.0
    time = ds.time.values
    summary: dict = {
        "runs": int(ds.sizes["run"]),
        "rms_second_half": {},
        "rms_second_half_std": {},
        "settling_time": {},
        "true_std_second_half": {},
        "units": {},
    }
    for name in STATES:
        error = paper_vector(errors, name)
        truth = paper_vector(ds, name)
        # numpy's stubs give a ufunc's result as an ndarray; a DataArray's __array_ufunc__ gives a DataArray
        rms = cast(xr.DataArray, np.sqrt((error.sel(time=ds.time >= half) ** 2).mean("time")))  # dims (run, dof)
        summary["units"][name] = truth.attrs["units"]
        summary["rms_second_half"][name] = dict(zip(DOF, rms.mean("run").values.tolist()))
        summary["rms_second_half_std"][name] = dict(zip(DOF, rms.std("run").values.tolist()))
        summary["true_std_second_half"][name] = dict(zip(DOF, truth.sel(time=ds.time >= half).std("time").mean("run").values.tolist()))
        settles = settling_time(error.transpose("run", "dof", "time").values, time, rms.transpose("run", "dof").values)
        summary["settling_time"][name] = dict(zip(DOF, np.median(settles, axis=0).tolist()))
    return summary


def simulate_runs(config: Config, *, progress: Callable | None = None, scenario: Scenario | None = None) -> xr.Dataset:
    """Simulate the scenario for the seeds of ``config`` (one run, or a vmapped batch).

    ``scenario`` is ``build(config)`` when the caller has already built it.

    Returns
    -------
    xarray.Dataset
        :meth:`lookout.Trajectory.to_xarray` with a ``seed`` coordinate along ``run``.
    """
    scenario = build(config) if scenario is None else scenario
    if config.runs == 1:
        trajectory = simulate(scenario, seed_keys(config.seed, 1)[0], progress=progress)
    else:
        trajectory = simulate_batch(scenario, seed_keys(config.seed, config.runs), progress=progress)
    ds = trajectory.to_xarray().assign_coords(seed=("run", np.asarray(config.seeds, dtype=np.int64), {"long_name": "PRNG seed of the run"}))
    ds.attrs.update({"reproduction": NAME, "title": TITLE, "config": config.model_dump_json()})
    return ds


def run(config: Config, out: Path, *, progress: Callable | None = None) -> dict:
    """Simulate, write NetCDF, figures and summary.json under ``out``; return the summary.

    ``out`` is created (with missing parents) if needed.
    """
    import matplotlib.pyplot as plt

    from lookout.plotting import plot_bode, plot_estimates

    scenario = build(config)
    ds = simulate_runs(config, progress=progress, scenario=scenario)
    out.mkdir(parents=True, exist_ok=True)
    write_netcdf(ds, out / "fossen_strand_1999.nc", history=f"lookout reproduce {NAME} (seeds {config.seeds[0]}..{config.seeds[-1]})")

    observer = built_as(scenario.observer, PassiveObserver, "the observer")
    response = frequency_response(observer)
    write_netcdf(response, out / "bode.nc", history=f"frequency response of the observer of {NAME}")
    figures = {"fig06_bode.png": plot_bode(response, title="Fossen & Strand (1999), Fig. 6: error-loop frequency response h0, hB, h")}
    for number, dof in zip((9, 10, 11), DOF):
        panels = [PAPER_VECTORS[name][DOF.index(dof)] for name in ("eta", "nu", "wave", "bias")]
        figures[f"fig{number:02d}_{dof}.png"] = plot_estimates(ds, panels, title=f"Fossen & Strand (1999), Fig. {number}: {dof}, true and estimated")
    for filename, figure in figures.items():
        figure.savefig(out / filename, dpi=110)
        plt.close(figure)

    summary = summarize(ds)
    summary.update(
        {
            "reproduction": NAME,
            "config": config.model_dump(),
            "seeds": config.seeds,
            "status": ds.status.values.tolist(),
            "gains_si": {
                "K1": observer.wave_injection_matrix().tolist(),
                "K2": observer.position_injection_matrix().tolist(),
                "velocity_injection_gain": np.asarray(observer.velocity_injection_gain).tolist(),
                "bias_injection_gain": np.asarray(observer.bias_injection_gain).tolist(),
            },
            "tuning_rule_holds": check_tuning_rule(observer).holds,
            "spr": {dof: report.verdict for dof, report in zip(DOF, check_spr(observer))},
            "files": sorted(["fossen_strand_1999.nc", "bode.nc", "summary.json", *figures]),
        }
    )
    write_summary(summary, out)
    return summary


#: The cases (one: the Section 6.1 study); a scenario file's preset "fossen-strand-1999" is it.
CASES: tuple[str, ...] = ("paper",)


def tables(summary: dict) -> list[Table]:
    """The summary as tables for the terminal: RMS errors (mean ± std over runs) and settling times."""
    runs = summary["runs"]
    spread = runs > 1
    seeds = summary["seeds"]
    which = f"seed {seeds[0]}" if runs == 1 else f"{runs} runs, seeds {seeds[0]}-{seeds[-1]}, mean ± std"
    error_rows, settling_rows, units = [], [], []
    for name, values in summary["rms_second_half"].items():
        units.append(f"{name} " + summary["units"][name].replace("surge: ", "").replace("sway: ", "").replace("yaw: ", ""))
        if spread:
            cells = [mean_and_spread(values[dof], summary["rms_second_half_std"][name][dof]) for dof in DOF]
        else:
            cells = [significant(values[dof]) for dof in DOF]
        error_rows.append((name, *cells))
        settling_rows.append((name, *(f"{summary['settling_time'][name][dof]:.0f}" for dof in DOF)))
    return [
        Table(f"RMS estimation error over the second half ({which})", ("state", *DOF), tuple(error_rows), "units: " + "; ".join(units)),
        Table(
            f"Settling time (s{', median over runs' if spread else ''})",
            ("state", *DOF),
            tuple(settling_rows),
            "the first time from which the RMS error over the rest of the run is within 10 % of its "
            "second-half RMS; 0 means at that level from the start, not that the estimate tracks the truth",
        ),
    ]


#: Fossen & Strand (1999), Section 6.1: the passive observer on the Northern Clipper.
REPRODUCTION = Reproduction(NAME, Config, CASES, composition, run, tables)
