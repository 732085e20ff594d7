"""Conformance suite: what every observer (and its scenario) must do in the engine.

A new observer joins by adding a :class:`Case` to ``CASES``, not by writing tests:

- vmapped runs equal the same runs one by one;
- a change of gains only does not trace the engine again;
- noise-free, from a perfect start, the estimation error stays at zero in each of
  the case's ``exact`` modes: "continuous" (integrated jointly with the plant) for
  continuous-time observers, and "sampled" for an observer whose sampled
  implementation runs its model free between samples (the passive observer with
  ``hold="innovation"``; holding the measurement instead is exact only to the
  discretization, 7.9 mm over 200 s at 10 Hz);
- NaN dropouts keep the estimate finite;
- a run in chunks (progress) equals the whole run, and decimated records are every
  n-th sample of the full run (engine properties: checked on one or two cases);
- a scenario built inside ``jax.vmap`` over a gain simulates like the ones built
  one by one, and (on four cases: two open loops, two closed loops) the derivative of an
  RMS error through ``simulate`` matches central differences.
"""

from __future__ import annotations

import dataclasses
import functools
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lookout._math import rotate
from lookout.analysis import estimation_errors
from lookout.sim import Scenario, simulate, simulate_batch


@dataclass(frozen=True)
class Case:
    """How to build a scenario of one observer for the suite.

    ``build(gain, *, noise, perfect, dropout, duration, **options)`` returns a
    Scenario; ``gain`` scales the observer's gains and may be a JAX tracer (it is
    vmapped and differentiated); ``perfect`` starts the observer at the true state;
    ``noise`` switches all process and measurement noise. ``exact`` lists the
    ``(observer_mode, options)`` in which a noise-free run from a perfect start stays
    exact, to ``exact_tolerance`` relative to the variable's size (rounding, unless the
    case says why not). ``error_variable`` is the recorded variable whose RMS error the gradient
    check differentiates (a ``<name>_hat`` of ``parameter_truth``: against its true value), by ``jax.grad`` (``gradient="reverse"``) or, for the closed
    loops, ``jax.jacfwd`` (``"forward"``): the same derivative of one scalar gain,
    which compiles 2.7x faster through a closed loop (19 s against 52 s for Kim's);
    reverse mode through ``simulate`` is checked on the open-loop cases.
    """

    name: str
    build: Callable[..., Scenario]
    exact: tuple[tuple[str, dict], ...]
    error_variable: str
    gradient: str | None = "reverse"  # None: the error is not differentiable in the gain (the case says why)
    exact_tolerance: float = 1e-12
    #: for an observer that estimates parameters rather than plant variables: the true
    #: value of each ``<name>_hat`` it outputs, checked by the exactness test too
    parameter_truth: tuple[tuple[str, float], ...] = ()
    #: probability of a dropped sample in the dropout test (0.5 unless the case says why not)
    dropout: float = 0.5


def _passive(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0, hold="measurement") -> Scenario:
    from lookout import PositionHeadingSensor
    from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_MASS, northern_clipper
    from lookout.observers import PassiveObserver, injection_gains_from_normalized
    from lookout.papers import fossen_strand_1999 as fs

    quiet = {} if noise else {"noise_std": (0, 0, 0), "bias_std": (0, 0, 0), "wave_amplitude": (0, 0, 0)}
    config = fs.Config(duration=duration, measurement_period=0.1 if perfect else 1.0, **quiet)
    base = fs.build(config)
    kappa, lam = injection_gains_from_normalized(
        config.velocity_gain_normalized, config.bias_gain_normalized, mass=NORTHERN_CLIPPER_MASS, length=NORTHERN_CLIPPER_LENGTH
    )
    observer = PassiveObserver.design(
        northern_clipper(),
        wave_frequency=config.wave_frequency,
        wave_damping=config.wave_damping,
        notch_damping=config.notch_damping,
        cutoff_frequency=config.cutoff_frequency,
        velocity_injection_gain=gain * jnp.asarray(kappa),
        bias_injection_gain=gain * jnp.asarray(lam),
        bias_time_constant=config.bias_time_constant,
        hold=hold,
    )
    sensor = PositionHeadingSensor(config.noise_std, config.measurement_period, dropout_probability=dropout)
    guess = base.initial_state if perfect else observer.guess()
    return Scenario(
        base.plant,
        sensor,
        observer,
        base.controller,
        base.initial_state,
        guess,
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
    )


def _velocity(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """The two-link arm of Calugi (2002), Section 2.3, with the reduced-order velocity observer."""
    from lookout.controllers import SinusoidalInput
    from lookout.models.manipulators import ManipulatorPlant, TwoLinkArm
    from lookout.observers import VelocityObserver
    from lookout.sensors import JointEncoder

    arm = TwoLinkArm()
    plant = ManipulatorPlant(arm, force_noise=0.05 if noise else 0.0)
    sensor = JointEncoder(arm, sample_period=0.01, noise_std=1e-4 if noise else 0.0, dropout_probability=dropout)
    observer = VelocityObserver(arm, gain * jnp.full(2, 5.0))
    start = plant.state(q=[-np.pi / 4, -np.pi / 4], qdot=[0.0, 0.0])
    guess = start.qdot if perfect else jnp.asarray([-4.0, -4.0])
    return Scenario(
        plant,
        sensor,
        observer,
        SinusoidalInput.constant([2.0, 1.0]),
        start,
        guess,
        plant_step=0.005,
        sample_period=0.01,
        duration=duration,
    )


def _sliding_mode_loop(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0, hold="measurement", thrusters=False) -> Scenario:
    """Kim (2002): the sliding-mode observer in closed loop with observer backstepping,
    a reference filter and thrust limits (or, with ``thrusters``, the supply vessel's
    thrusters and QP allocation); ``gain`` scales H3, H4 and Kbar."""
    from lookout import PositionHeadingSensor
    from lookout.actuators import SaturatingActuator, ThrusterLayout, ThrusterSystem
    from lookout.controllers import ObserverBackstepping
    from lookout.models.vessel import NORTHERN_CLIPPER_THRUST_LIMIT, VesselState, northern_clipper
    from lookout.papers import fossen_strand_1999 as fs
    from lookout.papers import kim_2002
    from lookout.reference import ReferenceFilter

    quiet = {} if noise else {"noise_std": (0, 0, 0), "bias_std": (0, 0, 0), "wave_amplitude": (0, 0, 0)}
    config = fs.Config(duration=duration, measurement_period=0.1 if perfect else 1.0, **quiet)
    base = fs.build(config)
    gains = kim_2002.gain_sets()["kyp"]
    observer = kim_2002.printed_observer(
        northern_clipper(),
        boundary_layer=(5.0, 5.0, 0.02),
        switching_gain=gain * jnp.asarray([10.0, 10.0, 0.01]),
        hold=hold,
        velocity_injection_gain=gain * jnp.asarray(gains["velocity_injection_gain"]),
        bias_injection_gain=gain * jnp.asarray(gains["bias_injection_gain"]),
        bias_time_constant=config.bias_time_constant,
    )
    controller = ObserverBackstepping.for_observer(
        observer, integral_gain=0.01, position_gain=0.1, velocity_gain=0.1, coupling_gain=0.01, damping_weights=[1e-3] * 3 + [1e-2] * 3
    )
    sensor = PositionHeadingSensor(config.noise_std, config.measurement_period, dropout_probability=dropout)
    start = VesselState.build(eta=[3.0, -2.0, 0.05], bias=config.bias_initial)
    return Scenario(
        base.plant,
        sensor,
        observer,
        controller,
        start,
        start if perfect else observer.guess(),
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
        reference=ReferenceFilter.vessel(0.05, [0.0, 5.0], [[0.0, 0.0, 0.0], [10.0, 5.0, 0.1]]),
        actuator=ThrusterSystem(ThrusterLayout.supply_vessel()) if thrusters else SaturatingActuator(NORTHERN_CLIPPER_THRUST_LIMIT),
    )


def _adaptive_loop(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0, form="discrete") -> Scenario:
    """Calugi et al. (2003): the adaptive observer (theta = m11) in closed loop with vectorial
    observer backstepping and a reference filter; ``gain`` scales K1, K2 and Gamma.
    ``form="continuous"`` reads the true velocity from the oracle sensor (analysis only)."""
    from lookout.controllers import VectorialBackstepping
    from lookout.environment import GaussMarkovBias, LinearWaveModel
    from lookout.models.vessel import VesselPlant, VesselState, northern_clipper
    from lookout.observers import AdaptiveObserver, InertiaParametrization
    from lookout.reference import ReferenceFilter
    from lookout.sensors import PositionHeadingSensor, PositionHeadingVelocitySensor

    vessel = northern_clipper()
    m11 = float(np.asarray(vessel.mass_matrix)[0, 0])
    plant = VesselPlant(vessel, GaussMarkovBias(1000.0, [1e3, 1e3, 1e5] if noise else 0.0), LinearWaveModel(0.8976, 0.1, 0.0))
    parametrization = InertiaParametrization(vessel, ("m11",), [0.5 * m11], [2.0 * m11])
    observer = AdaptiveObserver(parametrization, gain * jnp.full(3, 0.5), gain * jnp.full(3, 0.5), gain * 1e8, form=form, initial_theta=0.7 * m11)
    if form == "discrete":
        sensor = PositionHeadingSensor([0.5, 0.5, 1e-3] if noise else 0.0, 0.1, dropout_probability=dropout)
    else:
        sensor = PositionHeadingVelocitySensor([0.5, 0.5, 1e-3, 0.01, 0.01, 1e-4] if noise else 0.0, 0.1, dropout_probability=dropout)
    controller = VectorialBackstepping.for_observer(observer, position_gain=0.1, velocity_gain=0.1, damping_weights=[0.1] * 6, coupling_gain=0.01)
    start = VesselState.build(eta=[3.0, -2.0, 0.05], nu=[0.1, 0.0, 0.0])
    guess = observer.guess(start.eta, start.nu, m11) if perfect else observer.guess()
    return Scenario(
        plant,
        sensor,
        observer,
        controller,
        start,
        guess,
        plant_step=0.1,
        sample_period=0.1,
        duration=duration,
        reference=ReferenceFilter.vessel(0.1, [0.0, 5.0], [[0.0, 0.0, 0.0], [10.0, 5.0, 0.1]]),
    )


def _tracking_loop(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0, plant_step=0.05) -> Scenario:
    """Wondergem et al. (2009): the Earth-fixed observer (6) and the tracking scheme (23) on
    Cybership II around an ellipse, thrust limits on, JONSWAP waves and measurement noise
    when ``noise``; ``gain`` scales L1, L2 and Omega."""
    from lookout.actuators import SaturatingActuator
    from lookout.controllers import TrackingController
    from lookout.environment import JonswapWaves
    from lookout.models.cybership import CYBERSHIP_LENGTH, CYBERSHIP_THRUST_LIMIT, CybershipPlant, CybershipState, cybership2
    from lookout.observers import EarthFixedObserver
    from lookout.reference import EllipseReference
    from lookout.sensors import PositionHeadingSensor

    ship = cybership2()
    observer = EarthFixedObserver(ship, gain * 15.0, gain * 50.0)
    controller = TrackingController(ship, natural_frequency=gain * jnp.asarray([0.72, 0.42, 0.64]))
    plant = CybershipPlant(ship, JonswapWaves(0.01, 0.75, hull_length=CYBERSHIP_LENGTH) if noise else None)
    sensor = PositionHeadingSensor([0.002, 0.002, 0.002] if noise else 0.0, 0.05, dropout_probability=dropout)
    start = CybershipState.build(eta=[3.8, -1.2, 0.5 * np.pi], nu=[0.05, 0.0, 0.01])
    guess = observer.guess(start.eta, rotate(start.eta[2], start.nu)) if perfect else observer.guess([4.0, -1.0, 2.94], [0.5, 0.5, -0.5])
    return Scenario(
        plant,
        sensor,
        observer,
        controller,
        start,
        guess,
        plant_step=plant_step,
        sample_period=0.05,
        duration=duration,
        reference=EllipseReference((3.5, 1.823), (0.2,)),
        actuator=SaturatingActuator(CYBERSHIP_THRUST_LIMIT),
    )


def _adaptive_arm(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """Calugi (2002) ch. 4–5: the discrete adaptive observer (4.34)–(4.35) with resetting and
    the adaptive observer backstepping (5.9) on the two-link arm, theta = m2 unknown,
    tracking a filtered square wave; ``gain`` scales K and Gamma. Discrete only: (4.34)
    is Euler with the measured increment, exact to O(Delta^2) per step, so the case has
    no exact mode (the order is tested in test_adaptive_manipulator)."""
    from lookout.controllers.adaptive_backstepping import AdaptiveObserverBackstepping
    from lookout.models.manipulators import ManipulatorPlant, TwoLinkArm
    from lookout.models.parameters import ModelParameters
    from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver
    from lookout.papers.calugi_2002_backstepping import Config, reference
    from lookout.sensors import JointEncoder

    arm = TwoLinkArm((1.0, 1.5), (1.0, 1.0), (0.1, 0.1))
    parameters = ModelParameters(arm, ("masses[1]",), units=("kg",))
    observer = AdaptiveManipulatorObserver(parameters, gain * 5.0, gain * 0.1, sample_period=0.01, lower=0.5, upper=3.0, margin=0.2)
    controller = AdaptiveObserverBackstepping(parameters, gain * 5.0, 2.0, 2.0, 1.0)
    plant = ManipulatorPlant(arm, force_noise=0.05 if noise else 0.0)
    start = plant.state([0.2, -0.3], [0.1, 0.0])
    guess = observer.guess([0.1, 0.0], 1.5) if perfect else observer.guess(0.0, 1.0)
    return Scenario(
        plant,
        JointEncoder(arm, sample_period=0.01, noise_std=1e-4 if noise else 0.0, dropout_probability=dropout),
        observer,
        controller,
        start,
        guess,
        plant_step=0.005,
        sample_period=0.01,
        duration=duration,
        reference=reference(Config(duration=max(duration, 11.0))),
    )


def _parameter_estimator(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """Calugi (2002) ch. 3: the filtered-regressor estimator on a pendulum of unknown mass
    and friction, measuring q and q', under tau = 5 sin t; ``gain`` scales h."""
    from lookout.controllers import SinusoidalInput
    from lookout.models.manipulators import FreePendulum, ManipulatorPlant
    from lookout.models.parameters import ModelParameters
    from lookout.observers.parameter_estimator import ParameterEstimator
    from lookout.sensors import JointStateSensor

    pendulum = FreePendulum(1.0, 1.5, 0.1)
    parameters = ModelParameters(pendulum, ("mass", "friction[0]"), units=("kg", "N m s/rad"))
    observer = ParameterEstimator(parameters, gain * 10.0)
    plant = ManipulatorPlant(pendulum, force_noise=0.05 if noise else 0.0)
    sensor = JointStateSensor(pendulum, sample_period=0.01, noise_std=[1e-3, 1e-2] if noise else 0.0, dropout_probability=dropout)
    return Scenario(
        plant,
        sensor,
        observer,
        SinusoidalInput(5.0, 1.0, size=1),
        plant.state(0.5, 0.0),
        jnp.asarray([1.0, 0.1]) if perfect else jnp.asarray([0.5, 0.3]),
        plant_step=0.001,
        sample_period=0.01,
        duration=duration,
    )


def _furuta(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """Calugi (2002) ch. 6: the Furuta pendulum with stick-slip arm friction and quantized
    encoders, the adaptive observer (tau_C unknown) and the pendulum controller (6.5)–(6.11),
    tracking the hanging square wave (Exp. II); ``gain`` scales K and Gamma. Without noise
    the encoders still quantize, and (4.34) is Euler: no exact mode."""
    from lookout.controllers.furuta import FurutaPendulumBackstepping
    from lookout.models.furuta import FurutaConstants, FurutaPlant
    from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver
    from lookout.papers import calugi_2002_furuta as ch6
    from lookout.sensors import JointEncoder

    truth = FurutaConstants()
    unknowns = ch6.parameters(("coulomb_friction[0]",))
    observer = AdaptiveManipulatorObserver(unknowns, gain * 5.0, gain * 0.01, sample_period=ch6.SAMPLE_PERIOD, lower=0.001, upper=0.04, margin=1e-4)
    controller = FurutaPendulumBackstepping(unknowns, 10.0, 1.0, 10.0, 1.0)
    plant = FurutaPlant(truth)
    encoder = JointEncoder(
        truth, sample_period=ch6.SAMPLE_PERIOD, quantization=ch6.QUANTIZATION, noise_std=[2e-3, 2e-4] if noise else 0.0, dropout_probability=dropout
    )
    guess = observer.guess(0.0, 0.028 if perfect else 0.001)
    return Scenario(
        plant,
        encoder,
        observer,
        controller,
        plant.state([0.0, np.pi], [0.0, 0.0]),
        guess,
        plant_step=0.0025 / 4,
        sample_period=ch6.SAMPLE_PERIOD,
        duration=round(duration / ch6.SAMPLE_PERIOD) * ch6.SAMPLE_PERIOD,
        reference=ch6.reference(ch6.EXPERIMENTS["II"], duration),
    )


def _kalman(kind, gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """The extended or unscented Kalman filter on the Fossen & Strand vessel (its own
    model: bias and wave states included); ``gain`` scales the process noise Q."""
    from lookout import PositionHeadingSensor
    from lookout.observers.ekf import ExtendedKalmanFilter
    from lookout.observers.ukf import UnscentedKalmanFilter
    from lookout.papers import fossen_strand_1999 as fs

    quiet = {} if noise else {"noise_std": (0, 0, 0), "bias_std": (0, 0, 0), "wave_amplitude": (0, 0, 0)}
    config = fs.Config(duration=duration, measurement_period=0.1 if perfect else 1.0, **quiet)
    base = fs.build(config)
    sensor = PositionHeadingSensor(config.noise_std, config.measurement_period, dropout_probability=dropout)
    std = {"eta": [5.0, 5.0, 0.05], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [1.0, 1.0, 0.01, 1.0, 1.0, 0.01]}
    filter_class = {"ekf": ExtendedKalmanFilter, "ukf": UnscentedKalmanFilter}[kind]
    observer = filter_class(
        base.plant,
        sensor,
        process_noise=gain * jnp.ones(base.plant.noise_size),
        measurement_noise=[0.5, 0.5, 0.0017],
        initial_std=std,
        plant_step=config.plant_step,
        filter_period=config.sample_period,
    )
    guess = base.initial_state if perfect else observer.guess()
    return Scenario(
        base.plant,
        sensor,
        observer,
        base.controller,
        base.initial_state,
        guess,
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
    )


def _model_free(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """The observer without a hull model on the Fossen & Strand vessel; ``gain`` scales its
    model's white acceleration (the filter's Q)."""
    from lookout import PositionHeadingSensor
    from lookout.models.kinematic_vessel import KinematicState
    from lookout.observers.model_free import ModelFreeFilter
    from lookout.papers import fossen_strand_1999 as fs

    quiet = {} if noise else {"noise_std": (0, 0, 0), "bias_std": (0, 0, 0), "wave_amplitude": (0, 0, 0)}
    config = fs.Config(duration=duration, measurement_period=0.1 if perfect else 1.0, **quiet)
    base = fs.build(config)
    sensor = PositionHeadingSensor(config.noise_std, config.measurement_period, dropout_probability=dropout)
    model_sensor = PositionHeadingSensor((0.5, 0.5, 0.0017), config.measurement_period)  # its R: the filter's, also noise-free
    observer = ModelFreeFilter(model_sensor, plant_step=config.plant_step, filter_period=config.sample_period)
    observer = eqx.tree_at(lambda o: o.model.acceleration_std, observer, gain * observer.model.acceleration_std)
    truth = base.initial_state
    guess = KinematicState(truth.eta, truth.nu, jnp.zeros(0)) if perfect else observer.guess()
    return Scenario(
        base.plant,
        sensor,
        observer,
        base.controller,
        base.initial_state,
        guess,
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
    )


def _ins(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """The IMU-aided observer on the Northern Clipper with a suite of a GNSS receiver at a
    lever arm, a gyrocompass and an IMU at 10 Hz, built from a scenario document; ``gain``
    scales its model's noise densities and bias drift (the filter's Q). Dropouts: every
    instrument, the IMU included, silent over ``dropout`` of the run from 5 s."""
    from lookout.scenario.composition import compose

    quiet = 1.0 if noise else 0.0
    lost = [{"mode": "dropout", "start": 5.0, "duration": dropout * duration}] if dropout else []
    document = {
        "simulation": {"plant_step": 0.1, "sample_period": 0.1, "duration": duration, "runs": 1},
        "plant": {
            "kind": "dp-vessel",
            "vessel": {"kind": "northern-clipper"},
            "bias": {"kind": "gauss-markov", "time_constant": 1000.0, "std": [2000.0 * quiet, 2000.0 * quiet, 5e4 * quiet]},
            "waves": {"kind": "linear", "peak_frequency": 0.8976, "damping_ratio": 0.1, "amplitude": [2.0 * quiet, 2.0 * quiet, 0.0035 * quiet]},
        },
        "sensors": {
            "gnss": {"kind": "gnss", "lever_arm": [30.0, 5.0], "noise_std": 0.5 * quiet, "sample_period": 1.0, "failures": lost},
            "gyro": {"kind": "gyrocompass", "noise_std": 0.0017 * quiet, "sample_period": 0.1, "failures": lost},
            "imu": {"kind": "imu", "lever_arm": [2.0, 1.0], "accelerometer_std": 0.01 * quiet, "gyro_std": 0.001 * quiet, "failures": lost},
        },
        "observer": {
            "kind": "ins",
            # the filter's own noise: its R and Q stay positive when the truth is noise-free
            "measurement_noise": [0.5, 0.5, 0.0017, 1.0, 1.0, 1.0],
            "accelerometer_noise": 0.003,
            "gyro_noise": 3e-4,
            "bias_std": [1e-3, 1e-3, 1e-5],
            "bias_time_constant": 3600.0,
            "wave_period": 7.0,
            "wave_std": [0.7, 0.7, 0.0012],
        },
        "controller": {"kind": "sinusoidal", "amplitude": [1e5, 5e4, 1e6], "frequency": 0.05, "offset": [0.0, 0.0, 0.0]},
    }
    scenario = compose(document).scenario
    observer = scenario.observer
    model = observer.model
    scaled = eqx.tree_at(
        lambda o: (o.model.accelerometer_noise, o.model.gyro_noise, o.model.bias_std),
        observer,
        (gain * model.accelerometer_noise, gain * model.gyro_noise, gain * model.bias_std),
    )
    if perfect:
        truth = scenario.initial_state
        guess = model.state(truth.eta, rotate(truth.eta[2], truth.nu)[:2])
        scenario = eqx.tree_at(lambda s: s.initial_estimate, scenario, guess)
    return eqx.tree_at(lambda s: s.observer, scenario, scaled)


def _kalman_pid(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """The extended Kalman filter closing a DP loop with the nonlinear PID on the Fossen &
    Strand vessel, a reference filter and thrust limits; ``gain`` scales the filter's
    process noise Q and the PID's Kp, Kd and Ki."""
    from lookout import PositionHeadingSensor
    from lookout.actuators import SaturatingActuator
    from lookout.controllers import PidController
    from lookout.models.vessel import NORTHERN_CLIPPER_THRUST_LIMIT, VesselState, northern_clipper
    from lookout.observers.ekf import ExtendedKalmanFilter
    from lookout.papers import fossen_strand_1999 as fs
    from lookout.reference import ReferenceFilter

    quiet = {} if noise else {"noise_std": (0, 0, 0), "bias_std": (0, 0, 0), "wave_amplitude": (0, 0, 0)}
    config = fs.Config(duration=duration, measurement_period=0.1 if perfect else 1.0, **quiet)
    base = fs.build(config)
    sensor = PositionHeadingSensor(config.noise_std, config.measurement_period, dropout_probability=dropout)
    std = {"eta": [5.0, 5.0, 0.05], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [1.0, 1.0, 0.01, 1.0, 1.0, 0.01]}
    observer = ExtendedKalmanFilter(
        base.plant,
        sensor,
        process_noise=gain * jnp.ones(base.plant.noise_size),
        measurement_noise=[0.5, 0.5, 0.0017],
        initial_std=std,
        plant_step=config.plant_step,
        filter_period=config.sample_period,
    )
    design = PidController.design(northern_clipper(), integral_limit=NORTHERN_CLIPPER_THRUST_LIMIT)
    controller = PidController(
        design.vessel,
        gain * design.proportional_gain,
        gain * design.derivative_gain,
        gain * design.integral_gain,
        integral_limit=NORTHERN_CLIPPER_THRUST_LIMIT,
    )
    start = VesselState.build(eta=[3.0, -2.0, 0.05], bias=config.bias_initial)
    return Scenario(
        base.plant,
        sensor,
        observer,
        controller,
        start,
        start if perfect else observer.guess(),
        plant_step=config.plant_step,
        sample_period=config.sample_period,
        duration=config.duration,
        reference=ReferenceFilter.vessel(0.05, [0.0, 5.0], [[0.0, 0.0, 0.0], [10.0, 5.0, 0.1]]),
        actuator=SaturatingActuator(NORTHERN_CLIPPER_THRUST_LIMIT),
    )


EXAMPLE_PLUGIN = Path(__file__).resolve().parent.parent / "examples" / "plugins" / "luenberger.py"


def _luenberger(gain=1.0, *, noise=True, perfect=False, dropout=0.0, duration=30.0) -> Scenario:
    """The example plugin's Luenberger observer (examples/plugins/luenberger.py) on the
    Fossen & Strand vessel, built from a scenario document as a user's file would be;
    ``gain`` scales L1, L2 and L3. Its model has no wave filter and its bias no decay: the
    noise-free perfect start is exact with no sea and no bias."""
    from lookout.scenario.composition import compose

    quiet = {} if noise else {"noise_std": [0.0, 0.0, 0.0]}
    plant = (
        {}
        if noise
        else {
            "bias": {"kind": "gauss-markov", "time_constant": 1000.0, "std": [0.0, 0.0, 0.0]},
            "waves": {"kind": "linear", "peak_frequency": 0.8976, "damping_ratio": 0.1, "amplitude": [0.0, 0.0, 0.0]},
            "initial": {"bias": 0.0},
        }
    )
    document = {
        "plugins": [str(EXAMPLE_PLUGIN)],
        "preset": "fossen-strand-1999:paper",
        "simulation": {"duration": duration, "runs": 1},
        "plant": plant,
        "sensor": {**quiet, "sample_period": 0.1 if perfect else 1.0, "dropout_probability": dropout},
        "observer": {
            "kind": "luenberger",
            "design": "poles",
            "bandwidth": [0.05, 0.05, 0.05],
            **({"initial": {"eta": 0.0, "nu": 0.0, "bias": 0.0}} if perfect else {}),
        },
    }
    scenario = compose(document).scenario
    observer = scenario.observer
    scaled = eqx.tree_at(
        lambda o: (o.position_gain, o.velocity_gain, o.bias_gain),
        observer,
        (gain * observer.position_gain, gain * observer.velocity_gain, gain * observer.bias_gain),
    )
    return eqx.tree_at(lambda s: s.observer, scenario, scaled)


CASES = [
    Case(
        "passive observer (Fossen & Strand 1999)",
        _passive,
        exact=(("continuous", {}), ("sampled", {"hold": "innovation"})),
        error_variable="velocity",
    ),
    Case("velocity observer (Calugi 2002, ch. 2)", _velocity, exact=(("continuous", {}),), error_variable="joint_rate"),
    # propagated by the plant's own discretization: from a perfect start, noise-free, the
    # estimate is the plant's state to the bit
    Case("extended Kalman filter", functools.partial(_kalman, "ekf"), exact=(("sampled", {}),), error_variable="velocity", gradient="forward"),
    # not exact: with P > 0 its mean is the weighted mean of the propagated sigma points,
    # which differs from the propagated mean at second order in the rotation (4.8e-5 m
    # over 60 s from the suite's initial_std): the unscented transformation, not a fault
    Case("unscented Kalman filter", functools.partial(_kalman, "ukf"), exact=(), error_variable="velocity", gradient="forward"),
    # not exact: its model's velocity is a random walk, so it predicts the vessel at constant
    # velocity while the vessel accelerates under the input (no hull model: by design)
    Case("observer without a hull model", _model_free, exact=(), error_variable="velocity", gradient="forward"),
    # not exact: the IMU's reading is held over each sample (first order in the sample
    # period), as a strapdown system holds its increments, while the vessel accelerates
    Case("IMU-aided observer", _ins, exact=(), error_variable="velocity", gradient="forward"),
    # the same filter closing the loop: the PID moves the plant, and the filter's model, given
    # the applied input, still follows it to the bit
    Case("extended Kalman filter and nonlinear PID", _kalman_pid, exact=(("sampled", {}),), error_variable="velocity", gradient="forward"),
    Case(
        "sliding-mode observer and backstepping (Kim 2002)",
        _sliding_mode_loop,
        exact=(("continuous", {}), ("sampled", {"hold": "innovation"})),
        error_variable="velocity",
        gradient="forward",
    ),
    # the same loop through thrusters: rate limits and QP allocation bind from the first sample
    Case(
        "sliding-mode observer and backstepping through thrusters (Kim 2002)",
        functools.partial(_sliding_mode_loop, thrusters=True),
        exact=(("sampled", {"hold": "innovation"}),),
        error_variable="velocity",
        gradient="forward",
    ),
    Case(
        "adaptive observer and vectorial backstepping (Calugi et al. 2003)",
        _adaptive_loop,
        exact=(("continuous", {"form": "continuous"}),),
        error_variable="velocity",
        gradient="forward",
    ),
    Case(
        "Earth-fixed observer and tracking scheme (Wondergem et al. 2009)",
        _tracking_loop,
        exact=(("continuous", {"plant_step": 0.01}),),
        error_variable="velocity",
        gradient="forward",
        # the plant integrates (16) in the body frame, the observer (6) in the Earth frame:
        # RK4 of the two coordinate forms of one ODE agree to O(h^4), not to rounding
        # (velocity 4.5e-7 m/s over 60 s at h = 0.05 s; a wrong observer errs by mm/s)
        exact_tolerance=1e-8,
    ),
    Case(
        "parameter estimator (Calugi 2002, ch. 3)",
        _parameter_estimator,
        exact=(("continuous", {}),),
        error_variable="mass_hat",
        parameter_truth=(("mass_hat", 1.0), ("friction_0_hat", 0.1)),
    ),
    Case(
        "adaptive observer with resetting and observer backstepping (Calugi 2002, ch. 4-5)",
        _adaptive_arm,
        exact=(),
        error_variable="joint_rate",
        gradient="forward",
    ),
    Case(
        "adaptive observer and pendulum backstepping on the Furuta pendulum (Calugi 2002, ch. 6)",
        _furuta,
        exact=(),
        error_variable="joint_rate",
        # quantized encoders and stick-slip friction make the RMS error piecewise constant and
        # discontinuous in the gain: jax.jacfwd gave -0.60 where central differences gave 36.6
        gradient=None,
        # at 50 % dropouts the closed loop (not the observer) loses the pendulum at the first
        # reference switch (0.62 s), where the arm must reverse; 20 % rides through
        dropout=0.2,
    ),
    # a kind of one's own, from the example plugin: it joins by this case, as any kind does
    Case("Luenberger observer of the example plugin", _luenberger, exact=(("continuous", {}),), error_variable="velocity"),
]


def _max_difference(a: dict, b: dict) -> float:
    return max(float(np.nanmax(np.abs(np.asarray(a[k]) - np.asarray(b[k])) / (1.0 + np.abs(np.asarray(b[k]))))) for k in a)


@pytest.fixture(params=[pytest.param(c, marks=pytest.mark.xdist_group(f"conformance {i}")) for i, c in enumerate(CASES)], ids=lambda case: case.name)
def case(request) -> Case:
    """Each case's tests run on one worker (make test: --dist loadgroup), which reuses the
    programs one test compiled in the next (the single run of 10 s, for instance)."""
    return request.param


def test_every_registered_observer_and_controller_kind_has_a_case():
    """A registered kind with no case fails here (lookout's own kinds, and the example
    plugin's, which the Luenberger case registers)."""
    from lookout.scenario import registry

    registry.load_plugin(EXAMPLE_PLUGIN)
    built = [c.build(1.0, noise=False, perfect=True, duration=1.0) for c in CASES]
    covered = {(role, registry.kind_of(getattr(s, role))) for s in built for role in ("observer", "controller")}
    for role in ("observer", "controller"):
        registered = {k.name for k in registry.kinds(role) if k.module.startswith("lookout.") or k.module.startswith("lookout_plugin_")}
        plugins_of_tests = {
            k.name for k in registry.kinds(role) if k.module.startswith("lookout_plugin_") and Path(sys.modules[k.module].__file__) != EXAMPLE_PLUGIN
        }
        missing = sorted(registered - plugins_of_tests - {kind for r, kind in covered if r == role} - UNCASED[role])
        assert missing == [], f"{role} kinds without a conformance case: {missing}"


#: Kinds that run no observer or controller of their own: nothing to check in the engine
#: beyond what every case runs (open loop).
UNCASED = {"observer": set(), "controller": {"none", "sinusoidal"}}


def test_the_observer_declares_what_its_scenario_feeds_it(case):
    """The measurement and input an observer declares are its scenario's sensor's and
    plant's (lookout.filter and lookout.Stepper check logs and live samples against
    them), its guess() is shaped as the scenario's initial estimate, and a declared
    sample period is the scenario's."""
    scenario = case.build(duration=10.0)
    observer = scenario.observer
    # what it reads is among what the sensor measures, and what it takes among the plant's
    # input (the engine hands it its channels by name; an IMU-aided observer takes none)
    measured = {signal.name: signal for signal in scenario.sensor.measurement_layout.signals}
    assert all(measured.get(signal.name) == signal for signal in observer.measurement_layout.signals)
    inputs = {signal.name: signal for signal in scenario.plant.input_layout.signals}
    assert all(inputs.get(signal.name) == signal for signal in observer.input_layout.signals)
    if not hasattr(scenario.sensor, "instrument_layout"):  # a sensor suite's own channels are more than a filter reads
        assert observer.measurement_layout == scenario.sensor.measurement_layout
        assert observer.input_layout == scenario.plant.input_layout
    assert jax.tree.structure(observer.guess()) == jax.tree.structure(scenario.initial_estimate)
    assert observer.sample_period in (None, scenario.sample_period)
    # a scenario rebuilt by tree_map (as stacking does) flattens as the original: equinox
    # flattens a field left at its class default differently once it has been rebuilt
    rebuilt = jax.tree.map(lambda leaf: leaf, scenario)
    assert jax.tree.structure(jax.tree.map(lambda leaf: leaf, rebuilt)) == jax.tree.structure(scenario)


def test_vmapped_runs_equal_the_same_runs_one_by_one(case):
    scenario = case.build(duration=10.0)
    if jax.default_backend() == "cpu":
        assert len(jax.devices()) == 2, "conftest exposes two host devices, so the batch below is sharded"
    keys = jax.random.split(jax.random.key(7), 4)
    batch = simulate_batch(scenario, keys)
    for i in range(4):
        single = simulate(scenario, keys[i])
        assert _max_difference(jax.tree.map(lambda a: a[i], batch.estimate), single.estimate) < 1e-11
        assert _max_difference(jax.tree.map(lambda a: a[i], batch.truth), single.truth) < 1e-11
    assert list(batch.to_xarray().status.values) == ["finite"] * 4


def test_a_change_of_gains_only_does_not_trace_again(case):
    """Traces counted by jax.monitoring while ``simulate`` runs: the first gain may trace
    and compile (or find the program an earlier test of the case compiled on this worker);
    a scenario with other gains must trace nothing. The gains are array leaves, so they
    never enter the compiled program's key."""
    events: list[str] = []

    def listener(name, secs, **kwargs):
        del secs, kwargs
        events.append(name)

    key = jax.random.key(0)
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        simulate(case.build(1.0, duration=10.0), key)
        for gain in (2.0, 0.5):
            scenario = case.build(gain, duration=10.0)
            before = len(events)
            simulate(scenario, key)
            traced = [name for name in events[before:] if name.endswith("jaxpr_trace_duration")]
            assert not traced, (gain, traced)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


def test_noise_free_perfect_start_stays_exact(case):
    for mode, options in case.exact:
        scenario = dataclasses.replace(case.build(noise=False, perfect=True, duration=60.0, **options), observer_mode=mode)
        ds = simulate(scenario, jax.random.key(0)).to_xarray()
        errors = dict(estimation_errors(ds).items())
        truth = dict(case.parameter_truth)
        errors.update({name: ds[name] - value for name, value in truth.items()})
        assert errors, "the observer estimates no plant variable and no parameter"
        for name, error in errors.items():
            scale = 1.0 + (abs(truth[name]) if name in truth else float(np.abs(ds[name]).max()))
            assert float(np.abs(error).max()) <= case.exact_tolerance * scale, (mode, options, name, float(np.abs(error).max()))


def test_holding_the_measurement_is_not_exact_which_shows_the_check_can_fail():
    """The sampled passive observer with y_k held drifts from a perfect start, so the
    exactness check above can fail (and says what holding the innovation buys)."""
    ds = simulate(_passive(noise=False, perfect=True, duration=60.0), jax.random.key(0)).to_xarray()
    assert float(np.abs(estimation_errors(ds)["position"]).max()) > 1e-4


def test_nan_dropouts_keep_the_estimate_finite(case):
    ds = simulate(case.build(dropout=case.dropout, duration=10.0), jax.random.key(2)).to_xarray()
    measured = [name for name in ds.data_vars if name.startswith("measured_")]
    assert any(np.isnan(ds[name].values).any() for name in measured)
    for name in ds.data_vars:
        if name.endswith("_hat"):
            assert np.all(np.isfinite(ds[name].values)), name
    assert ds.status.values.tolist() == ["finite"]


def test_a_run_in_chunks_equals_the_whole_run():
    """Chunking is the engine's (the carry between chunks is the whole loop state, whatever
    the components), so one case checks it: each case costs a compile of two programs."""
    case = CASES[0]
    scenario = case.build(duration=20.0)
    calls = []
    chunked = simulate(scenario, jax.random.key(1), progress=lambda done, total: calls.append((done, total)), chunks=3)
    whole = simulate(scenario, jax.random.key(1))
    assert _max_difference(chunked.estimate, whole.estimate) < 1e-12 and _max_difference(chunked.truth, whole.truth) < 1e-12
    assert calls[-1] == (scenario.n_records, scenario.n_records) and len(calls) >= 3


@pytest.mark.parametrize("case", [CASES[0], CASES[2]], ids=lambda case: case.name)
def test_decimated_records_are_every_nth_sample_of_the_full_run(case):
    """record_every only thins the records: the noise of sample k depends on (key, k) alone.

    Decimation is the engine's: checked on one open loop and one closed loop, not on every
    case (each costs a compile of two programs).

    The two programs are compiled apart, and XLA may fuse (and so round) them
    differently: agreement is to a few ulp, where a shifted noise stream would differ
    at the size of the signal.
    """
    every = 5
    full = case.build(duration=15.0)
    thin = dataclasses.replace(full, record_every=every)
    key = jax.random.key(5)
    a, b = simulate(full, key), simulate(thin, key)
    np.testing.assert_array_equal(b.time, a.time[::every])
    for group in ("truth", "estimate"):
        for name in getattr(a, group):
            np.testing.assert_allclose(np.asarray(getattr(b, group)[name]), np.asarray(getattr(a, group)[name])[::every], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(b.measurement), np.asarray(a.measurement)[::every], rtol=1e-12, atol=1e-15)


GRADIENT_CASES = [
    c
    for c in CASES
    if c.gradient is not None
    and c.name.split(" (")[0]
    in (
        "passive observer",
        "parameter estimator",
        "sliding-mode observer and backstepping",
        "sliding-mode observer and backstepping through thrusters",
        "adaptive observer with resetting and observer backstepping",
    )
]


@pytest.mark.parametrize(
    "case", [pytest.param(c, marks=pytest.mark.xdist_group(f"conformance {CASES.index(c)}")) for c in GRADIENT_CASES], ids=lambda case: case.name
)
def test_a_scenario_built_inside_vmap_simulates_like_one_built_alone(case):
    """On the four cases of the gradient check (each compiles a program over a batched
    scenario): observers, controllers, plants and references whose constructors run
    under ``vmap`` (two open loops, two closed loops with thrust limits and resetting)."""
    gains = jnp.asarray([0.5, 1.0, 2.0])
    scenarios = eqx.filter_vmap(lambda g: case.build(g, duration=10.0))(gains)
    keys = jax.random.split(jax.random.key(9), 3)
    batch = simulate_batch(scenarios, keys, batched_scenario=True)
    for i, gain in enumerate(gains.tolist()):
        single = simulate(case.build(gain, duration=10.0), keys[i])
        assert _max_difference(jax.tree.map(lambda a: a[i], batch.estimate), single.estimate) < 1e-10


@pytest.mark.parametrize(
    "case", [pytest.param(c, marks=pytest.mark.xdist_group(f"conformance {CASES.index(c)}")) for c in GRADIENT_CASES], ids=lambda case: case.name
)
def test_gradient_of_an_rms_error_through_simulate_matches_central_differences(case):
    """On four cases, not all (each costs two compiles of a derivative program): reverse mode
    on two open loops (a plant variable, a parameter estimate) and forward mode on two closed
    loops (with a switching term and thrust limits; with resetting and adaptive backstepping).
    The Furuta loop is not differentiable in the gain (its Case says why)."""
    key = jax.random.key(3)

    def rms_error(gain):
        trajectory = simulate(case.build(gain, duration=10.0), key)
        truth = dict(case.parameter_truth)
        if case.error_variable in truth:  # a parameter estimate against its true value
            error = trajectory.estimate[case.error_variable] - truth[case.error_variable]
        else:
            error = trajectory.truth[case.error_variable] - trajectory.estimate[case.error_variable]
        return jnp.sqrt(jnp.mean(error**2))

    derivative = jax.grad if case.gradient == "reverse" else jax.jacfwd
    gradient = float(derivative(rms_error)(1.0))
    step = 1e-6  # small: the switching term and thrust limits are piecewise linear, and a kink
    # crossed inside [gain - step, gain + step] biases a central difference by O(step)
    central = (float(rms_error(1.0 + step)) - float(rms_error(1.0 - step))) / (2 * step)
    assert gradient != 0.0
    assert gradient == pytest.approx(central, rel=1e-5)
