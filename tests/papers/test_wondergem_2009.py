"""Wondergem et al. (2009): the error index (43) and the reproduction's outputs."""

import json

import numpy as np
import pytest

from lookout.cli import main
from lookout.models.cybership import CYBERSHIP_THRUST_LIMIT
from lookout.papers import wondergem_2009 as w


def test_error_index_of_known_signals():
    time = np.linspace(0.0, 2.0 * np.pi, 20001)
    # constant errors: the mean square; a sine over whole periods: 1/2 (trapezoid is exact to rounding here)
    assert w.error_index(time, np.full_like(time, 0.1), np.full_like(time, -0.2), np.full_like(time, 0.3)) == pytest.approx(0.14, rel=1e-12)
    assert w.error_index(time, np.sin(time), 0 * time, 0 * time) == pytest.approx(0.5, rel=1e-9)
    # a window [t1, t2]: the error outside does not count
    step = np.where(time < np.pi, 1.0, 0.0)
    assert w.error_index(time, step, 0 * time, 0 * time, start=np.pi + 0.01) == 0.0
    with pytest.raises(ValueError, match="error_index needs start < end"):
        w.error_index(time, time, time, time, start=3.0, end=2.0)


def test_reproduce_wondergem_2009_writes_its_outputs_and_never_exceeds_the_thrust_limits(tmp_path, capsys):
    out = tmp_path / "w09"
    assert main(["reproduce", "wondergem-2009", "--out", str(out), "--duration", "20", "--condition", "basin-waves", "--no-sweep"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["conditions"]) == ["basin-waves"]
    values = summary["conditions"]["basin-waves"]
    assert values["table_1"] == 0.12686 and np.isfinite(values["error_index"][0])
    files = sorted(path.name for path in out.iterdir())
    assert files == summary["files"]
    assert {"track.png", "errors.png", "velocities.png", "thrust.png", "wondergem_2009_basin_waves.nc"} <= set(files)
    import xarray as xr

    ds = xr.open_dataset(out / "wondergem_2009_basin_waves.nc")
    applied = np.concatenate([ds.force_applied.values, ds.moment_applied.values[..., None]], axis=-1)
    commanded = np.concatenate([ds.force_commanded.values, ds.moment_commanded.values[..., None]], axis=-1)
    assert np.all(np.abs(applied) <= np.asarray(CYBERSHIP_THRUST_LIMIT))
    assert np.any(np.abs(commanded) > np.asarray(CYBERSHIP_THRUST_LIMIT))  # the transient saturates
    assert float(np.abs(ds.wave_position).max()) > 0  # the waves reach the measurement
    assert "Table 1" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--condition", "basin"], "--condition must be distinct names from simulation, basin-calm, basin-waves; got basin"),
        (["--duration", "5"], "--duration must be between 10 s and 3600 s; got 5"),
        (["--gains", "kyp"], "--gains: wondergem-2009 has no such setting (it belongs to kim-2002)"),
    ],
)
def test_bad_wondergem_options_exit_2_with_one_line(argv, message, capsys):
    assert main(["reproduce", "wondergem-2009", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
