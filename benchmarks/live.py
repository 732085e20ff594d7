"""Live data: latency from a sentence's arrival to its estimate leaving, and replay speed.

(1) Latency: ``lookout.live.live`` on a UDP socket on 127.0.0.1, fed by a sender
    thread at the example's rates (THS at 10 Hz, GGA at 1 Hz, each in its own datagram),
    each estimate published as a JSON line over UDP. Two numbers per step: from the
    arrival of the heading sentence that takes the step to the estimate leaving (the
    session steps on heading), and from the arrival of every sentence a step used.
(2) Replay speed: one simulated hour of the example scenario written as a log
    (``lookout write-log``'s writer), replayed as fast as it goes, CSV and NMEA, with
    and without the first call's compilation; speed = log seconds / wall seconds.

Run: ``python benchmarks/live.py [--seconds 30] [--hours 1]``; results go to
docs/benchmarks.md by hand.
"""

from __future__ import annotations

import argparse
import socket
import tempfile
import threading
import time
import tomllib
import warnings
from pathlib import Path

import lookout

lookout.configure_cpu()
import jax  # noqa: E402

jax.config.update("jax_cpu_enable_async_dispatch", False)  # as lookout live sets it

import numpy as np  # noqa: E402

from lookout.io.geodesy import LocalFrame  # noqa: E402
from lookout.io.simulated_log import gga, ths, write_simulated_log  # noqa: E402
from lookout.live.output import Publisher  # noqa: E402
from lookout.live.run import live, open_source, replay  # noqa: E402
from lookout.live.session import Session  # noqa: E402
from lookout.scenario.composition import compose, simulate  # noqa: E402

ROOT = Path(__file__).parents[1]
ORIGIN = LocalFrame(63.44, 10.40)


def composition(duration: float):
    document = tomllib.loads((ROOT / "examples" / "live-dp.toml").read_text())
    document["simulation"]["duration"] = duration
    return compose(document)


def latency(seconds: float) -> dict:
    scenario = composition(1.0).scenario
    session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN)
    session.warm_up()
    source = open_source("udp://127.0.0.1:0")
    port = source[1].getsockname()[1]
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    publisher = Publisher(f"udp://127.0.0.1:{sink.getsockname()[1]}", frame_of=lambda: session.frame)
    rng = np.random.default_rng(0)

    def send():
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        start = time.time()
        for k in range(int(seconds * 10)):
            # a fix 40-90 ms before the heading of the same step, as in the example log
            due = start + 0.1 * k
            if k % 10 == 0:
                time.sleep(max(0.0, due - 0.06 - time.time()))
                latitude, longitude, _ = ORIGIN.geodetic(rng.normal(0, 0.5), rng.normal(0, 0.5), 0.0)
                sender.sendto((gga(k * 0.1, float(latitude), float(longitude)) + "\r\n").encode(), ("127.0.0.1", port))
            time.sleep(max(0.0, due - 0.02 - time.time()))
            sender.sendto((ths(rng.normal(0, 0.1)) + "\r\n").encode(), ("127.0.0.1", port))
        sender.close()

    steps = []

    def emit(block):
        publisher(block)
        steps.append((time.time(), float(block.time[-1])))

    thread = threading.Thread(target=send)
    thread.start()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        outcome = live(session, source, emit=emit, idle=1.0)
    thread.join()
    sink.close()
    trigger = outcome.latency.percentiles((50, 99, 100))
    return {"steps": outcome.steps, "trigger": trigger, "step": outcome.processing.percentiles((50, 99, 100))}


def replay_speed(hours: float) -> dict:
    duration = hours * 3600.0
    made = time.perf_counter()
    comp = composition(duration)
    ds = simulate(comp).to_xarray()
    folder = Path(tempfile.mkdtemp())
    paths = write_simulated_log(ds, folder, outage=(duration / 2, 30.0))
    made = time.perf_counter() - made
    scenario = comp.scenario
    results = {"log_seconds": duration, "made_seconds": made}
    for kind in ("csv", "nmea"):
        for run in ("first", "second"):
            session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN, batch=4096)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                started = time.perf_counter()
                outcome = replay(session, paths[kind], thrust=paths["thrust"])
                wall = time.perf_counter() - started
            results[f"{kind} {run}"] = (wall, duration / wall, outcome.steps)
    # without the thrust log (NMEA only, as a user without thrust feedback replays)
    session = Session(scenario.observer, scenario.sample_period, guess=scenario.initial_estimate, frame=ORIGIN, batch=4096)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        started = time.perf_counter()
        replay(session, paths["nmea"])
        wall = time.perf_counter() - started
    results["nmea, no thrust"] = (wall, duration / wall, session.steps)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="live: seconds of sending")
    parser.add_argument("--hours", type=float, default=1.0, help="replay: hours of log")
    args = parser.parse_args()
    measured = latency(args.seconds)
    print(f"(1) live over UDP, {measured['steps']} steps:")
    print("    heading arrival -> estimate sent: " + ", ".join(f"p{p} {v * 1e3:.3f} ms" for p, v in measured["trigger"].items()))
    print("    the step alone (Stepper call):    " + ", ".join(f"p{p} {v * 1e3:.3f} ms" for p, v in measured["step"].items()))
    speed = replay_speed(args.hours)
    print(f"(2) replay of {speed['log_seconds']:.0f} s of log (made in {speed['made_seconds']:.0f} s):")
    for key, value in speed.items():
        if isinstance(value, tuple):
            wall, ratio, steps = value
            print(f"    {key:16s}: {wall:7.2f} s, {ratio:8.0f}x real time, {steps} steps ({wall / steps * 1e6:.1f} us per step)")


if __name__ == "__main__":
    main()
