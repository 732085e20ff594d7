"""Calugi (2002), ch. 6: each experiment's composition, written as a scenario file and run
by ``lookout run``, gives the reproduction's numbers."""

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.papers import calugi_2002_furuta as ch6
from lookout.scenario.composition import compose
from lookout.scenario.file import CompositionSpec, save

from .roundtrip import segmented_progress

pytestmark = pytest.mark.xdist_group("calugi_2002_furuta")


def test_a_scenario_file_of_each_experiment_gives_the_reproductions_numbers_exactly(tmp_path):
    config = ch6.Config(duration=0.75)
    for case in ch6.REPRODUCTION.cases:
        path = tmp_path / f"{case}.toml"
        save(CompositionSpec(compose(ch6.REPRODUCTION.composition(config, case))), path)
        assert main(["run", str(path), "--out", str(tmp_path / case)]) == 0
        _, reproduced = ch6.simulate_case(config, case, progress=segmented_progress)
        with xr.open_dataset(tmp_path / case / "run.nc") as ran:
            compared = [name for name, variable in ran.data_vars.items() if variable.dtype.kind == "f"]
            for name in compared:
                np.testing.assert_array_equal(ran[name].isel(run=0).values, reproduced[name].values, err_msg=f"{case}: {name}")
        assert {"joint_angle", "joint_rate_hat", "coulomb_friction_0_hat", "pendulum_angle_desired", "arm_stuck_time"} <= set(compared), case


def test_the_printed_exp_iii_is_built_around_the_bounds_check_and_the_memory_estimate_counts_the_experiments_run():
    config = ch6.Config(duration=0.75, experiments=("III", "IV"))
    document = ch6.REPRODUCTION.composition(config, "III")
    assert document["observer"]["check_bounds"] is False and document["observer"]["lower"] == [0.001, 1e-4]
    np.testing.assert_array_equal(ch6.REPRODUCTION.scenario(config, "III").observer.lower, [0.001, 1e-4])
    assert [scenario.duration for scenario, _ in ch6.REPRODUCTION.batches(config)] == [0.75, 0.75]
