"""Theorem 2.1 of Calugi (2002) on concrete numbers: the velocity observer's gain condition.

Calugi (2002), master thesis, Lund, Section 2.2. With V = 1/2 x1~^T x1~ and the error
dynamics (2.9), Properties 2.1 and 2.3 and the speed bound (2.2) give (2.11)::

    V' <= (C_M / M_m (2 w_max + |x1~|) - sigma) |x1~|^2,      sigma = lambda_min(K)

so V decreases while |x1~| < M_m sigma / C_M - 2 w_max (region 2.13, Remark 2.1),
and from x1_hat(0) = 0 (|x1~(0)| = |q'(0)| <= w_max) the error converges
exponentially if sigma > 3 C_M w_max / M_m (Theorem 2.1). The constants:

* M_m = min over q of lambda_min(M(q)) and M_M = max over q of lambda_max(M(q))
  (Property 2.1; ``||M^-1|| <= 1/M_m`` is what (2.11) uses);
* C_M = max over q and unit v of ||C(q, v)||_2 (Property 2.3), for the
  Christoffel-symbol C of :meth:`~lookout.models.manipulators.ManipulatorModel.coriolis_matrix`,
  the factorization for which Property 2.2, used to derive (2.9), holds.

Norms are Euclidean in joint space (for the cart-pendulum they mix m/s and rad/s,
as the thesis does). The constants are found numerically over the configuration
space (:func:`configuration_bounds`): M(q), and with it C, depends only on the
revolute angles that it is found to vary with (checked at random configurations);
those angles are gridded over [-pi, pi) and the best grid point is refined by
Nelder–Mead. A prismatic coordinate must not enter M (the
cart position does not); if it does, there is no bounded configuration space to
search and a ValueError says so.

Friction. The thesis puts friction inside C, but then neither Property 2.2 nor
Property 2.3 (||C(q, v)|| <= C_M ||v|| for all v) can hold, since F v does not
vanish with the velocity. With friction apart (plant and observer both carry
F q'), (2.9) gains ``-M^-1 F x1~`` and (2.11) gains ``-x1~^T M^-1 F x1~
<= -phi |x1~|^2`` with::

    phi = min over q of lambda_min(1/2 (M^-1(q) F + F M^-1(q)))

When phi >= 0 friction only adds dissipation and the thesis's condition, with
friction left out, stays sufficient; M^-1 F is not symmetric, though, and phi can
be negative when the joints' frictions differ (the printed two-link arm, c1 = 0.5
and c2 = 0.1: phi = -0.21 1/s), and then the bound needs it.
So the condition reported here uses ``sigma_eff = sigma + min(phi, 0)``: it is the
thesis's condition whenever friction cannot hurt, and a sufficient one always.
(For the free pendulum C = 0 and the error obeys x1~' = -(K + c/(m l^2)) x1~
exactly: the thesis's gain K = 2 - c/(m l^2) puts the decay rate at 2, which
is sigma + phi, not sigma_eff.) ``friction_bound`` reports phi.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
import scipy.optimize

from lookout import _validation as check
from lookout.analysis.conditions import Condition, Inequality, Report
from lookout.models.manipulators import ManipulatorModel, configuration_angles, configuration_grid


def _directions(n: int, direction_points: int) -> np.ndarray:
    """Unit vectors covering the sphere up to sign (||C(q, v)|| is even in v)."""
    if n == 1:
        return np.ones((1, 1))
    if n == 2:
        phi = np.pi * np.arange(direction_points) / direction_points
        return np.stack([np.cos(phi), np.sin(phi)], axis=1)
    rng = np.random.default_rng(20021)
    v = np.vstack([np.eye(n), rng.standard_normal((direction_points * n, n))])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _maximize(objective, grid: np.ndarray, values: np.ndarray, refine: bool) -> float:
    """max of the scalar ``objective`` given its ``values`` on the rows of ``grid``: the
    best row refined by Nelder–Mead (the larger of the two)."""
    best = int(np.argmax(values))
    value = float(values[best])
    if not refine or grid.shape[1] == 0:
        return value
    result = scipy.optimize.minimize(
        lambda p: -objective(p),
        grid[best],
        method="Nelder-Mead",
        options={"xatol": 1e-10, "fatol": 1e-15, "maxiter": 4000},
    )
    return max(value, -float(result.fun))


def _configuration_functions(model: ManipulatorModel, angles: tuple[int, ...]):
    """The searched quantities as functions of the relevant angles ``p`` (and of a
    velocity direction for the Coriolis norm), jitted once per call."""
    k = len(angles)
    index = jnp.asarray(angles, dtype=int)

    def q_of(p):
        return jnp.zeros(model.size).at[index].set(p[:k]) if k else jnp.zeros(model.size)

    @jax.jit
    def inertia_and_friction(p):
        """(-lambda_min(M), lambda_max(M), -lambda_min(sym(M^-1 F))): all maximized."""
        M = model.mass_matrix(q_of(p))
        eigenvalues = jnp.linalg.eigvalsh(M)
        product = jnp.linalg.solve(M, jnp.diag(model.friction))
        friction = jnp.linalg.eigvalsh(0.5 * (product + product.T))[0]
        return jnp.stack([-eigenvalues[0], eigenvalues[-1], -friction])

    @jax.jit
    def coriolis_norm(p):
        """||C(q, v / |v|)||_2 with p = (angles, v)."""
        v = p[k:]
        return jnp.linalg.norm(model.coriolis_matrix(q_of(p), v / jnp.linalg.norm(v)), 2)

    return inertia_and_friction, coriolis_norm


@dataclass(frozen=True)
class ConfigurationBounds:
    """The model constants of Theorem 2.1, found over the configuration space.

    Attributes
    ----------
    min_inertia, max_inertia : float
        M_m and M_M of Property 2.1.
    coriolis_bound : float
        C_M of Property 2.3 (Christoffel C).
    friction_bound : float
        phi = min_q lambda_min(sym(M^-1 F)).
    angles : tuple of str
        Names of the joints whose angle M depends on (the searched coordinates).
    """

    min_inertia: float
    max_inertia: float
    coriolis_bound: float
    friction_bound: float
    angles: tuple[str, ...]

    def to_dict(self) -> dict:
        """Plain Python values."""
        return asdict(self) | {"angles": list(self.angles)}


def configuration_bounds(model: ManipulatorModel, *, grid_points: int = 64, direction_points: int = 64, refine: bool = True) -> ConfigurationBounds:
    """M_m, M_M (Property 2.1), C_M (Property 2.3) and phi of ``model``, to reuse across
    gains and speed bounds.

    C_M = max over q and unit v of ||C(q, v)||_2 for the Christoffel C; C is linear in
    v, so ``||C(q, v)|| <= C_M ||v||`` for every v. Each quantity is maximized over a
    grid of the angles M depends on (:func:`configuration_angles`; ``grid_points``
    per angle over [-pi, pi)) and, for C_M, of velocity directions
    (``direction_points`` on a half circle for n = 2), then refined by Nelder–Mead
    from the best grid point.
    """
    angles = configuration_angles(model)
    q_grid = configuration_grid(model, angles, grid_points)[:, list(angles)]
    inertia_and_friction, coriolis_norm = _configuration_functions(model, angles)
    table = np.asarray(jax.jit(jax.vmap(inertia_and_friction))(jnp.asarray(q_grid)))
    extremes = [_maximize(lambda p, i=i: float(np.asarray(inertia_and_friction(jnp.asarray(p)))[i]), q_grid, table[:, i], refine) for i in range(3)]
    directions = _directions(model.size, direction_points)
    pairs = np.concatenate([np.repeat(q_grid, len(directions), axis=0), np.tile(directions, (len(q_grid), 1))], axis=1)
    norms = np.asarray(jax.jit(jax.vmap(coriolis_norm))(jnp.asarray(pairs)))
    c_max = _maximize(lambda p: float(coriolis_norm(jnp.asarray(p))), pairs, norms, refine and norms.max() > 0.0)
    return ConfigurationBounds(
        min_inertia=-extremes[0],
        max_inertia=extremes[1],
        coriolis_bound=c_max,
        friction_bound=-extremes[2],
        angles=tuple(model.joint_names[i] for i in angles),
    )


@dataclass(frozen=True)
class VelocityObserverCondition:
    """Theorem 2.1 of Calugi (2002) evaluated for one model, gain and speed bound.

    Attributes
    ----------
    gain_bound : float
        sigma = lambda_min(K) (1/s).
    friction_bound : float
        phi = min_q lambda_min(sym(M^-1 F)) (1/s); see the module docstring.
    effective_gain : float
        sigma + min(phi, 0): the gain the condition uses.
    min_inertia, max_inertia : float
        M_m and M_M of Property 2.1 (in the units of M).
    coriolis_bound : float
        C_M of Property 2.3, Christoffel C.
    max_speed : float
        w_max of (2.2) (joint-space 2-norm of q').
    threshold : float
        3 C_M w_max / M_m (1/s).
    radius : float
        Region (2.13): M_m effective_gain / C_M - 2 w_max (``inf`` when C_M = 0);
        exponential convergence for every initial error of smaller norm.
    initial_error : float or None
        ||x1~(0)|| if given.
    report : Report
        The conditions: ``theorem_2_1`` (effective_gain > threshold) and, with an
        initial error, ``region_2_13`` (radius > initial_error); the numbers above in
        its ``quantities``. Its :meth:`~lookout.analysis.conditions.Report.to_dict` is
        the JSON form.
    """

    gain_bound: float
    friction_bound: float
    effective_gain: float
    min_inertia: float
    max_inertia: float
    coriolis_bound: float
    max_speed: float
    threshold: float
    radius: float
    initial_error: float | None
    report: Report

    @property
    def satisfied(self) -> bool:
        """Theorem 2.1's sufficient condition holds."""
        return self.report["theorem_2_1"].holds

    @property
    def margin(self) -> float:
        """effective_gain - threshold."""
        return self.report["theorem_2_1"].inequalities[0].margin

    @property
    def inside_region(self) -> bool | None:
        """initial_error < radius, if an initial error is given."""
        return self.report["region_2_13"].holds if self.initial_error is not None else None

    def __str__(self) -> str:
        text = (
            f"Theorem 2.1 {self.report['theorem_2_1'].verdict}: sigma_eff = {self.effective_gain:.4g} vs 3 C_M w_max / M_m = {self.threshold:.4g} "
            f"(C_M = {self.coriolis_bound:.4g}, M_m = {self.min_inertia:.4g}, w_max = {self.max_speed:.4g}); "
            f"region (2.13) radius {self.radius:.4g}"
        )
        if self.initial_error is not None:
            text += f", initial error {self.initial_error:.4g} {'inside' if self.inside_region else 'outside'}"
        return text


def velocity_observer_condition(
    model: ManipulatorModel,
    gain: npt.ArrayLike,
    max_speed: float,
    *,
    initial_error: float | None = None,
    bounds: ConfigurationBounds | None = None,
    grid_points: int = 64,
    direction_points: int = 64,
    refine: bool = True,
) -> VelocityObserverCondition:
    """Theorem 2.1 and region (2.13) of Calugi (2002) for ``model``, gain K and speed bound.

    Parameters
    ----------
    model : ManipulatorModel
        The model (the observer's and the plant's are taken to be the same).
    gain : float or array_like, shape (n,)
        Diagonal of K, > 0.
    max_speed : float
        w_max >= 0, a bound on ||q'(t)|| (eq. 2.2).
    initial_error : float, optional
        ||x1~(0)||, to check against the region (2.13).
    bounds : ConfigurationBounds, optional
        The model's constants from :func:`configuration_bounds` (computed if absent).
    grid_points : int
        Grid points per relevant angle over [-pi, pi).
    direction_points : int
        Velocity directions of the C_M search (n = 2: points on a half circle).
    refine : bool
        Refine the grid's best points by Nelder–Mead.

    Returns
    -------
    VelocityObserverCondition
    """
    gain = check.vector("velocity observer gain", gain, model.size)
    check.positive("velocity observer gain", gain)
    check.positive("max_speed", max_speed, allow_zero=True)
    if initial_error is not None:
        check.positive("initial_error", initial_error, allow_zero=True)
    sigma = float(np.min(gain))
    if bounds is None:
        bounds = configuration_bounds(model, grid_points=grid_points, direction_points=direction_points, refine=refine)
    low, high = bounds.min_inertia, bounds.max_inertia
    c_max, phi = bounds.coriolis_bound, bounds.friction_bound
    effective = sigma + min(phi, 0.0)
    w_max = float(max_speed)
    threshold = 3.0 * c_max * w_max / low
    radius = math.inf if c_max == 0.0 else low * effective / c_max - 2.0 * w_max
    error = None if initial_error is None else float(initial_error)
    numbers: dict[str, Any] = {
        "gain_bound": sigma,
        "friction_bound": phi,
        "effective_gain": effective,
        "min_inertia": low,
        "max_inertia": high,
        "coriolis_bound": c_max,
        "max_speed": w_max,
        "threshold": threshold,
        "radius": radius,
        "initial_error": error,
    }
    source = "Calugi (2002), Theorem 2.1, eq. (2.11)"
    conditions = [
        Condition(
            "theorem_2_1",
            "Theorem 2.1",
            "velocity observer: x1~ -> 0 exponentially",
            source,
            [Inequality.check("sigma_eff", "sigma + min(phi, 0) > 3 C_M w_max / M_m", effective, ">", threshold, units="1/s", source=source)],
        ),
    ]
    if error is not None:
        region = "Calugi (2002), Remark 2.1, region (2.13)"
        conditions.append(
            Condition(
                "region_2_13",
                "(2.13)",
                "the initial error inside the region",
                region,
                [
                    Inequality.check(
                        "||x1~(0)||", "M_m sigma_eff / C_M - 2 w_max > ||x1~(0)||", radius, ">", error, units="joint-space norm of q'", source=region
                    )
                ],
            )
        )
    report = Report("Calugi (2002), Theorem 2.1: velocity observer", conditions, numbers)
    return VelocityObserverCondition(**numbers, report=report)
