"""Batch throughput of the DP-class reference handling against the plain weighted mean.

The suite of examples/reference-failures.toml (two DGNSS receivers, a hydroacoustic
reference and three gyrocompasses; its drifting receiver included) on Kim's loop, with
ideal actuation so that the combining stage is what differs: a batch of runs, two ways,
``[references] kind = "weighted-mean"`` (the baseline) and ``"dp-class"``. Prints
simulated seconds per wall second over all runs and the ratio (the target: dp-class
costs at most 1.5x the weighted mean). Compilation is excluded (each is run once to warm
up); the figure is the median of --repeats.

Usage: python benchmarks/references.py [--batch 64] [--duration 300] [--repeats 3]
"""

from __future__ import annotations

import argparse
import copy
import time
import tomllib
from pathlib import Path

import lookout

lookout.configure_cpu()  # before JAX computes anything

import jax  # noqa: E402
import numpy as np  # noqa: E402

from lookout.scenario import composition  # noqa: E402
from lookout.sim import seed_keys, simulate_batch  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--duration", type=float, default=300.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with open(ROOT / "examples" / "reference-failures.toml", "rb") as handle:
        base = tomllib.load(handle)
    base["simulation"]["duration"] = args.duration
    base["actuator"] = {"kind": "ideal"}
    for table in base["sensors"].values():  # the drift within the shorter run
        for failure in table.get("failures", []):
            failure["start"] = min(failure["start"], args.duration / 2)
    keys = seed_keys(0, args.batch)
    rates = {}
    for kind in ("weighted-mean", "dp-class"):
        document = copy.deepcopy(base)
        document["references"] = {"kind": kind}
        scenario = composition.compose(document).scenario
        jax.block_until_ready(simulate_batch(scenario, keys).measurement)  # compile
        times = []
        for _ in range(args.repeats):
            started = time.perf_counter()
            jax.block_until_ready(simulate_batch(scenario, keys).measurement)
            times.append(time.perf_counter() - started)
        rates[kind] = args.batch * args.duration / float(np.median(times))
        print(f"{kind}: {rates[kind]:.4g} simulated s per s (median of {args.repeats}: {np.median(times):.3f} s)", flush=True)
    print(
        f"\nbatch of {args.batch} runs of {args.duration:g} s, sample period 0.1 s: dp-class costs {rates['weighted-mean'] / rates['dp-class']:.2f}x the weighted mean"
    )


if __name__ == "__main__":
    main()
