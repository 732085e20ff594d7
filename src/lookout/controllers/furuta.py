"""Observer backstepping of the Furuta pendulum's angle alone (Calugi 2002, chapter 6).

Calugi (2002), master thesis, Lund, eqs. (6.5)–(6.11), read as derived in
derivations-thesis-ch3-6.md (ch. 6). Only theta (the pendulum, joint 2) is controlled;
the arm is left to its zero dynamics. On q (the observer's joint angles), x1_hat (its
joint rates), theta_hat (its parameter estimates) and the reference theta_d, theta_d',
theta_d''::

    z1 = theta - theta_d                                                          (6.5)
    z2 = x1_hat_2 - theta_d' + (c1 + d1) z1                                       (6.6)
    v  = -(c1 + d1) (z2 - (c1 + d1) z1) + theta_d'' - (c2 + d2) z2 - z1
    tau_net = (v - [M_hat^-1 (-C(q, x1_hat) x1_hat - G)]_2) / [M_hat^-1]_21
    tau_u = tau_C_hat sgn(x1_hat_1) + tau_net                                     (6.9)–(6.11)

with M_hat = M(q; theta_hat) (in Exp. III alpha_hat enters M_hat; (6.9) and (6.10) print M
for M_hat because their M is known) and [M_hat^-1]_21 = -gamma cos theta / det M_hat
(singular at theta = +-pi/2, and of the wrong sign where det M_hat < 0). Derivation: the
observer's psi = M_hat^-1 (e1 (tau_u - tau_C_hat sgn x1_hat_1) - C x1_hat - G) (4.5) has
psi_2 = [M_hat^-1]_21 tau_net + [M_hat^-1 (-C x1_hat - G)]_2 = v, so the observer's
x1_hat_2 moves as v + k2 x1~_2 and, with z1' = z2 - (c1 + d1) z1 + x1~_2 (6.7),

    z2' = -(c2 + d2) z2 - z1 + (c1 + d1 + k2) x1~_2                               (6.8)

(the thesis's (6.8) reads "x2'" for z2' and x1~ for x1~_2: garbles). With exact velocity
and parameters (x1~ = 0) the pendulum channel is z2' = -(c2 + d2) z2 - z1 (tested). d2 is
a scalar gain here, not (5.12). In code, tau_u is computed in one piece,
tau_u = (v + [M_hat^-1 h]_2) / [M_hat^-1]_21 with h = C x1_hat + F x1_hat + tau_C_hat sgn(x1_hat) + G
(the model's own friction), which equals (6.9)–(6.11) when the Coulomb friction is on the
arm only: [M_hat^-1 e1]_2 tau_C_hat sgn = [M_hat^-1]_21 tau_C_hat sgn.
"""

from __future__ import annotations

from typing import final

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec
from lookout.components import Controller
from lookout.declare import POSITIVE, Part, Value, component
from lookout.models.parameters import AffineParameters
from lookout.observers.adaptive_manipulator import estimate_names, read_estimate

#: The reference signal the controller reads: ``<name>_desired`` (rad), ``_rate``, ``_acceleration``.
PENDULUM_REFERENCE = "pendulum_angle"


def _gain(name: str, value) -> Array:
    array = jnp.asarray(value, dtype=float)
    if array.ndim != 0:
        raise check.ParameterError(check.key(name), f"{name} must be a scalar; got shape {array.shape}")
    return array


@component(
    "controller",
    "furuta-backstepping",
    summary="Calugi (2002) ch. 6: the pendulum-angle law (6.9)–(6.11) on the observer's estimates.",
    parameters=(
        Part("parameters", "The model (a lookout.models.furuta.FurutaConstants) and its unknowns, as the observer's."),
        Value("position_gain", "float", "c1 of (6.6) (1/s); the thesis's 10.", range=POSITIVE),
        Value("position_damping", "float", "d1 of (6.6) (1/s); the thesis's 1.", range=POSITIVE),
        Value("velocity_gain", "float", "c2 of (6.9)–(6.11) (1/s); the thesis's 10.", range=POSITIVE),
        Value("velocity_damping", "float", "d2 of (6.9)–(6.11) (1/s); the thesis's 2 in experiment I, 1 in II–IV.", range=POSITIVE),
    ),
)
@final
class FurutaPendulumBackstepping(Controller):
    """Calugi (2002) ch. 6: the pendulum-angle law (6.9)–(6.11) on the observer's estimates.

    Reads q from the estimate's ``joint_angle``, x1_hat from ``joint_rate`` and theta_hat
    from ``<name>_hat`` (:func:`~lookout.observers.adaptive_manipulator.theta_signal_name`)
    of an :class:`~lookout.observers.adaptive_manipulator.AdaptiveManipulatorObserver`; the
    reference from ``pendulum_angle_desired`` (``_rate``, ``_acceleration``) of a
    :class:`~lookout.reference.ReferenceFilter` over a scalar, unwrapped ``pendulum_angle``
    signal (the hanging reference lives near pi, where a wrapped one would jump by 2 pi).
    Outputs (tau_u, 0): the pendulum is unactuated.

    Parameters
    ----------
    parameters : AffineParameters
        The model (a :class:`~lookout.models.furuta.FurutaConstants`) and its unknowns, as
        the observer's.
    position_gain : float, positive
        c1 of (6.6) (1/s); the thesis's 10.
    position_damping : float, positive
        d1 of (6.6) (1/s); the thesis's 1.
    velocity_gain : float, positive
        c2 of (6.9)–(6.11) (1/s); the thesis's 10.
    velocity_damping : float, positive
        d2 of (6.9)–(6.11) (1/s); the thesis's 2 in experiment I, 1 in II–IV.
    """

    parameters: AffineParameters
    position_gain: Array
    position_damping: Array
    velocity_gain: Array
    velocity_damping: Array

    def __init__(
        self,
        parameters: AffineParameters,
        position_gain: ArrayLike,
        position_damping: ArrayLike,
        velocity_gain: ArrayLike,
        velocity_damping: ArrayLike,
    ):
        if not isinstance(parameters, AffineParameters):
            raise check.ParameterError("parameters", f"parameters must be an AffineParameters; got {type(parameters).__name__}")
        model = parameters.model(parameters.reference)
        if model.size != 2:
            raise check.ParameterError("parameters", f"parameters must describe a two-joint (arm, pendulum) model; got {model.size} joints")
        self.parameters = parameters
        self.position_gain = _gain("position_gain c1", position_gain)
        self.position_damping = _gain("position_damping d1", position_damping)
        self.velocity_gain = _gain("velocity_gain c2", velocity_gain)
        self.velocity_damping = _gain("velocity_damping d2", velocity_damping)

    def __check_init__(self):
        for name, value in (
            ("position_gain c1", self.position_gain),
            ("position_damping d1", self.position_damping),
            ("velocity_gain c2", self.velocity_gain),
            ("velocity_damping d2", self.velocity_damping),
        ):
            check.positive(name, value)

    #: what (6.9)–(6.11) read: the estimate's q, x1_hat and theta_hat, the pendulum's reference
    estimate_needs = property(lambda self: estimate_names(self.parameters))
    measurement_needs = property(lambda self: ())
    reference_needs = property(lambda self: tuple(f"{PENDULUM_REFERENCE}_desired{s}" for s in ("", "_rate", "_acceleration")))

    def errors(self, q: Array, velocity: Array, reference: dict) -> tuple[Array, Array]:
        """(z1, z2) of (6.5)–(6.6)."""
        first = self.position_gain + self.position_damping
        z1 = q[1] - reference[f"{PENDULUM_REFERENCE}_desired"]
        z2 = velocity[1] - reference[f"{PENDULUM_REFERENCE}_desired_rate"] + first * z1
        return z1, z2

    def virtual_acceleration(self, q: Array, velocity: Array, reference: dict) -> Array:
        """v: the pendulum acceleration that gives z2' = -(c2 + d2) z2 - z1."""
        first = self.position_gain + self.position_damping
        second = self.velocity_gain + self.velocity_damping
        z1, z2 = self.errors(q, velocity, reference)
        return -first * (z2 - first * z1) + reference[f"{PENDULUM_REFERENCE}_desired_acceleration"] - second * z2 - z1

    def law(self, q: Array, velocity: Array, theta: Array, reference: dict) -> Array:
        """tau_u of (6.9)–(6.11) (see the module docstring for the one-piece form)."""
        model = self.parameters.model(theta)
        mass = model.mass_matrix(q)
        det = mass[0, 0] * mass[1, 1] - mass[0, 1] * mass[1, 0]
        inverse = jnp.array([[mass[1, 1], -mass[0, 1]], [-mass[1, 0], mass[0, 0]]]) / det
        h = model.coriolis_force(q, velocity) + model.friction_force(velocity) + model.gravity(q)
        v = self.virtual_acceleration(q, velocity, reference)
        return (v + matvec(inverse, h)[1]) / inverse[1, 0]

    def init(self) -> tuple[()]:
        """No internal state."""
        return ()

    def step(
        self, state: tuple[()], t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[tuple[()], Array]:
        """``((), (tau_u, 0))`` from the estimate's q, x1_hat and theta_hat."""
        del t, y, dt
        q, velocity, theta = read_estimate(estimate, self.parameters)
        tau = self.law(q, velocity, theta, reference)
        return state, jnp.stack([tau, jnp.zeros_like(tau)])


__all__ = ["FurutaPendulumBackstepping", "PENDULUM_REFERENCE"]
