"""The Kalman filters' family (``kind = "ekf"`` and ``"ukf"``): the process noise Q and the
measurement noise R, non-negative and positive definite by construction, checked on the
built filter at every accepted step.

The filters are :mod:`lookout.observers.kalman` (shared), :mod:`lookout.observers.ekf`
and :mod:`lookout.observers.ukf`: the continuous-discrete filter of Jazwinski (1970),
Stochastic Processes and Filtering Theory, Section 8.4, whose model assumes white
process noise of intensity Q >= 0 and measurement noise v_k ~ N(0, R) with R > 0 (so
that the innovation covariance S = H P- H^T + R is invertible whatever P-). What a
scenario file can say of them is what is tuned, spelled as the file spells it
(docs/kalman-filters.md), so that the tuned file composes back into the tuned filter:

* ``process_noise`` q (one intensity per noise input of the model) and ``state_noise``
  S (one per state entry), which give the discrete process noise
  Q_d = sum_j G_j diag(q) G_j^T / plant_step + S dt (:mod:`lookout.observers.kalman`);
* ``input_disturbance`` q_d, the random walk of the unknown input disturbance (only
  for a filter that estimates one);
* ``measurement_noise``, one standard deviation per channel: R = diag(std^2), the
  file's only form of R (a diagonal matrix, whose Cholesky factor is diag(std)).

There is no ``lookout design`` command for the Kalman filters: docs/kalman-filters.md
says what their parameters mean. Where the file gives no ``initial_std``, P_0 is the
steady state of the filter's own Q and R (the discrete algebraic Riccati equation of
the model linearized at its zero state), so it moves with them here too, with its
derivative from the Riccati equation itself (:func:`_riccati_derivative`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout.analysis.kalman import SOURCE as SOURCE
from lookout.analysis.kalman import check_kalman_filter as check_kalman_filter
from lookout.tuning.families import Family

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.observers.kalman import KalmanFilter
    from lookout.sim import Scenario

#: Where the steady-state P_0 counts as the scenario's own: entries of P_0 - P_ss, each
#: divided by the two standard deviations, at most this (the states' units span 1e14).
SAME_STEADY_STATE = 1e-9


def _observer(scenario: Scenario) -> KalmanFilter:
    from lookout.observers.kalman import KalmanFilter

    observer = scenario.observer
    if not isinstance(observer, KalmanFilter):  # component_as, for an abstract class (mypy's type[T] takes concrete ones)
        raise TypeError(f"observer is a {type(observer).__name__}, not the KalmanFilter its tuning family reads")
    return observer


@dataclass(frozen=True)
class KalmanFamily(Family):
    """Q and R of an extended or unscented Kalman filter (module docstring). With theta
    the log of every positive intensity and of every channel's standard deviation::

        process_noise      q_i   = exp(a_i)   where the start has q_i > 0, else 0
        state_noise        S_i   = exp(b_i)   where the start has S_i > 0, else 0
        input_disturbance  q_d,i = exp(c_i)   where the start has q_d,i > 0, else 0
        measurement_noise  std_i = exp(e_i),  R = diag(std^2)

    so every theta gives Q >= 0 and R > 0. An intensity that starts at zero stays zero
    (a state the model trusts exactly, a disturbance entry held constant): give it a
    small positive start in the file to tune it. The file's ``state_noise`` is written
    with zeros on the disturbance's entries and its whole random walk in
    ``input_disturbance`` (the filter adds the two).
    """

    state_size: int
    disturbance_size: int
    process_free: np.ndarray  # (noise_size,) bool: tuned entries of process_noise
    state_free: np.ndarray  # (state_size,) bool: tuned entries of state_noise
    disturbance_free: np.ndarray  # (disturbance_size,) bool: tuned entries of input_disturbance
    channels: int
    #: P_0 follows Q and R (the file gives no initial_std): (F, H, G) of the model
    #: linearized at its zero state over one filter period, whence the filter's P_0.
    steady: tuple | None
    name: str
    keys: tuple[str, ...]
    design: str = "docs/kalman-filters.md"

    @classmethod
    def of(cls, scenario: Scenario) -> KalmanFamily:
        """The family of ``scenario``'s filter; a ValueError names measurement_noise when
        its R is not diagonal (the file writes R as one standard deviation per channel)."""
        observer = _observer(scenario)
        r = np.asarray(observer.measurement_covariance, dtype=float)
        if np.any(r != np.diag(np.diag(r))):
            raise ValueError(
                "measurement_noise: the filter's R is not diagonal (the sensor's noise is correlated across channels), and a scenario file "
                "writes R as one standard deviation per channel; give measurement_noise to start from a diagonal R"
            )
        n, d = int(observer.state_size), int(observer.disturbance_size)
        s = np.asarray(observer.state_noise, dtype=float)
        dt = float(observer.filter_period)
        transition, observation, noise = (np.asarray(a) for a in _linearization(observer, dt))
        own = _solve_riccati(transition, observation, observer._noise_covariance(jnp.asarray(noise), dt), r)
        given = np.asarray(observer.initial_covariance, dtype=float)
        steady = (transition, observation, noise) if np.all(np.isfinite(own)) and _same(given, own) else None
        what = "extended" if type(observer).__name__.startswith("Extended") else "unscented"
        keys = ("observer.process_noise", "observer.state_noise") + (("observer.input_disturbance",) if d else ()) + ("observer.measurement_noise",)
        return cls(
            n,
            d,
            np.asarray(observer.process_noise, dtype=float) > 0,
            s[:n] > 0,
            s[n:] > 0,
            r.shape[0],
            steady,
            f"{what} Kalman filter (Jazwinski 1970, Section 8.4): Q >= 0 and R > 0 by construction, P_0 "
            + ("the steady state of Q, R" if steady is not None else "as given"),
            keys,
        )

    # ------------------------------------------------------------------ theta <-> gains
    def _counts(self) -> tuple[int, ...]:
        return int(self.process_free.sum()), int(self.state_free.sum()), int(self.disturbance_free.sum()), self.channels

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        theta = jnp.asarray(theta)
        parts, start = [], 0
        for count in self._counts():
            parts.append(theta[start : start + count])
            start += count
        a, b, c, e = parts
        process = jnp.zeros(self.process_free.size).at[np.flatnonzero(self.process_free)].set(jnp.exp(a))
        state = jnp.zeros(self.state_size + self.disturbance_size).at[np.flatnonzero(self.state_free)].set(jnp.exp(b))
        out = [process, state]
        if self.disturbance_size:
            out.append(jnp.zeros(self.disturbance_size).at[np.flatnonzero(self.disturbance_free)].set(jnp.exp(c)))
        return (*out, jnp.exp(e))

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        arrays = [np.asarray(g, dtype=float) for g in gains]
        process, state, std = arrays[0], arrays[1], arrays[-1]
        disturbance = arrays[2] if self.disturbance_size else np.zeros(0)
        pieces = []
        if state.shape != (self.state_size + self.disturbance_size,):
            raise ValueError(f"observer.state_noise: expected {self.state_size + self.disturbance_size} entries; got shape {state.shape}")
        for key, value, free in zip(
            ("observer.process_noise", "observer.state_noise", "observer.input_disturbance"),
            (process, state[: self.state_size], disturbance),
            (self.process_free, self.state_free, self.disturbance_free),
        ):
            if value.shape != free.shape:
                raise ValueError(f"{key}: expected {free.size} entries; got shape {value.shape}")
            if np.any(value[free] <= 0) or np.any(value[~free] != 0) or not np.all(np.isfinite(value)):
                raise ValueError(f"{key}: the tuned entries must be finite and > 0 and the others 0 (as at the start); got {value.tolist()}")
            pieces.append(np.log(value[free]))
        if np.any(state[self.state_size :] != 0):
            raise ValueError(
                f"observer.state_noise: its input_disturbance entries are written as 0 (the random walk is input_disturbance's); got {state.tolist()}"
            )
        if std.shape != (self.channels,) or not (np.all(np.isfinite(std)) and np.all(std > 0)):
            raise ValueError(f"observer.measurement_noise must be {self.channels} finite standard deviations > 0; got {std.tolist()}")
        return np.concatenate([*pieces, np.log(std)])

    # ------------------------------------------------------------------ the filter
    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        arrays = [jnp.asarray(g) for g in gains]
        process, state, std = arrays[0], arrays[1], arrays[-1]
        if self.disturbance_size:
            state = state + jnp.concatenate([jnp.zeros(self.state_size), arrays[2]])
        observer = eqx.tree_at(
            lambda o: (o.process_noise, o.state_noise, o.measurement_covariance), scenario.observer, (process, state, jnp.diag(std**2))
        )
        if self.steady is not None:
            transition, observation, noise = self.steady
            dt = float(observer.filter_period)
            q_d = observer._noise_covariance(jnp.asarray(noise), dt)
            p0 = _riccati(transition, observation)(q_d, observer.measurement_covariance)
            observer = eqx.tree_at(lambda o: o.initial_covariance, observer, p0)
        return eqx.tree_at(lambda s: s.observer, scenario, observer)

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        """The filter's own q, S (the disturbance's entries 0), q_d and standard deviations."""
        observer = _observer(scenario)
        s = np.asarray(observer.state_noise, dtype=float)
        n = self.state_size
        state = np.concatenate([s[:n], np.zeros(self.disturbance_size)])
        std = np.sqrt(np.diag(np.asarray(observer.measurement_covariance, dtype=float)))
        out = [np.asarray(observer.process_noise, dtype=float), state]
        if self.disturbance_size:
            out.append(s[n:])
        return (*out, std)

    def check(self, scenario: Scenario) -> Report:
        """R > 0, Q >= 0 and P_0 >= 0 of the built filter (:func:`check_kalman_filter`)."""
        return check_kalman_filter(_observer(scenario))


def _same(given: np.ndarray, steady: np.ndarray) -> bool:
    """Whether P_0 is the steady state (judged entry by entry in units of the two
    standard deviations, the states' units spanning many decades)."""
    scale = np.sqrt(np.abs(np.diag(steady)))
    scale = np.where(scale > 0, scale, 1.0)
    return bool(np.all(np.abs(given - steady) <= SAME_STEADY_STATE * np.outer(scale, scale)))


@eqx.filter_jit
def _linearization(observer, dt: float):
    """(F, H, G) at the model's zero state (u = 0, t = 0) over ``dt``: as the filter linearizes for its
    steady-state P_0 (:func:`lookout.observers.kalman._linearized`), with G the step's
    Jacobian in the noise of its substeps (Q_d is linear in q and S through it)."""
    from lookout.observers.kalman import _linearized

    transition, _, observation = _linearized(observer, dt)
    zero = observer.augmented(observer.model.state())
    u = jnp.zeros(observer.input_layout.size)
    substeps, size = observer.substeps(dt), observer.model.noise_size
    noise = jax.jacfwd(lambda w: observer.step(zero, 0.0, u, dt, w.reshape(substeps, size)))(jnp.zeros(substeps * size))
    return transition, observation, noise


def _solve_riccati(transition: np.ndarray, observation: np.ndarray, q_d, r) -> np.ndarray:
    """The prior covariance P of the steady-state filter, scipy's solve_discrete_are as the
    filter takes it, symmetrized; NaN where it does not exist."""
    from scipy.linalg import solve_discrete_are

    q_d, r = np.asarray(q_d, dtype=float), np.asarray(r, dtype=float)
    try:
        solution = solve_discrete_are(transition.T, observation.T, q_d, r)
    except (np.linalg.LinAlgError, ValueError):
        return np.full_like(q_d, np.nan)
    return 0.5 * (solution + solution.T)


def _riccati(transition: np.ndarray, observation: np.ndarray):
    """(Q_d, R) -> P, the steady-state prior covariance of
    P = F P F^T + Q_d - F P H^T (H P H^T + R)^-1 H P F^T, differentiable: its tangent
    (:func:`_riccati_derivative`) solves a Stein equation."""
    f, h = jnp.asarray(transition), jnp.asarray(observation)

    @jax.custom_jvp
    def solve(q_d, r):
        shape = jax.ShapeDtypeStruct(q_d.shape, q_d.dtype)
        return jax.pure_callback(lambda a, b: _solve_riccati(transition, observation, a, b).astype(a.dtype), shape, q_d, r, vmap_method="sequential")

    @solve.defjvp
    def _(primals, tangents):
        p = solve(*primals)
        return p, _riccati_derivative(f, h, p, primals[1], *tangents)

    return solve


def _riccati_derivative(f, h, p, r, dq, dr):
    """dP of the steady-state Riccati solution P for dQ_d, dR. With K = F P H^T S^-1,
    S = H P H^T + R and the closed loop A = F - K H, the gain's stationarity leaves

        dP = A dP A^T + dQ_d + K dR K^T

    (a Stein equation: the Riccati equation written in Joseph's form, whose derivative
    in K vanishes at the optimal gain), solved by its Kronecker form on the states
    scaled by P's standard deviations."""
    s = h @ p @ h.T + r
    gain = jnp.linalg.solve(s, h @ p @ f.T).T
    closed = f - gain @ h
    right = dq + gain @ dr @ gain.T
    scale = jnp.sqrt(jnp.abs(jnp.diagonal(p)))
    scale = jnp.where(scale > 0, scale, 1.0)
    a = closed * (1.0 / scale)[:, None] * scale[None, :]
    n = p.shape[0]
    x = jnp.linalg.solve(jnp.eye(n * n) - jnp.kron(a, a), (right / jnp.outer(scale, scale)).ravel()).reshape(n, n)
    x = 0.5 * (x + x.T)
    return x * jnp.outer(scale, scale)


__all__ = ["KalmanFamily", "check_kalman_filter"]
