"""Kim (2002), Fig. 8's claim at one model-error size, measured, and the reproduction's outputs.

The claim: with the same controller, the observer without the switching term lets the
ship drift away while the sliding-mode observer tracks. Measured here on 2 seeds x
1000 s at the default model error (M_true = 1.2 M, D_true = 1.5 D, a 4 kN
unmodelled force), for the printed observer gains and for gains that satisfy (14).
"""

import json

import pytest

from lookout.cli import main
from lookout.papers import kim_2002

SEEDS = (0, 1)
#: one worker computes the module's fixture once (make test runs pytest --dist loadgroup)
pytestmark = pytest.mark.xdist_group("kim_2002")


@pytest.fixture(scope="module")
def fig8():
    """The sweep's own code (one vmapped batch) at one model-error size, the default."""
    config = kim_2002.Config(sweep_duration=1000.0, sweep_seeds=len(SEEDS), seed=SEEDS[0])
    sweep = kim_2002.run_sweep(config, points=[("default", kim_2002.ModelError())])
    assert sweep.tracking_rms_m.dims == ("gains", "observer", "model_error", "seed")
    assert set(kim_2002._sweep_summary(sweep)) == {"printed", "kyp"}
    cell = sweep.isel(model_error=0)
    return {
        (gains, observer, seed): {name: cell[name].sel(gains=gains, observer=observer, seed=seed).item() for name in cell.data_vars}
        for gains in ("printed", "kyp") for observer in kim_2002.OBSERVERS for seed in SEEDS
    }


def test_with_the_printed_gains_the_conventional_observer_diverges_and_the_sliding_mode_one_does_not(fig8):
    """Fig. 8 as printed: true here, but because the Kbar = 0 observer with H3/H4 = 10 1/s is
    unstable on its own (an error mode at +0.0156 1/s), not because of the model error."""
    for seed in SEEDS:
        assert fig8[("printed", "conventional", seed)]["diverged"]
        assert fig8[("printed", "conventional", seed)]["estimate_error_max_m"] > 1e3
        sliding = fig8[("printed", "sliding-mode", seed)]
        assert not sliding["diverged"]
        assert sliding["estimate_error_max_m"] < 20.0


def test_with_gains_that_satisfy_14_both_observers_track_and_the_switching_term_does_not_help(fig8):
    """Measured: both track to well under a metre; the sliding-mode loop is 5-40 % worse
    (0.43 vs 0.38 m at this model error over 1400 s, docs/reproductions.md)."""
    for seed in SEEDS:
        sliding, conventional = fig8[("kyp", "sliding-mode", seed)], fig8[("kyp", "conventional", seed)]
        assert not sliding["diverged"] and not conventional["diverged"]
        assert sliding["tracking_rms_m"] < 1.0 and conventional["tracking_rms_m"] < 1.0
        assert 1.0 < sliding["tracking_rms_m"] / conventional["tracking_rms_m"] < 1.4


def test_the_printed_gains_track_worse_than_gains_that_satisfy_14(fig8):
    for seed in SEEDS:
        assert fig8[("printed", "sliding-mode", seed)]["tracking_rms_m"] > 2 * fig8[("kyp", "sliding-mode", seed)]["tracking_rms_m"]


def test_reproduce_kim_2002_writes_its_outputs(tmp_path, capsys):
    out = tmp_path / "kim"
    assert main(["reproduce", "kim-2002", "--out", str(out), "--duration", "300", "--no-sweep", "--model-error", "damping=0.5,force=2000"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["config"]["model_error"] == {"mass": 0.0, "damping": 0.5, "force": 2000.0, "force_period": 100.0}
    assert set(summary["observers"]) == {"sliding-mode", "conventional"}
    for name in ("tracking_rms_m", "position_error_rms_m", "thrust_peak_n", "thrust_rms_n", "time_saturated"):
        assert summary["observers"]["sliding-mode"][name]["mean"] is not None
    assert summary["stability"]["printed"]["verdicts"]["kyp_14"] == "fails"
    assert summary["stability"]["kyp"]["verdicts"]["kyp_14"] == "holds"
    files = sorted(path.name for path in out.iterdir())
    assert files == summary["files"]
    assert {"fig04_x_position.png", "fig05_wave_filtering.png", "fig06_surge_velocity.png", "fig07_surge_bias.png", "fig08_xy_track.png"} <= set(files)
    text = capsys.readouterr().out
    assert "sliding-mode" in text and "conventional" in text
    assert max(len(line) for line in text.splitlines() if not line.startswith("2/2")) <= 80


def test_the_sweep_points_cover_mass_damping_and_force_one_axis_at_a_time():
    points = kim_2002.sweep_points()
    assert len(points) == 13 and points[0][1].force == 0 and {p.mass for _, p in points} == {-0.5, -0.25, 0.0, 0.25, 0.5}
    assert {p.damping for _, p in points} == {-0.5, -0.25, 0.0, 0.25, 0.5}
    assert {p.force for _, p in points} == {0.0, 2e3, 4e3, 8e3, 16e3}
    assert all(sum(value != 0 for value in (p.mass, p.damping, p.force)) <= 1 for _, p in points)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--model-error", "mass=-1"], "--model-error mass must be a finite number above -1"),
        (["--model-error", "inertia=1"], "--model-error: unknown key 'inertia'"),
        (["--model-error", "force=-5"], "--model-error force must be a finite number >= 0"),
        (["--gains", "best"], "--gains must be 'printed' or 'kyp'"),
    ],
)
def test_bad_kim_options_exit_2_with_one_line(argv, message, capsys):
    assert main(["reproduce", "kim-2002", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_kim_options_are_refused_for_other_reproductions(capsys):
    assert main(["reproduce", "fossen-strand-1999", "--model-error", "mass=0.1"]) == 2
    assert "--model-error: fossen-strand-1999 has no such setting" in capsys.readouterr().err
