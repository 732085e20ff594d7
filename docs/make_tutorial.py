"""Write docs/tutorial.md: every command of the tutorial run in a scratch folder, and its
real output pasted under it.

    .venv/bin/python docs/make_tutorial.py          # about a minute on 2 cores

The commands are the ones a new user types, in order; the files they write are in the
scratch folder printed at the end (the figures are copied to docs/tutorial/).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

DOCS = Path(__file__).resolve().parent
LOOKOUT = str(Path(sys.executable).parent / "lookout")

MY_VESSEL = """\
# my-vessel.toml: Kim's closed loop (sliding-mode observer replaced by the passive one)
# on my own 60 m vessel
preset = "kim-2002"

[simulation]
duration = 600.0

[plant.vessel]
kind = "custom"
mass_matrix = [[2.59e6, 0.0, 0.0], [0.0, 4.04e6, 0.0], [0.0, 0.0, 1.13e9]]
damping_matrix = [[2.76e4, 0.0, 0.0], [0.0, 1.50e5, -1.90e6], [0.0, -1.90e6, 1.43e8]]

[observer]
kind = "passive"
"""

BAD_VESSEL = MY_VESSEL.replace('kind = "passive"', 'kind = "velocity"\ngain = 5.0')

STUDY = """\
# my-study.toml: the passive and the sliding-mode observer on my vessel, in three seas
scenario = "my-vessel.toml"
seeds_per_point = 4
chunk_runs = 4
metrics = ["rms_tracking:position", "rms_error:position", "rms_error:velocity"]

[sweep]
kind = "grid"

[[sweep.axes]]
name = "observer"
field = "observer"
values = [{ kind = "passive" }, { kind = "sliding-mode", switching_gain = [0.5, 0.5, 0.005], boundary_layer = [2.0, 2.0, 0.02] }]

[[sweep.axes]]
name = "wave_amplitude"
field = ["plant.waves.amplitude[0]", "plant.waves.amplitude[1]"]
values = [0.5, 1.0, 2.0]
scale = true
"""


def run(folder: Path, *args: str) -> str:
    """The command's output as a reader sees it (stdout then stderr), and its exit code."""
    environment = {**os.environ, "COLUMNS": "150"}
    done = subprocess.run([LOOKOUT, *args], cwd=folder, capture_output=True, text=True, env=environment)
    text = (done.stdout + done.stderr).rstrip()
    text = "\n".join(line.rstrip() for line in text.splitlines())
    text = text.replace(str(folder) + "/", "").replace(str(folder), ".")
    shown = " ".join(args)
    code = f"\n(exit code {done.returncode})" if done.returncode else ""
    return f"```\n$ lookout {shown}\n{text}{code}\n```\n"


def excerpt(text: str, start: str, lines: int) -> str:
    """``lines`` lines of a command's output from the first that contains ``start``."""
    body = text.split("\n")
    index = next(i for i, line in enumerate(body) if start in line)
    return "\n".join(body[index : index + lines])


def main() -> None:
    folder = Path(tempfile.mkdtemp(prefix="lookout-tutorial-"))
    (folder / "my-vessel.toml").write_text(MY_VESSEL)
    (folder / "bad-vessel.toml").write_text(BAD_VESSEL)
    (folder / "my-study.toml").write_text(STUDY)
    listing = run(folder, "components")
    observers = run(folder, "components", "observer")
    passive = run(folder, "components", "passive")
    refused = run(folder, "run", "bad-vessel.toml", "--out", "out/bad")
    ran = run(folder, "run", "my-vessel.toml", "--out", "out/my-vessel")
    written = (folder / "out" / "my-vessel" / "scenario.toml").read_text()
    observer_table = written[written.index("# observer:") : written.index("# reference:")].rstrip()
    campaign = run(folder, "campaign", "run", "my-study.toml", "--out", "out/my-study.zarr", "--workers", "0")
    campaign = re.sub(r"\b\d+(\.\d+)? s\b", "N s", campaign)  # times vary from run to run
    status = run(folder, "campaign", "status", "out/my-study.zarr")
    report = run(folder, "campaign", "report", "out/my-study.zarr")
    figures = DOCS / "tutorial"
    figures.mkdir(exist_ok=True)
    for name in ("estimates.png", "input.png", "reference.png"):
        shutil.copy(folder / "out" / "my-vessel" / name, figures / name)

    text = f"""# Tutorial: your own vessel, an observer of your choice, a run and a campaign

This page is written by `docs/make_tutorial.py`, which runs every command below in an
empty folder and pastes its real output.

## 1. What can be composed

`lookout components` lists every registered kind by role: plants and their parts
(vessels, models, seas, biases), sensors, observers (with their gain-design rules),
controllers, references and actuators.

{listing}
One role, with what each kind needs and provides:

{observers}
One kind: its parameters, their defaults, types, ranges and units (read from the
component's own docstring), and the signals it reads and gives. A parameter that is a
part (here the vessel model and the sea) is taken from the plant unless the table
gives one.

{passive}
## 2. A composition of your own

A scenario file has one table per component. The easiest start is a reproduction's
case (`preset`), with the parts you want changed. Here: Kim's (2002) closed loop
(observer backstepping, reference filter, thrust limits, the sea of Fossen & Strand's
study), on a 60 m vessel of your own, with Fossen & Strand's passive observer in
place of Kim's sliding-mode one:

```toml
{MY_VESSEL.rstrip()}
```

The `[observer]` table names another kind than the preset's, so it replaces the
preset's observer table: the passive observer is designed for the plant's own M and
D, its wave model tuned to the plant's sea, its Kappa and Lambda inside Fossen &
Strand's rule (48). The controller takes its gains from that observer.

A part that does not fit is refused before anything is compiled, in one line that
names what is missing and both parts (here the velocity observer of a robot arm):

{refused}
## 3. A run and its figures

{ran}
`scenario.toml` in the output folder is the composition as it ran, every key spelled
out with its description; its observer table:

```toml
{observer_table}
```

`estimates.png` shows every estimate against its truth (the full run and a zoom on its
end); `input.png` the commanded and applied thrust (shaded where the thrust limits cut
it); `reference.png` the reference against the truth.

![estimates](tutorial/estimates.png)

Read what the figure says, not only the table: in 600 s the bias moment estimate has
not reached the true bias (its loop, with Lambda / Kappa = sqrt(w_o / T) of the
default tuning rule, is slow in yaw), and the yaw-rate estimate carries that error.
The design rule's defaults are a start for a vessel nobody has tuned for yet, not a
tuning: `[observer] velocity_injection_gain = ...`, `bias_injection_gain = ...` or
`velocity_bandwidth = ...` change them, and a campaign compares the choices.
![input](tutorial/input.png)
![reference](tutorial/reference.png)

## 4. A campaign over it

A campaign sweeps any key of the composition, or replaces a whole component: here
both observers on the same seeds, in three seas (the wave amplitude scaled).

```toml
{STUDY.rstrip()}
```

{campaign}
{status}
{report}
The report (one HTML page) shows the spec as tables, a summary per point, and figures
of each metric against each axis; `lookout campaign status` says what is done, and a
killed campaign resumes where it stopped (docs/studies.md).
"""
    (DOCS / "tutorial.md").write_text(text)
    print(f"wrote {DOCS / 'tutorial.md'}; the tutorial's files are in {folder}")


if __name__ == "__main__":
    main()
