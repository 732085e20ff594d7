"""Dynamic positioning by a nonlinear PID on any observer's low-frequency estimates.

The DP practice since the first systems of the 1960s (Fossen & Strand 1999, Section 1):
a PID on the position and heading errors, rotated into the body frame where the
thrusters act, fed by a wave filter. The form is the MIMO nonlinear PID of Fossen
(2011), *Handbook of Marine Craft Hydrodynamics and Motion Control*, Wiley, Section 12.2
(PID control), also the horizontal-plane positioning law surveyed by
Sørensen (2011), "A survey of dynamic positioning control systems", Annual Reviews in
Control 35, 123–136 (its horizontal-plane positioning PID). Neither text is among the
five publications lookout reproduces, so no equation number of theirs is quoted here: the law is written out
below, and every property claimed is derived and tested (tests/test_pid.py).

The law
-------
With the estimate eta_hat = [position, heading] (Earth-fixed), nu_hat = [velocity,
yaw_rate] (body-fixed), the reference eta_d and its derivatives, e = eta_hat - eta_d
(heading through ``ssa``), the integral state z with z' = e (Earth-fixed), and
R = J(psi_hat) the rotation of Fossen & Strand (1999), eq. (2)::

    tau = - Kp R^T e - Kd (nu_hat - R^T eta_d') - Ki R^T z          PID on the estimate
          + M nu_d' + D nu_d                                          reference feed-forward
          - R^T b_hat                  (bias_feedforward = "bias")    bias feed-forward
          - d_hat               (bias_feedforward = "disturbance")    or input disturbance

with nu_d = J^T(psi_d) eta_d' and nu_d' = J^T(psi_d) eta_d'' + S^T(r_d) nu_d, r_d = psi_d'
(:func:`lookout.controllers.tracking.reference_velocity`). nu_hat - R^T eta_d' is
R^T e' exactly (e' = R nu - eta_d'), so the first line is -(Kp, Kd, Ki) acting on the
body-frame images of e, e' and z.

Choices (where the sources leave room)
--------------------------------------
* **The gains act in the body frame.** Kp R^T e rather than R^T Kp e: the two are equal
  when a gain's surge and sway entries are equal (a multiple of the identity commutes
  with R), and only the first keeps a per-DOF design from M exact at every heading when
  they differ (the Northern Clipper's surge and sway masses differ by 56 %). Linearized
  about a setpoint at heading psi_0 (no bias), with x = R^T(psi_0) e and w = R^T(psi_0) z,
  the loop is M x''' + (D + Kd) x'' + Kp x' + Ki x = 0 whatever psi_0 (tested), so per
  DOF of a diagonal M, D: m s^3 + (d + kd) s^2 + kp s + ki = 0.
* **Design rule** (``design``): the pole placement of a mass-damper-spring per DOF
  (Fossen 2011, Section 12.2): kp = m w_n^2, kd = 2 zeta w_n m - d, ki = r w_n kp with
  Fossen's r = 1/10 ("the integrator ten times slower than the natural frequency"),
  from the diagonals of the controller's M and D. The loop's characteristic polynomial
  per DOF is then exactly s^3 + 2 zeta w_n s^2 + w_n^2 s + r w_n^3, stable iff r < 2 zeta
  (Routh–Hurwitz: the rule refuses r >= 2 zeta); for r -> 0 its roots tend to the
  mass-damper-spring's and -r w_n. The off-diagonal entries of M and D (sway–yaw
  coupling) are not cancelled: :meth:`PidController.closed_loop_poles` gives the coupled
  loop's poles, docs/dp-control.md the Northern Clipper's. kd is negative where the
  vessel's own damping d exceeds the design's 2 zeta w_n m (the controller then removes
  damping); the closed loop's damping d + kd must be positive.
* **Integral and anti-windup.** z advances by forward Euler over the sample,
  z(k+1) = z(k) + dt e(k), and is kept where its body-frame force Ki R^T z stays within
  ``integral_limit`` entry by entry (surge force, sway force, yaw moment, as an
  actuator's limits are given): after each step and again at the heading of each sample,
  R^T z is clipped to +-integral_limit / Ki and rotated back. Clamping, not conditional
  integration, because the controller does not see the applied input (the engine gives
  it the measurement, the estimate and the reference): give it the actuator's limits,
  or the share of them the integral may take. Without a limit (the default) nothing is
  clamped.
* **Which estimate.** Only ``position``, ``heading``, ``velocity`` and ``yaw_rate`` are
  read (and ``bias_force``, ``bias_moment`` or ``disturbance_force``,
  ``disturbance_moment`` with the bias feed-forward), so any DP observer drives it. The
  rotation uses the estimated heading psi_hat. The estimate is low-frequency where the
  observer separates the wave motion from it (the passive and sliding-mode observers;
  a Kalman filter whose model plant has a wave state, as the DP vessel does): feeding
  the wave motion back gains nothing (Fossen & Strand 1999, Definition 1 and Remark 1)
  and wears the thrusters. docs/dp-control.md lists what each observer gives.
* **Reference.** ``position_desired`` and ``heading_desired`` are required; their
  ``_rate`` and ``_acceleration`` are used where the reference gives them, else zero: a
  setpoint-only reference has no feed-forward (as a :class:`~lookout.reference.ReferenceFilter`
  resting at a setpoint has none either).
"""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec, rotate, rotate_transpose, ssa
from lookout.components import Controller
from lookout.controllers.tracking import reference_velocity
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Rule, Value, component
from lookout.models.vessel import DPVessel

#: The estimate the law reads: eta_hat and nu_hat.
VESSEL_ESTIMATE = ("position", "heading", "velocity", "yaw_rate")
#: What the bias feed-forward reads, by its setting.
FEEDFORWARD_ESTIMATE = {"none": (), "bias": ("bias_force", "bias_moment"), "disturbance": ("disturbance_force", "disturbance_moment")}
#: The reference the law needs (its rates and accelerations are used where given).
SETPOINT = ("position_desired", "heading_desired")
#: Fossen's (2011) integral ratio: ki = w_n kp / 10.
FOSSEN_INTEGRAL_RATIO = 0.1
#: DOF names in messages.
DOF = ("surge", "sway", "yaw")


def _pair(values: dict, first: str, second: str) -> Array:
    return jnp.concatenate([jnp.asarray(values[first]), jnp.asarray(values[second])[None]])


def _pair_or_zero(values: dict, first: str, second: str) -> Array:
    return _pair(values, first, second) if first in values and second in values else jnp.zeros(3)


def _integral_limit(value) -> Array:
    """``integral_limit`` as a vector of 3 (inf where no limit), checked."""
    if value is None:
        return jnp.full(3, jnp.inf)
    limit = check.vector("integral_limit", value)
    if check.is_concrete(limit):
        array = np.asarray(limit, dtype=float)
        if np.any(np.isnan(array)) or np.any(array <= 0):
            raise check.ParameterError("integral_limit", f"integral_limit must be positive (N, N, N m); got {check._fmt(array)}")
    return jnp.asarray(limit)


@component(
    "controller",
    "pid",
    summary="Nonlinear PID for dynamic positioning on an observer's estimates, with reference and optional bias feed-forward.",
    family="lookout.tuning.families.pid:PidFamily",
    rules={
        "pole-placement": Rule(
            "design",
            (
                Part("vessel", "The controller's model M, D; in a composition, the plant's unless given."),
                Value(
                    "natural_frequency",
                    "array",
                    "w_n (rad/s) per DOF: the bandwidth of the position loop, well below the waves' (0.1 rad/s: a 63 s period).",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("damping_ratio", "array", "zeta (1) per DOF; 1 is critically damped.", shape="(3,)", range=POSITIVE),
                Value(
                    "integral_ratio",
                    "array",
                    "r = ki / (w_n kp) (1), below 2 damping_ratio; Fossen's 0.1 puts the integrator ten times slower than w_n.",
                    shape="(3,)",
                    range=NON_NEGATIVE,
                ),
                Value("proportional_gain", "array", "Kp (N/m, N/m, N m/rad); default m w_n^2.", shape="(3,)", range=POSITIVE),
                Value("derivative_gain", "array", "Kd (N s/m, N s/m, N m s/rad); default 2 zeta w_n m - d.", shape="(3,)"),
                Value("integral_gain", "array", "Ki (N/(m s), N/(m s), N m/(rad s)); default r w_n Kp.", shape="(3,)", range=NON_NEGATIVE),
                Value(
                    "integral_limit",
                    "array",
                    "Largest integral force and moment in the body frame (N, N, N m), as the actuator's limits; default none.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value(
                    "bias_feedforward",
                    "str",
                    'Also cancel the observer\'s Earth-fixed bias estimate ("bias") or a Kalman filter\'s input disturbance ("disturbance").',
                    choices=("none", "bias", "disturbance"),
                ),
            ),
        ),
        "gains": Rule(
            None,
            (
                Part("vessel", "The controller's model M, D for the feed-forward and the design; in a composition, the plant's unless given."),
                Value("proportional_gain", "array", "Kp (N/m, N/m, N m/rad), surge, sway, yaw.", shape="(3,)", range=POSITIVE),
                Value(
                    "derivative_gain",
                    "array",
                    "Kd (N s/m, N s/m, N m s/rad); negative where it removes part of the vessel's own damping (d + Kd must stay positive).",
                    shape="(3,)",
                ),
                Value(
                    "integral_gain",
                    "array",
                    "Ki (N/(m s), N/(m s), N m/(rad s)); zero switches the integral off in that DOF.",
                    shape="(3,)",
                    range=NON_NEGATIVE,
                ),
                Value(
                    "integral_limit",
                    "array",
                    "Largest integral force and moment in the body frame (N, N, N m), as the actuator's limits; default none.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value(
                    "bias_feedforward",
                    "str",
                    'Also cancel the observer\'s Earth-fixed bias estimate ("bias": bias_force, bias_moment) or a Kalman filter\'s input disturbance ("disturbance").',
                    choices=("none", "bias", "disturbance"),
                ),
            ),
        ),
    },
)
@final
class PidController(Controller):
    """Nonlinear PID for dynamic positioning on an observer's estimates, with reference and optional bias feed-forward.

    Fossen (2011), Section 12.2, gains in the body frame (module docstring). Build it from
    the gains (this class, design rule ``gains``) or by pole placement from the vessel's
    M and D (:meth:`design`, the default rule).

    Parameters
    ----------
    vessel : DPVessel
        The controller's model M, D for the feed-forward and the design; in a composition, the plant's unless given.
    proportional_gain : array_like, shape (3,), positive
        Kp (N/m, N/m, N m/rad), surge, sway, yaw.
    derivative_gain : array_like, shape (3,)
        Kd (N s/m, N s/m, N m s/rad); negative where it removes part of the vessel's own damping (d + Kd must stay positive).
    integral_gain : array_like, shape (3,), non-negative
        Ki (N/(m s), N/(m s), N m/(rad s)); zero switches the integral off in that DOF.
    integral_limit : array_like, shape (3,), positive, optional
        Largest integral force and moment in the body frame (N, N, N m), as the actuator's limits; default none.
    bias_feedforward : {"none", "bias", "disturbance"}
        Also cancel the observer's Earth-fixed bias estimate ("bias": bias_force, bias_moment) or a Kalman filter's input disturbance ("disturbance").
    """

    vessel: DPVessel
    proportional_gain: Array
    derivative_gain: Array
    integral_gain: Array
    integral_limit: Array
    bias_feedforward: str = eqx.field(static=True)

    def __init__(
        self,
        vessel: DPVessel,
        proportional_gain: npt.ArrayLike,
        derivative_gain: npt.ArrayLike,
        integral_gain: npt.ArrayLike,
        *,
        integral_limit: npt.ArrayLike | None = None,
        bias_feedforward: str = "none",
    ):
        if not isinstance(vessel, DPVessel):
            raise check.ParameterError("vessel", f"vessel must be a DPVessel (M, D); got {type(vessel).__name__}")
        if bias_feedforward not in FEEDFORWARD_ESTIMATE:
            raise check.ParameterError(
                "bias_feedforward", f"bias_feedforward must be one of {', '.join(repr(k) for k in FEEDFORWARD_ESTIMATE)}; got {bias_feedforward!r}"
            )
        self.vessel = vessel
        self.proportional_gain = jnp.asarray(check.vector("proportional_gain", proportional_gain))
        self.derivative_gain = jnp.asarray(check.vector("derivative_gain", derivative_gain))
        self.integral_gain = jnp.asarray(check.vector("integral_gain", integral_gain))
        self.integral_limit = _integral_limit(integral_limit)
        self.bias_feedforward = bias_feedforward

    def __check_init__(self):
        check.positive("proportional_gain", self.proportional_gain)
        check.finite("derivative_gain", self.derivative_gain)
        check.positive("integral_gain", self.integral_gain, allow_zero=True)
        gains = (self.proportional_gain, self.derivative_gain, self.integral_gain, self.vessel.mass_matrix, self.vessel.damping_matrix)
        if all(check.is_concrete(g) for g in gains):
            self._check_stable()

    def _check_stable(self) -> None:
        """The loop linearized about a setpoint with the controller's own model is stable:
        per DOF (Routh–Hurwitz of m s^3 + (d + kd) s^2 + kp s + ki), then coupled."""
        m, d = (np.diag(np.asarray(a, dtype=float)) for a in (self.vessel.mass_matrix, self.vessel.damping_matrix))
        kp, kd, ki = (np.asarray(g, dtype=float) for g in (self.proportional_gain, self.derivative_gain, self.integral_gain))
        damping = d + kd
        for i, name in enumerate(DOF):
            if damping[i] <= 0:
                raise check.ParameterError(
                    "derivative_gain",
                    f"derivative_gain must leave the closed loop's damping d + Kd positive in {name}; "
                    f"got d = {d[i]:.4g}, Kd = {kd[i]:.4g} (N s/m, or N m s/rad in yaw)",
                )
            if ki[i] >= damping[i] * kp[i] / m[i]:
                raise check.ParameterError(
                    "integral_gain",
                    f"integral_gain must be below (d + Kd) Kp / m = {damping[i] * kp[i] / m[i]:.4g} in {name} "
                    f"(Routh-Hurwitz: above it the loop linearized about a setpoint is unstable); got {ki[i]:.4g}",
                )
        largest = float(np.max(self.closed_loop_poles().real))
        if largest >= 0:
            raise ValueError(
                f"proportional_gain, derivative_gain and integral_gain give an unstable loop (linearized about a setpoint with "
                f"the controller's M and D, coupled): a pole at real part {largest:.3g} 1/s"
            )

    @classmethod
    def design(
        cls,
        vessel: DPVessel,
        *,
        natural_frequency: npt.ArrayLike = 0.1,
        damping_ratio: npt.ArrayLike = 1.0,
        integral_ratio: npt.ArrayLike = FOSSEN_INTEGRAL_RATIO,
        proportional_gain: npt.ArrayLike | None = None,
        derivative_gain: npt.ArrayLike | None = None,
        integral_gain: npt.ArrayLike | None = None,
        integral_limit: npt.ArrayLike | None = None,
        bias_feedforward: str = "none",
    ) -> PidController:
        """The PID with the gains of Fossen's (2011, Section 12.2) pole placement per DOF:
        kp = m w_n^2, kd = 2 zeta w_n m - d, ki = r w_n kp, from the diagonals of ``vessel``'s
        M and D, each unless given.

        Per DOF of a diagonal M, D the loop linearized about a setpoint has the
        characteristic polynomial s^3 + 2 zeta w_n s^2 + w_n^2 s + r w_n^3 (module
        docstring); stable iff r < 2 zeta.

        Parameters
        ----------
        vessel : DPVessel
            The controller's model M, D; in a composition, the plant's unless given.
        natural_frequency : array_like, shape (3,), positive
            w_n (rad/s) per DOF: the bandwidth of the position loop, well below the waves' (0.1 rad/s: a 63 s period).
        damping_ratio : array_like, shape (3,), positive
            zeta (1) per DOF; 1 is critically damped.
        integral_ratio : array_like, shape (3,), non-negative
            r = ki / (w_n kp) (1), below 2 damping_ratio; Fossen's 0.1 puts the integrator ten times slower than w_n.
        proportional_gain : array_like, shape (3,), positive, optional
            Kp (N/m, N/m, N m/rad); default m w_n^2.
        derivative_gain : array_like, shape (3,), optional
            Kd (N s/m, N s/m, N m s/rad); default 2 zeta w_n m - d.
        integral_gain : array_like, shape (3,), non-negative, optional
            Ki (N/(m s), N/(m s), N m/(rad s)); default r w_n Kp.
        integral_limit : array_like, shape (3,), positive, optional
            Largest integral force and moment in the body frame (N, N, N m), as the actuator's limits; default none.
        bias_feedforward : {"none", "bias", "disturbance"}
            Also cancel the observer's Earth-fixed bias estimate ("bias") or a Kalman filter's input disturbance ("disturbance").
        """
        if not isinstance(vessel, DPVessel):
            raise check.ParameterError("vessel", f"vessel must be a DPVessel (M, D); got {type(vessel).__name__}")
        w = check.vector("natural_frequency", natural_frequency)
        zeta = check.vector("damping_ratio", damping_ratio)
        ratio = check.vector("integral_ratio", integral_ratio)
        check.positive("natural_frequency", w)
        check.positive("damping_ratio", zeta)
        check.positive("integral_ratio", ratio, allow_zero=True)
        if all(check.is_concrete(v) for v in (ratio, zeta)) and np.any(np.asarray(ratio) >= 2.0 * np.asarray(zeta)):
            raise check.ParameterError(
                "integral_ratio",
                f"integral_ratio must be below 2 damping_ratio (Routh-Hurwitz of s^3 + 2 zeta w s^2 + w^2 s + r w^3); "
                f"got {check._fmt(np.asarray(ratio))} against 2 zeta = {check._fmt(2.0 * np.asarray(zeta))}",
            )
        m = jnp.diag(vessel.mass_matrix)
        d = jnp.diag(vessel.damping_matrix)
        w, zeta, ratio = (jnp.asarray(v) for v in (w, zeta, ratio))
        if proportional_gain is None:
            proportional_gain = m * w**2
        if derivative_gain is None:
            derivative_gain = 2.0 * zeta * w * m - d
        if integral_gain is None:
            integral_gain = ratio * w * jnp.asarray(check.vector("proportional_gain", proportional_gain))
        return cls(vessel, proportional_gain, derivative_gain, integral_gain, integral_limit=integral_limit, bias_feedforward=bias_feedforward)

    # ---------------------------------------------------------------- the contract

    #: what the law reads: eta_hat, nu_hat (and the bias estimate with its feed-forward)
    estimate_needs = property(lambda self: VESSEL_ESTIMATE + FEEDFORWARD_ESTIMATE[self.bias_feedforward])
    measurement_needs = property(lambda self: ())
    reference_needs = property(lambda self: SETPOINT)

    def init(self) -> Array:
        """The integral state z = 0 (m s, m s, rad s), Earth-fixed."""
        return jnp.zeros(3)

    def clamp(self, integral: Array, heading: Array) -> Array:
        """``integral`` with its body-frame force Ki R^T z within ``integral_limit`` entry
        by entry (R = J(heading)); unchanged without a limit or where Ki = 0."""
        # written with safe branches so that the derivative with respect to the gains is
        # finite without a limit (inf / Ki would give 0 * inf = NaN through jnp.where)
        positive = self.integral_gain > 0
        finite = jnp.isfinite(self.integral_limit)
        bound = jnp.where(finite, self.integral_limit, 1.0) / jnp.where(positive, self.integral_gain, 1.0)
        body = rotate_transpose(heading, integral)
        binds = positive & finite & (jnp.abs(body) > bound)
        clamped = rotate(heading, jnp.where(binds, jnp.sign(body) * bound, body))
        return jnp.where(jnp.any(binds), clamped, integral)  # untouched (to the bit) where nothing binds

    def errors(self, estimate: dict, reference: dict) -> dict[str, Array]:
        """e (heading through ssa), its body-frame image R^T e and R^T e' = nu_hat - R^T eta_d'."""
        eta_hat = _pair(estimate, "position", "heading")
        nu_hat = _pair(estimate, "velocity", "yaw_rate")
        eta_d = _pair(reference, "position_desired", "heading_desired")
        eta_d_rate = _pair_or_zero(reference, "position_desired_rate", "heading_desired_rate")
        e = (eta_hat - eta_d).at[2].set(ssa(eta_hat[2] - eta_d[2]))
        heading = eta_hat[2]
        return {"e": e, "heading": heading, "body": rotate_transpose(heading, e), "body_rate": nu_hat - rotate_transpose(heading, eta_d_rate)}

    def feedforward(self, estimate: dict, reference: dict) -> Array:
        """M nu_d' + D nu_d of the reference, and the bias feed-forward where it is on."""
        tau = jnp.zeros(3)
        if "position_desired_rate" in reference and "heading_desired_rate" in reference:
            full = {"position_desired_acceleration": jnp.zeros(2), "heading_desired_acceleration": jnp.zeros(()), **reference}
            _, nu_d, nu_d_rate = reference_velocity(full)
            tau = matvec(self.vessel.mass_matrix, nu_d_rate) + matvec(self.vessel.damping_matrix, nu_d)
        if self.bias_feedforward == "bias":
            tau = tau - rotate_transpose(jnp.asarray(estimate["heading"]), _pair(estimate, "bias_force", "bias_moment"))
        elif self.bias_feedforward == "disturbance":
            tau = tau - _pair(estimate, "disturbance_force", "disturbance_moment")
        return tau

    def step(
        self, integral: Array, t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike
    ) -> tuple[Array, Array]:
        """``(z(k+1), tau_k)``: the law at t_k (module docstring)."""
        del t, y
        err = self.errors(estimate, reference)
        heading = err["heading"]
        z = self.clamp(integral, heading)
        feedback = self.proportional_gain * err["body"] + self.derivative_gain * err["body_rate"] + self.integral_gain * rotate_transpose(heading, z)
        tau = self.feedforward(estimate, reference) - feedback
        return self.clamp(z + dt * err["e"], heading), tau

    # ---------------------------------------------------------------- analysis

    def _plant_matrices(self, heading: float) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of the controller's model linearized about a setpoint at ``heading``, in
        the body-frame error: [x, nu]' = A [x, nu] + B tau, x' = nu, M nu' = -D nu - K R x + tau."""
        inverse = np.linalg.inv(np.asarray(self.vessel.mass_matrix, dtype=float))
        damping = np.asarray(self.vessel.damping_matrix, dtype=float)
        c, s = np.cos(heading), np.sin(heading)
        stiffness = np.asarray(self.vessel.stiffness_matrix, dtype=float) @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        zero, eye = np.zeros((3, 3)), np.eye(3)
        return np.block([[zero, eye], [-inverse @ stiffness, -inverse @ damping]]), np.vstack([zero, inverse])

    def _active(self) -> np.ndarray:
        """The DOFs with integral action (Ki > 0): only their integral states take part."""
        return np.asarray(self.integral_gain, dtype=float) > 0

    def _gain_matrix(self) -> np.ndarray:
        """[Kp, Kd, Ki] as one matrix acting on [x, nu, w], w the active integral states."""
        kp, kd, ki = (np.diag(np.asarray(g, dtype=float)) for g in (self.proportional_gain, self.derivative_gain, self.integral_gain))
        return np.hstack([kp, kd, ki[:, self._active()]])

    def linearization(self, heading: float = 0.0) -> np.ndarray:
        """A of the loop linearized about a setpoint at ``heading`` (rad), no bias, perfect
        estimates, the controller's model as the plant: state [x, nu, w] with x = R^T e,
        w = R^T z (body frame, R frozen; w of the DOFs with Ki > 0 only, the others'
        integral acting on nothing): x' = nu, M nu' = -D nu - K R x - Kp x - Kd nu - Ki w,
        w' = x. The heading enters through the mooring stiffness K alone (zero for DP)."""
        plant, inputs = self._plant_matrices(heading)
        active = self._active()
        size = 6 + int(active.sum())
        loop = np.zeros((size, size))
        loop[:6, :6] = plant
        loop[:6, :] -= inputs @ self._gain_matrix()
        loop[6:, :3] = np.eye(3)[active]
        return loop

    def closed_loop_poles(self, heading: float = 0.0) -> np.ndarray:
        """The poles (1/s) of :meth:`linearization`, M and D coupled."""
        return np.linalg.eigvals(self.linearization(heading))

    def design_poles(self) -> np.ndarray:
        """The roots of m s^3 + (d + kd) s^2 + kp s + ki per DOF (m s^2 + (d + kd) s + kp
        where ki = 0), m and d the diagonals of M and D: the loop's poles when M and D are
        diagonal, all DOFs together, sorted."""
        m, d = (np.diag(np.asarray(a, dtype=float)) for a in (self.vessel.mass_matrix, self.vessel.damping_matrix))
        kp, kd, ki = (np.asarray(g, dtype=float) for g in (self.proportional_gain, self.derivative_gain, self.integral_gain))
        roots = [np.roots([m[i], d[i] + kd[i], kp[i], ki[i]] if ki[i] > 0 else [m[i], d[i] + kd[i], kp[i]]) for i in range(3)]
        return np.sort_complex(np.concatenate(roots))

    def sampled_spectral_radius(self, sample_period: float, heading: float = 0.0) -> float:
        """The spectral radius of the sampled loop linearized as :meth:`linearization`: the
        plant's exact zero-order-hold step over ``sample_period`` (scipy's ``expm``), tau_k of
        the sample's state, and the integral's forward-Euler step. Below 1: the sampled
        linear loop is stable."""
        from scipy.linalg import expm

        plant, inputs = self._plant_matrices(heading)
        augmented = np.zeros((9, 9))
        augmented[:6, :6], augmented[:6, 6:] = plant * sample_period, inputs * sample_period
        step = expm(augmented)
        phi, gamma = step[:6, :6], step[:6, 6:]
        active = self._active()
        size = 6 + int(active.sum())
        loop = np.eye(size)
        loop[:6, :6] = phi
        loop[:6, :] -= gamma @ self._gain_matrix()
        loop[6:, :3] = sample_period * np.eye(3)[active]
        return float(np.max(np.abs(np.linalg.eigvals(loop))))

    def gains_table(self) -> dict[str, np.ndarray]:
        """Kp, Kd, Ki and the integral limit as arrays (for reports)."""
        return {
            "Kp": np.asarray(self.proportional_gain),
            "Kd": np.asarray(self.derivative_gain),
            "Ki": np.asarray(self.integral_gain),
            "integral_limit": np.asarray(self.integral_limit),
        }


__all__ = ["PidController"]
