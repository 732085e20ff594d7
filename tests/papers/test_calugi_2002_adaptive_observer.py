"""Calugi (2002), ch. 4: each case's composition, written as a scenario file and run by
``lookout run``, gives the reproduction's numbers."""

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.papers import calugi_2002_adaptive_observer as ch4
from lookout.scenario.composition import compose
from lookout.scenario.file import CompositionSpec, save

from .roundtrip import segmented_progress

pytestmark = pytest.mark.xdist_group("calugi_2002_adaptive_observer")


def test_a_scenario_file_of_each_sample_interval_gives_the_reproductions_numbers_exactly(tmp_path):
    config = ch4.Config(duration=20.0, sweep=False)
    for case in ch4.REPRODUCTION.cases:
        path = tmp_path / f"{case}.toml"
        save(CompositionSpec(compose(ch4.REPRODUCTION.composition(config, case))), path)
        assert main(["run", str(path), "--out", str(tmp_path / case)]) == 0
        reproduced = ch4.simulate_case(config, case, progress=segmented_progress)
        with xr.open_dataset(tmp_path / case / "run.nc") as ran:
            compared = [name for name, variable in ran.data_vars.items() if variable.dtype.kind == "f"]
            for name in compared:
                np.testing.assert_array_equal(ran[name].values, reproduced[name].values, err_msg=f"{case}: {name}")
        assert {"joint_angle", "joint_rate_hat", "mass_hat", "resets"} <= set(compared), case


def test_the_memory_estimate_counts_the_studies():
    """``batches`` lists what ``run`` simulates: the cases, and with the studies the four
    order-study intervals and the stress run."""
    assert len(ch4.REPRODUCTION.batches(ch4.Config(duration=20.0, sweep=False))) == len(ch4.CASES)
    studied = ch4.REPRODUCTION.batches(ch4.Config(duration=20.0))
    assert [scenario.sample_period for scenario, _ in studied] == [*ch4.SAMPLE_PERIODS, *ch4.ORDER_PERIODS, ch4.SAMPLE_PERIODS[0]]
    assert float(studied[-1][0].observer.adaptation_gain[0]) == ch4.STRESS["adaptation_gain"]
