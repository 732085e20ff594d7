"""Tracking control of a ship at speed: Wondergem et al. (2009), eqs. (17)–(20) and (23).

Wondergem, M., Lefeber, E., Pettersen, K. Y. and Nijmeijer, H. (2009), "Output
feedback tracking of ships", Section 4. Errors (17), with R = J^T(e_psi)::

    e_eta = eta - eta_ref (heading through ssa),   e_nu = nu - R nu_ref,   e_r = r - r_ref

and the state-feedback controller (18) (Lindegaard's, without integral action)::

    tau = M [S^T(e_r) R nu_ref + R nu_ref'] + C(nu) nu + D_n(nu) + D R nu_ref
          - Kd e_nu - Kp J^T(psi) e_eta                                       (18)

which gives, with d/dt R = S^T(e_r) R, exactly (19)::

    e_eta' = J(psi) e_nu,    M e_nu' = -(D + Kd) e_nu - Kp J^T(psi) e_eta      (19)

Gains (20): M^-1 Kp = Omega^2, M^-1 (D + Kd) = 2 Lambda Omega, so that Kp = M Omega^2
and Kd = 2 M Lambda Omega - D, and each DOF of z = J^T e_eta obeys
z'' + 2 lambda_i omega_i z' + omega_i^2 z = 0 (checked in the tests). The paper's
example prints Omega = diag(0.72, 0.42, 0.64), Lambda = I (:mod:`lookout.papers.wondergem_2009`).

The output-feedback scheme (23) evaluates (18) on the observer's estimates
(derivations-wondergem-2009.md, section 3; the J(psi~) - I and S^T(r~) terms of (87)
confirm that psi_hat and the estimated rate error enter)::

    e_eta_hat = eta_hat - eta_ref,  e_psi_hat its heading,  R_hat = J^T(e_psi_hat)
    e_nu_hat = nu_hat - R_hat nu_ref,  e_r_hat = r_hat - r_ref
    tau = M [S^T(e_r_hat) R_hat nu_ref + R_hat nu_ref'] + C(nu_hat) nu_hat + D_n(nu_hat)
          + D R_hat nu_ref - Kd e_nu_hat - Kp J^T(psi_hat) e_eta_hat          (23)

The printed S^T(psi_hat') is read as S^T(e_r_hat) = S^T(r_hat - r_ref): S^T(r_hat)
would break (19). The reference is given Earth-fixed (eta_ref, eta_ref', eta_ref''),
as :class:`lookout.reference.EllipseReference` and :class:`ReferenceFilter` give it;
then nu_ref = J^T(psi_ref) eta_ref' (so that e_eta' = J(psi) e_nu, which (19) needs)
and nu_ref' = J^T(psi_ref) eta_ref'' + S^T(r_ref) nu_ref, r_ref = psi_ref'.
"""

from __future__ import annotations

from typing import final

import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec, rotate_transpose, ssa
from lookout.components import Controller
from lookout.declare import POSITIVE, Part, Rule, Value, component
from lookout.models.cybership import Cybership, skew
from lookout.observers.earth_fixed import WONDERGEM_RULE_VALUES


def _vector(values: dict, first: str, second: str) -> Array:
    return jnp.concatenate([jnp.asarray(values[first]), jnp.asarray(values[second])[None]])


#: The reference the law reads: eta_ref and its first two derivatives.
REFERENCE_NEEDS = tuple(f"{name}_desired{suffix}" for suffix in ("", "_rate", "_acceleration") for name in ("position", "heading"))


def reference_velocity(reference: dict) -> tuple[Array, Array, Array]:
    """``(eta_ref, nu_ref, nu_ref')`` from an Earth-fixed reference sample:
    nu_ref = J^T(psi_ref) eta_ref', nu_ref' = J^T(psi_ref) eta_ref'' + S^T(r_ref) nu_ref."""
    eta_ref = _vector(reference, "position_desired", "heading_desired")
    rate = _vector(reference, "position_desired_rate", "heading_desired_rate")
    acceleration = _vector(reference, "position_desired_acceleration", "heading_desired_acceleration")
    psi_ref = eta_ref[2]
    nu_ref = rotate_transpose(psi_ref, rate)
    nu_ref_rate = rotate_transpose(psi_ref, acceleration) + matvec(skew(nu_ref[2]).T, nu_ref)
    return eta_ref, nu_ref, nu_ref_rate


@component(
    "controller",
    "tracking",
    summary="The tracking law (18), evaluated on the estimate as the scheme (23) does.",
    family="lookout.tuning.families.tracking:TrackingFamily",
    rules={
        "gains": Rule(
            None,
            (
                Part("ship", "The controller's model (M, C, D, D_n); linear damping only in the basin scheme."),
                Value(
                    "natural_frequency",
                    "array",
                    "Omega (rad/s) of (20): the natural frequencies of the error dynamics (19).",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value(
                    "damping_ratio",
                    "array",
                    "Lambda of (20): the relative damping of the error dynamics (19) (1: critically damped).",
                    shape="(3,)",
                    range=POSITIVE,
                ),
            ),
        ),
        "wondergem-2009": Rule(
            "design",
            (
                Part("ship", "The controller's model (M, C, D, D_n); in a composition, the plant's ship model (else the observer's) unless given."),
                *WONDERGEM_RULE_VALUES,
            ),
        ),
    },
)
@final
class TrackingController(Controller):
    """The tracking law (18), evaluated on the estimate as the scheme (23) does.

    Given the plant's true state as the estimate (an oracle observer) it is the
    state-feedback controller (18); given an observer's estimate, the output-feedback
    scheme (23).

    Parameters
    ----------
    ship : Cybership
        The controller's model (M, C, D, D_n); linear damping only in the basin scheme.
        In a composition, the plant's ship model (else the observer's) unless given.
    natural_frequency : array_like, shape (3,), positive
        Omega (rad/s) of (20): the natural frequencies of the error dynamics (19).
    damping_ratio : array_like, shape (3,), positive
        Lambda of (20): the relative damping of the error dynamics (19) (1: critically damped).
    """

    ship: Cybership
    natural_frequency: Array
    damping_ratio: Array

    def __init__(self, ship: Cybership, natural_frequency: npt.ArrayLike, damping_ratio: npt.ArrayLike = 1.0):
        if not isinstance(ship, Cybership):
            raise check.ParameterError("ship", f"ship must be a Cybership; got {type(ship).__name__}")
        self.ship = ship
        self.natural_frequency = jnp.asarray(check.vector("natural_frequency (Omega)", natural_frequency))
        self.damping_ratio = jnp.asarray(check.vector("damping_ratio (Lambda)", damping_ratio))

    def __check_init__(self):
        check.positive("natural_frequency (Omega)", self.natural_frequency)
        check.positive("damping_ratio (Lambda)", self.damping_ratio)

    @classmethod
    def design(
        cls,
        ship: Cybership,
        *,
        reference_position: npt.ArrayLike,
        reference_velocity: npt.ArrayLike,
        reference_yaw_rate_max: float,
        reference_speed_max: float,
        reference_acceleration_max: float,
        start_position: npt.ArrayLike,
        start_velocity: npt.ArrayLike = 0.0,
        estimate_position: npt.ArrayLike | None = None,
        estimate_velocity: npt.ArrayLike = 0.0,
        damping_ratio: float = 1.0,
        velocity_bound: float = 0.3,
        margin: float = 1.1,
    ) -> TrackingController:
        """The scheme (23) for ``ship`` with Omega = omega I and Lambda = ``damping_ratio`` I
        from Wondergem et al. (2009)'s gain tuning procedure (steps 1–7 after Prop. 3.3),
        Kp = M Omega^2 and Kd = 2 M Lambda Omega - D by (24).

        omega is the smallest-L1 choice of a 1 % grid where an eps3 satisfies (27) (so (25),
        (21) hold), with the observer gains L1, L2 that satisfy (29)–(33) chosen with it
        (:func:`lookout.analysis.tracking.propose_wondergem_2009`): the observer's rule of
        the same name, given the same reference and start, takes the L1, L2 of the same
        proposal (:func:`lookout.analysis.tracking.wondergem_2009_gains`), and the pair
        satisfies (25), Prop. 3.1 ((10)–(15)) and Prop. 3.3 ((27)–(37)) at that start.
        Uniform Omega keeps kappa_r = 1: the gap in (81) does not arise.

        Parameters
        ----------
        ship : Cybership
            The controller's model (M, C, D, D_n); in a composition, the plant's ship model
            (else the observer's) unless given.
        reference_position : array_like, shape (3,)
            eta_ref(0): the reference's position north, east (m) and heading (rad) at t_0.
        reference_velocity : array_like, shape (3,)
            nu_ref(0): the reference's body-frame velocity surge, sway (m/s) and yaw rate (rad/s) at t_0.
        reference_yaw_rate_max : float, non-negative
            r_ref^max, the largest |r_ref| of the reference (rad/s).
        reference_speed_max : float, non-negative
            sup ||nu_ref|| of the reference (m/s and rad/s in one norm, as the paper's).
        reference_acceleration_max : float, non-negative
            sup ||nu_ref'|| of the reference (m/s^2 and rad/s^2 in one norm), its smooth part.
        start_position : array_like, shape (3,)
            eta(0): the ship's initial position north, east (m) and heading (rad).
        start_velocity : array_like, shape (3,)
            nu(0): the ship's initial body-frame velocity (m/s, m/s, rad/s).
        estimate_position : array_like, shape (3,), optional
            eta_hat(0), the observer's initial position estimate (m, m, rad); default
            ``start_position``, the estimate started at the measurement.
        estimate_velocity : array_like, shape (3,)
            v_hat(0) = eta_hat'(0), the initial Earth-frame velocity estimate (m/s, m/s, rad/s).
        damping_ratio : float, positive
            lambda of Lambda = lambda I, the relative damping of the error dynamics (19) (1).
        velocity_bound : float, non-negative
            V_M of Prop. 3.1, a bound on the ship's speed ||eta'|| (m/s).
        margin : float, in (1, inf)
            Factor by which L1 and L2 exceed their largest lower bound (1).
        """
        from lookout.analysis.tracking import wondergem_2009_gains

        proposal = wondergem_2009_gains(
            ship,
            reference_position=reference_position,
            reference_velocity=reference_velocity,
            reference_yaw_rate_max=reference_yaw_rate_max,
            reference_speed_max=reference_speed_max,
            reference_acceleration_max=reference_acceleration_max,
            start_position=start_position,
            start_velocity=start_velocity,
            estimate_position=estimate_position,
            estimate_velocity=estimate_velocity,
            damping_ratio=damping_ratio,
            velocity_bound=velocity_bound,
            margin=margin,
        )
        return cls(ship, proposal.natural_frequency, proposal.damping_ratio)

    @property
    def stiffness_gain(self) -> Array:
        """Kp = M Omega^2 (20)."""
        return self.ship.mass_matrix * (self.natural_frequency**2)[None, :]

    @property
    def damping_gain(self) -> Array:
        """Kd = 2 M Lambda Omega - D (20), with D the model's linear damping."""
        return 2.0 * self.ship.mass_matrix * (self.damping_ratio * self.natural_frequency)[None, :] - self.ship.damping_matrix

    #: what (23) reads: eta_hat, nu_hat and the reference velocity with its derivative
    estimate_needs = property(lambda self: ("position", "heading", "velocity", "yaw_rate"))
    measurement_needs = property(lambda self: ())
    reference_needs = property(lambda self: REFERENCE_NEEDS)

    def init(self) -> tuple[()]:
        """No internal state."""
        return ()

    def errors(self, estimate: dict, reference: dict) -> dict[str, Array]:
        """The errors (17) of the estimate: e_eta, e_nu, e_r, and R = J^T(e_psi), nu_ref, nu_ref'."""
        eta_ref, nu_ref, nu_ref_rate = reference_velocity(reference)
        eta = _vector(estimate, "position", "heading")
        nu = _vector(estimate, "velocity", "yaw_rate")
        e_eta = (eta - eta_ref).at[2].set(ssa(eta[2] - eta_ref[2]))
        R_nu_ref = rotate_transpose(e_eta[2], nu_ref)
        return {
            "e_eta": e_eta,
            "e_nu": nu - R_nu_ref,
            "e_r": nu[2] - nu_ref[2],
            "eta": eta,
            "nu": nu,
            "R_nu_ref": R_nu_ref,
            "R_nu_ref_rate": rotate_transpose(e_eta[2], nu_ref_rate),
        }

    def step(
        self, state: tuple[()], t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[tuple[()], Array]:
        """``((), tau_k)``: (23) at t_k."""
        del t, y, dt
        e = self.errors(estimate, reference)
        ship, nu = self.ship, e["nu"]
        feedforward = matvec(ship.mass_matrix, matvec(skew(e["e_r"]).T, e["R_nu_ref"]) + e["R_nu_ref_rate"])
        model = matvec(ship.coriolis(nu), nu) + ship.nonlinear_damping(nu) + matvec(ship.damping_matrix, e["R_nu_ref"])
        feedback = matvec(self.damping_gain, e["e_nu"]) + matvec(self.stiffness_gain, rotate_transpose(e["eta"][2], e["e_eta"]))
        return state, feedforward + model - feedback

    def gains_table(self) -> dict[str, np.ndarray]:
        """Kp and Kd of (20) as NumPy arrays."""
        return {"Kp": np.asarray(self.stiffness_gain), "Kd": np.asarray(self.damping_gain)}


__all__ = ["TrackingController", "reference_velocity"]
