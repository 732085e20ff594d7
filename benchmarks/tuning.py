"""Cost of tuning by gradient (lookout.tuning): one gradient of the objective over a batch
of training runs against one forward batch of the same runs (the objective alone), both
compiled, in the same run; and the time to tune (wall, compilation included) with
``lookout.tuning.tune.tune``.

Usage: python benchmarks/tuning.py [--case passive] [--seeds 32] [--duration S] [--steps 20] [--no-tune]

Cases (each family's scenario; --duration overrides the case's):
passive (Fossen & Strand 1999, rms_error:bias_force), ekf (the same runs, Q and R),
kim (examples/kim-closed-loop.toml: the sliding-mode observer and its backstepping
controller), wondergem (Cybership II in basin waves, the estimate started at the fix),
adaptive-dp (calugi-2003:satisfying, observer and controller), velocity (the two-link arm).
"""

from __future__ import annotations

import argparse
import time

import lookout

lookout.configure_cpu()  # before JAX computes anything

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from lookout.scenario.composition import compose  # noqa: E402
from lookout.scenario.registry import preset  # noqa: E402
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


#: Each case's run length (s): 1500 s for the passive one, the others about a minute of
#: compilation and runs each.
DURATIONS = {"passive": 1500.0, "ekf": 600.0, "kim": 700.0, "wondergem": 120.0, "adaptive-dp": 600.0, "velocity": 2.0}


def _case(name: str) -> tuple[dict, str]:
    """(scenario document, objective) of a case."""
    from lookout.scenario._toml import read

    if name in ("passive", "ekf"):
        document = preset("fossen-strand-1999", "paper")
        if name == "ekf":
            document["observer"] = {"kind": "ekf"}
        return document, "rms_error:bias_force" if name == "passive" else "rms_error:position + 10*rms_error:velocity"
    if name == "kim":
        return read("examples/kim-closed-loop.toml")[0], "rms_tracking:position + rms_error:position"
    if name == "wondergem":
        document = preset("wondergem-2009", "basin-waves")
        document["observer"]["initial"] = {"eta": document["plant"]["initial"]["eta"], "velocity": [0.0, 0.0, 0.0]}
        return document, "rms_tracking:position + rms_error:velocity"
    if name == "adaptive-dp":
        return preset("calugi-2003", "satisfying"), "rms_tracking:position + rms_error:position"
    if name == "velocity":
        return read("examples/velocity-two-link-arm.toml")[0], "rms_error:joint_rate"
    raise SystemExit(f"--case: no case {name!r}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--case", default="passive")
    parser.add_argument("--seeds", type=int, default=32)
    parser.add_argument("--duration", type=float, default=None, help="default: the case's (DURATIONS)")
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--no-tune", action="store_true", help="the gradient's cost only")
    options = parser.parse_args()
    document, objective_text = _case(options.case)
    options.duration = options.duration or DURATIONS[options.case]
    document["simulation"]["duration"] = options.duration
    scenario = compose(document).scenario
    family, start, _ = family_of(scenario)
    objective, metrics = parse_objective(objective_text, scenario)
    value = _objective_function(scenario, family, objective, metrics, None)
    keys = keys_of_seeds(list(range(options.seeds)))
    theta = jnp.asarray(family.theta(start))
    forward = jax.jit(lambda t: value(family.gains(t), keys)[0])
    gradient = jax.jit(jax.value_and_grad(lambda t: value(family.gains(t), keys)[0]))
    seconds_forward = best_of(lambda: forward(theta))
    seconds_gradient = best_of(lambda: gradient(theta))
    print(f"{options.case}: forward batch of {options.seeds} runs x {options.duration:g} s:  {seconds_forward:.3f} s")
    print(f"gradient (value and grad), same runs:  {seconds_gradient:.3f} s   gradient/forward {seconds_gradient / seconds_forward:.2f}x")
    if options.no_tune:
        return
    started = time.perf_counter()
    result = tune(
        scenario,
        objective_text,
        train_seeds=list(range(options.seeds)),
        test_seeds=list(range(options.seeds, 2 * options.seeds)),
        steps=options.steps,
        learning_rate=0.2,
        say=lambda text: None,
    )
    wall = time.perf_counter() - started
    print(f"time to tune ({len(result.steps) - 1} steps, {result.stopped or 'all steps'}; compile and held-out runs included): {wall:.1f} s")


if __name__ == "__main__":
    main()
