"""Calugi (2002), ch. 2: each system's composition, written as a scenario file and run by
``lookout run``, gives the reproduction's numbers."""

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.composition import compose
from lookout.papers import calugi_2002_velocity_observer as ch2
from lookout.studies.scenario_file import CompositionSpec, save

pytestmark = pytest.mark.xdist_group("calugi_2002_velocity_observer")


def segmented_progress(done, total):
    """A progress callback, as ``lookout run`` gives one: the reproduction then simulates in
    the same segments and reuses the compiled program (the numbers are the same either way)."""


def test_a_scenario_file_of_each_system_gives_the_reproductions_numbers_exactly(tmp_path):
    config = ch2.Config(duration=1.0)
    for case in ch2.REPRODUCTION.cases:
        path = tmp_path / f"{case}.toml"
        save(CompositionSpec(compose(ch2.REPRODUCTION.composition(config, case))), path)
        assert main(["run", str(path), "--out", str(tmp_path / case)]) == 0
        _, reproduced = ch2.simulate_system(config, case, progress=segmented_progress)
        with xr.open_dataset(tmp_path / case / "run.nc") as ran:
            compared = [name for name, variable in ran.data_vars.items() if variable.dtype.kind == "f"]
            for name in compared:
                np.testing.assert_array_equal(ran[name].values, reproduced[name].values, err_msg=f"{case}: {name}")
        assert {"joint_angle", "joint_rate_hat", "joint_torque_applied"} & set(compared), case
        assert len(compared) >= 5, (case, compared)
