"""The Furuta pendulum of Calugi (2002), chapter 6, in its inertia constants, with a
stick-slip Coulomb friction on the arm.

Calugi (2002), master thesis, Lund, eqs. (6.1)–(6.4). q = (phi, theta): phi the arm's
angle about the pillar, theta the pendulum's angle from the upward vertical::

    (alpha + beta sin^2 th) phi'' + gamma cos th th'' + 2 beta cos th sin th phi' th' - gamma sin th th'^2 = tau   (6.1)
    gamma cos th phi'' + beta th'' - beta cos th sin th phi'^2 - delta sin th = 0                              (6.2)
    tau = tau_u - tau_F,    tau_F = tau_C sgn(phi')                                                            (6.3), (6.4)

with (alpha, beta, gamma, delta) = (0.00354, 0.00384, 0.00258, 0.103) and
tau_C = 0.028 N m, as printed. In the form (2.1), M = [[alpha + beta sin^2 th,
gamma cos th], [gamma cos th, beta]], G = (0, -delta sin th) and the printed
C = [[beta c s th', beta c s phi' - gamma s th'], [-beta c s phi', 0]], which is the
Christoffel-symbol factorization (the one :class:`~lookout.models.manipulators.ManipulatorModel`
derives; checked in ``tests/test_furuta.py``).

:class:`FurutaConstants` is the model (for the observer, the controller and the plant).
Its ``coulomb_friction`` enters :meth:`~lookout.models.manipulators.ManipulatorModel.friction_force`
as ``tau_C sign(v)`` with sign(0) = 0, which is what the observer's model needs (the
thesis's tau_C_hat sgn x1_hat_1). The plant, :class:`FurutaPlant`, instead lets the arm
stick.

Stick-slip on the arm (joint 0). With the friction torque f on joint 0 as the unknown,
q'' = M^-1 (tau - h) - M^-1 e1 f with h = C(q, q') q' + F q' + G(q) (F the viscous
friction, zero here), so phi'' = b - m f with b = [M^-1 (tau - h)]_1 and m = [M^-1]_11 > 0.
The torque that holds phi'' = a is f(a) = (b - a) / m. The arm can stay at rest
(phi' = 0, phi'' = 0) while |f(0)| <= tau_C. Written out, with phi' = 0, (6.2) gives
th''_s = delta sin th / beta and (6.1) gives f(0) = tau_u - gamma cos th th''_s + gamma sin th th'^2,
so the stick condition is |tau_u - gamma cos th th''_s + gamma sin th th'^2| <= tau_C, as in
derivations-thesis-ch3-6.md (verified here symbolically by the line above and numerically
in the tests).

Integration with fixed-step RK4 (the chosen model; Karnopp-style):

* **stick** when |phi'| < ``stick_band`` and |f(0)| <= tau_C: the friction is
  f(-phi'/``stick_relaxation``) clipped to +-tau_C, so phi' decays to zero with time constant
  ``stick_relaxation`` (a true rest, not a drift at a speed below the band);
* **slip** otherwise: f = tau_C sgn(phi') outside the band, and f = tau_C sgn(f(0)) (the
  direction the net torque breaks the arm away) inside it.

Its error: the arm is caught when |phi'| < band instead of exactly at phi' = 0, so the
velocity jumps by at most the band (default 0.02 rad/s) and the angle moves by at most
band * relaxation (2e-5 rad by default, below the arm encoder's 0.01 rad); a zero crossing
of phi' faster than 2 band per step (|phi''| > 160 rad/s^2 at 0.25 ms) overshoots the band,
is pushed back by the reversed friction and is caught a step or two later. Each RK4 stage
picks its mode afresh, so a step across a switch has an O(h) error, as any fixed-step
method on a discontinuous field. The time spent sticking is integrated as a state
(``arm_stuck_time``).
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
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Value, component, initial_values
from lookout.models.manipulators import (
    JOINT_INPUT,
    JOINT_POSITION,
    JOINT_VELOCITY,
    REVOLUTE,
    ManipulatorModel,
    _scalar,
    joint_layout,
)

#: The printed constants of Calugi (2002), Section 6.1 (from Åström's Furuta model):
#: alpha, beta, gamma (kg m^2), delta (N m).
PRINTED_CONSTANTS = (0.00354, 0.00384, 0.00258, 0.103)
#: tau_C of (6.4), N m.
PRINTED_COULOMB_FRICTION = 0.028


@component(
    "model",
    "furuta-constants",
    summary="The Furuta pendulum of Calugi (2002), Section 6.1, eqs. (6.1)–(6.2), in its constants.",
    parameters=(
        Value("alpha", "float", "alpha (kg m^2), above gamma^2/beta so that M is positive definite at every theta; Section 6.1: 0.00354."),
        Value("beta", "float", "beta (kg m^2); Section 6.1: 0.00384.", range=POSITIVE),
        Value("gamma", "float", "gamma (kg m^2); Section 6.1: 0.00258."),
        Value("delta", "float", "delta (N m), the pendulum's gravity torque coefficient; Section 6.1: 0.103.", range=NON_NEGATIVE),
        Value(
            "coulomb_friction", "array", "tau_C per joint (N m) of (6.4); Section 6.1: (0.028, 0), on the arm only.", shape="(2,)", range=NON_NEGATIVE
        ),
        Value("friction", "array", "Viscous friction per joint (N m s/rad); none in the thesis.", shape="(2,)", range=NON_NEGATIVE),
    ),
)
@final
class FurutaConstants(ManipulatorModel):
    """The Furuta pendulum of Calugi (2002), Section 6.1, eqs. (6.1)–(6.2), in its constants.

    q = (phi, theta): arm angle and pendulum angle from the upward vertical (theta = 0
    upright, pi hanging)::

        M = [[alpha + beta sin^2 theta, gamma cos theta], [gamma cos theta, beta]],   G = (0, -delta sin theta)

    plus the arm's Coulomb friction tau_C sgn(phi') of (6.4) through ``coulomb_friction``
    (the plant :class:`FurutaPlant` lets the arm stick; a model evaluates sign(0) = 0).

    Parameters
    ----------
    alpha : float
        alpha (kg m^2), above gamma^2/beta so that M is positive definite at every theta; Section 6.1: 0.00354.
    beta : float, positive
        beta (kg m^2); Section 6.1: 0.00384.
    gamma : float
        gamma (kg m^2); Section 6.1: 0.00258.
    delta : float, non-negative
        delta (N m), the pendulum's gravity torque coefficient; Section 6.1: 0.103.
    coulomb_friction : array_like, shape (2,), non-negative
        tau_C per joint (N m) of (6.4); Section 6.1: (0.028, 0), on the arm only.
    friction : array_like, shape (2,), non-negative
        Viscous friction per joint (N m s/rad); none in the thesis.
    """

    alpha: Array
    beta: Array
    gamma: Array
    delta: Array
    coulomb_friction: Array
    friction: Array
    joint_names: ClassVar[tuple[str, ...]] = ("arm", "pendulum")
    joint_kinds: ClassVar[tuple[str, ...]] = (REVOLUTE, REVOLUTE)

    def __init__(
        self,
        alpha: ArrayLike = PRINTED_CONSTANTS[0],
        beta: ArrayLike = PRINTED_CONSTANTS[1],
        gamma: ArrayLike = PRINTED_CONSTANTS[2],
        delta: ArrayLike = PRINTED_CONSTANTS[3],
        coulomb_friction: npt.ArrayLike = (PRINTED_COULOMB_FRICTION, 0.0),
        friction: npt.ArrayLike = (0.0, 0.0),
    ):
        self.alpha = _scalar("alpha", alpha)
        self.beta = _scalar("beta", beta)
        self.gamma = _scalar("gamma", gamma)
        self.delta = _scalar("delta", delta)
        self.coulomb_friction = jnp.asarray(check.vector("coulomb_friction", coulomb_friction, 2), dtype=float)
        self.friction = jnp.asarray(check.vector("Furuta friction", friction, 2), dtype=float)

    def __check_init__(self):
        # estimates (ModelParameters.model, built by eqx.tree_at) skip these checks: an
        # alpha_hat may be anything, and the observer's resetting bounds keep M_hat positive definite
        check.positive("beta", self.beta)
        if check.is_concrete(self.alpha) and check.is_concrete(self.gamma) and check.is_concrete(self.beta):
            floor = float(self.gamma) ** 2 / float(self.beta)
            if not float(self.alpha) > floor:
                raise check.ParameterError(
                    "alpha",
                    f"alpha must exceed gamma^2/beta = {floor:.4g} kg m^2 so that M is positive definite at every theta "
                    f"(Property 2.1); got {float(self.alpha):.4g}",
                )
        check.positive("delta", self.delta, allow_zero=True)
        check.positive("coulomb_friction", self.coulomb_friction, allow_zero=True)
        check.positive("Furuta friction", self.friction, allow_zero=True)

    def mass_matrix(self, q: Array) -> Array:
        """M(q) of (6.1)–(6.2)."""
        coupling = self.gamma * jnp.cos(q[1])
        return jnp.array([[self.alpha + self.beta * jnp.sin(q[1]) ** 2, coupling], [coupling, self.beta]])

    def gravity(self, q: Array) -> Array:
        """G(q) = (0, -delta sin theta)."""
        return jnp.array([jnp.zeros_like(q[1]), -self.delta * jnp.sin(q[1])])

    def potential_energy(self, q: Array) -> Array:
        """V = delta cos theta (so that G = dV/dq)."""
        return self.delta * jnp.cos(q[1])

    def printed_coriolis_matrix(self, q: Array, v: Array) -> Array:
        """C(q, q') as printed in Section 6.1 (to check against the derived Christoffel C)."""
        c, s = jnp.cos(q[1]), jnp.sin(q[1])
        return jnp.array(
            [[self.beta * c * s * v[1], self.beta * c * s * v[0] - self.gamma * s * v[1]], [-self.beta * c * s * v[0], jnp.zeros_like(v[0])]]
        )

    def determinant(self, q: Array) -> Array:
        """det M(q) = (alpha + beta sin^2 theta) beta - gamma^2 cos^2 theta; positive for all
        theta iff alpha > gamma^2 / beta (0.00173 for the printed beta, gamma)."""
        return (self.alpha + self.beta * jnp.sin(q[1]) ** 2) * self.beta - (self.gamma * jnp.cos(q[1])) ** 2


class FurutaState(eqx.Module):
    """State of :class:`FurutaPlant`.

    Attributes
    ----------
    q : Array, shape (2,)
        (phi, theta), rad (not wrapped).
    qdot : Array, shape (2,)
        Their rates, rad/s.
    stuck_time : Array, scalar
        Time the arm has spent sticking so far, s.
    """

    q: Array
    qdot: Array
    stuck_time: Array


@component(
    "plant",
    "furuta",
    summary="The Furuta pendulum with stick-slip Coulomb friction on the arm (Calugi 2002, (6.1)–(6.4)).",
    parameters=(
        Part("model", "The true pendulum in its constants, Coulomb friction included."),
        Value("stick_band", "float", "|phi'| (rad/s) below which the arm may stick; default 0.02.", range=POSITIVE),
        Value(
            "stick_relaxation",
            "float",
            "Time constant (s) by which a sticking arm's residual speed goes to zero; default 1 ms (keep it >= 2 plant steps for RK4).",
            range=POSITIVE,
        ),
    ),
)
@final
class FurutaPlant(Plant):
    """The Furuta pendulum with stick-slip Coulomb friction on the arm (Calugi 2002, (6.1)–(6.4)).

    The model's ``coulomb_friction[0]`` sticks and slips as in the module docstring
    (Karnopp-style band plus relaxation to rest); the pendulum's Coulomb friction must be 0.
    Input: ``joint_torque`` over (arm, pendulum), the second entry a torque on the pendulum
    (0 in the thesis). Records ``joint_angle``, ``joint_rate`` and ``arm_stuck_time``.

    Parameters
    ----------
    model : FurutaConstants
        The true pendulum in its constants, Coulomb friction included.
    stick_band : float, positive
        |phi'| (rad/s) below which the arm may stick; default 0.02.
    stick_relaxation : float, positive
        Time constant (s) by which a sticking arm's residual speed goes to zero; default
        1 ms (keep it >= 2 plant steps for RK4).
    """

    #: a failed run: a joint-rate error of 100 rad/s (about 950 rpm): beyond the pendulum's motion
    divergence: ClassVar[DivergenceBound] = DivergenceBound("joint_rate", 100.0)

    model: FurutaConstants
    stick_band: Array
    stick_relaxation: Array
    noise_size: int = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True)
    position_layout: Layout = eqx.field(static=True)
    velocity_layout: Layout = eqx.field(static=True)

    def __init__(self, model: FurutaConstants, stick_band: ArrayLike = 0.02, stick_relaxation: ArrayLike = 1e-3):
        if not isinstance(model, FurutaConstants):
            raise check.ParameterError("model", f"model must be a FurutaConstants; got {type(model).__name__}")
        names, kinds = model.joint_names, model.joint_kinds
        self.model = model
        self.stick_band = _scalar("stick_band", stick_band)
        self.stick_relaxation = _scalar("stick_relaxation", stick_relaxation)
        self.noise_size = 0
        self.input_layout = joint_layout(names, kinds, JOINT_INPUT)
        self.position_layout = joint_layout(names, kinds, JOINT_POSITION)
        self.velocity_layout = joint_layout(names, kinds, JOINT_VELOCITY)
        self.variable_signals = (
            self.position_layout.signals
            + self.velocity_layout.signals
            + (Signal("arm_stuck_time", "s", "time the arm has spent sticking (Coulomb friction)"),)
        )

    def __check_init__(self):
        check.positive("stick_band", self.stick_band)
        check.positive("stick_relaxation", self.stick_relaxation)
        if check.is_concrete(self.model.coulomb_friction) and float(np.asarray(self.model.coulomb_friction)[1]) != 0.0:
            raise ValueError("model.coulomb_friction[1] (the pendulum's) must be 0: FurutaPlant models stick-slip on the arm only")

    def friction_torque(self, q: Array, qdot: Array, tau: Array) -> tuple[Array, Array]:
        """``(f, sticking)``: the arm's friction torque tau_F (entering as tau_u - tau_F, (6.3))
        and whether the arm sticks, by the rule of the module docstring."""
        model = self.model
        limit = model.coulomb_friction[0]
        h = model.coriolis_force(q, qdot) + model.friction * qdot + model.gravity(q)
        mass = model.mass_matrix(q)
        det = mass[0, 0] * mass[1, 1] - mass[0, 1] * mass[1, 0]
        inv_00, inv_01 = mass[1, 1] / det, -mass[0, 1] / det
        free = tau - h
        arm_free = inv_00 * free[0] + inv_01 * free[1]  # b = [M^-1 (tau - h)]_1

        def holding(target):  # f(a) = (b - a) / m
            return (arm_free - target) / inv_00

        at_rest = holding(0.0)
        slow = jnp.abs(qdot[0]) < self.stick_band
        sticking = slow & (jnp.abs(at_rest) <= limit)
        stick = jnp.clip(holding(-qdot[0] / self.stick_relaxation), -limit, limit)
        slip = limit * jnp.where(slow, jnp.sign(at_rest), jnp.sign(qdot[0]))
        return jnp.where(sticking, stick, slip), sticking

    def vector_field(self, t: ArrayLike, x: FurutaState, u: Array, w: Array) -> FurutaState:
        """(q', q'', stuck') of (6.1)–(6.4) with the stick-slip friction."""
        del t, w
        model = self.model
        f, sticking = self.friction_torque(x.q, x.qdot, u)
        force = u - model.coriolis_force(x.q, x.qdot) - model.friction * x.qdot - model.gravity(x.q)
        mass = model.mass_matrix(x.q)
        det = mass[0, 0] * mass[1, 1] - mass[0, 1] * mass[1, 0]
        force = force.at[0].add(-f)
        accel = jnp.array([mass[1, 1] * force[0] - mass[0, 1] * force[1], mass[0, 0] * force[1] - mass[1, 0] * force[0]]) / det
        return FurutaState(x.qdot, accel, sticking.astype(float))

    @initial_values(
        Value(
            "q",
            "array",
            "(phi, theta): arm and pendulum angles (rad; zeros when not given; an observer's guess takes it from the first measurement).",
            shape="(2,)",
        ),
        Value("qdot", "array", "Their rates (rad/s).", shape="(2,)"),
    )
    def state(self, q: npt.ArrayLike | None = None, qdot: npt.ArrayLike = 0.0) -> FurutaState:
        """A state of this plant, not sticking (zeros where not given): a composition's ``[plant.initial]``.

        Parameters
        ----------
        q : array_like, shape (2,), optional
            (phi, theta): arm and pendulum angles (rad; zeros when not given; an observer's guess takes it from the first measurement).
        qdot : array_like, shape (2,)
            Their rates (rad/s).
        """
        return FurutaState(
            jnp.asarray(check.vector("q", 0.0 if q is None else q, 2), dtype=float),
            jnp.asarray(check.vector("qdot", qdot, 2), dtype=float),
            jnp.asarray(0.0),
        )

    def models(self) -> tuple:
        """The model in its constants (friction included)."""
        return (self.model,)

    def normalize(self, x: FurutaState) -> FurutaState:
        """The identity: angles are not wrapped (an incremental encoder counts turns)."""
        return x

    def variables(self, x: FurutaState) -> dict[str, Array]:
        """``joint_angle``, ``joint_rate`` (over arm, pendulum) and ``arm_stuck_time``."""
        return {**self.position_layout.split(x.q), **self.velocity_layout.split(x.qdot), "arm_stuck_time": x.stuck_time}

    def realize(self, key: Array) -> FurutaPlant:
        """No randomness: the plant itself."""
        del key
        return self


__all__ = ["FurutaConstants", "FurutaPlant", "FurutaState", "PRINTED_CONSTANTS", "PRINTED_COULOMB_FRICTION"]
