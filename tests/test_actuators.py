"""Actuators: the ideal one, and symmetric per-entry saturation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from lookout.actuators import IdealActuator, SaturatingActuator
from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_THRUST_LIMIT
from lookout.sim import Scenario, simulate

# XLA:CPU flushes subnormals to zero, so none are drawn
_finite = st.floats(-1e9, 1e9, allow_nan=False, allow_subnormal=False)
_limits = st.floats(1e-6, 1e9) | st.just(float("inf"))


def test_ideal_actuator_passes_the_command_through():
    u = jnp.array([1.0, -2.0, 3e9])
    np.testing.assert_array_equal(IdealActuator().apply(u), u)


@settings(max_examples=60)
@given(data=st.data(), n=st.integers(1, 6))
def test_applied_input_is_within_the_limits_and_equals_the_command_inside_them(data, n):
    limit = data.draw(arrays(float, n, elements=_limits))
    u = data.draw(arrays(float, n, elements=_finite))
    actuator = SaturatingActuator(limit)
    applied = np.asarray(actuator.apply(u))
    assert np.all(np.abs(applied) <= limit)
    inside = np.abs(u) <= limit
    np.testing.assert_array_equal(applied[inside], u[inside])
    np.testing.assert_array_equal(applied[~inside], np.sign(u[~inside]) * limit[~inside])
    np.testing.assert_array_equal(np.asarray(actuator.saturated(u)), ~inside)


def test_nan_command_stays_nan_and_is_not_counted_as_saturated():
    actuator = SaturatingActuator([1.0, 1.0, 1.0])
    u = jnp.array([np.nan, 5.0, -0.5])
    applied = np.asarray(actuator.apply(u))
    assert np.isnan(applied[0]) and applied[1] == 1.0 and applied[2] == -0.5
    assert actuator.saturated(u).tolist() == [False, True, False]


def test_infinite_limit_does_not_clip_and_scalar_limit_broadcasts():
    actuator = SaturatingActuator([np.inf, 2.0])
    np.testing.assert_array_equal(actuator.apply(jnp.array([-1e300, 5.0])), [-1e300, 2.0])
    np.testing.assert_array_equal(SaturatingActuator(2.0, size=3).limit, [2.0, 2.0, 2.0])


def test_apply_works_under_jit_and_vmap_over_limits_and_time():
    actuator = SaturatingActuator([1.0, 2.0, 3.0])
    u = jnp.linspace(-10.0, 10.0, 30).reshape(10, 3)
    batched = jax.jit(jax.vmap(actuator.apply))(u)
    assert np.all(np.abs(batched) <= np.array([1.0, 2.0, 3.0]))
    limits = jnp.array([[1.0, 1.0, 1.0], [5.0, 5.0, 5.0]])
    over_limits = jax.vmap(lambda limit: SaturatingActuator(limit).apply(u[0]))(limits)
    np.testing.assert_array_equal(over_limits, [[-1.0, -1.0, -1.0], [-5.0, -5.0, -5.0]])


def test_northern_clipper_limits():
    actuator = SaturatingActuator(NORTHERN_CLIPPER_THRUST_LIMIT)
    limit = np.asarray(actuator.limit)
    assert limit.shape == (3,) and np.all(np.isfinite(limit)) and np.all(limit > 0)
    np.testing.assert_array_equal(limit, NORTHERN_CLIPPER_THRUST_LIMIT)
    # surge above sway (main propellers against tunnel thrusters); yaw about sway x a
    # lever of 0.3-0.6 L (76.2 m)
    assert NORTHERN_CLIPPER_LENGTH == 76.2
    assert limit[0] > limit[1] and 0.3 * NORTHERN_CLIPPER_LENGTH <= limit[2] / limit[1] <= 0.6 * NORTHERN_CLIPPER_LENGTH
    # far above the loads of Fossen & Strand (1999): bias 10 kN, 5 kN, 100 kN m
    assert np.all(limit > np.array([1e4, 5e3, 1e5]) * 10)


@pytest.mark.parametrize(
    "limit, kwargs, message",
    [
        ([1.0, 0.0, 1.0], {}, "limit must be positive"),
        ([1.0, -2.0], {}, "limit must be positive"),
        ([1.0, np.nan], {}, "limit must be positive"),
        ([[1.0, 2.0]], {}, "limit must be a scalar or have shape"),
        ([], {}, "limit must be a scalar or have shape"),
        ([1.0, 2.0], {"size": 3}, r"limit must be a scalar or have shape \(3,\)"),
        (1.0, {}, "limit is a scalar: give size"),
        (-np.inf, {"size": 2}, "limit must be positive"),
    ],
)
def test_bad_limits_fail_with_one_line(limit, kwargs, message):
    with pytest.raises(ValueError, match=message) as error:
        SaturatingActuator(limit, **kwargs)
    assert "\n" not in str(error.value)


def test_command_of_the_wrong_size_is_rejected():
    with pytest.raises(ValueError, match="SaturatingActuator has 3 limits; the commanded input has shape"):
        SaturatingActuator(NORTHERN_CLIPPER_THRUST_LIMIT).apply(jnp.zeros(2))


def _fossen_strand(actuator, duration=20.0):
    from lookout.papers import fossen_strand_1999 as fs

    config = fs.Config(duration=duration)
    base = fs.build(config)
    return Scenario(
        base.plant,
        base.sensor,
        base.observer,
        base.controller,
        base.initial_state,
        base.initial_estimate,
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
        actuator=actuator,
    )


def test_a_scenario_rejects_limits_that_do_not_fit_the_plant():
    with pytest.raises(ValueError, match="actuator and plant"):
        _fossen_strand(SaturatingActuator([1.0, 1.0]))


@pytest.mark.slow
def test_saturation_bounds_the_applied_input_of_a_run():
    """The paper's tau (amplitude 1000 N, N, N m) through limits of 500: commanded
    exceeds them, the recorded applied input does not."""
    limit = 500.0
    actuator = SaturatingActuator(limit, size=3)
    ds = simulate(_fossen_strand(actuator), jax.random.key(0)).to_xarray()
    assert ds.attrs["actuator"] == "SaturatingActuator"
    for name in ("force", "moment"):
        commanded, applied = ds[f"{name}_commanded"].values, ds[f"{name}_applied"].values
        assert np.nanmax(np.abs(commanded)) > 1.5 * limit
        assert np.all(np.abs(applied) <= limit)
        inside = np.abs(commanded) <= limit
        np.testing.assert_array_equal(applied[inside], commanded[inside])
        assert ds[f"{name}_applied"].attrs["units"] == ds[f"{name}_commanded"].attrs["units"]
    # time saturated per entry, from the mask
    commanded = np.concatenate([ds["force_commanded"].values.reshape(-1, 2), ds["moment_commanded"].values.reshape(-1, 1)], axis=1)
    fraction = np.asarray(jax.vmap(actuator.saturated)(jnp.asarray(commanded))).mean(axis=0)
    assert np.all((fraction > 0.0) & (fraction < 1.0)), fraction
