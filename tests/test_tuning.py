"""Tuning by gradient inside the papers' conditions (lookout.tuning): the gradient
through the simulation against central differences, the tuned gains against the
design command's own analysis, held-out seeds, and what is refused."""

from __future__ import annotations

import json
import re

import jax.numpy as jnp
import numpy as np
import pytest
from tuning_checks import gradient_and_central_differences

from lookout.cli import main
from lookout.scenario.composition import compose
from lookout.scenario.registry import preset
from lookout.sim import keys_of_seeds
from lookout.tuning.families import family_of
from lookout.tuning.families.passive import PassiveFamily
from lookout.tuning.tune import _objective_function, parse_objective

pytestmark = pytest.mark.xdist_group("tuning")


def _scenario(duration: float, **observer):
    document = preset("fossen-strand-1999", "paper")
    document["simulation"]["duration"] = duration
    document["observer"].update(observer)
    return document


def test_the_gradient_matches_central_differences_at_the_starting_gains():
    """Kappa, Lambda, w_c and zeta_n of the passive observer, through 200 s of two runs."""
    scenario = compose(_scenario(200.0)).scenario
    family = family_of(scenario)[0]
    assert isinstance(family, PassiveFamily)
    objective, metrics = parse_objective("rms_error:bias_force + 100*rms_error:position", scenario)
    value = _objective_function(scenario, family, objective, metrics, None)
    keys = keys_of_seeds([3, 4])
    theta = jnp.asarray(family.theta(family.current(scenario)))
    gradient, central = gradient_and_central_differences(value, family, theta, keys, 1e-5)
    np.testing.assert_allclose(gradient, central, rtol=1e-5, atol=1e-6 * np.abs(central).max())
    assert np.abs(gradient).min() > 0  # every parameter moves the objective


def test_the_parametrization_round_trips_and_stays_inside_48():
    scenario = compose(_scenario(100.0)).scenario
    family = family_of(scenario)[0]
    start = family.current(scenario)
    for given, back in zip(start, family.gains(jnp.asarray(family.theta(start)))):
        np.testing.assert_allclose(np.asarray(back), given, rtol=1e-12)
    rng = np.random.default_rng(0)
    for theta in rng.normal(scale=30.0, size=(50, 12)):  # far out: still inside the chain
        kappa, lam, cutoff, notch = (np.asarray(g) for g in family.gains(jnp.asarray(theta)))
        corner = lam / kappa
        assert np.all(10.0 / 1000.0 <= corner) and np.all(corner < 0.8976) and np.all(0.8976 < cutoff) and np.all(notch > 0.1)


def test_lookout_tune_improves_held_out_seeds_and_stays_inside_every_condition(tmp_path, capsys):
    """A short tuning of the bias estimate (4 training seeds, 300 s): the tuned file's
    observer, built again from it through the composition, satisfies (48) and SPR as the
    design command checks them, and the held-out seeds' median improves."""
    from lookout.analysis import check_passive_observer
    from lookout.scenario._toml import read, write

    source = tmp_path / "dp.toml"
    write(source, _scenario(300.0))
    out = tmp_path / "tuned"
    assert (
        main(
            [
                "tune",
                str(source),
                "--out",
                str(out),
                "--objective",
                "rms_error:bias_force",
                "--train-seeds",
                "4",
                "--test-seeds",
                "4",
                "--steps",
                "6",
                "--learning-rate",
                "0.2",
            ]
        )
        == 0
    )
    for name in ("tuned.toml", "tuning.json", "training.png", "held_out.png"):
        assert (out / name).exists(), name
    document, _ = read(out / "tuned.toml")
    observer = compose(document).scenario.observer
    report = check_passive_observer(observer)
    assert report.holds, report.verdicts
    summary = json.loads((out / "tuning.json").read_text())
    assert summary["conditions_after"]["holds"] and summary["conditions_before"]["holds"]
    np.testing.assert_allclose(
        np.asarray(observer.velocity_injection_gain), summary["gains"]["observer.velocity_injection_gain"]["tuned"], rtol=1e-12
    )
    medians = summary["held_out_median"]["rms_error:bias_force"]
    # measured: 2402 -> 2303 N (-4.1 %) on seeds 4..7, the tuner stopping at SPR's boundary after 5 steps
    assert medians["tuned"] <= 0.98 * medians["start"], medians
    assert summary["steps"][-1]["objective"] < summary["steps"][0]["objective"]
    # a refused step tried itself and BACKTRACKS halvings, and says that number wherever it is reported
    from lookout.tuning.tune import BACKTRACKS

    refused = [s for s in summary["steps"] if not s["accepted"]]
    assert refused and all(s["halvings"] == BACKTRACKS for s in refused), summary["steps"]
    assert all(s["halvings"] <= BACKTRACKS for s in summary["steps"])
    said = "".join(capsys.readouterr())
    assert {int(n) for n in re.findall(r"its (\d+) halvings", said)} == {BACKTRACKS}, said


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--objective", "settling_time:position"], "--objective: settling_time:position is not smooth in the gains"),
        (["--objective", "rms_error:speed"], "--objective: 'rms_error:speed': the observer estimates no 'speed'"),
        (["--objective", "-1*rms_error:position"], "--objective: the weight of rms_error:position must be a finite positive number; got -1"),
        (["--objective", "rms_error:position - rms_error:velocity"], "--objective: 'rms_error:position - rms_error:velocity' is not a term"),
        (["--train-seeds", "0"], "--train-seeds: must be a positive integer"),
        (["--learning-rate", "nan"], "--learning-rate must be a finite positive number"),
    ],
)
def test_bad_options_are_one_line(tmp_path, capsys, arguments, message):
    from lookout.scenario._toml import write

    source = tmp_path / "dp.toml"
    write(source, _scenario(100.0))
    assert main(["tune", str(source), "--out", str(tmp_path / "out"), *arguments]) == 2
    error = capsys.readouterr().err.strip()
    assert message in error and "\n" not in error, error
    assert not (tmp_path / "out").exists()


def test_a_scenario_whose_conditions_cannot_be_met_is_refused_naming_the_condition(tmp_path, capsys):
    """Bias time constants of 5 s: 10/T = 2 rad/s is above w_o, so no Kappa, Lambda
    satisfies (48)."""
    from lookout.scenario._toml import write

    source = tmp_path / "dp.toml"
    write(source, _scenario(100.0, bias_time_constant=[5.0, 5.0, 5.0]))
    assert main(["tune", str(source), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert "tuning rule (48): 10/T (2 rad/s) is not below w_o (0.8976 rad/s) in surge" in error and "\n" not in error, error


def test_an_observer_without_a_family_is_refused(tmp_path, capsys, monkeypatch):
    """(The registry without the passive family: every shipped observer has one.)"""
    from lookout.scenario._toml import write
    from lookout.tuning import families

    declared = families.families
    monkeypatch.setattr(families, "families", lambda role: {k: v for k, v in declared(role).items() if k != "passive"})
    document = _scenario(100.0)
    source = tmp_path / "dp.toml"
    write(source, document)
    assert main(["tune", str(source), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert "neither observer passive nor controller sinusoidal has a tunable family yet (tunable observers: " in error, error


def test_a_campaign_study_file_is_refused_naming_its_scenario(tmp_path, capsys):
    assert main(["tune", "examples/kim-model-error.toml", "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert "examples/kim-model-error.toml is a campaign's study (a sweep over kim-closed-loop.toml); tune its scenario" in error, error
    assert "\n" not in error and not (tmp_path / "out").exists()


def test_a_gradient_that_would_not_fit_in_memory_is_refused_before_it_runs(tmp_path, capsys, monkeypatch):
    """The compiled program's own memory analysis (the test's program is the CLI test's:
    the compilation cache serves it), against 100 MB available."""
    from lookout import _resources
    from lookout.scenario._toml import write

    monkeypatch.setattr(_resources, "available_memory", lambda: 100e6)
    source = tmp_path / "dp.toml"
    write(source, _scenario(300.0))
    assert (
        main(
            [
                "tune",
                str(source),
                "--out",
                str(tmp_path / "out"),
                "--objective",
                "rms_error:bias_force",
                "--train-seeds",
                "4",
                "--test-seeds",
                "4",
                "--steps",
                "6",
                "--learning-rate",
                "0.2",
            ]
        )
        == 2
    )
    error = capsys.readouterr().err.strip()
    assert "--train-seeds: a gradient over 4 runs would need about" in error and "use fewer training seeds or a shorter duration" in error, error
    assert "\n" not in error and not (tmp_path / "out").exists()


def test_the_tuner_runs_the_program_whose_gradient_the_checks_compare_with_central_differences(monkeypatch):
    """``tune`` builds its gradient with ``value_and_gradient``, the function whose program
    tests/tuning_checks.py compares with central differences: the checks test the
    tuner's own program (and a tune test of the same scenario loads it from the cache)."""
    import tuning_checks

    from lookout.tuning import tune as tune_module

    assert tuning_checks.value_and_gradient is tune_module.value_and_gradient
    built = []

    class Built(Exception):
        pass

    def recording(value, family):
        built.append(family)
        raise Built

    monkeypatch.setattr(tune_module, "value_and_gradient", recording)
    with pytest.raises(Built):
        tune_module.tune(compose(_scenario(100.0)).scenario, "rms_error:position", train_seeds=[0], test_seeds=[1], say=lambda _: None)
    assert len(built) == 1 and isinstance(built[0], PassiveFamily)
