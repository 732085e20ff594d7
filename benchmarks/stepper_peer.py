"""Live stepping: ``lookout.Stepper`` against MCSimPython's ``NonlinObs3dof.update``,
cost per sample, timed in the same process.

Both are the passive nonlinear DP observer of Fossen & Strand (1999), one 0.1 s
sample per call, on the Northern Clipper:

- lookout: the observer of ``lookout reproduce fossen-strand-1999`` (built as
  benchmarks/observers.py builds it), stepped by ``lookout.Stepper``: the checks of
  every argument, RK4 over the sample, the finiteness check of the result, the
  estimate returned as a dict of NumPy arrays;
- the peer: MCSimPython's ``NonlinObs3dof`` (NumPy, forward Euler over the sample,
  no argument checks, the estimate kept in the object) with the reproduction's w_c,
  w_o, wave damping (its ``lambd``) and T = 1000 s, and the same vessel's M and D.
  Its own gain choices (K2 = w_c I, K4 = diag(1, 1, 0.1), K3 = 0.1 K4) are kept:
  cost, not accuracy, is compared.

Also timed: the compiled step alone (update, output and RK4 prediction jitted over one
packed vector, called back to back with no checks), what any Python caller of the
compiled observer pays at least.

Each call gets a fresh measurement (position 0.5 m and heading 0.1 deg noise around
a slow drift, as NumPy rows) and a thrust input, with Python floats for t and dt. After
a warm-up, each repetition times ``--calls`` calls of each in turn; the median and the
minimum over ``--repeats`` repetitions are printed, and the CPU time other processes
took meanwhile (XLA runs the step on a worker thread, so a busy second core changes the
Stepper's cost and not the single-threaded peer's).

MCSimPython is GPL-3.0 and not a dependency of lookout: install it next to lookout to
run this (``pip install mcsimpython``); without it the script says so and exits.
With ``--gap-ms``, single calls are also timed each after an idle pause of that
length, as in a live loop where samples arrive at intervals (caches and the worker
thread have gone cold by then, for the peer too).

Usage: python benchmarks/stepper_peer.py [--calls 2000] [--repeats 9] [--gap-ms 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import lookout

lookout.configure_cpu()  # before JAX computes anything

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from jax.flatten_util import ravel_pytree  # noqa: E402

from lookout.papers import fossen_strand_1999 as fs  # noqa: E402

DT = 0.1


def samples(count: int, seed: int = 0) -> tuple[list, list]:
    """``count`` measurements (north, east, heading) and inputs (surge, sway, yaw), as
    lists of NumPy rows."""
    rng = np.random.default_rng(seed)
    k = np.arange(count)
    drift = np.stack([10.0 + 0.01 * k, 5.0 - 0.005 * k, 0.1 + 1e-5 * k], axis=1)
    ys = drift + rng.normal(0.0, [0.5, 0.5, np.deg2rad(0.1)], (count, 3))
    us = np.array([1e5, 5e4, 1e6]) + rng.normal(0.0, [1e4, 1e4, 1e5], (count, 3))
    return list(ys), list(us)


def peer_observer(observer):
    """MCSimPython's observer with the reproduction's w_c, w_o, zeta, T, M and D, or None."""
    try:
        from MCSimPython.observer.nonlinobs import NonlinObs3dof
    except ImportError:
        return None
    M = np.linalg.inv(np.asarray(observer.mass_inverse))
    D = np.asarray(observer.damping_matrix)
    config = fs.Config()
    return NonlinObs3dof(DT, config.cutoff_frequency, config.wave_frequency, config.wave_damping, 1000.0, M, D)


def compiled_step(observer, y0):
    """The observer's update, output and prediction jitted over one packed vector
    [state, t, dt, y, u] -> [next state, estimate]; returns (call, buffer, state size)."""
    flat, unravel = ravel_pytree(observer.init(jnp.asarray(y0), observer.guess()))
    n_s = flat.size

    def step(packed):
        t, dt, y, u = packed[n_s], packed[n_s + 1], packed[n_s + 2 : n_s + 5], packed[n_s + 5 :]
        state = observer.update(unravel(packed[:n_s]), t, y)
        estimate = observer.output(state, y)
        state = ravel_pytree(observer.predict(state, t, y, u, dt))[0]
        return jnp.concatenate([state, *(jnp.ravel(leaf) for leaf in jax.tree.leaves(estimate))])

    buffer = np.zeros(n_s + 8)
    buffer[:n_s] = np.asarray(flat)
    return jax.jit(step), buffer, n_s


def busy_seconds() -> float | None:
    """CPU seconds all processes have used (Linux /proc/stat), or None."""
    try:
        with open("/proc/stat") as stat:
            fields = [int(x) for x in stat.readline().split()[1:]]
        return (sum(fields[:3]) + sum(fields[5:8])) / os.sysconf("SC_CLK_TCK")  # user nice system, irq softirq steal
    except (OSError, ValueError, IndexError):
        return None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=2000, help="calls per repetition")
    parser.add_argument("--repeats", type=int, default=9, help="repetitions (median and minimum printed)")
    parser.add_argument("--warmup", type=int, default=1000, help="untimed calls of each first")
    parser.add_argument("--gap-ms", type=float, default=0.0, help="also time single calls after an idle pause of this many ms (0: not)")
    parser.add_argument("--gap-calls", type=int, default=300, help="single calls of each timed after a pause")
    args = parser.parse_args()

    observer = fs.build(fs.Config(duration=10.0)).observer
    peer = peer_observer(observer)
    if peer is None:
        print("MCSimPython is not installed (pip install mcsimpython; GPL-3.0, not a lookout dependency): nothing to compare against.")
        return 0
    count = args.warmup + args.calls * args.repeats + (args.gap_calls if args.gap_ms > 0 else 0)
    ys, us = samples(count)
    times = [DT * k for k in range(count)]
    stepper = lookout.Stepper(observer, observer.guess(), ys[0], input_size=3)
    step, buffer, n_s = compiled_step(observer, ys[0])

    def run_peer(ks):
        for k in ks:
            peer.update(ys[k], us[k])

    def run_stepper(ks):
        for k in ks:
            stepper(times[k], ys[k], us[k], DT)

    def run_step(ks):
        for k in ks:
            buffer[n_s] = times[k]
            buffer[n_s + 1] = DT
            buffer[n_s + 2 : n_s + 5] = ys[k]
            buffer[n_s + 5 :] = us[k]
            buffer[:n_s] = np.asarray(step(buffer))[:n_s]

    candidates = {
        "MCSimPython NonlinObs3dof.update": run_peer,
        "lookout.Stepper.__call__": run_stepper,
        "compiled step alone (no checks)": run_step,
    }
    for run in candidates.values():
        run(range(args.warmup))
    timings: dict[str, list[float]] = {name: [] for name in candidates}
    busy, own, wall = busy_seconds(), time.process_time(), time.perf_counter()
    for r in range(args.repeats):
        ks = range(args.warmup + r * args.calls, args.warmup + (r + 1) * args.calls)
        for name, run in candidates.items():
            start = time.perf_counter()
            run(ks)
            timings[name].append((time.perf_counter() - start) / args.calls * 1e6)
    wall = time.perf_counter() - wall
    others = None if busy is None else (busy_seconds() - busy - (time.process_time() - own)) / wall

    gaps: dict[str, list[float]] = {name: [] for name in list(candidates)[:2]}
    if args.gap_ms > 0:
        first = args.warmup + args.calls * args.repeats
        for k in range(first, first + args.gap_calls):
            for name in gaps:
                time.sleep(args.gap_ms / 1000)
                start = time.perf_counter()
                candidates[name](range(k, k + 1))
                gaps[name].append((time.perf_counter() - start) * 1e6)

    estimate = stepper(times[-1] + DT, ys[-1], us[-1], DT)
    assert np.all(np.isfinite(estimate["position"])) and np.all(np.isfinite(peer.eta)), "an estimate is not finite"
    peer_median = statistics.median(timings["MCSimPython NonlinObs3dof.update"])
    print(
        f"devices: {len(jax.devices())} x {jax.devices()[0].platform}, {os.cpu_count()} cores, JAX {jax.__version__}, NumPy {np.__version__}, float64"
    )
    print(f"passive observer, Fossen & Strand 1999, Northern Clipper, one {DT:g} s sample per call; {args.repeats} x {args.calls} calls each")
    for name, values in timings.items():
        median = statistics.median(values)
        print(f"    {name:34s}: median {median:7.1f} us per call, min {min(values):7.1f}   ratio to the peer {median / peer_median:5.2f}")
    print("    target: Stepper.__call__ at most the peer's (ratio <= 1)")
    if others is not None:
        print(f"    other processes used {max(others, 0.0):.2f} of {os.cpu_count()} cores meanwhile")
    if args.gap_ms > 0:
        peer_gap = statistics.median(gaps["MCSimPython NonlinObs3dof.update"])
        print(f"one call after an idle pause of {args.gap_ms:g} ms, {args.gap_calls} calls each")
        for name, values in gaps.items():
            median = statistics.median(values)
            print(f"    {name:34s}: median {median:7.1f} us per call   ratio to the peer {median / peer_gap:5.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
