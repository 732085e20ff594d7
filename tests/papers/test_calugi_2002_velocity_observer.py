"""Calugi (2002), ch. 2: each system's composition, written as a scenario file and run by
``lookout run``, gives the reproduction's numbers."""

import pytest

from lookout.papers import calugi_2002_velocity_observer as ch2

from .roundtrip import assert_same_floats, run_written_case, segmented_progress

pytestmark = pytest.mark.xdist_group("calugi_2002_velocity_observer")


def test_a_scenario_file_of_each_system_gives_the_reproductions_numbers_exactly(tmp_path):
    config = ch2.Config(duration=1.0)
    for case in ch2.REPRODUCTION.cases:
        ran = run_written_case(ch2.REPRODUCTION, config, case, tmp_path)
        _, reproduced = ch2.simulate_system(config, case, progress=segmented_progress)
        compared = assert_same_floats(ran, reproduced, case)
        assert {"joint_angle", "joint_rate_hat", "joint_torque_applied"} & set(compared), case
        assert len(compared) >= 5, (case, compared)
