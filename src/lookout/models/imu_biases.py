"""A plant model with an IMU's biases as states: what a model-based observer needs to read
a suite's IMU as a measurement of its model's acceleration (acceleration feedback).

A DP observer built on a hull model can take the IMU's specific force as a measurement
of the acceleration its model predicts, as Lindegaard & Fossen (2001), "A model based
wave filter for surface vessels using position, velocity and partial acceleration
feedback" (Proc. 40th IEEE Conference on Decision and Control), feed measured
acceleration to the model-based DP observer. An accelerometer's bias then enters the
model as a constant force of M b: over minutes without position references it moves
the estimate as far as the bias would move the vessel. So the biases are states::

    x_a = (x, b),   b = [b_ax, b_ay, b_g]' = diag(q_b) w_b      (random walks)

and the IMU reads the model's kinematics with them: specific force ``a + b_a`` (at its
lever arm) and yaw rate ``r + b_g`` (:class:`~lookout.sensing.motion.InertialUnit`
adds the ``accelerometer_bias`` and ``gyro_bias`` the kinematics carry); every other
instrument reads the model as before. One IMU per suite: every IMU reads the same biases.
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import BODY_FIXED, DivergenceBound, Layout, Plant, Signal
from lookout.declare import Value, initial_values
from lookout.vessel_signals import BODY_AXES

#: The estimated biases, recorded beside the plant's variables.
BIAS_SIGNALS = (
    Signal("accelerometer_bias", "m/s2", "accelerometer bias (surge, sway)", BODY_FIXED, BODY_AXES, "body_axis"),
    Signal("gyro_bias", "rad/s", "rate gyro bias", BODY_FIXED),
)
#: The keyword of :meth:`ImuBiases.state` for the biases.
BIAS_PART = "imu_bias"


class BiasedState(eqx.Module):
    """The wrapped plant's state and the IMU's biases [b_ax, b_ay, b_g]."""

    plant: Any
    bias: Array


@final
class ImuBiases(Plant):
    """``plant`` with the IMU's biases as random-walk states (module docstring).

    Parameters
    ----------
    plant : Plant
        The model, with kinematics (a vessel).
    bias_noise : array_like, shape (3,), non-negative
        sqrt of the random walks' intensities [accelerometers (m/s2/sqrt(s)) x2, gyro
        (rad/s/sqrt(s))].
    """

    divergence: ClassVar[DivergenceBound | None] = None

    plant: Plant
    bias_noise: Array
    noise_size: int = eqx.field(static=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)

    def __init__(self, plant: Plant, bias_noise: npt.ArrayLike):
        if getattr(plant, "kinematics", None) is None:
            raise check.ParameterError("plant", f"plant {type(plant).__name__} gives no kinematics for an IMU to measure")
        noise = check.vector("imu_bias", bias_noise)
        check.positive("imu_bias", noise, allow_zero=True)
        self.plant = plant
        self.bias_noise = jnp.asarray(noise)
        self.noise_size = plant.noise_size + 3
        self.variable_signals = tuple(plant.variable_signals) + BIAS_SIGNALS
        self.input_layout = plant.input_layout

    def vector_field(self, t: ArrayLike, state: BiasedState, u: Array, noise: Array) -> BiasedState:
        inner = self.plant.noise_size
        return BiasedState(self.plant.vector_field(t, state.plant, u, noise[:inner]), self.bias_noise * noise[inner : inner + 3])

    def state_parameters(self) -> dict[str, inspect.Parameter]:
        """The wrapped plant's ``state`` keywords and :data:`BIAS_PART`."""
        parameters = dict(inspect.signature(self.plant.state).parameters)
        parameters[BIAS_PART] = inspect.Parameter(BIAS_PART, inspect.Parameter.KEYWORD_ONLY, default=0.0)
        return parameters

    @initial_values(
        same_as="plant.state",
        extra=(Value(BIAS_PART, "array", "The IMU's biases [accelerometers (m/s2) x2, gyro (rad/s)] (default 0).", shape="(3,)"),),
    )
    def state(self, *args: Any, imu_bias: npt.ArrayLike = 0.0, **parts: Any) -> BiasedState:
        """The wrapped plant's state from ``parts`` and the biases ``imu_bias`` (zero
        unless given; a scenario file's ``[observer.initial]`` table takes the wrapped
        plant's keys)."""
        return BiasedState(self.plant.state(*args, **parts), jnp.asarray(check.vector(BIAS_PART, imu_bias)))

    def kinematics(self, t: ArrayLike, state: BiasedState, u: Array) -> dict[str, Array]:
        """The wrapped plant's, with the biases an IMU adds to what it reads."""
        kinematics = dict(self.plant.kinematics(t, state.plant, u))  # type: ignore[attr-defined]
        kinematics["accelerometer_bias"] = state.bias[:2]
        kinematics["gyro_bias"] = state.bias[2]
        return kinematics

    def normalize(self, state: BiasedState) -> BiasedState:
        return BiasedState(self.plant.normalize(state.plant), state.bias)

    def variables(self, state: BiasedState) -> dict[str, Array]:
        return {**self.plant.variables(state.plant), "accelerometer_bias": state.bias[..., :2], "gyro_bias": state.bias[..., 2]}

    def models(self) -> tuple:
        return self.plant.models()

    def realize(self, key: Array) -> ImuBiases:
        return eqx.tree_at(lambda m: m.plant, self, self.plant.realize(key))


__all__ = ["BIAS_PART", "BIAS_SIGNALS", "BiasedState", "ImuBiases"]
