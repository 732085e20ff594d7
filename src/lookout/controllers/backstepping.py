"""Observer backstepping for dynamic positioning: Kim (2002) with integral action
(:class:`ObserverBackstepping`) and the vectorial, adaptive form of Calugi, Robertsson
& Johansson (2003) (:class:`VectorialBackstepping`).

Kim (2002), Section 4.1, eqs. (18)–(26), after Aarset, Strand & Fossen (1998), with
the corrections derived in ``derivations-kim-calugi-2003.md`` (K3), each checked by
differentiating the error variables (below). Notation: e = eta_hat - eta_d (heading
through ``ssa``), integral state e_I with e_I' = e, J = J(y) built from the measured
heading::

    z1 = e + K_I e_I                                                       (18)
    alpha1 = -(C1 + D1) z1 + eta_d' - K_I e          (printed "-D1 z1'": a typo)
    z2 = J nu_hat - alpha1 = J nu_hat + (C1 + D1) z1 - eta_d' + K_I e
    z1' = -(C1 + D1) z1 + z2 + H2 y~ + Kbar sat                            (20)

Differentiating z2 along the observer (6) and J' = J S(mu), mu = [0, 0, r + psi_w']
(eq. 22; the printed "r + psi_w" adds rad/s to rad, and the printed "+" of the
estimation-error part has the wrong sign since S(a) b = -S(b) a)::

    z2' = J S(mu_hat) nu_hat + J M^-1 (-D nu_hat + tau + J^T b_hat)
          + (C1 + D1)(-(C1 + D1) z1 + z2) - eta_d'' + K_I (J nu_hat - eta_d')
          + Omega1 y~ + Omega2 nu~ + Omega3 xi~ + Omega4 sat                (24)

with Omega1 = J M^-1 J^T H4 + (C1 + D1 + K_I) H2, Omega2 = J q e3^T,
Omega3 = J q e3^T C_w A_w, Omega4 = (C1 + D1 + K_I) Kbar, q = [-v_hat, u_hat, 0].
The control law (25), tau = -(J M^-1)^-1 [Lambda + (C2 + D2) z2 + z1], with Lambda of
(23) read term by term (the printed "-J M^-1 nu_hat" is -J M^-1 D nu_hat and
"K_II nu_hat" is K_I J nu_hat), is then::

    tau = -M S(mu_hat) nu_hat + D nu_hat - J^T b_hat
          - M J^T [ z1 - (C1 + D1)^2 z1 + (C1 + D1 + C2 + D2) z2
                    + K_I (J nu_hat - eta_d') - eta_d'' ]

so that z2' = -(C2 + D2) z2 - z1 + (the Omega terms). The y~ and sat terms are not
cancelled (y~ is noisy); they are damped by the nonlinear damping
D1 = diag(d_i (|row_i H2|^2 + |row_i Kbar|^2)), i = 1..3, and
D2 = diag(d_{i+3} sum_k |row_i Omega_k|^2), evaluated at each sample. ("H1^T" in the
text under (20) is read as H2: the disturbances of (20) are H2 y~ and Kbar sat.)

With V_con = 1/2 |z|^2 + e_I^T K_I C1 e_I (29) and no estimation error,
V_con' = -e'^T C1 e' - e_I^T K_I C1 K_I e_I - z1^T D1 z1 - z2^T (C2 + D2) z2 <= 0
(the printed "+2 e_I^T K_I C1 e_I" of (30) is + 2 e_I^T K_I C1 e_I').

The coupling term (choice)
--------------------------
The z1 in (25) and -z1 in (26) come from V_con = 1/2 |z1|^2 + 1/2 |z2|^2, which adds
metres to metres per second: it hides a unit weight of 1 s^-2, and with the printed
C1 = C2 = 0.1 s^-1 the noise-free z-dynamics z1' = -C1 z1 + z2, z2' = -C2 z2 - z1 have
poles s^2 + (C1 + C2) s + C1 C2 + 1 = 0, a natural frequency of at least 1 rad/s
(damping 0.1 here), inside the wave band a DP controller must stay out of. This class
makes the weight explicit: ``coupling_gain`` P1 (diagonal, s^-2) with
V_con = 1/2 z1^T P1 z1 + 1/2 |z2|^2 + e_I^T K_I C1 P1 e_I, so that P1 z1 replaces z1
in (25) and -P1 z1 replaces -z1 in (26); the poles are then at
s^2 + (C1 + C2) s + C1 C2 + P1 = 0. P1 = 1 is Kim's law as printed (the default).

The controller works with any observer whose estimate gives ``position``,
``heading``, ``velocity``, ``yaw_rate``, ``bias_force``, ``bias_moment`` and
``wave_heading_rate`` (the passive and the sliding-mode observers do), and a
reference giving ``position_desired``, ``heading_desired`` and their ``_rate`` and
``_acceleration`` (:class:`~lookout.reference.ReferenceFilter`). The integral state
is advanced by forward Euler over the sample, e_I(k+1) = e_I(k) + dt e(k).
"""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import rotate, rotate_transpose, rotation, ssa
from lookout.components import Controller, Observer
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Value, component
from lookout.observers.adaptive_dp import AdaptiveObserver, InertiaParametrization
from lookout.observers.wave_filtering import WaveFilteringObserver

#: The estimate a DP controller reads: eta_hat and nu_hat.
VESSEL_ESTIMATE = ("position", "heading", "velocity", "yaw_rate")
#: The reference a DP tracking law reads: eta_d and its first two derivatives.
VESSEL_REFERENCE = tuple(f"{name}_desired{suffix}" for suffix in ("", "_rate", "_acceleration") for name in ("position", "heading"))


def _vector(estimate: dict, names: tuple[str, str]) -> Array:
    """``position``/``heading``-style pairs joined into a 3-vector."""
    first, second = names
    return jnp.concatenate([jnp.asarray(estimate[first]), jnp.asarray(estimate[second])[None]])


@component(
    "controller",
    "observer-backstepping",
    summary="Kim (2002) observer backstepping with integral action, eqs. (18)–(26).",
    family="lookout.tuning.families.positive:ObserverBacksteppingFamily",
    build="for_observer",
    parameters=(
        Part("observer", "The observer whose estimate the controller uses (in a composition, its observer)."),
        Value("integral_gain", "array", "K_I (1/s).", shape="(3,)", range=NON_NEGATIVE),
        Value("position_gain", "array", "C1 (1/s).", shape="(3,)", range=POSITIVE),
        Value("velocity_gain", "array", "C2 (1/s).", shape="(3,)", range=POSITIVE),
        Value("damping_weights", "array", "d1..d6 of the nonlinear damping D1 (d1..d3) and D2 (d4..d6) (s).", shape="(6,)", range=NON_NEGATIVE),
        Value("coupling_gain", "array", "P1 (1/s^2), the weight of z1 in V_con; 1 is Kim's law as printed.", shape="(3,)", range=POSITIVE),
    ),
)
@final
class ObserverBackstepping(Controller):
    """Kim (2002) observer backstepping with integral action, eqs. (18)–(26).

    Build it with :meth:`for_observer`, which takes the model and the injection gains
    that enter the nonlinear damping from the observer.

    Parameters
    ----------
    mass_matrix, damping_matrix : array_like, shape (3, 3)
        The controller's (and observer's) model M and D.
    integral_gain : array_like, shape (3,)
        K_I (1/s).
    position_gain, velocity_gain : array_like, shape (3,)
        C1 and C2 (1/s).
    coupling_gain : array_like, shape (3,)
        P1 (1/s^2), the weight of z1 in V_con; 1 is Kim's law as printed.
    damping_weights : array_like, shape (6,)
        d1..d6 of the nonlinear damping D1 (d1..d3) and D2 (d4..d6).
    position_injection_gain, velocity_injection_gain, switching_gain : array_like, shape (3,)
        H2, H4 and Kbar of the observer (diagonals); Kbar = 0 for the passive observer.
    wave_frequency, wave_damping : array_like, shape (3,)
        The observer's wave model (for Omega3).
    """

    mass_matrix: Array
    damping_matrix: Array
    mass_inverse: Array
    integral_gain: Array
    position_gain: Array
    velocity_gain: Array
    coupling_gain: Array
    damping_weights: Array
    position_injection_gain: Array
    velocity_injection_gain: Array
    switching_gain: Array
    wave_frequency: Array
    wave_damping: Array

    def __init__(
        self,
        mass_matrix: npt.ArrayLike,
        damping_matrix: npt.ArrayLike,
        *,
        integral_gain: npt.ArrayLike,
        position_gain: npt.ArrayLike,
        velocity_gain: npt.ArrayLike,
        damping_weights: npt.ArrayLike,
        position_injection_gain: npt.ArrayLike,
        velocity_injection_gain: npt.ArrayLike,
        switching_gain: npt.ArrayLike,
        wave_frequency: npt.ArrayLike,
        wave_damping: npt.ArrayLike,
        coupling_gain: npt.ArrayLike = 1.0,
    ):
        check.symmetric_positive_definite("mass_matrix", mass_matrix, size=3)
        check.square("damping_matrix", damping_matrix)
        self.mass_matrix = jnp.asarray(mass_matrix, dtype=float)
        self.damping_matrix = jnp.asarray(damping_matrix, dtype=float)
        self.mass_inverse = jnp.linalg.inv(self.mass_matrix)
        self.integral_gain = jnp.asarray(check.vector("integral_gain", integral_gain))
        self.position_gain = jnp.asarray(check.vector("position_gain (C1)", position_gain))
        self.velocity_gain = jnp.asarray(check.vector("velocity_gain (C2)", velocity_gain))
        self.coupling_gain = jnp.asarray(check.vector("coupling_gain (P1)", coupling_gain))
        self.damping_weights = jnp.asarray(check.vector("damping_weights (d1..d6)", damping_weights, 6))
        self.position_injection_gain = jnp.asarray(check.vector("position_injection_gain (H2)", position_injection_gain))
        self.velocity_injection_gain = jnp.asarray(check.vector("velocity_injection_gain (H4)", velocity_injection_gain))
        self.switching_gain = jnp.asarray(check.vector("switching_gain (Kbar)", switching_gain))
        self.wave_frequency = jnp.asarray(check.vector("wave_frequency", wave_frequency))
        self.wave_damping = jnp.asarray(check.vector("wave_damping", wave_damping))

    def __check_init__(self):
        check.positive("integral_gain", self.integral_gain, allow_zero=True)
        check.positive("position_gain (C1)", self.position_gain)
        check.positive("velocity_gain (C2)", self.velocity_gain)
        check.positive("coupling_gain (P1)", self.coupling_gain)
        check.positive("damping_weights (d1..d6)", self.damping_weights, allow_zero=True)
        check.finite("position_injection_gain (H2)", self.position_injection_gain)
        check.finite("velocity_injection_gain (H4)", self.velocity_injection_gain)
        check.positive("switching_gain (Kbar)", self.switching_gain, allow_zero=True)

    @classmethod
    def for_observer(
        cls,
        observer: WaveFilteringObserver,
        *,
        integral_gain: npt.ArrayLike,
        position_gain: npt.ArrayLike,
        velocity_gain: npt.ArrayLike,
        damping_weights: npt.ArrayLike,
        coupling_gain: npt.ArrayLike = 1.0,
    ) -> ObserverBackstepping:
        """The controller for a wave-filtering observer (passive, sliding-mode): M, D,
        H2, H4, Kbar and the wave model are taken from ``observer``.

        Parameters
        ----------
        observer : WaveFilteringObserver
            The observer whose estimate the controller uses (in a composition, its observer).
        integral_gain : array_like, shape (3,), non-negative
            K_I (1/s).
        position_gain : array_like, shape (3,), positive
            C1 (1/s).
        velocity_gain : array_like, shape (3,), positive
            C2 (1/s).
        damping_weights : array_like, shape (6,), non-negative
            d1..d6 of the nonlinear damping D1 (d1..d3) and D2 (d4..d6) (s).
        coupling_gain : array_like, shape (3,), positive
            P1 (1/s^2), the weight of z1 in V_con; 1 is Kim's law as printed.
        """
        if not isinstance(observer, WaveFilteringObserver):
            raise check.ParameterError(
                "observer", f"observer must be a wave-filtering observer (passive, sliding-mode); got {type(observer).__name__}"
            )
        gains = observer.wave_filter_gains()
        return cls(
            gains.mass_matrix,
            gains.damping_matrix,
            integral_gain=integral_gain,
            position_gain=position_gain,
            velocity_gain=velocity_gain,
            coupling_gain=coupling_gain,
            damping_weights=damping_weights,
            position_injection_gain=gains.position_injection_gain,
            velocity_injection_gain=gains.velocity_injection_gain,
            switching_gain=gains.switching_gain,
            wave_frequency=gains.wave_frequency,
            wave_damping=gains.wave_damping,
        )

    def follow(self, observer: Observer) -> ObserverBackstepping:
        """H2, H4, Kbar and the wave model taken again from ``observer`` (traceable), a
        wave-filtering observer (TypeError otherwise)."""
        if not isinstance(observer, WaveFilteringObserver):
            raise TypeError(f"observer backstepping follows a wave-filtering observer's gains; got {type(observer).__name__}")
        gains = observer.wave_filter_gains()
        return eqx.tree_at(
            lambda c: (c.position_injection_gain, c.velocity_injection_gain, c.switching_gain, c.wave_frequency, c.wave_damping),
            self,
            tuple(
                jnp.broadcast_to(jnp.asarray(v, dtype=float), (3,))
                for v in (
                    gains.position_injection_gain,
                    gains.velocity_injection_gain,
                    gains.switching_gain,
                    gains.wave_frequency,
                    gains.wave_damping,
                )
            ),
        )

    #: what the law reads (eqs. 18–26): the estimate with its wave motion, the measured
    #: heading, and the reference with two derivatives
    estimate_needs = property(lambda self: VESSEL_ESTIMATE + ("bias_force", "bias_moment", "wave_heading", "wave_heading_rate"))
    measurement_needs = property(lambda self: ("measured_heading",))
    reference_needs = property(lambda self: VESSEL_REFERENCE)

    def init(self) -> Array:
        """The integral state e_I = 0 (m, m, rad s)."""
        return jnp.zeros(3)

    def errors(self, integral: Array, y: Array, estimate: dict, reference: dict) -> dict[str, Array]:
        """e, z1, z2, alpha1 and the nonlinear damping D1, D2 at one sample (eqs. 18–20, 26)."""
        eta_hat = _vector(estimate, ("position", "heading"))
        nu_hat = _vector(estimate, ("velocity", "yaw_rate"))
        eta_d = _vector(reference, ("position_desired", "heading_desired"))
        eta_d_rate = _vector(reference, ("position_desired_rate", "heading_desired_rate"))
        heading_y = jnp.where(jnp.isfinite(y[2]), y[2], eta_hat[2] + estimate["wave_heading"])
        e = (eta_hat - eta_d).at[2].set(ssa(eta_hat[2] - eta_d[2]))
        k_i, h2, h4, kbar = self.integral_gain, self.position_injection_gain, self.velocity_injection_gain, self.switching_gain
        d = self.damping_weights
        d1 = d[:3] * (h2**2 + kbar**2)
        c1d1 = self.position_gain + d1
        z1 = e + k_i * integral
        z2 = rotate(heading_y, nu_hat) + c1d1 * z1 - eta_d_rate + k_i * e
        # nonlinear damping D2 from the rows of Omega1..Omega4 (eq. 26)
        j = rotation(heading_y)
        omega1 = j @ self.mass_inverse @ j.T * h4[None, :] + jnp.diag((c1d1 + k_i) * h2)
        q = jnp.stack([-nu_hat[1], nu_hat[0], 0.0])
        jq = rotate(heading_y, q)
        w3, zeta3 = self.wave_frequency[2], self.wave_damping[2]
        wave_row = w3**4 + (2.0 * zeta3 * w3) ** 2  # |e3^T C_w A_w|^2
        rows = jnp.sum(omega1**2, axis=1) + jq**2 * (1.0 + wave_row) + ((c1d1 + k_i) * kbar) ** 2
        d2 = d[3:] * rows
        return {"e": e, "z1": z1, "z2": z2, "d1": d1, "d2": d2, "heading_y": heading_y, "nu_hat": nu_hat}

    def lyapunov(self, integral: Array, y: Array, estimate: dict, reference: dict) -> Array:
        """V_con = 1/2 (z1^T P1 z1 + |z2|^2) + e_I^T K_I C1 P1 e_I of eq. (29) (P1 = 1 as printed)."""
        err = self.errors(integral, y, estimate, reference)
        p1 = self.coupling_gain
        return 0.5 * (jnp.sum(p1 * err["z1"] ** 2) + jnp.sum(err["z2"] ** 2)) + jnp.sum(
            integral * self.integral_gain * self.position_gain * p1 * integral
        )

    def step(
        self, integral: Array, t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[Array, Array]:
        """``(e_I(k+1), tau_k)``: the control law (25) at t_k."""
        del t
        err = self.errors(integral, y, estimate, reference)
        z1, z2, e, heading_y, nu_hat = err["z1"], err["z2"], err["e"], err["heading_y"], err["nu_hat"]
        c1d1 = self.position_gain + err["d1"]
        k_i = self.integral_gain
        b_hat = _vector(estimate, ("bias_force", "bias_moment"))
        eta_d_rate = _vector(reference, ("position_desired_rate", "heading_desired_rate"))
        eta_d_accel = _vector(reference, ("position_desired_acceleration", "heading_desired_acceleration"))
        # S(mu_hat) nu_hat with mu_hat_3 = r_hat + psi_w_hat' (eq. 22, corrected)
        mu3 = nu_hat[2] + estimate["wave_heading_rate"]
        s_mu_nu = mu3 * jnp.stack([-nu_hat[1], nu_hat[0], 0.0])
        bracket = (
            self.coupling_gain * z1
            - c1d1**2 * z1
            + (c1d1 + self.velocity_gain + err["d2"]) * z2
            + k_i * (rotate(heading_y, nu_hat) - eta_d_rate)
            - eta_d_accel
        )
        tau = (
            -self.mass_matrix @ s_mu_nu
            + self.damping_matrix @ nu_hat
            - rotate_transpose(heading_y, b_hat)
            - self.mass_matrix @ rotate_transpose(heading_y, bracket)
        )
        return integral + dt * e, tau

    def gains_table(self) -> dict[str, np.ndarray]:
        """K_I, C1, C2, P1 and d1..d6 as arrays (for reports)."""
        return {
            "K_I": np.asarray(self.integral_gain),
            "C1": np.asarray(self.position_gain),
            "C2": np.asarray(self.velocity_gain),
            "P1": np.asarray(self.coupling_gain),
            "d": np.asarray(self.damping_weights),
        }


@component(
    "controller",
    "vectorial-backstepping",
    summary="Calugi, Robertsson & Johansson (2003) vectorial observer backstepping, eqs. (24)–(40), with M_hat, D_hat, K_hat from the current parameter estimate theta_hat (Remark 3).",
    family="lookout.tuning.families.adaptive_dp:VectorialBacksteppingFamily",
    build="for_observer",
    parameters=(
        Part("observer", "The observer whose estimate (and theta_hat) the controller uses."),
        Value("position_gain", "array", "C1 (1/s).", shape="(3,)", range=POSITIVE),
        Value("velocity_gain", "array", "C2 (1/s).", shape="(3,)", range=POSITIVE),
        Value("damping_weights", "array", "d1..d6 (s).", shape="(6,)", range=POSITIVE),
        Value("coupling_gain", "array", "P1 (1/s^2), 1 as printed.", shape="(3,)", range=POSITIVE),
    ),
)
@final
class VectorialBackstepping(Controller):
    """Calugi, Robertsson & Johansson (2003) vectorial observer backstepping, eqs. (24)–(40),
    with M_hat, D_hat, K_hat from the current parameter estimate theta_hat (Remark 3).

    With z1 = eta_hat - eta_d (heading through ``ssa``), alpha1 = -(C1 + D1) z1 + eta_d'
    (27) and z2 = J(psi) nu_hat - alpha1 (25), the observer (13)–(14) gives
    z1' = -(C1 + D1) z1 + z2 + K1 eta~ (29) and, with J' = J S(rho) and
    S(rho~) nu_hat = T(nu_hat) nu~ (32)–(34)::

        z2' = J S(rho_hat) nu_hat + J T(nu_hat) nu~ + J M_hat^-1 (tau - D_hat nu_hat - K_hat eta_hat)
              + J K2 nu~ + (C1 + D1)(-(C1 + D1) z1 + z2 + K1 eta~) - eta_d''

    The control law (36), read as derived (derivations-kim-calugi-2003.md, C4: the
    reference term is -eta_d'', not -eta_d' (NOTES.md); the stiffness term is
    K_hat eta_hat, the only one that cancels -J M_hat^-1 K_hat eta_hat; T(nu_hat) has
    hats), is::

        tau = D_hat nu_hat + K_hat eta_hat - M_hat S(rho_hat) nu_hat
              - M_hat J^T [ P1 z1 - (C1 + D1)^2 z1 + (C1 + D1 + C2 + D2) z2 - eta_d'' ]

    so that z2' = -(C2 + D2) z2 - P1 z1 + Omega1 eta~ + Omega2 nu~ (37) with
    Omega1 = (C1 + D1) K1 (38) and Omega2 = J (T(nu_hat) + K2) (39);
    D1 = diag(d_i |k_i|^2) (28), k_i the rows of K1, and D2 = diag(d_{i+3}
    (|row_i Omega1|^2 + |row_i Omega2|^2)) (40), evaluated at each sample. P1 is the
    coupling weight of :class:`ObserverBackstepping` (1 s^-2 in the paper, where the
    z-loop then has poles at s^2 + (C1 + C2) s + C1 C2 + 1 = 0). J is built from the
    measured heading (eq. 24 uses J(eta)); when it is missing, from the estimate.

    Parameters
    ----------
    parametrization
        The observer's :class:`~lookout.observers.adaptive_dp.InertiaParametrization`
        (``matrices(theta)`` and ``names``); theta_hat is read from the estimate as
        ``theta_<name>``.
    observer_position_gain, observer_velocity_gain : array_like, shape (3,)
        K1 and K2 of the observer (diagonals, 1/s), for D1 and D2.
    position_gain, velocity_gain : array_like, shape (3,)
        C1 and C2 (1/s).
    damping_weights : array_like, shape (6,)
        d1..d6 (s).
    coupling_gain : array_like, shape (3,)
        P1 (1/s^2), 1 as printed.
    """

    parametrization: InertiaParametrization
    observer_position_gain: Array
    observer_velocity_gain: Array
    position_gain: Array
    velocity_gain: Array
    damping_weights: Array
    coupling_gain: Array

    def __init__(
        self,
        parametrization: InertiaParametrization,
        *,
        observer_position_gain: npt.ArrayLike,
        observer_velocity_gain: npt.ArrayLike,
        position_gain: npt.ArrayLike,
        velocity_gain: npt.ArrayLike,
        damping_weights: npt.ArrayLike,
        coupling_gain: npt.ArrayLike = 1.0,
    ):
        self.parametrization = parametrization
        self.observer_position_gain = jnp.asarray(check.vector("observer_position_gain (K1)", observer_position_gain))
        self.observer_velocity_gain = jnp.asarray(check.vector("observer_velocity_gain (K2)", observer_velocity_gain))
        self.position_gain = jnp.asarray(check.vector("position_gain (C1)", position_gain))
        self.velocity_gain = jnp.asarray(check.vector("velocity_gain (C2)", velocity_gain))
        self.damping_weights = jnp.asarray(check.vector("damping_weights (d1..d6)", damping_weights, 6))
        self.coupling_gain = jnp.asarray(check.vector("coupling_gain (P1)", coupling_gain))

    def __check_init__(self):
        check.positive("observer_position_gain (K1)", self.observer_position_gain)
        check.positive("observer_velocity_gain (K2)", self.observer_velocity_gain)
        check.positive("position_gain (C1)", self.position_gain)
        check.positive("velocity_gain (C2)", self.velocity_gain)
        check.positive("damping_weights (d1..d6)", self.damping_weights)
        check.positive("coupling_gain (P1)", self.coupling_gain)

    @classmethod
    def for_observer(
        cls,
        observer: AdaptiveObserver,
        *,
        position_gain: npt.ArrayLike,
        velocity_gain: npt.ArrayLike,
        damping_weights: npt.ArrayLike,
        coupling_gain: npt.ArrayLike = 1.0,
    ) -> VectorialBackstepping:
        """The controller for an :class:`~lookout.observers.AdaptiveObserver`: its
        parametrization and K1, K2 are taken from ``observer``.

        Parameters
        ----------
        observer : AdaptiveObserver
            The observer whose estimate (and theta_hat) the controller uses.
        position_gain : array_like, shape (3,), positive
            C1 (1/s).
        velocity_gain : array_like, shape (3,), positive
            C2 (1/s).
        damping_weights : array_like, shape (6,), positive
            d1..d6 (s).
        coupling_gain : array_like, shape (3,), positive
            P1 (1/s^2), 1 as printed.
        """
        if not isinstance(observer, AdaptiveObserver):
            raise check.ParameterError("observer", f"observer must be an AdaptiveObserver; got {type(observer).__name__}")
        return cls(
            observer.parametrization,
            observer_position_gain=observer.position_gain,
            observer_velocity_gain=observer.velocity_gain,
            position_gain=position_gain,
            velocity_gain=velocity_gain,
            damping_weights=damping_weights,
            coupling_gain=coupling_gain,
        )

    def follow(self, observer: Observer) -> VectorialBackstepping:
        """K1, K2 taken again from ``observer`` (traceable), an
        :class:`~lookout.observers.AdaptiveObserver` (TypeError otherwise)."""
        if not isinstance(observer, AdaptiveObserver):
            raise TypeError(f"vectorial backstepping follows an adaptive observer's gains; got {type(observer).__name__}")
        return eqx.tree_at(
            lambda c: (c.observer_position_gain, c.observer_velocity_gain),
            self,
            (
                jnp.broadcast_to(jnp.asarray(observer.position_gain, dtype=float), self.observer_position_gain.shape),
                jnp.broadcast_to(jnp.asarray(observer.velocity_gain, dtype=float), self.observer_velocity_gain.shape),
            ),
        )

    #: what the law (36) reads: the estimate and theta_hat, the measured heading, the reference
    estimate_needs = property(lambda self: VESSEL_ESTIMATE + tuple(f"theta_{name}" for name in self.parametrization.names))
    measurement_needs = property(lambda self: ("measured_heading",))
    reference_needs = property(lambda self: VESSEL_REFERENCE)

    def init(self) -> tuple[()]:
        """No internal state."""
        return ()

    def theta(self, estimate: dict) -> Array:
        """theta_hat from the estimate's ``theta_<name>`` entries."""
        return jnp.stack([jnp.asarray(estimate[f"theta_{name}"]) for name in self.parametrization.names])

    def errors(self, y: Array, estimate: dict, reference: dict) -> dict[str, Array]:
        """z1, z2 (eqs. 24–27), D1 (28) and D2 (40) at one sample."""
        eta_hat = _vector(estimate, ("position", "heading"))
        nu_hat = _vector(estimate, ("velocity", "yaw_rate"))
        eta_d = _vector(reference, ("position_desired", "heading_desired"))
        eta_d_rate = _vector(reference, ("position_desired_rate", "heading_desired_rate"))
        heading = jnp.where(jnp.isfinite(y[2]), y[2], eta_hat[2])
        k1, k2 = self.observer_position_gain, self.observer_velocity_gain
        d = self.damping_weights
        d1 = d[:3] * k1**2
        c1d1 = self.position_gain + d1
        z1 = (eta_hat - eta_d).at[2].set(ssa(eta_hat[2] - eta_d[2]))
        z2 = rotate(heading, nu_hat) + c1d1 * z1 - eta_d_rate
        t_matrix = jnp.array([[0.0, 0.0, -nu_hat[1]], [0.0, 0.0, nu_hat[0]], [0.0, 0.0, 0.0]])
        omega2 = rotation(heading) @ (t_matrix + jnp.diag(k2))
        d2 = d[3:] * ((c1d1 * k1) ** 2 + jnp.sum(omega2**2, axis=1))
        return {"z1": z1, "z2": z2, "d1": d1, "d2": d2, "heading": heading, "nu_hat": nu_hat, "eta_hat": eta_hat}

    def lyapunov(self, y: Array, estimate: dict, reference: dict) -> Array:
        """The controller's part 1/2 (z1^T P1 z1 + |z2|^2) of V in eq. (47)."""
        err = self.errors(y, estimate, reference)
        return 0.5 * (jnp.sum(self.coupling_gain * err["z1"] ** 2) + jnp.sum(err["z2"] ** 2))

    def step(
        self, state: tuple[()], t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[tuple[()], Array]:
        """``((), tau_k)``: the control law (36) at t_k with M_hat, D_hat, K_hat of theta_hat(k)."""
        del t, dt
        err = self.errors(y, estimate, reference)
        z1, z2, heading, nu_hat, eta_hat = err["z1"], err["z2"], err["heading"], err["nu_hat"], err["eta_hat"]
        c1d1 = self.position_gain + err["d1"]
        eta_d_accel = _vector(reference, ("position_desired_acceleration", "heading_desired_acceleration"))
        mass, damping, stiffness = self.parametrization.matrices(self.theta(estimate))
        s_rho_nu = nu_hat[2] * jnp.stack([-nu_hat[1], nu_hat[0], 0.0])  # S(rho_hat) nu_hat, (31)
        bracket = self.coupling_gain * z1 - c1d1**2 * z1 + (c1d1 + self.velocity_gain + err["d2"]) * z2 - eta_d_accel
        eta_wrapped = eta_hat.at[2].set(ssa(eta_hat[2]))
        tau = damping @ nu_hat + stiffness @ eta_wrapped - mass @ s_rho_nu - mass @ rotate_transpose(heading, bracket)
        return state, tau
