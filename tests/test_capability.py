"""DP capability (lookout.actuators.capability, lookout capability): the linear program
against the allocator's closed-form reach of each axis alone (itself checked against
SciPy in tests/test_thrusters.py), its symmetries and its monotonicity in the
thrusters, and the command's outputs and refusals."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from lookout.actuators.allocation import Allocator
from lookout.actuators.capability import SIDES, capability, largest_force, single_failure_capability
from lookout.actuators.layout import ThrusterLayout
from lookout.cli import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "thrusters-dp.toml"
#: The inscribed polygon's loss of an azimuth's thrust circle.
POLYGON = 1.0 - math.cos(math.pi / SIDES)


@pytest.mark.parametrize("layout", [ThrusterLayout.supply_vessel(), ThrusterLayout.cybership_ii()], ids=["supply-vessel", "cybership-ii"])
def test_each_axis_alone_is_the_allocators_reach(layout):
    """With the other two axes left free, the program's largest force along an axis is
    the allocator's reach of that axis (tunnels at their limits, azimuth circles, main
    propellers ahead with their rudders or astern), within the polygon's loss."""
    allocator = Allocator(layout)
    reach = np.asarray(allocator.reach) * np.asarray(allocator.force_scale)
    for axis in range(3):
        for side, sign in ((1, 1.0), (0, -1.0)):
            direction = np.zeros(3)
            direction[axis] = sign
            found = largest_force(layout, direction, free=[a for a in range(3) if a != axis])
            expected = abs(reach[side, axis])
            assert expected * (1 - POLYGON) - 1e-6 * expected <= found <= expected * (1 + 1e-9), (axis, sign, found, expected)


def test_the_supply_vessel_holds_as_much_from_behind_as_from_ahead_and_loses_with_each_thruster():
    """Its tunnels push both ways and its azimuths turn: the feasible forces are symmetric,
    so F(beta) = F(beta + 180 deg) without a moment; a thruster out of service never adds
    capability, and each one loses some somewhere."""
    layout = ThrusterLayout.supply_vessel()
    directions = np.radians(np.arange(0, 360, 15))
    found = single_failure_capability(layout, directions)
    intact = found["intact"]
    half = len(directions) // 2
    np.testing.assert_allclose(intact[:half], intact[half:], rtol=1e-7)
    for name in layout.names:
        assert np.all(found[name] <= intact * (1 + 1e-9)), name
        assert np.any(found[name] < 0.9 * intact), name
    # balanced in all three axes: never more than the reach of the axis alone
    assert intact[0] <= 600e3 * (1 + 1e-9) and intact[half // 2] <= 860e3


def test_a_moment_takes_capability_and_bad_arguments_are_refused():
    layout = ThrusterLayout.supply_vessel()
    directions = np.radians([0.0, 90.0])
    assert np.all(capability(layout, directions, moment_arm=20.0) < capability(layout, directions))
    with pytest.raises(ValueError, match="out must name thrusters by index, 0 to 3; got 7"):
        capability(layout, directions, out=(7,))
    with pytest.raises(ValueError, match="moment_arm must be a finite number"):
        capability(layout, directions, moment_arm=math.nan)
    with pytest.raises(ValueError, match="sides must be a whole number >= 8"):
        capability(layout, directions, sides=3)


def test_the_command_writes_the_polar_and_the_table(tmp_path, capsys):
    out = tmp_path / "capability"
    assert main(["capability", str(EXAMPLE), "--out", str(out), "--step", "30"]) == 0
    printed = capsys.readouterr().out
    assert "worst single thruster failure: " in printed
    assert (out / "capability.png").stat().st_size > 10_000
    with (out / "capability.csv").open() as handle:
        rows = list(csv.reader(handle))
    assert rows[0][:2] == ["direction_deg", "intact"] and len(rows) == 1 + 12
    expected = capability(ThrusterLayout.supply_vessel(), np.radians([0.0, 30.0]))
    np.testing.assert_allclose([float(rows[1][1]), float(rows[2][1])], expected, rtol=1e-5)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--step", "7"], "--step must divide 360 degrees into at least 4 directions"),
        (["--moment-arm", "inf"], "--moment-arm must be a finite number of metres"),
    ],
)
def test_bad_options_are_one_line_and_nothing_is_written(argv, message, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["capability", str(EXAMPLE), "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert not out.exists()


def test_a_scenario_without_thrusters_is_refused(tmp_path, capsys):
    scenario = tmp_path / "plain.toml"
    scenario.write_text('preset = "fossen-strand-1999"\n')
    out = tmp_path / "out"
    assert main(["capability", str(scenario), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "lookout capability needs thrusters" in err, err
    assert not out.exists()
