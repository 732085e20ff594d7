"""Observers over a recorded log (lookout.filter) and live (lookout.Stepper)."""

import re

import equinox as eqx
import jax
import numpy as np
import pytest

import lookout
from lookout.models.vessel import VESSEL_INPUT
from lookout.papers import fossen_strand_1999 as fs
from lookout.sensors import POSITION_HEADING
from lookout.sim import simulate

#: one worker computes the module's fixture once (make test runs pytest --dist loadgroup)
pytestmark = pytest.mark.xdist_group("filtering")


@pytest.fixture(scope="module")
def recorded():
    scenario = fs.build(fs.Config(duration=120.0))
    trajectory = simulate(scenario, jax.random.key(6))
    return scenario, trajectory, trajectory.to_xarray()


@pytest.mark.slow
def test_filtering_a_simulation_log_gives_the_simulation_estimates(recorded):
    scenario, trajectory, ds = recorded
    log = lookout.filter(
        scenario.observer,
        trajectory.time,
        trajectory.measurement,
        trajectory.applied,
        guess=scenario.initial_estimate,
        measurement_layout=POSITION_HEADING,
        input_layout=VESSEL_INPUT,
    )
    assert set(log.data_vars) >= {"position_hat", "heading_hat", "innovation_position", "measured_position", "force_applied"}
    for name in ("position_hat", "heading_hat", "velocity_hat", "bias_force_hat", "wave_position_hat", "innovation_heading"):
        assert log[name].dims == ds[name].dims and log[name].attrs["units"] == ds[name].attrs["units"]
        # the row steps t_{k+1} - t_k equal the sample period to rounding
        np.testing.assert_allclose(log[name].values, ds[name].values, rtol=1e-9, atol=1e-9 * float(np.abs(ds[name]).max()))


@pytest.mark.slow
def test_filter_rides_through_missing_channels_and_irregular_times(recorded):
    scenario, trajectory, _ = recorded
    rng = np.random.default_rng(0)
    times = np.cumsum(rng.uniform(0.05, 0.2, 400))
    measurements = np.asarray(trajectory.measurement)[: times.size].copy()
    measurements[rng.random(measurements.shape) < 0.3] = np.nan
    log = lookout.filter(scenario.observer, times, measurements, np.zeros((times.size, 3)), guess=scenario.initial_estimate)
    for name in log.data_vars:
        if name.endswith("_hat"):
            assert np.all(np.isfinite(log[name].values)), name
    # the columns are named by the observer's declared measurement
    assert log.earth_axis.values.tolist() == ["north", "east"] and log.status.values.tolist() == ["finite"]
    assert set(log.data_vars) >= {"measured_position", "measured_heading", "force_applied", "moment_applied"}


def test_stepper_gives_the_filter_row_by_row(recorded):
    scenario, trajectory, _ = recorded
    rows = 50
    times, ys, us = np.asarray(trajectory.time)[:rows], np.asarray(trajectory.measurement)[:rows], np.asarray(trajectory.applied)[:rows]
    log = lookout.filter(scenario.observer, times, ys, us, guess=scenario.initial_estimate)
    stepper = lookout.Stepper(scenario.observer, scenario.initial_estimate, ys[0], input_size=3)
    steps = np.diff(times, append=times[-1] + 0.1)  # the last step is not seen by the estimates compared
    for k in range(rows):
        estimate = stepper(times[k], ys[k], us[k], steps[k])
        np.testing.assert_allclose(np.asarray(estimate["position"]), log.position_hat.values[0, k], rtol=1e-12, atol=1e-12)


def test_guess_defaults_to_the_observers_own(recorded):
    scenario, trajectory, _ = recorded
    times, ys = np.asarray(trajectory.time)[:20], np.asarray(trajectory.measurement)[:20]
    default = lookout.filter(scenario.observer, times, ys)
    given = lookout.filter(scenario.observer, times, ys, np.zeros((20, 3)), guess=scenario.observer.guess())
    np.testing.assert_array_equal(default.position_hat.values, given.position_hat.values)


def _guess_with(observer, **changes):
    guess = observer.guess()
    for name, value in changes.items():
        guess = eqx.tree_at(lambda g: getattr(g, name), guess, value)
    return guess


#: (arguments that differ from a good 3-row log, the message): each names the argument,
#: what it must be and what it got
BAD_LOGS = [
    ({"times": [0.0, 0.1, 0.1]}, r"times must be strictly increasing; row 2 \(0.1 s\) does not come after row 1 \(0.1 s\)"),
    ({"times": [0.0, np.nan, 0.2]}, r"times must be finite; row 1 is nan"),
    ({"times": [[0.0, 0.1, 0.2]]}, r"times must be a 1-D array with at least one row; got shape \(1, 3\)"),
    (
        {"times": [0.0, 100.0, 200.0]},
        r"times: the longest row step \(row 0 to 1\), 100 s is too long for this observer: one prediction step multiplies a state error by .* are the times in seconds\?",
    ),
    (
        {"measurements": np.zeros((3, 2))},
        r"measurements must have shape \(3, 3\): 3 rows and the 3 columns the observer reads \(measured_position, measured_heading\); got shape \(3, 2\)",
    ),
    ({"measurements": np.zeros((2, 3))}, r"measurements must have shape \(3, 3\).*got shape \(2, 3\)"),
    ({"measurements": np.full((3, 3), np.nan)}, r"measurements hold no finite value \(3 rows, all NaN\)"),
    ({"measurements": [[0.0, np.inf, 0.0]] * 3}, r"measurements must be finite or NaN \(a missing channel\); row 0, column 1 is inf"),
    (
        {"inputs": np.zeros((3, 2))},
        r"inputs must have shape \(3, 3\): 3 rows and the 3 columns the observer's prediction reads \(force, moment\); got shape \(3, 2\)",
    ),
    ({"inputs": np.full((3, 3), np.nan)}, r"inputs must be finite .*; row 0, column 0 is nan"),
    (
        {"guess": {"eta": np.zeros(3)}},
        r"guess must be shaped like observer.guess\(\) \(VesselState with eta \(3,\), nu \(3,\), bias \(3,\), wave_state \(6,\)\); got dict",
    ),
    ({"guess": "eta"}, r"guess must be shaped like observer.guess\(\)"),
    ({"guess_eta": np.zeros(2)}, r"guess.eta must have shape \(3,\) \(as in observer.guess\(\)\); got shape \(2,\)"),
    (
        {"guess_eta": np.array([0.0, 0.0, np.inf])},
        r"^guess.eta must be finite \(NaN only where observer.guess\(\) leaves a state to the first measurement\); got \[0.0, 0.0, inf\]$",
    ),
    ({"guess_nu": np.full(3, np.nan)}, r"^guess.nu must be finite; got \[nan, nan, nan\]$"),  # NaN only where the first measurement gives the state
    (
        {"measurement_layout": POSITION_HEADING.renamed(suffix="_x").__class__(POSITION_HEADING.signals[:1])},
        r"measurement_layout must have 3 entries \(the observer reads measured_position, measured_heading\); got 2",
    ),
    ({"measurements": np.zeros((3, 3)) + 1j}, r"measurements must hold real numbers; got complex numbers"),
    ({"times": ["0", "0.1", "0.2"]}, r"times must hold real numbers; got text"),
]


@pytest.mark.parametrize("kwargs, message", BAD_LOGS, ids=[f"{next(iter(k))}-{i}" for i, (k, _) in enumerate(BAD_LOGS)])
def test_filter_refuses_a_bad_log_naming_the_argument(recorded, kwargs, message):
    scenario, _, _ = recorded
    observer = scenario.observer
    args = {"times": [0.0, 0.1, 0.2], "measurements": np.zeros((3, 3)), "inputs": np.zeros((3, 3)), "guess": observer.guess()}
    if "guess_eta" in kwargs:
        kwargs = {"guess": _guess_with(observer, eta=kwargs["guess_eta"])}
    if "guess_nu" in kwargs:
        kwargs = {"guess": _guess_with(observer, nu=kwargs["guess_nu"])}
    args |= kwargs
    with pytest.raises(ValueError, match=message) as raised:
        lookout.filter(observer, args.pop("times"), args.pop("measurements"), args.pop("inputs"), **args)
    assert "\n" not in str(raised.value)


def test_filter_names_a_bad_observer_takes_an_integer_guess_and_warns_where_the_estimates_stop_being_finite(recorded):
    scenario, trajectory, _ = recorded
    observer = scenario.observer
    for bad in (None, scenario):
        with pytest.raises(ValueError, match=r"observer must be a lookout Observer \(a scenario's is scenario.observer\); got"):
            lookout.filter(bad, [0.0, 0.1], np.zeros((2, 3)))
    times, ys = np.asarray(trajectory.time)[:40], np.asarray(trajectory.measurement)[:40].copy()
    integer = lookout.filter(observer, times, ys, guess=_guess_with(observer, eta=np.zeros(3, dtype=int)))
    np.testing.assert_array_equal(
        integer.position_hat.values, lookout.filter(observer, times, ys, guess=_guess_with(observer, eta=np.zeros(3))).position_hat.values
    )
    ys[10, 0] = 1e306  # one absurd sample: the estimates overflow after it, and the user is told where
    with pytest.warns(
        RuntimeWarning, match=r"the estimates are not finite from row 11 \(t = 1.1 s\) on, after row 10's measurement \[ ?1.0000e\+306"
    ):
        log = lookout.filter(observer, times, ys)
    assert log.status.values.tolist() == ["diverged"]


def test_the_step_length_check_is_the_filters_and_a_replays(recorded):
    """check_step_length, the test lookout.filter runs on a log's longest row step and
    lookout replay on a log's typical step: the spectral radius of one prediction
    step's Jacobian against MAX_STEP_AMPLIFICATION, refused with "are the times in
    seconds?" and returned otherwise."""
    from lookout.sim.filtering import MAX_STEP_AMPLIFICATION, check_step_length, step_amplification

    scenario, _, _ = recorded
    observer, guess, zeros = scenario.observer, scenario.initial_estimate, np.zeros(3)
    radius = check_step_length(observer, guess, zeros, zeros, 0.1, "a step of")
    assert radius == step_amplification(observer, guess, zeros, zeros, 0.1) and radius <= MAX_STEP_AMPLIFICATION
    too_long = step_amplification(observer, guess, zeros, zeros, 100.0)
    assert too_long > MAX_STEP_AMPLIFICATION
    expected = (
        f"LOG x: its typical step between lines, 100 s is too long for this observer: one prediction step multiplies a state error by "
        f"{too_long:.3g} (above 2 the estimates diverge); are the times in seconds?"
    )
    with pytest.raises(ValueError, match="^" + re.escape(expected)):
        check_step_length(observer, guess, zeros, zeros, 100.0, "LOG x: its typical step between lines,")


def test_a_discrete_time_observer_needs_rows_one_sample_period_apart():
    from lookout.papers import calugi_2002_adaptive_observer as ch4

    scenario = ch4.REPRODUCTION.scenario(ch4.Config(), "delta-0.01")
    observer = scenario.observer
    assert observer.sample_period == 0.01
    with pytest.raises(
        ValueError,
        match=r"times must step by the observer's sample_period 0.01 s \(a discrete-time observer\); the step from row 0 to 1 is 10 s; are the times in seconds\?",
    ):
        lookout.filter(observer, [0.0, 10.0, 20.0], np.zeros((3, 1)))
    stepper = lookout.Stepper(observer, y0=[0.0])
    with pytest.raises(ValueError, match=r"dt must be the observer's sample_period 0.01 s \(a discrete-time observer\); got 0.02 s"):
        stepper(0.0, [0.0], [0.0], 0.02)
    stepper(0.0, [0.0], [0.0], 0.01)


def test_stepper_checks_y0_and_input_size_at_construction(recorded):
    scenario, _, _ = recorded
    observer = scenario.observer
    with pytest.raises(ValueError, match=r"y0 must have 3 entries \(measured_position, measured_heading\); got 2"):
        lookout.Stepper(observer, observer.guess(), y0=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"y0 must be finite or NaN"):
        lookout.Stepper(observer, y0=[1.0, np.inf, 0.0])
    with pytest.raises(ValueError, match=r"y0 must be the first measurement \(3 entries"):
        lookout.Stepper(observer)
    with pytest.raises(ValueError, match=r"input_size must be 3, the length of the observer's input \(force, moment\); got 2"):
        lookout.Stepper(observer, y0=[0.0, 0.0, 0.0], input_size=2)
    with pytest.raises(ValueError, match=r"guess.eta must have shape \(3,\)"):
        lookout.Stepper(observer, _guess_with(observer, eta=np.zeros(4)), y0=[0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"observer must be a lookout Observer; got str"):
        lookout.Stepper("passive", y0=[0.0, 0.0, 0.0])


#: (t, y, u, dt) of a bad second call after a good call at t = 0 with dt = 0.1
BAD_CALLS = [
    ((0.1, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], np.nan), r"dt must be finite \(s\); got nan"),
    ((0.1, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.0), r"dt must be positive"),
    ((0.1, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], -0.1), r"dt must be positive"),
    ((np.inf, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.1), r"t must be finite \(s\); got inf"),
    ((-0.1, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.1), r"t must come after the previous call's t = 0 s; got -0.1 s \(time must not go backwards\)"),
    ((0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.1), r"t must come after the previous call's t = 0 s; got 0 s"),
    ((0.1, [0.0, 0.0, 0.0], [np.nan, 0.0, 0.0], 0.1), r"u must be finite \(the input applied until t \+ dt\); got \[nan, 0.0, 0.0\]"),
    ((0.1, [0.0, 0.0, 0.0], [0.0, 0.0], 0.1), r"u must have 3 entries \(force, moment\); got 2"),
    ((0.1, [0.0, np.inf, 0.0], [0.0, 0.0, 0.0], 0.1), r"y must be finite or NaN \(a missing channel\)"),
    ((0.1, [0.0, 0.0], [0.0, 0.0, 0.0], 0.1), r"y must have 3 entries"),
    (
        (0.1, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 100.0),
        r"dt: a step of 100 s is too long for this observer: one prediction step multiplies a state error by",
    ),
    (
        (0.1, [1e306, 0.0, 0.0], [0.0, 0.0, 0.0], 0.1),
        r"the step at t = 0.1 s over dt = 0.1 s gives a non-finite state or estimate; refused, the state is kept as it was",
    ),
    ((0.1, "abc", [0.0, 0.0, 0.0], 0.1), r"y must hold real numbers; got text"),
    (("0.1", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.1), r"t must hold real numbers"),
]


@pytest.mark.slow
@pytest.mark.parametrize("call, message", BAD_CALLS, ids=[f"call-{i}" for i in range(len(BAD_CALLS))])
def test_a_bad_call_raises_and_leaves_the_stepper_as_it_was(recorded, call, message):
    scenario, _, _ = recorded
    observer = scenario.observer
    stepper = lookout.Stepper(observer, y0=[1.0, 2.0, 0.1])
    stepper(0.0, [1.0, 2.0, 0.1], [0.0, 0.0, 0.0], 0.1)
    before = jax.tree.map(np.asarray, stepper.state)
    with pytest.raises(ValueError, match=message):
        stepper(*call)
    jax.tree.map(np.testing.assert_array_equal, jax.tree.map(np.asarray, stepper.state), before)
    # and the stepper goes on as if the bad call had never come
    reference = lookout.Stepper(observer, y0=[1.0, 2.0, 0.1])
    reference(0.0, [1.0, 2.0, 0.1], [0.0, 0.0, 0.0], 0.1)
    np.testing.assert_array_equal(
        stepper(0.1, [1.0, 2.0, np.nan], [1e3, 0.0, 0.0], 0.1)["position"], reference(0.1, [1.0, 2.0, np.nan], [1e3, 0.0, 0.0], 0.1)["position"]
    )


@pytest.mark.slow
def test_a_kalman_filter_on_a_log_gives_the_simulation_estimates():
    """The EKF steps a log whose time steps are known only when it runs (its propagation
    splits each step into the substeps of its filter period): the simulation's
    estimates, to rounding."""
    from lookout.scenario.composition import compose
    from lookout.scenario.registry import preset

    document = preset("fossen-strand-1999", "paper")
    document["simulation"]["duration"] = 60.0
    document["observer"] = {"kind": "ekf"}
    scenario = compose(document).scenario
    trajectory = simulate(scenario, jax.random.key(0))
    ds = trajectory.to_xarray()
    log = lookout.filter(
        scenario.observer,
        trajectory.time,
        trajectory.measurement,
        trajectory.applied,
        guess=scenario.initial_estimate,
        measurement_layout=POSITION_HEADING,
        input_layout=VESSEL_INPUT,
    )
    for name in ("position_hat", "heading_hat", "velocity_hat", "bias_force_hat", "wave_position_hat"):
        np.testing.assert_allclose(log[name].values, ds[name].values, rtol=1e-9, atol=1e-9 * float(np.abs(ds[name]).max()))
