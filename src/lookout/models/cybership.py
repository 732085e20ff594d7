"""Cybership II, the 1:70 model supply ship of Wondergem et al. (2009), eq. (39).

Wondergem, M., Lefeber, E., Pettersen, K. Y. and Nijmeijer, H. (2009), "Output
feedback tracking of ships", report (IEEE TCST 19(2), 2011). Body-fixed model (16)::

    eta' = J(psi) nu
    M nu' + C(nu) nu + D nu + D_n(nu) = tau                                   (16)

with (39) as printed::

    M    = [[25.8, 0, 0], [0, 33.8, 1.0115], [0, 1.0115, 2.76]]
    C(nu) = [[0, 0, -33.8 v - 1.0115 r], [0, 0, 25.8 u], [33.8 v + 1.0115 r, -25.8 u, 0]]
    D(nu) = [[0.72 + 1.33|u|, 0, 0], [0, 0.86 + 36.28|v|, -0.11], [0, -0.11 - 5.04|v|, 0.5]]

so D(nu) nu = D nu + D_n(nu) with the linear D = D(0) and
D_n(nu) = [1.33 |u| u, 36.28 |v| v, -5.04 |v| v]. C(nu) is the rigid-body plus
added-mass Coriolis matrix of this M (Y_r' = N_v' = 0): with m_ij the entries of M,
C(nu) = [[0, 0, -(m22 v + m23 r)], [0, 0, m11 u], [m22 v + m23 r, -m11 u, 0]], which
reproduces the printed numbers and is skew-symmetric for every nu.

(39) is kept as printed. The widely copied data set of Skjetne et al. (2004) differs
(m23 = 1.0948 from x_g = 0.046 m, and other sway/yaw damping); only X_u and X_|u|u
agree (derivations-wondergem-2009.md, section 1). It is a different plant.

Earth-fixed form (1)–(2) (Fossen's kinematic transformation), for the observer and
the proof's bounds: with eta' = J nu, nu' = J^T eta'' - S(r) J^T eta'::

    M*(psi) = J M J^T
    C*(psi, x) = J [C(J^T x) - M S(psi')] J^T        (psi' = x_3)
    d*(psi, x) = J [D J^T x + D_n(J^T x)]
    M* eta'' + C*(psi, eta') eta' + d*(psi, eta') = J(psi) tau

(the right side is J tau, Fossen's tau*; the paper writes tau for both). Property (3),
C*(psi, x) y = C*(psi, y) x, holds for the Christoffel factorization of M*(psi), not
for the C* above; both give the same C*(psi, x) x (see :meth:`Cybership.christoffel_coriolis`).
"""

from __future__ import annotations

from typing import ClassVar, Protocol, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec, rotate, rotate_transpose, rotation, ssa
from lookout.components import DivergenceBound, Layout, Plant, Signal
from lookout.declare import Part, Value, component, initial_values, register
from lookout.models.vessel import VESSEL_INPUT, VESSEL_SIGNALS, DPVessel
from lookout.vessel_signals import vessel_kinematics

#: Wondergem et al. (2009), eq. (39).
CYBERSHIP_M = np.array([[25.8, 0.0, 0.0], [0.0, 33.8, 1.0115], [0.0, 1.0115, 2.76]])
CYBERSHIP_D = np.array([[0.72, 0.0, 0.0], [0.0, 0.86, -0.11], [0.0, -0.11, 0.5]])
#: Coefficients of D_n(nu) = [X |u| u, Y |v| v, N |v| v] (from D(nu) of (39)).
CYBERSHIP_QUADRATIC = np.array([1.33, 36.28, -5.04])
#: Length over all (m) and the thrust limits quoted in the paper (N, N, N m).
CYBERSHIP_LENGTH = 1.255
CYBERSHIP_THRUST_LIMIT = (2.0, 1.5, 1.5)

#: Recorded quantities: position, heading, velocities and first-order wave motion.
CYBERSHIP_SIGNALS = tuple(s for s in VESSEL_SIGNALS if not s.name.startswith("bias"))


def skew(r: ArrayLike) -> Array:
    """S(r) = [[0, -r, 0], [r, 0, 0], [0, 0, 0]], so that d/dt J(psi) = J(psi) S(r)."""
    r = jnp.asarray(r)
    zero = jnp.zeros_like(r)
    return jnp.stack([jnp.stack([zero, -r, zero]), jnp.stack([r, zero, zero]), jnp.stack([zero, zero, zero])])


@final
class Cybership(eqx.Module):
    """A ship model (16): M, C(nu) of M, linear D and D_n(nu); by default Cybership II's (39).

    Parameters
    ----------
    mass_matrix : array_like, shape (3, 3)
        M (rigid body plus added mass); symmetric positive definite, with
        m12 = m13 = 0 (the structure C(nu) assumes).
    damping_matrix : array_like, shape (3, 3)
        The linear damping D = D(0).
    quadratic_damping : array_like, shape (3,)
        [X, Y, N] of D_n(nu) = [X |u| u, Y |v| v, N |v| v]; zeros for a model with
        linear damping only (the basin scheme of Section 5).
    """

    mass_matrix: Array
    damping_matrix: Array
    quadratic_damping: Array
    mass_inverse: Array

    def __init__(
        self,
        mass_matrix: npt.ArrayLike = CYBERSHIP_M,
        damping_matrix: npt.ArrayLike = CYBERSHIP_D,
        quadratic_damping: npt.ArrayLike = CYBERSHIP_QUADRATIC,
    ):
        check.symmetric_positive_definite("mass_matrix", mass_matrix, size=3)
        if check.is_concrete(mass_matrix):
            mass = np.asarray(mass_matrix, dtype=float)
            if mass[0, 1] != 0 or mass[0, 2] != 0:
                raise check.ParameterError(
                    "mass_matrix",
                    f"mass_matrix must have m12 = m13 = 0 (surge decoupled, as C(nu) of (39) assumes); got m12 = {mass[0, 1]:g}, m13 = {mass[0, 2]:g}",
                )
        check.square("damping_matrix", damping_matrix)
        check.finite("quadratic_damping", quadratic_damping)
        self.mass_matrix = jnp.asarray(mass_matrix, dtype=float)
        self.damping_matrix = jnp.asarray(damping_matrix, dtype=float)
        self.quadratic_damping = jnp.asarray(check.vector("quadratic_damping", quadratic_damping))
        self.mass_inverse = jnp.linalg.inv(self.mass_matrix)

    @classmethod
    def from_dp_vessel(cls, vessel: DPVessel) -> Cybership:
        """A DP vessel in the form (16): its M and linear D, the C(nu) of that M, no D_n.

        So that the observer (6) and the tracking scheme (23), which take a ship model
        (16), run on a DP vessel (a composition's ``[plant] kind = "dp-vessel"``). The
        DP model (Fossen & Strand 1999, eq. 3) has no C(nu): it neglects it at DP
        speeds, and the model built here adds it (the rigid-body and added-mass C(nu) of
        its M, with m12 = m13 = 0), so at speed the scheme models a term the DP plant
        does not have.

        Parameters
        ----------
        vessel : DPVessel
            The vessel (in a composition, the plant's): M with m12 = m13 = 0 (surge
            decoupled from sway and yaw, as C(nu) assumes), and no mooring stiffness K
            (the model (16) has none).
        """
        if check.is_concrete(vessel.stiffness_matrix) and np.any(np.asarray(vessel.stiffness_matrix) != 0):
            stiffness = np.asarray(vessel.stiffness_matrix).tolist()
            raise check.ParameterError("vessel", f"vessel has a mooring stiffness K (the ship model (16) has none); got K = {stiffness}")
        return cls(vessel.mass_matrix, vessel.damping_matrix, np.zeros(3))

    def linear(self) -> Cybership:
        """The same ship with D_n = 0 (the model of the basin scheme, Section 5)."""
        return Cybership(self.mass_matrix, self.damping_matrix, jnp.zeros(3))

    # -- body frame ---------------------------------------------------------------

    def coriolis(self, nu: Array) -> Array:
        """C(nu) of (39): rigid-body plus added-mass Coriolis and centripetal matrix (skew)."""
        m = self.mass_matrix
        u, v, r = nu[0], nu[1], nu[2]
        a = m[1, 1] * v + m[1, 2] * r
        b = m[0, 0] * u
        zero = jnp.zeros_like(u)
        return jnp.stack([jnp.stack([zero, zero, -a]), jnp.stack([zero, zero, b]), jnp.stack([a, -b, zero])])

    def nonlinear_damping(self, nu: Array) -> Array:
        """D_n(nu) = [X |u| u, Y |v| v, N |v| v] (N, N, N m)."""
        q = self.quadratic_damping
        return jnp.stack([q[0] * jnp.abs(nu[0]) * nu[0], q[1] * jnp.abs(nu[1]) * nu[1], q[2] * jnp.abs(nu[1]) * nu[1]])

    def damping_force(self, nu: Array) -> Array:
        """D(nu) nu = D nu + D_n(nu)."""
        return matvec(self.damping_matrix, nu) + self.nonlinear_damping(nu)

    def acceleration(self, nu: Array, tau: Array) -> Array:
        """nu' = M^-1 (tau - C(nu) nu - D nu - D_n(nu)), eq. (16)."""
        return matvec(self.mass_inverse, tau - matvec(self.coriolis(nu), nu) - self.damping_force(nu))

    # -- Earth frame --------------------------------------------------------------

    def earth_mass(self, psi: Array) -> Array:
        """M*(psi) = J M J^T."""
        J = rotation(psi)
        return J @ self.mass_matrix @ J.T

    def earth_coriolis(self, psi: Array, x: Array) -> Array:
        """C*(psi, x) = J [C(J^T x) - M S(x_3)] J^T, x an Earth-fixed velocity eta'."""
        J = rotation(psi)
        return J @ (self.coriolis(J.T @ x) - self.mass_matrix @ skew(x[2])) @ J.T

    def earth_damping(self, psi: Array, x: Array) -> Array:
        """d*(psi, x) = J [D J^T x + D_n(J^T x)]."""
        return rotate(psi, self.damping_force(rotate_transpose(psi, x)))

    def earth_acceleration(self, psi: Array, x: Array, tau: Array) -> Array:
        """eta'' for eta' = x and body input tau, without inverting M*:
        J [S(r) nu + M^-1 (tau - C(nu) nu - D(nu) nu)], nu = J^T x, r = x_3."""
        nu = rotate_transpose(psi, x)
        return rotate(psi, matvec(skew(nu[2]), nu) + self.acceleration(nu, tau))

    def christoffel_coriolis(self, psi: Array, x: Array) -> Array:
        """The Christoffel-symbol factorization of M*(psi) (derivations-wondergem-2009.md, 1):
        with K = [E, M], E = S(1), and a = J^T x,
        C_Gamma(psi, x) = 1/2 J [a_3 K + (K a) e3^T - e3 (K a)^T] J^T.
        C_Gamma(psi, x) x equals C*(psi, x) x, C_Gamma(psi, x) y = C_Gamma(psi, y) x
        (property (3)) and M*' - 2 C_Gamma is skew."""
        J = rotation(psi)
        E = skew(1.0)
        K = E @ self.mass_matrix - self.mass_matrix @ E
        a = J.T @ x
        Ka = K @ a
        e3 = jnp.array([0.0, 0.0, 1.0])
        return 0.5 * J @ (a[2] * K + jnp.outer(Ka, e3) - jnp.outer(e3, Ka)) @ J.T


register(
    "ship",
    "cybership-ii",
    Cybership,
    summary="A ship model (16): M, C(nu) of M, linear D and D_n(nu); by default Cybership II's (39).",
    parameters=(
        Value(
            "mass_matrix",
            "array",
            "M (rigid body plus added mass); symmetric positive definite, with m12 = m13 = 0 (the structure C(nu) assumes).",
            shape="(3, 3)",
        ),
        Value("damping_matrix", "array", "The linear damping D = D(0).", shape="(3, 3)"),
        Value(
            "quadratic_damping",
            "array",
            "[X, Y, N] of D_n(nu) = [X |u| u, Y |v| v, N |v| v]; zeros for a model with linear damping only (the basin scheme of Section 5).",
            shape="(3,)",
        ),
    ),
)


register(
    "ship",
    "dp-vessel",
    Cybership,
    summary="A ship model (16): M, C(nu) of M, linear D and D_n(nu); by default Cybership II's (39).",
    build="from_dp_vessel",
    parameters=(
        Part(
            "vessel",
            "The vessel (in a composition, the plant's): M with m12 = m13 = 0 (surge decoupled from sway and yaw, as C(nu) assumes), and no mooring stiffness K (the model (16) has none).",
        ),
    ),
)


def cybership2() -> Cybership:
    """Cybership II with (39) as printed."""
    return Cybership()


@final
class CybershipState(eqx.Module):
    """State of the Cybership II plant, or an observer's estimate of it.

    Attributes
    ----------
    eta : Array, shape (3,)
        Earth-fixed position and heading [x, y, psi] (m, m, rad).
    nu : Array, shape (3,)
        Body-fixed velocities [u, v, r] (m/s, m/s, rad/s).
    wave : Array, shape (3,)
        First-order wave-induced motion eta_w (m, m, rad), added to the measurement.
    """

    eta: Array
    nu: Array
    wave: Array

    @classmethod
    def build(cls, eta: npt.ArrayLike = 0.0, nu: npt.ArrayLike = 0.0, wave: npt.ArrayLike = 0.0) -> CybershipState:
        """State from scalars or sequences, validated and broadcast."""
        return cls(jnp.asarray(check.vector("eta", eta)), jnp.asarray(check.vector("nu", nu)), jnp.asarray(check.vector("wave", wave)))

    def wrapped(self) -> CybershipState:
        """The same state with heading wrapped to [-pi, pi)."""
        return eqx.tree_at(lambda s: s.eta, self, self.eta.at[2].set(ssa(self.eta[2])))

    def signals(self) -> dict[str, Array]:
        """The state as the named quantities of :data:`CYBERSHIP_SIGNALS`."""
        return {
            "position": self.eta[..., :2],
            "heading": self.eta[..., 2],
            "velocity": self.nu[..., :2],
            "yaw_rate": self.nu[..., 2],
            "wave_position": self.wave[..., :2],
            "wave_heading": self.wave[..., 2],
        }


class _Waves(Protocol):
    """What :class:`CybershipPlant` asks of its waves (:class:`lookout.environment.JonswapWaves` has it)."""

    def motion(self, t, position) -> Array: ...

    def rate(self, t, position, velocity) -> Array: ...

    def realize(self, key: Array) -> _Waves: ...


@component(
    "plant",
    "cybership-ii",
    summary="Cybership II (16) with optional first-order wave motion.",
    parameters=(
        Part("ship", "The true ship (the plant may have D_n where the scheme's model has none)."),
        Part(
            "waves",
            "A wave realization with rate(t, position, velocity), motion(t, position) and realize(key) (lookout.environment.JonswapWaves); None for calm water.",
        ),
        Value("wave_ramp", "float", "Seconds over which the waves rise, 1/2 (1 - cos(pi t / wave_ramp)); > 0."),
    ),
)
@final
class CybershipPlant(Plant):
    """Cybership II (16) with optional first-order wave motion.

    The input is tau (N, N, N m, body-fixed), as applied by the actuator. The wave
    motion eta_w is part of the state: integrated from ``waves.rate`` (the exact time
    derivative of the realized wave motion at the ship's position, Doppler included),
    multiplied by a ramp that brings the waves up from zero over ``wave_ramp`` seconds
    like a wave maker starting, so that eta_w(0) = 0 holds exactly and
    eta_w(t) = ramp(t) motion(t, position(t)) up to the integration error.

    Parameters
    ----------
    ship : Cybership
        The true ship (the plant may have D_n where the scheme's model has none).
    waves : optional
        A wave realization with ``rate(t, position, velocity)``, ``motion(t, position)``
        and ``realize(key)`` (:class:`lookout.environment.JonswapWaves`); None for calm water.
    wave_ramp : float
        Seconds over which the waves rise, 1/2 (1 - cos(pi t / wave_ramp)); > 0.
    """

    #: a failed run: a position error of 5 m, four lengths of the 1.255 m model ship: beyond the basin's working area
    divergence: ClassVar[DivergenceBound] = DivergenceBound("position", 5.0)

    ship: Cybership
    waves: _Waves | None
    wave_ramp: float = eqx.field(static=True)
    noise_size: int = eqx.field(static=True, default=0, kw_only=True)
    input_layout: Layout = eqx.field(static=True, default=VESSEL_INPUT, kw_only=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True, default=CYBERSHIP_SIGNALS, kw_only=True)

    def __init__(self, ship: Cybership, waves: _Waves | None = None, wave_ramp: float = 10.0):
        if not isinstance(ship, Cybership):
            raise check.ParameterError("ship", f"ship must be a Cybership; got {type(ship).__name__}")
        self.ship = ship
        self.waves = waves
        check.positive("wave_ramp", wave_ramp)
        self.wave_ramp = float(wave_ramp)
        self.noise_size = 0

    def _ramp(self, t):
        phase = jnp.clip(t / self.wave_ramp, 0.0, 1.0)
        return 0.5 * (1.0 - jnp.cos(jnp.pi * phase)), jnp.where(phase < 1.0, 0.5 * jnp.pi / self.wave_ramp * jnp.sin(jnp.pi * phase), 0.0)

    def vector_field(self, t: ArrayLike, state: CybershipState, tau: Array, noise: Array) -> CybershipState:
        """eta' = J nu, nu' of (16), and eta_w' = d/dt [ramp(t) motion(t, position(t))]."""
        del noise
        eta_rate = rotate(state.eta[2], state.nu)
        if self.waves is None:
            wave_rate = jnp.zeros(3)
        else:
            ramp, ramp_rate = self._ramp(t)
            position = state.eta[:2]
            wave_rate = ramp * self.waves.rate(t, position, eta_rate[:2]) + ramp_rate * self.waves.motion(t, position)
        return CybershipState(eta=eta_rate, nu=self.ship.acceleration(state.nu, tau), wave=wave_rate)

    @initial_values(
        Value(
            "eta",
            "array",
            "Position north, east (m) and heading (rad), Earth-fixed (zeros when not given; an observer's guess takes it from the first measurement).",
            shape="(3,)",
        ),
        Value("nu", "array", "Velocity surge, sway (m/s) and yaw rate (rad/s), body-fixed.", shape="(3,)"),
        Value("wave", "array", "Wave-induced motion eta_w (m, m, rad).", shape="(3,)"),
    )
    def state(self, eta: npt.ArrayLike | None = None, nu: npt.ArrayLike = 0.0, wave: npt.ArrayLike = 0.0) -> CybershipState:
        """A state of this plant (zeros where not given): a composition's ``[plant.initial]``.

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            Position north, east (m) and heading (rad), Earth-fixed (zeros when not given; an observer's guess takes it from the first measurement).
        nu : array_like, shape (3,)
            Velocity surge, sway (m/s) and yaw rate (rad/s), body-fixed.
        wave : array_like, shape (3,)
            Wave-induced motion eta_w (m, m, rad).
        """
        return CybershipState.build(0.0 if eta is None else eta, nu, wave)

    def kinematics(self, t: ArrayLike, state: CybershipState, tau: Array) -> dict[str, Array]:
        """What the ship's sensors measure at ``t`` under the applied ``tau``
        (:func:`lookout.vessel_signals.vessel_kinematics`)."""
        return vessel_kinematics(state.eta, state.wave, state.nu, self.ship.acceleration(state.nu, tau))

    def normalize(self, state: CybershipState) -> CybershipState:
        """Heading wrapped to [-pi, pi), as a compass reports it."""
        return state.wrapped()

    def variables(self, state: CybershipState) -> dict[str, Array]:
        """Position, heading, velocities and wave motion (:data:`CYBERSHIP_SIGNALS`)."""
        return state.signals()

    def models(self) -> tuple:
        """The ship (M, C, D, D_n), and its M and linear D as a DP vessel model (for the
        observers of Fossen & Strand and Kim, which neglect C and D_n at DP speeds)."""
        from lookout.models.vessel import DPVessel

        return (self.ship, DPVessel(self.ship.mass_matrix, self.ship.damping_matrix))

    def realize(self, key: Array) -> CybershipPlant:
        """The waves' random phases drawn from ``key`` (calm water: the plant itself)."""
        if self.waves is None:
            return self
        return eqx.tree_at(lambda p: p.waves, self, self.waves.realize(key))


__all__ = [
    "CYBERSHIP_D",
    "CYBERSHIP_LENGTH",
    "CYBERSHIP_M",
    "CYBERSHIP_QUADRATIC",
    "CYBERSHIP_SIGNALS",
    "CYBERSHIP_THRUST_LIMIT",
    "Cybership",
    "CybershipPlant",
    "CybershipState",
    "cybership2",
    "skew",
]
