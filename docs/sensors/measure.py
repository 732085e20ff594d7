"""The numbers and the figure of docs/sensors.md: examples/dp-suite.toml run by
``lookout run``, its references.png copied to docs/sensors/, and each reference's
error measured from its run.nc.

    .venv/bin/python docs/sensors/measure.py                 # runs into out/dp-suite
    .venv/bin/python docs/sensors/measure.py --out DIR       # another folder

Each error is taken as references.png draws it (lookout.plotting.suite_references):
a fix taken back to the reference point with the true heading, less the true
position with the waves, at the instrument's own sample instants.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np
import xarray as xr

from lookout.cli import main
from lookout.plotting.suite_references import sensor_reference_errors

ROOT = Path(__file__).resolve().parents[2]


def measure(run_nc: Path) -> None:
    """Print the errors of docs/sensors.md from a run of examples/dp-suite.toml."""
    ds = xr.open_dataset(run_nc).load()
    found = sensor_reference_errors(ds)
    assert found is not None, f"{run_nc} holds no sensor suite"
    positions, headings = found
    print("error of each reference (m; deg for a heading): rms over 100-600 s, before the failures; median over the last 60 s")
    for each in positions + headings:
        before = (each.time >= 100.0) & (each.time < 600.0)
        last = each.time >= float(ds.time[-1]) - 60.0
        rms = np.sqrt(np.nanmean(each.error[before] ** 2, axis=0))
        print(f"  {each.name:9s} rms {np.round(rms, 2)}  median at the end {np.round(np.nanmedian(each.error[last], axis=0), 2)}")
    run = ds.isel(run=0)
    time = run.time.values
    error = (run.measured_position - run.position - run.wave_position).values
    print("combined position's error (rms over 100-600 s, north and east), taken at every")
    for period in (0.1, 1.0, 2.0):
        at = (np.abs(time / period - np.round(time / period)) < 1e-6) & (time >= 100.0) & (time < 600.0)
        print(f"  {period:g} s: {np.round(np.sqrt(np.mean(error[at] ** 2, axis=0)), 2)} m")
    last = run.time >= float(ds.time[-1]) - 60.0
    print("the vessel against its setpoint, mean over the last 60 s:")
    print(f"  true position - desired {np.round((run.position - run.position_desired)[last].mean('time').values, 2)} m")
    print(f"  estimated position - desired {np.round((run.position_hat - run.position_desired)[last].mean('time').values, 2)} m")
    print(f"  true heading - desired {np.degrees(float((run.heading - run.heading_desired)[last].mean('time'))):.2f} deg")


def run() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="out/dp-suite", help="the folder lookout run writes into")
    out = Path(parser.parse_args().out)
    assert main(["run", str(ROOT / "examples" / "dp-suite.toml"), "--out", str(out)]) == 0
    shutil.copyfile(out / "references.png", ROOT / "docs" / "sensors" / "references.png")
    measure(out / "run.nc")


if __name__ == "__main__":
    run()
