"""Calugi (2002), ch. 3: the estimator's claims on Sims 1 and 2, and the reproduction's outputs."""

import json

import numpy as np
import pytest
import xarray as xr

from lookout.cli import main
from lookout.papers import calugi_2002_parameter_estimation as ch3
from lookout.scenario.composition import compose
from lookout.scenario.file import CompositionSpec, save

from .roundtrip import segmented_progress

#: one worker runs these tests (make test: --dist loadgroup), and the session fixture computes the reproduction once there
pytestmark = pytest.mark.xdist_group("calugi_2002_parameter_estimation")


@pytest.fixture(scope="session")
def reproduction(tmp_path_factory):
    """``lookout reproduce calugi-2002-parameter-estimation`` with its defaults (60 s): one
    run of the command serves the claims and the check of what it writes (22 s here,
    less than a short run plus separate full simulations, which compile apart)."""
    out = tmp_path_factory.mktemp("ch3")
    assert main(["reproduce", ch3.NAME, "--out", str(out)]) == 0
    return out, json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="session")
def summary(reproduction):
    return reproduction[1]


def test_sim1_tracks_each_mass_to_1_percent_within_10_s(summary):
    """Fig. 3.2: after the start and after each jump of m, m_hat settles within 1 % (the
    settling band the reproduction reports) before the next jump; h = 10."""
    segments = summary["sim1"]["segments"]
    assert [s["mass"] for s in segments] == list(ch3.SIM1_MASSES)
    for segment in segments:
        assert abs(segment["after_s"]["10"]["relative_error"]) < ch3.SETTLE_BAND, segment
        assert segment["settle_1pct_s"] is not None and segment["settle_1pct_s"] < 10.0, segment
    # theta constant since t = 0 on the first interval: V = |m~|^2 / 2 never rises (rounding allowed)
    assert summary["sim1"]["lyapunov"]["largest_increase_relative"] < 1e-12


def test_sim2_converges_under_persistent_excitation_although_the_pointwise_rank_never_holds(summary):
    """Fig. 3.3: theta_hat -> (m l^2, m l). With one joint and two parameters phi_f^T phi_f
    has rank 1 at every instant (Lemma 3.1(2)'s condition fails), but the windowed
    integral is positive definite over the whole run (PE), and theta_hat converges: within
    1 % by the end, V = |theta~|^2 / 2 never increasing."""
    sim2 = summary["sim2"]
    truth = {"inertia": ch3.SIM2_MASS * ch3.LENGTH**2, "moment": ch3.SIM2_MASS * ch3.LENGTH}
    for name, value in truth.items():
        parameter = sim2["parameters"][name]
        assert parameter["truth"] == pytest.approx(value, rel=1e-14)
        assert abs(parameter["final_relative_error"]) < ch3.SETTLE_BAND
        assert parameter["settle_1pct_s"] is not None
    excitation = sim2["excitation"]
    assert excitation["lambda_min"] > 1e-3 * excitation["stiffness_per_s"] / sim2["gain"]
    assert excitation["pointwise_lambda_min_max"] < 1e-12 * excitation["stiffness_per_s"] / sim2["gain"]
    assert sim2["lyapunov"]["largest_increase_relative"] < 1e-12
    assert sim2["lyapunov"]["final"] < 1e-4 * sim2["lyapunov"]["initial"]
    # the RK4 step is well inside the stability limit (2.78) of the stiffest mode h lambda_max
    assert excitation["rk4_step_times_stiffness"] < 1.0


def test_reproduce_writes_its_outputs(reproduction):
    out, summary = reproduction
    files = sorted(path.name for path in out.iterdir())
    assert files == summary["files"]
    assert {"fig3_2_mass_estimate.png", "fig3_3_inertia_moment_estimates.png", "excitation.png", "calugi_2002_ch3_sim2.nc"} <= set(files)
    assert summary["status"] == ["finite"] * 4
    assert [s["from_s"] for s in summary["sim1"]["segments"]] == [0.0, *ch3.SIM1_SWITCH_TIMES]
    ds = xr.open_dataset(out / "calugi_2002_ch3_sim1.nc")
    assert {"mass", "mass_hat", "filtered_regressor_mass", "torque_prediction_error"} <= set(ds.data_vars)
    assert ds.mass.attrs["units"] == "kg" and ds.filtered_regressor_mass.attrs["units"] == "N m/kg"
    ds.close()
    assert ch3.tables(summary)[0].rows[0][0] == "0"


def test_without_excitation_the_estimates_do_not_move(summary):
    """tau = 0: Sim 2 at rest, and Sim 1 swinging from q(0) = 1 rad, where phi = l^2 q'' +
    g l sin q is zero along the motion. Neither estimate moves (rounding allowed)."""
    for name, still in summary["no_excitation"].items():
        assert still["max_estimate_change"] < 1e-12, name
        assert still["max_abs_filtered_regressor"] < 1e-9, name
    assert summary["no_excitation"]["sim1_free_swing"]["max_abs_angle"] > 0.9


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--duration", "0"], "--duration must be a finite positive number"),
        (["--duration", "8.005"], "--duration must be a whole multiple of the sample period (0.01 s)"),
        (["--duration", "4"], "--duration must be at least 5.01 s (the PE window pe_window, 5 s, plus one sample); got 4 s"),
        (["--runs", "2"], "--runs must be 1"),
        (["--seed", "-1"], "--seed must be an integer from 0"),
    ],
)
def test_bad_options_exit_2_with_one_line(argv, message, capsys):
    assert main(["reproduce", ch3.NAME, *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


def test_a_scenario_file_of_each_run_gives_the_reproductions_numbers_exactly(tmp_path):
    config = ch3.Config(duration=1.0, pe_window=0.5)
    for case in ch3.REPRODUCTION.cases:
        path = tmp_path / f"{case}.toml"
        save(CompositionSpec(compose(ch3.REPRODUCTION.composition(config, case))), path)
        assert main(["run", str(path), "--out", str(tmp_path / case)]) == 0
        _, reproduced = ch3.simulate_run(config, case, progress=segmented_progress)
        with xr.open_dataset(tmp_path / case / "run.nc") as ran:
            compared = [name for name, variable in ran.data_vars.items() if variable.dtype.kind == "f"]
            for name in compared:
                np.testing.assert_array_equal(ran[name].values, reproduced[name].values, err_msg=f"{case}: {name}")
        assert {"joint_angle", "joint_rate", "filtered_regressor_inertia" if case.startswith("sim2") else "mass_hat"} <= set(compared), case


def test_bad_settings_of_the_config_name_the_field():
    for fields, message in (
        ({"plant_step": 3e-3}, r"sample_period\n.*must be a whole multiple of plant_step \(0.003 s\); got 0.01 s"),
        ({"pe_window": 0.0}, "must be a finite positive number"),
        ({"filter_pole": -1.0}, "must be a finite positive number"),
        ({"input_amplitude": 0.0}, "must be a finite nonzero number"),
        ({"input_frequency": float("nan")}, "must be a finite positive number"),
    ):
        with pytest.raises(ValueError, match=message):
            ch3.Config(**fields)
    assert np.isclose(ch3.Config().duration, 60.0)
