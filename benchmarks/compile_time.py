"""Time a user waits before the first sample: the first simulate call of a fresh process.

Builds the Fossen & Strand (1999) scenario (600 s) and times the first ``simulate`` of
one run and of a batch of two, with a progress callback (the CLI's path: the run is
split into about 20 segments), so the time is dominated by tracing and compiling.
Run it in a fresh process; compare versions with PYTHONPATH=<checkout>/src.

Usage: python benchmarks/compile_time.py
"""

import time

import lookout

lookout.configure_cpu()

import jax  # noqa: E402

from lookout.papers import fossen_strand_1999 as fs  # noqa: E402


def main() -> None:
    for runs in (1, 2):
        scenario = fs.build(fs.Config(duration=600.0))
        keys = jax.random.split(jax.random.key(0), runs)
        start = time.perf_counter()
        if runs == 1:
            trajectory = lookout.simulate(scenario, keys[0], progress=lambda done, total: None)
        else:
            trajectory = lookout.simulate_batch(scenario, keys, progress=lambda done, total: None)
        jax.block_until_ready(trajectory.state)
        print(f"{runs} run(s): first simulate with progress {time.perf_counter() - start:.2f} s")


if __name__ == "__main__":
    main()
