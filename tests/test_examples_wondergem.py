"""The example scenario files around Wondergem et al. (2009): its observer and tracking
scheme on the Northern Clipper, and Fossen & Strand's passive observer on Cybership II."""

import copy
from pathlib import Path

import jax
import numpy as np

from lookout.environment.jonswap import peak_frequency
from lookout.models.cybership import Cybership
from lookout.models.vessel import NORTHERN_CLIPPER_D, NORTHERN_CLIPPER_M
from lookout.scenario.composition import compose, set_path
from lookout.scenario.file import load
from lookout.sim import simulate

EXAMPLES = Path(__file__).parents[1] / "examples"


def _first_20_seconds(name: str):
    """The example's scenario (as the file builds it) and its first 20 s simulated."""
    spec = load(EXAMPLES / name)
    document = copy.deepcopy(spec.document())
    set_path(document, "simulation.duration", 20.0)
    short = compose(document).scenario
    assert short.duration == 20.0
    ds = simulate(short, jax.random.key(0)).to_xarray().isel(run=0)
    estimates = [variable for variable in ds.data_vars if variable.endswith("_hat")]
    assert len(estimates) >= 4 and all(bool(np.isfinite(ds[each]).all()) for each in estimates)
    return spec.build(), ds


def test_wondergem_scheme_on_the_northern_clipper_takes_the_plants_m_and_d():
    scenario, ds = _first_20_seconds("wondergem-northern-clipper.toml")
    ship = scenario.observer.ship
    assert isinstance(ship, Cybership) and scenario.controller.ship is ship  # the controller takes the observer's model
    np.testing.assert_array_equal(ship.mass_matrix, NORTHERN_CLIPPER_M)
    np.testing.assert_array_equal(ship.damping_matrix, NORTHERN_CLIPPER_D)
    np.testing.assert_array_equal(ship.quadratic_damping, np.zeros(3))
    np.testing.assert_array_equal(scenario.actuator.limit, [5.0e5, 3.0e5, 1.0e7])
    assert float(np.abs(ds.force_commanded).max()) > 0  # the scheme drives the vessel


def test_passive_observer_on_cybership_ii_is_tuned_for_the_plants_sea():
    scenario, ds = _first_20_seconds("passive-cybership.toml")
    observer, waves = scenario.observer, scenario.plant.waves
    np.testing.assert_allclose(observer.wave_frequency, peak_frequency(waves.mean_period), rtol=1e-15)
    np.testing.assert_array_equal(observer.mass_matrix, scenario.plant.ship.mass_matrix)
    assert float(np.abs(ds.wave_position).max()) > 0  # the sea reaches the measurement
