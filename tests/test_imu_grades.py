"""IMU grades (lookout.sensing.imu_grades) and the IMU's turn-on and drifting biases: the
grades' SI figures against their datasheet units converted here, a grade's white noise
per sample and the values that win over it, the drift's stationary spread and
autocorrelation over many seeds against a first-order Gauss-Markov process, the turn-on
bias's spread over seeds and its constancy through a run, the IMU without either as it
was, the refusals, and a scenario file that names a grade."""

from __future__ import annotations

import math
import tomllib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout._validation import ParameterError
from lookout.scenario.composition import CompositionError, compose
from lookout.scenario.file import from_document
from lookout.sensing.imu_grades import GRADE_NAMES, GRADES, imu_grade
from lookout.sensing.motion import InertialUnit
from lookout.sim import keys_of_seeds, simulate

G0 = 9.80665  # m/s2 per g
DEG = math.pi / 180.0


def _kinematics(acceleration=(0.0, 0.0), yaw_rate: float = 0.0, yaw_acceleration: float = 0.0) -> dict:
    return {
        "position": jnp.zeros(2),
        "heading": jnp.asarray(0.0),
        "velocity": jnp.zeros(2),
        "yaw_rate": jnp.asarray(yaw_rate),
        "acceleration": jnp.asarray(acceleration),
        "yaw_acceleration": jnp.asarray(yaw_acceleration),
    }


# ----------------------------------------------------------------------------------
# (a) the grades: datasheet units converted


#: grade -> (accelerometer noise density m/s2/sqrt(Hz), gyro noise density rad/s/sqrt(Hz),
#: accelerometer turn-on bias m/s2, gyro turn-on bias rad/s, accelerometer in-run bias
#: instability m/s2, gyro in-run bias instability rad/s), each from its datasheet units;
#: the figure a source does not give is a tenth (in-run) or ten times (turn-on) the one
#: it gives (Groves 2013, Section 4.4.1)
DATASHEET = {
    # 400 micro-g/sqrt(Hz); 3 deg/sqrt(h); 1000 micro-g; 0.1 deg/s (turn-on)
    "consumer": (400e-6 * G0, 3.0 * DEG / 60.0, 1000e-6 * G0, 0.1 * DEG, 100e-6 * G0, 0.01 * DEG),
    # 120 micro-g/sqrt(Hz); 0.007 deg/s/sqrt(Hz); 0.03 mg; 10 deg/h (in-run)
    "industrial": (120e-6 * G0, 0.007 * DEG, 0.3e-3 * G0, 100.0 * DEG / 3600.0, 0.03e-3 * G0, 10.0 * DEG / 3600.0),
    # 0.065 ft/s/sqrt(h); 0.125 deg/sqrt(h); 1 mg; 1 deg/h (turn-on)
    "tactical": (0.065 * 0.3048 / 60.0, 0.125 * DEG / 60.0, 1e-3 * G0, 1.0 * DEG / 3600.0, 0.1e-3 * G0, 0.1 * DEG / 3600.0),
    # 0.02 ft/s/sqrt(h) (a class figure); 0.002 deg/sqrt(h); 25 micro-g; 0.0035 deg/h (turn-on)
    "navigation": (0.02 * 0.3048 / 60.0, 0.002 * DEG / 60.0, 25e-6 * G0, 0.0035 * DEG / 3600.0, 2.5e-6 * G0, 0.00035 * DEG / 3600.0),
}


@pytest.mark.parametrize("name", list(DATASHEET))
def test_each_grade_holds_its_datasheet_figures_in_si_units(name):
    grade = GRADES[name]
    got = (
        grade.accelerometer_noise_density,
        grade.gyro_noise_density,
        grade.accelerometer_turn_on_bias,
        grade.gyro_turn_on_bias,
        grade.accelerometer_bias_instability,
        grade.gyro_bias_instability,
    )
    np.testing.assert_allclose(got, DATASHEET[name], rtol=1e-12, atol=0)
    assert grade.name == name and grade.bias_time_constant == 3600.0 and grade.source


def test_the_grades_are_the_four_named_and_each_better_than_the_one_before_in_its_gyro():
    assert GRADE_NAMES == ("consumer", "industrial", "tactical", "navigation") and imu_grade("tactical") is GRADES["tactical"]
    for figure in ("gyro_bias_instability", "gyro_turn_on_bias", "gyro_noise_density"):
        values = [getattr(GRADES[name], figure) for name in GRADE_NAMES]
        assert values == sorted(values, reverse=True), figure


# ----------------------------------------------------------------------------------
# (b) a grade's white noise per sample, and the values that win over it


@pytest.mark.parametrize("period", [0.1, 0.25])
def test_a_grade_gives_density_over_root_period_per_sample_its_turn_on_bias_and_its_drift(period):
    unit = InertialUnit(grade="tactical", sample_period=period)
    vrw, arw, accelerometer_turn_on, gyro_turn_on, accelerometer_bias, gyro_bias = DATASHEET["tactical"]
    np.testing.assert_allclose(float(unit.accelerometer_std), vrw / math.sqrt(period), rtol=1e-12)
    np.testing.assert_allclose(float(unit.gyro_std), arw / math.sqrt(period), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(unit.bias_drift.std), [accelerometer_bias, accelerometer_bias, gyro_bias], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(unit.turn_on_std), [accelerometer_turn_on, accelerometer_turn_on, gyro_turn_on], rtol=1e-12)
    assert float(unit.bias_drift.time_constant) == 3600.0 and unit.bias_drift.step == period
    assert unit.noise_count == 9 and unit.drifting and unit.turned_on
    # R of a filter that models no bias: the white noise widened by the turn-on spread and
    # the drift's stationary spread
    random_bias = np.hypot([accelerometer_bias, accelerometer_bias, gyro_bias], [accelerometer_turn_on, accelerometer_turn_on, gyro_turn_on])
    np.testing.assert_allclose(np.asarray(unit.measurement_std()), np.hypot(np.asarray(unit.noise_std()), random_bias), rtol=1e-12)


def test_values_given_win_over_the_grades():
    vrw, arw, _, _, accelerometer_bias, _ = DATASHEET["industrial"]
    unit = InertialUnit(grade="industrial", accelerometer_std=0.05, gyro_bias_std=0.0, bias_time_constant=100.0)
    assert float(unit.accelerometer_std) == 0.05 and float(unit.bias_drift.time_constant) == 100.0
    np.testing.assert_allclose(float(unit.gyro_std), arw / math.sqrt(0.1), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(unit.bias_drift.std), [accelerometer_bias, accelerometer_bias, 0.0], rtol=1e-12)
    other = InertialUnit(grade="navigation", gyro_std=0.002, accelerometer_bias_std=[0.001, 0.003])
    np.testing.assert_allclose(float(other.accelerometer_std), DATASHEET["navigation"][0] / math.sqrt(0.1), rtol=1e-12)
    assert float(other.gyro_std) == 0.002
    np.testing.assert_allclose(np.asarray(other.bias_drift.std), [0.001, 0.003, DATASHEET["navigation"][5]], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(other.turn_on_std), [DATASHEET["navigation"][2]] * 2 + [DATASHEET["navigation"][3]], rtol=1e-12)
    steady = InertialUnit(grade="tactical", accelerometer_turn_on_std=[0.0, 0.02], gyro_turn_on_std=0.0)
    np.testing.assert_allclose(np.asarray(steady.turn_on_std), [0.0, 0.02, 0.0], rtol=1e-12)
    quiet = InertialUnit(grade="consumer", accelerometer_bias_std=0.0, gyro_bias_std=0.0, accelerometer_turn_on_std=0.0, gyro_turn_on_std=0.0)
    assert quiet.noise_count == 3 and quiet.initial_memory(_kinematics()) == ()


def test_without_a_grade_the_defaults_are_as_documented():
    unit = InertialUnit()
    assert float(unit.accelerometer_std) == 0.01 and float(unit.gyro_std) == 0.001
    np.testing.assert_array_equal(np.asarray(unit.bias_drift.std), np.zeros(3))
    np.testing.assert_array_equal(np.asarray(unit.turn_on_std), np.zeros(3))
    assert float(unit.bias_drift.time_constant) == 3600.0
    drifting = InertialUnit(accelerometer_bias_std=0.002)  # one number for both accelerometers
    np.testing.assert_array_equal(np.asarray(drifting.bias_drift.std), [0.002, 0.002, 0.0])
    assert drifting.noise_count == 6 and float(drifting.accelerometer_std) == 0.01


# ----------------------------------------------------------------------------------
# (c) the drift over many seeds: a first-order Gauss-Markov process, stationary from
# its first sample

SEEDS, SAMPLES, PERIOD, TAU = 20000, 41, 0.1, 2.0
DRIFT_STD = np.array([0.02, 0.05, 0.003])
TURN_ON_STD = np.array([0.04, 0.01, 0.002])
#: standard errors allowed: the tolerances are this many standard errors of each
#: estimate over SEEDS independent runs (a false failure has odds of about 6e-5 each)
Z = 4.0


def _random_biases(unit: InertialUnit, seed: int) -> np.ndarray:
    """The IMU's value less its expected sample, (SEEDS, SAMPLES, 3), at rest and without
    white noise or constant bias: its random biases alone, from emit vmapped over seeds."""
    kinematics = _kinematics()

    def run(key):
        normals = jax.random.normal(key, (SAMPLES, unit.noise_count))

        def step(memory, drawn):
            memory, value, white = unit.emit(memory, kinematics, drawn)
            return memory, (value - unit.expected(kinematics), white)

        _, (values, white) = jax.lax.scan(step, unit.initial_memory(kinematics), normals)
        return values, white

    values, white = jax.jit(jax.vmap(run))(jax.random.split(jax.random.key(seed), SEEDS))
    np.testing.assert_array_equal(np.asarray(white), 0.0)
    return np.asarray(values)


def _noiseless(drift: bool, turn_on: bool) -> InertialUnit:
    """An IMU without white noise at PERIOD: with the drift of DRIFT_STD and TAU, and the
    turn-on bias of TURN_ON_STD, where asked."""
    drifts = {"accelerometer_bias_std": DRIFT_STD[:2], "gyro_bias_std": float(DRIFT_STD[2]), "bias_time_constant": TAU} if drift else {}
    turns_on = {"accelerometer_turn_on_std": TURN_ON_STD[:2], "gyro_turn_on_std": float(TURN_ON_STD[2])} if turn_on else {}
    return InertialUnit(accelerometer_std=0.0, gyro_std=0.0, sample_period=PERIOD, **drifts, **turns_on)


@pytest.fixture(scope="module")
def drift() -> np.ndarray:
    """The drift alone: an IMU without a turn-on bias."""
    unit = _noiseless(drift=True, turn_on=False)
    assert unit.noise_count == 6
    return _random_biases(unit, 20)


@pytest.mark.parametrize("sample", [0, 1, 10, SAMPLES - 1])
def test_the_drift_has_its_stationary_spread_from_the_first_sample(drift, sample):
    """The variance over seeds (the mean known, 0) is sigma^2 within Z standard errors,
    sqrt(2 / N) relative; the mean is 0 within Z sigma / sqrt(N)."""
    x = drift[:, sample, :]
    variance = np.mean(x**2, axis=0) / DRIFT_STD**2
    assert np.all(np.abs(variance - 1.0) < Z * math.sqrt(2.0 / SEEDS)), variance
    assert np.all(np.abs(x.mean(axis=0)) < Z * DRIFT_STD / math.sqrt(SEEDS)), x.mean(axis=0)


@pytest.mark.parametrize(("start", "lag"), [(0, 1), (0, 10), (0, 30), (10, 30)])
def test_the_drifts_autocorrelation_is_exp_of_minus_lag_over_its_time_constant(drift, start, lag):
    """E[e_i e_(i+k)] / sigma^2 = exp(-k h / T): the mean of the product over N seeds has
    a standard error sqrt((1 + rho^2) / N) (of a bivariate normal of unit variance)."""
    rho = math.exp(-lag * PERIOD / TAU)
    estimate = np.mean(drift[:, start, :] * drift[:, start + lag, :], axis=0) / DRIFT_STD**2
    assert np.all(np.abs(estimate - rho) < Z * math.sqrt((1.0 + rho**2) / SEEDS)), (estimate, rho)


# ----------------------------------------------------------------------------------
# (d) the turn-on bias: drawn once, constant through the run


def test_the_turn_on_bias_is_constant_through_a_run_with_its_spread_over_seeds():
    """Turn-on bias alone: each seed's bias the same at every sample, bit for bit; over
    seeds, mean 0 and variance TURN_ON_STD^2 (Z standard errors), the channels
    uncorrelated."""
    unit = _noiseless(drift=False, turn_on=True)
    assert unit.noise_count == 6 and unit.turned_on and not unit.drifting
    biases = _random_biases(unit, 21)
    np.testing.assert_array_equal(biases, np.broadcast_to(biases[:, :1, :], biases.shape))
    x = biases[:, 0, :]
    assert np.all(np.abs(np.mean(x**2, axis=0) / TURN_ON_STD**2 - 1.0) < Z * math.sqrt(2.0 / SEEDS))
    assert np.all(np.abs(x.mean(axis=0)) < Z * TURN_ON_STD / math.sqrt(SEEDS))
    correlation = np.corrcoef(x.T)[np.triu_indices(3, 1)]
    assert np.all(np.abs(correlation) < Z / math.sqrt(SEEDS)), correlation


def test_with_both_the_bias_spreads_by_both_and_changes_by_the_drift_alone():
    """Turn-on bias and drift: the variance at a sample is the sum of theirs; the change
    between two samples k apart has the drift's variance 2 sigma_d^2 (1 - exp(-k h / T))."""
    unit = _noiseless(drift=True, turn_on=True)
    assert unit.noise_count == 9
    biases = _random_biases(unit, 22)
    for sample in (0, SAMPLES - 1):
        variance = np.mean(biases[:, sample, :] ** 2, axis=0) / (DRIFT_STD**2 + TURN_ON_STD**2)
        assert np.all(np.abs(variance - 1.0) < Z * math.sqrt(2.0 / SEEDS)), variance
    change = biases[:, 30, :] - biases[:, 0, :]
    expected = 2.0 * DRIFT_STD**2 * (1.0 - math.exp(-30 * PERIOD / TAU))
    assert np.all(np.abs(np.mean(change**2, axis=0) / expected - 1.0) < Z * math.sqrt(2.0 / SEEDS))


# ----------------------------------------------------------------------------------
# (e) without random biases: the IMU as it was


def test_an_imu_without_a_drift_draws_three_normals_keeps_no_memory_and_emits_as_before():
    """noise_count 3, memory (), and each sample the expected one plus the constant
    biases plus std * normals, bit for bit, as an IMU of constant biases gave it."""
    kinematics = _kinematics(acceleration=(0.3, -0.2), yaw_rate=0.05, yaw_acceleration=-0.01)
    normals = jnp.asarray(np.random.default_rng(4).normal(size=3))
    for unit, std, bias in (
        (InertialUnit(), [0.01, 0.01, 0.001], [0.0, 0.0, 0.0]),
        (
            InertialUnit(lever_arm=(10.0, -2.0), accelerometer_std=0.02, gyro_std=0.004, accelerometer_bias=(0.01, -0.02), gyro_bias=0.001),
            [0.02, 0.02, 0.004],
            [0.01, -0.02, 0.001],
        ),
    ):
        assert unit.noise_count == 3 and not unit.drifting
        memory = unit.initial_memory(kinematics)
        assert memory == ()
        memory, value, white = unit.emit(memory, kinematics, normals)
        assert memory == ()
        np.testing.assert_array_equal(np.asarray(value), np.asarray(unit.expected(kinematics) + jnp.asarray(bias)))
        np.testing.assert_array_equal(np.asarray(white), np.asarray(jnp.asarray(std) * normals))
        np.testing.assert_array_equal(np.asarray(unit.measurement_std()), std)


# ----------------------------------------------------------------------------------
# (f) refusals


def test_an_unknown_grade_is_refused_at_grade():
    with pytest.raises(ParameterError) as raised:
        InertialUnit(grade="x")
    assert raised.value.location == ("grade",)
    assert str(raised.value) == "grade must be one of consumer, industrial, tactical, navigation; got 'x'"


@pytest.mark.parametrize(
    ("keywords", "name"),
    [
        ({"accelerometer_bias_std": -0.01}, "accelerometer_bias_std"),
        ({"accelerometer_bias_std": [0.01, -0.01]}, "accelerometer_bias_std"),
        ({"accelerometer_bias_std": [0.01, 0.01, 0.01]}, "accelerometer_bias_std"),
        ({"gyro_bias_std": -0.001}, "gyro_bias_std"),
        ({"gyro_bias_std": -0.001, "grade": "tactical"}, "gyro_bias_std"),
        ({"bias_time_constant": 0.0}, "bias_time_constant"),
        ({"accelerometer_turn_on_std": -0.01}, "accelerometer_turn_on_std"),
        ({"accelerometer_turn_on_std": [0.01, 0.01, 0.01]}, "accelerometer_turn_on_std"),
        ({"gyro_turn_on_std": -0.001, "grade": "navigation"}, "gyro_turn_on_std"),
    ],
)
def test_a_bad_drift_is_refused_naming_its_parameter(keywords, name):
    with pytest.raises(ParameterError) as raised:
        InertialUnit(**keywords)
    assert raised.value.location == (name,) and str(raised.value).startswith(f"{name} must be"), str(raised.value)


# ----------------------------------------------------------------------------------
# (g) a scenario file that names a grade

SCENARIO = """\
[simulation]
duration = 2.0
plant_step = 0.1
sample_period = 0.1

[plant]
kind = "dp-vessel"
[plant.bias]
time_constant = 1000.0
std = [0.0, 0.0, 0.0]
[plant.waves]
kind = "linear"
peak_frequency = 0.8976
damping_ratio = 0.1
amplitude = [0.0, 0.0, 0.0]
[plant.initial]
eta = [0.0, 0.0, 0.0]
nu = [0.5, 0.0, 0.01]

[sensors.dgnss1]
kind = "gnss"
noise_std = 0.5

[sensors.gyro1]
kind = "gyrocompass"

[sensors.imu]
kind = "imu"
grade = "tactical"
accelerometer_std = 0.0
gyro_std = 0.0

[sensors.imu0]
kind = "imu"
accelerometer_std = 0.0
gyro_std = 0.0

[observer]
kind = "passive"
"""


@pytest.mark.slow
def test_a_scenario_file_with_a_grade_loads_and_its_imu_drifts_from_a_stationary_draw():
    """``grade = "tactical"``: the suite's IMU has the grade's turn-on bias and drift, the
    values given win, and the file's spelled-out sensors keep the grade. Run: the
    tactical IMU less the one without random biases (both without white noise, at one
    point) is the turn-on bias plus the drift, nonzero from the first sample, within Z
    of their spread, and hardly moving over 2 s of a one hour time constant (each step
    within Z sigma_d sqrt(2 (1 - a^k)))."""
    composition = from_document(tomllib.loads(SCENARIO)).composition
    suite = composition.scenario.sensor
    imu = suite.instruments[suite.names.index("imu")]
    assert isinstance(imu, InertialUnit) and imu.noise_count == 9 and float(imu.accelerometer_std) == 0.0
    np.testing.assert_allclose(np.asarray(imu.bias_drift.std), [1e-4 * G0, 1e-4 * G0, 0.1 * DEG / 3600.0], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(imu.turn_on_std), [1e-3 * G0, 1e-3 * G0, DEG / 3600.0], rtol=1e-12)
    assert composition.document["sensors"]["imu"]["grade"] == "tactical"
    ds = simulate(composition.scenario, keys_of_seeds([5])[0]).to_xarray()
    ds = ds.isel(run=0) if "run" in ds.dims else ds
    drift = np.column_stack(
        [
            np.asarray(ds["imu.measured_specific_force"].values) - np.asarray(ds["imu0.measured_specific_force"].values),
            np.asarray(ds["imu.measured_yaw_rate"].values) - np.asarray(ds["imu0.measured_yaw_rate"].values),
        ]
    )
    drift = drift[np.all(np.isfinite(drift), axis=1)]
    std = np.asarray(imu.bias_drift.std)
    assert len(drift) >= 19 and np.all(drift[0] != 0.0) and np.all(np.abs(drift[0]) < Z * np.hypot(std, np.asarray(imu.turn_on_std)))
    k = np.arange(len(drift))[:, None]
    bound = Z * std * np.sqrt(2.0 * (1.0 - np.exp(-k * 0.1 / 3600.0)))
    assert np.all(np.abs(drift - drift[0]) <= bound + 1e-15)


def test_a_scenario_file_with_an_unknown_grade_is_refused_at_its_key():
    text = SCENARIO.replace('grade = "tactical"', 'grade = "military"')
    with pytest.raises(CompositionError) as raised:
        compose(tomllib.loads(text))
    assert str(raised.value).startswith("sensors.imu.grade: "), str(raised.value)
