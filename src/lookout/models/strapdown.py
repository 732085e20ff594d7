"""Strapdown inertial navigation in the horizontal plane: a vessel's low-frequency motion
integrated from an IMU's specific force and yaw rate, with the IMU's biases as states,
and an optional wave-frequency part.

The horizontal-plane mechanization of a strapdown system over a flat Earth (the local
navigation frame mechanization of Farrell (2008), Aided Navigation: GPS with High Rate
Sensors, and Groves (2013), Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems, 2nd ed., reduced to the plane, with the Earth's rotation and the
transport rate left out: 7.3e-5 rad/s against a DP vessel's yaw rates, and metres from
the origin)::

    p'   = v                                   p: north, east (m); v Earth-fixed (m/s)
    v'   = R(psi) (f - b_a - n_a + r^2 l)      f: measured specific force, surge and sway
    psi' = r_m - b_g - n_g                     r_m: measured yaw rate
    b'   = -b / T_b + w_b                      b = [b_a, b_g]: the IMU's biases

with R(psi) the planar rotation (Fossen & Strand (1999), eq. (2)), n_a and n_g the
accelerometers' and gyro's white noise (their velocity and angle random walk), and the
biases first-order Gauss-Markov processes of correlation time T_b and stationary spread
sigma_b (w_b of intensity 2 sigma_b^2 / T_b; a random walk where T_b is infinite). An
IMU at the lever arm l from the reference point feels ``a - r^2 l + r' [-l_y, l_x]``
(:mod:`lookout.sensing.motion`); the centripetal part is put back with the corrected
rate, the tangential part ``r' [-l_y, l_x]`` is left out (no yaw acceleration is
measured: 1e-3 m/s2 at 10 m for a DP vessel's 1e-4 rad/s2, below a tactical
accelerometer's bias).

The IMU's reading is the model's input, held over each sample as a strapdown system
holds its increments: the propagation is first order in the IMU's sample period.

**Waves.** lookout's vessels carry their first-order wave motion as a position-level
model, Fossen & Strand (1999), eqs. (10)-(11): a disturbance on what the position
references and gyros measure, which the IMU on the simulated hull does not feel. With
``waves`` the model carries the same wave states, and what a reference measures is the
integrated low-frequency motion plus the wave motion, so that the low-frequency
position and velocity a DP controller needs are the strapdown states themselves. On a
hull whose accelerometers feel the wave-frequency acceleration, that acceleration is
noise to this model (give it in ``accelerometer_noise``).
"""

from __future__ import annotations

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import rotate, rotate_transpose, ssa
from lookout.components import BODY_FIXED, DivergenceBound, Layout, Plant, Signal
from lookout.declare import Value, initial_values
from lookout.environment import LinearWaveModel
from lookout.vessel_signals import BODY_AXES, VESSEL_SIGNALS, vessel_kinematics

#: The model's input: the IMU's reading, as the suite's instrument gives it.
IMU_INPUT = Layout(
    (
        Signal("specific_force", "m/s2", "measured specific force (accelerometers)", BODY_FIXED, BODY_AXES, "body_axis"),
        Signal("angular_rate", "rad/s", "measured yaw rate (rate gyro)", BODY_FIXED),
    )
)
#: The estimated biases, recorded beside the vessel's variables.
BIAS_SIGNALS = (
    Signal("accelerometer_bias", "m/s2", "accelerometer bias (surge, sway)", BODY_FIXED, BODY_AXES, "body_axis"),
    Signal("gyro_bias", "rad/s", "rate gyro bias", BODY_FIXED),
)
_LOW_FREQUENCY = tuple(signal for signal in VESSEL_SIGNALS if not signal.name.startswith(("bias", "wave")))
_WAVE = tuple(signal for signal in VESSEL_SIGNALS if signal.name.startswith("wave"))


class StrapdownState(eqx.Module):
    """State of :class:`StrapdownVessel`.

    Attributes
    ----------
    eta : Array, shape (3,)
        Low-frequency position north, east and heading [x, y, psi] (m, m, rad).
    velocity : Array, shape (2,)
        Low-frequency velocity, Earth-fixed [north, east] (m/s).
    bias : Array, shape (3,)
        The IMU's biases [surge accelerometer, sway accelerometer, gyro] (m/s2, m/s2, rad/s).
    wave_state : Array, shape (6,) or (0,)
        The wave model's state [xi1, xi2] (none without waves); the motion is ``xi2``.
    """

    eta: Array
    velocity: Array
    bias: Array
    wave_state: Array

    @property
    def wave(self) -> Array:
        """The wave-induced motion (zero without waves)."""
        return self.wave_state[..., 3:] if self.wave_state.shape[-1] else jnp.zeros_like(self.eta)


@final
class StrapdownVessel(Plant):
    """Strapdown navigation in the horizontal plane driven by an IMU's reading (module
    docstring). It is a Kalman filter's model (:mod:`lookout.observers.ins`), not a
    plant kind of a scenario file: its input is the IMU's reading, not thrust.

    The noise is ``[n_a (2), n_g, w_b (3)]`` and, with waves, the wave model's (3).

    Parameters
    ----------
    accelerometer_noise : float, non-negative
        Noise density of each accelerometer, its velocity random walk (m/s2/sqrt(Hz) =
        m/s/sqrt(s)).
    gyro_noise : float, non-negative
        Noise density of the rate gyro, its angle random walk (rad/s/sqrt(Hz) = rad/sqrt(s)).
    bias_std : array_like, shape (3,), non-negative
        Stationary spread of the biases [accelerometers (2), gyro] (m/s2, m/s2, rad/s).
    bias_time_constant : float, positive
        Their correlation time T_b (s); ``inf`` for a random walk of intensity
        ``bias_std^2`` per second.
    lever_arm : array_like, shape (2,)
        The IMU's body-fixed position [x, y] from the reference point (m).
    waves : LinearWaveModel, optional
        The wave-frequency motion; None for none.
    """

    divergence: ClassVar[DivergenceBound] = DivergenceBound("position", 100.0)

    accelerometer_noise: Array
    gyro_noise: Array
    bias_std: Array
    bias_time_constant: Array
    lever_arm: Array
    waves: LinearWaveModel | None
    noise_size: int = eqx.field(static=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True, default=IMU_INPUT, kw_only=True)

    def __init__(
        self,
        accelerometer_noise: float = 0.0,
        gyro_noise: float = 0.0,
        bias_std: npt.ArrayLike = 0.0,
        bias_time_constant: float = float("inf"),
        lever_arm: npt.ArrayLike = (0.0, 0.0),
        waves: LinearWaveModel | None = None,
    ):
        check.positive("accelerometer_noise", accelerometer_noise, allow_zero=True)
        check.positive("gyro_noise", gyro_noise, allow_zero=True)
        spread = check.vector("bias_std", bias_std)
        check.positive("bias_std", spread, allow_zero=True)
        if not bias_time_constant > 0:
            raise check.ParameterError("bias_time_constant", f"bias_time_constant must be > 0 (inf: a random walk); got {bias_time_constant!r}")
        arm = check.vector("lever_arm", lever_arm, 2)
        if waves is not None and not isinstance(waves, LinearWaveModel):
            raise ValueError(f"waves must be a linear wave model or None; got {type(waves).__name__}")
        self.accelerometer_noise = jnp.asarray(float(accelerometer_noise))
        self.gyro_noise = jnp.asarray(float(gyro_noise))
        self.bias_std = jnp.asarray(spread)
        self.bias_time_constant = jnp.asarray(float(bias_time_constant))
        self.lever_arm = jnp.asarray(arm)
        self.waves = waves
        self.noise_size = 6 if waves is None else 9
        self.variable_signals = _LOW_FREQUENCY + (() if waves is None else _WAVE) + BIAS_SIGNALS

    def _bias_drive(self) -> tuple[Array, Array]:
        """(decay rate 1 / T_b, intensity's square root sqrt(2 sigma^2 / T_b)), a random
        walk of intensity sigma^2 where T_b is infinite."""
        rate = 1.0 / self.bias_time_constant
        finite = jnp.isfinite(self.bias_time_constant)
        return rate, self.bias_std * jnp.sqrt(jnp.where(finite, 2.0 * rate, 1.0))

    def reference_acceleration(self, state: StrapdownState, reading: Array, noise: Array | None = None) -> Array:
        """The reference point's acceleration in body axes from the IMU's ``reading``
        [f_x, f_y, r_m], its biases removed and the centripetal term of the lever arm put back."""
        white = jnp.zeros(3) if noise is None else noise[:3] * jnp.stack([self.accelerometer_noise, self.accelerometer_noise, self.gyro_noise])
        rate = reading[2] - state.bias[2] - white[2]
        return reading[:2] - state.bias[:2] - white[:2] + rate**2 * self.lever_arm

    def vector_field(self, t: ArrayLike, state: StrapdownState, u: Array, noise: Array) -> StrapdownState:
        """The mechanization of the module docstring, with the reading ``u`` = [f_x, f_y, r_m]."""
        del t
        psi = state.eta[2]
        rate = u[2] - state.bias[2] - self.gyro_noise * noise[2]
        acceleration = self.reference_acceleration(state, u, noise)
        earth = rotate(psi, jnp.concatenate([acceleration, jnp.zeros(1)]))[:2]
        decay, drive = self._bias_drive()
        bias = -decay * state.bias + drive * noise[3:6]
        wave = state.wave_state if self.waves is None else self.waves.derivative(state.wave_state, noise[6:9])
        return StrapdownState(jnp.concatenate([state.velocity, jnp.reshape(rate, (1,))]), earth, bias, wave)

    @initial_values(
        Value("eta", "array", "Position north, east (m) and heading (rad), Earth-fixed.", shape="(3,)"),
        Value("velocity", "array", "Velocity north, east (m/s), Earth-fixed.", shape="(2,)"),
        Value("bias", "array", "The IMU's biases: accelerometers surge, sway (m/s2) and gyro (rad/s).", shape="(3,)"),
        Value("wave_state", "array", "Wave-model state [xi1, xi2] (with waves).", shape="(6,)"),
    )
    def state(
        self, eta: npt.ArrayLike | None = None, velocity: npt.ArrayLike = 0.0, bias: npt.ArrayLike = 0.0, wave_state: npt.ArrayLike = 0.0
    ) -> StrapdownState:
        """A state of this model (zeros where not given).

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            Position north, east (m) and heading (rad), Earth-fixed.
        velocity : array_like, shape (2,)
            Velocity north, east (m/s), Earth-fixed.
        bias : array_like, shape (3,)
            The IMU's biases: accelerometers surge, sway (m/s2) and gyro (rad/s).
        wave_state : array_like, shape (6,)
            Wave-model state [xi1, xi2] (with waves).
        """
        waves = jnp.asarray(check.vector("wave_state", wave_state, 6)) if self.waves is not None else jnp.zeros(0)
        return StrapdownState(
            jnp.asarray(check.vector("eta", 0.0 if eta is None else eta)),
            jnp.asarray(check.vector("velocity", velocity, 2)),
            jnp.asarray(check.vector("bias", bias)),
            waves,
        )

    def body_velocity(self, state: StrapdownState) -> Array:
        """[u, v]: the Earth-fixed velocity in body axes."""
        return rotate_transpose(state.eta[2], jnp.concatenate([state.velocity, jnp.zeros(1)]))[:2]

    def kinematics(self, t: ArrayLike, state: StrapdownState, u: Array) -> dict[str, Array]:
        """What the suite's instruments measure (:func:`lookout.vessel_signals.vessel_kinematics`):
        the wave motion added to position and heading, the rates the IMU's corrected reading."""
        del t
        rate = u[2] - state.bias[2]
        nu = jnp.concatenate([self.body_velocity(state), jnp.reshape(rate, (1,))])
        kinematics = vessel_kinematics(state.eta, state.wave, nu, jnp.zeros(3))
        # the acceleration is the IMU's own (the tangential lever-arm term left out, as in the model)
        kinematics["acceleration"] = self.reference_acceleration(state, u)
        return kinematics

    def normalize(self, state: StrapdownState) -> StrapdownState:
        """Heading wrapped to [-pi, pi)."""
        return eqx.tree_at(lambda s: s.eta, state, state.eta.at[2].set(ssa(state.eta[2])))

    def variables(self, state: StrapdownState) -> dict[str, Array]:
        """Position, heading, body velocity, yaw rate (zero: the model's rate is its input,
        replaced by the filter), the biases and, with waves, the wave motion."""
        named = {
            "position": state.eta[..., :2],
            "heading": state.eta[..., 2],
            "velocity": self.body_velocity(state),
            "yaw_rate": jnp.zeros(()),
            "accelerometer_bias": state.bias[..., :2],
            "gyro_bias": state.bias[..., 2],
        }
        if self.waves is not None:
            named |= {"wave_position": state.wave[..., :2], "wave_heading": state.wave[..., 2]}
        return named

    def models(self) -> tuple:
        """No hull model."""
        return ()

    def realize(self, key: Array) -> StrapdownVessel:
        """No per-run randomness beyond the white noise."""
        del key
        return self


__all__ = ["BIAS_SIGNALS", "IMU_INPUT", "StrapdownState", "StrapdownVessel"]
