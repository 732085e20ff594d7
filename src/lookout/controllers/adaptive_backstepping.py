"""Adaptive observer backstepping for manipulators with unknown parameters.

Calugi (2002), master thesis, Lund, chapter 5, eqs. (5.9)–(5.12), read as derived in
derivations-thesis-ch3-6.md (ch. 5). On the measured q, the adaptive observer's x1_hat
and theta_hat (:class:`~lookout.observers.adaptive_manipulator.AdaptiveManipulatorObserver`)
and the reference q_d, q_d', q_d''::

    z1 = q - q_d,     alpha1 = -(C1 + D1) z1 + q_d',     z2 = x1_hat - alpha1
    v  = -(C1 + D1)^2 z1 + (C1 + D1) z2 - q_d'' + (C2 + D2) z2 + z1
    tau = -M_hat v + C_hat(q, x1_hat) x1_hat + F_hat x1_hat + G_hat(q)                        (5.9)

with M_hat = M(q; theta_hat) (likewise C_hat, F_hat, G_hat; F is the viscous friction
lookout keeps apart from C), C1, C2 > 0 diagonal, D1 = diag(d_1..d_n),
Omega = C1 + D1 + K (5.11) and D2 = diag(d_{n+i} |omega_i|^2), omega_i the i-th row of
Omega (5.12), d_i > 0 for i = 1..2n. The observer's psi is then -v exactly, and with
x1~ = q' - x1_hat the closed loop is::

    z1' = -(C1 + D1) z1 + z2 + x1~,       z2' = -(C2 + D2) z2 - z1 + Omega x1~

(the skew coupling's sign is E = [[0, I], [-I, 0]] here; the thesis's (5.16) prints the
opposite, which is harmless because E is skew either way). The (5.28) condition is in
:func:`lookout.analysis.adaptive_manipulator.check_5_28`.
"""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec
from lookout.components import Controller, Layout
from lookout.declare import POSITIVE, Part, Value, component
from lookout.models.manipulators import JOINT_POSITION, joint_layout
from lookout.models.parameters import AffineParameters
from lookout.observers.adaptive_manipulator import estimate_names, read_estimate


@component(
    "controller",
    "adaptive-backstepping",
    summary="Calugi (2002) ch. 5: the control law (5.9) on the adaptive observer's estimates.",
    parameters=(
        Part("parameters", "The model and its unknowns, as the observer's."),
        Value("observer_gain", "array", "K of the observer (1/s), for Omega (5.11).", shape="(n,)", range=POSITIVE),
        Value("position_gain", "array", "C1 of (5.9) (1/s).", shape="(n,)", range=POSITIVE),
        Value("velocity_gain", "array", "C2 of (5.9) (1/s).", shape="(n,)", range=POSITIVE),
        Value(
            "damping_weights",
            "array",
            "d_1..d_2n: D1 = diag(d_1..d_n) (1/s) and D2 = diag(d_{n+i} |omega_i|^2) of (5.12).",
            shape="(2n,)",
            range=POSITIVE,
        ),
    ),
)
@final
class AdaptiveObserverBackstepping(Controller):
    """Calugi (2002) ch. 5: the control law (5.9) on the adaptive observer's estimates.

    Reads q as the observer's joint position (the measurement, or the observer's
    prediction of a missing sample), x1_hat as the plant's joint velocity signal and theta_hat as
    ``<name>_hat`` from the estimate, and q_d, q_d', q_d'' as
    ``joint_angle_desired`` (``_rate``, ``_acceleration``) from the reference (a
    :class:`~lookout.reference.ReferenceFilter` over the joint-angle signal).

    Parameters
    ----------
    parameters : AffineParameters
        The model and its unknowns, as the observer's.
    observer_gain : float or array_like, shape (n,), positive
        K of the observer (1/s), for Omega (5.11).
    position_gain : float or array_like, shape (n,), positive
        C1 of (5.9) (1/s).
    velocity_gain : float or array_like, shape (n,), positive
        C2 of (5.9) (1/s).
    damping_weights : float or array_like, shape (2n,), positive
        d_1..d_2n: D1 = diag(d_1..d_n) (1/s) and D2 = diag(d_{n+i} |omega_i|^2) of (5.12).
    """

    parameters: AffineParameters
    observer_gain: Array
    position_gain: Array
    velocity_gain: Array
    damping_weights: Array
    position_layout: Layout = eqx.field(static=True)

    def __init__(
        self,
        parameters: AffineParameters,
        observer_gain: npt.ArrayLike,
        position_gain: npt.ArrayLike,
        velocity_gain: npt.ArrayLike,
        damping_weights: npt.ArrayLike,
    ):
        if not isinstance(parameters, AffineParameters):
            raise check.ParameterError("parameters", f"parameters must be an AffineParameters; got {type(parameters).__name__}")
        model = parameters.model(parameters.reference)
        n = model.size
        self.parameters = parameters
        self.observer_gain = jnp.asarray(check.vector("observer gain K", observer_gain, n))
        self.position_gain = jnp.asarray(check.vector("position_gain C1", position_gain, n))
        self.velocity_gain = jnp.asarray(check.vector("velocity_gain C2", velocity_gain, n))
        self.damping_weights = jnp.asarray(check.vector("damping_weights d", damping_weights, 2 * n))
        self.position_layout = joint_layout(model.joint_names, model.joint_kinds, JOINT_POSITION)

    def __check_init__(self):
        for name, value in (
            ("observer gain K", self.observer_gain),
            ("position_gain C1", self.position_gain),
            ("velocity_gain C2", self.velocity_gain),
            ("damping_weights d", self.damping_weights),
        ):
            check.positive(name, value)

    #: what (5.9) reads: q, x1_hat and theta_hat, and the joints' reference with two derivatives
    estimate_needs = property(lambda self: estimate_names(self.parameters))
    measurement_needs = property(lambda self: ())
    reference_needs = property(lambda self: tuple(f"{n}_desired{s}" for s in ("", "_rate", "_acceleration") for n in self.position_layout.names))

    @property
    def size(self) -> int:
        return self.position_gain.shape[0]

    def gains(self) -> tuple[Array, Array]:
        """(C1 + D1, C2 + D2) as vectors (diagonals): D1 = diag(d_1..d_n) and
        D2 = diag(d_{n+i} |omega_i|^2), Omega = C1 + D1 + K diagonal, so |omega_i|^2 = Omega_ii^2."""
        n = self.size
        first = self.position_gain + self.damping_weights[:n]
        omega = first + self.observer_gain
        return first, self.velocity_gain + self.damping_weights[n:] * omega**2

    def errors(self, q: Array, velocity: Array, reference: dict) -> tuple[Array, Array, Array]:
        """(z1, z2, q_d'')."""
        layout = self.position_layout
        q_d = layout.join({s.name: reference[f"{s.name}_desired"] for s in layout.signals})
        q_d_rate = layout.join({s.name: reference[f"{s.name}_desired_rate"] for s in layout.signals})
        q_d_accel = layout.join({s.name: reference[f"{s.name}_desired_acceleration"] for s in layout.signals})
        first, _ = self.gains()
        z1 = q - q_d
        alpha1 = -first * z1 + q_d_rate
        return z1, velocity - alpha1, q_d_accel

    def law(self, q: Array, velocity: Array, theta: Array, reference: dict) -> Array:
        """tau of (5.9)."""
        z1, z2, q_d_accel = self.errors(q, velocity, reference)
        first, second = self.gains()
        v = -(first**2) * z1 + first * z2 - q_d_accel + second * z2 + z1
        model = self.parameters.model(theta)
        return -matvec(model.mass_matrix(q), v) + model.coriolis_force(q, velocity) + model.friction_force(velocity) + model.gravity(q)

    def init(self) -> tuple[()]:
        """No internal state."""
        return ()

    def step(
        self, state: tuple[()], t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[tuple[()], Array]:
        """``((), tau_k)`` from q_k, x1_hat_k and theta_hat_k of the estimate."""
        del t, y, dt
        q, velocity, theta = read_estimate(estimate, self.parameters)
        return state, self.law(q, velocity, theta, reference)


__all__ = ["AdaptiveObserverBackstepping"]
