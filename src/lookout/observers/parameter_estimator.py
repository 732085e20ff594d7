"""On-line estimation of a manipulator's unknown parameters from q and q' (no q'').

Calugi (2002), master thesis, Lund, chapter 3, after Middleton and Goodwin: a
filtered-regressor, unnormalized gradient estimator for any parameters that enter
the dynamics affinely (Property 4.2, :mod:`lookout.models.parameters`)::

    tau = phi(q, q', q'') theta + phi0(q, q', q'')                          (3.13)
    tau_f = phi_f theta + phi0_f,   x_f = 1/(s + a) x, zero initial state    (3.14)
    tau_hat_f = phi_f theta_hat + phi0_f                                    (3.15)
    e = tau_f - tau_hat_f = phi_f theta~                                    (3.16)
    theta_hat' = h phi_f^T e                                                (3.9)

with theta~ = theta - theta_hat, h > 0 (a scalar, or here also a positive diagonal)
and the filter pole a (the thesis's 1/(s + 1): a = 1 rad/s). With
V = 1/2 theta~^T h^-1 theta~ and theta constant, V' = -|phi_f theta~|^2 <= 0 (3.10)–(3.11).

Garbles of the printed text, read as follows:

* (3.7) and (3.9) lost the hat and the dot: (3.9) is theta_hat' = h F_f e. This sign
  makes (3.11) nonpositive.
* (3.16) is e = tau_f - tau_hat_f (= phi_f theta~).
* Lemma 3.1(2) asks for rank(F_f F_f^T) = p at each instant. That is neither necessary
  nor sufficient: with one joint and two parameters it never holds, yet the estimate
  converges. What is needed is persistent excitation, int_{t-T}^t phi_f^T phi_f >= alpha I
  for all t; :func:`windowed_excitation` measures it from a recorded phi_f.

How phi_f is formed without q''. By Property 4.2 the left side is affine in the
acceleration psi = q'', which enters only through M(q; theta) psi. So the augmented
regressor Psi = [phi0, phi] (n x (p + 1)) splits as Psi(q, q', q'') = A(q) q'' + B(q, q'),
with A(q) psi = Psi(q, 0, psi) - Psi(q, 0, 0) depending on q alone. Filtering A(q) q''
is not A(q) filtered q'' when A depends on q (a two-link arm), so it is written as a
derivative: A(q) q'' = d/dt[A(q) q'] - A'(q) q', with A' = dA/dt = (dA/dq) q'. For any
signal w, 1/(s + a) w' = w - a 1/(s + a) w - w(0) e^{-a t} (zero initial filter state).
So, with the filter states W = 1/(s + a)[A(q) q'] and R = 1/(s + a)[B(q, q') - A'(q) q']
and E = A(q(0)) q'(0) e^{-a t}::

    Psi_f = A(q) q' - a W - E + R

(check: X = A q' - a W - E has X(0) = 0 and X' = A q'' + A' q' - a X, so X is the filter
of A q'' + A' q', and R removes A' q'.) For the pendulum with theta = m, A = l^2 and
this is the derivation notes' phi_f = l^2 (q' - q'_f - q'(0) e^{-t}) + g l (sin q)_f: the
filtered acceleration is (1/(s + 1)) q'' = q' - q'_f - q'(0) e^{-t}, and the q'(0) term
is kept (the thesis's (3.6) drops it, exact there only because q'(0) = 0). A, B and
A' q' come from ``parameters.split`` (a JVP in psi, and one in q for A'), so no
regressor is written by hand.

Other choices (see docs/reproductions.md):

* Measurement: ``y = [q, q']`` in joint order,
  :class:`lookout.sensors.JointStateSensor`.
* Missing samples. A NaN channel (a dropout, held by the engine until its next
  sample) is replaced by its last valid value (``held``, set at each
  :meth:`ParameterEstimator.update`), the filters run on those held values, and
  theta_hat is held (theta_hat' = 0) while any channel is NaN. The estimate stays
  finite. Afterwards the filters carry the held stretch for a few 1/a: e then
  differs from phi_f theta~ by a transient that decays like e^{-a t}. A first sample
  that is NaN starts that channel at 0.
* Sampled operation: :meth:`ParameterEstimator.predict` integrates the vector field
  by RK4 with y and tau held over the sample (zero-order hold); the continuous mode
  of the engine integrates it jointly with the plant instead (the setting of the
  thesis).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import ContinuousObserver, Layout, Signal
from lookout.declare import POSITIVE, Part, Value, component, initial_values
from lookout.models.manipulators import JOINT_INPUT, PRISMATIC, REVOLUTE, joint_layout
from lookout.models.parameters import AffineParameters, parameter_signal_name, parameter_signals
from lookout.sensors import joint_state_layout
from lookout.sim.integrators import integrate_sample

if TYPE_CHECKING:
    import xarray as xr

#: Units of the generalized force per joint kind (the prediction error, tau_f).
FORCE_UNITS = {REVOLUTE: "N m", PRISMATIC: "N"}


def _per(force: str, unit: str) -> str:
    """``force / unit`` written for UDUNITS: ``N m/kg``, ``N m/(kg m2)``."""
    return f"{force}/({unit})" if any(c in unit for c in " /*.^") else f"{force}/{unit}"


class ParameterEstimatorState(eqx.Module):
    """Internal state of :class:`ParameterEstimator` (Psi = [phi0, phi], n x (p + 1)).

    Attributes
    ----------
    theta : Array, shape (p,)
        theta_hat, the parameter estimate.
    torque : Array, shape (n,)
        tau_f = 1/(s + a) tau (N m, N).
    inertial : Array, shape (n, p + 1)
        W = 1/(s + a) [A(q) q'], the filtered inertial part of Psi (module docstring).
    remainder : Array, shape (n, p + 1)
        R = 1/(s + a) [B(q, q') - A'(q) q'].
    transient : Array, shape (n, p + 1)
        E = A(q(0)) q'(0) e^{-a t}, the initial-rate term of the filtered acceleration.
    held : Array, shape (2n,)
        The last valid measurement [q, q'], used where a channel is NaN.
    """

    theta: Array
    torque: Array
    inertial: Array
    remainder: Array
    transient: Array
    held: Array


@component(
    "observer",
    "parameter-estimator",
    summary="Middleton–Goodwin filtered-regressor estimator, Calugi (2002), eqs. (3.9), (3.13)–(3.16).",
    parameters=(
        Part("parameters", "The unknown parameters and the model they build; every parameter needs a unit."),
        Value("gain", "array", "h of (3.9): a scalar, or the diagonal of a positive diagonal matrix.", shape="(p,)", range=POSITIVE),
        Value("filter_pole", "float", "a of the filter 1/(s + a) (rad/s); the thesis's 1.", range=POSITIVE),
        Value("steps_per_sample", "int", "RK4 steps of predict per sample period (sampled mode).", range=POSITIVE),
    ),
)
@final
class ParameterEstimator(ContinuousObserver):
    """Middleton–Goodwin filtered-regressor estimator, Calugi (2002), eqs. (3.9), (3.13)–(3.16).

    Estimates theta of any :class:`~lookout.models.parameters.AffineParameters` from
    the measured ``y = [q, q']`` and the applied input tau; the module docstring gives
    the derivation and the choices. It estimates no plant variable
    (``estimate_signals`` is empty); its outputs are extra signals:

    * ``<name>_hat`` per parameter (``mass_hat``; ``masses[1]`` gives ``masses_1_hat``),
      in the parameter's unit;
    * ``torque_prediction_error`` / ``force_prediction_error``: e of (3.16) per joint;
    * ``filtered_regressor_<name>`` (revolute joints) and
      ``filtered_regressor_<name>_prismatic`` per parameter: column ``name`` of phi_f,
      for the persistence-of-excitation check (:func:`windowed_excitation`).

    Parameters
    ----------
    parameters : AffineParameters
        The unknown parameters and the model they build; every parameter needs a unit.
    gain : float or array_like, shape (p,), positive
        h of (3.9): a scalar, or the diagonal of a positive diagonal matrix.
    filter_pole : float, positive
        a of the filter 1/(s + a) (rad/s); the thesis's 1.
    steps_per_sample : int, positive
        RK4 steps of :meth:`predict` per sample period (sampled mode).
    """

    parameters: AffineParameters
    gain: Array
    filter_pole: Array
    steps_per_sample: int = eqx.field(static=True)
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    parameter_layout: Layout = eqx.field(static=True)
    error_layout: Layout = eqx.field(static=True)
    regressor_layouts: tuple[Layout, ...] = eqx.field(static=True)
    #: [q, q'] it reads and the joint torques/forces applied; any step dt
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    sample_period: None = eqx.field(static=True)

    def __init__(self, parameters: AffineParameters, gain: npt.ArrayLike, filter_pole: ArrayLike = 1.0, steps_per_sample: int = 1):
        if not isinstance(parameters, AffineParameters):
            raise check.ParameterError(
                "parameters", f"parameters must be AffineParameters (lookout.models.parameters); got {type(parameters).__name__}"
            )
        model = parameters.model(parameters.reference)
        names, kinds = model.joint_names, model.joint_kinds
        self.parameters = parameters
        self.gain = jnp.asarray(check.vector("parameter estimator gain", gain, parameters.size))
        if check.is_concrete(filter_pole) and np.ndim(filter_pole) != 0:
            raise check.ParameterError("filter_pole", f"filter_pole must be a scalar; got shape {np.shape(filter_pole)}")
        self.filter_pole = jnp.asarray(filter_pole, dtype=float)
        if not (isinstance(steps_per_sample, int) and steps_per_sample >= 1):
            raise check.ParameterError("steps_per_sample", f"steps_per_sample must be a positive integer; got {steps_per_sample!r}")
        self.steps_per_sample = steps_per_sample
        self.parameter_layout = Layout(parameter_signals(parameters, "_hat", "estimated "))
        force = {kind: FORCE_UNITS[kind] for kind in (REVOLUTE, PRISMATIC)}
        self.error_layout = joint_layout(
            names,
            kinds,
            {
                REVOLUTE: ("torque_prediction_error", force[REVOLUTE], "prediction error e = tau_f - tau_hat_f, eq. (3.16)"),
                PRISMATIC: ("force_prediction_error", force[PRISMATIC], "prediction error e = tau_f - tau_hat_f, eq. (3.16)"),
            },
        )
        layouts = []
        for name, unit in zip(parameters.names, parameters.units):
            safe = parameter_signal_name(name)
            long_name = f"filtered regressor phi_f, column {name}, eq. (3.14)"
            layouts.append(
                joint_layout(
                    names,
                    kinds,
                    {
                        REVOLUTE: (f"filtered_regressor_{safe}", _per(force[REVOLUTE], unit), long_name),
                        PRISMATIC: (f"filtered_regressor_{safe}_prismatic", _per(force[PRISMATIC], unit), long_name),
                    },
                )
            )
        self.regressor_layouts = tuple(layouts)
        self.measurement_layout = joint_state_layout(model)
        self.input_layout = joint_layout(names, kinds, JOINT_INPUT)
        self.sample_period = None
        self.estimate_signals = ()
        self.extra_signals = self.parameter_layout.signals + self.error_layout.signals + tuple(s for layout in layouts for s in layout.signals)

    def __check_init__(self):
        check.positive("parameter estimator gain", self.gain)
        check.positive("filter_pole", self.filter_pole)

    @property
    def size(self) -> int:
        """n, the number of joints."""
        return self.error_layout.size

    # --- the regressor, Property 4.2 -------------------------------------------------

    def _augmented(self, q: Array, xi: Array, psi: Array) -> Array:
        """Psi = [phi0, phi] of Property 4.2 at (q, xi, psi), shape (n, p + 1)."""
        phi0, phi = self.parameters.split(q, xi, psi)
        return jnp.concatenate([phi0[:, None], phi], axis=1)

    def regressor_pieces(self, q: Array, qdot: Array) -> tuple[Array, Array, Array]:
        """``(A(q) q', B(q, q'), A'(q) q')``, each (n, p + 1): Psi(q, q', psi) = A(q) psi + B(q, q').

        A(q) q' is the derivative of psi -> Psi(q, 0, psi) in the direction q' (exact:
        Psi is affine in psi); A'(q) q' = (dA/dq q') q' its derivative in q along q'.
        """
        zero = jnp.zeros_like(qdot)
        remainder = self._augmented(q, qdot, zero)

        def inertial(position):
            return jax.jvp(lambda psi: self._augmented(position, zero, psi), (zero,), (qdot,))[1]

        inertial_term, inertial_rate = jax.jvp(inertial, (q,), (qdot,))
        return inertial_term, remainder, inertial_rate

    def _measurement(self, state: ParameterEstimatorState, y: Array) -> tuple[Array, Array]:
        """(q, q') from y, the held values standing in for NaN channels."""
        values = jnp.where(jnp.isfinite(y), y, state.held)
        n = self.size
        return values[:n], values[n:]

    def filtered_regressors(self, state: ParameterEstimatorState, y: Array) -> tuple[Array, Array]:
        """``(phi0_f, phi_f)`` of (3.14), shapes (n,) and (n, p): Psi_f = A q' - a W - E + R."""
        q, qdot = self._measurement(state, y)
        inertial_term, _, _ = self.regressor_pieces(q, qdot)
        filtered = inertial_term - self.filter_pole * state.inertial - state.transient + state.remainder
        return filtered[:, 0], filtered[:, 1:]

    def prediction_error(self, state: ParameterEstimatorState, y: Array) -> Array:
        """e = tau_f - phi0_f - phi_f theta_hat, eq. (3.16) with (3.15)."""
        phi0_f, phi_f = self.filtered_regressors(state, y)
        return state.torque - phi0_f - phi_f @ state.theta

    # --- the observer contract -------------------------------------------------------

    @initial_values(
        Value("theta", "array", "theta_hat(0), in the parameters' units; default their reference values.", shape="(p,)"),
    )
    def guess(self, theta: npt.ArrayLike | None = None) -> Array:
        """An initial parameter estimate theta_hat(0): ``theta``, by default the
        parameters' reference values (as :class:`AdaptiveManipulatorObserver` starts).

        Parameters
        ----------
        theta : array_like, shape (p,), optional
            theta_hat(0), in the parameters' units; default their reference values.
        """
        theta = self.parameters.reference if theta is None else theta
        return jnp.asarray(check.vector("theta_hat(0)", theta, self.parameters.size))

    def init(self, y0: Array, guess: npt.ArrayLike) -> ParameterEstimatorState:
        """Filters at zero, E(0) = A(q(0)) q'(0), theta_hat(0) = ``guess``.

        Parameters
        ----------
        y0 : Array, shape (2n,)
            The first measurement [q, q'] (NaN channels start at 0).
        guess : float or array_like, shape (p,)
            theta_hat(0).
        """
        held = jnp.where(jnp.isfinite(y0), y0, 0.0)
        n, p = self.size, self.parameters.size
        theta = jnp.asarray(guess, dtype=held.dtype)
        if theta.shape not in ((), (p,)):
            raise ValueError(
                f"the initial estimate theta_hat(0) must be a scalar or have {p} entries ({', '.join(self.parameters.names)}); got shape {theta.shape}"
            )
        theta = jnp.broadcast_to(theta, (p,))
        inertial_term, _, _ = self.regressor_pieces(held[:n], held[n:])
        zeros = jnp.zeros((n, p + 1), held.dtype)
        return ParameterEstimatorState(theta, jnp.zeros(n, held.dtype), zeros, zeros, inertial_term, held)

    def update(self, state: ParameterEstimatorState, t: ArrayLike, y: Array) -> ParameterEstimatorState:
        """No correction; the valid channels of y become the held values."""
        del t
        return eqx.tree_at(lambda s: s.held, state, jnp.where(jnp.isfinite(y), y, state.held))

    def output(self, state: ParameterEstimatorState, y: Array) -> dict[str, Array]:
        """theta_hat, e and the columns of phi_f, by signal name."""
        phi0_f, phi_f = self.filtered_regressors(state, y)
        error = state.torque - phi0_f - phi_f @ state.theta
        outputs = {**self.parameter_layout.split(state.theta), **self.error_layout.split(error)}
        for j, layout in enumerate(self.regressor_layouts):
            outputs.update(layout.split(phi_f[:, j]))
        return outputs

    def vector_field(self, t: ArrayLike, state: ParameterEstimatorState, y: Array, u: Array) -> ParameterEstimatorState:
        """The filters of (3.14) and theta_hat' = h phi_f^T e of (3.9) (frozen while y has a NaN)."""
        del t
        a = self.filter_pole
        q, qdot = self._measurement(state, y)
        inertial_term, remainder, inertial_rate = self.regressor_pieces(q, qdot)
        filtered = inertial_term - a * state.inertial - state.transient + state.remainder  # Psi_f = [phi0_f, phi_f]
        phi0_f, phi_f = filtered[:, 0], filtered[:, 1:]
        error = state.torque - phi0_f - phi_f @ state.theta  # eq. (3.16)
        adapt = jnp.all(jnp.isfinite(y))
        theta_rate = jnp.where(adapt, self.gain * (phi_f.T @ error), 0.0)  # eq. (3.9)
        return ParameterEstimatorState(
            theta_rate,
            -a * state.torque + u,
            -a * state.inertial + inertial_term,
            -a * state.remainder + remainder - inertial_rate,
            -a * state.transient,
            jnp.zeros_like(state.held),
        )

    def normalize(self, state: ParameterEstimatorState) -> ParameterEstimatorState:
        """The identity: nothing wraps."""
        return state

    def predict(self, state: ParameterEstimatorState, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> ParameterEstimatorState:
        """From t to t + dt with y and u held: ``steps_per_sample`` RK4 steps of :meth:`vector_field`."""
        state = self.update(state, t, y)
        field = lambda time, s: self.vector_field(time, s, y, u)
        return integrate_sample(field, t, state, dt, self.steps_per_sample)

    # --- reading the results ---------------------------------------------------------

    def estimates(self, ds: xr.Dataset, run: int = 0) -> np.ndarray:
        """theta_hat over time from a results Dataset, shape (time, p)."""
        return np.stack([np.asarray(ds[s.name].isel(run=run).values, dtype=float) for s in self.parameter_layout.signals], axis=-1)

    def regressor_series(self, ds: xr.Dataset, run: int = 0) -> np.ndarray:
        """phi_f over time from a results Dataset, shape (time, n, p), joints in joint order."""
        columns = []
        for layout in self.regressor_layouts:
            parts = {s.name: np.asarray(ds[s.name].isel(run=run).values, dtype=float) for s in layout.signals}
            columns.append(np.asarray(layout.join(parts)))
        return np.stack(columns, axis=-1)


def windowed_excitation(time: npt.ArrayLike, regressor: npt.ArrayLike, window: float) -> tuple[np.ndarray, np.ndarray]:
    """Persistence of excitation: lambda_min of int_{t - T}^{t} phi_f^T phi_f ds at each t.

    The condition under which (3.9) converges exponentially is that this stays above
    some alpha > 0 for all t (with phi_f bounded); Lemma 3.1(2)'s pointwise rank
    condition is not it (module docstring).

    Parameters
    ----------
    time : array_like, shape (K,)
        Uniform sample times (s).
    regressor : array_like, shape (K, n, p)
        phi_f at those times (e.g. :meth:`ParameterEstimator.regressor_series`).
    window : float
        T (s), a positive whole number of sample intervals, at most the span of ``time``.

    Returns
    -------
    (times, lambda_min) : tuple of ndarray
        The window ends t >= time[0] + T and the smallest eigenvalue of the
        trapezoid-rule integral over [t - T, t] at each.
    """
    time = np.asarray(time, dtype=float)
    phi = np.asarray(regressor, dtype=float)
    if time.ndim != 1 or time.size < 2 or phi.ndim != 3 or phi.shape[0] != time.size:
        raise check.ParameterError(
            "regressor", f"regressor must have shape (len(time), n, p) with at least two times; got time {time.shape} and regressor {phi.shape}"
        )
    step = float(time[1] - time[0])
    if not (step > 0 and np.allclose(np.diff(time), step, rtol=1e-9, atol=0.0)):
        raise check.ParameterError("time", "time must be uniformly spaced and increasing")
    count = int(round(window / step)) if np.isfinite(window) and window > 0 else 0
    if count < 1 or abs(count * step - window) > 1e-9 * max(window, 1.0):
        raise check.ParameterError("window", f"window must be a positive whole number of sample intervals ({step:g} s); got {window:g}")
    if count >= time.size:
        raise check.ParameterError("window", f"window must be at most the span of the records ({time[-1] - time[0]:g} s); got {window:g}")
    gram = np.einsum("kia,kib->kab", phi, phi)
    cumulative = np.concatenate([np.zeros((1,) + gram.shape[1:]), np.cumsum(0.5 * (gram[1:] + gram[:-1]) * step, axis=0)])
    integral = cumulative[count:] - cumulative[:-count]
    return time[count:], np.linalg.eigvalsh(integral)[:, 0]


__all__ = ["ParameterEstimator", "ParameterEstimatorState", "windowed_excitation"]
