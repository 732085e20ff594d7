"""Kim (2002) sliding-mode observer, eqs. (6)–(7): against the passive observer it extends."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from lookout.models.vessel import northern_clipper
from lookout.observers import PassiveObserver, saturation
from lookout.papers import fossen_strand_1999 as fs
from lookout.papers import kim_2002
from lookout.papers.kim_2002 import BIAS_GAIN as KIM_2002_BIAS_GAIN
from lookout.papers.kim_2002 import VELOCITY_GAIN as KIM_2002_VELOCITY_GAIN
from lookout.sim import simulate

finite = st.floats(-1e6, 1e6, allow_nan=False)
width = st.floats(1e-6, 1e3, allow_nan=False)


@given(finite, width)
def test_sat_is_odd_bounded_and_linear_inside_the_layer(x, eps):
    value = float(saturation(x, eps))
    assert abs(value) <= 1.0
    assert float(saturation(-x, eps)) == -value
    if abs(x) < eps:
        assert value == pytest.approx(x / eps, rel=1e-12, abs=1e-300)
    else:
        assert value == np.sign(x)


@given(width, st.floats(1e-9, 1e-3))
def test_sat_is_continuous_at_the_layer_edge(eps, delta):
    inside = float(saturation(eps * (1 - delta), eps))
    outside = float(saturation(eps * (1 + delta), eps))
    assert float(saturation(eps, eps)) == 1.0
    assert abs(outside - inside) <= delta * 1.000001
    assert float(saturation(-eps, eps)) == -1.0


def _scenario(observer, duration=120.0):
    base = fs.build(fs.Config(duration=duration))
    return dataclasses.replace(base, observer=observer, initial_estimate=observer.guess())


def _printed(switching_gain, boundary_layer=(5.0, 5.0, 0.02), **overrides):
    return kim_2002.printed_observer(northern_clipper(), boundary_layer=boundary_layer, switching_gain=switching_gain, **overrides)


def test_without_switching_the_sliding_mode_observer_is_the_passive_observer():
    sliding = _printed(0.0)
    passive = PassiveObserver.design(
        northern_clipper(),
        wave_frequency=0.8976,
        wave_damping=0.1,
        notch_damping=1.0,
        cutoff_frequency=1.1,
        velocity_injection_gain=KIM_2002_VELOCITY_GAIN,
        bias_injection_gain=KIM_2002_BIAS_GAIN,
        bias_time_constant=(1000.0, 1000.0, 10000.0),
    )
    key = jax.random.key(4)
    a = simulate(_scenario(sliding), key)
    b = simulate(_scenario(passive), key)
    for name in b.estimate:
        if name.startswith("switching"):
            continue
        np.testing.assert_allclose(
            np.asarray(a.estimate[name]), np.asarray(b.estimate[name]), rtol=1e-10, atol=1e-10 * (1 + np.abs(np.asarray(b.estimate[name])).max())
        )
    assert float(np.abs(np.asarray(a.estimate["switching_position"])).max()) == 0.0


def test_inside_the_layer_the_switching_term_is_an_extra_position_gain():
    """With |y~| < eps throughout, Kbar sat(y~/eps) = (Kbar/eps) y~: the passive observer with H2 + Kbar/eps."""
    kbar, eps = np.array([2.0, 2.0, 0.002]), np.array([1e4, 1e4, 10.0])
    sliding = _printed(kbar, eps)
    passive = sliding.passive
    stiffer = eqx.tree_at(lambda o: o.position_injection_gain, passive, passive.position_injection_gain + kbar / eps)
    key = jax.random.key(5)
    a = simulate(_scenario(sliding), key)
    b = simulate(_scenario(stiffer), key)
    assert float(np.abs(np.asarray(a.estimate["innovation_position"])).max()) < 1e4
    for name in ("position", "velocity", "bias_force", "wave_position", "heading"):
        np.testing.assert_allclose(
            np.asarray(a.estimate[name]), np.asarray(b.estimate[name]), rtol=1e-9, atol=1e-9 * (1 + np.abs(np.asarray(b.estimate[name])).max())
        )


def test_outside_the_layer_the_switching_term_injects_kbar_in_eta_hat_dot():
    observer = _printed(np.array([10.0, 10.0, 0.01]), (1.0, 1.0, 0.01))
    estimate = observer.guess(eta=0.0)
    measurement = jnp.array([50.0, -50.0, 0.5])
    rates = observer.vector_field(0.0, estimate, measurement, jnp.zeros(3))
    base = observer.passive.vector_field(0.0, estimate, measurement, jnp.zeros(3))
    np.testing.assert_allclose(np.asarray(rates.eta - base.eta), [10.0, -10.0, 0.01], rtol=1e-15)
    for field in ("nu", "bias", "wave_state"):
        np.testing.assert_array_equal(np.asarray(getattr(rates, field)), np.asarray(getattr(base, field)))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"switching_gain": -1.0}, "switching_gain must be"),
        ({"boundary_layer": 0.0}, "boundary_layer must be positive"),
        ({"boundary_layer": (1.0, 2.0)}, "boundary_layer must be a scalar or have 3 entries"),
    ],
)
def test_bad_switching_parameters_fail_with_one_line(kwargs, message):
    settings = {"switching_gain": 1.0, "boundary_layer": 1.0, **kwargs}
    with pytest.raises(ValueError, match=message) as info:
        kim_2002.printed_observer(northern_clipper(), **settings)
    assert "\n" not in str(info.value)
