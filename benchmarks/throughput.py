"""Throughput of the Fossen & Strand (1999) reproduction scenario, three ways, one run.

(a) a plain NumPy per-step loop of the same plant and observer (RK4, 0.1 s, 1 Hz
    fixes held, the way Python ship simulators are usually written);
(b) lookout, one run (jitted lax.scan);
(c) lookout, a batch of runs (vmap), counting the simulated seconds of all runs.

Prints simulated seconds per wall second and the ratios b/a and c/a. Compilation
is excluded from (b) and (c) (each is run once to warm up).
Usage: python benchmarks/throughput.py [--batch 1000] [--duration 3000]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import lookout

lookout.configure_cpu()  # before JAX computes anything

import jax  # noqa: E402
import numpy as np  # noqa: E402

from lookout.papers import fossen_strand_1999 as fs
from lookout.sim import simulate, simulate_batch  # noqa: E402


def numpy_loop(scenario, duration: float, seed: int = 0) -> float:
    """Plain NumPy: the same equations, one Python iteration per 0.1 s step."""
    plant, obs, sensor = scenario.plant, scenario.observer, scenario.sensor
    M_inv = np.asarray(plant.vessel.mass_inverse)
    D = np.asarray(plant.vessel.damping_matrix)
    T_b = np.asarray(plant.bias.time_constant)
    psi_gain = np.asarray(plant.bias.noise_gain)
    w0, zeta, sigma = (np.asarray(a) for a in (plant.waves.peak_frequency, plant.waves.damping_ratio, plant.waves.intensity))
    oM_inv, oD = np.asarray(obs.mass_inverse), np.asarray(obs.damping_matrix)
    ow0, ozeta, k = np.asarray(obs.wave_frequency), np.asarray(obs.wave_damping), np.asarray(obs.wave_injection_gain)
    k3, kap, lam, oT = (np.asarray(a) for a in (obs.position_injection_gain, obs.velocity_injection_gain, obs.bias_injection_gain, obs.bias_time_constant))
    noise_std = np.asarray(sensor.noise_std)
    rng = np.random.default_rng(seed)
    h = scenario.plant_step

    def J(psi):
        c, s = np.cos(psi), np.sin(psi)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def plant_f(x, tau, noise):
        eta, nu, b, xi = x[:3], x[3:6], x[6:9], x[9:]
        R = J(eta[2])
        return np.concatenate([R @ nu, M_inv @ (tau + R.T @ b - D @ nu), -b / T_b + psi_gain * noise[:3], xi[3:], -(w0**2) * xi[:3] - 2 * zeta * w0 * xi[3:] + sigma * noise[3:]])

    def obs_f(z, y, tau):
        eta, nu, b, xi = z[:3], z[3:6], z[6:9], z[9:]
        e = y - (eta + xi[3:])
        e[2] = (e[2] + np.pi) % (2 * np.pi) - np.pi
        R = J(y[2])
        return np.concatenate([R @ nu + k3 * e, oM_inv @ (-oD @ nu + R.T @ (b + kap * e) + tau), -b / oT + lam * e, xi[3:] + k[:3] * e, -(ow0**2) * xi[:3] - 2 * ozeta * ow0 * xi[3:] + k[3:] * e])

    def rk4(f, x, *args):
        k1 = f(x, *args); k2 = f(x + 0.5 * h * k1, *args); k3_ = f(x + 0.5 * h * k2, *args); k4 = f(x + h * k3_, *args)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3_ + k4)

    x = np.zeros(15); x[6:9] = [1e4, 5e3, 1e5]
    z = np.zeros(15)
    y = np.zeros(3)
    steps = int(round(duration / h))
    start = time.perf_counter()
    for i in range(steps):
        t = i * h
        if i % 10 == 0:
            y = x[:3] + x[12:15] + noise_std * rng.standard_normal(3)
            y[2] = (y[2] + np.pi) % (2 * np.pi) - np.pi
        tau = 1000.0 * np.sin(np.array([0.05, 0.1, 0.07]) * t)
        z_next = rk4(obs_f, z, y, tau)
        x = rk4(plant_f, x, tau, rng.standard_normal(6) / np.sqrt(h))
        z = z_next
    return duration / (time.perf_counter() - start)


def lookout_single(scenario, duration: float) -> float:
    jax.block_until_ready(simulate(scenario, jax.random.key(0)).truth)  # compile
    start = time.perf_counter()
    jax.block_until_ready(simulate(scenario, jax.random.key(1)).truth)
    return duration / (time.perf_counter() - start)


def lookout_batch(scenario, duration: float, batch: int) -> float:
    keys = jax.random.split(jax.random.key(2), batch)
    jax.block_until_ready(simulate_batch(scenario, keys).truth)  # compile
    start = time.perf_counter()
    jax.block_until_ready(simulate_batch(scenario, jax.random.split(jax.random.key(3), batch)).truth)
    return batch * duration / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=3000.0, help="simulated seconds per run")
    parser.add_argument("--numpy-duration", type=float, default=300.0, help="simulated seconds for the slow NumPy loop")
    parser.add_argument("--batch", type=int, default=1000)
    parser.add_argument("--record-every", type=int, default=100, help="decimation of recorded samples in the batch")
    args = parser.parse_args()
    single = fs.build(fs.Config(duration=args.duration))
    batched = fs.build(fs.Config(duration=args.duration))
    batched = dataclasses.replace(batched, record_every=args.record_every)
    a = numpy_loop(single, args.numpy_duration)
    b = lookout_single(single, args.duration)
    c = lookout_batch(batched, args.duration, args.batch)
    print(f"devices: {len(jax.devices())} x {jax.devices()[0].platform}, float64, plant step 0.1 s, observer 10 Hz, fixes 1 Hz")
    print(f"(a) NumPy per-step loop      : {a:12.4g} simulated s / wall s")
    print(f"(b) lookout, one run         : {b:12.4g} simulated s / wall s   b/a = {b / a:.1f}")
    print(f"(c) lookout, batch of {args.batch:<6d} : {c:12.4g} simulated s / wall s   c/a = {c / a:.1f}")


if __name__ == "__main__":
    main()
