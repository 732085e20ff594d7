"""Continuous-discrete Kalman filtering over any Plant and Sensor: what the extended
(:mod:`lookout.observers.ekf`) and the unscented (:mod:`lookout.observers.ukf`) filter share.

The model is the filter's own plant (any :class:`~lookout.components.Plant`) and
sensor, with no model-specific code::

    x' = f(t, x, u, w)          the plant's vector field; x its state raveled into a vector,
                                w its unit white noise inputs (noise_size of them)
    y_k = h(x_k) + v_k          h = sensor.ideal, v_k ~ N(0, R)

**Propagation** over one sample [t_k, t_k + dt] is the engine's own discretization:
the plant's integrator (RK4 or Euler) in ``dt / plant_step`` steps of ``plant_step``
with the input held, and the noise of step j held over it as the engine holds it,
w_j ~ N(0, diag(q) / plant_step) (q: ``process_noise``, 1 for the plant's own
intensities). With x_{k+1} = Phi(x_k, w_1, ..., w_n) that step, its Jacobians at
w = 0, F = dPhi/dx and G_j = dPhi/dw_j, give the discrete process noise

    Q_d = sum_j G_j diag(q) G_j^T / plant_step + S dt,

S the continuous intensity ``state_noise`` added per state entry (for a plant
without noise of its own, or for what its model leaves out). This is the
continuous-discrete filter of Jazwinski (1970), Stochastic Processes and Filtering
Theory, Section 8.4 (mean by the noise-free model, covariance by the linearized
step), with the propagation discretized exactly as the simulated plant is.

**Correction** when a sample arrives: a channel takes part when it is due (its
sample period, :attr:`Sensor.sample_period`, divides t: between its samples the
engine holds the last value, which is not a new measurement) and is finite (NaN: a
dropout). A missing channel is masked at static shapes: its row of H (or of the
unscented filter's measurement deviations) and its innovation are zero and its row
and column of R are those of a unit variance, so its Kalman gain column is exactly
zero and jit and vmap keep one program. Angle channels (``Signal.angle``) have their
innovations wrapped by ``ssa``; angle states (those the plant's ``normalize`` wraps,
found by probing it at 3 pi / 2) are wrapped after each correction. A correction
whose result is not finite leaves the prior unchanged, so a bad sample cannot poison
the filter's state.

**Unknown input disturbance** (``input_disturbance``, off by default): the usual DP
practice for a model without a bias of its own. The state is augmented by d, one entry
per input entry, a random walk ``d' = w_d`` with ``E[w_d w_d^T] = diag(q_d)``, and the
model is driven by u + d: an unknown slowly varying force (current, wind, mean wave
drift) that the filter estimates as it estimates any state. Its process noise enters
Q_d as ``q_d dt`` (the cross terms with the plant's states, of order dt^2, are left
out, as for ``state_noise``). Its estimate is recorded as ``disturbance_<input>``
(for the DP vessel ``disturbance_force`` and ``disturbance_moment``, in the input's
body-fixed frame).

**A sensor suite** (:class:`~lookout.sensing.suite.SensorSuite`, a
:class:`~lookout.components.KinematicSensor`) is taken directly: every instrument's
channel is a measurement of its own (its ``instrument_layout``: ``dgnss1.measured_position``,
``gyro.measured_heading``, ...; not the failure flags nor the combining stage's
``measured_position``), with

    h(x, u, t) = suite.expected(model.kinematics(t, x, u + d))

the instruments' noise-free channels of the filter's own model plant, each at its
lever arm (a GNSS antenna at r reads p + R(psi) r, so two references with different
lever arms observe the heading too), d the input disturbance where the filter
estimates one. An IMU's specific force depends on the applied input, which
:meth:`~KalmanFilter.update` is not given: the filter state carries the input of the
last :meth:`~KalmanFilter.predict` (:attr:`KalmanState.applied`), the input applied
over [t_{k-1}, t_k], which is exactly the input under which the suite sampled at t_k
(the engine reads a kinematic sensor under the input applied since the sample
before; zero at the first sample). A channel is due at its instrument's
``sample_period`` and missing when NaN (a ``dropout`` failure), as any sensor's.

Defaults derived from the scenario (each can be given instead):

* R from the sensor's own noise: J J^T, J the Jacobian of ``sensor.measure`` with
  respect to its standard normals at zero (exact for additive Gaussian noise); it must
  be positive definite (a noiseless channel needs ``measurement_noise``). For a suite,
  diag(sigma^2) with sigma each instrument's
  :meth:`~lookout.sensing.instrument.Instrument.measurement_std`: its white noise, and
  where it has a slow Gauss-Markov error (a GNSS receiver's multipath, a gyrocompass's
  settling error), that error's stationary variance added, sigma^2 = noise_std^2 +
  error_std^2. The filter does not estimate the slow error as a state: it takes it as
  white of its stationary variance, its correlation in time neglected (Bryson &
  Henrikson 1968, "Estimation using sampled data containing sequentially correlated
  noise", Journal of Spacecraft and Rockets 5(6), 662-665, give the exact treatments:
  the error as a state, or differenced measurements), so that a receiver with a 0.5 m
  multipath error is not trusted as if it had its white noise alone. The spread is the
  one the combining stage weights the references by
  (:meth:`~lookout.sensing.position.PositionReference.weight_std`). A hydroacoustic
  reference's is its spread at the transponder's horizontal position; an IMU's constant
  biases are not in R, its drifting bias is, as a slow error (its stationary spread).
* P_0 from the steady state: the solution of the discrete algebraic Riccati equation
  of the model linearized at the initial guess (u = 0, t = 0) over one observer
  sample, the covariance of a filter that has run for ever (scipy's
  ``solve_discrete_are``); a model whose own noise does not reach every state has
  none, and then ``initial_std`` must be given.
"""

from __future__ import annotations

import abc
import copy
import inspect
import math
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.flatten_util import ravel_pytree
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa, unmarked
from lookout._resources import refuse_unless_it_fits
from lookout.components import KinematicSensor, Layout, Observer, Plant, Sensor, Signal, kinematics_of
from lookout.declare import initial_values
from lookout.sensing.suite import SensorSuite
from lookout.sim.integrators import INTEGRATORS


class KalmanState(eqx.Module):
    """Internal state of a Kalman filter.

    Attributes
    ----------
    mean : Array, shape (n,)
        The estimate of the plant's state, raveled (``jax.flatten_util.ravel_pytree``
        of the model's ``state()``), followed by the input disturbance's when the
        filter estimates one.
    covariance : Array, shape (n, n)
        Its error covariance P.
    applied : Array or None, shape (inputs,)
        On a kinematic sensor (a suite) only: the input applied over the interval that
        ends at the state's time (set by :meth:`KalmanFilter.predict`, zero at the
        start), under which the sensor sampled (an IMU's specific force); None otherwise.
    time : Array or None, shape ()
        On a kinematic sensor only: the time of the state (s), at which h is taken by
        :meth:`KalmanFilter.innovation_statistics`; None otherwise.
    """

    mean: Array
    covariance: Array
    applied: Array | None = None
    time: Array | None = None


def _angle_entries(model: Plant) -> tuple[bool, ...]:
    """Per raveled state entry: whether the plant's ``normalize`` wraps it (an angle)."""
    probe = 1.5 * math.pi
    back = np.asarray(_probe_normalize(model, probe))
    return tuple(bool(abs(value - (probe - 2.0 * math.pi)) < 1e-9) for value in back)


@eqx.filter_jit
def _probe_normalize(model: Plant, probe: float) -> Array:
    """Entry i of the normalized state that has ``probe`` in entry i only, for every i."""
    zero, unravel = ravel_pytree(model.state())
    moved = jnp.eye(zero.size) * probe
    return jnp.diagonal(jax.vmap(lambda x: ravel_pytree(model.normalize(unravel(x)))[0])(moved))


#: Most propagation steps per sample: the step's Jacobian in the noise of every one costs
#: their number squared (64 steps: about 1.7e5 model evaluations a sample on a 3-DOF vessel).
MAX_PROPAGATION_STEPS = 64
#: Substeps per sample up to which the propagation is unrolled in the trace (beyond, a scan).
UNROLLED_SUBSTEPS = 16
#: Gauss-Newton steps that solve the states left to the first measurement (:meth:`KalmanFilter.init`).
INITIAL_SOLVE_STEPS = 3


def working_nbytes(n: int, substeps: int, noise_size: int) -> int:
    """Bytes one sample of a Kalman filter holds on an n-entry state propagated in
    ``substeps`` steps with ``noise_size`` noise inputs each: the Jacobians of the step in
    the state and the noise, by forward mode over an identity of n + substeps x
    noise_size columns, each carrying the step's intermediates (RK4: four stages of n per
    substep)."""
    columns = n + substeps * noise_size
    return 8 * columns * (columns + 4 * n * substeps + n)


def _measured_parts(model: Plant) -> tuple[str, ...]:
    """The keywords of the plant's ``state`` whose default is None: the parts a sensor
    measures directly (a vessel's eta, an arm's q), which an observer's guess leaves to
    the first measurement."""
    return tuple(name for name, parameter in state_parameters(model).items() if parameter.default is None)


def state_parameters(model: Plant) -> dict[str, inspect.Parameter]:
    """The keywords of the model's ``state``: its signature's, or, for a model that wraps
    another (:class:`~lookout.models.imu_biases.ImuBiases`), what its ``state_parameters``
    gives."""
    own = getattr(model, "state_parameters", None)
    return dict(own()) if own is not None else dict(inspect.signature(model.state).parameters)


#: The key of the input disturbance's entries in a table of state parts.
DISTURBANCE = "input_disturbance"


def _state_vector(model: Plant, value, name: str, disturbance_size: int = 0, default_disturbance: float | None = None) -> np.ndarray | None:
    """A per-state-entry vector: None, a flat array of the state's size, or a table of
    the plant's state parts (the keywords of its ``state``, as ``[plant.initial]``).
    With ``disturbance_size`` entries of an input disturbance appended: in a table under
    :data:`DISTURBANCE` (``default_disturbance`` each where the table has none)."""
    if value is None:
        return None
    size = ravel_pytree(model.state())[0].size + disturbance_size
    if isinstance(value, dict):
        parts = dict(value)
        extra = parts.pop(DISTURBANCE, None)
        if extra is not None and not disturbance_size:
            raise check.ParameterError(check.key(name), f"{name}: {DISTURBANCE} is for a filter with input_disturbance; this one estimates none")
        if extra is None:
            if disturbance_size and default_disturbance is None:
                raise check.ParameterError(check.key(name), f"{name}: give {DISTURBANCE} too (one entry per input entry: {disturbance_size})")
            extra = np.full(disturbance_size, default_disturbance if disturbance_size else 0.0)
        extra = np.asarray(extra, dtype=float)
        if disturbance_size and extra.shape not in ((), (disturbance_size,)):
            raise check.ParameterError(
                check.key(name), f"{name}: {DISTURBANCE} must have one entry per input entry ({disturbance_size}); got shape {extra.shape}"
            )
        extra = np.broadcast_to(extra, (disturbance_size,)) if disturbance_size else np.zeros(0)
        known = list(state_parameters(model))
        unknown = [key for key in parts if key not in known]
        if unknown:
            raise check.ParameterError(
                check.key(name),
                f"{name}: the plant's state has no part {unknown[0]!r} (its parts: {', '.join(known)}"
                + (f", and {DISTURBANCE}" if disturbance_size else "")
                + ")",
            )
        try:
            vector = np.concatenate([np.asarray(ravel_pytree(model.state(**parts))[0], dtype=float), extra])
        except (TypeError, ValueError) as error:
            raise check.ParameterError(check.key(name), f"{name}: {error}") from None
    else:
        vector = np.asarray(value, dtype=float)
        if vector.shape != (size,):
            what = f"state entry ({size}: the plant's and the input disturbance's)" if disturbance_size else f"state entry ({size})"
            raise check.ParameterError(
                check.key(name), f"{name} must have one entry per {what}, or be a table of the plant's state parts; got shape {vector.shape}"
            )
    if not (np.all(np.isfinite(vector)) and np.all(vector >= 0)):
        raise check.ParameterError(check.key(name), f"{name} must be finite and >= 0; got {vector.tolist()}")
    return vector


def filter_layout(sensor: Sensor) -> Layout:
    """The channels a Kalman filter on ``sensor`` reads: a suite's instruments'
    (:attr:`~lookout.sensing.suite.SensorSuite.instrument_layout`, what its ``expected``
    gives: not the failure flags, which are the truth of a failure, nor the combining
    stage's channels, which repeat the instruments'), else the whole measurement."""
    return sensor.instrument_layout if isinstance(sensor, SensorSuite) else sensor.measurement_layout


def suite_measurement_std(suite: SensorSuite) -> np.ndarray:
    """The default R's standard deviations on a suite, per channel of its
    :attr:`~lookout.sensing.suite.SensorSuite.instrument_layout`: each instrument's
    :meth:`~lookout.sensing.instrument.Instrument.measurement_std` (its white noise, and
    a slow Gauss-Markov error's stationary variance where it has one; module docstring)."""
    return np.concatenate([np.asarray(each.measurement_std(), dtype=float).reshape(-1) for each in suite.instruments])


def default_measurement_covariance(sensor: Sensor, plant: Plant) -> np.ndarray:
    """The default R of a Kalman filter on ``sensor`` over the model ``plant`` (module
    docstring): a suite's instruments' white noise and slow errors, channel by channel,
    else J J^T of the sensor's own noise at the model's zero state.

    Raises
    ------
    ValueError
        Naming ``measurement_noise`` for a kinematic sensor that states no noise of its own.
    """
    if isinstance(sensor, SensorSuite):  # each instrument's white noise and slow error, channel by channel
        return np.diag(suite_measurement_std(sensor) ** 2)
    if isinstance(sensor, KinematicSensor):
        raise check.ParameterError(
            "measurement_noise", f"measurement_noise: sensor {type(sensor).__name__} states no noise of its own; give measurement_noise"
        )
    return _sensor_covariance(sensor, plant.state())


def _sensor_covariance(sensor: Sensor, x) -> np.ndarray:
    """R = J J^T, J the Jacobian of the sensor's measurement with respect to its
    standard normals at zero (NaN entries, channels dropped at zero, count as zero)."""
    jacobian = np.nan_to_num(np.asarray(_measurement_jacobian(sensor, x), dtype=float), nan=0.0)
    return jacobian @ jacobian.T


@eqx.filter_jit
def _measurement_jacobian(sensor: Sensor, x) -> Array:
    return jax.jacfwd(lambda normals: sensor.measure(x, normals))(jnp.zeros(sensor.noise_size))


def masked(y: Array, predicted: Array, due: Array, angles: tuple[bool, ...]) -> tuple[Array, Array]:
    """(innovation, mask): ``y - predicted`` on the channels that are due and finite (angle
    channels wrapped), zero elsewhere; the mask is 1.0 where a channel takes part."""
    use = due & jnp.isfinite(y)
    difference = jnp.where(use, y, predicted) - predicted
    difference = jnp.where(jnp.asarray(angles), ssa(difference), difference)
    return jnp.where(use, difference, 0.0), use.astype(predicted.dtype)


def masked_noise(covariance: Array, mask: Array) -> Array:
    """R with the rows and columns of missing channels replaced by those of a unit
    variance (so S stays invertible and their gain columns are zero)."""
    both = mask[:, None] * mask[None, :]
    return covariance * both + jnp.diag(1.0 - mask)


def _symmetric(matrix: Array) -> Array:
    return 0.5 * (matrix + matrix.T)


class KalmanFilter(Observer):
    """What the continuous-discrete EKF and UKF share (see the module docstring): the
    model, the noise, the propagation step and its Jacobians, the masking, the
    interface to the engine. Concrete filters implement :meth:`propagate` and
    :meth:`correct`."""

    model: Plant
    sensor: Sensor
    process_noise: Array  # (noise_size,) intensity of each of the model's noise inputs
    state_noise: Array  # (n,) continuous intensity added per state entry (the disturbance's last)
    measurement_covariance: Array  # (m, m) R
    initial_covariance: Array  # (n, n) P_0
    plant_step: float = eqx.field(static=True)
    filter_period: float = eqx.field(static=True)
    integrator: str = eqx.field(static=True)
    state_size: int = eqx.field(static=True)  # entries of the plant's raveled state
    disturbance_size: int = eqx.field(static=True)  # entries of the input disturbance (0: none)
    state_angles: tuple[bool, ...] = eqx.field(static=True)
    channel_angles: tuple[bool, ...] = eqx.field(static=True)
    channel_periods: tuple[float, ...] = eqx.field(static=True)
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    sample_period: None = eqx.field(static=True)
    #: per channel: read by the filter's user in another way (an IMU that is the model's
    #: input, or that the model has nothing to compare with), never a measurement
    ignored_channels: tuple[bool, ...] = eqx.field(static=True)

    # ------------------------------------------------------------------ the model
    def _unravel(self, vector: Array):
        """The plant's state from the filter's (the input disturbance left out)."""
        return ravel_pytree(self.model.state())[1](vector[: self.state_size])

    def _ravel(self, state) -> Array:
        return ravel_pytree(state)[0]

    def augmented(self, state: Any, disturbance: Array | None = None) -> Array:
        """The filter's vector of a plant state: raveled, with the input disturbance
        (zero unless given) appended when the filter estimates one."""
        disturbance = jnp.zeros(self.disturbance_size) if disturbance is None else disturbance
        return jnp.concatenate([self._ravel(state), disturbance])

    def step(self, mean: Array, t: ArrayLike, u: Array, dt: ArrayLike, noise: Array | None = None) -> Array:
        """Phi: the model over one sample from ``mean`` (raveled) with ``u`` held and
        ``noise`` (substeps x noise_size, zero when None) held over each substep."""
        substeps, h = self.substeps(dt), self.substep(dt)
        size = self.model.noise_size
        noise = jnp.zeros((substeps, size)) if noise is None else noise
        integrate = INTEGRATORS[self.integrator]
        state, disturbance = mean[: self.state_size], mean[self.state_size :]
        driven = u + disturbance if self.disturbance_size else u

        def field(s, x, w):
            # integrated on the raveled vector (elementwise, as on the state's leaves): its
            # Jacobian by forward mode is 4x faster than through the state's PyTree
            return self._ravel(self.model.vector_field(s, self._unravel(x), driven, w))

        with unmarked():  # the step is differentiated (EKF) or vmapped over sigma points (UKF)
            if substeps <= UNROLLED_SUBSTEPS:  # a handful of substeps per sample: unrolled, as the engine's
                for j in range(substeps):
                    state = integrate(lambda s, x, w=noise[j]: field(s, x, w), t + j * h, state, h)
            else:  # many: a loop, whose compilation does not grow with them
                state, _ = jax.lax.scan(
                    lambda x, j: (integrate(lambda s, y: field(s, y, noise[j]), t + j * h, x, h), None), state, jnp.arange(substeps)
                )
        return jnp.concatenate([state, disturbance])

    @property
    def working_nbytes(self) -> int:
        """Bytes one run holds while the filter takes a sample (:func:`working_nbytes`)."""
        return working_nbytes(self.state_size + self.disturbance_size, max(1, round(self.filter_period / self.plant_step)), self.model.noise_size)

    def substeps(self, dt: ArrayLike) -> int:
        """Integration steps per sample of ``dt`` s: ``dt / plant_step``; for a ``dt`` known
        only when the filter runs (a log's time steps, :func:`lookout.filter`), as many as
        in one ``filter_period``."""
        if not check.is_concrete(dt):
            return max(1, round(self.filter_period / self.plant_step))
        seconds = float(np.asarray(dt))  # concrete here: a number, whichever array-like holds it
        count = round(seconds / self.plant_step)
        if count < 1 or abs(count * self.plant_step - seconds) > 1e-9 * max(1.0, seconds):
            raise check.ParameterError(
                "plant_step", f"the filter's plant_step ({self.plant_step:g} s) must divide the observer's sample period ({seconds:g} s)"
            )
        return count

    def substep(self, dt: ArrayLike) -> ArrayLike:
        """The integration step over a sample of ``dt`` s: ``plant_step``, or ``dt`` split
        evenly when ``dt`` is known only when the filter runs."""
        return self.plant_step if check.is_concrete(dt) else dt / self.substeps(dt)

    def linearized(self, mean: Array, t: ArrayLike, u: Array, dt: ArrayLike) -> tuple[Array, Array, Array]:
        """(F, Q_d, Phi(mean)) of one sample at ``mean`` (module docstring): the Jacobians
        from one forward-mode pass of the step in the state and the noise together, which
        gives the step's value too."""
        substeps, size, n = self.substeps(dt), self.model.noise_size, mean.size
        joint = jnp.concatenate([mean, jnp.zeros(substeps * size)])
        step = lambda z: self.step(z[:n], t, u, dt, z[n:].reshape(substeps, size))  # noqa: E731
        value, columns = jax.vmap(lambda tangent: jax.jvp(step, (joint,), (tangent,)), out_axes=(None, 1))(jnp.eye(joint.size))
        return columns[:, :n], self._noise_covariance(columns[:, n:], dt), value

    def process_covariance(self, mean: Array, t: ArrayLike, u: Array, dt: ArrayLike) -> Array:
        """Q_d over one sample (module docstring), linearized at ``mean``."""
        substeps, size = self.substeps(dt), self.model.noise_size
        jacobian = jax.jacfwd(lambda w: self.step(mean, t, u, dt, w.reshape(substeps, size)))(jnp.zeros(substeps * size))
        return self._noise_covariance(jacobian, dt)

    def _noise_covariance(self, noise_jacobian: Array, dt) -> Array:
        """Q_d from G = [G_1 ... G_n], the step's Jacobian in the noise of its substeps."""
        weighted = noise_jacobian * jnp.tile(self.process_noise, self.substeps(dt))[None, :]
        return _symmetric(weighted @ noise_jacobian.T / self.substep(dt) + jnp.diag(self.state_noise) * dt)

    def due_every(self, period: float) -> KalmanFilter:
        """This filter with every channel due at every multiple of ``period`` (s): for a
        stream whose readings are new when they arrive (a live session's), not on their
        instruments' schedule; a channel without a new reading is NaN, a missing one."""
        check.positive("period", period)
        twin = copy.copy(self)
        object.__setattr__(twin, "channel_periods", (float(period),) * len(self.channel_periods))  # a static field: no tree_at
        return twin

    def due(self, t: ArrayLike) -> Array:
        """Per channel: whether a new sample of it arrives at ``t``."""
        periods = jnp.asarray(self.channel_periods)
        ratio = t / periods
        return (jnp.abs(ratio - jnp.round(ratio)) <= 1e-6) & ~jnp.asarray(self.ignored_channels, dtype=bool)

    @property
    def kinematic(self) -> bool:
        """Whether the sensor measures the plant's kinematics under the applied input (a
        suite), so that h reads the input and the time the state carries."""
        return isinstance(self.sensor, KinematicSensor)

    def measurement(self, mean: Array, applied: Array | None = None, t: ArrayLike = 0.0) -> Array:
        """h(x): the sensor's noise-free measurement of the raveled state. On a kinematic
        sensor (a suite), its ``expected`` channels of the model's kinematics at ``t``
        under the input ``applied`` (zero when None) plus the input disturbance's
        estimate (module docstring); ``applied`` and ``t`` are unused otherwise."""
        state = self._unravel(mean)
        if not isinstance(self.sensor, KinematicSensor):
            return self.sensor.ideal(state)
        u = jnp.zeros(self.input_layout.size) if applied is None else applied
        if self.disturbance_size:  # the model is driven by u + d, and an IMU feels the acceleration it gives
            u = u + mean[self.state_size :]
        return self.sensor.expected(kinematics_of(self.model, t, state, u))

    def normalized(self, mean: Array) -> Array:
        """The filter's state with its angles wrapped."""
        return self.augmented(self.model.normalize(self._unravel(mean)), mean[self.state_size :])

    # ------------------------------------------------------------------ the filter
    @abc.abstractmethod
    def propagate(self, state: KalmanState, t: ArrayLike, u: Array, dt: ArrayLike) -> KalmanState:
        """The prior at t + dt from the posterior at t."""

    @abc.abstractmethod
    def correct(self, state: KalmanState, t: ArrayLike, y: Array) -> KalmanState:
        """The posterior at t from the prior and the sample ``y`` (channels masked)."""

    @abc.abstractmethod
    def innovation_statistics(self, state: KalmanState, y: Array) -> tuple[Array, Array]:
        """``(nu, S)``: the innovation of ``y`` at the prior ``state`` and its covariance,
        nu = y - y_hat (angle channels wrapped) and S = cov(nu) = H P- H^T + R (the
        extended filter's) or its unscented counterpart, on every finite channel whether
        or not it is due (a missing one: zero innovation, unit variance). What a
        validation gate tests: nu_c^T S_cc^-1 nu_c, the normalized innovation squared
        of channel c, is chi-square with the channel's size as degrees of freedom when
        the filter is consistent (Bar-Shalom, Li & Kirubarajan 2001, Estimation with
        Applications to Tracking and Navigation, Section 5.4); :class:`lookout.live.GatedObserver`
        gates a live reading on it."""

    # ------------------------------------------------------------------ Observer
    @initial_values(same_as="model.state")
    def guess(self, **parts: Any) -> Any:
        """The model plant's state from its named parts (the keywords of the plant's
        ``state``; zeros where not given, except the parts a plant leaves to a
        measurement (a default of None: a vessel's eta, an arm's q), which are NaN: the
        first measurement sets them, :meth:`init`)."""
        unset = {name: math.nan for name in _measured_parts(self.model) if parts.get(name) is None}
        return self.model.state(**{**{name: value for name, value in parts.items() if value is not None}, **unset})

    def init(self, y0: Array, guess: Any) -> KalmanState:
        """x_0 from the guess, its NaN entries (the states left to the first measurement,
        :mod:`lookout.observers.start`) solved from y_0: the least change of them that
        makes h(x_0) = y_0 on the channels y_0 has, by Gauss-Newton steps from 0 (one is
        exact for a measurement linear in them, as a vessel's eta + eta_w is in eta); P_0
        as given. On a suite the least squares are weighted by R^-1 (the channels'
        units differ: metres of two references with different lever arms, radians of a
        gyrocompass, an IMU's m/s2), and h is taken at t = 0 under a zero input, as the
        engine's first sample is. The correction at t_0 (:meth:`update`) then takes the
        first sample."""
        mean = self.augmented(guess)
        unknown = jnp.isnan(mean)
        mean = jnp.where(unknown, 0.0, mean)
        y0 = jnp.asarray(y0, dtype=float)
        present = jnp.isfinite(y0) & ~jnp.asarray(self.ignored_channels, dtype=bool)
        # 1 / std per channel on a suite; none on any other sensor, whose solve is left as it was
        weight = 1.0 / jnp.sqrt(jnp.diagonal(self.measurement_covariance)) if self.kinematic else None
        for _ in range(INITIAL_SOLVE_STEPS):
            residual, _ = masked(y0, self.measurement(mean), present, self.channel_angles)
            jacobian = jax.jacfwd(self.measurement)(mean) * unknown[None, :] * present[:, None]
            if weight is not None:
                residual, jacobian = weight * residual, weight[:, None] * jacobian
            mean = mean + jnp.linalg.pinv(jacobian) @ residual
        if not self.kinematic:
            return KalmanState(mean, self.initial_covariance)
        return KalmanState(mean, self.initial_covariance, jnp.zeros(self.input_layout.size), jnp.zeros(()))

    def update(self, state: KalmanState, t: ArrayLike, y: Array) -> KalmanState:
        if self.kinematic:  # the state is now at t (the input it carries is the one applied up to t)
            state = KalmanState(state.mean, state.covariance, state.applied, jnp.asarray(t, dtype=float))
        # a branch, not a select: t (hence which channels are due) is the same for every
        # run of a batch, so under vmap the samples with no fix skip the correction
        corrected = jax.lax.cond(jnp.any(self.due(t)), lambda s: _carried(self.correct(s, t, y), s), lambda s: s, state)
        finite = jnp.all(jnp.isfinite(corrected.mean)) & jnp.all(jnp.isfinite(corrected.covariance))
        return jax.tree.map(lambda new, old: jnp.where(finite, new, old), corrected, state)

    def output(self, state: KalmanState, y: Array) -> dict[str, Array]:
        estimate = dict(self.model.variables(self._unravel(state.mean)))
        if self.disturbance_size:
            disturbance = self.input_layout.split(state.mean[self.state_size :])
            estimate.update({f"disturbance_{name}": value for name, value in disturbance.items()})
        return estimate

    def predict(self, state: KalmanState, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> KalmanState:
        prior = self.propagate(state, t, u, dt)
        if not self.kinematic:
            return prior
        # the input applied over [t, t + dt]: what the suite's IMU feels at the sample at t + dt
        applied = jnp.asarray(u, dtype=float)
        return KalmanState(prior.mean, prior.covariance, applied, jnp.asarray(t + dt, dtype=float))

    def _time(self, state: KalmanState) -> ArrayLike:
        """The time of ``state``, where it carries one (a kinematic sensor's), else 0."""
        return 0.0 if state.time is None else state.time


def _carried(new: KalmanState, old: KalmanState) -> KalmanState:
    """``new``'s mean and covariance with ``old``'s input and time (a correction moves neither)."""
    return KalmanState(new.mean, new.covariance, old.applied, old.time)


def kalman_fields(
    plant: Plant,
    sensor: Sensor,
    *,
    process_noise: npt.ArrayLike | None,
    state_noise: npt.ArrayLike | dict[str, Any] | None,
    measurement_noise: npt.ArrayLike | None,
    initial_std: npt.ArrayLike | dict[str, Any] | None,
    plant_step: float,
    sample_period: float,
    integrator: str,
    input_disturbance: npt.ArrayLike | None = None,
    ignored_channels: tuple[bool, ...] | None = None,
) -> dict[str, Any]:
    """The shared fields of a Kalman filter on ``plant`` and ``sensor``, validated, with
    the defaults of the module docstring (the steady state from the extended filter's
    linearization, for either filter). ``ignored_channels`` marks channels the filter
    never takes as a measurement (never due, left out of the first solve and of the
    steady state's H)."""
    if not isinstance(plant, Plant):
        raise check.ParameterError("plant", f"plant must be a Plant; got {type(plant).__name__}")
    if not isinstance(sensor, Sensor):
        raise check.ParameterError("sensor", f"sensor must be a Sensor; got {type(sensor).__name__}")
    check.positive("plant_step", plant_step)
    check.positive("filter_period", sample_period)
    if integrator not in INTEGRATORS:
        raise check.ParameterError("integrator", f"integrator must be one of {', '.join(INTEGRATORS)}; got {integrator!r}")
    zero, _ = ravel_pytree(plant.state())
    layout = filter_layout(sensor)
    n, m, size = zero.size, layout.size, plant.noise_size
    inputs = plant.input_layout.size
    if input_disturbance is None:
        disturbance = np.zeros(0)
    else:
        disturbance = np.broadcast_to(np.asarray(input_disturbance, dtype=float), np.shape(input_disturbance) or (inputs,))
        if disturbance.shape != (inputs,) or not (np.all(np.isfinite(disturbance)) and np.all(disturbance >= 0)):
            raise check.ParameterError(
                "input_disturbance",
                f"input_disturbance must be {inputs} finite intensities >= 0 (one per input entry of the plant, units^2/s); got {np.asarray(input_disturbance).tolist()}",
            )
    d = disturbance.size
    substeps = max(1, round(float(sample_period) / float(plant_step)))
    if substeps > MAX_PROPAGATION_STEPS:  # the linearization runs through every one, at a cost in their square
        raise check.ParameterError(
            "plant_step",
            f"plant_step ({float(plant_step):g} s) makes {substeps} propagation steps per sample of {float(sample_period):g} s, and a "
            f"Kalman filter linearizes through each (its work grows with their square): at most {MAX_PROPAGATION_STEPS}; give the filter "
            f"a plant_step of its own of at least {float(sample_period) / MAX_PROPAGATION_STEPS:.3g} s",
        )
    refuse_unless_it_fits(
        working_nbytes(n + d, substeps, size),
        f"plant_step {float(plant_step):g} s ({substeps} propagation steps per sample of {float(sample_period):g} s, "
        f"{substeps * size} noise inputs to linearize in)",
        "give a longer plant_step",
    )
    q: Array | np.ndarray
    if process_noise is None:
        q = jnp.ones(size)
    elif not check.is_concrete(process_noise):  # traced (built under vmap or grad): checked where concrete
        q = jnp.broadcast_to(jnp.asarray(process_noise, dtype=float), (size,))
    else:
        q = np.asarray(process_noise, dtype=float)
        if q.ndim == 0:  # one intensity for every noise input, as state_noise and initial_std take one number
            q = np.full(size, float(q))
        if q.shape != (size,):
            raise check.ParameterError(
                "process_noise", f"process_noise must have {size} entries (one per noise input of the plant), or be one number for all; got {q.size}"
            )
        if not (np.all(np.isfinite(q)) and np.all(q >= 0)):
            raise check.ParameterError("process_noise", f"process_noise must be finite and non-negative; got {check._fmt(q)}")
    s = _state_vector(plant, state_noise, "state_noise", d, default_disturbance=0.0)
    s = np.zeros(n + d) if s is None else s
    s = np.concatenate([s[:n], s[n:] + disturbance])  # the disturbance's random walk
    if isinstance(sensor, KinematicSensor) and getattr(plant, "kinematics", None) is None:
        raise check.ParameterError(
            "plant", f"plant {type(plant).__name__} gives no kinematics (position, heading, rates) for the filter's sensor suite to measure"
        )
    if measurement_noise is None:
        r = default_measurement_covariance(sensor, plant)
        eigenvalues = np.linalg.eigvalsh(r)
        if eigenvalues.min() <= 1e-300:
            silent = [signal for signal, value in zip(_channel_names(layout), np.diag(r)) if value <= 0]
            raise check.ParameterError(
                "measurement_noise",
                f"measurement_noise: the sensor's own noise is zero on {', '.join(silent) or 'a combination of channels'}; "
                "give measurement_noise (a standard deviation per channel)",
            )
    else:
        std = np.asarray(measurement_noise, dtype=float)
        if std.shape != (m,) or not (np.all(np.isfinite(std)) and np.all(std > 0)):
            raise check.ParameterError(
                "measurement_noise", f"measurement_noise must be {m} finite standard deviations > 0 (one per measured channel); got {std.tolist()}"
            )
        r = np.diag(std**2)
    fields = {
        "model": plant,
        "sensor": sensor,
        "process_noise": jnp.asarray(q),
        "state_noise": jnp.asarray(s),
        "measurement_covariance": jnp.asarray(r),
        "plant_step": float(plant_step),
        "filter_period": float(sample_period),
        "integrator": integrator,
        "state_size": n,
        "disturbance_size": d,
        "state_angles": _angle_entries(plant) + (False,) * d,
        "channel_angles": tuple(bool(signal.angle) for signal in layout.signals for _ in range(signal.size)),
        # a suite's instrument channels come first in its measurement, each with its instrument's period
        "channel_periods": tuple(float(p) for p in sensor.sample_period[:m]),
        "estimate_signals": tuple(plant.variable_signals),
        "extra_signals": tuple(plant.input_layout.renamed(prefix="disturbance_", long_prefix="estimated input disturbance: ").signals) if d else (),
        "measurement_layout": layout,
        "input_layout": plant.input_layout,
        "sample_period": None,
        "ignored_channels": tuple(bool(each) for each in (ignored_channels or (False,) * m)),
    }
    initial = _state_vector(plant, initial_std, "initial_std", d)
    if initial is not None:
        fields["initial_covariance"] = jnp.diag(jnp.asarray(initial**2))
    else:
        fields["initial_covariance"] = jnp.asarray(_steady_state(fields, sample_period))
    return fields


def _channel_names(layout: Layout) -> list[str]:
    return [f"{signal.name}[{label}]" if signal.labels else signal.name for signal in layout.signals for label in (signal.labels or ("",))]


def _steady_state(fields: dict, sample_period: float) -> np.ndarray:
    """P_0: the prior covariance of the steady-state filter of the model linearized at
    its zero state over one observer sample (scipy's solve_discrete_are)."""
    from scipy.linalg import solve_discrete_are

    n = fields["state_size"] + fields["disturbance_size"]
    probe = _Linearization(**fields, initial_covariance=jnp.zeros((n, n)))
    transition, noise, observation = (np.asarray(a) for a in _linearized(probe, float(sample_period)))
    try:
        solution = solve_discrete_are(transition.T, observation.T, noise, np.asarray(fields["measurement_covariance"]))
    except (np.linalg.LinAlgError, ValueError) as error:
        reason = str(error).split("\n")[0]
        raise check.ParameterError(
            "initial_std",
            f"initial_std: the model's steady-state covariance does not exist ({reason}: its own noise does not reach every state); "
            "give initial_std (a table of the plant's state parts, or one standard deviation per state entry)",
        ) from None
    solution = 0.5 * (solution + solution.T)
    scale = np.sqrt(np.abs(np.diag(solution)))
    # positive definite, judged on the correlation matrix (the states' units differ by 1e10)
    if not np.all(np.isfinite(solution)) or np.any(scale <= 0) or np.linalg.eigvalsh(solution / np.outer(scale, scale)).min() <= 1e-12:
        raise check.ParameterError("initial_std", "initial_std: the model's steady-state covariance is not positive definite; give initial_std")
    return np.asarray(solution)


@eqx.filter_jit
def _linearized(probe: KalmanFilter, dt: float):
    """(F, Q_d, H) of the model at its zero state, u = 0, t = 0, over ``dt``."""
    zero = probe.augmented(probe.model.state())
    transition, noise, _ = probe.linearized(zero, 0.0, jnp.zeros(probe.input_layout.size), dt)
    used = 1.0 - jnp.asarray(probe.ignored_channels, dtype=float)
    return transition, noise, jax.jacfwd(probe.measurement)(zero) * used[:, None]


class _Linearization(KalmanFilter):
    """A filter's fields without a prior of its own (to linearize the model for P_0)."""

    def propagate(self, state, t, u, dt):
        raise NotImplementedError

    def correct(self, state, t, y):
        raise NotImplementedError

    def innovation_statistics(self, state, y):
        raise NotImplementedError


#: The parameters every Kalman filter takes (numpydoc; the registry reads them).
PARAMETERS = """
    plant : Plant
        The filter's model of the plant (default: the composition's plant; give a
        ``[observer.plant]`` table for a model that differs from the truth).
    sensor : Sensor
        The filter's model of the sensor (default: the composition's sensor). On a
        sensor suite every instrument channel is a measurement of its own.
    process_noise : array_like, shape (noise_size,), non-negative, optional
        Intensity of each of the model's unit white noise inputs (1: the model's own;
        default all 1). One number is every input's.
    state_noise : array_like or table, non-negative, optional
        Continuous-time process noise intensity added per state entry (units^2/s): one
        per raveled state entry, or a table of the plant's state parts as
        ``[plant.initial]`` takes them (default 0).
    measurement_noise : array_like, shape (m,), positive, optional
        Standard deviation of each measured channel, R = diag(std^2) (default: the
        sensor's own noise). A suite's own is each instrument's white noise and slow
        Gauss-Markov error, sqrt(noise_std^2 + error_std^2).
    initial_std : array_like or table, non-negative, optional
        Standard deviation of the initial guess per state entry, or a table of the
        plant's state parts and ``input_disturbance`` (default: the steady-state
        filter's, from the Riccati equation).
    input_disturbance : array_like, non-negative, optional
        Estimate an unknown disturbance added to the plant's input, a random walk of
        this intensity per input entry (units^2/s; 0: a constant, and with an initial
        std of 0 none on that entry): the usual DP bias state, for a model without one
        (default none).
    plant_step : float, positive
        Step of the propagation (s); default the composition's ``simulation.plant_step``,
        which makes the propagation the simulated plant's own discretization.
    filter_period : float, positive
        The filter's sample period (s), for the steady-state P_0; default the
        composition's ``simulation.sample_period``.
    integrator : str
        ``rk4`` or ``euler``; default the composition's ``simulation.integrator``."""
