"""Thrusters as the actuator of a vessel: allocation, thruster response, delivered force."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa
from lookout.actuators.allocation import IDLE, QP_SOLVERS, Allocator
from lookout.actuators.failures import ThrusterFailure, flag_signal
from lookout.actuators.layout import ThrusterLayout, direction_of, magnitude
from lookout.components import BODY_FIXED, Actuator, Layout, Signal
from lookout.declare import NON_NEGATIVE, Part, Range, Value, component, kind_of


def _thruster_signal(name: str, units: str, long_name: str, labels, angle: bool = False) -> Signal:
    return Signal(name, units, long_name, "body-fixed", tuple(labels), "thruster", angle)


#: A :class:`ThrusterSystem`'s state: each thruster's thrust and angle, the previous
#: scaled command, the QP's active set, the steering's filtered demand and whether each
#: azimuth is turning.
ThrusterState = tuple[Array, Array, Array, Array, Array, Array]

#: What the thrusters act on: a 3-DOF vessel's input, (name, units, labels) of each signal.
VESSEL_INPUT_SIGNALS = (("force", "N", ("surge", "sway")), ("moment", "N m", ()))


def describe_input(layout: Layout) -> str:
    """A plant's input in words, for a message: ``joint_torque (N m: shoulder, elbow)``.

    Parameters
    ----------
    layout : Layout
        The plant's input layout (its first four signals are named, and six labels of each).

    Returns
    -------
    str
    """
    parts = []
    for signal in layout.signals[:4]:
        labels = f": {', '.join(signal.labels[:6])}{', ...' if len(signal.labels) > 6 else ''}" if signal.labels else ""
        parts.append(f"{signal.name} ({signal.units}{labels})")
    more = f" and {len(layout.signals) - 4} more" if len(layout.signals) > 4 else ""
    return ", ".join(parts) + more if parts else "no input"


#: A delivered thrust within this fraction of a thruster's largest thrust of a limit
#: is at it: thrust approaches its command through a first-order lag, so it reaches
#: a limit it is commanded to only in the limit of time; 1 % of the largest thrust is
#: within a line's width on the thrusters' figure.
AT_LIMIT = 0.01


def at_limit(thrust: ArrayLike, largest: ArrayLike, smallest: ArrayLike, tolerance: float = AT_LIMIT) -> Array:
    """Whether each thruster's thrust (..., n) is at its ``largest`` or (when negative)
    ``smallest`` thrust (n,), within ``tolerance`` of its largest (JAX, so a campaign's
    metric takes it inside the simulation; NumPy arrays in, JAX arrays out).

    ``time_at_limit:thrust`` is the fraction of the samples with some thruster at a
    limit by this test, on the delivered thrust (the solid curves of ``thrusters.png``
    at the top or bottom of a thruster's range)."""
    thrust, largest, smallest = jnp.asarray(thrust), jnp.asarray(largest), jnp.asarray(smallest)
    margin = tolerance * largest
    return (thrust >= largest - margin) | ((thrust <= smallest + margin) & (smallest < 0))


def relative_power(thrust: ArrayLike, largest: ArrayLike) -> Array:
    """The thrusters' power as a fraction of the installed power, ``thrust`` shaped (..., n).

    A propeller's power at bollard pull grows as |T|^(3/2) (momentum theory,
    P = |T|^(3/2) / sqrt(2 rho A)); with the disc area A of each thruster in
    proportion to its ``largest`` thrust (equal disc loading), thruster i at T_i draws
    (|T_i| / T_max,i)^(3/2) of its installed power, which is in proportion to T_max,i.
    """
    thrust, largest = jnp.asarray(thrust), jnp.asarray(largest)
    return jnp.sum((jnp.abs(thrust) / largest) ** 1.5 * largest, axis=-1) / jnp.sum(largest)


@component(
    "actuator",
    "thrusters",
    summary="A vessel's thrusters between the controller's generalized force and the hull.",
    parameters=(
        Part("layout", "The thrusters."),
        Value("allocation", "str", "Allocation method (lookout.actuators.allocation).", choices=("qp", "pseudo-inverse")),
        Value(
            "slack_weight", "array", '"qp" only: the QP\'s weight of the unproduced force (surge, sway, yaw) against thrust; positive (default 1e6).'
        ),
        Value(
            "clip_to_reach",
            "bool",
            "Clip each axis of the command to what the thrusters reach on it alone before allocating (lookout.actuators.allocation.Allocator).",
        ),
        Value(
            "solver",
            "str",
            '"qp" only: the QP\'s solver (default "active-set"; lookout.actuators.allocation.Allocator).',
            choices=QP_SOLVERS,
        ),
        Value(
            "steering_time_constant",
            "float",
            '"qp" only: time constant of the low-pass filter on the command whose allocation the azimuths turn toward (s; default 10 s, longer than a DP sea\'s wave periods; 0 for none).',
            range=NON_NEGATIVE,
        ),
        Value(
            "steering_deadband",
            "float",
            '"qp" only: how far an azimuth may point from its filtered direction before it turns (rad; default 10 deg, where it still gives 98.5 % of its thrust along it).',
            range=Range(0.0, math.pi, True, True),
        ),
        Value(
            "steering_load",
            "float",
            '"qp" only: the filtered load (fraction of its largest thrust) below which an azimuth holds its angle (default 0.05).',
            range=Range(0.0, 1.0, True, True),
        ),
        Value(
            "steering_bias",
            "float",
            '"qp" only: thrust (fraction of its largest) each azimuth puts along its layout direction, of which the part that produces no force is kept as a bias: azimuths pointing against each other then answer a small force of either sign with thrust, not a turn (default 0.2; 0 for none).',
            range=Range(0.0, 1.0, True, False),
        ),
    ),
)
@final
class ThrusterSystem(Actuator):
    """A vessel's thrusters between the controller's generalized force and the hull.

    At each sample k the commanded tau_k = (X, Y, N) is allocated to the thrusters'
    commands (:class:`~lookout.actuators.allocation.Allocator`; with ``"qp"`` the
    azimuths are first steered toward the filtered demand); each thruster's thrust
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
    sample ``allocation_shortfall`` (the largest part of tau the allocation left
    unproduced, |tau - B u| on an axis as a fraction of that axis's reach; 0 when tau
    is produced), ``allocation_saturated`` (1 when the shortfall is above
    :data:`~lookout.actuators.allocation.SATURATED`, 1 % of the reach: the limits kept
    the allocation from producing tau), and the residual tau - B u itself,
    ``force_shortfall`` (N; surge, sway) and ``moment_shortfall`` (N m). An infeasible
    tau is a shortfall, never a NaN; a NaN command (a failed controller) gives NaN
    thrust, so the run is seen to fail.

    Thruster failures (``failures``, :mod:`lookout.actuators.failures`): while one is
    active, a stopped thruster delivers no thrust and is commanded 0, a stuck one holds
    the thrust and angle it had when the failure began, a reduced one's force limits are
    scaled by its ``fraction``; the allocation re-solves with the thrusters that remain
    (:meth:`~lookout.actuators.allocation.Allocator.allocate`), and the steering turns
    no failed azimuth. Each failure's flag is recorded (``THRUSTER.MODE_failure``, 1
    while it is active).

    Parameters
    ----------
    layout : ThrusterLayout
        The thrusters.
    allocation : {"qp", "pseudo-inverse"}
        Allocation method (:mod:`lookout.actuators.allocation`).
    slack_weight : float or array_like, optional
        ``"qp"`` only: the QP's weight of the unproduced force (surge, sway, yaw) against
        thrust; positive (default 1e6).
    clip_to_reach : bool
        Clip each axis of the command to what the thrusters reach on it alone before
        allocating (:class:`~lookout.actuators.allocation.Allocator`).
    solver : {"active-set", "active-set-general", "qpax"}, optional
        ``"qp"`` only: the QP's solver (default "active-set";
        :class:`~lookout.actuators.allocation.Allocator`).
    steering_time_constant : float, non-negative, optional
        ``"qp"`` only: time constant of the low-pass filter on the command whose
        allocation the azimuths turn toward (s; default 10 s, longer than a DP sea's
        wave periods; 0 for none).
    steering_deadband : float, in [0, pi], optional
        ``"qp"`` only: how far an azimuth may point from its filtered direction before
        it turns (rad; default 10 deg, where it still gives 98.5 % of its thrust along it).
    steering_load : float, in [0, 1], optional
        ``"qp"`` only: the filtered load (fraction of its largest thrust) below which an
        azimuth holds its angle (default 0.05).
    steering_bias : float, in [0, 1), optional
        ``"qp"`` only: thrust (fraction of its largest) each azimuth puts along its
        layout ``direction``, of which the part that produces no force is kept as a
        bias: azimuths pointing against each other then answer a small force of either
        sign with thrust, not a turn (default 0.2; 0 for none).

    Other Parameters
    ----------------
    failures : sequence of ThrusterFailure
        The thrusters' failures (a scenario file's ``[[actuator.failures]]`` tables,
        :func:`lookout.actuators.failures.failure_from_table`); none by default.
    """

    layout: ThrusterLayout
    allocator: Allocator
    failures: tuple[ThrusterFailure, ...]

    #: The functions of the delivered thrust that a campaign's thruster metrics take
    #: (``mean_power:thrust`` and ``time_at_limit:thrust``, :mod:`lookout.scenario.metrics`),
    #: with the thrust limits of :attr:`layout`.
    relative_power = staticmethod(relative_power)
    at_limit = staticmethod(at_limit)

    def __init__(
        self,
        layout: ThrusterLayout,
        allocation: Literal["qp", "pseudo-inverse"] = "qp",
        slack_weight: npt.ArrayLike | None = None,
        clip_to_reach: bool = True,
        solver: Literal["active-set", "active-set-general", "qpax"] | None = None,
        steering_time_constant: float | None = None,
        steering_deadband: float | None = None,
        steering_load: float | None = None,
        steering_bias: float | None = None,
        failures: Sequence[ThrusterFailure] = (),
    ):
        if not isinstance(layout, ThrusterLayout):
            raise check.ParameterError("layout", f"layout must be a ThrusterLayout; got {type(layout).__name__}")
        self.layout = layout
        self.allocator = Allocator(
            layout, allocation, slack_weight, clip_to_reach, solver, steering_time_constant, steering_deadband, steering_load, steering_bias
        )
        for index, failure in enumerate(failures):
            if not isinstance(failure, ThrusterFailure):
                raise check.ParameterError("failures", f"failures[{index}] must be a ThrusterFailure; got {type(failure).__name__}")
            if not 0 <= failure.thruster < layout.size:
                raise check.ParameterError("failures", f"failures[{index}] names thruster {failure.thruster}; the layout has {layout.size}")
        self.failures = tuple(failures)

    def with_failures(self, failures: Sequence[ThrusterFailure]) -> ThrusterSystem:
        """These thrusters with ``failures`` in place of their own (:class:`ThrusterFailure`)."""
        for index, failure in enumerate(failures):
            if not isinstance(failure, ThrusterFailure) or not 0 <= failure.thruster < self.layout.size:
                raise check.ParameterError("failures", f"failures[{index}] is not a ThrusterFailure of this layout's {self.layout.size} thrusters")
        return eqx.tree_at(lambda system: system.failures, self, tuple(failures))

    def _flag_signals(self) -> tuple[Signal, ...]:
        names = self.layout.names
        modes = {i: [f.mode for f in self.failures if f.thruster == i] for i in range(self.layout.size)}
        signals, seen = [], {i: 0 for i in range(self.layout.size)}
        for failure in self.failures:
            i = failure.thruster
            signals.append(flag_signal(names[i], failure.mode, seen[i], modes[i]))
            seen[i] += 1
        return tuple(signals)

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def output_signals(self) -> tuple[Signal, ...]:  # type: ignore[override]  # (read-only: the signals follow from the layout)
        names = self.layout.names
        return (
            _thruster_signal("thrust", "N", "delivered thrust", names),
            _thruster_signal("thrust_commanded", "N", "commanded thrust", names),
            _thruster_signal("thruster_angle", "rad", "thruster angle (azimuth or rudder)", names, angle=True),
            _thruster_signal("thruster_angle_commanded", "rad", "commanded thruster angle (azimuth or rudder)", names, angle=True),
            Signal("allocation_saturated", "1", "allocation short of the commanded force by more than 1 % of the reach (1) or not (0)"),
            Signal("allocation_shortfall", "1", "largest unproduced part of the commanded force, as a fraction of the thrusters' reach on its axis"),
            Signal(
                "force_shortfall",
                "N",
                "commanded force less the force allocated to the available thrusters",
                BODY_FIXED,
                ("surge", "sway"),
                "body_axis",
            ),
            Signal("moment_shortfall", "N m", "commanded moment less the moment allocated to the available thrusters", BODY_FIXED),
        ) + self._flag_signals()

    @property
    def working_nbytes(self) -> int:
        """Bytes one run holds while stepping: the allocation's matrices and one sample's
        work (:func:`lookout.actuators.allocation.working_nbytes`), and the state."""
        return self.allocator.working_nbytes + 8 * (4 * self.layout.size + 3 * self.allocator.size + 3)

    def plant_input_refusal(self, plant_input: Layout, plant_kind: str) -> str | None:
        """Why these thrusters cannot drive a plant whose input is ``plant_input`` (its
        kind ``plant_kind`` for the message), or None when they can: they produce a 3-DOF
        vessel's force (surge, sway) and moment (yaw)."""
        given = tuple((s.name, s.units, tuple(s.labels)) for s in plant_input.signals)
        if given == VESSEL_INPUT_SIGNALS:
            return None
        return f"actuator {kind_of(self)} needs a 3-DOF vessel plant (force surge, sway; moment yaw); plant {plant_kind} takes {describe_input(plant_input)}"

    def init(self) -> ThrusterState:
        """Every thruster idle: zero thrust, rudders amidships, azimuths pointing where
        their bias points (along their layout ``direction`` without one); no previous
        command, no active set (the QP's warm start), no demand and no azimuth turning
        (the steering's state)."""
        layout, allocator = self.layout, self.allocator
        angle = jnp.where(jnp.asarray(layout.is_kind("main")), 0.0, jnp.asarray(layout.direction, dtype=float))
        index = allocator.indices
        if allocator.bias is not None and index.azimuth.size:
            bx, by = allocator.bias[index.azimuth_x], allocator.bias[index.azimuth_y]
            biased = magnitude(bx, by) > IDLE
            angle = angle.at[index.azimuth].set(jnp.where(biased, direction_of(bx, by, angle[index.azimuth]), angle[index.azimuth]))
        return (
            jnp.zeros(layout.size),
            angle,
            jnp.zeros(allocator.size),
            jnp.full(allocator.size, -1),
            jnp.zeros(3),
            jnp.zeros(layout.size, dtype=bool),
        )

    def commands(self, u: Array, angle: Array, preferred: Array) -> tuple[Array, Array]:
        """Each thruster's commanded thrust (N) and angle (rad) from the scaled allocation
        ``u``, with the azimuths at ``angle`` (the steered angle with ``"qp"``, the
        current one with ``"pseudo-inverse"``).

        ``"qp"``: an azimuth's command is its thrust along its steered angle, and that
        angle. ``"pseudo-inverse"``: an azimuth turns toward its force, or, idle, toward
        its force in the scaled ``preferred`` allocation (the unconstrained one); an
        angle left undefined holds ``angle``."""
        layout, allocator, index = self.layout, self.allocator, self.allocator.indices
        physical = u * allocator.scale
        thrust = jnp.zeros(layout.size)
        target = jnp.asarray(layout.direction, dtype=float)
        if index.tunnel.size:
            thrust = thrust.at[index.tunnel].set(physical[index.tunnel_thrust])
        if index.azimuth.size:
            i, jx, jy = index.azimuth, index.azimuth_x, index.azimuth_y
            fx, fy = physical[jx], physical[jy]
            size = magnitude(fx, fy)
            thrust = thrust.at[i].set(size)
            if allocator.method == "qp":
                target = target.at[i].set(angle[i])
            else:
                wished = preferred * allocator.scale
                wx, wy = wished[jx], wished[jy]
                largest = jnp.asarray(layout.max_thrust[i])
                idle = size <= IDLE * largest
                wanted = magnitude(wx, wy) > IDLE * largest
                target = target.at[i].set(
                    jnp.where(~idle, direction_of(fx, fy, angle[i]), jnp.where(wanted, direction_of(wx, wy, angle[i]), angle[i]))
                )
        if index.main.size:
            i = index.main
            value, lift = physical[index.main_thrust], physical[index.main_lift]
            thrust = thrust.at[i].set(value)
            largest, coefficient, rudder = jnp.asarray(layout.max_thrust[i]), jnp.asarray(layout.rudder_lift[i]), jnp.asarray(layout.max_rudder[i])
            ahead = value > IDLE * largest
            gain = coefficient * jnp.where(ahead, value, 1.0)
            angle_wanted = jnp.where(ahead & (coefficient > 0), lift / jnp.where(gain > 0, gain, 1.0), angle[i])
            target = target.at[i].set(jnp.clip(angle_wanted, -rudder, rudder))
        return thrust, target

    def respond(self, thrust: Array, angle: Array, thrust_command: Array, angle_command: Array, dt: ArrayLike) -> tuple[Array, Array]:
        """The thrusters' thrust and angle after ``dt`` from ``thrust`` and ``angle``
        toward the commands (first-order lag, rate and force limits, turning rate)."""
        layout = self.layout
        tau = jnp.asarray(layout.time_constant)
        lag = jnp.where(tau > 0, -jnp.expm1(-jnp.asarray(dt) / jnp.where(tau > 0, tau, 1.0)), 1.0)
        change = jnp.clip(lag * (thrust_command - thrust), -layout.thrust_rate * dt, layout.thrust_rate * dt)
        thrust = jnp.clip(thrust + change, layout.min_thrust, layout.max_thrust)
        turn = jnp.clip(ssa(angle_command - angle), -layout.turn_rate * dt, layout.turn_rate * dt)
        main = jnp.asarray(layout.is_kind("main"))
        tunnel = jnp.asarray(layout.is_kind("tunnel"))
        turned = jnp.where(main, jnp.clip(angle + turn, -layout.max_rudder, layout.max_rudder), ssa(angle + turn))
        return thrust, jnp.where(tunnel, jnp.asarray(layout.direction, dtype=float), turned)

    def step(self, state: ThrusterState, t: ArrayLike, u: Array, dt: ArrayLike) -> tuple[ThrusterState, Array, dict[str, Array]]:
        """Allocate ``u`` = (X, Y, N), move the thrusters over ``dt``; see the class docstring."""
        if jnp.shape(u) != (3,):
            raise check.ParameterError(
                "thrusters", f"thrusters take a 3-DOF vessel's force (surge, sway) and moment (yaw), 3 entries; got an input of shape {jnp.shape(u)}"
            )
        thrust, angle, previous, working, demand, turning = state
        held_thrust, held_angle = thrust, angle
        fraction, frozen, flags = self.availability(t)
        if fraction is not None and frozen is not None:
            owner = np.asarray([i for i, _ in self.layout.variables], dtype=int)
            # a stuck thruster's previous command is the force it holds: its limits pin it there
            previous = jnp.where(frozen[owner], self.extended(thrust, angle), previous)
        steered = angle
        if self.allocator.method == "qp":
            demand, steered, turning = self.allocator.steer(demand, angle, turning, u, dt, fraction, frozen, previous)
        allocated, info = self.allocator.allocate(u, previous, steered, dt, working, fraction, frozen)
        thrust_command, angle_command = self.commands(allocated, steered, info["unconstrained"])
        thrust, angle = self.respond(thrust, angle, thrust_command, angle_command, dt)
        if fraction is not None and frozen is not None:
            share = fraction
            thrust = jnp.clip(thrust, share * self.layout.min_thrust, share * self.layout.max_thrust)
            thrust = jnp.where(frozen & (share > 0.0), held_thrust, thrust)
            angle = jnp.where(frozen, held_angle, angle)
            thrust_command = jnp.where(share == 0.0, 0.0, thrust_command)
        applied = self.layout.forces(thrust, angle)
        residual = info["residual"]
        outputs = {
            "thrust": thrust,
            "thrust_commanded": thrust_command,
            "thruster_angle": angle,
            "thruster_angle_commanded": angle_command,
            "allocation_saturated": info["saturated"].astype(float),
            "allocation_shortfall": info["shortfall"],
            "force_shortfall": residual[:2],
            "moment_shortfall": residual[2],
        }
        outputs.update({signal.name: flag for signal, flag in zip(self._flag_signals(), flags)})
        return (thrust, angle, allocated, info["working"], demand, turning), applied, outputs

    def availability(self, t: ArrayLike) -> tuple[Array | None, Array | None, list[Array]]:
        """``(fraction, frozen, flags)`` at ``t``: each thruster's share of its force
        limits (0 stopped, 1 intact; a reduced one's ``fraction``), whether it is stuck,
        and each failure's flag (1.0 while active); ``(None, None, [])`` without failures
        (the allocation then is the intact one's program)."""
        if not self.failures:
            return None, None, []
        fraction = jnp.ones(self.layout.size)
        frozen = jnp.zeros(self.layout.size, dtype=bool)
        flags = []
        for failure in self.failures:
            on = failure.active(t)
            i = failure.thruster
            if failure.mode == "stop":
                fraction = fraction.at[i].set(jnp.where(on, 0.0, fraction[i]))
            elif failure.mode == "reduced":
                fraction = fraction.at[i].set(jnp.where(on, jnp.minimum(fraction[i], failure.fraction), fraction[i]))
            else:
                frozen = frozen.at[i].set(frozen[i] | on)
            flags.append(on.astype(float))
        return fraction, frozen, flags

    def extended(self, thrust: Array, angle: Array) -> Array:
        """The scaled extended variables (:attr:`Allocator.B`'s) of the thrusters at
        ``thrust`` and ``angle``: a tunnel's thrust, an azimuth's force components, a main
        propeller's thrust and rudder lift."""
        layout, allocator, index = self.layout, self.allocator, self.allocator.indices
        u = jnp.zeros(allocator.size)
        if index.tunnel.size:
            u = u.at[index.tunnel_thrust].set(thrust[index.tunnel])
        if index.azimuth.size:
            i = index.azimuth
            u = u.at[index.azimuth_x].set(thrust[i] * jnp.cos(angle[i])).at[index.azimuth_y].set(thrust[i] * jnp.sin(angle[i]))
        if index.main.size:
            i = index.main
            lift = jnp.asarray(layout.rudder_lift[i]) * angle[i] * jnp.maximum(thrust[i], 0.0)
            u = u.at[index.main_thrust].set(thrust[i]).at[index.main_lift].set(lift)
        return u / allocator.scale
