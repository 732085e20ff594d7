"""The nonlinear PID's family (:mod:`lookout.controllers.pid`): Kp, Kd and Ki of each DOF,
parametrized so that the loop linearized about a setpoint with the controller's own model
is stable by construction DOF by DOF, the coupled and the sampled loop checked.

Per DOF, with m and d the diagonal entries of the controller's M and D, the loop's
characteristic polynomial is m s^3 + (d + kd) s^2 + kp s + ki (the module docstring of
:mod:`lookout.controllers.pid`), which Routh–Hurwitz makes stable iff kp > 0, d + kd > 0 and
0 <= ki < (d + kd) kp / m. The parameters, any real numbers, give exactly these gains::

    kp = exp(a),    kd = -d + exp(b),    ki = (d + kd) kp / m * sigmoid(c)

(kd itself may be negative: the controller may remove part of the vessel's own damping, as
the pole-placement rule does where d exceeds 2 zeta w_n m). An integral gain that is zero in
the scenario stays zero: a PD is a structural choice, not a value to tune.

Checked on every accepted step (:meth:`PidFamily.check`): the per-DOF inequalities as
built, the coupled loop (M, D with their off-diagonal entries: the poles of
:meth:`~lookout.controllers.pid.PidController.closed_loop_poles` in the left half-plane),
and the sampled loop at the scenario's sample period (the spectral radius of
:meth:`~lookout.controllers.pid.PidController.sampled_spectral_radius` below 1).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout.tuning.families import Family, component_as

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.controllers.pid import PidController
    from lookout.sim import Scenario

SOURCE = "Routh-Hurwitz of the loop linearized about a setpoint (lookout.controllers.pid; Fossen 2011, Section 12.2)"
DOF = ("surge", "sway", "yaw")


def _controller(scenario: Scenario) -> PidController:
    from lookout.controllers.pid import PidController

    return component_as(scenario.controller, PidController, "controller")


class PidFamily(Family):
    """Kp, Kd, Ki of the nonlinear PID, stable per DOF by construction (module docstring)."""

    name = "nonlinear PID: Kp > 0, d + Kd > 0, 0 <= Ki < (d + Kd) Kp / m per DOF; the coupled and the sampled loop checked"
    keys = ("controller.proportional_gain", "controller.derivative_gain", "controller.integral_gain")
    design = "the loop's linearization (PidController.closed_loop_poles and sampled_spectral_radius)"

    def __init__(self, scenario: Scenario):
        controller = _controller(scenario)
        self.mass = np.diag(np.asarray(controller.vessel.mass_matrix, dtype=float))
        self.damping = np.diag(np.asarray(controller.vessel.damping_matrix, dtype=float))
        self.integral = np.asarray(controller.integral_gain, dtype=float) > 0
        self.sample_period = float(scenario.sample_period)

    @classmethod
    def of(cls, scenario: Scenario) -> PidFamily:
        return cls(scenario)

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, Array, Array]:
        proportional = jnp.exp(theta[:3])
        loop_damping = jnp.exp(theta[3:6])
        bound = loop_damping * proportional / self.mass
        tuned = np.flatnonzero(self.integral)
        integral = jnp.zeros(3).at[tuned].set(bound[tuned] * jax.nn.sigmoid(theta[6 : 6 + tuned.size]))
        return proportional, loop_damping - self.damping, integral

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        proportional, derivative, integral = (np.asarray(g, dtype=float) * np.ones(3) for g in gains)
        loop_damping = self.damping + derivative
        if np.any(proportional <= 0):
            raise ValueError(f"Routh-Hurwitz: proportional_gain (Kp) must be positive; got {proportional.tolist()}")
        if np.any(loop_damping <= 0):
            raise ValueError(f"Routh-Hurwitz: d + Kd must be positive; got {loop_damping.tolist()}")
        ratio = integral * self.mass / (loop_damping * proportional)
        if np.any(ratio[self.integral] >= 1) or np.any(ratio[self.integral] <= 0):
            raise ValueError(f"Routh-Hurwitz: 0 < Ki < (d + Kd) Kp / m where Ki is tuned; got Ki m / ((d + Kd) Kp) = {ratio.tolist()}")
        tuned = ratio[self.integral]
        return np.concatenate([np.log(proportional), np.log(loop_damping), np.log(tuned / (1.0 - tuned))])

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        return eqx.tree_at(
            lambda s: (s.controller.proportional_gain, s.controller.derivative_gain, s.controller.integral_gain),
            scenario,
            tuple(jnp.broadcast_to(jnp.asarray(g, dtype=float), (3,)) for g in gains),
        )

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        controller = _controller(scenario)
        return tuple(np.asarray(g, dtype=float) for g in (controller.proportional_gain, controller.derivative_gain, controller.integral_gain))

    def check(self, scenario: Scenario) -> Report:
        from lookout.analysis.conditions import Condition, Inequality, Report

        controller = _controller(scenario)
        kp, kd, ki = self.current(scenario)
        loop_damping = self.damping + kd
        per_dof = []
        for i, dof in enumerate(DOF):
            per_dof += [
                Inequality.check(f"{dof}: Kp", "Kp > 0", kp[i], ">", 0.0, units="N/m" if i < 2 else "N m/rad", source=SOURCE, tolerance=0.0),
                Inequality.check(
                    f"{dof}: d + Kd", "d + Kd > 0", loop_damping[i], ">", 0.0, units="N s/m" if i < 2 else "N m s/rad", source=SOURCE, tolerance=0.0
                ),
                Inequality.check(
                    f"{dof}: Ki",
                    "Ki < (d + Kd) Kp / m",
                    ki[i],
                    "<",
                    loop_damping[i] * kp[i] / self.mass[i],
                    units="N/(m s)" if i < 2 else "N m/(rad s)",
                    source=SOURCE,
                ),
            ]
        largest = float(np.max(controller.closed_loop_poles().real))
        radius = controller.sampled_spectral_radius(self.sample_period)
        conditions = [
            Condition(
                "routh_hurwitz",
                "Routh-Hurwitz per DOF",
                "each DOF's loop, linearized about a setpoint with the diagonal of M and D, is stable",
                SOURCE,
                per_dof,
            ),
            Condition(
                "coupled_loop",
                "coupled loop",
                "the loop linearized with M and D coupled (off-diagonal entries) has its poles in the left half-plane",
                SOURCE,
                [Inequality.check("max Re s", "max Re(s) < 0", largest, "<", 0.0, units="1/s", source=SOURCE, tolerance=0.0)],
            ),
            Condition(
                "sampled_loop",
                "sampled loop",
                f"the loop sampled at {self.sample_period:g} s (zero-order hold) is stable",
                SOURCE,
                [Inequality.check("rho", "spectral radius < 1", radius, "<", 1.0, units="1", source=SOURCE, tolerance=0.0)],
            ),
        ]
        poles = np.sort_complex(controller.closed_loop_poles())
        return Report(self.name, conditions, {"closed_loop_poles_real": poles.real.tolist(), "closed_loop_poles_imag": poles.imag.tolist()})
