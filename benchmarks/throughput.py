"""Throughput of the Fossen & Strand (1999) reproduction scenario, three ways, and of
the Kim (2002) closed loop the same three ways.

(a) a plain NumPy per-step loop of the same plant and observer (RK4, 0.1 s, 1 Hz
    fixes held, the way Python ship simulators are usually written);
(b) lookout, one run (jitted lax.scan);
(c) lookout, a batch of runs (vmap), counting the simulated seconds of all runs.
(d)-(f) the same for the closed loop of ``lookout reproduce kim-2002``: sliding-mode
    observer, observer backstepping, reference filter, thrust limits, model error.

Prints simulated seconds per wall second and the ratios b/a, c/a, e/d, f/d and the
closed-loop batch against the open-loop batch (f/c; target >= 0.5). Compilation is
excluded from the lookout figures (each is run once to warm up).
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

from lookout.papers import fossen_strand_1999 as fs  # noqa: E402
from lookout.papers import kim_2002  # noqa: E402
from lookout.sim import simulate, simulate_batch  # noqa: E402


def J(psi):
    """The rotation J(psi) as a NumPy matrix."""
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def wrap(angle):
    """An angle wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2 * np.pi) - np.pi


def rk4(f, x, h, *args):
    """One classical Runge-Kutta step of dx/dt = f(x, *args)."""
    k1 = f(x, *args)
    k2 = f(x + 0.5 * h * k1, *args)
    k3 = f(x + 0.5 * h * k2, *args)
    k4 = f(x + h * k3, *args)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


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
    k3, kap, lam, oT = (
        np.asarray(a) for a in (obs.position_injection_gain, obs.velocity_injection_gain, obs.bias_injection_gain, obs.bias_time_constant)
    )
    noise_std = np.asarray(sensor.noise_std)
    rng = np.random.default_rng(seed)
    h = scenario.plant_step

    def plant_f(x, tau, noise):
        eta, nu, b, xi = x[:3], x[3:6], x[6:9], x[9:]
        R = J(eta[2])
        return np.concatenate(
            [
                R @ nu,
                M_inv @ (tau + R.T @ b - D @ nu),
                -b / T_b + psi_gain * noise[:3],
                xi[3:],
                -(w0**2) * xi[:3] - 2 * zeta * w0 * xi[3:] + sigma * noise[3:],
            ]
        )

    def obs_f(z, y, tau):
        eta, nu, b, xi = z[:3], z[3:6], z[6:9], z[9:]
        e = y - (eta + xi[3:])
        e[2] = wrap(e[2])
        R = J(y[2])
        return np.concatenate(
            [
                R @ nu + k3 * e,
                oM_inv @ (-oD @ nu + R.T @ (b + kap * e) + tau),
                -b / oT + lam * e,
                xi[3:] + k[:3] * e,
                -(ow0**2) * xi[:3] - 2 * ozeta * ow0 * xi[3:] + k[3:] * e,
            ]
        )

    x = np.zeros(15)
    x[6:9] = [1e4, 5e3, 1e5]
    z = np.zeros(15)
    y = np.zeros(3)
    steps = int(round(duration / h))
    start = time.perf_counter()
    for i in range(steps):
        t = i * h
        if i % 10 == 0:
            y = x[:3] + x[12:15] + noise_std * rng.standard_normal(3)
            y[2] = wrap(y[2])
        tau = 1000.0 * np.sin(np.array([0.05, 0.1, 0.07]) * t)
        z_next = rk4(obs_f, z, h, y, tau)
        x = rk4(plant_f, x, h, tau, rng.standard_normal(6) / np.sqrt(h))
        z = z_next
    return duration / (time.perf_counter() - start)


def numpy_closed_loop(scenario, duration: float, seed: int = 0) -> float:
    """Plain NumPy: the Kim (2002) closed loop of ``scenario``, one Python iteration per step."""
    plant, sliding, sensor, control, ref = scenario.plant, scenario.observer, scenario.sensor, scenario.controller, scenario.reference
    obs = sliding.passive
    M, M_inv, D = (np.asarray(a) for a in (plant.vessel.mass_matrix, plant.vessel.mass_inverse, plant.vessel.damping_matrix))
    T_b, psi_gain = np.asarray(plant.bias.time_constant), np.asarray(plant.bias.noise_gain)
    w0, zeta, sigma = (np.asarray(a) for a in (plant.waves.peak_frequency, plant.waves.damping_ratio, plant.waves.intensity))
    dist = plant.disturbance
    f_const, f_amp, f_period = np.asarray(dist.constant), np.asarray(dist.amplitude), float(dist.period)
    oM, oM_inv, oD = np.asarray(obs.mass_matrix), np.asarray(obs.mass_inverse), np.asarray(obs.damping_matrix)
    ow0, ozeta, k = np.asarray(obs.wave_frequency), np.asarray(obs.wave_damping), np.asarray(obs.wave_injection_gain)
    k3, kap, lam, oT = (
        np.asarray(a) for a in (obs.position_injection_gain, obs.velocity_injection_gain, obs.bias_injection_gain, obs.bias_time_constant)
    )
    kbar, eps = np.asarray(sliding.switching_gain), np.asarray(sliding.boundary_layer)
    k_i, c1, c2, p1, d = (
        np.asarray(a) for a in (control.integral_gain, control.position_gain, control.velocity_gain, control.coupling_gain, control.damping_weights)
    )
    limit = np.asarray(scenario.actuator.limit)
    noise_std = np.asarray(sensor.noise_std)
    bandwidth = np.asarray(ref.bandwidth)
    times, setpoints = np.asarray(ref.schedule_times), np.asarray(ref.setpoints)
    rng = np.random.default_rng(seed)
    h = scenario.plant_step

    def plant_f(x, tau, noise, t):
        eta, nu, b, xi = x[:3], x[3:6], x[6:9], x[9:]
        R = J(eta[2])
        force = tau + f_const + f_amp * np.sin(2 * np.pi * t / f_period)
        return np.concatenate(
            [
                R @ nu,
                M_inv @ (force + R.T @ b - D @ nu),
                -b / T_b + psi_gain * noise[:3],
                xi[3:],
                -(w0**2) * xi[:3] - 2 * zeta * w0 * xi[3:] + sigma * noise[3:],
            ]
        )

    def obs_f(z, y, tau):
        eta, nu, b, xi = z[:3], z[3:6], z[6:9], z[9:]
        e = y - (eta + xi[3:])
        e[2] = wrap(e[2])
        R = J(y[2])
        switching = kbar * np.clip(e / eps, -1.0, 1.0)
        return np.concatenate(
            [
                R @ nu + k3 * e + switching,
                oM_inv @ (-oD @ nu + R.T @ (b + kap * e) + tau),
                -b / oT + lam * e,
                xi[3:] + k[:3] * e,
                -(ow0**2) * xi[:3] - 2 * ozeta * ow0 * xi[3:] + k[3:] * e,
            ]
        )

    # reference filter: exact discretization of the third-order critically damped model
    A = np.zeros((3, 3, 3))
    for i, w in enumerate(np.broadcast_to(bandwidth, 3)):
        A[i] = [[0, 1, 0], [0, 0, 1], [-(w**3), -3 * w**2, -3 * w]]
    from scipy.linalg import expm

    Phi = np.stack([expm(A[i] * h) for i in range(3)])
    r_state = np.zeros((3, 3))
    r_state[:, 0] = setpoints[0]

    x = np.zeros(15)
    x[6:9] = [1e4, 5e3, 1e5]
    z = np.zeros(15)
    y = np.zeros(3)
    integral = np.zeros(3)
    d1 = d[:3] * (k3**2 + kbar**2)
    c1d1 = c1 + d1
    wave_row = ow0[2] ** 4 + (2 * ozeta[2] * ow0[2]) ** 2
    steps = int(round(duration / h))
    start = time.perf_counter()
    for i in range(steps):
        t = i * h
        if i % 10 == 0:
            y = x[:3] + x[12:15] + noise_std * rng.standard_normal(3)
            y[2] = wrap(y[2])
        setpoint = setpoints[max(0, np.searchsorted(times, t, side="right") - 1)]
        eta_d, eta_d1, eta_d2 = r_state[:, 0].copy(), r_state[:, 1].copy(), r_state[:, 2].copy()
        error = setpoint - r_state[:, 0]
        error[2] = wrap(error[2])
        target = r_state[:, 0] + error
        r_state = np.einsum("ijk,ik->ij", Phi, r_state - np.stack([target, np.zeros(3), np.zeros(3)], axis=1)) + np.stack(
            [target, np.zeros(3), np.zeros(3)], axis=1
        )
        r_state[2, 0] = wrap(r_state[2, 0])
        # observer backstepping (Kim 2002, (25) as in lookout.controllers.backstepping)
        eta_hat, nu_hat, b_hat = z[:3], z[3:6], z[6:9]
        R = J(y[2])
        e = eta_hat - eta_d
        e[2] = wrap(e[2])
        z1 = e + k_i * integral
        z2 = R @ nu_hat + c1d1 * z1 - eta_d1 + k_i * e
        omega1 = R @ oM_inv @ R.T * kap[None, :] + np.diag((c1d1 + k_i) * k3)
        jq = R @ np.array([-nu_hat[1], nu_hat[0], 0.0])
        d2 = d[3:] * (np.sum(omega1**2, axis=1) + jq**2 * (1 + wave_row) + ((c1d1 + k_i) * kbar) ** 2)
        mu3 = nu_hat[2] - ow0[2] ** 2 * z[11] - 2 * ozeta[2] * ow0[2] * z[14]
        bracket = p1 * z1 - c1d1**2 * z1 + (c1d1 + c2 + d2) * z2 + k_i * (R @ nu_hat - eta_d1) - eta_d2
        tau = -oM @ (mu3 * np.array([-nu_hat[1], nu_hat[0], 0.0])) + oD @ nu_hat - R.T @ b_hat - oM @ (R.T @ bracket)
        integral = integral + scenario.sample_period * e
        applied = np.clip(tau, -limit, limit)
        z_next = rk4(obs_f, z, h, y, applied)
        x = rk4(plant_f, x, h, applied, rng.standard_normal(6) / np.sqrt(h), t)
        z = z_next
        z[2] = wrap(z[2])
        x[2] = wrap(x[2])
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
    loop_config = kim_2002.Config(duration=args.duration, sweep=False)
    loop = kim_2002.build(loop_config)
    d = numpy_closed_loop(kim_2002.build(kim_2002.Config(duration=args.numpy_duration, sweep=False)), args.numpy_duration)
    e = lookout_single(loop, args.duration)
    f = lookout_batch(dataclasses.replace(loop, record_every=args.record_every), args.duration, args.batch)
    print(f"devices: {len(jax.devices())} x {jax.devices()[0].platform}, float64, plant step 0.1 s, observer 10 Hz, fixes 1 Hz")
    print("open loop: Fossen & Strand (1999) passive observer, sinusoidal tau")
    print(f"(a) NumPy per-step loop      : {a:12.4g} simulated s / wall s")
    print(f"(b) lookout, one run         : {b:12.4g} simulated s / wall s   b/a = {b / a:.1f}")
    print(f"(c) lookout, batch of {args.batch:<6d} : {c:12.4g} simulated s / wall s   c/a = {c / a:.1f}")
    print("closed loop: Kim (2002) sliding-mode observer, backstepping, reference filter, thrust limits")
    print(f"(d) NumPy per-step loop      : {d:12.4g} simulated s / wall s")
    print(f"(e) lookout, one run         : {e:12.4g} simulated s / wall s   e/d = {e / d:.1f}")
    print(f"(f) lookout, batch of {args.batch:<6d} : {f:12.4g} simulated s / wall s   f/d = {f / d:.1f}   f/c = {f / c:.2f} (target >= 0.5)")


if __name__ == "__main__":
    main()
