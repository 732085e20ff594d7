"""The numbers of docs/failures.md: the ``dp-class`` reference handling on the suite
of tests/test_reference_handling.py (two DGNSS receivers, a hydroacoustic reference,
three gyrocompasses; the vessel adrift in a sea that moves it by about a metre), the
intact suite's statistics against their thresholds, each failure's rejection and
reinstatement, and examples/dp-suite.toml with ``dp-class`` in place of the weighted
mean.

    .venv/bin/python docs/failures/measure.py

About four minutes on two cores (six programs compiled; the false-alarm rate, 2 x 64
runs of an hour, takes about one of them).
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lookout.scenario.composition import compose
from lookout.sim import keys_of_seeds, simulate_batch

jax.config.update("jax_enable_x64", True)

ROOT = Path(__file__).resolve().parents[2]
DT = 0.1
GNSS = {"kind": "gnss", "noise_std": 0.7, "error_std": 0.5, "error_time_constant": 300.0}
GYRO = {"kind": "gyrocompass", "noise_std": 0.0017, "error_std": 0.0017}
FAILURES = {
    "drift": ("dgnss2", {"mode": "drift", "start": 50.0, "rate": [0.05, 0.0]}),
    "jump": ("dgnss1", {"mode": "jump", "start": 100.0, "duration": 60.0, "size": [8.0, -6.0]}),
    "dropout": ("dgnss1", {"mode": "dropout", "start": 60.0, "duration": 20.0}),
    "freeze": ("hpr", {"mode": "freeze", "start": 150.0}),
    "gyro jump": ("gyro3", {"mode": "jump", "start": 100.0, "duration": 50.0, "size": 0.05}),
    "gyro freeze": ("gyro2", {"mode": "freeze", "start": 200.0}),
}
REFERENCES = ("dgnss1", "dgnss2", "hpr")
GYROS = ("gyro1", "gyro2", "gyro3")
STATISTICS = (
    ("noise_ratio", "noise_factor"),
    ("prediction_distance", "prediction_gate"),
    ("divergence", "divergence_limit"),
    ("drift_rate", "drift_limit"),
)


def document(references: dict, duration: float, wave_amplitude: float = 1.0, failures: bool = True) -> dict:
    sensors = {
        "dgnss1": {**GNSS, "lever_arm": [30.0, 5.0]},
        "dgnss2": {**GNSS, "lever_arm": [-25.0, -4.0]},
        "hpr": {"kind": "hydroacoustic", "lever_arm": [5.0, 0.0], "depth": 100.0},
        **{name: dict(GYRO) for name in GYROS},
    }
    if failures:
        for name, failure in FAILURES.values():
            sensors[name].setdefault("failures", []).append(copy.deepcopy(failure))
    return {
        "simulation": {"duration": duration, "plant_step": DT, "sample_period": DT},
        "plant": {
            "kind": "dp-vessel",
            "bias": {"time_constant": 1000.0, "std": [2000.0, 2000.0, 50000.0]},
            "waves": {
                "kind": "linear",
                "peak_frequency": 0.8976,
                "damping_ratio": 0.1,
                "amplitude": [wave_amplitude, wave_amplitude, 0.0017 * wave_amplitude],
            },
            "initial": {"bias": [1e4, 5e3, 1e5]},
        },
        "sensors": sensors,
        "references": references,
        "observer": {"kind": "passive"},
    }


def keeping(scenario, kept: str | None):
    """Every failure but the one named ``kept`` (a key of FAILURES) moved past the end."""
    suite = scenario.sensor
    order = {name: [] for name in suite.names}
    for label, (name, _) in FAILURES.items():
        order[name].append(label)
    where = [(i, j) for i, name in enumerate(suite.names) for j, label in enumerate(order[name]) if label != kept]
    return eqx.tree_at(lambda s: [s.sensor.failures[i][j].start for i, j in where], scenario, [jnp.asarray(np.inf)] * len(where))


def changes(ds, name: str, run: int) -> str:
    accepted, reason, time = ds[f"{name}.accepted"].values[run], ds[f"{name}.rejected_by"].values[run], ds.time.values
    steps = np.flatnonzero(np.diff(accepted) != 0) + 1
    return ", ".join(f"{'in' if accepted[k] else 'out'} {time[k]:.1f} s" + ("" if accepted[k] else f" ({int(reason[k])})") for k in steps) or "none"


def block_error(ds, block: int = 20) -> np.ndarray:
    time = ds.time.values
    whole = np.abs(time - np.round(time)) < 1e-9
    error = (ds["measured_position"].values - ds["position"].values - ds["wave_position"].values)[:, whole]
    n = error.shape[1] // block * block
    means = error[:, :n].reshape(error.shape[0], -1, block, 2).mean(axis=2)
    return np.hypot(means[..., 0], means[..., 1])


def intact(wave_amplitude: float) -> None:
    composition = compose(document({"kind": "dp-class"}, 600.0, wave_amplitude, failures=False))
    handler = composition.scenario.sensor.combining
    ds = simulate_batch(composition.scenario, keys_of_seeds(list(range(8)))).to_xarray()
    rejections = sum(int((np.diff(ds[f"{name}.accepted"].values, axis=1) < 0).sum()) for name in REFERENCES + GYROS)
    print(f"intact suite, waves of {wave_amplitude:g} m (3 sigma), seeds 0-7, 600 s: {rejections} rejections")
    for statistic, threshold in STATISTICS:
        largest = max(float(ds[f"{name}.{statistic}"].values.max()) for name in REFERENCES)
        print(f"  {statistic:20s} largest {largest:.3g} (threshold {float(getattr(handler, threshold)):g})")
    largest = max(float(ds[f"{name}.divergence"].values.max()) for name in GYROS)
    print(f"  {'gyro divergence':20s} largest {largest:.3g} (threshold {float(handler.heading_divergence_limit):g})")


def false_alarms(wave_amplitude: float, seeds: int = 64, duration: float = 3600.0, chunk: int = 8) -> None:
    """The intact suite's false rejections and alarms over ``seeds`` runs of ``duration``:
    each a rejection (accepted to rejected) or a rising alarm, counted per sensor, with
    the rate's one-sided 95 % upper bound (Poisson: 3.0 / hours when none is seen)."""
    scenario = compose(document({"kind": "dp-class"}, duration, wave_amplitude, failures=False)).scenario
    counts = dict.fromkeys(REFERENCES + GYROS + ("position_alarm", "heading_alarm"), 0)
    for first in range(0, seeds, chunk):
        ds = simulate_batch(scenario, keys_of_seeds(list(range(first, first + chunk)))).to_xarray()
        for name in REFERENCES + GYROS:
            counts[name] += int((np.diff(ds[f"{name}.accepted"].values, axis=1) < 0).sum())
        for alarm in ("position_alarm", "heading_alarm"):
            raised = ds[f"references.{alarm}"].values > 0
            counts[alarm] += int(raised[:, 0].sum() + (np.diff(raised.astype(int), axis=1) > 0).sum())
    hours = seeds * duration / 3600.0
    total = sum(counts[name] for name in REFERENCES + GYROS)
    # the 95 % upper bound of a Poisson rate from k events: chi2(0.95, 2k + 2) / 2 / hours
    from scipy.stats import chi2

    bound = chi2.ppf(0.95, 2 * total + 2) / 2.0 / hours
    print(f"intact suite, waves of {wave_amplitude:g} m (3 sigma), seeds 0-{seeds - 1}, {duration:g} s each ({hours:g} h):")
    print(
        f"  false rejections {total} ({', '.join(f'{name} {counts[name]}' for name in REFERENCES + GYROS)}): {total / hours:.3g} per hour, 95 % upper bound {bound:.3g} per hour"
    )
    print(f"  alarms raised: position {counts['position_alarm']}, heading {counts['heading_alarm']}")


def failures() -> None:
    keys = keys_of_seeds([0, 1, 2, 3])
    handled = compose(document({"kind": "dp-class"}, 300.0))
    weighted = compose(document({"kind": "weighted-mean"}, 300.0))
    for label, (name, failure) in FAILURES.items():
        ds = simulate_batch(keeping(handled.scenario, label), keys).to_xarray()
        print(f"{label} of {name} from {failure['start']:g} s, seeds 0-3:")
        for run in range(4):
            print(f"  run {run}: {changes(ds, name, run)}")
        if label == "drift":
            plain = simulate_batch(keeping(weighted.scenario, label), keys).to_xarray()
            print(f"  combined position's error, 20 s means at each second: dp-class largest {np.round(block_error(ds).max(axis=1), 2)} m")
            print(f"  weighted-mean, last 20 s {np.round(block_error(plain)[:, -1], 2)} m")


def example() -> None:
    text = (ROOT / "examples" / "dp-suite.toml").read_text()
    document = tomllib.loads(text)
    document["references"] = {"kind": "dp-class"}
    ds = simulate_batch(compose(document).scenario, keys_of_seeds([0])).to_xarray()
    print("examples/dp-suite.toml with dp-class (seed 0):")
    for name in ("dgnss1", "dgnss2", "hpr", "gyro1", "gyro2"):
        print(f"  {name}: {changes(ds, name, 0)}")
    for alarm in ("references.position_alarm", "references.heading_alarm"):
        raised = ds[alarm].values[0] > 0
        first = ds.time.values[np.argmax(raised)] if raised.any() else None
        print(f"  {alarm}: {'from ' + format(first, '.1f') + ' s' if first is not None else 'never'}, {raised.mean() * 100:.0f} % of the run")
    last = ds.time.values >= ds.time.values[-1] - 60.0
    run = ds.isel(run=0)
    error = (run.measured_position - run.position - run.wave_position).values[last]
    print(f"  combined position's error, median over the last 60 s: {np.round(np.median(error, axis=0), 2)} m")
    print(f"  true position - desired, mean over the last 60 s: {np.round((run.position - run.position_desired).values[last].mean(axis=0), 2)} m")


if __name__ == "__main__":
    intact(1.0)
    intact(10.0)
    false_alarms(1.0)
    false_alarms(10.0)
    failures()
    example()
