"""Closed-loop batch throughput with thrusters against per-axis saturation.

The closed loop of examples/thrusters-dp.toml (Kim's observer backstepping on the
Northern Clipper with the passive observer, reference filter, Fossen & Strand's sea)
as a batch of runs, five ways, each the same loop with another actuator:

(a) per-axis saturation at the thrusters' reach (the baseline: ``thrust-limits``);
(b) the supply vessel's thrusters, weighted pseudo-inverse then per-thruster limits;
(c) the thrusters with the QP, lookout's active-set solver (its bounds-only form for
    this layout of tunnels and azimuths);
(d) the thrusters with the QP, qpax's interior-point solver (if qpax is installed);
(e) the ideal actuator, for scale;
(f) the thrusters with the QP, the active-set solver's general form.

With --failure MODE, every thruster actuator has the port azimuth fail in that mode
(stop, stuck, reduced to half) from the middle of the run: a failure campaign's run.

Prints simulated seconds per wall second (all runs), each against (a) (the
target: (c) >= 0.5 x (a)), and the share of samples at which the allocation was saturated. Compilation is
excluded (each is run once to warm up); the figure is the median of --repeats.

Usage: python benchmarks/allocation.py [--batch 64] [--duration 200] [--repeats 3] [--only a,c] [--failure stop]
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

from lookout.actuators import Allocator, ThrusterLayout  # noqa: E402
from lookout.scenario import composition  # noqa: E402
from lookout.sim import seed_keys, simulate_batch  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def actuators() -> dict[str, dict]:
    layout = ThrusterLayout.supply_vessel()
    allocator = Allocator(layout)
    reach = [float(v) for v in np.max(np.abs(np.asarray(allocator.reach) * allocator.force_scale), axis=0)]
    found = {
        "(a) per-axis saturation": {"kind": "thrust-limits", "limit": reach},
        "(b) thrusters, pseudo-inverse": {"kind": "thrusters", "allocation": "pseudo-inverse", "layout": {"kind": "supply-vessel"}},
        "(c) thrusters, QP (active set)": {"kind": "thrusters", "allocation": "qp", "layout": {"kind": "supply-vessel"}},
        "(f) thrusters, QP (active set, general form)": {
            "kind": "thrusters",
            "allocation": "qp",
            "solver": "active-set-general",
            "layout": {"kind": "supply-vessel"},
        },
    }
    try:
        import qpax  # noqa: F401

        found["(d) thrusters, QP (qpax)"] = {"kind": "thrusters", "allocation": "qp", "solver": "qpax", "layout": {"kind": "supply-vessel"}}
    except ImportError:
        print("qpax is not installed: (d) left out")
    found["(e) ideal actuator"] = {"kind": "ideal"}
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--duration", type=float, default=200.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", default="", help="the actuators to run, by letter (e.g. 'a,c'); default: all")
    parser.add_argument("--failure", choices=("stop", "stuck", "reduced"), help="fail the port azimuth from the middle of the run")
    args = parser.parse_args()
    only = {letter.strip() for letter in args.only.split(",") if letter.strip()}
    with open(ROOT / "examples" / "thrusters-dp.toml", "rb") as handle:
        base = tomllib.load(handle)
    base["simulation"]["duration"] = args.duration
    keys = seed_keys(0, args.batch)
    rates, iterations = {}, {}
    for name, actuator in actuators().items():
        if only and name[1] not in only:
            continue
        document = copy.deepcopy(base)
        document["actuator"] = copy.deepcopy(actuator)
        if args.failure and actuator["kind"] == "thrusters":
            failure = {"thruster": "port-azimuth", "mode": args.failure, "start": args.duration / 2}
            if args.failure == "reduced":
                failure["fraction"] = 0.5
            document["actuator"]["failures"] = [failure]
        scenario = composition.compose(document).scenario
        jax.block_until_ready(simulate_batch(scenario, keys).applied)  # compile
        times = []
        for _ in range(args.repeats):
            started = time.perf_counter()
            trajectory = simulate_batch(scenario, keys)
            jax.block_until_ready(trajectory.applied)
            times.append(time.perf_counter() - started)
        rates[name] = args.batch * args.duration / float(np.median(times))
        if "allocation_saturated" in trajectory.actuation:
            iterations[name] = float(np.mean(np.asarray(trajectory.actuation["allocation_saturated"])))
        print(f"{name}: {rates[name]:.4g} simulated s per s (median of {args.repeats}: {np.median(times):.3f} s)", flush=True)
    baseline = rates["(a) per-axis saturation"]
    failure = f", the port azimuth failing ({args.failure}) at {args.duration / 2:g} s" if args.failure else ""
    print(f"\nbatch of {args.batch} runs of {args.duration:g} s{failure}, sample period 0.1 s; against (a):")
    for name, rate in rates.items():
        note = f"; allocation saturated at {100 * iterations[name]:.0f} % of the samples" if name in iterations else ""
        print(f"  {name}: {rate / baseline:.3f} x{note}")


if __name__ == "__main__":
    main()
