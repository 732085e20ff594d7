"""Compositions (lookout.scenario.composition) and the component registry (lookout.scenario.registry):
schemas from the components' declarations, presets with parts replaced, parts that do
not fit refused in one line naming both, a model-based part taking the plant's model."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from lookout.components import Actuator, Controller, Observer, Plant, Reference, Sensor
from lookout.papers import fossen_strand_1999 as fs
from lookout.scenario import registry
from lookout.scenario.composition import CompositionError, compose
from lookout.sim import simulate

ROLES = {"plant": Plant, "sensor": Sensor, "observer": Observer, "controller": Controller, "reference": Reference, "actuator": Actuator}
SHORT = {"simulation": {"duration": 20.0}}


def test_every_kind_documents_every_parameter_it_takes():
    """Each parameter a file may give has a type and a description in its declaration
    (else `lookout components` could not say what it is)."""
    missing = []
    for each in registry.kinds():
        assert each.description, (each.role, each.name)
        for design in each.designs or [None]:
            for p in each.parameters(design):
                if not (p.type and p.description) or (p.sort == "value" and not p.value_type):
                    missing.append(f"{each.role} {each.name} {design or ''}: {p.name} (type {p.type!r})")
    assert not missing, missing


def test_every_component_kind_builds_a_component_of_its_role():
    for role, base in ROLES.items():
        for each in registry.kinds(role):
            assert issubclass(each.component_class, base), (role, each.name, each.component_class)


def test_a_declared_range_is_checked_under_the_files_key():
    (probability,) = [p for p in registry.kind("sensor", "position-heading").parameters() if p.name == "dropout_probability"]
    assert probability.range == (0.0, 1.0, True, False)
    with pytest.raises(CompositionError) as raised:
        compose({"preset": "fossen-strand-1999", "sensor": {"dropout_probability": 1.0}})
    assert raised.value.location == ("sensor", "dropout_probability")
    assert str(raised.value) == "sensor.dropout_probability: must be in [0, 1); got 1.0"


def test_the_preset_is_the_reproductions_scenario():
    composed = compose({"preset": "fossen-strand-1999"}).scenario
    built = fs.build(fs.Config())
    assert jax.tree.structure(composed) == jax.tree.structure(built)
    for a, b in zip(jax.tree.leaves(composed), jax.tree.leaves(built)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_a_preset_with_one_component_replaced_runs():
    """Kim's sliding-mode observer in Fossen & Strand's study, by its kind alone: the
    gains are the design rule's for the plant's own vessel and sea."""
    composition = compose({"preset": "fossen-strand-1999", **SHORT, "observer": {"kind": "sliding-mode", "switching_gain": [0.1, 0.1, 0.001]}})
    assert composition.kinds == {**compose({"preset": "fossen-strand-1999"}).kinds, "observer": "sliding-mode"}
    observer = composition.scenario.observer
    # the model is the plant's, the wave model the plant's wave frequency
    np.testing.assert_array_equal(observer.passive.mass_matrix, composition.scenario.plant.vessel.mass_matrix)
    np.testing.assert_array_equal(observer.passive.wave_frequency, composition.scenario.plant.waves.peak_frequency)
    trajectory = simulate(composition.scenario, jax.random.key(0))
    assert all(np.isfinite(np.asarray(leaf)).all() for leaf in jax.tree.leaves(trajectory.estimate))


def test_the_observers_model_is_the_plants_unless_its_table_gives_one():
    plain = compose({"preset": "fossen-strand-1999"}).scenario
    heavier = (1.2 * np.asarray(plain.plant.vessel.mass_matrix)).tolist()
    damping = np.asarray(plain.plant.vessel.damping_matrix).tolist()
    erred = compose(
        {"preset": "fossen-strand-1999", "observer": {"vessel": {"kind": "custom", "mass_matrix": heavier, "damping_matrix": damping}}}
    ).scenario
    np.testing.assert_array_equal(erred.plant.vessel.mass_matrix, plain.plant.vessel.mass_matrix)
    np.testing.assert_allclose(erred.observer.mass_matrix, heavier, rtol=1e-15)


@pytest.mark.parametrize(
    "change, location, message",
    [
        # a controller for another ship: the plant has no model of that kind
        (
            {"controller": {"kind": "tracking"}},
            ("controller",),
            "controller tracking needs a ship (Cybership), and plant dp-vessel has none; give [controller.ship]",
        ),
        # a tracking law without a reference: the missing signal and both parts
        (
            {
                "controller": {
                    "kind": "observer-backstepping",
                    "integral_gain": 0.0,
                    "position_gain": 0.1,
                    "velocity_gain": 0.1,
                    "damping_weights": 0.0,
                }
            },
            ("controller",),
            "controller observer-backstepping needs reference position_desired, which reference none does not provide (it gives nothing)",
        ),
        # an observer of a manipulator on a vessel: it reads what the sensor does not measure
        (
            {"observer": {"kind": "velocity", "model": {"kind": "pendulum"}, "gain": 1.0}},
            ("observer",),
            "observer velocity needs measurement measured_joint_angle, which sensor position-heading does not measure (it measures measured_position, measured_heading)",
        ),
        ({"sensor": {"kind": "joint-encoder", "sample_period": 1.0}}, ("sensor",), "sensor joint-encoder needs a model ("),
        ({"observer": {"kind": "nope"}}, ("observer", "kind"), "observer.kind: no observer kind 'nope' (one of passive, "),
        (
            {"observer": {"kind": "passive", "gain": 1.0}},
            ("observer", "gain"),
            "observer.gain: unknown key (observer passive takes: vessel, waves, wave_frequency",
        ),
        (
            {"controller": {"kind": "sinusoidal", "amplitude": 1.0, "frequency": 0.1, "observer": {}}},
            ("controller", "observer"),
            "controller.observer: unknown key",
        ),
    ],
)
def test_a_replaced_component_that_does_not_fit_is_refused_in_one_line_naming_it(change, location, message):
    with pytest.raises(CompositionError) as raised:
        compose({"preset": "fossen-strand-1999", **change})
    assert raised.value.location == location
    assert "\n" not in str(raised.value) and message in str(raised.value), str(raised.value)


def test_a_component_needing_another_of_a_type_names_both():
    """Kim's backstepping reads a wave-filtering observer's gains: it says so, and names
    the observer that is not one (not the isinstance test of a concrete class)."""
    document = {
        "preset": "fossen-strand-1999",
        "plant": {"kind": "cybership-ii"},
        "observer": {"kind": "earth-fixed", "position_gain": 1.0, "velocity_gain": 1.0},
        "reference": {"kind": "ellipse", "semi_axes": [2.0, 1.0], "lap_speeds": [0.05]},
        "controller": {"kind": "observer-backstepping", "integral_gain": 0.0, "position_gain": 0.1, "velocity_gain": 0.1, "damping_weights": 0.0},
    }
    with pytest.raises(
        CompositionError,
        match=r"^controller: controller observer-backstepping needs an observer that is a WaveFilteringObserver; observer earth-fixed is not one$",
    ):
        compose(document)


def test_an_estimate_the_plant_does_not_model_is_recorded_without_a_truth():
    """The passive observer estimates a bias; Cybership II has none: the estimate is
    kept, and no error is taken of it."""
    composition = compose(
        {
            "preset": "fossen-strand-1999",
            **SHORT,
            "plant": {"kind": "cybership-ii"},
            "controller": {"kind": "sinusoidal", "amplitude": 0.1, "frequency": 0.1},
            "observer": {"kind": "passive", "wave_frequency": 5.0, "cutoff_frequency": 6.0},
        }
    )
    ds = simulate(composition.scenario, jax.random.key(0)).to_xarray()
    assert "bias_force_hat" in ds and "bias_force" not in ds
    assert np.isfinite(ds.position_hat).all()


def test_the_kinds_name_the_classes_they_build():
    scenario = compose({"preset": "fossen-strand-1999"}).scenario
    assert [registry.kind_of(getattr(scenario, role)) for role in ROLES] == [
        "dp-vessel",
        "position-heading",
        "passive",
        "sinusoidal",
        "none",
        "ideal",
    ]
