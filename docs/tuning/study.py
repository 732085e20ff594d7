"""The tuning study of docs/tuning.md: `lookout tune` on the papers' cases, each case's
scenario written here from a preset or an example, its results in docs/tuning/<case>/,
and docs/tuning/study.md made from their tuning.json.

    python docs/tuning/study.py [CASE ...]      (make tuning-study: every case)

The cases (sizes chosen to fit a 2-core machine in about half an hour):

- passive-{calm,paper,rough}: Fossen & Strand's (1999) Northern Clipper in the three
  seas of the observer benchmark (docs/benchmark), the observer told the sea's peak
  frequency (w_c = 1.2255 w_o where the paper's 1.1 rad/s would be below it);
- ekf-paper: the EKF (every default: the plant's own model and noise) on the same runs;
- kim-mass-plus-25: Kim's (2002) closed loop (examples/kim-closed-loop.toml) on a vessel
  25 % heavier than the model its observer and controller are built on;
- wondergem-cybership: Wondergem et al.'s (2009) Cybership II around their ellipse in
  their basin's waves and sensor noise (the reproduction's basin-waves case), the
  estimate started at the first fix and at rest.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "src"))

DP = "rms_error:position + 10*rms_error:velocity"
SEAS = {
    "calm": (1.2, [2.0, 2.0, 0.0034906585039886592]),
    "paper": (0.8976, [10.0, 10.0, 0.017453292519943295]),
    "rough": (0.6, [20.0, 20.0, 0.03490658503988659]),
}


def _dp(sea: str, observer: dict | None = None) -> dict:
    from lookout.scenario.registry import preset

    document = preset("fossen-strand-1999", "paper")
    document["simulation"]["duration"] = 1200.0
    frequency, amplitude = SEAS[sea]
    document["plant"]["waves"].update(peak_frequency=frequency, amplitude=amplitude)
    if observer is None:
        document["observer"].update(wave_frequency=frequency, cutoff_frequency=max(1.1, round(1.2255 * frequency, 4)))
    else:
        document["observer"] = observer
    return document


def _kim() -> dict:
    from lookout.scenario._toml import read

    document, _ = read(ROOT / "examples" / "kim-closed-loop.toml")
    document["simulation"]["duration"] = 700.0
    document["plant"]["vessel"]["mass_scale"] = 1.25
    return document


def _wondergem() -> dict:
    from lookout.scenario.registry import preset

    document = preset("wondergem-2009", "basin-waves")
    document["simulation"]["duration"] = 120.0
    document["observer"]["initial"] = {"eta": document["plant"]["initial"]["eta"], "velocity": [0.0, 0.0, 0.0]}
    return document


#: case -> (scenario document, lookout tune options)
CASES = {
    **{
        f"passive-{sea}": (
            lambda sea=sea: _dp(sea),
            ["--objective", DP, "--train-seeds", "8", "--test-seeds", "16", "--steps", "15", "--learning-rate", "0.1"],
        )
        for sea in SEAS
    },
    "ekf-paper": (
        lambda: _dp("paper", {"kind": "ekf"}),
        ["--objective", DP, "--train-seeds", "8", "--test-seeds", "16", "--steps", "8", "--learning-rate", "0.3"],
    ),
    "kim-mass-plus-25": (
        _kim,
        ["--objective", "rms_tracking:position + rms_error:position", "--train-seeds", "4", "--test-seeds", "8", "--steps", "8"],
    ),
    "wondergem-cybership": (
        _wondergem,
        ["--objective", "rms_tracking:position + rms_error:velocity", "--train-seeds", "4", "--test-seeds", "8", "--steps", "8"],
    ),
}


def run(case: str) -> None:
    from lookout.scenario._toml import write

    make, options = CASES[case]
    folder = HERE / case
    folder.mkdir(parents=True, exist_ok=True)
    write(folder / "scenario.toml", make())
    command = [
        str(Path(sys.executable).parent / "lookout"),
        "tune",
        str((folder / "scenario.toml").relative_to(ROOT)),
        "--out",
        str(folder.relative_to(ROOT)),
        *options,
    ]
    print("lookout " + " ".join(command[1:]), flush=True)
    subprocess.run(command, cwd=ROOT, check=True)


def table() -> str:
    lines = [
        "| case | gains tuned | metric (held-out median) | file's gains (outside) | start | tuned | change | steps, stop | s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for case in CASES:
        path = HERE / case / "tuning.json"
        if not path.exists():
            continue
        summary = json.loads(path.read_text())
        for name, medians in summary["held_out_median"].items():
            given = f"{medians['given']:.4g}" if "given" in medians else "—"
            change = (medians["tuned"] - medians["start"]) / medians["start"]
            lines.append(
                f"| {case} | {', '.join(k.split('.')[-1] for k in summary['gains'])} | {name} | {given} | {medians['start']:.4g} | "
                f"{medians['tuned']:.4g} | {change:+.1%} | {len(summary['steps']) - 1}, {summary['stopped']} | {summary['seconds']:.0f} |"
            )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    for case in sys.argv[1:] or list(CASES):
        run(case)
    (HERE / "study.md").write_text(table())
    print((HERE / "study.md").read_text())
