"""Cost per sample of lookout's extended Kalman filter on the DP vessel (Northern
Clipper, bias and wave model: 15 states, position and heading at 1 Hz, the filter at
10 Hz) against filterpy's ExtendedKalmanFilter driven with the same model, in the
same run; and the EKF's batch throughput against the passive observer's.

(a) filterpy 1.4.5: per sample ``update`` when a fix is due, then ``predict`` with F and
    Q_d from the same model, computed by the same jitted JAX functions lookout uses
    (the way a filterpy user would drive our model); the model callbacks dominate;
(b) lookout, one run: the whole simulation (plant, sensor, EKF) as one jitted scan;
(c) lookout, a batch of runs (vmap), per run and sample;
(d) lookout, the passive observer (Fossen & Strand) in the same batch.

lookout's figures include simulating the plant and the sensor, filterpy's do not: the
ratios are conservative. Compilation is excluded (each lookout program runs once to warm up).
Usage: python benchmarks/kalman.py [--batch 256] [--duration 600]
"""

from __future__ import annotations

import argparse
import time

import lookout

lookout.configure_cpu()  # before JAX computes anything

import jax  # noqa: E402
import numpy as np  # noqa: E402

from lookout.scenario._toml import read  # noqa: E402
from lookout.scenario.composition import compose  # noqa: E402
from lookout.sim import keys_of_seeds, simulate, simulate_batch  # noqa: E402


def scenario(kind: str, duration: float):
    document, _ = read("examples/dp-observer.toml")
    document["simulation"]["duration"] = duration
    if kind != "passive":
        document["observer"] = {"kind": kind}
    return compose(document).scenario


def filterpy_seconds_per_sample(ekf_scenario, samples: int) -> float:
    from filterpy.kalman import ExtendedKalmanFilter as Reference

    ekf = ekf_scenario.observer
    dt = ekf_scenario.sample_period
    trajectory = simulate(ekf_scenario, keys_of_seeds([0])[0])
    ys, us = np.array(trajectory.measurement), np.array(trajectory.applied)
    step = jax.jit(lambda x, u: ekf.step(x, 0.0, u, dt))
    jacobian = jax.jit(jax.jacfwd(lambda x, u: ekf.step(x, 0.0, u, dt)))
    noise = jax.jit(lambda x, u: ekf.process_covariance(x, 0.0, u, dt))
    measure = jax.jit(lambda x: ekf.measurement(x))
    measure_jacobian = jax.jit(jax.jacfwd(lambda x: ekf.measurement(x)))
    R = np.asarray(ekf.measurement_covariance)
    reference = Reference(dim_x=ekf.initial_covariance.shape[0], dim_z=3)
    reference.x = np.array(ekf._ravel(ekf.guess()))
    reference.P = np.array(ekf.initial_covariance)
    wrap = lambda a, b: np.where(np.arange(3) == 2, (a - b + np.pi) % (2 * np.pi) - np.pi, a - b)  # noqa: E731

    def one(k):
        y, u = ys[k], us[k]
        if k % round(1.0 / dt) == 0:
            reference.update(y, lambda x: np.asarray(measure_jacobian(x)), lambda x: np.asarray(measure(x)), R=R, residual=wrap)
        x = reference.x.copy()
        reference.F = np.asarray(jacobian(x, u))
        reference.Q = np.asarray(noise(x, u))
        reference.predict()  # P = F P F' + Q (x = F x is replaced below by the model's step)
        reference.x = np.array(step(x, u))

    for k in range(20):  # compile the callbacks
        one(k)
    start = time.perf_counter()
    for k in range(20, samples):
        one(k)
    return (time.perf_counter() - start) / (samples - 20)


def lookout_seconds_per_run_sample(run_scenario, runs: int) -> float:
    keys = keys_of_seeds(list(range(runs)))
    jax.block_until_ready(simulate_batch(run_scenario, keys).truth)  # compile
    start = time.perf_counter()
    jax.block_until_ready(simulate_batch(run_scenario, keys).truth)
    return (time.perf_counter() - start) / (runs * round(run_scenario.duration / run_scenario.sample_period))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--duration", type=float, default=600.0)
    args = parser.parse_args()
    ekf = scenario("ekf", args.duration)
    passive = scenario("passive", args.duration)
    a = filterpy_seconds_per_sample(ekf, min(round(ekf.duration / ekf.sample_period), 2000))
    b = lookout_seconds_per_run_sample(ekf, 1)
    c = lookout_seconds_per_run_sample(ekf, args.batch)
    d = lookout_seconds_per_run_sample(passive, args.batch)
    print(f"(a) filterpy EKF, one run:             {a * 1e6:9.1f} us per sample")
    print(f"(b) lookout EKF, one run:              {b * 1e6:9.1f} us per sample   b/a speed {a / b:6.1f}x")
    print(f"(c) lookout EKF, batch of {args.batch:4d}:         {c * 1e6:9.2f} us per run-sample   c/a speed {a / c:6.1f}x")
    print(f"(d) lookout passive observer, batch:   {d * 1e6:9.2f} us per run-sample   EKF/passive cost {c / d:5.1f}x")


if __name__ == "__main__":
    main()
