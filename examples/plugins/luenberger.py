"""A Luenberger observer for a DP vessel, written as a lookout plugin: one file.

The observer estimates the low-frequency position and heading eta, the body-frame
velocity nu and an Earth-fixed bias b from position and heading fixes, on the vessel's
own model M nu' + D nu = tau + R(psi)^T b (Fossen & Strand 1999, eqs. (3)-(7), without
their wave filter):

    eta_hat' = R(psi) nu_hat + L1 e
    nu_hat'  = M^-1 (tau - D nu_hat + R(psi)^T (b_hat + L2 e))
    b_hat'   = L3 e,                   e = y - eta_hat  (heading entry wrapped)

with diagonal L1, L2, L3. This is Luenberger's (1971) observer of the model linearized
at a fixed heading: per DOF (M, D diagonal) its error obeys

    s^3 + (l1 + d/m) s^2 + (l1 d + l2) / m s + l3 / m = 0,

and the rule ``poles`` places the three poles of each DOF at -bandwidth:
l1 = 3 w - d/m, l2 = 3 m w^2 - l1 d, l3 = m w^3. The placement is exact for surge and sway
at headings where R mixes them only when their m and d agree; between the two it is a
design at psi = 0. Without a wave filter, the first-order wave motion reaches the
estimates: pick a bandwidth well below the wave frequency (waves at 0.9 rad/s: 0.05 rad/s).

A scenario names this file (``plugins = ["plugins/luenberger.py"]``, relative to the
scenario) and uses ``kind = "luenberger"``; ``lookout components --plugin`` lists it. See
examples/luenberger-dp.toml. It imports what a plugin needs of lookout from the public
modules: the declarations, checks, kinematics and the sampled integration from
:mod:`lookout.plugin`, the contract from :mod:`lookout.components`.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout.components import ContinuousObserver, Layout
from lookout.models.vessel import VESSEL_INPUT, VESSEL_SIGNALS, DPVessel
from lookout.plugin import (
    POSITIVE,
    ParameterError,
    Part,
    Rule,
    Value,
    check,
    component,
    from_first_measurement,
    initial_values,
    integrate_sample,
    matvec,
    rotate,
    rotate_transpose,
    ssa,
)
from lookout.sensors import POSITION_HEADING


class LuenbergerEstimate(eqx.Module):
    """eta_hat (m, m, rad), nu_hat (m/s, m/s, rad/s), b_hat (N, N, N m)."""

    eta: Array
    nu: Array
    bias: Array


@component(
    "observer",
    "luenberger",
    summary="Luenberger observer of the vessel's low-frequency model: position, velocity and bias, no wave filter.",
    rules={
        "poles": Rule(
            "design",
            (
                Part("vessel", "The observer's vessel model (M, D); in a composition, the plant's unless given."),
                Value("bandwidth", "array", "The observer's poles per DOF, all three at -bandwidth (rad/s).", shape="(3,)", range=POSITIVE),
                Value("steps_per_sample", "int", "RK4 steps of predict per sample period.", range=POSITIVE),
            ),
        ),
        "gains": Rule(
            None,
            (
                Part("vessel", "The observer's vessel model (M, D); in a composition, the plant's unless given."),
                Value("position_gain", "array", "Diagonal of L1 (1/s).", shape="(3,)", range=POSITIVE),
                Value("velocity_gain", "array", "Diagonal of L2 (N/m, N/m, N m/rad).", shape="(3,)"),
                Value("bias_gain", "array", "Diagonal of L3 (N/(m s), N/(m s), N m/(rad s)).", shape="(3,)", range=POSITIVE),
                Value("steps_per_sample", "int", "RK4 steps of predict per sample period.", range=POSITIVE),
            ),
        ),
    },
)
class LuenbergerObserver(ContinuousObserver):
    """Luenberger observer of a DP vessel's low-frequency model (module docstring).

    Parameters
    ----------
    vessel : DPVessel
        The observer's vessel model (M, D); in a composition, the plant's unless given.
    position_gain : array_like, shape (3,), positive
        Diagonal of L1 (1/s).
    velocity_gain : array_like, shape (3,)
        Diagonal of L2 (N/m, N/m, N m/rad).
    bias_gain : array_like, shape (3,), positive
        Diagonal of L3 (N/(m s), N/(m s), N m/(rad s)).
    steps_per_sample : int, positive
        RK4 steps of predict per sample period.
    """

    mass_matrix: Array
    damping_matrix: Array
    mass_inverse: Array
    position_gain: Array
    velocity_gain: Array
    bias_gain: Array
    steps_per_sample: int = eqx.field(static=True)
    estimate_signals: tuple = eqx.field(static=True)
    extra_signals: tuple = eqx.field(static=True)
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    sample_period: None = eqx.field(static=True)

    def __init__(self, vessel: DPVessel, position_gain, velocity_gain, bias_gain, steps_per_sample: int = 1):
        self.mass_matrix = jnp.asarray(vessel.mass_matrix, dtype=float)
        self.damping_matrix = jnp.asarray(vessel.damping_matrix, dtype=float)
        self.mass_inverse = jnp.linalg.inv(self.mass_matrix)
        self.position_gain = jnp.asarray(check.vector("position_gain", position_gain), dtype=float)
        self.velocity_gain = jnp.asarray(check.vector("velocity_gain", velocity_gain), dtype=float)
        self.bias_gain = jnp.asarray(check.vector("bias_gain", bias_gain), dtype=float)
        check.positive("position_gain", self.position_gain)
        check.positive("bias_gain", self.bias_gain)
        if not (isinstance(steps_per_sample, int) and steps_per_sample >= 1):
            raise ParameterError("steps_per_sample", f"steps_per_sample must be a positive integer; got {steps_per_sample!r}")
        self.steps_per_sample = steps_per_sample
        self.estimate_signals = VESSEL_SIGNALS[:6]  # position, heading, velocity, yaw rate, bias force and moment
        self.extra_signals = ()
        self.measurement_layout, self.input_layout, self.sample_period = POSITION_HEADING, VESSEL_INPUT, None

    @classmethod
    def design(cls, vessel: DPVessel, bandwidth=(0.05, 0.05, 0.05), steps_per_sample: int = 1) -> LuenbergerObserver:
        """The observer whose error has its three poles per DOF at -``bandwidth``
        (module docstring: l1 = 3 w - d/m, l2 = 3 m w^2 - l1 d, l3 = m w^3), from the
        diagonals of the vessel's M and D.

        Parameters
        ----------
        vessel : DPVessel
            The observer's vessel model (M, D); in a composition, the plant's unless given.
        bandwidth : array_like, shape (3,), positive
            The observer's poles per DOF, all three at -bandwidth (rad/s).
        steps_per_sample : int, positive
            RK4 steps of predict per sample period.
        """
        w = np.asarray(check.vector("bandwidth", bandwidth), dtype=float)
        check.positive("bandwidth", w)
        m, d = np.diag(np.asarray(vessel.mass_matrix)), np.diag(np.asarray(vessel.damping_matrix))
        l1 = 3.0 * w - d / m
        if np.any(l1 <= 0):
            raise ParameterError(
                "bandwidth",
                f"bandwidth must exceed d/(3 m) = {np.round(d / (3 * m), 6).tolist()} rad/s in each DOF "
                f"(the vessel's own damping is faster); got {w.tolist()}",
            )
        l2 = 3.0 * m * w**2 - l1 * d
        l3 = m * w**3
        return cls(vessel, l1, l2, l3, steps_per_sample)

    @initial_values(
        Value("eta", "array", "Position north, east (m) and heading (rad); default the first measurement.", shape="(3,)"),
        Value("nu", "array", "Velocity surge, sway (m/s) and yaw rate (rad/s).", shape="(3,)"),
        Value("bias", "array", "Bias forces and moment (N, N, N m).", shape="(3,)"),
    )
    def guess(self, eta=None, nu=0.0, bias=0.0) -> LuenbergerEstimate:
        """An initial estimate (eta the first measurement unless given).

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            Position north, east (m) and heading (rad); default the first measurement.
        nu : array_like, shape (3,)
            Velocity surge, sway (m/s) and yaw rate (rad/s).
        bias : array_like, shape (3,)
            Bias forces and moment (N, N, N m).
        """
        eta = jnp.full(3, jnp.nan) if eta is None else jnp.asarray(check.vector("eta", eta), dtype=float)
        return LuenbergerEstimate(eta, jnp.asarray(check.vector("nu", nu), dtype=float), jnp.asarray(check.vector("bias", bias), dtype=float))

    def init(self, y0: Array, guess: LuenbergerEstimate) -> LuenbergerEstimate:
        """The guess, with eta from the first measurement where the guess leaves it."""
        return eqx.tree_at(lambda s: s.eta, guess, from_first_measurement(guess.eta, y0, angles=(2,)))

    def update(self, estimate: LuenbergerEstimate, t, measurement: Array) -> LuenbergerEstimate:
        """No discrete correction: the measurement enters the vector field."""
        return estimate

    def innovation(self, estimate: LuenbergerEstimate, measurement: Array) -> Array:
        """e = y - eta_hat, heading wrapped; zero on a missing channel."""
        error = measurement - estimate.eta
        error = error.at[2].set(ssa(error[2]))
        return jnp.where(jnp.isfinite(measurement), error, 0.0)

    def vector_field(self, t, estimate: LuenbergerEstimate, measurement: Array, tau: Array) -> LuenbergerEstimate:
        """The observer's equations (module docstring) with the measurement held."""
        e = self.innovation(estimate, measurement)
        psi = estimate.eta[2]
        force = tau - matvec(self.damping_matrix, estimate.nu) + rotate_transpose(psi, estimate.bias + self.velocity_gain * e)
        return LuenbergerEstimate(rotate(psi, estimate.nu) + self.position_gain * e, matvec(self.mass_inverse, force), self.bias_gain * e)

    def normalize(self, estimate: LuenbergerEstimate) -> LuenbergerEstimate:
        """Heading wrapped to [-pi, pi)."""
        return eqx.tree_at(lambda s: s.eta, estimate, estimate.eta.at[2].set(ssa(estimate.eta[2])))

    def predict(self, estimate: LuenbergerEstimate, t, measurement: Array, tau: Array, dt) -> LuenbergerEstimate:
        """``steps_per_sample`` RK4 steps over the sample, measurement and tau held."""
        field = lambda time, x: self.vector_field(time, x, measurement, tau)  # noqa: E731
        return integrate_sample(field, t, estimate, dt, self.steps_per_sample, normalize=self.normalize)

    def output(self, estimate: LuenbergerEstimate, measurement: Array) -> dict[str, Array]:
        """The estimates by name."""
        return {
            "position": estimate.eta[:2],
            "heading": estimate.eta[2],
            "velocity": estimate.nu[:2],
            "yaw_rate": estimate.nu[2],
            "bias_force": estimate.bias[:2],
            "bias_moment": estimate.bias[2],
        }
