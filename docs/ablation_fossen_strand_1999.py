"""Where the estimation error of the Fossen & Strand (1999) reproduction comes from.

Runs the reproduction scenario (8 seeds, 3000 s) with parts switched off and prints
the mean RMS error over the second half. Used in docs/reproductions.md.
Usage: python docs/ablation_fossen_strand_1999.py
"""

import dataclasses

import lookout

lookout.configure_cpu()

import numpy as np  # noqa: E402

from lookout.analysis import estimation_errors, rms_over  # noqa: E402
from lookout.papers import fossen_strand_1999 as fs  # noqa: E402
from lookout.sim import seed_keys, simulate_batch  # noqa: E402

RUNS, DURATION = 8, 3000.0
VARIANTS = {
    "paper scenario (1 Hz fixes held, noise, waves)": ({}, "sampled"),
    "no waves": ({"wave_amplitude": (0.0, 0.0, 0.0)}, "sampled"),
    "fixes at 10 Hz (observer rate)": ({"measurement_period": 0.1}, "sampled"),
    "continuous observer, noise-free measurement": ({}, "continuous"),
    "continuous observer, no waves": ({"wave_amplitude": (0.0, 0.0, 0.0)}, "continuous"),
    "continuous observer, no waves, constant bias": ({"wave_amplitude": (0.0, 0.0, 0.0), "bias_std": (0.0, 0.0, 0.0)}, "continuous"),
}


def main() -> None:
    keys = seed_keys(0, RUNS)  # the seeds of `lookout reproduce fossen-strand-1999 --runs 8`
    print(f"mean RMS error over [{DURATION / 2:g}, {DURATION:g}] s, {RUNS} seeds: surge, sway, yaw")
    for label, (overrides, mode) in VARIANTS.items():
        scenario = fs.build(fs.Config(duration=DURATION, **overrides))
        scenario = dataclasses.replace(scenario, observer_mode=mode)
        ds = simulate_batch(scenario, keys).to_xarray()
        rms = rms_over(estimation_errors(ds), DURATION / 2).mean("run")
        print(f"\n{label}")
        for name in ("eta", "nu", "bias", "wave"):
            print(f"  {name:5s}", np.array2string(fs.paper_vector(rms, name).values, precision=4, separator=", "))


if __name__ == "__main__":
    main()
