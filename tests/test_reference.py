"""The third-order reference filter (Fossen 1994): exact sampled step response, angles,
schedule, JAX transformations, validation and recording through the engine."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.scipy.linalg import expm

from lookout._math import ssa
from lookout.components import Signal
from lookout.reference import NoReference, ReferenceFilter, reference_filter_signals
from lookout.sim import Scenario, simulate

PAIR = Signal("depth", "m", "depth of the two probes", "Earth-fixed", ("left", "right"), "probe")
ROLL = Signal("roll", "rad", "roll angle", "body-fixed", angle=True)


@eqx.filter_jit
def _run(reference, dt, n):
    """Outputs of ``n`` samples, t_k = k dt, stacked over k."""

    def body(state, k):
        return reference.step(state, k * dt, dt, jnp.zeros(0))

    return jax.lax.scan(body, reference.init(), jnp.arange(n))[1]


def _analytic(r, w, t):
    """x_d, x_d', x_d'' of (s + w)^3 x_d = w^3 r from rest at 0, r a step at t = 0."""
    decay = np.exp(-w * t)
    a = w * t
    return r * (1 - decay * (1 + a + a**2 / 2)), r * w**3 * t**2 * decay / 2, r * w**3 * decay * (t - w * t**2 / 2)


def test_transition_is_the_matrix_exponential_and_gamma_its_input_matrix():
    w = np.array([0.05, 0.7, 3.0])
    f = ReferenceFilter.vessel(w, 0.0, [0.0, 0.0, 0.0])
    phi, gamma = f.transition(0.25)
    for i, wi in enumerate(w):
        a = np.array([[0, 1, 0], [0, 0, 1], [-(wi**3), -3 * wi**2, -3 * wi]])
        b = np.array([0, 0, wi**3])
        expected = np.asarray(expm(jnp.asarray(a * 0.25)))
        np.testing.assert_allclose(phi[i], expected, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(gamma[i], np.linalg.solve(a, (expected - np.eye(3)) @ b), rtol=1e-10, atol=1e-14)


def test_step_response_is_the_analytic_critically_damped_solution():
    w, r, dt, n = np.array([0.3, 1.0]), np.array([2.0, -1.5]), 0.1, 600
    f = ReferenceFilter((PAIR,), w, [0.0], [r], initial=[0.0, 0.0])
    out = _run(f, dt, n)
    t = np.arange(n) * dt
    for i in range(2):
        x, v, a = _analytic(r[i], w[i], t)
        np.testing.assert_allclose(out["depth_desired"][:, i], x, rtol=0, atol=1e-10)
        np.testing.assert_allclose(out["depth_desired_rate"][:, i], v, rtol=0, atol=1e-10)
        np.testing.assert_allclose(out["depth_desired_acceleration"][:, i], a, rtol=0, atol=1e-10)
        # critically damped: monotone towards the setpoint, never past it
        moved = np.sign(r[i]) * np.asarray(out["depth_desired"][:, i])
        assert np.all(np.diff(moved) >= -1e-15) and np.all(moved <= abs(r[i]) + 1e-15)
    # final value: w t = 60 for the fast DOF
    assert abs(float(out["depth_desired"][-1, 1]) - r[1]) < 1e-12
    assert abs(float(out["depth_desired_rate"][-1, 1])) < 1e-12


def test_the_result_does_not_depend_on_the_sample_period():
    times = [0.0, 3.0, 7.5]
    setpoints = [[5.0, -2.0, 1.0], [5.0, 4.0, 2.5], [-3.0, 0.0, -2.0]]
    f = ReferenceFilter.vessel([0.2, 0.4, 0.8], times, setpoints, initial=[0.0, 0.0, 0.0])
    coarse, fine = _run(f, 0.1, 200), _run(f, 0.05, 400)
    for name in coarse:
        a, b = np.asarray(coarse[name]), np.asarray(fine[name])[::2]
        difference = ssa(a - b) if name == "heading_desired" else a - b
        assert np.max(np.abs(difference)) < 1e-10, name


def test_heading_across_pi_takes_the_short_way_and_stays_wrapped():
    f = ReferenceFilter.vessel(0.5, 0.0, [0.0, 0.0, 3.1], initial=[0.0, 0.0, -3.1])
    out = _run(f, 0.1, 600)
    heading = np.asarray(out["heading_desired"])
    assert np.all(heading >= -np.pi) and np.all(heading < np.pi)
    path = np.unwrap(heading)
    short = -2 * (np.pi - 3.1)  # -3.1 -> -pi = pi -> 3.1: 0.083 rad, not +6.2 rad
    assert abs(path[-1] - path[0] - short) < 1e-9
    assert np.all(np.asarray(out["heading_desired_rate"]) <= 1e-15)
    assert np.max(np.abs(path - path[0])) <= abs(short) + 1e-12
    assert abs(float(ssa(heading[-1] - 3.1))) < 1e-9
    assert heading[-1] > 3.0  # wrapped: reported as 3.1, not -3.183


def test_an_angle_initial_value_outside_pi_is_wrapped():
    f = ReferenceFilter((ROLL,), 1.0, 0.0, [7.0])
    assert abs(float(f.init()[0, 0]) - float(ssa(7.0))) < 1e-15


def test_schedule_lookup_before_at_and_after_the_switch_times():
    f = ReferenceFilter.vessel(1.0, [1.0, 5.0], [[1.0, 2.0, 0.5], [3.0, 4.0, -0.5]])
    lookup = eqx.filter_jit(lambda reference, t: reference.setpoint(t))
    for t, row in ((-2.0, 0), (0.0, 0), (1.0, 0), (4.999, 0), (5.0, 1), (5.0 - 1e-12, 1), (100.0, 1)):
        np.testing.assert_array_equal(lookup(f, jnp.asarray(t)), f.setpoints[row], err_msg=f"t = {t}")
        np.testing.assert_array_equal(f.setpoint(t), f.setpoints[row], err_msg=f"t = {t}")
    # the initial value defaults to the first setpoint: at rest until the second entry
    out = _run(f, 0.5, 10)
    np.testing.assert_allclose(out["position_desired"][:, 0], 1.0, atol=1e-15)
    assert float(out["position_desired"][-1, 0]) == 1.0 and float(out["position_desired_rate"][-1, 0]) == 0.0


def test_jit_vmap_over_the_bandwidth_and_grad_are_consistent():
    def final(w):
        f = ReferenceFilter((PAIR,), w, 0.0, [1.0, 1.0], initial=[0.0, 0.0])
        return _run(f, 0.1, 51)["depth_desired"][-1]

    ws = jnp.array([[0.1, 0.2], [0.5, 1.0], [2.0, 0.3]])
    batched = jax.vmap(final)(ws)
    for i in range(3):
        np.testing.assert_allclose(batched[i], final(ws[i]), rtol=0, atol=1e-14)
        np.testing.assert_allclose(batched[i], _analytic(1.0, np.asarray(ws[i]), 5.0)[0], atol=1e-10)
    gradient = jax.grad(lambda w: final(jnp.array([w, 1.0]))[0])(0.4)
    a = 0.4 * 5.0
    assert np.isfinite(gradient) and abs(float(gradient) - 5.0 * a**2 * np.exp(-a) / 2) < 1e-9


def test_vmap_over_a_built_filter_leaf():
    f = ReferenceFilter.vessel(0.5, [0.0, 2.0], [[0.0, 0.0, 0.0], [1.0, 2.0, 1.0]])
    ws = jnp.stack([jnp.full(3, 0.5), jnp.full(3, 1.0)])
    out = jax.vmap(lambda w: _run(eqx.tree_at(lambda g: g.bandwidth, f, w), 0.1, 40))(ws)
    np.testing.assert_allclose(out["position_desired"][0], _run(f, 0.1, 40)["position_desired"], atol=1e-14)
    assert out["heading_desired"].shape == (2, 40)


def test_signals_names_units_and_shapes():
    f = ReferenceFilter.vessel([0.1, 0.1, 0.2], 0.0, [0.0, 0.0, 0.0])
    units = {s.name: s.units for s in f.reference_signals}
    assert units == {
        "position_desired": "m",
        "position_desired_rate": "m s-1",
        "position_desired_acceleration": "m s-2",
        "heading_desired": "rad",
        "heading_desired_rate": "rad s-1",
        "heading_desired_acceleration": "rad s-2",
    }
    by_name = {s.name: s for s in f.reference_signals}
    assert by_name["position_desired"].labels == ("north", "east") and by_name["position_desired"].dim == "earth_axis"
    assert by_name["heading_desired"].angle and not by_name["heading_desired_rate"].angle
    assert f.noise_size == 0 and f.angle_mask == (False, False, True)
    _, sample = f.step(f.init(), 0.0, 0.1, jnp.zeros(0))
    assert {k: v.shape for k, v in sample.items()} == {s.name: s.shape for s in f.reference_signals}
    (dimensionless,) = reference_filter_signals((Signal("gain", "1", "gain"),))[1:2]
    assert dimensionless.units == "s-1"


def test_no_reference_is_unchanged():
    state, sample = NoReference().step(NoReference().init(), 0.0, 0.1, jnp.zeros(0))
    assert state == () and sample == {}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"schedule_times": [0.0, 0.0]}, "schedule_times must be strictly increasing"),
        ({"schedule_times": [0.0, np.nan]}, "schedule_times must be finite"),
        ({"setpoints": [[0.0, 0.0, np.nan], [1.0, 1.0, 1.0]]}, "setpoints must be finite"),
        ({"setpoints": [[0.0, 0.0], [1.0, 1.0]]}, r"setpoints must have shape \(2, 3\)"),
        ({"setpoints": [[0.0, 0.0, 0.0]]}, r"setpoints must have shape \(2, 3\)"),
        ({"bandwidth": 0.0}, "bandwidth must be positive"),
        ({"bandwidth": [0.1, -0.1, 0.1]}, "bandwidth must be positive"),
        ({"bandwidth": [0.1, 0.1]}, "bandwidth must be a scalar or have 3 entries"),
        ({"bandwidth": np.inf}, "bandwidth must be finite"),
        ({"initial": [0.0, 0.0]}, "initial must be a scalar or have 3 entries"),
        ({"initial": [0.0, np.inf, 0.0]}, "initial must be finite"),
        ({"schedule_times": []}, "schedule_times must be a non-empty 1-D sequence"),
    ],
)
def test_bad_arguments_fail_with_one_line_naming_the_parameter(kwargs, message):
    arguments = {"bandwidth": 0.1, "schedule_times": [0.0, 10.0], "setpoints": [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], "initial": None}
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message) as error:
        ReferenceFilter.vessel(**arguments)
    assert "\n" not in str(error.value)


def test_signals_must_be_signals():
    with pytest.raises(ValueError, match="signals must be a non-empty sequence"):
        ReferenceFilter((), 1.0, 0.0, [[]])
    with pytest.raises(ValueError, match="distinct"):
        ReferenceFilter((ROLL, ROLL), 1.0, 0.0, [0.0, 0.0])


def test_construction_inside_vmap_skips_the_value_checks_only():
    build = lambda w: ReferenceFilter.vessel(w, [0.0, 1.0], [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]).bandwidth
    assert jax.vmap(build)(jnp.array([0.1, 0.2])).shape == (2, 3)


@pytest.fixture(scope="module")
def dataset():
    """A 20 s Fossen & Strand (1999) run with a reference filter recorded."""
    from lookout.papers import fossen_strand_1999 as fs

    config = fs.Config(duration=20.0)
    base = fs.build(config)
    reference = ReferenceFilter.vessel([0.1, 0.1, 0.2], [0.0, 5.0], [[0.0, 0.0, 0.0], [10.0, -5.0, 3.1]], initial=[0.0, 0.0, -3.1])
    scenario = Scenario(
        base.plant,
        base.sensor,
        base.observer,
        base.controller,
        base.initial_state,
        base.initial_estimate,
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
        reference=reference,
    )
    return reference, simulate(scenario, jax.random.key(0)).to_xarray()


def test_the_engine_records_the_reference_with_its_units(dataset):
    reference, ds = dataset
    for signal in reference.reference_signals:
        assert signal.name in ds and ds[signal.name].attrs["units"] == signal.units
    assert ds["position_desired"].dims[-2:] == ("time", "earth_axis") and ds["heading_desired"].dims[-1] == "time"
    ds = ds.squeeze("run", drop=True) if "run" in ds.dims else ds
    assert ds.attrs["reference"] == "ReferenceFilter"
    expected = _run(reference, 0.1, ds.sizes["time"])
    for name, value in expected.items():
        np.testing.assert_allclose(ds[name].values, value, rtol=0, atol=1e-12, err_msg=name)
    north = ds["position_desired"].sel(earth_axis="north").values
    assert np.all(north[ds.time.values <= 5.0] == 0.0) and 0.0 < north[-1] < 10.0
    heading = ds["heading_desired"].values
    assert np.all(heading >= -np.pi) and np.all(heading < np.pi)
