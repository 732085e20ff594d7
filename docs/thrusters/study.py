"""The allocation study of docs/thrusters.md: the seed papers' closed loops and the
closed-loop observer ranking, rerun with thrusters instead of generalized forces.

    .venv/bin/python docs/thrusters/study.py            # make thruster-study
    .venv/bin/python docs/thrusters/study.py --quick    # shorter runs, fewer seeds
    .venv/bin/python docs/thrusters/study.py --turning out/thrusters-dp/run.nc   # a run's azimuths
    .venv/bin/python docs/thrusters/study.py --example steering_bias=0.2        # the example, an option changed
    .venv/bin/python docs/thrusters/study.py --loops kim-2002 --qp steering_bias=0.2   # the QP's cells, options changed

For each loop, each observer that fits it, and each actuation (the ideal actuator;
per-axis saturation at the layout's reach; the thrusters with the weighted
pseudo-inverse and with the QP), the same seeds are run and their metrics
accumulated in the simulation (lookout.scenario.metrics.summarize). Writes
docs/thrusters/study.csv (every run), docs/thrusters/table.md (medians and the
rankings) and docs/thrusters/kim-2002.png (Kim's loop with the passive observer, seed
0, each actuation: the position tracking error and the yaw moment).
"""

from __future__ import annotations

import argparse
import copy
import itertools
import sys
import time
import tomllib
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from lookout.actuators import Allocator, ThrusterLayout  # noqa: E402
from lookout.scenario import composition  # noqa: E402
from lookout.scenario.metrics import resolve, summarize  # noqa: E402
from lookout.scenario.registry import preset  # noqa: E402
from lookout.sim import keys_of_seeds  # noqa: E402
from lookout.studies.benchmark import shipped_spec  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def reach_limits(layout: ThrusterLayout) -> list[float]:
    """The per-axis saturation that matches the layout: each axis's largest |tau| alone."""
    allocator = Allocator(layout)
    reach = np.asarray(allocator.reach) * allocator.force_scale
    return [float(v) for v in np.max(np.abs(reach), axis=0)]


def actuations(layout_kind: str) -> dict[str, dict]:
    layout = {"supply-vessel": ThrusterLayout.supply_vessel, "cybership-ii": ThrusterLayout.cybership_ii}[layout_kind]()
    return {
        "ideal": {"kind": "ideal"},
        "per-axis limits": {"kind": "thrust-limits", "limit": reach_limits(layout)},
        "thrusters, pseudo-inverse": {"kind": "thrusters", "allocation": "pseudo-inverse", "layout": {"kind": layout_kind}},
        "thrusters, QP": {"kind": "thrusters", "allocation": "qp", "layout": {"kind": layout_kind}},
    }


def kim_loop() -> dict:
    with open(ROOT / "examples" / "kim-closed-loop.toml", "rb") as handle:
        return tomllib.load(handle)


def cybership_observers() -> dict[str, dict]:
    with open(shipped_spec("cybership-ii"), "rb") as handle:
        return tomllib.load(handle)["observers"]


def wondergem_loop() -> dict:
    """The basin case with waves (JONSWAP, Hs 1 cm; 10 Hz fixes with the basin's noise),
    every observer sampled at 20 Hz, recorded at 10 Hz."""
    document = preset("wondergem-2009", "basin-waves")
    document["simulation"].update(record_every=2)
    return document


LOOPS = {
    "kim-2002": {
        "title": "Kim (2002): observer backstepping on the Northern Clipper, setpoint changes of 30 m, 1400 s",
        "document": kim_loop,
        "observers": lambda: {
            "sliding-mode (Kim)": None,  # the example's own
            "passive (Fossen & Strand rule)": {"kind": "passive", "design": "fossen-strand-1999"},
        },
        "layout": "supply-vessel",
        "metrics": ["rms_tracking:position", "max_tracking:position", "rms_tracking:heading", "rms_error:velocity"],
        "seeds": 8,
    },
    "calugi-2003": {
        "title": "Calugi et al. (2003): adaptive observer and vectorial backstepping, setpoints of 10 m, 1200 s",
        "document": lambda: preset("calugi-2003", "satisfying"),
        "observers": lambda: {"adaptive (Calugi)": None},
        "layout": "supply-vessel",
        "metrics": ["rms_tracking:position", "max_tracking:position", "rms_tracking:heading", "rms_error:velocity"],
        "seeds": 8,
    },
    "wondergem-2009": {
        "title": "Wondergem et al. (2009): the tracking scheme on Cybership II in the basin's waves, the first 300 s of the ellipse, every observer of the Cybership II benchmark",
        "document": wondergem_loop,
        "observers": lambda: {"earth-fixed (Wondergem)": None} | {k: v for k, v in cybership_observers().items() if k != "earth-fixed"},
        "layout": "cybership-ii",
        "metrics": ["rms_tracking:position", "max_tracking:position", "rms_tracking:heading", "rms_error:velocity"],
        "seeds": 4,
        "duration": 300.0,  # 7 s of RK4 at 0.01 s per run and seed: the whole 714 s is left to make thruster-study-full
    },
}
THRUSTER_METRICS = ["mean_power:thrust", "time_at_limit:thrust"]


def run_case(document: dict, seeds: int, metrics: list[str]):
    built = composition.compose(document)
    scenario = built.scenario
    names = metrics + (THRUSTER_METRICS if document["actuator"]["kind"] == "thrusters" else [])
    resolved = resolve(names, scenario)
    keys = keys_of_seeds(range(seeds))
    started = time.perf_counter()
    result = summarize(scenario, keys, resolved, after=0.0)
    return result, time.perf_counter() - started


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="runs of a third of the length and 2 seeds")
    parser.add_argument("--seeds", type=int, default=None, help="seeds per cell instead of each loop's own")
    parser.add_argument("--full", action="store_true", help="every loop over its paper's whole duration")
    parser.add_argument("--loops", nargs="*", default=list(LOOPS))
    parser.add_argument("--figure-only", action="store_true", help="draw kim-2002.png alone")
    parser.add_argument(
        "--one-limit-at-a-time",
        action="store_true",
        help="Calugi et al. (2003)'s loop, 400 s, seed 0, through the supply vessel with one of its limits at a time",
    )
    parser.add_argument(
        "--turning",
        nargs="+",
        metavar="RUN_NC",
        help="for each run.nc of `lookout run` with thrusters: degrees each azimuth turned, mean power, saturation, tracking",
    )
    parser.add_argument(
        "--qp",
        nargs="+",
        metavar="KEY=VALUE",
        help="only the QP's cells, with these [actuator] options (TOML values); printed, not written to the table",
    )
    parser.add_argument(
        "--example",
        nargs="*",
        metavar="KEY=VALUE",
        help="run examples/thrusters-dp.toml with these [actuator] options and measure it as --turning does",
    )
    args = parser.parse_args(argv)
    if args.example is not None:
        example(args.example)
        return 0
    if args.turning:
        for path in args.turning:
            turning(Path(path))
        return 0
    if args.figure_only:
        figure()
        return 0
    if args.one_limit_at_a_time:
        one_limit_at_a_time()
        return 0
    rows, used = [], {}
    for loop_name in args.loops:
        loop = LOOPS[loop_name]
        seeds = 2 if args.quick else (args.seeds or loop["seeds"])
        used[loop_name] = seeds
        cells = actuations(loop["layout"])
        if args.qp:
            cells = {"thrusters, QP": {**cells["thrusters, QP"], **_options(args.qp)}}
        for (observer_name, observer), (actuation_name, actuator) in itertools.product(loop["observers"]().items(), cells.items()):
            document = copy.deepcopy(loop["document"]())
            if "duration" in loop and not args.full:
                document["simulation"]["duration"] = loop["duration"]
            if args.quick:
                document["simulation"]["duration"] = round(document["simulation"]["duration"] / 3, 1)
            if observer is not None:
                document["observer"] = copy.deepcopy(observer)
            document["actuator"] = actuator
            document["simulation"]["runs"] = 1
            try:
                result, seconds = run_case(document, seeds, loop["metrics"])
            except ValueError as error:
                print(f"{loop_name} / {observer_name} / {actuation_name}: does not fit: {str(error).splitlines()[0]}", file=sys.stderr)
                continue
            for seed in range(seeds):
                row = {"loop": loop_name, "observer": observer_name, "actuation": actuation_name, "seed": seed}
                row.update({name: float(np.asarray(value)[seed]) for name, value in result.items()})
                rows.append(row)
            medians = {k: float(np.nanmedian(v)) for k, v in result.items() if k != "diverged"}
            print(
                f"{loop_name} / {observer_name} / {actuation_name}: {seconds:.0f} s, " + ", ".join(f"{k} {v:.4g}" for k, v in medians.items()),
                flush=True,
            )
    if args.qp:
        return 0
    write(rows, used, args)
    if "kim-2002" in args.loops and not args.quick:
        figure()
    return 0


def _options(options: list[str]) -> dict:
    """``KEY=VALUE`` strings as a table (each VALUE a TOML value)."""
    table = {}
    for option in options:
        key, _, value = option.partition("=")
        table[key] = tomllib.loads(f"value = {value}")["value"]
    return table


def turning(path: Path) -> None:
    """What the thrusters of one recorded run (``lookout run``'s run.nc, run 0) did over the
    whole run: the degrees each azimuth turned in all (the sum of |ssa(angle change)| over
    the samples), the mean power as a fraction of the installed power (delivered thrust;
    :func:`lookout.actuators.thrusters.relative_power`), the fractions of the samples
    saturated and with a thruster at a limit, the largest shortfall, the RMS position
    tracking error, and how the commanded surge force swings (its standard deviation, and
    the share of its variance below 0.4 rad/s, periods over 16 s)."""
    import xarray as xr

    from lookout._math import ssa
    from lookout.actuators.thrusters import at_limit, relative_power

    with xr.open_dataset(path) as ds:
        run = ds.isel(run=0).load()
    angle = run.thruster_angle.transpose("time", "thruster").values
    turned = np.degrees(np.abs(np.asarray(ssa(np.diff(angle, axis=0)))).sum(axis=0))
    thrust = run.thrust.transpose("time", "thruster").values
    layout = _layout_of(path.parent / "scenario.toml")  # the limits are not in the records
    power = float(np.mean(np.asarray(relative_power(thrust, layout.max_thrust))))
    limit = float(np.mean(np.asarray(at_limit(thrust, layout.max_thrust, layout.min_thrust)).any(axis=-1)))
    error = np.hypot(*(run.position - run.position_desired).transpose("earth_axis", "time").values)
    surge = run.force_commanded.isel(body_axis=0).values
    surge = surge - surge.mean()
    spectrum = np.abs(np.fft.rfft(surge)) ** 2
    frequency = 2 * np.pi * np.fft.rfftfreq(surge.size, float(run.time.values[1] - run.time.values[0]))
    slow = spectrum[(frequency > 0) & (frequency < 0.4)].sum() / spectrum[frequency > 0].sum()
    names = [str(name) for name in run.thruster.values]
    azimuths = ", ".join(f"{name} {value:.0f} deg" for name, value, kind in zip(names, turned, layout.kinds) if kind == "azimuth")
    print(
        f"{path}: {run.time.values[-1]:g} s; turned: {azimuths}; mean power {power:.4f} of the installed power; "
        f"saturated in {run.allocation_saturated.values.mean():.4f} of the samples; a thruster at a limit in {limit:.4f}; "
        f"largest shortfall {run.allocation_shortfall.values.max():.3f}; RMS position tracking {np.sqrt(np.mean(error**2)):.3f} m; "
        f"commanded surge force: standard deviation {surge.std() / 1e3:.0f} kN, {100 * slow:.0f} % of its variance below 0.4 rad/s",
        flush=True,
    )


def example(options: list[str]) -> None:
    """examples/thrusters-dp.toml with ``KEY=VALUE`` [actuator] options (TOML values),
    run as `lookout run` runs it, then measured by :func:`turning`."""
    import tempfile

    from lookout.cli import main as lookout

    with open(ROOT / "examples" / "thrusters-dp.toml", "rb") as handle:
        document = tomllib.load(handle)
    document["actuator"].update(_options(options))
    from lookout.scenario import _toml

    with tempfile.TemporaryDirectory() as folder:
        scenario = _toml.write(Path(folder) / "scenario-in.toml", document)
        if lookout(["run", str(scenario), "--out", str(Path(folder) / "run")]) != 0:
            raise SystemExit(1)
        print(" ".join(options) or "defaults", end=": ")
        turning(Path(folder) / "run" / "run.nc")


def _layout_of(scenario: Path) -> ThrusterLayout:
    """The thruster layout of a scenario file (``lookout run`` writes one next to run.nc),
    built from its [actuator.layout] table alone."""
    from lookout.scenario import registry

    with open(scenario, "rb") as handle:
        table = dict(tomllib.load(handle)["actuator"]["layout"])
    return registry.kind("layout", table.pop("kind", "custom")).callable()(**table)


def one_limit_at_a_time() -> None:
    """Which of the supply vessel's limits breaks Calugi et al. (2003)'s loop: its layout with
    no limit but force, then with the thrust lag, the rate limits or the turning rate alone
    (the QP, the QP with its azimuths unsteered, the pseudo-inverse; 400 s, seed 0). Prints
    the RMS position tracking error."""
    layout = ThrusterLayout.supply_vessel()
    table = {name: list(getattr(layout, name)) for name in ("x", "y", "direction", "max_thrust", "min_thrust")}
    base = {"kind": "custom", "names": list(layout.names), "kinds": list(layout.kinds), **table}
    limits = {
        "force limits only": {},
        f"+ thrust lag {layout.time_constant[0]:g} s": {"time_constant": float(layout.time_constant[0])},
        "+ rate limits": {"thrust_rate": list(layout.thrust_rate)},
        f"+ turning {np.degrees(layout.turn_rate[2]):g} deg/s": {"turn_rate": float(layout.turn_rate[2])},
    }
    allocations = {
        "qp": {"allocation": "qp"},
        # the azimuths turned toward each sample's command at once, as far as their rate allows (no filter, no deadband)
        "qp, unsteered": {"allocation": "qp", "steering_time_constant": 0.0, "steering_deadband": 0.0, "steering_load": 0.0},
        "pseudo-inverse": {"allocation": "pseudo-inverse"},
    }
    for allocation, options in allocations.items():
        for name, extra in limits.items():
            document = preset("calugi-2003", "satisfying")
            document["simulation"].update(duration=400.0, runs=1)
            document["actuator"] = {"kind": "thrusters", **options, "layout": {**base, **extra}}
            result, _ = run_case(document, 1, ["rms_tracking:position"])
            print(f"{allocation}, {name}: RMS position tracking {float(result['rms_tracking__position'][0]):.3g} m", flush=True)
            if allocation == "qp, unsteered" and not extra:  # a loop that tracks: its command as the controller means it
                ds = composition.simulate(composition.compose(document)).to_xarray().isel(run=0)
                rate = np.max(np.abs(np.diff(ds.force_commanded.values, axis=0)), axis=0) / float(np.diff(ds.time.values[:2])[0])
                print(f"  the commanded force changes by up to {rate[0]:.3g} N/s in surge and {rate[1]:.3g} N/s in sway", flush=True)


def figure() -> None:
    """docs/thrusters/kim-2002.png: one run (seed 0) of Kim's loop with the passive
    observer through each actuation, the tracking error and the yaw moment applied."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    loop = LOOPS["kim-2002"]
    fig, axes = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True, layout="constrained")
    for name, actuator in actuations(loop["layout"]).items():
        document = copy.deepcopy(loop["document"]())
        document["observer"] = {"kind": "passive", "design": "fossen-strand-1999"}
        document["actuator"] = actuator
        document["simulation"]["runs"] = 1
        ds = composition.simulate(composition.compose(document)).to_xarray().isel(run=0)
        error = np.hypot(*(ds.position - ds.position_desired).transpose("earth_axis", "time").values)
        style = {"lw": 1.0} if "thrusters" in name else {"lw": 1.6, "ls": "--"}
        axes[0].plot(ds.time, error, label=name, **style)
        axes[1].plot(ds.time, ds.moment_applied / 1e6, label=name, **style)
    axes[0].set_ylabel("position tracking error |p - p_desired| (m)")
    axes[1].set_ylabel("applied yaw moment (MN m)")
    axes[1].set_xlabel("time (s)")
    for axis in axes:
        axis.grid(alpha=0.3)
    axes[0].legend(ncols=2, loc="upper right")
    fig.suptitle(
        "Kim (2002) observer backstepping with the passive observer, Northern Clipper, seed 0:\n"
        "ideal and per-axis saturation overlap (dashed); through the supply vessel's thrusters (solid)"
    )
    fig.savefig(HERE / "kim-2002.png", dpi=110)


def write(rows: list[dict], used: dict, args) -> None:
    import pandas as pd

    frame = pd.DataFrame(rows)
    suffix = "-quick" if args.quick else ""
    frame.to_csv(HERE / f"study{suffix}.csv", index=False)
    lines = [
        f"Made by `python docs/thrusters/study.py{' --quick' if args.quick else ''}`; each cell the median over the seeds "
        f"({', '.join(f'{name}: {count}' for name, count in used.items())} per cell), metrics over the whole run.",
        "",
    ]
    for loop_name in args.loops:
        part = frame[frame.loop == loop_name]
        if part.empty:
            continue
        loop = LOOPS[loop_name]
        lines += [f"### {loop['title']}", ""]
        columns = [c for c in part.columns if "__" in c]
        header = "| observer | actuation | " + " | ".join(c.replace("__", ":") for c in columns) + " | diverged |"
        lines += [header, "|" + "---|" * (len(columns) + 3)]
        for (observer, actuation), cell in part.groupby(["observer", "actuation"], sort=False):
            values = [f"{np.nanmedian(cell[c]):.4g}" if np.isfinite(cell[c]).any() else "—" for c in columns]
            lines.append(f"| {observer} | {actuation} | " + " | ".join(values) + f" | {int(cell['diverged'].sum())}/{len(cell)} |")
        observers = part.observer.unique()
        if len(observers) > 1:
            lines += ["", "Ranking by median RMS position tracking error (best first):", ""]
            from scipy.stats import kendalltau

            medians = part.groupby(["actuation", "observer"])["rms_tracking__position"].median().unstack(0)
            for actuation, cell in part.groupby("actuation", sort=False):
                order = cell.groupby("observer")["rms_tracking__position"].median().sort_values()
                tau = kendalltau(medians["ideal"], medians[actuation]).statistic
                lines.append(
                    f"- {actuation}: "
                    + " < ".join(f"{name} ({value:.3g})" for name, value in order.items())
                    + f"; Kendall's tau-b against the ideal ranking {tau:.2f}"
                )
        lines.append("")
    (HERE / f"table{suffix}.md").write_text("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
