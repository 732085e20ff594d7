"""Cost of tuning by gradient (lookout.tuning) on the Fossen & Strand (1999) scenario:
one gradient of the objective over a batch of training runs against one forward batch
of the same runs (the objective alone), both compiled, in the same run; and the time to
tune (wall, compilation included) with ``lookout.tuning.tune.tune``.

Usage: python benchmarks/tuning.py [--seeds 32] [--duration 1500] [--steps 20]
"""

from __future__ import annotations

import argparse
import time

import lookout

lookout.configure_cpu()  # before JAX computes anything

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from lookout.composition import compose  # noqa: E402
from lookout.registry import preset  # noqa: E402
from lookout.sim import keys_of_seeds  # noqa: E402
from lookout.tuning.families import family_of  # noqa: E402
from lookout.tuning.tune import _objective_function, parse_objective, tune  # noqa: E402


def best_of(function, repeats: int = 3) -> float:
    jax.block_until_ready(function())  # compiles
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(function())
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=32)
    parser.add_argument("--duration", type=float, default=1500.0)
    parser.add_argument("--steps", type=int, default=20)
    options = parser.parse_args()
    document = preset("fossen-strand-1999", "paper")
    document["simulation"]["duration"] = options.duration
    scenario = compose(document).scenario
    family = family_of(scenario)[0]
    objective, metrics = parse_objective("rms_error:bias_force", scenario)
    value = _objective_function(scenario, family, objective, metrics, None)
    keys = keys_of_seeds(list(range(options.seeds)))
    theta = jnp.asarray(family.theta(family.current(scenario)))
    forward = jax.jit(lambda t: value(family.gains(t), keys)[0])
    gradient = jax.jit(jax.value_and_grad(lambda t: value(family.gains(t), keys)[0]))
    seconds_forward = best_of(lambda: forward(theta))
    seconds_gradient = best_of(lambda: gradient(theta))
    print(f"forward batch of {options.seeds} runs x {options.duration:g} s:  {seconds_forward:.3f} s")
    print(f"gradient (value and grad), same runs:  {seconds_gradient:.3f} s   gradient/forward {seconds_gradient / seconds_forward:.2f}x")
    start = time.perf_counter()
    result = tune(scenario, "rms_error:bias_force", train_seeds=list(range(options.seeds)), test_seeds=list(range(options.seeds, 2 * options.seeds)),
                  steps=options.steps, learning_rate=0.2, say=lambda text: None)
    wall = time.perf_counter() - start
    print(f"time to tune ({len(result.steps) - 1} steps, {result.stopped or 'all steps'}; compile and held-out runs included): {wall:.1f} s")


if __name__ == "__main__":
    main()
