"""Thrusters as the actuator of a vessel: allocation, thruster response, delivered force."""

from __future__ import annotations

from typing import Literal, final

import jax.numpy as jnp
from jax import Array

from lookout._math import ssa
from lookout.actuators.allocation import IDLE, Allocator
from lookout.actuators.layout import ThrusterLayout, direction_of, magnitude
from lookout.components import Actuator, Signal



def _thruster_signal(name: str, units: str, long_name: str, labels, angle: bool = False) -> Signal:
    return Signal(name, units, long_name, "body-fixed", tuple(labels), "thruster", angle)


@final
class ThrusterSystem(Actuator):
    """A vessel's thrusters between the controller's generalized force and the hull.

    At each sample k the commanded tau_k = (X, Y, N) is allocated to the thrusters'
    commands (:class:`~lookout.actuators.allocation.Allocator`); each thruster's thrust
    then moves toward its command as a first-order lag over the sample,
    T_k+1 = T_k + (1 - exp(-dt / time_constant)) (T_cmd - T_k), limited to
    ``thrust_rate`` dt and to its force limits, and an azimuth's angle or a rudder turns
    toward its commanded angle by at most ``turn_rate`` dt (the shorter way). The
    applied input over [t_k, t_k+1] is the generalized force of the thrusters at
    t_k+1 (:meth:`ThrusterLayout.forces`): with a time constant of 0 and no rate limit
    binding, it is the allocated force at once, as the ideal actuator's would be.

    Recorded per thruster (dimension ``thruster``): ``thrust`` and
    ``thrust_commanded`` (N), ``thruster_angle`` and ``thruster_angle_commanded``
    (rad: an azimuth's angle, a rudder's angle, a tunnel's fixed direction); and per
    sample ``allocation_saturated`` (1 when the unconstrained allocation broke a limit)
    and ``allocation_shortfall`` (the largest part of tau left unproduced, as a
    fraction of each axis's reach; 0 when tau is produced). An infeasible tau is a
    shortfall, never a NaN; a NaN command (a failed controller) gives NaN thrust, so
    the run is seen to fail.

    Parameters
    ----------
    layout : ThrusterLayout
        The thrusters.
    allocation : {"qp", "pseudo-inverse"}
        Allocation method (:mod:`lookout.actuators.allocation`).
    slack_weight : float or array_like
        The QP's weight of the unproduced force (surge, sway, yaw) against thrust;
        positive.
    polygon_sides : int
        Sides of the polygon inside an azimuth's thrust circle in the QP; at least 4.
    clip_to_reach : bool
        Clip each axis of the command to what the thrusters reach on it alone before
        allocating (:class:`~lookout.actuators.allocation.Allocator`).
    solver : {"active-set", "qpax"}
        The QP's solver (:class:`~lookout.actuators.allocation.Allocator`).
    """

    layout: ThrusterLayout
    allocator: Allocator

    def __init__(self, layout: ThrusterLayout, allocation: Literal["qp", "pseudo-inverse"] = "qp", slack_weight=1e6, polygon_sides: int = 16,
                 clip_to_reach: bool = True, solver: Literal["active-set", "qpax"] = "active-set"):
        if not isinstance(layout, ThrusterLayout):
            raise ValueError(f"layout must be a ThrusterLayout; got {type(layout).__name__}")
        self.layout = layout
        self.allocator = Allocator(layout, allocation, slack_weight, polygon_sides, clip_to_reach, solver)

    @property
    def output_signals(self) -> tuple[Signal, ...]:
        names = self.layout.names
        return (
            _thruster_signal("thrust", "N", "delivered thrust", names),
            _thruster_signal("thrust_commanded", "N", "commanded thrust", names),
            _thruster_signal("thruster_angle", "rad", "thruster angle (azimuth or rudder)", names, angle=True),
            _thruster_signal("thruster_angle_commanded", "rad", "commanded thruster angle (azimuth or rudder)", names, angle=True),
            Signal("allocation_saturated", "1", "allocation limited by a thruster limit (1) or not (0)"),
            Signal("allocation_shortfall", "1", "largest unproduced part of the commanded force, as a fraction of the thrusters' reach"),
        )

    def init(self):
        """Every thruster idle: zero thrust, azimuths at their initial angle, rudders
        amidships; no previous command, no active set (the QP's warm start)."""
        layout = self.layout
        angle = jnp.where(jnp.asarray(layout.is_kind("main")), 0.0, jnp.asarray(layout.direction, dtype=float))
        return jnp.zeros(layout.size), angle, jnp.zeros(self.allocator.size), jnp.full(self.allocator.size, -1)

    def commands(self, u: Array, angle: Array, preferred: Array) -> tuple[Array, Array]:
        """Each thruster's commanded thrust (N) and angle (rad) from the scaled allocation
        ``u``. An idle azimuth turns toward its force in the scaled ``preferred``
        allocation (the unconstrained one); an angle left undefined holds ``angle``."""
        layout, allocator = self.layout, self.allocator
        physical = u * allocator.scale
        wished = preferred * allocator.scale
        thrust, target = [], []
        for i, kind in enumerate(layout.kinds):
            if kind == "azimuth":
                fx = physical[layout.variables.index((i, "x"))]
                fy = physical[layout.variables.index((i, "y"))]
                size = magnitude(fx, fy)
                wx, wy = wished[layout.variables.index((i, "x"))], wished[layout.variables.index((i, "y"))]
                idle = size <= IDLE * layout.max_thrust[i]
                wanted = magnitude(wx, wy) > IDLE * layout.max_thrust[i]
                thrust.append(size)
                target.append(jnp.where(~idle, direction_of(fx, fy, angle[i]), jnp.where(wanted, direction_of(wx, wy, angle[i]), angle[i])))
                continue
            value = physical[layout.variables.index((i, "thrust"))]
            thrust.append(value)
            if kind == "main":
                lift = physical[layout.variables.index((i, "lift"))]
                ahead = value > IDLE * layout.max_thrust[i]
                gain = layout.rudder_lift[i] * jnp.where(ahead, value, 1.0)
                rudder = jnp.where(ahead & (layout.rudder_lift[i] > 0), lift / jnp.where(gain > 0, gain, 1.0), angle[i])
                target.append(jnp.clip(rudder, -layout.max_rudder[i], layout.max_rudder[i]))
            else:
                target.append(jnp.asarray(layout.direction[i], dtype=float))
        return jnp.stack(thrust), jnp.stack(target)

    def respond(self, thrust: Array, angle: Array, thrust_command: Array, angle_command: Array, dt) -> tuple[Array, Array]:
        """The thrusters' thrust and angle after ``dt`` from ``thrust`` and ``angle``
        toward the commands (first-order lag, rate and force limits, turning rate)."""
        layout = self.layout
        tau = jnp.asarray(layout.time_constant)
        lag = jnp.where(tau > 0, -jnp.expm1(-dt / jnp.where(tau > 0, tau, 1.0)), 1.0)
        change = jnp.clip(lag * (thrust_command - thrust), -layout.thrust_rate * dt, layout.thrust_rate * dt)
        thrust = jnp.clip(thrust + change, layout.min_thrust, layout.max_thrust)
        turn = jnp.clip(ssa(angle_command - angle), -layout.turn_rate * dt, layout.turn_rate * dt)
        main = jnp.asarray(layout.is_kind("main"))
        tunnel = jnp.asarray(layout.is_kind("tunnel"))
        turned = jnp.where(main, jnp.clip(angle + turn, -layout.max_rudder, layout.max_rudder), ssa(angle + turn))
        return thrust, jnp.where(tunnel, jnp.asarray(layout.direction, dtype=float), turned)

    def step(self, state, t, u: Array, dt):
        """Allocate ``u`` = (X, Y, N), move the thrusters over ``dt``; see the class docstring."""
        thrust, angle, previous, working = state
        allocated, info = self.allocator.allocate(u, previous, angle, dt, working)
        thrust_command, angle_command = self.commands(allocated, angle, info["unconstrained"])
        thrust, angle = self.respond(thrust, angle, thrust_command, angle_command, dt)
        applied = self.layout.forces(thrust, angle)
        outputs = {
            "thrust": thrust,
            "thrust_commanded": thrust_command,
            "thruster_angle": angle,
            "thruster_angle_commanded": angle_command,
            "allocation_saturated": info["saturated"].astype(float),
            "allocation_shortfall": info["shortfall"],
        }
        return (thrust, angle, allocated, info["working"]), applied, outputs


def at_limit(thrust, largest, smallest, tolerance: float = 1e-6):
    """Whether each thruster's thrust (..., n) is at its ``largest`` or (when negative)
    ``smallest`` thrust (n,), within ``tolerance`` of its largest (JAX, so a campaign's
    metric takes it inside the simulation; NumPy arrays in, JAX arrays out)."""
    thrust, largest, smallest = jnp.asarray(thrust), jnp.asarray(largest), jnp.asarray(smallest)
    margin = tolerance * largest
    return (thrust >= largest - margin) | ((thrust <= smallest + margin) & (smallest < 0))


def relative_power(thrust, largest):
    """The thrusters' power as a fraction of the installed power, ``thrust`` shaped (..., n).

    A propeller's power at bollard pull grows as |T|^(3/2) (momentum theory,
    P = |T|^(3/2) / sqrt(2 rho A)); with the disc area A of each thruster in
    proportion to its ``largest`` thrust (equal disc loading), thruster i at T_i draws
    (|T_i| / T_max,i)^(3/2) of its installed power, which is in proportion to T_max,i.
    """
    thrust, largest = jnp.asarray(thrust), jnp.asarray(largest)
    return jnp.sum((jnp.abs(thrust) / largest) ** 1.5 * largest, axis=-1) / jnp.sum(largest)
