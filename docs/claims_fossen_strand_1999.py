"""Ratios quoted in docs/reproductions.md for the Fossen & Strand (1999) reproduction.

Runs the reproduction scenario for the 20 seeds of
``lookout reproduce fossen-strand-1999 --runs 20`` (3000 s each) and prints, over the
second half of each run:

- wave filtering: LF position error RMS over the RMS of y - eta (what the raw
  measurement gives), surge and sway, min–max over runs;
- velocity: observer's Earth-frame velocity error RMS against differencing
  consecutive 1 Hz fixes (largest ratio over runs), and the body-frame error RMS over
  the velocity's own std (mean over runs);
- bias: mean error RMS over the bias's stationary std (the prior).

Usage: python docs/claims_fossen_strand_1999.py
"""

import lookout

lookout.configure_cpu()

import numpy as np  # noqa: E402

from lookout.analysis import earth_frame_velocity, estimation_errors, rms_over  # noqa: E402
from lookout.papers import fossen_strand_1999 as fs  # noqa: E402

RUNS, DURATION = 20, 3000.0
FIX_EVERY = 10  # 1 Hz fixes at the 10 Hz observer rate


def main() -> None:
    config = fs.Config(duration=DURATION, runs=RUNS)
    recorded = fs.simulate_runs(config)
    ds = fs.paper_view(recorded)  # eta, nu, bias, wave, measurement over (surge, sway, yaw)
    settled = DURATION / 2
    late = ds.time.values >= settled
    rms = rms_over(estimation_errors(recorded), settled)
    errors = {name: fs.paper_vector(rms, name) for name in ("eta", "nu", "bias")}  # dims (run, dof)

    raw = np.sqrt(((ds.measurement - ds.eta).sel(time=late) ** 2).mean("time"))
    wave_filtering = (errors["eta"] / raw).sel(dof=["surge", "sway"]).values
    print(f"{RUNS} runs, seeds {config.seeds[0]}-{config.seeds[-1]}, {DURATION:g} s, errors over [{settled:g}, {DURATION:g}] s")
    print(f"wave filtering, LF position error / raw error (surge, sway): {wave_filtering.min():.3f} .. {wave_filtering.max():.3f}")

    psi = ds.eta.sel(dof="yaw").values
    nu, nu_hat = ds.nu.values, ds.nu_hat.values
    observer = np.sqrt((earth_frame_velocity(psi, nu - nu_hat)[:, late] ** 2).mean(axis=1))
    fixes = ds.measurement.values[:, ::FIX_EVERY, :2]
    naive_error = np.diff(fixes, axis=1) / (FIX_EVERY * float(ds.time[1] - ds.time[0])) - earth_frame_velocity(psi, nu)[:, ::FIX_EVERY][:, :-1]
    naive = np.sqrt((naive_error[:, late[::FIX_EVERY][:-1]] ** 2).mean(axis=1))
    print(f"velocity, observer / differenced fixes, Earth frame (surge, sway): at most {np.max(observer / naive):.4f}")
    own_std = ds.nu.sel(time=late).std("time")
    print(
        "velocity, error RMS / velocity std (surge, sway, yaw), mean over runs:",
        np.array2string((errors["nu"] / own_std).mean("run").values, precision=3, separator=", "),
    )

    prior = errors["bias"].mean("run").values / np.asarray(config.bias_std)
    print("bias, mean error RMS / stationary std (surge, sway, yaw):", np.array2string(prior, precision=3, separator=", "))


if __name__ == "__main__":
    main()
