"""lookout identify (lookout.tuning.identify, lookout.live.identify_cli): M and D of a known
vessel from the log lookout write-log writes of it, the written scenario that composes,
and a log without thrust refused with a pointer to the observer without a hull model."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from lookout.cli import main
from lookout.models.vessel import NORTHERN_CLIPPER_D, NORTHERN_CLIPPER_M
from lookout.scenario.composition import compose

EXAMPLE = Path(__file__).parents[1] / "examples"


def _scaled_error(found: np.ndarray, true: np.ndarray) -> np.ndarray:
    """|found - true| entry by entry over sqrt(|true_ii true_jj|): each entry against the
    size its row's and column's diagonal give it (a coupling of surge and yaw against
    sqrt(m_11 m_33))."""
    return np.abs(found - true) / np.sqrt(np.abs(np.outer(np.diagonal(true), np.diagonal(true))))


@pytest.mark.slow
def test_m_and_d_of_the_northern_clipper_from_its_raw_log(tmp_path, capsys):
    """examples/logs/identify-vessel-raw.nmea and -thrust.csv, what `lookout write-log
    examples/identify-vessel.toml --outage none --raw` writes: 1800 s of the Northern
    Clipper under sinusoidal thrust, DGNSS of 0.5 m at 1 Hz, a gyro of 0.1 deg at 10 Hz,
    a light sea.
    Identified with six windows of 299.8 s, the last held out: every entry of M within 1 %
    of the size its diagonal gives it (measured 0.67 % at most); of D within 15 %
    (measured 7.8 % for the surge-yaw coupling D_13 and 5.8 % for D_12, both 0 in the
    truth: the surge row, whose damping is the smallest against its inertia, is the
    least excited; 0.7 % or less for the other entries); the diagonals of M within 1 %,
    of D within 5 % (measured 2.9 % for surge, 0.07 % and 0.02 % for sway and yaw); the
    held-out window predicted within 4 m and 1 degree RMS (measured 2.94 m north, 0.74 m
    east, 0.65 degree: 300 s of prediction from one start with the last fitted window's
    environment)."""
    logs = EXAMPLE / "logs"
    out = tmp_path / "identified"
    assert main(["identify", str(logs / "identify-vessel-raw.nmea"), "--thrust", str(logs / "identify-vessel-thrust.csv"), "--out", str(out)]) == 0
    capsys.readouterr()
    numbers = json.loads((out / "identification.json").read_text())
    mass, damping = np.asarray(numbers["mass_matrix"]), np.asarray(numbers["damping_matrix"])
    assert _scaled_error(mass, NORTHERN_CLIPPER_M).max() < 0.01
    assert _scaled_error(damping, NORTHERN_CLIPPER_D).max() < 0.15
    np.testing.assert_allclose(np.diagonal(mass), np.diagonal(NORTHERN_CLIPPER_M), rtol=0.01)
    np.testing.assert_allclose(np.diagonal(damping), np.diagonal(NORTHERN_CLIPPER_D), rtol=0.05)
    assert np.all(np.linalg.eigvalsh(mass) > 0) and np.all(np.linalg.eigvalsh(0.5 * (damping + damping.T)) >= 0)
    validation = numbers["validation_rms"]
    assert validation["north_m"] < 4.0 and validation["east_m"] < 4.0 and np.degrees(validation["heading_rad"]) < 1.0
    composed = compose(tomllib.loads((out / "identified.toml").read_text()))
    np.testing.assert_allclose(np.asarray(composed.scenario.plant.vessel.mass_matrix), mass)
    assert (out / "fit.png").stat().st_size > 10_000 and (out / "session.nc").exists()


def test_a_log_without_thrust_is_refused_with_a_pointer_to_the_observer_without_a_hull_model(capsys):
    assert main(["identify", str(EXAMPLE / "logs" / "dp-vessel-raw.nmea")]) == 2
    message = capsys.readouterr().err.strip()
    assert message.startswith("error: identify needs --thrust THRUST.csv") and "lookout replay" in message and "\n" not in message
    assert main(["identify", str(EXAMPLE / "logs" / "dp-vessel-raw.nmea"), "--thrust", str(EXAMPLE / "logs" / "dp-vessel.csv")]) == 2
    assert "must be a CSV log whose first line is time,surge,sway,yaw" in capsys.readouterr().err


@pytest.mark.slow
def test_a_thrust_log_that_does_not_cover_the_log_and_a_window_too_long_are_refused_before_the_fit(tmp_path, capsys):
    logs = EXAMPLE / "logs"
    out = tmp_path / "id"
    arguments = ["identify", str(logs / "identify-vessel-raw.nmea"), "--out", str(out)]
    assert main([*arguments, "--thrust", str(logs / "dp-vessel-thrust.csv")]) == 2  # the 600 s run's thrust for the 1800 s log
    message = capsys.readouterr().err.strip().splitlines()[-1]
    assert message.startswith("error: --thrust") and "covers 599.8 s of the log's 1799.0 s" in message
    assert main([*arguments, "--thrust", str(logs / "identify-vessel-thrust.csv"), "--window", "5000"]) == 2
    assert capsys.readouterr().err.strip() == "error: --window 5000 s is longer than half the log (1799.0 s): give a shorter window or a longer log"
    assert not (out / "session.nc").exists()
