"""Reduced-order velocity observer for rigid-link manipulators.

Calugi (2002), master thesis, Lund, Section 2.2, eqs. (2.6)–(2.7), after
Nicosia and Tomei: from the measured joint positions q and the input tau::

    z'     = M^-1(q) [tau - C(q, x1_hat) x1_hat - F x1_hat - G(q)] - K x1_hat    (2.6)
    x1_hat = z + K q                                                        (2.7)

with K a positive diagonal gain and z in R^n the observer's internal state.
Eliminating z gives (2.8), ``x1_hat' = M^-1 [...] + K (q' - x1_hat)``: the model's
acceleration plus an injection of the velocity error, although q' is never formed.

Choices made where the thesis is silent (see docs/reproductions.md):

* Friction. The thesis's C includes the viscous friction (C = c for the pendulum);
  here the observer's model carries it as F x1_hat, F the model's own diagonal
  :attr:`~lookout.models.manipulators.ManipulatorModel.friction`, so the observer
  computes exactly the thesis's ``C(q, x1_hat) x1_hat`` with the printed C. Only the
  product C(q, v) v enters, so the factorization of C does not matter here.
* Missing samples. A NaN channel of y (a dropped encoder sample, held by the engine
  until the channel's next sample) is replaced by the observer's own running
  position estimate q_hat, which integrates ``q_hat' = x1_hat`` and is reset to y
  whenever y is valid. On a dropped channel (2.7) then gives
  ``x1_hat' = z' + K q_hat' = M^-1[...]``: the observer predicts with its model and
  no velocity injection (a dropout is not a crash), and stays finite. When the channel
  returns, x1_hat moves by K (y - q_hat), the injection of the position drift.
  A first sample y_0 that is NaN starts q_hat at 0 on that channel.
* Sampled operation. :meth:`predict` integrates (2.6) by RK4 with y and tau held
  over the sample (zero-order hold), so x1_hat = z + K y jumps by K times the
  position increment when the next sample arrives; the continuous-time mode of the
  engine integrates :meth:`vector_field` jointly with the plant instead.
* Joint angles are not wrapped (:meth:`normalize` is the identity): x1_hat = z + K q
  would jump by 2 pi K if q did.
"""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import ContinuousObserver, Layout, Signal
from lookout.declare import POSITIVE, Part, Value, component, initial_values
from lookout.models.manipulators import JOINT_INPUT, JOINT_MEASUREMENT, JOINT_VELOCITY, ManipulatorModel, joint_layout
from lookout.sim.integrators import integrate_sample


class VelocityObserverState(eqx.Module):
    """Internal state of :class:`VelocityObserver`.

    Attributes
    ----------
    z : Array, shape (n,)
        The internal state z of eqs. (2.6)–(2.7) (rad/s, m/s).
    position : Array, shape (n,)
        The observer's running joint position estimate q_hat (rad, m): the last
        valid measurement plus the integral of x1_hat since; used in place of a
        missing (NaN) measurement only.
    """

    z: Array
    position: Array


@component(
    "observer",
    "velocity",
    summary="Reduced-order velocity observer of Calugi (2002), eqs. (2.6)–(2.7).",
    family="lookout.tuning.families.velocity:VelocityFamily",
    parameters=(
        Part("model", "The observer's own model M, C, F, G (it may differ from the plant's)."),
        Value("gain", "array", "Diagonal of K (1/s).", shape="(n,)", range=POSITIVE),
        Value("steps_per_sample", "int", "RK4 steps of predict per sample period (sampled mode).", range=POSITIVE),
    ),
)
@final
class VelocityObserver(ContinuousObserver):
    """Reduced-order velocity observer of Calugi (2002), eqs. (2.6)–(2.7).

    Estimates the joint velocities x1 = q' from the measured joint positions; its
    estimate is named as the plant's velocity signals (``joint_rate`` over
    ``revolute_joint``, ``joint_speed`` over ``prismatic_joint``), so the results
    pair it with the truth as ``joint_rate_hat`` / ``joint_speed_hat``; there are no
    extra outputs (``extra_signals`` is empty). Convergence
    condition: Theorem 2.1, :func:`lookout.analysis.velocity.velocity_observer_condition`.

    Parameters
    ----------
    model : ManipulatorModel
        The observer's own model M, C, F, G (it may differ from the plant's).
    gain : float or array_like, shape (n,), positive
        Diagonal of K (1/s).
    steps_per_sample : int, positive
        RK4 steps of :meth:`predict` per sample period (sampled mode).
    """

    model: ManipulatorModel
    gain: Array
    steps_per_sample: int = eqx.field(static=True)
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    #: the joint positions it reads and the joint torques/forces applied; any step dt
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    sample_period: None = eqx.field(static=True)

    def __init__(self, model: ManipulatorModel, gain: npt.ArrayLike, steps_per_sample: int = 1):
        if not isinstance(model, ManipulatorModel):
            raise check.ParameterError("model", f"model must be a ManipulatorModel; got {type(model).__name__}")
        self.model = model
        self.gain = jnp.asarray(check.vector("velocity observer gain", gain, model.size))
        if not (isinstance(steps_per_sample, int) and steps_per_sample >= 1):
            raise check.ParameterError("steps_per_sample", f"steps_per_sample must be a positive integer; got {steps_per_sample!r}")
        self.steps_per_sample = steps_per_sample
        self.estimate_signals = joint_layout(model.joint_names, model.joint_kinds, JOINT_VELOCITY).signals
        self.extra_signals = ()  # the reduced-order observer outputs only its velocity estimate
        self.measurement_layout = joint_layout(model.joint_names, model.joint_kinds, JOINT_MEASUREMENT)
        self.input_layout = joint_layout(model.joint_names, model.joint_kinds, JOINT_INPUT)
        self.sample_period = None

    def __check_init__(self):
        check.positive("velocity observer gain", self.gain)

    def _positions(self, state: VelocityObserverState, y: Array) -> Array:
        """The measured q where valid, the running estimate q_hat where y is NaN."""
        return jnp.where(jnp.isfinite(y), y, state.position)

    def velocity(self, state: VelocityObserverState, y: Array) -> Array:
        """x1_hat = z + K q (eq. 2.7), q_hat standing in for missing channels."""
        return state.z + self.gain * self._positions(state, y)

    @initial_values(
        Value("velocity", "array", "x1_hat(0), the joints' velocity estimate (rad/s, m/s).", shape="(n,)"),
    )
    def guess(self, velocity: npt.ArrayLike = 0.0) -> Array:
        """An initial velocity estimate x1_hat(0) (rad/s, m/s): ``velocity`` per joint (zero by default).

        Parameters
        ----------
        velocity : array_like, shape (n,)
            x1_hat(0), the joints' velocity estimate (rad/s, m/s).
        """
        return jnp.asarray(check.vector("velocity", velocity, self.model.size))

    def init(self, y0: Array, guess: npt.ArrayLike) -> VelocityObserverState:
        """z_0 = x1_hat(0) - K y_0, so that the estimate at t_0 is ``guess``.

        Parameters
        ----------
        y0 : Array, shape (n,)
            The first measurement (NaN channels start q_hat at 0).
        guess : float or array_like, shape (n,)
            The initial velocity estimate x1_hat(0) (rad/s, m/s).
        """
        position = jnp.where(jnp.isfinite(y0), y0, 0.0)
        guess = jnp.broadcast_to(jnp.asarray(guess, dtype=position.dtype), position.shape)
        return VelocityObserverState(guess - self.gain * position, position)

    def update(self, state: VelocityObserverState, t: ArrayLike, y: Array) -> VelocityObserverState:
        """No discrete correction: the measurement enters through (2.6)–(2.7)."""
        del t, y
        return state

    def output(self, state: VelocityObserverState, y: Array) -> dict[str, Array]:
        """The velocity estimate x1_hat as the plant's ``joint_rate`` / ``joint_speed``."""
        return Layout(self.estimate_signals).split(self.velocity(state, y))

    def vector_field(self, t: ArrayLike, state: VelocityObserverState, y: Array, u: Array) -> VelocityObserverState:
        """(z', q_hat') of eq. (2.6) with measurement ``y`` and input ``u`` (joint order)."""
        del t
        q = self._positions(state, y)
        velocity = state.z + self.gain * q  # eq. (2.7)
        # Calugi (2002), eq. (2.6): M^-1(q) [u - C(q, x1_hat) x1_hat - F x1_hat - G(q)] - K x1_hat
        z_rate = self.model.acceleration(q, velocity, u) - self.gain * velocity
        return VelocityObserverState(z_rate, velocity)

    def normalize(self, state: VelocityObserverState) -> VelocityObserverState:
        """The identity: joint angles are not wrapped."""
        return state

    def predict(self, state: VelocityObserverState, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> VelocityObserverState:
        """From t to t + dt with y and u held: ``steps_per_sample`` RK4 steps of (2.6).

        q_hat restarts from y on the valid channels, so over a dropout it
        continues from the last valid sample integrated by x1_hat.
        """
        state = VelocityObserverState(state.z, self._positions(state, y))
        field = lambda time, s: self.vector_field(time, s, y, u)
        return integrate_sample(field, t, state, dt, self.steps_per_sample)
