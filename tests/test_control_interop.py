"""lookout plants and observers as python-control systems (:mod:`lookout.control_systems`).

Which input/output pair of the observer's linearization is h0
---------------------------------------------------------------
Fossen & Strand (1999), Section 4.2 and Proposition 1: with eta0 = [xi; eta], the
position error loop is

    eta0~' = (A0 - K C0) eta0~ + B0 eps_v,   y~ = C0 eta0~,   eps_v = J(y) nu~    (30), (36)

so h0(s) = C0 (sI - A0 + K C0)^-1 B0 per DOF, eq. (42) (the extracted text prints
``sI + A0 - K C0``; the sign that makes (42) is minus). Linearize the observer (22)–(26)
at rest (nu_hat = 0, b_hat = 0, y~ = 0) at a heading psi0: the terms J(y) nu_hat and
J^T(y) (b_hat + Kappa y~ / gamma) have zero derivative in the heading there, so

    eta0_hat' = (A0 - K C0) eta0_hat + B0 J(psi0) nu_hat + K y,   y_hat = C0 eta0_hat.

With the measurement input y held at zero (only the thrust tau drives the observer),
y_hat = h0(s) J(psi0) nu_hat exactly, whatever the velocity and bias loops make of tau:
for the transfer matrices of the linearized observer from tau (all three inputs) to
the output y_hat = -innovation (``innovation_position``, ``innovation_heading``) and to
the velocity estimate nu_hat (``velocity_hat``, ``yaw_rate_hat``),

    G_{tau -> y_hat}(jw) = diag(h0_1, h0_2, h0_3)(jw) J(psi0) G_{tau -> nu_hat}(jw),

so diag(h0) = -G_{tau -> innovation} G_{tau -> nu_hat}^-1 J(psi0)^T, channel by
channel on the diagonal, and zero off it. At psi0 = 0 and one input this is the ratio
-G_{tau_i -> innovation_i} / G_{tau_i -> nu_hat_i}. The loop itself is also the block of
the linearization's A on the states (xi1_hat, xi2_hat, eta_hat) of one DOF, with input
column A[eta_hat, nu_hat] (= B0 J(psi0)) and output row -C[innovation, .] (= C0).
"""

from __future__ import annotations

import functools

import control  # a test extra (pyproject: dev): the tests fail, not skip, without it
import equinox as eqx
import jax
import numpy as np
import pytest

from lookout import control_systems as cs
from lookout._math import rotation
from lookout.analysis.passive import default_frequencies, transfer_functions
from lookout.environment import GaussMarkovBias, LinearWaveModel
from lookout.models.manipulators import FreePendulum, ManipulatorPlant
from lookout.models.vessel import DOF, NORTHERN_CLIPPER_D, NORTHERN_CLIPPER_M, VesselPlant, northern_clipper
from lookout.observers import PassiveObserver
from lookout.sensors import PositionHeadingSensor

#: (estimate of the measured channel's low-frequency part, wave part, velocity) per DOF,
#: as the observer system names its states and outputs.
LOOP_STATES = {
    "surge": ("position_hat[north]", "wave_position_hat[north]", "velocity_hat[surge]", "innovation_position[north]", 0),
    "sway": ("position_hat[east]", "wave_position_hat[east]", "velocity_hat[sway]", "innovation_position[east]", 1),
    "yaw": ("heading_hat", "wave_heading_hat", "yaw_rate_hat", "innovation_heading", 2),
}
INNOVATIONS = ["innovation_position[north]", "innovation_position[east]", "innovation_heading"]
VELOCITIES = ["velocity_hat[surge]", "velocity_hat[sway]", "yaw_rate_hat"]
THRUST = ["force[surge]", "force[sway]", "moment"]


def _distinct_observer() -> PassiveObserver:
    """Other gains in every DOF, so that a channel mixed up with another shows."""
    return PassiveObserver.design(
        northern_clipper(),
        wave_frequency=[0.6, 0.9, 1.2],
        wave_damping=[0.05, 0.1, 0.15],
        notch_damping=[0.8, 1.0, 1.2],
        cutoff_frequency=[1.0, 1.3, 1.6],
        bias_time_constant=[500.0, 1000.0, 2000.0],
    )


def _observers(paper_observer):
    return {"paper": paper_observer, "distinct": _distinct_observer()}


def _operating_point(system, heading: float):
    """The observer at rest at ``heading``: eta_hat = (0, 0, psi0), the measurement equal to it."""
    x0 = system.state_vector(system.component.guess(eta=[0.0, 0.0, heading]))
    u0 = np.zeros(system.ninputs)
    u0[system.input_labels.index("measured_heading")] = heading
    return x0, u0


def _linearizations(system, x0, u0):
    return {
        "jax": cs.linearize_exact(system, x0, u0),
        "python-control": control.linearize(system, x0, u0, copy_names=True),
    }


@pytest.mark.parametrize("gains", ["paper", "distinct"])
@pytest.mark.parametrize("heading", [0.0, 2.5])
def test_h0_of_the_linearized_observer_is_lookouts_frequency_response(paper_observer, gains, heading):
    """diag(h0) = -G_{tau -> innovation} G_{tau -> nu_hat}^-1 J(psi0)^T (module docstring)
    equals lookout.analysis.passive.transfer_functions' h0 (eq. 42) on the grid of
    ``lookout design passive-observer``, to 1e-9 relative, in each DOF, for both
    linearizations, the paper's gains (59)–(60) and gains that differ per DOF; the
    off-diagonal terms are zero to 1e-9 of |h0|. Measured: at most 4e-15 (diagonal) and
    2e-14 (off it), except python-control's finite differences at psi0 = 2.5: 1.4e-10."""
    observer = _observers(paper_observer)[gains]
    system = cs.observer_system(observer)
    frequencies = default_frequencies(observer, points=300)
    expected = transfer_functions(observer, frequencies)["h0"]
    rotation_transpose = np.asarray(rotation(heading)).T
    for method, linear in _linearizations(system, *_operating_point(system, heading)).items():
        response = control.frequency_response(linear, frequencies).complex  # (outputs, inputs, frequencies)
        inputs = [linear.input_labels.index(name) for name in THRUST]
        innovation = response[np.ix_([linear.output_labels.index(n) for n in INNOVATIONS], inputs)]
        velocity = response[np.ix_([linear.output_labels.index(n) for n in VELOCITIES], inputs)]
        for k in range(frequencies.size):
            h0 = -innovation[:, :, k] @ np.linalg.inv(velocity[:, :, k]) @ rotation_transpose
            scale = np.abs(expected[k]).max()
            np.testing.assert_allclose(np.diag(h0), expected[k], rtol=1e-9, err_msg=f"{method}, w = {frequencies[k]:.4g} rad/s")
            off_diagonal = h0 - np.diag(np.diag(h0))
            assert np.abs(off_diagonal).max() <= 1e-9 * scale, (method, frequencies[k])


@pytest.mark.parametrize("gains", ["paper", "distinct"])
def test_the_loop_block_of_the_linearization_is_the_notch_shape_44(paper_observer, gains):
    """The error loop read off the linearization by state names (A's block on xi1_hat,
    xi2_hat, eta_hat; input column A[eta_hat, nu_hat]; output row -C[innovation, .]),
    turned into a transfer function by python-control's ``ss2tf``, is the notch shape
    (44) that the gains (45)–(47) were designed for:
    (s^2 + 2 zeta w_o s + w_o^2) / ((s^2 + 2 zeta_n w_o s + w_o^2)(s + w_c)), coefficients
    to 1e-10 relative, in each DOF."""
    observer = _observers(paper_observer)[gains]
    system = cs.observer_system(observer)
    linear = cs.linearize_exact(system, *_operating_point(system, 0.0))
    zeta_n = {"paper": np.full(3, 1.0), "distinct": np.array([0.8, 1.0, 1.2])}[gains]
    w_o, zeta, w_c = (
        np.broadcast_to(np.asarray(v, dtype=float), (3,)) for v in (observer.wave_frequency, observer.wave_damping, observer.position_injection_gain)
    )
    for dof in DOF:
        low, wave, velocity, innovation, i = LOOP_STATES[dof]
        states = [linear.state_labels.index(name) for name in (f"wave_state[{i}]", wave, low)]
        A = linear.A[np.ix_(states, states)]
        B = linear.A[np.ix_(states, [linear.state_labels.index(velocity)])]
        C = -linear.C[np.ix_([linear.output_labels.index(innovation)], states)]
        h0 = control.ss2tf(control.ss(A, B, C, 0.0))
        numerator, denominator = np.ravel(h0.num[0][0]), np.ravel(h0.den[0][0])
        numerator, denominator = numerator / denominator[0], denominator / denominator[0]
        numerator = numerator[np.argmax(np.abs(numerator) > 1e-12 * np.abs(numerator).max()) :]
        expected_numerator = [1.0, 2.0 * zeta[i] * w_o[i], w_o[i] ** 2]
        expected_denominator = np.polymul([1.0, 2.0 * zeta_n[i] * w_o[i], w_o[i] ** 2], [1.0, w_c[i]])
        np.testing.assert_allclose(numerator, expected_numerator, rtol=1e-10, err_msg=dof)
        np.testing.assert_allclose(denominator, expected_denominator, rtol=1e-10, err_msg=dof)


def _vessel_plant():
    return VesselPlant(northern_clipper(), GaussMarkovBias([800.0, 1000.0, 1200.0]), LinearWaveModel([0.7, 0.8976, 1.1], [0.05, 0.1, 0.2]))


def _assert_same_linearization(system, x0, u0, rtol):
    """jax.jacfwd and python-control's finite differences (step 1e-6 in every state and
    input) agree: each entry within ``rtol`` of its column's largest entry (the truncation
    error) plus 1e-9 of the value of its row's function at the point (the rounding error
    of a difference of step 1e-6 is about 2.2e-16 / 1e-6 = 2.2e-10 of that value)."""
    exact = cs.linearize_exact(system, x0, u0)
    numerical = control.linearize(system, x0, u0, copy_names=True)
    rates = np.abs(system._rhs(0.0, x0, u0))[:, None]
    outputs = np.abs(system._out(0.0, x0, u0))[:, None]
    for symbol, rounding in (("A", rates), ("B", rates), ("C", outputs), ("D", outputs)):
        a, b = getattr(exact, symbol), getattr(numerical, symbol)
        tolerance = rtol * np.abs(a).max(axis=0, keepdims=True) + 1e-9 * rounding + 1e-300
        np.testing.assert_array_less(np.abs(a - b), tolerance, err_msg=symbol)
    for labels in ("input_labels", "output_labels", "state_labels"):
        assert getattr(exact, labels) == getattr(numerical, labels)


def test_python_controls_linearize_and_the_jax_jacobians_agree_away_from_equilibrium(paper_observer):
    """At a moving vessel with bias, waves, a heading and an innovation (not an
    equilibrium), python-control's finite differences and jax.jacfwd give the same A, B,
    C, D for the plant and the observer, within the error of a difference of step 1e-6
    (:func:`_assert_same_linearization`)."""
    plant = _vessel_plant()
    state = plant.state(eta=[120.0, -40.0, 2.2], nu=[1.5, -0.3, 0.01], bias=[2e4, -1e4, 3e5], wave_state=[0.3, -0.2, 0.01, 1.0, 0.5, 0.02])
    plant_sys = cs.plant_system(plant, sensor=PositionHeadingSensor())
    x0 = plant_sys.state_vector(state)
    u0 = np.array([3e4, -1e4, 2e6])
    _assert_same_linearization(plant_sys, x0, u0, 1e-6)

    observer_sys = cs.observer_system(paper_observer)
    guess = paper_observer.guess(
        eta=[118.0, -41.0, 2.15], nu=[1.4, -0.2, 0.012], bias=[1.5e4, -8e3, 2e5], wave_state=[0.2, -0.1, 0.0, 0.8, 0.4, 0.01]
    )
    x0 = observer_sys.state_vector(guess)
    u0 = np.concatenate([[121.0, -39.5, 2.23], [3e4, -1e4, 2e6]])
    _assert_same_linearization(observer_sys, x0, u0, 1e-6)


@pytest.mark.parametrize("heading", [0.0, 0.7, -2.9])
def test_the_vessels_linearization_is_its_model(heading):
    """Exact reference, Fossen & Strand (1999), eqs. (1), (3), (7), (11): at rest at a
    heading psi0, d eta'/d nu = J(psi0), d nu'/d nu = -M^-1 D, d nu'/d b = M^-1 J^T(psi0),
    d nu'/d tau = M^-1, d b'/d b = -T^-1, the wave block is [[0, I], [-w0^2, -2 zeta w0]];
    the measurement output is eta + eta_w."""
    plant = _vessel_plant()
    system = cs.plant_system(plant, sensor=PositionHeadingSensor())
    linear = cs.linearize_exact(system, plant.state(eta=[5.0, -3.0, heading]), 0.0)
    index = {name: i for i, name in enumerate(linear.state_labels)}
    eta = [index[n] for n in ("position[north]", "position[east]", "heading")]
    nu = [index[n] for n in ("velocity[surge]", "velocity[sway]", "yaw_rate")]
    bias = [index[n] for n in ("bias_force[north]", "bias_force[east]", "bias_moment")]
    xi1 = [index[f"wave_state[{i}]"] for i in range(3)]
    xi2 = [index[n] for n in ("wave_position[north]", "wave_position[east]", "wave_heading")]
    M_inv = np.linalg.inv(NORTHERN_CLIPPER_M)
    J = np.asarray(rotation(heading))
    w0, zeta = np.array([0.7, 0.8976, 1.1]), np.array([0.05, 0.1, 0.2])
    expected = np.zeros((15, 15))
    expected[np.ix_(eta, nu)] = J
    expected[np.ix_(nu, nu)] = -M_inv @ NORTHERN_CLIPPER_D
    expected[np.ix_(nu, bias)] = M_inv @ J.T
    expected[np.ix_(bias, bias)] = -np.diag(1.0 / np.array([800.0, 1000.0, 1200.0]))
    expected[np.ix_(xi1, xi2)] = np.eye(3)
    expected[np.ix_(xi2, xi1)] = -np.diag(w0**2)
    expected[np.ix_(xi2, xi2)] = -np.diag(2.0 * zeta * w0)
    np.testing.assert_allclose(linear.A, expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(linear.B[nu], M_inv, rtol=1e-12)
    assert np.all(np.delete(linear.B, nu, axis=0) == 0.0)
    measured = [linear.output_labels.index(n) for n in ("measured_position[north]", "measured_position[east]", "measured_heading")]
    np.testing.assert_array_equal(linear.C[measured][:, eta], np.eye(3))
    np.testing.assert_array_equal(linear.C[measured][:, xi2], np.eye(3))


@pytest.mark.parametrize("angle", [0.0, 0.4, np.pi])
def test_the_pendulums_linearization_is_its_model(angle):
    """Another plant family: the free pendulum m l^2 q'' + c q' + m g l sin q = u of
    Calugi (2002), Section 2.3, at q0: A = [[0, 1], [-g cos(q0) / l, -c / (m l^2)]],
    B = [0, 1 / (m l^2)]; the states are named by the joint."""
    m, l, c, g = 0.5, 0.5, 0.1, 9.81
    plant = ManipulatorPlant(FreePendulum(m, l, c, g))
    system = cs.plant_system(plant)
    assert system.state_labels == ["joint_angle[pendulum]", "joint_rate[pendulum]"]
    assert system.input_labels == ["joint_torque[pendulum]"]
    for linear in (cs.linearize_exact(system, [angle, 0.0], 0.0), control.linearize(system, [angle, 0.0], 0.0)):
        np.testing.assert_allclose(linear.A, [[0.0, 1.0], [-g * np.cos(angle) / l, -c / (m * l**2)]], rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(linear.B, [[0.0], [1.0 / (m * l**2)]], rtol=1e-6)


def test_plant_and_observer_connect_by_name_and_the_error_stays_zero_from_a_perfect_start(paper_observer):
    """``control.interconnect`` joins the plant (with the sensor's noise-free measurement)
    and the observer by signal name; from a perfect start, without noise and with no
    wave-induced heading (the observer's J(y) is the plant's J(psi) then, assumption of
    eq. 15), python-control's simulation keeps every estimate on its truth to the
    solver's tolerance (5e-9 relative), under a thrust that turns the vessel."""
    plant = VesselPlant(northern_clipper(), GaussMarkovBias(1000.0), LinearWaveModel(0.8976, 0.1))
    plant_sys = cs.plant_system(plant, sensor=PositionHeadingSensor())
    observer_sys = cs.observer_system(paper_observer)
    truths = cs.signal_names(plant.variable_signals)
    estimates = cs.signal_names(paper_observer.estimate_signals, "_hat")
    loop = control.interconnect(
        [plant_sys, observer_sys], inplist=THRUST, outlist=truths + estimates, ignore_outputs=cs.signal_names(paper_observer.extra_signals)
    )
    start = plant.state(eta=[10.0, -5.0, 0.4], nu=[0.5, 0.1, 0.001], bias=[1e4, 5e3, 1e5], wave_state=[0.1, 0.1, 0.0, 0.5, 0.3, 0.0])
    x0 = np.concatenate([plant_sys.state_vector(start), observer_sys.state_vector(start)])
    times = np.linspace(0.0, 20.0, 21)
    thrust = np.array([1e3, -2e3, 1e6])[:, None] * np.ones((1, times.size))
    response = control.input_output_response(loop, times, thrust, x0, solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-12})
    truth, estimate = response.outputs[: len(truths)], response.outputs[len(truths) :]
    scale = np.abs(truth).max(axis=1, keepdims=True) + 1e-12
    error = np.abs(np.asarray(estimate) - np.asarray(truth))
    assert np.all(error <= 5e-9 * scale + 1e-15), dict(zip(truths, (error / scale).max(axis=1)))
    assert np.abs(truth[2, -1] - truth[2, 0]) > 0.05  # the heading turned


def test_a_gain_change_does_not_compile_again(monkeypatch, paper_observer):
    """Gains are traced arguments of the jitted functions: a system of another observer
    of the same structure (other gains, other wave frequency) reuses the compiled code."""
    traced = eqx.debug.assert_max_traces(cs._observer_rates.__wrapped__, max_traces=1)
    monkeypatch.setattr(cs, "_observer_rates", functools.partial(jax.jit, static_argnums=(1, 2))(traced))
    for observer in (paper_observer, _distinct_observer()):
        system = cs.observer_system(observer)
        system.updfcn(0.0, np.zeros(system.nstates), np.ones(system.ninputs), {})


# ---------------------------------------------------------------------------- refusals


def _refusal(build) -> str:
    with pytest.raises(ValueError) as error:
        build()
    message = str(error.value)
    assert "\n" not in message and len(message) < 400, message
    return message


def test_a_discrete_time_observer_is_refused_in_one_line():
    from lookout.models.manipulators import TwoLinkArm
    from lookout.models.parameters import ModelParameters
    from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver

    arm = ModelParameters(TwoLinkArm((1.0, 1.5), (1.0, 1.0), (0.0, 0.0)), ("masses[1]",), units=("kg",))
    observer = AdaptiveManipulatorObserver(arm, 5.0, 0.1, sample_period=0.01, lower=0.5, upper=3.0, margin=0.2)
    message = _refusal(lambda: cs.observer_system(observer))
    assert "adaptive-manipulator" in message and "sample_period = 0.01 s" in message


def test_an_observer_in_its_discrete_form_is_refused_in_one_line():
    from lookout.observers.adaptive_dp import AdaptiveObserver, InertiaParametrization

    vessel = northern_clipper()
    m11 = float(np.asarray(vessel.mass_matrix)[0, 0])
    observer = AdaptiveObserver(InertiaParametrization(vessel, ("m11",), [0.5 * m11], [2.0 * m11]), 0.5, 0.5, 0.0, form="discrete", initial_theta=m11)
    message = _refusal(lambda: cs.observer_system(observer))
    assert "adaptive-dp" in message and "no continuous-time vector field" in message and "form='discrete'" in message


def test_a_kalman_filter_is_refused_in_one_line():
    from lookout.observers.ekf import ExtendedKalmanFilter

    plant = _vessel_plant()
    std = {"eta": [5.0, 5.0, 0.05], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [1.0, 1.0, 0.01, 1.0, 1.0, 0.01]}
    observer = ExtendedKalmanFilter(
        plant, PositionHeadingSensor(), measurement_noise=[0.5, 0.5, 0.002], initial_std=std, plant_step=0.1, filter_period=0.1
    )
    message = _refusal(lambda: cs.observer_system(observer))
    assert "ekf" in message and "not a continuous-time observer" in message


def test_a_plant_with_randomness_that_cannot_be_set_to_zero_is_refused_in_one_line():
    from lookout.environment import JonswapWaves
    from lookout.models.cybership import CYBERSHIP_LENGTH, CybershipPlant, cybership2

    random_sea = CybershipPlant(cybership2(), JonswapWaves(0.01, 0.75, hull_length=CYBERSHIP_LENGTH))
    message = _refusal(lambda: cs.plant_system(random_sea))
    assert "cybership-ii" in message and "waves." in message and "realize" in message
    calm = cs.plant_system(CybershipPlant(cybership2()))  # calm water: deterministic
    assert calm.state_labels[:3] == ["position[north]", "position[east]", "heading"]


@pytest.mark.parametrize(
    ("x0", "u0", "expected"),
    [
        (np.zeros(14), 0.0, "x0 must have shape (15,)"),
        (np.zeros(100_000), 0.0, "x0 must have shape (15,)"),
        (np.full(15, np.nan), 0.0, "x0 must be finite; entry 0 (position_hat[north])"),
        (0.0, np.zeros(100_000), "u0 must have shape (6,)"),
        (0.0, [0.0, 0.0, np.inf, 0.0, 0.0, 0.0], "u0 must be finite; entry 2 (measured_heading)"),
        ("calm", 0.0, "x0 must be an array of 15 numbers"),
        (
            ManipulatorPlant(FreePendulum()).state(q=0.1),
            0.0,
            "x0: state must be a state of PassiveObserver (parts eta, nu, bias, wave_state); got a JointState",
        ),
        (None, 0.0, "x0 must be an array of 15 numbers or a state of the component; got None"),
        ([0.0] * 14 + [None], 0.0, "x0 must be an array of 15 numbers or a state of the component; entry 14 is None"),
        (0.0, None, "u0 must be an array of 6 numbers; got None"),
        (np.full(15, 1j), 0.0, "x0 must be real; got complex values"),
        (0.0, [0.0, 0.0, 0.1 + 0.0j, 0.0, 0.0, 0.0], "u0 must be real; got complex values"),
    ],
)
def test_a_bad_operating_point_is_refused_in_one_line_naming_the_argument(paper_observer, x0, u0, expected):
    system = cs.observer_system(paper_observer)
    message = _refusal(lambda: cs.linearize_exact(system, x0, u0))
    assert expected in message, message


@pytest.mark.parametrize("t", [None, 1j, float("nan"), "0"])
def test_a_time_that_is_not_a_finite_real_number_is_refused_naming_t(paper_observer, t):
    system = cs.observer_system(paper_observer)
    assert _refusal(lambda: cs.linearize_exact(system, 0.0, 0.0, t)) == f"t must be a finite real number; got {t!r}"


def test_a_complex_state_is_refused_not_cast(paper_observer):
    system = cs.observer_system(paper_observer)
    guess = paper_observer.guess(eta=[0.0, 0.0, 0.0])
    complex_guess = jax.tree.map(lambda leaf: np.asarray(leaf) + 1j, guess)
    assert _refusal(lambda: cs.linearize_exact(system, complex_guess, 0.0)) == "x0: state must be real; got a VesselState with complex entries"


def test_the_observers_default_guess_starts_from_the_measurement_of_the_operating_point(paper_observer):
    """The docs' call: ``linearize_exact(system, observer.guess(), 0)``. The default
    guess leaves the position to the first measurement; it starts from the measurement
    in u0, as a run starts (observer.init), so it equals the guess given that position."""
    system = cs.observer_system(paper_observer)
    default = cs.linearize_exact(system, paper_observer.guess(), 0)
    given = cs.linearize_exact(system, paper_observer.guess(eta=[0.0, 0.0, 0.0]), 0)
    assert np.array_equal(default.A, given.A) and np.array_equal(default.C, given.C)
    heading = 0.4
    u0 = np.zeros(system.ninputs)
    u0[system.input_labels.index("measured_heading")] = heading
    x0, _ = _operating_point(system, heading)
    assert np.array_equal(system.state_vector(paper_observer.guess(), u0[:3]), x0)
    assert np.array_equal(cs.linearize_exact(system, paper_observer.guess(), u0).A, cs.linearize_exact(system, x0, u0).A)


def test_a_sensor_that_does_not_measure_the_plant_is_refused_naming_both():
    from lookout.sensors import JointEncoder

    encoder = JointEncoder(FreePendulum(), sample_period=0.01)
    message = _refusal(lambda: cs.plant_system(_vessel_plant(), sensor=encoder))
    assert message == "sensor joint-encoder and plant dp-vessel do not fit: 'VesselState' object has no attribute 'q'"


def test_linearize_exact_refuses_a_system_it_did_not_build(paper_observer):
    other = control.nlsys(lambda t, x, u, params: -x, None, states=1, inputs=1, outputs=1)
    message = _refusal(lambda: cs.linearize_exact(other, 0.0, 0.0))
    assert message.startswith("system must be built by lookout.control_systems")
