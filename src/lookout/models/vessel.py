"""Three-degree-of-freedom DP vessel with bias and wave-induced motion.

Low-frequency model, Fossen & Strand (1999), eqs. (1)–(3) with the mooring term of
Calugi, Robertsson & Johansson (2003), eq. (2):

    eta' = J(psi) nu
    M nu' + D nu + K eta = tau + J(psi)^T b

The bias b follows eq. (7) and the wave-induced motion eqs. (10)–(11); the
measured output is ``y = eta + eta_w + d`` (eq. 12), see :mod:`lookout.sensors`.
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
from lookout._math import matvec, rotate, rotate_transpose, ssa
from lookout.components import DivergenceBound, Layout, Plant, Signal
from lookout.declare import NON_NEGATIVE, Part, Value, component, initial_values
from lookout.environment import BodyDisturbance, GaussMarkovBias, LinearWaveModel
from lookout.vessel_signals import BODY_AXES as BODY_AXES
from lookout.vessel_signals import DOF as DOF
from lookout.vessel_signals import EARTH_AXES as EARTH_AXES
from lookout.vessel_signals import VESSEL_INPUT as VESSEL_INPUT
from lookout.vessel_signals import VESSEL_SIGNALS as VESSEL_SIGNALS
from lookout.vessel_signals import vessel_kinematics

#: Northern Clipper, Fossen & Strand (1999), eqs. (56)–(57) and Section 6.
NORTHERN_CLIPPER_MASS = 4.591e6  # kg
NORTHERN_CLIPPER_LENGTH = 76.2  # m
NORTHERN_CLIPPER_M = np.diag([5.3122e6, 8.2831e6, 3.7454e9])
NORTHERN_CLIPPER_D = np.array([[5.0242e4, 0.0, 0.0], [0.0, 2.7229e5, -4.3933e6], [0.0, -4.3933e6, 4.1894e8]])
#: Thrust limits chosen for the Northern Clipper (surge force N, sway force N, yaw moment
#: N m; the input layout of :data:`VESSEL_INPUT`), for an actuator ``kind =
#: "thrust-limits"`` (:class:`lookout.actuators.SaturatingActuator`); Fossen & Strand
#: (1999) give none:
#:
#: - surge force 0.5 MN: about 50 t of the roughly 80 t bollard pull of a twin-screw
#:   supply vessel of 70-80 m of the 1990s, the share a DP system typically keeps
#:   available (the rest is margin);
#: - sway force 0.3 MN: two bow and one stern tunnel thruster of 600-800 kW at about
#:   12 kg of thrust per kW (about 26 t), plus a little from the main propellers and rudders;
#: - yaw moment 1.0e7 N m: bow and stern thrusters about +-33 m (0.43 L) from midships
#:   pushing in opposite directions, 0.3 MN x 33 m.
#:
#: Against the paper's loads (bias of 10 kN, 5 kN, 100 kN m; tau of 1 kN) these limits
#: never bind; they matter for a controller that moves the vessel.
NORTHERN_CLIPPER_THRUST_LIMIT = (5.0e5, 3.0e5, 1.0e7)


class VesselState(eqx.Module):
    """State of the vessel-bias-wave system, or an observer's estimate of it.

    Attributes
    ----------
    eta : Array, shape (3,)
        Earth-fixed low-frequency position and heading [x, y, psi] (m, m, rad).
    nu : Array, shape (3,)
        Body-frame velocities [u, v, r] (m/s, m/s, rad/s).
    bias : Array, shape (3,)
        Earth-fixed bias forces and moment (N, N, N m).
    wave_state : Array, shape (6,)
        Wave model state [xi1, xi2]; the wave-induced motion is ``xi2``.
    """

    eta: Array
    nu: Array
    bias: Array
    wave_state: Array

    @property
    def wave(self) -> Array:
        """First-order wave-induced motion eta_w = Gamma xi = xi2 (m, m, rad)."""
        return self.wave_state[..., 3:]

    @classmethod
    def zeros(cls) -> VesselState:
        """All-zero state."""
        return cls(jnp.zeros(3), jnp.zeros(3), jnp.zeros(3), jnp.zeros(6))

    @classmethod
    def build(
        cls, eta: npt.ArrayLike | None = 0.0, nu: npt.ArrayLike = 0.0, bias: npt.ArrayLike = 0.0, wave_state: npt.ArrayLike = 0.0
    ) -> VesselState:
        """State from scalars or sequences, validated and broadcast (an ``eta`` of None is
        unknown: NaN, which an observer's ``init`` fills from the first measurement)."""
        return cls(
            jnp.asarray(check.vector("eta", eta)),
            jnp.asarray(check.vector("nu", nu)),
            jnp.asarray(check.vector("bias", bias)),
            jnp.asarray(check.vector("wave_state", wave_state, 6)),
        )

    def wrapped(self) -> VesselState:
        """The same state with heading wrapped to [-pi, pi)."""
        return eqx.tree_at(lambda s: s.eta, self, self.eta.at[2].set(ssa(self.eta[2])))

    def signals(self) -> dict[str, Array]:
        """The state as the named quantities of :data:`VESSEL_SIGNALS`."""
        wave = self.wave
        return {
            "position": self.eta[..., :2],
            "heading": self.eta[..., 2],
            "velocity": self.nu[..., :2],
            "yaw_rate": self.nu[..., 2],
            "bias_force": self.bias[..., :2],
            "bias_moment": self.bias[..., 2],
            "wave_position": wave[..., :2],
            "wave_heading": wave[..., 2],
        }


class DPVessel(eqx.Module):
    """Linear low-frequency 3-DOF vessel model M nu' + D nu + K eta = tau + J^T b.

    Fossen & Strand (1999), eq. (3); stiffness term from Calugi et al. (2003), eq. (2)
    (heading enters through ssa so a mooring moment does not jump at +-pi).

    Parameters
    ----------
    mass_matrix : array_like, shape (3, 3)
        M including added mass; symmetric positive definite (assumption A1).
    damping_matrix : array_like, shape (3, 3)
        Linear damping D.
    stiffness_matrix : array_like, shape (3, 3), optional
        Mooring stiffness K (zero for a free-floating DP vessel).
    """

    mass_matrix: Array
    damping_matrix: Array
    stiffness_matrix: Array
    mass_inverse: Array

    def __init__(self, mass_matrix: npt.ArrayLike, damping_matrix: npt.ArrayLike, stiffness_matrix: npt.ArrayLike | None = None):
        check.symmetric_positive_definite("mass_matrix", mass_matrix, size=3)
        check.square("damping_matrix", damping_matrix)
        check.dissipative("damping_matrix", damping_matrix)
        if stiffness_matrix is None:
            stiffness_matrix = jnp.zeros((3, 3))
        check.square("stiffness_matrix", stiffness_matrix)
        self.mass_matrix = jnp.asarray(mass_matrix, dtype=float)
        self.damping_matrix = jnp.asarray(damping_matrix, dtype=float)
        self.stiffness_matrix = jnp.asarray(stiffness_matrix, dtype=float)
        self.mass_inverse = jnp.linalg.inv(self.mass_matrix)

    def scaled(self, mass_scale: npt.ArrayLike = 1.0, damping_scale: npt.ArrayLike = 1.0) -> DPVessel:
        """This vessel with M and D multiplied entry by entry (a model error).

        ``mass_scale`` and ``damping_scale`` are scalars or 3x3 arrays of factors
        (1.2 is a 20 % heavier vessel than the model); the scaled M must stay
        symmetric positive definite.
        """
        mass_scale = np.broadcast_to(np.asarray(mass_scale, dtype=float), (3, 3))
        damping_scale = np.broadcast_to(np.asarray(damping_scale, dtype=float), (3, 3))
        for name, scale in (("mass_scale", mass_scale), ("damping_scale", damping_scale)):
            if not np.all(np.isfinite(scale)) or np.any(scale < 0):
                raise check.ParameterError(check.key(name), f"{name} must be finite and non-negative; got {scale.tolist()}")
        return DPVessel(np.asarray(self.mass_matrix) * mass_scale, np.asarray(self.damping_matrix) * damping_scale, self.stiffness_matrix)

    def acceleration(self, eta: Array, nu: Array, tau: Array, bias: Array) -> Array:
        """nu' = M^{-1} (tau + J^T(psi) b - D nu - K eta)."""
        eta_wrapped = eta.at[2].set(ssa(eta[2]))
        force = tau + rotate_transpose(eta[2], bias) - matvec(self.damping_matrix, nu)
        force = force - matvec(self.stiffness_matrix, eta_wrapped)
        return matvec(self.mass_inverse, force)


@component(
    "vessel",
    "northern-clipper",
    summary="Linear low-frequency 3-DOF vessel model M nu' + D nu + K eta = tau + J^T b.",
    parameters=(
        Value(
            "mass_scale", "float", "M multiplied entry by entry (1.2: a vessel 20 % heavier than the paper's, a model error) (1).", range=NON_NEGATIVE
        ),
        Value("damping_scale", "float", "D multiplied entry by entry (1).", range=NON_NEGATIVE),
    ),
)
def northern_clipper(mass_scale: float = 1.0, damping_scale: float = 1.0) -> DPVessel:
    """The supply vessel Northern Clipper, Fossen & Strand (1999), eqs. (56)–(57).

    Parameters
    ----------
    mass_scale : float, non-negative
        M multiplied entry by entry (1.2: a vessel 20 % heavier than the paper's, a model error) (1).
    damping_scale : float, non-negative
        D multiplied entry by entry (1).
    """
    return scaled_vessel(NORTHERN_CLIPPER_M, NORTHERN_CLIPPER_D, None, mass_scale, damping_scale)


@component(
    "vessel",
    "custom",
    summary="Linear low-frequency 3-DOF vessel model M nu' + D nu + K eta = tau + J^T b.",
    parameters=(
        Value("mass_matrix", "array", "M including added mass (kg, kg m, kg m^2); symmetric positive definite (assumption A1).", shape="(3, 3)"),
        Value("damping_matrix", "array", "Linear damping D (kg/s, kg m/s, kg m^2/s); its symmetric part positive semi-definite.", shape="(3, 3)"),
        Value("stiffness_matrix", "array", "Mooring stiffness K (N/m, N/rad, N m/rad); zero for a free-floating DP vessel.", shape="(3, 3)"),
        Value("mass_scale", "float", "M multiplied entry by entry (1).", range=NON_NEGATIVE),
        Value("damping_scale", "float", "D multiplied entry by entry (1).", range=NON_NEGATIVE),
    ),
)
def scaled_vessel(
    mass_matrix: npt.ArrayLike,
    damping_matrix: npt.ArrayLike,
    stiffness_matrix: npt.ArrayLike | None = None,
    mass_scale: float = 1.0,
    damping_scale: float = 1.0,
) -> DPVessel:
    """A DP vessel of M, D (and K), its M and D scaled entry by entry (a model error).

    Parameters
    ----------
    mass_matrix : array_like, shape (3, 3)
        M including added mass (kg, kg m, kg m^2); symmetric positive definite (assumption A1).
    damping_matrix : array_like, shape (3, 3)
        Linear damping D (kg/s, kg m/s, kg m^2/s); its symmetric part positive semi-definite.
    stiffness_matrix : array_like, shape (3, 3), optional
        Mooring stiffness K (N/m, N/rad, N m/rad); zero for a free-floating DP vessel.
    mass_scale : float, non-negative
        M multiplied entry by entry (1).
    damping_scale : float, non-negative
        D multiplied entry by entry (1).
    """
    vessel = DPVessel(mass_matrix, damping_matrix, stiffness_matrix)
    return vessel if (mass_scale, damping_scale) == (1.0, 1.0) else vessel.scaled(mass_scale, damping_scale)


@component(
    "plant",
    "dp-vessel",
    summary="Vessel, bias and wave model integrated together as one continuous-time plant.",
    parameters=(
        Part("vessel", "The true vessel (it may differ from the observer's and controller's model: that difference is the model error)."),
        Part("bias", "The slowly varying environmental forces b (currents, mean wave drift, wind)."),
        Part("waves", "The first-order wave-frequency motion eta_w added to the measured position."),
        Part(
            "disturbance",
            "An unmodelled body-fixed force (Kim's E_nu w_nu); its white part adds three noise channels after the six of bias and waves.",
        ),
    ),
)
@final
class VesselPlant(Plant):
    """Vessel, bias and wave model integrated together as one continuous-time plant.

    The input is tau (N, N, N m, body-fixed); the noise is a 6-vector of unit white
    noise ``[n, w]`` driving the bias (7) and the waves (11), held over one
    integration step (the engine scales it by ``1/sqrt(step)``).

    Parameters
    ----------
    vessel : DPVessel
        The true vessel (it may differ from the observer's and controller's model:
        that difference is the model error).
    bias : GaussMarkovBias
        The slowly varying environmental forces b (currents, mean wave drift, wind).
    waves : LinearWaveModel
        The first-order wave-frequency motion eta_w added to the measured position.
    disturbance : BodyDisturbance, optional
        An unmodelled body-fixed force (Kim's E_nu w_nu); its white part adds three
        noise channels after the six of bias and waves.
    """

    #: a failed run: a position estimation or tracking error of 100 m, a DP vessel's length: no DP observer or loop that works is that far off
    divergence: ClassVar[DivergenceBound] = DivergenceBound("position", 100.0)

    vessel: DPVessel
    bias: GaussMarkovBias
    waves: LinearWaveModel
    disturbance: BodyDisturbance | None
    noise_size: int = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True, default=VESSEL_INPUT, kw_only=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True, default=VESSEL_SIGNALS, kw_only=True)

    def __init__(self, vessel: DPVessel, bias: GaussMarkovBias, waves: LinearWaveModel, disturbance: BodyDisturbance | None = None):
        self.vessel = vessel
        self.bias = bias
        self.waves = waves
        self.disturbance = disturbance
        self.noise_size = 6 + (disturbance.noise_size if disturbance is not None else 0)

    def vector_field(self, t: ArrayLike, state: VesselState, tau: Array, noise: Array) -> VesselState:
        """Time derivative of the plant state (eqs. 1, 3, 7, 11), with the unmodelled
        body-fixed force E_nu w_nu of Kim (2002), eq. (1), added to tau when given."""
        force = tau if self.disturbance is None else tau + self.disturbance.force(t, noise[6:])
        return VesselState(
            eta=rotate(state.eta[2], state.nu),
            nu=self.vessel.acceleration(state.eta, state.nu, force, state.bias),
            bias=self.bias.derivative(state.bias, noise[:3]),
            wave_state=self.waves.derivative(state.wave_state, noise[3:6]),
        )

    @initial_values(
        Value(
            "eta",
            "array",
            "Position north, east (m) and heading (rad), Earth-fixed (zeros when not given; an observer's guess takes it from the first measurement).",
            shape="(3,)",
        ),
        Value("nu", "array", "Velocity surge, sway (m/s) and yaw rate (rad/s), body-fixed.", shape="(3,)"),
        Value("bias", "array", "Bias forces and moment (N, N, N m), Earth-fixed.", shape="(3,)"),
        Value("wave_state", "array", "Wave-model state [xi1, xi2] of eq. (11) (m s, m s, rad s, m, m, rad).", shape="(6,)"),
    )
    def state(
        self, eta: npt.ArrayLike | None = None, nu: npt.ArrayLike = 0.0, bias: npt.ArrayLike = 0.0, wave_state: npt.ArrayLike = 0.0
    ) -> VesselState:
        """A state of this plant (zeros where not given): a composition's ``[plant.initial]``.

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            Position north, east (m) and heading (rad), Earth-fixed (zeros when not given; an observer's guess takes it from the first measurement).
        nu : array_like, shape (3,)
            Velocity surge, sway (m/s) and yaw rate (rad/s), body-fixed.
        bias : array_like, shape (3,)
            Bias forces and moment (N, N, N m), Earth-fixed.
        wave_state : array_like, shape (6,)
            Wave-model state [xi1, xi2] of eq. (11) (m s, m s, rad s, m, m, rad).
        """
        return VesselState.build(0.0 if eta is None else eta, nu, bias, wave_state)

    def kinematics(self, t: ArrayLike, state: VesselState, tau: Array) -> dict[str, Array]:
        """What the vessel's sensors measure at ``t`` under the applied ``tau``
        (:func:`lookout.vessel_signals.vessel_kinematics`): the accelerations are those
        of :meth:`vector_field` without its white noise."""
        rates = self.vector_field(t, state, tau, jnp.zeros(self.noise_size))
        return vessel_kinematics(state.eta, state.wave, state.nu, rates.nu)

    def normalize(self, state: VesselState) -> VesselState:
        """Heading wrapped to [-pi, pi), as a gyro compass reports it."""
        return state.wrapped()

    def variables(self, state: VesselState) -> dict[str, Array]:
        """Position, heading, velocities, bias and wave motion (:data:`VESSEL_SIGNALS`)."""
        return state.signals()

    def models(self) -> tuple:
        """The true vessel (M, D, K)."""
        return (self.vessel,)

    def realize(self, key: Array) -> VesselPlant:
        """No per-run randomness beyond the white noise: the plant itself."""
        del key
        return self
