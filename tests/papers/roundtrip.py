"""What every reproduction's tests check of a case: written as a scenario file and run by
``lookout run``, it gives the reproduction's own numbers, bit for bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from lookout.cli import main
from lookout.scenario.composition import compose
from lookout.scenario.file import CompositionSpec, save


def run_written_case(reproduction, config, case: str, folder: Path) -> xr.Dataset:
    """``case`` of ``reproduction`` with ``config``, saved as a scenario file in ``folder``
    and run by ``lookout run``: the run.nc it writes, loaded. The exit code is 0, or 3
    where a run failed (a case that diverges, as its paper says), and run.nc says which."""
    from lookout._commandline import DIVERGED_EXIT_CODE

    path = save(CompositionSpec(compose(reproduction.composition(config, case))), folder / f"{case}.toml")
    out = folder / f"{case}-run"
    code = main(["run", str(path), "--out", str(out)])
    with xr.open_dataset(out / "run.nc") as ran:
        ran = ran.load()
    assert code == (DIVERGED_EXIT_CODE if "diverged" in list(ran.status.values) else 0), (case, code)
    return ran


def assert_same_floats(ran: xr.Dataset, reproduced: xr.Dataset, label: str = "") -> list[str]:
    """Every float variable of ``ran`` equals ``reproduced``'s to the bit; the names compared."""
    compared = [name for name, variable in ran.data_vars.items() if variable.dtype.kind == "f"]
    for name in compared:
        np.testing.assert_array_equal(ran[name].values, reproduced[name].values, err_msg=f"{label}: {name}")
    return compared


def segmented_progress(done, total):
    """A progress callback, as ``lookout run`` gives one: a reproduction given it simulates
    in the same segments and reuses the compiled program (the numbers are the same either way)."""
