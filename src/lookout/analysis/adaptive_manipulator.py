"""Theorem 4.1 of Calugi (2002) on concrete numbers: the adaptive observer's conditions.

Calugi (2002), master thesis, Lund, Section 4.4, read as derived in
derivations-thesis-ch3-6.md (ch. 4). With V = 1/2 (x1~^T M x1~ + theta~^T Gamma^-1 theta~)
and the error system (4.21), the skew symmetry of M' - 2C (Property 4.1, Christoffel C)
gives::

    V' <= -(sigma - C_M w_max - C_M |x1~|) |x1~|^2,      sigma = inf_q lambda_min(K M(q) + M(q) K) / 2

(the constant is C_M w_max, not the 2 C_M w_max of (2.11), because the skew symmetry is
used). With p_l = min(M_m, 1/gamma_max) and p_u = max(M_M, 1/gamma_min) bounding
diag(M(q), Gamma^-1), and a margin beta > 0::

    (4.a)  sigma > C_M w_max + beta
    (4.b)  ||e(0)|| < sqrt(p_l / p_u) ((sigma - beta) / C_M - w_max),      e = (x1~, theta~)

then x1~ -> 0 exponentially and theta~ stays bounded (it need not go to zero: that
needs persistent excitation). With C_M = 0 (a pendulum) the region is all of R^n x R^p.
The model is the true one, M = M(q; theta); sigma and the constants are found over the
configuration space as for Theorem 2.1 (:mod:`lookout.analysis.velocity`).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt

from lookout import _validation as check
from lookout.analysis.conditions import Condition, Inequality, Report
from lookout.analysis.velocity import configuration_bounds
from lookout.models.manipulators import configuration_angles, configuration_grid
from lookout.models.parameters import AffineParameters

PAPER = "Calugi (2002)"
#: Units of sigma and the other side of (4.a) and (5.28): those of K M (1/s times inertia).
INJECTION_UNITS = "1/s kg m2"


def injection_bound(parameters: AffineParameters, gain: npt.ArrayLike, *, grid_points: int = 64) -> float:
    """sigma = min over q of lambda_min(K M(q) + M(q) K) / 2 for the true model, on a grid of
    the angles M depends on (M is smooth in q; the grid has 64 points per angle)."""
    model = parameters.model(parameters.reference)
    K = jnp.diag(jnp.asarray(check.vector("observer gain K", gain, model.size), dtype=float))
    q_grid = jnp.asarray(configuration_grid(model, configuration_angles(model), grid_points))

    def smallest(q):
        M = model.mass_matrix(q)
        return jnp.linalg.eigvalsh(K @ M + M @ K)[0] / 2.0

    return float(jnp.min(jax.jit(jax.vmap(smallest))(q_grid)))


def check_theorem_4_1(
    parameters: AffineParameters,
    gain: npt.ArrayLike,
    adaptation_gain: npt.ArrayLike,
    max_speed: float,
    *,
    margin: float = 0.0,
    initial_error: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
) -> Report:
    """Theorem 4.1 for the arm and unknowns ``parameters`` (true values at its reference),
    K, Gamma (diagonals), w_max >= ||q'||, beta = ``margin`` >= 0 and, optionally, the
    initial errors (x1~(0), theta~(0)) to place in the region (4.b).

    Returns a report with the condition ``theorem_4_1``: (4.a) and, with an initial error
    and C_M > 0, (4.b) (with C_M = 0 the region is global: a note says so); the constants
    in ``quantities``."""
    model = parameters.model(parameters.reference)
    K = np.asarray(check.vector("observer gain K", gain, model.size), dtype=float)
    Gamma = np.asarray(check.vector("adaptation gain Gamma", adaptation_gain, parameters.size), dtype=float)
    check.positive("observer gain K", K)
    check.positive("adaptation gain Gamma", Gamma)
    check.positive("max_speed", max_speed, allow_zero=True)
    check.positive("margin beta", margin, allow_zero=True)
    bounds = configuration_bounds(model)
    sigma = injection_bound(parameters, K)
    c_m = bounds.coriolis_bound
    p_l = min(bounds.min_inertia, 1.0 / Gamma.max())
    p_u = max(bounds.max_inertia, 1.0 / Gamma.min())
    source = f"{PAPER}, Theorem 4.1"
    inequalities = [Inequality.check("(4.a)", "sigma > C_M w_max + beta", sigma, ">", c_m * max_speed + margin, units=INJECTION_UNITS, source=source)]
    radius = math.inf if c_m == 0 else math.sqrt(p_l / p_u) * ((sigma - margin) / c_m - max_speed)
    quantities = {
        "sigma": sigma,
        "C_M": c_m,
        "M_m": bounds.min_inertia,
        "M_M": bounds.max_inertia,
        "p_l": p_l,
        "p_u": p_u,
        "max_speed": max_speed,
        "beta": margin,
        "radius": radius,
    }
    notes = []
    if initial_error is not None and c_m == 0:
        notes.append("region (4.b) global: C_M = 0, it holds for every initial error")
    if initial_error is not None and c_m > 0:
        x_error, theta_error = initial_error
        norm = float(
            np.linalg.norm(np.concatenate([np.atleast_1d(np.asarray(x_error, dtype=float)), np.atleast_1d(np.asarray(theta_error, dtype=float))]))
        )
        if not math.isfinite(norm):
            raise check.ParameterError("initial_error", f"initial_error must be finite; got {initial_error!r}")
        inequalities.append(
            Inequality.check("(4.b)", "sqrt(p_l/p_u) ((sigma - beta)/C_M - w_max) > ||e(0)||", radius, ">", norm, units="mixed", source=source)
        )
        quantities["initial_error_norm"] = norm
    condition = Condition("theorem_4_1", "Theorem 4.1", "adaptive observer: x1~ -> 0, theta~ bounded", source, inequalities)
    return Report(f"{PAPER}, Theorem 4.1: adaptive observer", (condition,), quantities, notes=notes)


def check_5_28(
    parameters: AffineParameters, gain: npt.ArrayLike, damping_weights: npt.ArrayLike, max_speed: float, initial_error: npt.ArrayLike = 0.0
) -> Report:
    """(5.28) of Calugi (2002), ch. 5, for the closed loop of (5.9) with the adaptive observer:
    from (5.27), V' <= -z^T C_z z - (sigma - C_M w_max - C_M |x1~| - p/4) |x1~|^2 with
    sigma = inf_q lambda_min(K M + M K)/2 and p = sum_{i=1}^{2n} 1/d_i (the thesis's "6"
    and omega_{i+3} are carried over from the ship case; derivations-thesis-ch3-6.md).
    Two inequalities: at rest (w_max = 0, x1~ = 0; a necessary part) and with the given
    w_max and |x1~| (the initial velocity error). Returns a report with the condition
    ``condition_5_28``."""
    model = parameters.model(parameters.reference)
    d = np.asarray(check.vector("damping_weights d", damping_weights, 2 * model.size), dtype=float)
    check.positive("damping_weights d", d)
    check.positive("max_speed", max_speed, allow_zero=True)
    error = float(np.linalg.norm(np.atleast_1d(np.asarray(initial_error, dtype=float))))
    if not math.isfinite(error):
        raise check.ParameterError("initial_error", f"initial_error must be finite; got {initial_error!r}")
    sigma = injection_bound(parameters, gain)
    c_m = configuration_bounds(model).coriolis_bound
    p = float(np.sum(1.0 / d))
    source = f"{PAPER}, eq. (5.28)"
    inequalities = [
        Inequality.check("(5.28) at rest", "sigma > p/4", sigma, ">", p / 4.0, units=INJECTION_UNITS, source=source),
        Inequality.check(
            "(5.28)", "sigma > C_M w_max + C_M |x1~| + p/4", sigma, ">", c_m * max_speed + c_m * error + p / 4.0, units=INJECTION_UNITS, source=source
        ),
    ]
    condition = Condition("condition_5_28", "(5.28)", "adaptive observer backstepping, closed loop", source, inequalities)
    return Report(
        f"{PAPER}, (5.28): adaptive observer backstepping",
        (condition,),
        {"sigma": sigma, "C_M": c_m, "p": p, "max_speed": max_speed, "velocity_error": error},
    )


__all__ = ["check_5_28", "check_theorem_4_1", "injection_bound"]
