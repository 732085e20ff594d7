"""Throughput and latency beyond the ship simulation, each against a NumPy baseline
timed in the same run:

(1) the two-link arm of Calugi (2002), Section 2.3, with the reduced-order velocity
    observer (2.6)-(2.7), integrated jointly in continuous time (RK4, 1 ms): one
    run and a batch, simulated seconds per wall second, against a NumPy per-step loop
    of the same equations (the thesis's printed M, C, G);
(2) live use: one call of ``lookout.Stepper`` (the passive observer of Fossen &
    Strand 1999, one 0.1 s sample) in microseconds, against one NumPy step of the
    same observer;
(3) filtering one hour of a 10 Hz log with ``lookout.filter``, in seconds, against
    a NumPy loop of the same observer over the log.

Compilation is excluded (each is run once to warm up).
Usage: python benchmarks/observers.py [--batch 1000] [--duration 10]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import lookout

lookout.configure_cpu()  # before JAX computes anything

import jax  # noqa: E402
import numpy as np  # noqa: E402

from lookout.papers import calugi_2002_velocity_observer as calugi  # noqa: E402
from lookout.papers import fossen_strand_1999 as fs  # noqa: E402
from lookout.sim import seed_keys, simulate, simulate_batch  # noqa: E402


def arm_numpy(duration: float, step: float = 1e-3) -> float:
    """Two-link arm and velocity observer as a NumPy RK4 loop (printed M, C, G)."""
    m1, m2, l1, l2, c1, c2, g = 0.5, 0.7, 1.0, 1.5, 0.5, 0.1, 9.81
    K = np.array([5.0, 5.0])
    tau = np.array([2.0, 1.0])

    def accel(q, v):
        c2_, s2 = math.cos(q[1]), math.sin(q[1])
        M = np.array(
            [
                [m2 * l2**2 + 2 * m2 * l1 * l2 * c2_ + (m1 + m2) * l1**2, m2 * l2**2 + m2 * l1 * l2 * c2_],
                [m2 * l2**2 + m2 * l1 * l2 * c2_, m2 * l2**2],
            ]
        )
        C = np.array([[c1 - 2 * m2 * l1 * l2 * s2 * v[1], -m2 * l1 * l2 * s2 * v[1]], [m2 * l1 * l2 * s2 * v[0], c2]])
        G = np.array([m2 * l2 * g * math.cos(q[0] + q[1]) + (m1 + m2) * l1 * g * math.cos(q[0]), m2 * l2 * g * math.cos(q[0] + q[1])])
        return np.linalg.solve(M, tau - C @ v - G)

    def field(x):
        q, v, z = x[:2], x[2:4], x[4:]
        v_hat = z + K * q
        return np.concatenate([v, accel(q, v), accel(q, v_hat) - K * v_hat])

    x = np.array([-math.pi / 4, -math.pi / 4, 0.0, 0.0, -4.0 + 5.0 * math.pi / 4, -4.0 + 5.0 * math.pi / 4])
    steps = int(round(duration / step))
    start = time.perf_counter()
    for _ in range(steps):
        k1 = field(x)
        k2 = field(x + 0.5 * step * k1)
        k3 = field(x + 0.5 * step * k2)
        k4 = field(x + step * k3)
        x = x + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return duration / (time.perf_counter() - start)


def arm_lookout(duration: float, batch: int) -> tuple[float, float]:
    config = calugi.Config(duration=duration)
    scenario = calugi.build(config, "two_link")
    jax.block_until_ready(simulate(scenario, seed_keys(0, 1)[0]).truth)
    start = time.perf_counter()
    jax.block_until_ready(simulate(scenario, seed_keys(1, 1)[0]).truth)
    single = duration / (time.perf_counter() - start)
    batched = dataclasses.replace(scenario, record_every=10)
    jax.block_until_ready(simulate_batch(batched, seed_keys(0, batch)).truth)
    start = time.perf_counter()
    jax.block_until_ready(simulate_batch(batched, seed_keys(batch, batch)).truth)
    return single, batch * duration / (time.perf_counter() - start)


def passive_numpy_step(observer):
    """One 0.1 s RK4 step of the passive observer, eqs. (22)-(25), in NumPy."""
    oM_inv, oD = np.asarray(observer.mass_inverse), np.asarray(observer.damping_matrix)
    w0, zeta, k = np.asarray(observer.wave_frequency), np.asarray(observer.wave_damping), np.asarray(observer.wave_injection_gain)
    k3, kap, lam, T = (
        np.asarray(a)
        for a in (observer.position_injection_gain, observer.velocity_injection_gain, observer.bias_injection_gain, observer.bias_time_constant)
    )

    def field(z, y, tau):
        eta, nu, b, xi = z[:3], z[3:6], z[6:9], z[9:]
        e = np.where(np.isfinite(y), y - (eta + xi[3:]), 0.0)
        e[2] = (e[2] + np.pi) % (2 * np.pi) - np.pi
        c, s = math.cos(y[2]), math.sin(y[2])
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return np.concatenate(
            [
                R @ nu + k3 * e,
                oM_inv @ (-oD @ nu + R.T @ (b + kap * e) + tau),
                -b / T + lam * e,
                xi[3:] + k[:3] * e,
                -(w0**2) * xi[:3] - 2 * zeta * w0 * xi[3:] + k[3:] * e,
            ]
        )

    def step(z, y, tau, h):
        k1 = field(z, y, tau)
        k2 = field(z + 0.5 * h * k1, y, tau)
        k3_ = field(z + 0.5 * h * k2, y, tau)
        k4 = field(z + h * k3_, y, tau)
        return z + h / 6 * (k1 + 2 * k2 + 2 * k3_ + k4)

    return step


def live_and_log(rows: int) -> dict:
    scenario = fs.build(fs.Config(duration=10.0))
    observer = scenario.observer
    y, u = np.array([1.0, 2.0, 0.1]), np.zeros(3)
    stepper = lookout.Stepper(observer, observer.guess(), y, input_size=3)
    for _ in range(500):
        stepper(0.0, y, u, 0.1)
    calls = 5000
    start = time.perf_counter()
    for k in range(calls):
        stepper(0.1 * k, y, u, 0.1)
    live = (time.perf_counter() - start) / calls * 1e6

    step = passive_numpy_step(observer)
    z = np.zeros(15)
    start = time.perf_counter()
    for _ in range(calls):
        z = step(z, y, u, 0.1)
    numpy_step = (time.perf_counter() - start) / calls * 1e6

    times = np.arange(rows) * 0.1
    ys, us = np.tile(y, (rows, 1)), np.zeros((rows, 3))
    lookout.filter(observer, times, ys, us, guess=observer.guess())  # compile
    start = time.perf_counter()
    lookout.filter(observer, times, ys, us, guess=observer.guess())
    log = time.perf_counter() - start
    z = np.zeros(15)
    start = time.perf_counter()
    for k in range(rows):
        z = step(z, ys[k], us[k], 0.1)
    numpy_log = time.perf_counter() - start
    return {"live_us": live, "numpy_step_us": numpy_step, "log_s": log, "numpy_log_s": numpy_log}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0, help="simulated seconds per arm run")
    parser.add_argument("--numpy-duration", type=float, default=2.0, help="simulated seconds of the slow NumPy arm loop")
    parser.add_argument("--batch", type=int, default=1000)
    parser.add_argument("--log-rows", type=int, default=36000, help="rows of the log (36000: one hour at 10 Hz)")
    args = parser.parse_args()
    a = arm_numpy(args.numpy_duration)
    single, batch = arm_lookout(args.duration, args.batch)
    print(f"devices: {len(jax.devices())} x {jax.devices()[0].platform}, float64")
    print("(1) two-link arm + velocity observer, RK4 1 ms, continuous observer")
    print(f"    NumPy per-step loop      : {a:12.4g} simulated s / wall s")
    print(f"    lookout, one run         : {single:12.4g} simulated s / wall s   ratio {single / a:.1f}")
    print(f"    lookout, batch of {args.batch:<6d} : {batch:12.4g} simulated s / wall s   ratio {batch / a:.1f}")
    live = live_and_log(args.log_rows)
    print("(2) live: passive observer, one 0.1 s sample per call")
    print(f"    lookout.Stepper          : {live['live_us']:8.1f} us per call (target <= 20)")
    print(f"    NumPy step               : {live['numpy_step_us']:8.1f} us per step   ratio {live['numpy_step_us'] / live['live_us']:.2f}")
    print(f"(3) log of {args.log_rows} rows (10 Hz: {args.log_rows / 36000:g} h)")
    print(f"    lookout.filter           : {live['log_s']:8.3f} s (target <= 1 s for one hour)")
    print(f"    NumPy loop               : {live['numpy_log_s']:8.3f} s   ratio {live['numpy_log_s'] / live['log_s']:.1f}")


if __name__ == "__main__":
    main()
