"""Claims of Fossen & Strand (1999), Section 6.1, checked on 8 seeds of the reproduction scenario.

Each claim is checked over a batch of seeds, so none rests on one lucky realization.
"""

import numpy as np
import pytest
import xarray as xr

from lookout.analysis import earth_frame_velocity, estimation_errors, rms_over
from lookout.papers import fossen_strand_1999 as fs

RUNS = 8
SETTLED = 600.0  # s; errors are compared after this time


@pytest.fixture(scope="module")
def run():
    config = fs.Config(duration=1200.0, seed=11, runs=RUNS)
    ds = fs.simulate_runs(config)
    return config, ds


def test_netcdf_variables_and_dims(run, tmp_path):
    _, ds = run
    for name in ("eta", "eta_hat", "nu", "nu_hat", "bias", "bias_hat", "wave", "wave_hat", "measurement", "tau"):
        assert ds[name].dims == ("run", "time", "dof") and "units" in ds[name].attrs
    path = tmp_path / "run.nc"
    ds.to_netcdf(path, engine="netcdf4")
    assert xr.load_dataset(path).status.values.tolist() == ["finite"] * RUNS


def test_wave_filtering_low_frequency_position_is_much_closer_than_the_measurement(run):
    """Definition 1: eta_hat reconstructs the LF motion; wave motion is filtered out.

    In every run, the LF position error RMS is below 30 % of the RMS of what the raw
    measurement would give (y - eta, dominated by the 3.3 m std wave motion).
    """
    _, ds = run
    late = ds.time >= SETTLED
    errors = rms_over(estimation_errors(ds), SETTLED)
    raw = np.sqrt(((ds.measurement - ds.eta).sel(time=late) ** 2).mean("time"))
    ratio = errors.eta.sel(dof=["surge", "sway"]).values / raw.sel(dof=["surge", "sway"]).values
    assert np.all(ratio < 0.3), ratio


def test_velocity_estimate_beats_differencing_the_fixes_tenfold(run):
    """Velocity from position fixes alone: in every run, the observer's Earth-frame
    velocity error RMS in surge and sway is at least 10x smaller than differencing
    consecutive 1 Hz fixes (the naive alternative). Against the velocity's own
    spread the estimate is not "excellent": see docs/reproductions.md.
    """
    _, ds = run
    fixes = slice(0, None, 10)  # 1 Hz fixes at a 10 Hz observer rate
    late = ds.time.values >= SETTLED
    late_fixes = ds.time.values[fixes][:-1] >= SETTLED
    for r in range(RUNS):
        one = ds.isel(run=r)
        psi = one.eta.sel(dof="yaw").values
        observer_error = earth_frame_velocity(psi, one.nu.values - one.nu_hat.values)
        naive_error = np.diff(one.measurement.values[fixes, :2], axis=0) / 1.0 - earth_frame_velocity(psi, one.nu.values)[fixes][:-1]
        observer_rms = np.sqrt((observer_error[late] ** 2).mean(axis=0))
        naive_rms = np.sqrt((naive_error[late_fixes] ** 2).mean(axis=0))
        assert np.all(observer_rms < 0.1 * naive_rms), (r, observer_rms, naive_rms)


def _bias_error_over_prior(run):
    config, ds = run
    error = rms_over(estimation_errors(ds), SETTLED).bias.mean("run").values
    return error / np.asarray(config.bias_std)


def test_bias_estimate_beats_the_prior(run):
    """Mean over runs of the bias error RMS is below the bias's stationary std
    (2 kN, 2 kN, 50 kN m: the error of knowing only that the bias is zero-mean)."""
    ratio = _bias_error_over_prior(run)
    assert np.all(ratio < 1.0), ratio


@pytest.mark.xfail(strict=True, reason="known gap vs the paper: bias error about 0.7 of the bias std in surge and sway: wave leakage past the notch and the bias-loop bandwidth (docs/reproductions.md)")
def test_bias_estimate_halves_the_prior_error(run):
    ratio = _bias_error_over_prior(run)
    assert np.all(ratio < 0.5), ratio
