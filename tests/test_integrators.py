"""integrate_sample: the one sampled integration loop of the continuous observers' predict.

References: the stability functions of RK4 and Euler on a linear system (exact), the
same loop written out step by step, and, for every continuous observer, its predict
through the loop against its predict with every step written out, and the order of
convergence as steps_per_sample grows past the unroll limit.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from lookout.sim import integrators
from lookout.sim.integrators import UNROLL_LIMIT, euler_step, integrate_sample, rk4_step

A = np.array([[0.0, 1.0], [-4.0, -0.4]])
X0 = np.array([1.0, -0.5])
STEP_COUNTS = (1, 2, UNROLL_LIMIT, UNROLL_LIMIT + 1, 3 * UNROLL_LIMIT + 1)


def _stability_function(method: str, z: np.ndarray) -> np.ndarray:
    """R(z) of one step on x' = A x, z = h A: x_{i+1} = R(h A) x_i."""
    identity = np.eye(len(z))
    if method == "euler":
        return identity + z
    return identity + z + z @ z / 2 + z @ z @ z / 6 + z @ z @ z @ z / 24


@pytest.mark.parametrize("method", ["rk4", "euler"])
@pytest.mark.parametrize("steps", STEP_COUNTS)
def test_a_linear_system_over_one_sample_is_the_stability_function_to_the_power_of_the_steps(method, steps):
    dt = 0.3
    field = lambda t, x: jnp.asarray(A) @ x
    result = jax.jit(lambda x: integrate_sample(field, 2.0, x, dt, steps, method=method))(jnp.asarray(X0))
    expected = np.linalg.matrix_power(_stability_function(method, A * dt / steps), steps) @ X0
    np.testing.assert_allclose(result, expected, rtol=1e-13, atol=1e-15)


def test_rk4_over_one_sample_converges_with_order_4_against_expm_across_the_unroll_limit():
    decaying = np.array([[-1.0, 0.5], [0.0, -2.0]])  # real modes: the errors fall monotonically
    dt = 1.0
    exact = scipy.linalg.expm(decaying * dt) @ X0
    counts = (UNROLL_LIMIT, 2 * UNROLL_LIMIT, 4 * UNROLL_LIMIT, 8 * UNROLL_LIMIT)
    errors = [np.linalg.norm(integrate_sample(lambda t, x: jnp.asarray(decaying) @ x, 0.0, jnp.asarray(X0), dt, n) - exact) for n in counts]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 4.0) < 0.35), orders


@pytest.mark.parametrize("method", ["rk4", "euler"])
@pytest.mark.parametrize("steps", STEP_COUNTS)
def test_the_loop_equals_its_steps_written_out_with_time_and_normalization(method, steps):
    """A time-varying field (so that each step's start time t + i dt / steps counts) and a
    normalization that is not idempotent (so that once at the end and after every step
    differ), in the unrolled and the scanned form alike."""
    step_function = {"rk4": rk4_step, "euler": euler_step}[method]
    field = lambda t, x: {"a": jnp.sin(t) * x["b"], "b": -x["a"] + t}
    normalize = lambda x: {"a": 0.5 * x["a"], "b": x["b"]}
    t, dt, x0 = 1.5, 0.4, {"a": jnp.asarray(0.7), "b": jnp.asarray(-0.2)}
    h = dt / steps
    for each_step in (False, True):
        expected = x0
        for i in range(steps):
            expected = step_function(field, t + i * h, expected, h)
            expected = normalize(expected) if each_step else expected
        expected = expected if each_step else normalize(expected)
        for limit in (0, steps):  # scanned, written out
            result = jax.jit(
                lambda x: integrate_sample(
                    field, t, x, dt, steps, method=method, normalize=normalize, normalize_each_step=each_step, unroll_limit=limit
                )
            )(x0)
            for name in x0:
                assert float(result[name]) == pytest.approx(float(expected[name]), rel=1e-14, abs=1e-15), (name, limit, each_step)


def test_the_program_stops_growing_past_the_unroll_limit_and_the_gradient_goes_through_the_loop():
    field = lambda t, x: jnp.asarray(A) @ x

    def size(steps, limit=None):
        jaxpr = jax.make_jaxpr(lambda x: integrate_sample(field, 0.0, x, 1.0, steps, unroll_limit=limit))(jnp.asarray(X0))
        return len(jaxpr.eqns)

    assert size(2) > size(1) and size(UNROLL_LIMIT) > size(UNROLL_LIMIT - 1)
    assert size(UNROLL_LIMIT + 1) == size(10 * UNROLL_LIMIT) < size(UNROLL_LIMIT)
    assert size(2, limit=1) == size(50, limit=1)
    # d x(dt) / d x0 = R(h A)^n, scanned or not
    for steps in (UNROLL_LIMIT, UNROLL_LIMIT + 3):
        jacobian = jax.jacrev(lambda x: integrate_sample(field, 0.0, x, 1.0, steps))(jnp.asarray(X0))
        expected = np.linalg.matrix_power(_stability_function("rk4", A / steps), steps)
        np.testing.assert_allclose(jacobian, expected, rtol=1e-13, atol=1e-15)


def test_a_state_of_python_numbers_and_weak_types_goes_through_the_scan():
    result = integrate_sample(lambda t, x: (-x[0], 1.0 + 0.0 * x[1]), 0.0, (1.0, jnp.asarray(0.0)), 1.0, 3 * UNROLL_LIMIT)
    assert float(result[0]) == pytest.approx(math.exp(-1.0), rel=1e-6)
    assert float(result[1]) == pytest.approx(1.0, rel=1e-14)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"steps": 0}, "steps must be a positive integer; got 0"),
        ({"steps": 2.0}, "steps must be a positive integer; got 2.0"),
        ({"steps": True}, "steps must be a positive integer; got True"),
        ({"steps": 2, "method": "heun"}, "method must be one of ['euler', 'rk4']; got 'heun'"),
    ],
)
def test_bad_arguments_are_refused_naming_them(options, message):
    steps = options.pop("steps")
    with pytest.raises(ValueError) as error:
        integrate_sample(lambda t, x: x, 0.0, jnp.zeros(2), 1.0, steps, **options)
    assert str(error.value) == message


# --- every continuous observer's predict goes through the loop --------------------------


def _vessel_measurements(count, velocity=False):
    y = np.zeros((count, 6 if velocity else 3))
    y[:, 0], y[:, 1] = np.linspace(0.0, 5.0, count), np.linspace(0.0, -3.0, count)
    y[:, 2] = np.pi - 0.02 + 0.004 * np.arange(count)  # across the +-pi wrap
    if velocity:
        y[:, 3:] = [0.1, 0.05, 0.01]
    y[count // 3, 2] = np.nan  # a dropped heading, a dropped position
    y[2 * count // 3, :2] = np.nan
    return y


def _joint_measurements(count):
    y = np.stack([np.sin(0.1 * np.arange(count)), np.cos(0.1 * np.arange(count))], axis=1)
    y[count // 2, 1] = np.nan
    return y


def _observer_cases():
    """name -> (build(steps_per_sample), guess(observer), measurements, input, sample period)."""
    from lookout.analysis.sliding_mode import kim_2002_observer
    from lookout.models.cybership import cybership2
    from lookout.models.manipulators import FreePendulum, TwoLinkArm
    from lookout.models.parameters import ModelParameters
    from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_MASS, northern_clipper
    from lookout.observers import (
        AdaptiveObserver,
        EarthFixedObserver,
        InertiaParametrization,
        PassiveObserver,
        VelocityObserver,
        injection_gains_from_normalized,
    )
    from lookout.observers.parameter_estimator import ParameterEstimator

    vessel = northern_clipper()
    m11 = float(np.asarray(vessel.mass_matrix)[0, 0])
    kappa, lam = injection_gains_from_normalized([0.1, 0.1, 0.01], [0.01, 0.01, 0.001], mass=NORTHERN_CLIPPER_MASS, length=NORTHERN_CLIPPER_LENGTH)
    waves = {"wave_frequency": 0.8976, "wave_damping": 0.1, "cutoff_frequency": 1.1}
    vessel_guess = lambda o: o.guess(eta=[0.5, 0.2, 3.0], nu=[0.1, 0.0, 0.0])
    tau, count = np.array([1e4, 2e3, 1e5]), 12
    cases = {}
    for hold in ("measurement", "innovation"):
        cases[f"passive, hold {hold}"] = (
            lambda n, hold=hold: PassiveObserver.design(
                vessel,
                **waves,
                notch_damping=1.0,
                velocity_injection_gain=kappa,
                bias_injection_gain=lam,
                bias_time_constant=1000.0,
                steps_per_sample=n,
                hold=hold,
            ),
            vessel_guess,
            _vessel_measurements(count),
            tau,
            0.25,
        )
        cases[f"sliding mode, hold {hold}"] = (
            lambda n, hold=hold: kim_2002_observer(
                vessel, **waves, switching_gain=[10.0, 10.0, 0.01], boundary_layer=[5.0, 5.0, 0.02], steps_per_sample=n, hold=hold
            ),
            vessel_guess,
            _vessel_measurements(count),
            tau,
            0.25,
        )
    parametrization = InertiaParametrization(vessel, ("m11",), [0.5 * m11], [2.0 * m11])
    cases["adaptive DP, continuous"] = (
        lambda n: AdaptiveObserver(
            parametrization, jnp.full(3, 0.5), jnp.full(3, 0.5), 1e8, form="continuous", initial_theta=0.7 * m11, steps_per_sample=n
        ),
        vessel_guess,
        _vessel_measurements(count, velocity=True),
        10 * tau,
        0.1,
    )
    for method in ("rk4", "euler"):
        cases[f"Earth-fixed, {method}"] = (
            lambda n, method=method: EarthFixedObserver(cybership2(), 15.0, 50.0, steps_per_sample=n, method=method),
            lambda o: o.guess([0.1, 0.0, 3.0], [0.5, 0.5, -0.5]),
            _vessel_measurements(count) * [0.1, 0.1, 1.0],
            np.array([1.0, 0.5, 0.1]),
            0.05,
        )
    cases["velocity"] = (
        lambda n: VelocityObserver(TwoLinkArm(), jnp.full(2, 5.0), steps_per_sample=n),
        lambda o: o.guess([0.3, -0.2]),
        _joint_measurements(count),
        np.array([2.0, 1.0]),
        0.01,
    )
    pendulum = ModelParameters(FreePendulum(1.0, 1.5, 0.1), ("mass", "friction[0]"), units=("kg", "N m s/rad"))
    cases["parameter estimator"] = (
        lambda n: ParameterEstimator(pendulum, 10.0, steps_per_sample=n),
        lambda o: o.guess([0.5, 0.3]),
        _joint_measurements(count),
        np.array([5.0]),
        0.01,
    )
    return cases


OBSERVER_CASES = _observer_cases()


def test_the_cases_cover_every_continuous_observer():
    import lookout.observers  # noqa: F401  (every observer module)
    from lookout.components import ContinuousObserver

    def concrete(cls):
        below = [c for sub in cls.__subclasses__() for c in concrete(sub)]
        return below + ([cls] if not getattr(cls, "__abstractmethods__", None) else [])

    covered = {type(build(1)) for build, *_ in OBSERVER_CASES.values()}
    library = {cls for cls in concrete(ContinuousObserver) if cls.__module__.startswith("lookout.")}
    assert library <= covered, library - covered


def _run(case, steps, samples=None):
    """The observer's state after its samples (update, then predict), jitted."""
    build, guess, measurements, u, dt = case
    observer = build(steps)
    ys = jnp.asarray(measurements if samples is None else measurements[:samples])

    def run():
        state = observer.init(jnp.nan_to_num(ys[0]), guess(observer))

        def sample(state, k):
            state = observer.update(state, k * dt, ys[k])
            return observer.predict(state, k * dt, ys[k], jnp.asarray(u) * (1.0 + 0.1 * k), dt), None

        return jax.lax.scan(sample, state, jnp.arange(len(ys)))[0]

    return [np.asarray(leaf) for leaf in jax.tree.leaves(jax.jit(run)())]


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(OBSERVER_CASES))
def test_every_continuous_observer_predicts_through_the_loop_as_with_every_step_written_out(name, monkeypatch):
    """Past the unroll limit the steps run as a scan: the same numbers as written out
    (the Earth-fixed observer loops from two steps on, whatever the limit)."""
    steps = UNROLL_LIMIT + 2
    scanned = _run(OBSERVER_CASES[name], steps)
    monkeypatch.setattr(integrators, "UNROLL_LIMIT", steps)
    written_out = _run(OBSERVER_CASES[name], steps)
    assert all(np.isfinite(leaf).all() for leaf in scanned)
    for a, b in zip(scanned, written_out, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13 * max(1.0, float(np.max(np.abs(b), initial=0.0))))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(OBSERVER_CASES))
def test_every_continuous_observer_converges_with_its_method_order_as_steps_per_sample_grows(name):
    """One sample with the measurement valid, from the first: the state after it against
    an integration 16 times finer than the finest; errors fall 2^order times per doubling of the steps,
    across the unroll limit. Every leaf is compared relative to its own scale."""
    case = OBSERVER_CASES[name]
    order = 1.0 if "euler" in name else 4.0
    counts = (UNROLL_LIMIT // 2, UNROLL_LIMIT, 2 * UNROLL_LIMIT)
    reference = _run(case, 32 * UNROLL_LIMIT, samples=1)
    scale = [max(np.max(np.abs(leaf), initial=0.0), 1e-300) for leaf in reference]
    errors = []
    for n in counts:
        state = _run(case, n, samples=1)
        errors.append(max(np.max(np.abs(a - b), initial=0.0) / s for a, b, s in zip(state, reference, scale, strict=True)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - order) < 0.4), (errors, orders)
