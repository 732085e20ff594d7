"""A manipulator whose unknown parameters change in steps: theta(t) piecewise constant.

Calugi (2002), master thesis, Lund, chapter 3, first simulation: the pendulum's mass
is "unknown and piecewise constant", and the estimator (3.9) is shown tracking it
(Fig. 3.2). :class:`ScheduledParameterPlant` is that plant for any
:class:`~lookout.models.parameters.AffineParameters`: at time t the dynamics are those
of ``parameters.model(theta(t))``, with ``theta(t) = values[k]`` on
``[switch_times[k-1], switch_times[k])`` (``values[0]`` before the first switch,
the last value after the last). The state stays :class:`JointState` (q and q' are
continuous across a switch; q'' jumps).

The plant records the joints; :meth:`ScheduledParameterPlant.truth` gives the true
parameters at any times, named after the parameters (``mass``; ``masses[1]`` becomes
``masses_1``) as :attr:`ScheduledParameterPlant.parameter_layout` describes them, so
that they can be put next to an estimator's ``<name>_hat``.
"""

from __future__ import annotations

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import DivergenceBound, Layout, Plant, Signal
from lookout.declare import NON_NEGATIVE, Part, Value, component, initial_values
from lookout.models.manipulators import JOINT_INPUT, JOINT_POSITION, JOINT_VELOCITY, JointState, joint_layout
from lookout.models.parameters import AffineParameters, parameter_signals


@component(
    "plant",
    "scheduled-parameters",
    summary="A manipulator with piecewise-constant parameters theta(t), as a plant with state JointState.",
    parameters=(
        Part("parameters", "Which parameters change, and the model they build (its other parameters fixed)."),
        Value(
            "values",
            "array",
            "theta on each interval, finite, in the parameters' units; one row means constant parameters.",
            shape="(K + 1, p) or (p,)",
        ),
        Value("switch_times", "array", "Strictly increasing, finite times (s) at which theta jumps to the next row.", shape="(K,)"),
        Value(
            "force_noise",
            "array",
            "Standard deviation of a white force disturbance per joint (N m sqrt(s) or N sqrt(s)); default 0, none.",
            shape="(n,)",
            range=NON_NEGATIVE,
        ),
    ),
)
@final
class ScheduledParameterPlant(Plant):
    """A manipulator with piecewise-constant parameters theta(t), as a plant with state :class:`JointState`.

    ``q' = qdot``, ``qdot' = M^-1(q; theta(t)) [u + sigma w - C qdot - F qdot - G(q; theta(t))]``,
    the model being ``parameters.model(theta(t))``.

    Parameters
    ----------
    parameters : AffineParameters
        Which parameters change, and the model they build (its other parameters fixed).
    values : array_like, shape (K + 1, p) or (p,)
        theta on each interval, finite, in the parameters' units; one row means constant parameters.
    switch_times : sequence of K floats
        Strictly increasing, finite times (s) at which theta jumps to the next row.
    force_noise : float or array_like, shape (n,), non-negative
        Standard deviation of a white force disturbance per joint (N m sqrt(s) or N sqrt(s));
        default 0, none.
    """

    #: a failed run: a joint-rate error of 100 rad/s (about 950 rpm): beyond any arm's motion
    divergence: ClassVar[DivergenceBound] = DivergenceBound("joint_rate", 100.0)

    parameters: AffineParameters
    values: Array
    switch_times: Array
    force_noise: Array
    noise_size: int = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True)
    position_layout: Layout = eqx.field(static=True)
    velocity_layout: Layout = eqx.field(static=True)
    parameter_layout: Layout = eqx.field(static=True)

    def __init__(self, parameters: AffineParameters, values: npt.ArrayLike, switch_times: npt.ArrayLike = (), force_noise: npt.ArrayLike = 0.0):
        if not isinstance(parameters, AffineParameters):
            raise check.ParameterError("parameters", f"parameters must be AffineParameters; got {type(parameters).__name__}")
        p = parameters.size
        values = jnp.asarray(values, dtype=float)
        if values.ndim == 1:
            values = values[None, :]
        if values.ndim != 2 or values.shape[1] != p:
            raise check.ParameterError(
                "values", f"values must have shape (intervals, {p}) (one row of the {p} parameters per interval); got shape {values.shape}"
            )
        switch_times = jnp.asarray(switch_times, dtype=float).reshape(-1)
        if switch_times.shape[0] != values.shape[0] - 1:
            raise check.ParameterError(
                "switch_times", f"switch_times must have one entry fewer than values has rows ({values.shape[0] - 1}); got {switch_times.shape[0]}"
            )
        model = parameters.model(parameters.reference)
        names, kinds = model.joint_names, model.joint_kinds
        self.parameters = parameters
        self.values = values
        self.switch_times = switch_times
        self.force_noise = jnp.asarray(check.vector("force_noise", force_noise, model.size))
        self.noise_size = model.size
        self.input_layout = joint_layout(names, kinds, JOINT_INPUT)
        self.position_layout = joint_layout(names, kinds, JOINT_POSITION)
        self.velocity_layout = joint_layout(names, kinds, JOINT_VELOCITY)
        self.parameter_layout = Layout(parameter_signals(parameters, long_prefix="true "))
        self.variable_signals = self.position_layout.signals + self.velocity_layout.signals

    def __check_init__(self):
        check.positive("force_noise", self.force_noise, allow_zero=True)
        check.finite("scheduled parameter values", self.values)
        if check.is_concrete(self.switch_times):
            times = np.asarray(self.switch_times)
            check.finite("switch_times", times)
            if np.any(np.diff(times) <= 0):
                raise check.ParameterError("switch_times", f"switch_times must be strictly increasing; got {times.tolist()}")

    def theta(self, t: ArrayLike) -> Array:
        """theta(t): the row of :attr:`values` whose interval holds t (right-continuous)."""
        return self.values[jnp.searchsorted(self.switch_times, t, side="right")]

    @initial_values(
        Value(
            "q",
            "array",
            "Joint coordinates in joint order (rad, m; zeros when not given; an observer's guess takes it from the first measurement).",
            shape="(n,)",
        ),
        Value("qdot", "array", "Their rates (rad/s, m/s).", shape="(n,)"),
    )
    def state(self, q: npt.ArrayLike | None = None, qdot: npt.ArrayLike = 0.0) -> JointState:
        """A :class:`JointState` from scalars or sequences, checked for size n (zeros where
        not given): a composition's ``[plant.initial]``.

        Parameters
        ----------
        q : array_like, shape (n,), optional
            Joint coordinates in joint order (rad, m; zeros when not given; an observer's guess takes it from the first measurement).
        qdot : array_like, shape (n,)
            Their rates (rad/s, m/s).
        """
        n = self.noise_size
        return JointState(jnp.asarray(check.vector("q", 0.0 if q is None else q, n)), jnp.asarray(check.vector("qdot", qdot, n)))

    def vector_field(self, t: ArrayLike, x: JointState, u: Array, w: Array) -> JointState:
        """(q', qdot') of eq. (2.1) with the model of theta(t)."""
        model = self.parameters.model(self.theta(t))
        return JointState(x.qdot, model.acceleration(x.q, x.qdot, u + self.force_noise * w))

    def normalize(self, x: JointState) -> JointState:
        """The identity: joint angles are not wrapped (as :class:`ManipulatorPlant`)."""
        return x

    def variables(self, x: JointState) -> dict[str, Array]:
        """``joint_angle`` / ``joint_position`` and ``joint_rate`` / ``joint_speed`` by joint name.

        theta(t) is not recorded here (the state carries no time, and a clock state
        would put a switch one rounding error early or late); :meth:`truth` gives it
        at the recorded times.
        """
        return {**self.position_layout.split(x.q), **self.velocity_layout.split(x.qdot)}

    def truth(self, time: npt.ArrayLike) -> dict[str, np.ndarray]:
        """The true parameters at the times ``time`` (s), by signal name (:attr:`parameter_layout`)."""
        index = np.searchsorted(np.asarray(self.switch_times), np.asarray(time, dtype=float), side="right")
        values = np.asarray(self.values)[index]
        return {signal.name: values[..., j] for j, signal in enumerate(self.parameter_layout.signals)}

    def models(self) -> tuple:
        """The model with the first interval's parameters, and the parameters' description."""
        return (self.parameters.model(self.values[0]), self.parameters)

    def realize(self, key: Array) -> ScheduledParameterPlant:
        """No per-run randomness beyond the white noise: the plant itself."""
        del key
        return self


__all__ = ["ScheduledParameterPlant"]
