"""A vessel without a hull model: its velocities a random walk, and an optional
wave-frequency part.

The kinematics of Fossen & Strand (1999), eq. (1), with nothing known of the vessel's
mass and damping: the body velocity is a slowly varying state driven by white
acceleration (the continuous white noise acceleration model of target tracking,
Bar-Shalom, Li & Kirubarajan (2001), Estimation with Applications to Tracking and
Navigation, Chapter 6)::

    eta' = J(psi) nu
    nu'  = diag(q) w,             w unit white noise (3)

and, in waves, the first-order wave-frequency motion of Fossen & Strand (1999), eqs.
(10)-(11), added to what a position reference and a gyro measure. The thrust is not
an input of the model (a log seldom carries it): an observer on it knows the vessel
only by what it measures (:mod:`lookout.observers.model_free`, whose model this is;
it is not a plant kind of a scenario file).
"""

from __future__ import annotations

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import rotate, ssa
from lookout.components import DivergenceBound, Layout, Plant, Signal
from lookout.declare import Value, initial_values
from lookout.environment import LinearWaveModel
from lookout.vessel_signals import VESSEL_INPUT, VESSEL_SIGNALS, vessel_kinematics

#: The signals of the model: those of a vessel plant but its bias (and, without waves, its wave motion).
_LOW_FREQUENCY = tuple(signal for signal in VESSEL_SIGNALS if not signal.name.startswith(("bias", "wave")))
_WAVE = tuple(signal for signal in VESSEL_SIGNALS if signal.name.startswith("wave"))


class KinematicState(eqx.Module):
    """State of :class:`KinematicVessel`.

    Attributes
    ----------
    eta : Array, shape (3,)
        Earth-fixed low-frequency position and heading [x, y, psi] (m, m, rad).
    nu : Array, shape (3,)
        Body-frame velocities [u, v, r] (m/s, m/s, rad/s).
    wave_state : Array, shape (6,) or (0,)
        The wave model's state [xi1, xi2] (none without waves); the motion is ``xi2``.
    """

    eta: Array
    nu: Array
    wave_state: Array

    @property
    def wave(self) -> Array:
        """The wave-induced motion (zero without waves)."""
        return self.wave_state[..., 3:] if self.wave_state.shape[-1] else jnp.zeros_like(self.eta)


@final
class KinematicVessel(Plant):
    """A vessel without a hull model (module docstring): eta' = J(psi) nu, nu' = diag(q) w.

    The input (thrust) is accepted, as a vessel plant's, and not used. The noise is
    ``[w, the wave model's]``: 3 entries, 6 with waves.

    Parameters
    ----------
    acceleration_std : array_like, shape (3,), non-negative
        q: intensity of the white acceleration of surge, sway and yaw rate (m/s^1.5,
        m/s^1.5, rad/s^1.5).
    waves : LinearWaveModel, optional
        The wave-frequency motion; None for none.
    """

    divergence: ClassVar[DivergenceBound] = DivergenceBound("position", 100.0)

    acceleration_std: Array
    waves: LinearWaveModel | None
    noise_size: int = eqx.field(static=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True, default=VESSEL_INPUT, kw_only=True)

    def __init__(self, acceleration_std: npt.ArrayLike = (0.01, 0.01, 0.001), waves: LinearWaveModel | None = None):
        values = check.vector("acceleration_std", acceleration_std)
        check.positive("acceleration_std", values, allow_zero=True)
        if waves is not None and not isinstance(waves, LinearWaveModel):
            raise ValueError(f"waves must be a linear wave model or None; got {type(waves).__name__}")
        self.acceleration_std = jnp.asarray(values)
        self.waves = waves
        self.noise_size = 3 if waves is None else 6
        self.variable_signals = _LOW_FREQUENCY + (() if waves is None else _WAVE)

    def vector_field(self, t: ArrayLike, state: KinematicState, tau: Array, noise: Array) -> KinematicState:
        """eta' = J(psi) nu, nu' = q w, and the wave model's eq. (11)."""
        del t, tau
        wave = state.wave_state if self.waves is None else self.waves.derivative(state.wave_state, noise[3:6])
        return KinematicState(rotate(state.eta[2], state.nu), self.acceleration_std * noise[:3], wave)

    @initial_values(
        Value("eta", "array", "Position north, east (m) and heading (rad), Earth-fixed.", shape="(3,)"),
        Value("nu", "array", "Velocity surge, sway (m/s) and yaw rate (rad/s), body-fixed.", shape="(3,)"),
        Value("wave_state", "array", "Wave-model state [xi1, xi2] (with waves).", shape="(6,)"),
    )
    def state(self, eta: npt.ArrayLike | None = None, nu: npt.ArrayLike = 0.0, wave_state: npt.ArrayLike = 0.0) -> KinematicState:
        """A state of this model (zeros where not given).

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            Position north, east (m) and heading (rad), Earth-fixed.
        nu : array_like, shape (3,)
            Velocity surge, sway (m/s) and yaw rate (rad/s), body-fixed.
        wave_state : array_like, shape (6,)
            Wave-model state [xi1, xi2] (with waves).
        """
        waves = jnp.asarray(check.vector("wave_state", wave_state, 6)) if self.waves is not None else jnp.zeros(0)
        return KinematicState(jnp.asarray(check.vector("eta", 0.0 if eta is None else eta)), jnp.asarray(check.vector("nu", nu)), waves)

    def kinematics(self, t: ArrayLike, state: KinematicState, tau: Array) -> dict[str, Array]:
        """What a sensor measures (:func:`lookout.vessel_signals.vessel_kinematics`): the
        mean acceleration of a random walk is zero."""
        del t, tau
        return vessel_kinematics(state.eta, state.wave, state.nu, jnp.zeros(3))

    def normalize(self, state: KinematicState) -> KinematicState:
        """Heading wrapped to [-pi, pi)."""
        return eqx.tree_at(lambda s: s.eta, state, state.eta.at[2].set(ssa(state.eta[2])))

    def variables(self, state: KinematicState) -> dict[str, Array]:
        """Position, heading, velocity, yaw rate and, with waves, the wave motion."""
        named = {"position": state.eta[..., :2], "heading": state.eta[..., 2], "velocity": state.nu[..., :2], "yaw_rate": state.nu[..., 2]}
        if self.waves is not None:
            named |= {"wave_position": state.wave[..., :2], "wave_heading": state.wave[..., 2]}
        return named

    def models(self) -> tuple:
        """No hull model."""
        return ()

    def realize(self, key: Array) -> KinematicVessel:
        """No per-run randomness beyond the white noise."""
        del key
        return self


__all__ = ["KinematicState", "KinematicVessel"]
