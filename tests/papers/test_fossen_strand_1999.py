"""Claims of Fossen & Strand (1999), Section 6.1, checked on 8 seeds of the reproduction scenario.

Each claim is checked over a batch of seeds, so none rests on one lucky realization.
"""

import numpy as np
import pytest
import xarray as xr

from lookout.analysis import earth_frame_velocity, estimation_errors, rms_over
from lookout.papers import fossen_strand_1999 as fs
from lookout.results import write_netcdf

RUNS = 8
SETTLED = 600.0  # s; errors are compared after this time


#: one worker computes the module's fixture once (make test runs pytest --dist loadgroup)
pytestmark = pytest.mark.xdist_group("fossen_strand_1999")


@pytest.fixture(scope="module")
def run():
    """Config, the recorded Dataset, and the same in the paper's notation (eta, nu, ... over dof)."""
    config = fs.Config(duration=1200.0, seed=11, runs=RUNS)
    ds = fs.simulate_runs(config)
    return config, fs.paper_view(ds), ds


def _rms_errors(ds, name: str):
    """RMS over the settled part of the error of the paper's vector ``name``, dims (run, dof)."""
    return fs.paper_vector(rms_over(estimation_errors(ds), SETTLED), name)


def test_netcdf_variables_dims_and_units(run, tmp_path):
    _, view, ds = run
    units = {
        "position": "m",
        "heading": "rad",
        "velocity": "m/s",
        "yaw_rate": "rad/s",
        "bias_force": "N",
        "bias_moment": "N m",
        "wave_position": "m",
        "wave_heading": "rad",
    }
    for name, unit in units.items():  # one unit per variable, as UDUNITS writes it
        assert ds[name].dims[:2] == ("run", "time") and ds[f"{name}_hat"].dims == ds[name].dims
        assert ds[name].attrs["units"] == ds[f"{name}_hat"].attrs["units"] == unit
    assert view.eta.dims == ("run", "time", "dof") and view.eta.attrs["units"] == "surge: m, sway: m, yaw: rad"
    path = write_netcdf(ds, tmp_path / "run.nc")
    loaded = xr.load_dataset(path)
    assert loaded.status.values.tolist() == ["finite"] * RUNS and loaded.seed.values.tolist() == config_seeds(run)


def config_seeds(run):
    return run[0].seeds


def test_wave_filtering_low_frequency_position_is_much_closer_than_the_measurement(run):
    """Definition 1: eta_hat reconstructs the LF motion; wave motion is filtered out.

    In every run, the LF position error RMS is below 30 % of the RMS of what the raw
    measurement would give (y - eta, dominated by the 3.3 m std wave motion).
    """
    _, view, ds = run
    late = view.time >= SETTLED
    raw = np.sqrt(((view.measurement - view.eta).sel(time=late) ** 2).mean("time"))
    ratio = _rms_errors(ds, "eta").sel(dof=["surge", "sway"]).values / raw.sel(dof=["surge", "sway"]).values
    assert np.all(ratio < 0.3), ratio


def test_velocity_estimate_beats_differencing_the_fixes_tenfold(run):
    """Velocity from position fixes alone: in every run, the observer's Earth-frame
    velocity error RMS in surge and sway is at least 10x smaller than differencing
    consecutive 1 Hz fixes (the naive alternative). Against the velocity's own
    spread the estimate is not "excellent": see docs/reproductions.md.
    """
    _, view, _ = run
    fixes = slice(0, None, 10)  # 1 Hz fixes at a 10 Hz observer rate
    late = view.time.values >= SETTLED
    late_fixes = view.time.values[fixes][:-1] >= SETTLED
    for r in range(RUNS):
        one = view.isel(run=r)
        psi = one.eta.sel(dof="yaw").values
        observer_error = earth_frame_velocity(psi, one.nu.values - one.nu_hat.values)
        naive_error = np.diff(one.measurement.values[fixes, :2], axis=0) / 1.0 - earth_frame_velocity(psi, one.nu.values)[fixes][:-1]
        observer_rms = np.sqrt((observer_error[late] ** 2).mean(axis=0))
        naive_rms = np.sqrt((naive_error[late_fixes] ** 2).mean(axis=0))
        assert np.all(observer_rms < 0.1 * naive_rms), (r, observer_rms, naive_rms)


def _bias_error_over_prior(run):
    config, _, ds = run
    error = _rms_errors(ds, "bias").mean("run").values
    return error / np.asarray(config.bias_std)


def test_bias_estimate_beats_the_prior(run):
    """Mean over runs of the bias error RMS is below the bias's stationary std
    (2 kN, 2 kN, 50 kN m: the error of knowing only that the bias is zero-mean)."""
    ratio = _bias_error_over_prior(run)
    assert np.all(ratio < 1.0), ratio


@pytest.mark.xfail(
    strict=True,
    reason="known gap vs the paper: bias error about 0.7 of the bias std in surge and sway: wave leakage past the notch and the bias-loop bandwidth (docs/reproductions.md)",
)
def test_bias_estimate_halves_the_prior_error(run):
    ratio = _bias_error_over_prior(run)
    assert np.all(ratio < 0.5), ratio
