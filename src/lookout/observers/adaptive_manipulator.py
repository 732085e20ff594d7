"""Reduced-order adaptive observer for manipulators with unknown parameters, with resetting.

Calugi (2002), master thesis, Lund, chapter 4. The arm M(q) q'' + C(q, q') q' + G(q) = tau
with unknown parameters theta entering affinely (Property 4.2,
:mod:`lookout.models.parameters`); only q is measured. The continuous observer
(4.5)–(4.7), dots restored::

    x1_hat' = psi + K x1~,      psi = M_hat^-1 [tau - C_hat(q, x1_hat) x1_hat - F_hat x1_hat - G_hat]   (4.5)
    theta_hat' = -Gamma phi^T(q, x1_hat, psi) x1~,                x1~ = q' - x1_hat                  (4.7)

with M_hat = M(q; theta_hat) (likewise C_hat, F_hat, G_hat; F is the model's viscous
friction, which lookout keeps apart from C) and K, Gamma positive diagonal. It needs
q' through x1~, so it is a reference for analysis (:meth:`continuous_rate`), not an
implementable observer. The implementable form is the discrete one (4.34)–(4.35),
forward Euler of (4.5)/(4.7) with q' Delta replaced by the measured increment::

    x1_hat(i) = (I - Delta K) x1_hat(i-1) + Delta psi(i-1) + K [q(i) - q(i-1)]                    (4.34)
    theta_hat(i) = theta_hat(i-1) + Gamma phi^T(i-1) [Delta x1_hat(i-1) - q(i) + q(i-1)]             (4.35)

psi(i-1) and phi(i-1) from q(i-1), x1_hat(i-1), theta_hat(i-1) and tau(i-1) (the input
held over the sample). The sign of (4.35) is the sign of (4.7): Delta x1_hat - Delta q
= -x1~ Delta. It needs |1 - Delta K_i| < 1 and has an O(Delta) error (x1_hat ~ q'(t +
Delta/2)); derivations-thesis-ch3-6.md, ch. 4.

Parameter resetting (4.45), after every update, per component::

    theta_hat_i <- l_i   if theta_hat_i <= l_i - mu_i;     theta_hat_i <- h_i   if theta_hat_i >= h_i + mu_i

with the bounds [l, h] containing theta and mu such that M(q; theta_hat) is positive
definite for every q and every theta_hat in [l - mu, h + mu] (checked at construction
on concrete values: M is affine in theta, so its smallest eigenvalue over the box is
reached at a vertex; the vertices are checked on a grid of the angles M depends on).
A reset never increases V = 1/2 (x1~^T M x1~ + theta~^T Gamma^-1 theta~): at the lower
bound it changes V by -(2 (theta_i - l_i) + mu_i) mu_i / gamma_i <= 0 (the thesis's
(4.48) prints -mu where the algebra gives +mu). The observer counts the resets.

Engine time indices (:mod:`lookout.sim.loop`): ``predict(S, t_{i-1}, q(i-1), tau(i-1),
Delta)`` evaluates psi(i-1), phi(i-1) and stores the parts of (4.34)–(4.35) that do not
need q(i); ``update(S, t_i, q(i))`` adds the measured increment and resets. At t_0 the
stored increment is zero, so the estimate at t_0 is the guess (reset if outside).

A missing sample (NaN channel) is replaced by the prediction q(i-1) + Delta x1_hat(i-1):
its increment then equals Delta x1_hat(i-1), so (4.34) reduces to the model prediction
x1_hat + Delta psi and (4.35) leaves theta_hat unchanged on that channel's terms. The
observer rides through dropouts on its model and stays finite.
"""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec, solve
from lookout.components import Layout, Observer, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Value, component, initial_values
from lookout.models.manipulators import (
    JOINT_INPUT,
    JOINT_MEASUREMENT,
    JOINT_POSITION,
    JOINT_VELOCITY,
    configuration_angles,
    configuration_grid,
    joint_layout,
)
from lookout.models.parameters import AffineParameters, parameter_signal_name, parameter_signals


def theta_signal_name(name: str) -> str:
    """The estimate's name for unknown parameter ``name``: ``mass_hat``, ``masses_1_hat``
    (as :class:`~lookout.observers.parameter_estimator.ParameterEstimator` names it)."""
    return f"{parameter_signal_name(name)}_hat"


def estimate_names(parameters: AffineParameters) -> tuple[str, ...]:
    """The estimate :func:`read_estimate` reads: the joints' positions and velocities and theta_hat."""
    model = parameters.model(parameters.reference)
    positions = joint_layout(model.joint_names, model.joint_kinds, JOINT_POSITION)
    velocities = joint_layout(model.joint_names, model.joint_kinds, JOINT_VELOCITY)
    return positions.names + velocities.names + tuple(theta_signal_name(name) for name in parameters.names)


def read_estimate(estimate: dict, parameters: AffineParameters) -> tuple[Array, Array, Array]:
    """``(q, x1_hat, theta_hat)`` from the output of an :class:`AdaptiveManipulatorObserver`
    on ``parameters``: what the chapter 5 and 6 controllers close the loop on."""
    model = parameters.model(parameters.reference)
    positions = joint_layout(model.joint_names, model.joint_kinds, JOINT_POSITION)
    velocities = joint_layout(model.joint_names, model.joint_kinds, JOINT_VELOCITY)
    q = positions.join({s.name: estimate[s.name] for s in positions.signals})
    velocity = velocities.join({s.name: estimate[s.name] for s in velocities.signals})
    theta = jnp.stack([jnp.asarray(estimate[theta_signal_name(name)]) for name in parameters.names])
    return q, velocity, theta


class AdaptiveManipulatorState(eqx.Module):
    """Internal state of :class:`AdaptiveManipulatorObserver`.

    Between ``predict`` and ``update`` the estimates hold the parts of (4.34)–(4.35) that
    do not need q(i); ``update`` completes them.

    Attributes
    ----------
    velocity : Array, shape (n,)
        x1_hat (rad/s).
    theta : Array, shape (p,)
        theta_hat.
    position : Array, shape (n,)
        q(i-1), the last measurement used (its prediction on a missing channel).
    predicted : Array, shape (n,)
        q(i-1) + Delta x1_hat(i-1), standing in for a missing q(i).
    regressor : Array, shape (n, p)
        phi(i-1).
    resets : Array, shape (p,)
        Resets fired so far, per parameter.
    """

    velocity: Array
    theta: Array
    position: Array
    predicted: Array
    regressor: Array
    resets: Array


class AdaptiveGuess(eqx.Module):
    """Initial estimates: x1_hat(0) (rad/s) and theta_hat(0)."""

    velocity: Array
    theta: Array


def _box_vertices(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    p = len(lower)
    corners = np.array(np.meshgrid(*[[0, 1]] * p, indexing="ij")).reshape(p, -1).T
    return np.where(corners == 1, upper, lower)


def mass_matrix_margin(parameters: AffineParameters, lower: npt.ArrayLike, upper: npt.ArrayLike, *, grid_points: int = 64) -> float:
    """min over q and theta in the box [lower, upper] of lambda_min(M(q; theta)): positive
    when M_hat stays positive definite. M is affine in theta, so the minimum over the box
    is at a vertex (lambda_min is concave); q runs over a grid of the angles M depends on."""
    model = parameters.model(parameters.reference)
    angles = configuration_angles(model)
    q_grid = jnp.asarray(configuration_grid(model, angles, grid_points))
    vertices = jnp.asarray(_box_vertices(np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)))
    return float(_smallest_inertia(parameters, vertices, q_grid))


@eqx.filter_jit
def _smallest_inertia(parameters: AffineParameters, vertices: Array, q_grid: Array) -> Array:
    """min over the vertices and the grid of lambda_min(M(q; theta)); compiled once per kind
    of parameter set and reused by every observer built on it."""

    def smallest(theta, q):
        return jnp.linalg.eigvalsh(parameters.model(theta).mass_matrix(q))[0]

    return jnp.min(jax.vmap(lambda theta: jax.vmap(lambda q: smallest(theta, q))(q_grid))(vertices))


@component(
    "observer",
    "adaptive-manipulator",
    summary="Calugi (2002) ch. 4: the discrete adaptive observer (4.34)–(4.35) with resetting (4.45).",
    family="lookout.tuning.families.adaptive_manipulator:AdaptiveManipulatorFamily",
    parameters=(
        Part("parameters", "The model and which of its parameters are unknown; the observer's model is parameters.model(theta_hat)."),
        Value("gain", "array", "Diagonal of K (1/s), with |1 - Delta K| < 1.", shape="(n,)", range=POSITIVE),
        Value(
            "adaptation_gain",
            "array",
            "Diagonal of Gamma; 0 freezes that parameter (with all of Gamma 0 this is the chapter-2 velocity observer in the discrete form (4.34), as Calugi's experiment I runs it).",
            shape="(p,)",
            range=NON_NEGATIVE,
        ),
        Value("sample_period", "float", "Delta (s): the engine's sample period, fixed here because (4.34) is written for it.", range=POSITIVE),
        Value("lower", "array", "Lower bounds l of the resetting (4.45), below upper; default none (-inf).", shape="(p,)"),
        Value("upper", "array", "Upper bounds h of the resetting (4.45), above lower; default none (inf).", shape="(p,)"),
        Value("margin", "array", "mu of (4.45): M(q; theta_hat) must stay positive definite on [l - mu, h + mu].", shape="(p,)", range=NON_NEGATIVE),
        Part("regressor", role="parameters", doc="Whose regressor phi (4.7) uses; default parameters."),
        Value(
            "check_bounds",
            "bool",
            "Refuse bounds and a margin that let M(q; theta_hat) lose positive definiteness on [lower - mu, upper + mu] (default true); false only to reproduce a printed setting that fails (Calugi 2002, experiment III).",
        ),
    ),
)
@final
class AdaptiveManipulatorObserver(Observer):
    """Calugi (2002) ch. 4: the discrete adaptive observer (4.34)–(4.35) with resetting (4.45).

    Estimates the joint velocities (named as the plant's, so the results pair them with
    the truth; the joint positions too, which are the measurement where there is one)
    and the unknown parameters (extra signals ``<name>_hat``, plus
    ``resets`` fired so far). Conditions: Theorem 4.1,
    :func:`lookout.analysis.adaptive_manipulator.check_theorem_4_1`.

    Parameters
    ----------
    parameters : AffineParameters
        The model and which of its parameters are unknown; the observer's model is
        ``parameters.model(theta_hat)``.
    gain : float or array_like, shape (n,), positive
        Diagonal of K (1/s), with |1 - Delta K| < 1.
    adaptation_gain : float or array_like, shape (p,), non-negative
        Diagonal of Gamma; 0 freezes that parameter (with all of Gamma 0 this is the
        chapter-2 velocity observer in the discrete form (4.34), as Calugi's experiment I runs it).
    lower : array_like, shape (p,)
        Lower bounds l of the resetting (4.45), below ``upper``; default none (-inf).
    upper : array_like, shape (p,)
        Upper bounds h of the resetting (4.45), above ``lower``; default none (inf).
    margin : float or array_like, shape (p,), non-negative
        mu of (4.45): M(q; theta_hat) must stay positive definite on [l - mu, h + mu].
    sample_period : float, positive
        Delta (s): the engine's sample period, fixed here because (4.34) is written for it.
    regressor : AffineParameters, optional
        Whose regressor phi (4.7) uses; default ``parameters``. Only to reproduce a printed
        model whose M_hat and phi disagree (Calugi 2002, (5.37) against (5.41)).
    check_bounds : bool
        Refuse bounds and a margin that let M(q; theta_hat) lose positive definiteness on
        [lower - mu, upper + mu] (default true); false only to reproduce a printed setting
        that fails (Calugi 2002, experiment III).
    """

    parameters: AffineParameters
    regressor_source: AffineParameters
    gain: Array
    adaptation_gain: Array
    lower: Array
    upper: Array
    margin: Array
    sample_period: float = eqx.field(static=True)
    check_bounds: bool = eqx.field(static=True)
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    #: the joint positions it reads and the joint torques/forces applied
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)

    def __init__(
        self,
        parameters: AffineParameters,
        gain: npt.ArrayLike,
        adaptation_gain: npt.ArrayLike,
        *,
        sample_period: float,
        lower: npt.ArrayLike | None = None,
        upper: npt.ArrayLike | None = None,
        margin: npt.ArrayLike = 0.0,
        regressor: AffineParameters | None = None,
        check_bounds: bool = True,
    ):
        if not isinstance(parameters, AffineParameters):
            raise check.ParameterError("parameters", f"parameters must be an AffineParameters; got {type(parameters).__name__}")
        if regressor is not None and not (isinstance(regressor, AffineParameters) and regressor.names == parameters.names):
            raise check.ParameterError("regressor", "regressor must be an AffineParameters with the same unknowns as parameters")
        model = parameters.model(parameters.reference)
        p = parameters.size
        self.parameters = parameters
        self.regressor_source = parameters if regressor is None else regressor
        self.gain = jnp.asarray(check.vector("observer gain K", gain, model.size))
        self.adaptation_gain = jnp.asarray(check.vector("adaptation gain Gamma", adaptation_gain, p))
        self.lower = jnp.asarray(check.vector("lower", -np.inf if lower is None else lower, p))
        self.upper = jnp.asarray(check.vector("upper", np.inf if upper is None else upper, p))
        self.margin = jnp.asarray(check.vector("margin mu", margin, p))
        if not (isinstance(sample_period, (int, float)) and np.isfinite(sample_period) and sample_period > 0):
            raise check.ParameterError("sample_period", f"sample_period must be finite and positive (s); got {sample_period!r}")
        self.sample_period = float(sample_period)
        if not isinstance(check_bounds, bool):
            raise check.ParameterError("check_bounds", f"check_bounds must be true or false; got {check_bounds!r}")
        self.check_bounds = check_bounds
        self.measurement_layout = joint_layout(model.joint_names, model.joint_kinds, JOINT_MEASUREMENT)
        self.input_layout = joint_layout(model.joint_names, model.joint_kinds, JOINT_INPUT)
        self.estimate_signals = (
            joint_layout(model.joint_names, model.joint_kinds, JOINT_POSITION).signals
            + joint_layout(model.joint_names, model.joint_kinds, JOINT_VELOCITY).signals
        )
        self.extra_signals = parameter_signals(parameters, "_hat", "estimated ") + (
            Signal("resets", "1", "parameter resets (4.45) fired so far, all parameters"),
        )

    def __check_init__(self):
        check.positive("observer gain K", self.gain)
        check.positive("adaptation gain Gamma", self.adaptation_gain, allow_zero=True)
        check.positive("margin mu", self.margin, allow_zero=True)
        if check.is_concrete(self.gain):
            step = np.abs(1.0 - self.sample_period * np.asarray(self.gain))
            if np.any(step >= 1.0):
                raise check.ParameterError(
                    "observer",
                    f"observer gain K must satisfy |1 - Delta K| < 1 for (4.34); got Delta K = {self.sample_period * np.asarray(self.gain)}",
                )
        if check.is_concrete(self.lower) and check.is_concrete(self.upper):
            lower, upper = np.asarray(self.lower), np.asarray(self.upper)
            if np.any(np.isnan(lower)) or np.any(np.isnan(upper)) or np.any(lower >= upper):
                raise check.ParameterError("lower", f"lower must be below upper for every parameter; got {lower.tolist()}, {upper.tolist()}")
            if self.check_bounds and np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)):
                low, high = lower - np.asarray(self.margin), upper + np.asarray(self.margin)
                smallest = mass_matrix_margin(self.parameters, low, high)
                if not smallest > 0:
                    raise check.ParameterError(
                        "margin",
                        f"margin mu and the bounds must keep M(q; theta_hat) positive definite on [lower - mu, upper + mu] "
                        f"= [{low.tolist()}, {high.tolist()}]; its smallest eigenvalue there is {smallest:.3g}",
                    )

    @initial_values(
        Value("velocity", "array", "x1_hat(0), the joints' velocity estimate (rad/s, m/s).", shape="(n,)"),
        Value("theta", "array", "theta_hat(0), in the parameters' units; default their reference values.", shape="(p,)"),
    )
    def guess(self, velocity: npt.ArrayLike = 0.0, theta: npt.ArrayLike | None = None) -> AdaptiveGuess:
        """Initial estimates; theta_hat(0) defaults to the parameters' reference (the truth).

        Parameters
        ----------
        velocity : array_like, shape (n,)
            x1_hat(0), the joints' velocity estimate (rad/s, m/s).
        theta : array_like, shape (p,), optional
            theta_hat(0), in the parameters' units; default their reference values.
        """
        n = self.parameters.model(self.parameters.reference).size
        theta = self.parameters.reference if theta is None else theta
        return AdaptiveGuess(
            jnp.broadcast_to(jnp.asarray(velocity, dtype=float), (n,)), jnp.asarray(check.vector("theta_hat(0)", theta, self.parameters.size))
        )

    # -- the equations ------------------------------------------------------------

    def model_acceleration(self, theta: Array, q: Array, velocity: Array, tau: Array) -> Array:
        """psi = M_hat^-1 [tau - C_hat(q, x1_hat) x1_hat - F_hat x1_hat - G_hat(q)] (4.5)."""
        model = self.parameters.model(theta)
        force = tau - model.coriolis_force(q, velocity) - model.friction_force(velocity) - model.gravity(q)
        return solve(model.mass_matrix(q), force)

    def continuous_rate(self, velocity: Array, theta: Array, q: Array, qdot: Array, tau: Array) -> tuple[Array, Array]:
        """(x1_hat', theta_hat') of the continuous observer (4.5)–(4.7), given the true q'
        (analysis only: the implementable form is the discrete one)."""
        psi = self.model_acceleration(theta, q, velocity, tau)
        error = qdot - velocity
        return psi + self.gain * error, -self.adaptation_gain * matvec(self.regressor_source.regressor(q, velocity, psi).T, error)

    def reset(self, theta: Array) -> tuple[Array, Array]:
        """(4.45): ``(theta_hat after the resets, which components were reset)``."""
        low = theta <= self.lower - self.margin
        high = theta >= self.upper + self.margin
        return jnp.where(low, self.lower, jnp.where(high, self.upper, theta)), low | high

    # -- the contract -------------------------------------------------------------

    def init(self, y0: Array, guess: AdaptiveGuess) -> AdaptiveManipulatorState:
        """The state at t_0: the guess, with a zero increment pending (see the module docstring)."""
        position = jnp.where(jnp.isfinite(y0), y0, 0.0)
        p, n = self.parameters.size, position.shape[0]
        velocity = jnp.broadcast_to(jnp.asarray(guess.velocity, dtype=float), (n,))
        return AdaptiveManipulatorState(velocity, jnp.asarray(guess.theta, dtype=float), position, position, jnp.zeros((n, p)), jnp.zeros(p))

    def update(self, state: AdaptiveManipulatorState, t: ArrayLike, y: Array) -> AdaptiveManipulatorState:
        """Complete (4.34)–(4.35) with q(i) (its prediction where y is NaN), then reset (4.45)."""
        del t
        q = jnp.where(jnp.isfinite(y), y, state.predicted)
        increment = q - state.position
        velocity = state.velocity + self.gain * increment
        theta, fired = self.reset(state.theta - self.adaptation_gain * matvec(state.regressor.T, increment))
        return AdaptiveManipulatorState(velocity, theta, q, q, jnp.zeros_like(state.regressor), state.resets + fired)

    def output(self, state: AdaptiveManipulatorState, y: Array) -> dict[str, Array]:
        """q (the measurement, or its prediction on a missing channel) and x1_hat as the plant's
        joint position and velocity; theta_hat and the resets."""
        del y
        out = Layout(self.estimate_signals).split(jnp.concatenate([state.position, state.velocity]))
        for k, signal in enumerate(self.extra_signals[:-1]):
            out[signal.name] = state.theta[k]
        out["resets"] = jnp.sum(state.resets)
        return out

    def predict(self, state: AdaptiveManipulatorState, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> AdaptiveManipulatorState:
        """The parts of (4.34)–(4.35) known at t_{i-1}: (I - Delta K) x1_hat + Delta psi(i-1)
        and theta_hat + Gamma phi^T(i-1) Delta x1_hat(i-1); phi(i-1) is kept for ``update``."""
        del t, y  # q(i-1) is the state's position
        h = self.sample_period
        if isinstance(dt, (int, float)) and abs(dt - h) > 1e-12 * h:
            raise check.ParameterError("sample_period", f"the engine's sample period {dt!r} s must equal the observer's sample_period {h!r} s (4.34)")
        q, velocity, theta = state.position, state.velocity, state.theta
        psi = self.model_acceleration(theta, q, velocity, u)
        regressor = self.regressor_source.regressor(q, velocity, psi)
        return AdaptiveManipulatorState(
            velocity=(1.0 - h * self.gain) * velocity + h * psi,
            theta=theta + self.adaptation_gain * matvec(regressor.T, h * velocity),
            position=q,
            predicted=q + h * velocity,
            regressor=regressor,
            resets=state.resets,
        )


__all__ = ["AdaptiveGuess", "AdaptiveManipulatorObserver", "AdaptiveManipulatorState", "mass_matrix_margin", "read_estimate", "theta_signal_name"]
