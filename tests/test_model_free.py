"""The observer without a hull model (lookout.observers.model_free on
lookout.models.kinematic_vessel): its tuning rule against SciPy's Riccati solution, the
model's kinematics, speed and course over ground on a simulated vessel in waves, and
its refusals."""

from __future__ import annotations

import math
import tomllib

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from lookout import PositionHeadingSensor
from lookout.models.kinematic_vessel import KinematicVessel
from lookout.observers.model_free import ModelFreeFilter, acceleration_intensity
from lookout.scenario.composition import compose, simulate

SCENARIO = """
preset = "fossen-strand-1999:paper"

[simulation]
duration = 300.0
runs = 4

[sensor]
kind = "position-heading"
noise_std = [0.5, 0.5, 0.0017453292519943296]
sample_period = [1.0, 1.0, 0.1]

[observer]
kind = "model-free"
wave_period = 7.0
wave_std = [3.3, 3.3, 0.0058]
"""


@pytest.mark.parametrize("settling_time", [5.0, 20.0, 60.0])
def test_the_tuning_rule_gives_the_settling_time_it_is_asked_for(settling_time):
    """For x' = v, v' = sqrt(q) w, y = x + noise of density r = sigma^2 T, SciPy's
    steady-state Kalman-Bucy filter has the poles of s^2 + sqrt(2) w s + w^2 with
    w = 4 sqrt(2) / settling_time: damping 1/sqrt(2), 2 % settling in settling_time."""
    sigma, period = 0.5, 1.0
    r = sigma**2 * period
    q = acceleration_intensity(r, settling_time)
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    h = np.array([[1.0, 0.0]])
    p = scipy.linalg.solve_continuous_are(a.T, h.T, np.diag([0.0, q]), np.array([[r]]))
    gain = p @ h.T / r
    poles = np.linalg.eigvals(a - gain @ h)
    omega = 4.0 * math.sqrt(2.0) / settling_time
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(np.roots([1.0, math.sqrt(2.0) * omega, omega**2])), rtol=1e-9)
    assert np.all(poles.real == pytest.approx(-4.0 / settling_time, rel=1e-9))  # zeta omega = 4 / t_s


def test_the_kinematic_model_moves_with_its_velocity_and_measures_eta_plus_waves():
    model = KinematicVessel((0.01, 0.01, 0.001))
    state = model.state(eta=[1.0, 2.0, math.pi / 2], nu=[3.0, 0.5, 0.1])
    rates = model.vector_field(0.0, state, jnp.zeros(3), jnp.zeros(3))
    np.testing.assert_allclose(rates.eta, [-0.5, 3.0, 0.1], atol=1e-15)  # R(psi) nu at psi = 90 degrees
    np.testing.assert_array_equal(rates.nu, np.zeros(3))
    kinematics = model.kinematics(0.0, state, jnp.zeros(3))
    np.testing.assert_array_equal(kinematics["position"], [1.0, 2.0])
    assert set(model.variables(state)) == {"position", "heading", "velocity", "yaw_rate"}
    with pytest.raises(ValueError, match="acceleration_std"):
        KinematicVessel((0.01, -0.01, 0.001))


@pytest.mark.slow
def test_speed_and_course_over_ground_without_a_hull_model():
    """The Northern Clipper in the paper's sea (Fossen & Strand 1999's preset), observed
    with no M, D or bias: after 60 s, on seeds 0-3, the speed over ground's RMS error is
    within 0.06 m/s (measured 0.048-0.049) of a speed of about 0.15 m/s, and the course
    over ground's within 40 degrees (measured 20-34: at 0.15 m/s a velocity error of 0.05
    m/s turns the course by 20 degrees; the course of a vessel that hardly moves is
    hardly defined)."""
    ds = simulate(compose(tomllib.loads(SCENARIO))).to_xarray()
    after = ds["time"].values >= 60.0

    def over_ground(velocity, heading):
        north = np.cos(heading) * velocity[..., 0] - np.sin(heading) * velocity[..., 1]
        east = np.sin(heading) * velocity[..., 0] + np.cos(heading) * velocity[..., 1]
        return np.hypot(north, east), np.degrees(np.arctan2(east, north))

    speed, course = over_ground(ds["velocity"].values, ds["heading"].values)
    speed_hat, course_hat = over_ground(ds["velocity_hat"].values, ds["heading_hat"].values)
    speed_error = np.sqrt(np.mean((speed_hat - speed)[:, after] ** 2, axis=1))
    course_error = np.sqrt(np.mean(((course_hat - course + 180.0) % 360.0 - 180.0)[:, after] ** 2, axis=1))
    assert np.all(speed_error < 0.06), speed_error
    assert np.all(course_error < 40.0), course_error
    assert 0.1 < np.mean(speed[:, after]) < 0.2


@pytest.mark.parametrize(
    "options, message",
    [
        ({"settling_time": 0.0}, "settling_time must be a finite positive number of seconds"),
        ({"settling_time": math.inf}, "settling_time must be a finite positive number of seconds"),
        ({"wave_period": 7.0}, "wave_period and wave_std go together"),
        ({"wave_period": -7.0, "wave_std": [1.0, 1.0, 0.01]}, "wave_period"),
        ({"measurement_noise": [0.5, 0.5]}, "measurement_noise must be 3 finite standard deviations > 0"),
        ({"measurement_noise": [0.5, 0.5, 0.0]}, "measurement_noise must be 3 finite standard deviations > 0"),
    ],
)
def test_refusals_name_the_parameter(options, message):
    sensor = PositionHeadingSensor((0.5, 0.5, 0.002), (1.0, 1.0, 0.1))
    with pytest.raises(ValueError, match=message):
        ModelFreeFilter(sensor, plant_step=0.1, filter_period=0.1, **options)
