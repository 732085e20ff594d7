"""Reference generators: the desired trajectory a controller tracks.

:class:`NoReference` gives nothing (an observer run open loop; defined in
:mod:`lookout.null_components`, as the engine's default). :class:`ReferenceFilter`
is the third-order reference model of Fossen (1994, 2002), which turns a
piecewise-constant setpoint schedule into a smooth desired position, velocity and
acceleration, as the output-feedback controllers of Kim (2002) assume ("eta_d,
eta_d', eta_d'' from a proper reference trajectory generator").
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa
from lookout.components import Layout, Reference, Signal
from lookout.declare import POSITIVE, Context, Value, component
from lookout.null_components import NoReference as NoReference  # defined beside the contract, the engine's default
from lookout.vessel_signals import VESSEL_SIGNALS

#: A switch time counts as reached at sample time t when ``time <= t + SWITCH_TOLERANCE * max(1, |t|)``:
#: a sample time that rounds a hair below a switch time does not postpone the switch by a sample.
SWITCH_TOLERANCE = 1e-9


def _rate_units(units: str, power: int) -> str:
    """``units`` per second (``power`` 1) or per second squared (``power`` 2), as UDUNITS reads it.

    A trailing ``s-1`` multiplies the whole product before it (UDUNITS products are
    left-associative), so ``m/s s-1`` is m s-2; a dimensionless ``1`` becomes ``s-1``.
    """
    return f"s-{power}" if units.strip() == "1" else f"{units} s-{power}"


def reference_filter_signals(setpoint_signals: tuple[Signal, ...]) -> tuple[Signal, ...]:
    """The outputs of a :class:`ReferenceFilter` over ``setpoint_signals``.

    For each setpoint signal ``<n>`` in unit ``<u>``: ``<n>_desired`` (u, an angle
    where ``<n>`` is), ``<n>_desired_rate`` (``<u> s-1``) and
    ``<n>_desired_acceleration`` (``<u> s-2``), with the frame, labels and dim of
    ``<n>``; in the order of ``setpoint_signals``, the three of each signal together.
    """
    signals = []
    for s in setpoint_signals:
        signals += [
            Signal(f"{s.name}_desired", s.units, f"desired {s.long_name}", s.frame, s.labels, s.dim, s.angle),
            Signal(f"{s.name}_desired_rate", _rate_units(s.units, 1), f"rate of change of the desired {s.long_name}", s.frame, s.labels, s.dim),
            Signal(
                f"{s.name}_desired_acceleration", _rate_units(s.units, 2), f"second derivative of the desired {s.long_name}", s.frame, s.labels, s.dim
            ),
        ]
    return tuple(signals)


def _strictly_increasing(name: str, value) -> None:
    if not check.is_concrete(value):
        return
    array = np.asarray(value, dtype=float)
    if array.size > 1 and not np.all(np.diff(array) > 0):
        raise check.ParameterError(check.key(name), f"{name} must be strictly increasing; got {check._fmt(array)}")


@component(
    "reference",
    "reference-filter",
    summary="Third-order critically damped reference model per degree of freedom.",
    parameters=(
        Context(
            "signals",
            "The setpoint signals, scalars or vectors (e.g. position over north, east in m, and heading in rad with angle=True); the setpoint vector lays them end to end (lookout.components.Layout), n entries.",
        ),
        Value("bandwidth", "array", "w_i (rad/s), > 0; a scalar applies to every DOF.", shape="(n,) or scalar"),
        Value("schedule_times", "array", "Times (s) at which the setpoints take effect; finite, strictly increasing.", shape="(m,)"),
        Value("setpoints", "array", "Setpoint vector from each schedule time on, finite (shape (n,) for m = 1).", shape="(m, n)"),
        Value("initial", "array", "x_d at t = 0 (rates and acceleration start at zero); default the first setpoint.", shape="(n,)"),
    ),
)
@final
class ReferenceFilter(Reference):
    """Third-order critically damped reference model per degree of freedom.

    The reference model of Fossen (1994), *Guidance and Control of Ocean Vehicles*
    (and Fossen 2002, *Marine Control Systems*) for dynamic positioning: per DOF i,
    with bandwidth w_i > 0 and setpoint r_i,

        x_d''' + 3 w x_d'' + 3 w^2 x_d' + w^3 x_d = w^3 r,

    the cascade of a first-order low-pass filter w/(s + w) and a critically damped
    mass-spring-damper w^2/(s^2 + 2 w s + w^2). From rest, a setpoint step gives
    x_d(t) = r (1 - e^{-wt} (1 + wt + (wt)^2 / 2)): monotone, no overshoot, with
    continuous x_d, x_d' and x_d'' (bounded x_d'''), the smooth desired position,
    velocity and acceleration that Kim (2002) assumes "from a proper reference
    trajectory generator".

    Discretization. The setpoint is piecewise constant and is held over each sample
    period, so the filter is propagated exactly: with state s = [x_d, x_d', x_d'']
    and z = s - [r, 0, 0], z' = A z with A the companion matrix of (s + w)^3, so
    s_{k+1} = Phi s_k + (I - Phi) [r_k, 0, 0] (= Phi s_k + Gamma r_k, Gamma =
    A^{-1} (Phi - I) B) with Phi = expm(A dt) in closed form: N = A + w I is
    nilpotent (N^3 = 0), so Phi = e^{-w dt} (I + N dt + N^2 dt^2 / 2). The samples
    are the continuous solution at the sample times whatever the sample period,
    as long as the schedule times are sample times (a switch between samples takes
    effect at the next sample); ``step`` works under ``jit``, ``vmap`` and
    ``grad`` with the bandwidth an array leaf.

    Angles. For a DOF of an angle signal (``Signal.angle``), the setpoint error
    r - x_d is taken as ``ssa(r - x_d)`` at the start of each sample, so a heading
    setpoint across +-pi is approached the short way (from -3.1 rad to 3.1 rad
    through -pi, 0.083 rad, not 6.2 rad). The filter state keeps x_d wrapped to
    [-pi, pi) after every sample (the dynamics only see x_d through the wrapped
    error, so wrapping the state changes nothing else), and the output
    ``<n>_desired`` is wrapped.

    Schedule. ``r(t)`` is the setpoint of the last schedule time <= t; before the
    first schedule time it is the first setpoint (so with the default initial value
    the filter rests until the second entry). A schedule time counts as reached
    within :data:`SWITCH_TOLERANCE` (relative) of t. The filter starts at rest at
    ``initial`` (default: the first setpoint).

    Parameters
    ----------
    signals : tuple of Signal
        The setpoint signals, scalars or vectors (e.g. ``position`` over north,
        east in m, and ``heading`` in rad with ``angle=True``); the setpoint vector
        lays them end to end (:class:`~lookout.components.Layout`), n entries.
    bandwidth : array_like, shape (n,) or scalar
        w_i (rad/s), > 0; a scalar applies to every DOF.
    schedule_times : array_like, shape (m,)
        Times (s) at which the setpoints take effect; finite, strictly increasing.
    setpoints : array_like, shape (m, n)
        Setpoint vector from each schedule time on, finite (shape (n,) for m = 1).
    initial : array_like, shape (n,), optional
        x_d at t = 0 (rates and acceleration start at zero); default the first setpoint.

    Outputs
    -------
    For each setpoint signal ``<n>`` in unit ``<u>``: ``<n>_desired`` (u),
    ``<n>_desired_rate`` (``<u> s-1``), ``<n>_desired_acceleration``
    (``<u> s-2``), with the signal's frame, labels and dim
    (:func:`reference_filter_signals`).

    References
    ----------
    T. I. Fossen (1994), Guidance and Control of Ocean Vehicles, Wiley
    (third-order reference model for DP); T. I. Fossen (2002), Marine Control Systems,
    Marine Cybernetics. Kim (2002) on output-feedback tracking with eta_d, eta_d',
    eta_d'' from a reference generator.
    """

    bandwidth: Array
    schedule_times: Array
    setpoints: Array
    initial: Array
    setpoint_signals: tuple[Signal, ...] = eqx.field(static=True)
    reference_signals: tuple[Signal, ...] = eqx.field(static=True)
    noise_size: int = eqx.field(static=True, default=0, kw_only=True)

    def __init__(
        self,
        signals: Iterable[Signal],
        bandwidth: npt.ArrayLike,
        schedule_times: npt.ArrayLike,
        setpoints: npt.ArrayLike,
        initial: npt.ArrayLike | None = None,
    ):
        signals = tuple(signals)
        if not signals or not all(isinstance(s, Signal) for s in signals):
            raise check.ParameterError("signals", f"signals must be a non-empty sequence of lookout Signals; got {signals!r}")
        layout = Layout(signals)  # checks the names are distinct
        n = layout.size
        self.setpoint_signals = signals
        self.reference_signals = reference_filter_signals(signals)
        self.bandwidth = jnp.asarray(check.vector("bandwidth", bandwidth, n))
        times = jnp.asarray(schedule_times, dtype=float)
        if times.ndim == 0:
            times = times[None]
        if times.ndim != 1 or times.shape[0] == 0:
            raise check.ParameterError("schedule_times", f"schedule_times must be a non-empty 1-D sequence; got shape {times.shape}")
        values = jnp.asarray(setpoints, dtype=float)
        if values.ndim == 1 and times.shape[0] == 1:
            values = values[None]
        if values.shape != (times.shape[0], n):
            raise check.ParameterError(
                "setpoints",
                f"setpoints must have shape ({times.shape[0]}, {n}) (one setpoint of {n} entries per schedule time); got shape {values.shape}",
            )
        self.schedule_times = times
        self.setpoints = values
        self.initial = values[0] if initial is None else jnp.asarray(check.vector("initial", initial, n))

    def __check_init__(self):
        check.positive("bandwidth", self.bandwidth)
        check.finite("schedule_times", self.schedule_times)
        _strictly_increasing("schedule_times", self.schedule_times)
        check.finite("setpoints", self.setpoints)
        check.finite("initial", self.initial)

    @classmethod
    def vessel(
        cls, bandwidth: npt.ArrayLike, schedule_times: npt.ArrayLike, setpoints: npt.ArrayLike, initial: npt.ArrayLike | None = None
    ) -> ReferenceFilter:
        """The DP vessel's reference: setpoint [north (m), east (m), heading (rad)].

        Uses the ``position`` and ``heading`` signals of
        :data:`lookout.vessel_signals.VESSEL_SIGNALS`, so the outputs are
        ``position_desired`` (m), ``heading_desired`` (rad), ``position_desired_rate``
        (m s-1), ``heading_desired_rate`` (rad s-1), ``position_desired_acceleration``
        (m s-2) and ``heading_desired_acceleration`` (rad s-2).

        Parameters
        ----------
        bandwidth : array_like, shape (3,) or scalar
            w (rad/s) for north, east and heading.
        schedule_times, setpoints, initial
            As in :class:`ReferenceFilter`, setpoints of shape (m, 3).
        """
        by_name = {s.name: s for s in VESSEL_SIGNALS}
        return cls((by_name["position"], by_name["heading"]), bandwidth, schedule_times, setpoints, initial)

    @property
    def layout(self) -> Layout:
        """The setpoint vector's layout (the setpoint signals end to end)."""
        return Layout(self.setpoint_signals)

    @property
    def angle_mask(self) -> tuple[bool, ...]:
        """Per DOF, whether it is an angle (wrapped errors and output)."""
        return tuple(s.angle for s in self.setpoint_signals for _ in range(s.size))

    def setpoint(self, t: ArrayLike) -> Array:
        """r(t), shape (n,): the setpoint of the last schedule time <= t (the first before it)."""
        t = jnp.asarray(t, dtype=self.schedule_times.dtype)
        reached = t + SWITCH_TOLERANCE * jnp.maximum(1.0, jnp.abs(t))
        index = jnp.searchsorted(self.schedule_times, reached, side="right") - 1
        return self.setpoints[jnp.clip(index, 0, self.setpoints.shape[0] - 1)]

    def transition(self, dt: ArrayLike) -> tuple[Array, Array]:
        """``(Phi, Gamma)``: the exact sampled filter over ``dt``, shapes (n, 3, 3) and (n, 3).

        state_{k+1} = Phi state_k + Gamma r_k per DOF, for r held over the sample.
        """
        w = self.bandwidth
        zero, one = jnp.zeros_like(w), jnp.ones_like(w)
        # N = A + w I, A the companion matrix of (s + w)^3; N^3 = 0
        n = jnp.stack([jnp.stack([w, one, zero], -1), jnp.stack([zero, w, one], -1), jnp.stack([-(w**3), -3.0 * w**2, -2.0 * w], -1)], -2)
        h = jnp.asarray(dt, dtype=w.dtype)
        eye = jnp.eye(3, dtype=w.dtype)
        phi = jnp.exp(-w * h)[:, None, None] * (eye + n * h + (n @ n) * (0.5 * h * h))
        gamma = (eye - phi)[:, :, 0]
        return phi, gamma

    def _wrap(self, x: Array) -> Array:
        mask = self.angle_mask
        if not any(mask):
            return x
        return jnp.where(jnp.asarray(mask), ssa(x), x)

    def init(self) -> Array:
        """Filter state at t_0, shape (n, 3): rows [x_d, x_d', x_d''], at rest at ``initial``."""
        x = self._wrap(jnp.asarray(self.initial, dtype=float))
        return jnp.stack([x, jnp.zeros_like(x), jnp.zeros_like(x)], axis=-1)

    def step(self, state: Array, t: ArrayLike, dt: ArrayLike, normals: Array) -> tuple[Array, dict[str, Array]]:
        """``(state at t + dt, {name: value at t})`` with r(t) held over the sample."""
        del normals
        x = state[:, 0]
        r = self.setpoint(t)
        error = r - x
        if any(self.angle_mask):
            error = jnp.where(jnp.asarray(self.angle_mask), ssa(error), error)
        target = x + error  # r, or for an angle the equivalent of r nearest x_d
        phi, _ = self.transition(dt)
        z = state.at[:, 0].set(-error)  # state - [target, 0, 0]
        z_next = phi[:, :, 0] * z[:, 0:1] + phi[:, :, 1] * z[:, 1:2] + phi[:, :, 2] * z[:, 2:3]
        new_state = z_next.at[:, 0].add(target)
        new_state = new_state.at[:, 0].set(self._wrap(new_state[:, 0]))
        layout = self.layout
        sample = {}
        for suffix, column in (("_desired", 0), ("_desired_rate", 1), ("_desired_acceleration", 2)):
            for name, value in layout.split(state[:, column]).items():
                sample[f"{name}{suffix}"] = value
        return new_state, sample


@component(
    "reference",
    "ellipse",
    summary="An ellipse traced at a constant speed per lap, paced by arc length.",
    parameters=(
        Value("semi_axes", "array", "Semi-axes a, b (m) along north and east.", shape="(2,)", range=POSITIVE),
        Value("lap_speeds", "array", "U_k (m/s) per lap, > 0."),
        Value("centre", "array", "Centre (x_c, y_c) (m).", shape="(2,)"),
        Value("start_angle", "float", "theta_0 (rad): theta_0 = 0 starts at (x_c + a, y_c) heading along +y for s = +1."),
        Value("direction", "str", "s above.", choices=(1, -1)),
        Value("substeps", "int", "RK4 steps for theta per sample."),
    ),
)
@final
class EllipseReference(Reference):
    """An ellipse traced at a constant speed per lap, paced by arc length.

    The reference of Wondergem et al. (2009), Section 5 (:mod:`lookout.papers.wondergem_2009`
    chooses its ellipse and gives its four lap speeds).

    The path is x = x_c + a cos(theta), y = y_c + s b sin(theta) (x north, y east;
    s = +1 traces it with the yaw rate positive, s = -1 the other way), with the path
    parameter theta(t) from theta' = U_k / rho(theta), rho = sqrt(a^2 sin^2 theta +
    b^2 cos^2 theta), so the speed along the path is U_k on lap k = floor((theta -
    theta_0) / 2 pi) (the last speed after the last lap). The heading is along the path,
    psi_ref = atan2(y', x'), and its rate r_ref = s U kappa with the curvature
    kappa = a b / rho^3 (derivations-wondergem-2009.md, section 5). The speed steps at
    each lap ("stepwise", the paper's Figure 5), so nu_ref jumps there; the theory
    excludes that, and its effect on the error index is small.

    Outputs the signals of :meth:`ReferenceFilter.vessel` (``position_desired``,
    ``heading_desired`` and their ``_rate`` and ``_acceleration``), exact at the sample
    for the theta there; theta is advanced by ``substeps`` RK4 steps per sample.

    Parameters
    ----------
    semi_axes : array_like, shape (2,), positive
        Semi-axes a, b (m) along north and east.
    lap_speeds : sequence of float
        U_k (m/s) per lap, > 0.
    centre : array_like, shape (2,)
        Centre (x_c, y_c) (m).
    start_angle : float
        theta_0 (rad): theta_0 = 0 starts at (x_c + a, y_c) heading along +y for s = +1.
    direction : {1, -1}
        s above.
    substeps : int
        RK4 steps for theta per sample.
    """

    semi_axes: Array
    centre: Array
    lap_speeds: Array
    start_angle: Array
    direction: Array
    substeps: int = eqx.field(static=True)
    reference_signals: tuple[Signal, ...] = eqx.field(static=True, kw_only=True)
    noise_size: int = eqx.field(static=True, default=0, kw_only=True)

    def __init__(
        self,
        semi_axes: npt.ArrayLike,
        lap_speeds: npt.ArrayLike,
        centre: npt.ArrayLike = (0.0, 0.0),
        start_angle: ArrayLike = 0.0,
        direction: ArrayLike = 1,
        substeps: int = 1,
    ):
        self.semi_axes = jnp.asarray(check.vector("semi_axes", semi_axes, 2))
        if check.is_concrete(lap_speeds):
            speeds = np.asarray(lap_speeds, dtype=float)
            if speeds.ndim != 1:
                raise check.ParameterError("lap_speeds", f"lap_speeds must be a sequence of speeds (m/s); got shape {speeds.shape}")
            self.lap_speeds = jnp.asarray(speeds, dtype=float)
        else:
            self.lap_speeds = jnp.asarray(lap_speeds, dtype=float)
        self.centre = jnp.asarray(check.vector("centre", centre, 2))
        check.finite("start_angle", start_angle)
        self.start_angle = jnp.asarray(start_angle, dtype=float)
        if check.is_concrete(direction) and float(np.asarray(direction)) not in (1.0, -1.0):
            raise check.ParameterError("direction", f"direction must be 1 or -1; got {direction!r}")
        self.direction = jnp.asarray(direction, dtype=float)
        if not (isinstance(substeps, int) and not isinstance(substeps, bool) and substeps >= 1):
            raise check.ParameterError("substeps", f"substeps must be a positive integer; got {substeps!r}")
        self.substeps = substeps
        by_name = {s.name: s for s in VESSEL_SIGNALS}
        self.reference_signals = reference_filter_signals((by_name["position"], by_name["heading"]))

    def __check_init__(self):
        check.positive("semi_axes", self.semi_axes)
        check.positive("lap_speeds", self.lap_speeds)

    def speed(self, theta: ArrayLike) -> Array:
        """U_k of the lap that theta is on."""
        lap = jnp.floor((theta - self.start_angle) / (2.0 * jnp.pi)).astype(int)
        return self.lap_speeds[jnp.clip(lap, 0, self.lap_speeds.shape[0] - 1)]

    def _rho(self, theta):
        a, b = self.semi_axes[0], self.semi_axes[1]
        return jnp.sqrt((a * jnp.sin(theta)) ** 2 + (b * jnp.cos(theta)) ** 2)

    def perimeter(self) -> float:
        """The ellipse's perimeter (m), by quadrature of rho over a lap."""
        theta = np.linspace(0.0, 2.0 * np.pi, 20001)
        rho = np.asarray(self._rho(jnp.asarray(theta)))
        return float(np.sum(0.5 * (rho[1:] + rho[:-1]) * np.diff(theta)))

    def sample(self, theta: ArrayLike) -> dict[str, Array]:
        """The reference at path parameter theta."""
        a, b = self.semi_axes[0], self.semi_axes[1]
        s = self.direction
        U = self.speed(theta)
        c, n = jnp.cos(theta), jnp.sin(theta)
        rho = self._rho(theta)
        theta_rate = U / rho
        rho_prime = (a * a - b * b) * n * c / rho
        theta_accel = -U * rho_prime / rho**2 * theta_rate
        kappa = a * b / rho**3
        kappa_prime = -3.0 * a * b * rho_prime / rho**4
        position = self.centre + jnp.stack([a * c, s * b * n])
        rate = jnp.stack([-a * n * theta_rate, s * b * c * theta_rate])
        acceleration = jnp.stack([-a * c * theta_rate**2 - a * n * theta_accel, s * (-b * n * theta_rate**2 + b * c * theta_accel)])
        return {
            "position_desired": position,
            "heading_desired": ssa(jnp.arctan2(rate[1], rate[0])),
            "position_desired_rate": rate,
            "heading_desired_rate": s * U * kappa,
            "position_desired_acceleration": acceleration,
            "heading_desired_acceleration": s * U * kappa_prime * theta_rate,
        }

    def init(self) -> Array:
        """theta(t_0) = theta_0."""
        return self.start_angle

    def step(self, state: Array, t: ArrayLike, dt: ArrayLike, normals: Array) -> tuple[Array, dict[str, Array]]:
        """``(theta(t + dt), reference at theta(t))``."""
        del normals
        h = dt / self.substeps

        def field(time, theta):
            del time
            return self.speed(theta) / self._rho(theta)

        theta = state
        for i in range(self.substeps):  # classical RK4 on the scalar theta
            time = t + i * h
            k1 = field(time, theta)
            k2 = field(time + 0.5 * h, theta + 0.5 * h * k1)
            k3 = field(time + 0.5 * h, theta + 0.5 * h * k2)
            k4 = field(time + h, theta + h * k3)
            theta = theta + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return theta, self.sample(state)
