"""The signals of a dynamically positioned vessel: its state's variables and its input,
by name, unit and frame.

The vessel models (:mod:`lookout.models.vessel`, :mod:`lookout.models.cybership`)
record these, and the references that a vessel tracks (:mod:`lookout.reference`) name
their desired position and heading after them; so they are defined here, beside the
contract, and neither needs the other. :mod:`lookout.models.vessel` re-exports them.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp

from lookout.components import BODY_FIXED, EARTH_FIXED, Layout, Signal

#: The degrees of freedom, in the order of eta, nu and tau.
DOF = ("surge", "sway", "yaw")
#: Labels of the horizontal axes: Earth-fixed (position, bias, waves) and body-fixed (velocity, thrust).
EARTH_AXES = ("north", "east")
BODY_AXES = ("surge", "sway")


def _earth(name: str, units: str, long_name: str) -> Signal:
    return Signal(name, units, long_name, EARTH_FIXED, EARTH_AXES, "earth_axis")


def _body(name: str, units: str, long_name: str) -> Signal:
    return Signal(name, units, long_name, BODY_FIXED, BODY_AXES, "body_axis")


#: The recorded quantities of a vessel state (and of an observer's estimate of it):
#: eta, nu, b and eta_w of Fossen & Strand (1999), split so that each has one unit.
VESSEL_SIGNALS = (
    _earth("position", "m", "low-frequency position"),
    Signal("heading", "rad", "low-frequency heading", EARTH_FIXED, angle=True),
    _body("velocity", "m/s", "linear velocity"),
    Signal("yaw_rate", "rad/s", "yaw rate", BODY_FIXED),
    _earth("bias_force", "N", "bias force"),
    Signal("bias_moment", "N m", "bias moment about the vertical axis", EARTH_FIXED),
    _earth("wave_position", "m", "first-order wave-induced position"),
    Signal("wave_heading", "rad", "first-order wave-induced heading", EARTH_FIXED, angle=True),
)
#: Control forces and moment tau (body-fixed).
VESSEL_INPUT = Layout((_body("force", "N", "thrust force"), Signal("moment", "N m", "thrust moment about the vertical axis", BODY_FIXED)))


#: What a vessel's sensors can measure (:meth:`kinematics` of the vessel plants), by
#: name: a GNSS receiver, a gyrocompass, a speed sensor and an IMU read these.
VESSEL_KINEMATICS = (
    "position",
    "heading",
    "velocity",
    "yaw_rate",
    "acceleration",
    "yaw_acceleration",
)


def vessel_kinematics(eta: Any, wave: Any, nu: Any, nu_rate: Any) -> dict[str, Any]:
    """The kinematics of a 3-DOF vessel at its reference point, from eta (m, m, rad),
    the wave-induced motion eta_w, the body-fixed velocity nu = [u, v, r] and its time
    derivative.

    ``position`` (north, east) and ``heading`` are the total motion eta + eta_w (what a
    GNSS antenna and a gyrocompass see; heading wrapped by the sensor), ``velocity``
    (surge, sway) and ``yaw_rate`` the low-frequency nu; ``acceleration`` is the
    inertial acceleration of the reference point in body axes,
    ``[u' - r v, v' + r u]`` (the derivative of R(psi) [u, v] rotated back to the
    body: what an accelerometer's horizontal axes feel), and ``yaw_acceleration`` r'.
    The wave-frequency motion is a position-level model here, so the rates and
    accelerations are those of the low-frequency motion.
    """
    total = eta + wave
    r = nu[..., 2]
    return {
        "position": total[..., :2],
        "heading": total[..., 2],
        "velocity": nu[..., :2],
        "yaw_rate": r,
        "acceleration": nu_rate[..., :2] + r[..., None] * jnp.stack([-nu[..., 1], nu[..., 0]], axis=-1),
        "yaw_acceleration": nu_rate[..., 2],
    }
