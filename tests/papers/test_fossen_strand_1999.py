"""Claims of Fossen & Strand (1999), Section 6.1, checked on the reproduction scenario."""

import jax
import numpy as np
import pytest
import xarray as xr

from lookout.analysis import estimation_errors, rms_over
from lookout.papers import fossen_strand_1999 as fs
from lookout.sim import simulate


@pytest.fixture(scope="module")
def run():
    config = fs.Config(duration=1200.0, seed=11)
    ds = simulate(fs.build(config), jax.random.key(config.seed)).to_xarray()
    return config, ds


def test_netcdf_variables_and_dims(run, tmp_path):
    _, ds = run
    for name in ("eta", "eta_hat", "nu", "nu_hat", "bias", "bias_hat", "wave", "wave_hat", "measurement", "tau"):
        assert ds[name].dims == ("run", "time", "dof") and "units" in ds[name].attrs
    path = tmp_path / "run.nc"
    ds.to_netcdf(path, engine="netcdf4")
    assert xr.load_dataset(path).status.values.tolist() == ["finite"]


def test_wave_filtering_low_frequency_position_is_much_closer_than_the_measurement(run):
    """Definition 1: eta_hat reconstructs the LF motion; wave motion is filtered out.

    Tolerance: the LF position error RMS must be below 30 % of the RMS of what the
    raw measurement would give (y - eta, dominated by the 3.3 m std wave motion).
    """
    _, ds = run
    late = ds.time >= 600
    errors = rms_over(estimation_errors(ds), 600.0).isel(run=0)
    raw = np.sqrt(((ds.measurement - ds.eta).sel(time=late) ** 2).mean("time")).isel(run=0)
    ratio = errors.eta.sel(dof=["surge", "sway"]).values / raw.sel(dof=["surge", "sway"]).values
    assert np.all(ratio < 0.3), ratio


def test_velocity_estimate_beats_differencing_the_fixes_tenfold(run):
    """Velocity from position fixes alone: compared with differencing consecutive 1 Hz
    fixes (the naive alternative), the observer's Earth-frame velocity error RMS in
    surge and sway is at least 10x smaller. (Against the velocity's own spread the
    estimate is not "excellent": see docs/reproductions.md.)
    """
    _, ds = run
    one = ds.isel(run=0)
    psi = one.eta.sel(dof="yaw").values
    def earth(v):
        return np.stack([np.cos(psi) * v[:, 0] - np.sin(psi) * v[:, 1], np.sin(psi) * v[:, 0] + np.cos(psi) * v[:, 1]], axis=1)
    true_velocity = earth(one.nu.values)
    observer_error = earth(one.nu.values - one.nu_hat.values)
    fixes = slice(0, None, 10)  # 1 Hz fixes at a 10 Hz observer rate
    differenced = np.diff(one.measurement.values[fixes, :2], axis=0) / 1.0
    naive_error = differenced - true_velocity[fixes][:-1]
    late, late_fixes = one.time.values >= 600, one.time.values[fixes][:-1] >= 600
    observer_rms = np.sqrt((observer_error[late] ** 2).mean(axis=0))
    naive_rms = np.sqrt((naive_error[late_fixes] ** 2).mean(axis=0))
    assert np.all(observer_rms < 0.1 * naive_rms), (observer_rms, naive_rms)


def test_bias_estimate_beats_ignoring_the_bias(run):
    """After 600 s the bias error RMS is below the RMS of the bias itself in every DOF."""
    _, ds = run
    late = ds.time >= 600
    error = rms_over(estimation_errors(ds), 600.0).bias.isel(run=0).values
    ignored = np.sqrt((ds.bias.sel(time=late) ** 2).mean("time")).isel(run=0).values
    assert np.all(error < ignored), (error, ignored)


@pytest.mark.xfail(strict=True, reason="known gap vs the paper: wave leakage through the 1 Hz hold; surge ratio 0.63 (docs/reproductions.md)")
def test_bias_estimate_at_least_halves_the_error_of_ignoring_the_bias(run):
    """Stochastic bias (std 2 kN, 2 kN, 50 kN m; T = 1000 s): after 600 s the bias error
    RMS is below half the RMS of the bias itself (the error of assuming b = 0).
    Exponential convergence of the noise-free bias error is tested separately."""
    _, ds = run
    late = ds.time >= 600
    error = rms_over(estimation_errors(ds), 600.0).bias.isel(run=0).values
    ignored = np.sqrt((ds.bias.sel(time=late) ** 2).mean("time")).isel(run=0).values
    assert np.all(error < 0.5 * ignored), (error, ignored)
