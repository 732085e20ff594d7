"""The assumptions of a Kalman filter's noise model, checked on the built filter (what
``lookout design`` and the Kalman filters' tuning family report): R > 0, Q >= 0,
P_0 >= 0."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from lookout.analysis.conditions import Condition, Inequality, Report

if TYPE_CHECKING:
    from lookout.observers.kalman import KalmanFilter

# ---------------------------------------------------------------------- the conditions
SOURCE = "Jazwinski (1970), Section 8.4"


def _correlation_minimum(matrix: np.ndarray) -> float:
    """The least eigenvalue of the correlation matrix of a covariance (a zero variance's
    row and column those of a unit one): the covariance is >= 0 exactly when its
    variances are and this is; NaN where the matrix is not finite."""
    matrix = np.asarray(matrix, dtype=float)
    if matrix.size == 0:
        return 1.0
    if not np.all(np.isfinite(matrix)):
        return float("nan")
    matrix = 0.5 * (matrix + matrix.T)
    variance = np.diag(matrix)
    known = variance > 0
    scale = np.where(known, np.sqrt(np.abs(variance)), 1.0)
    correlation = matrix / np.outer(scale, scale)
    correlation = np.where(np.outer(known, known), correlation, np.diag(np.where(known, 0.0, 1.0)))
    with np.errstate(invalid="ignore", over="ignore"):
        return float(np.linalg.eigvalsh(correlation).min())


def check_kalman_filter(observer: KalmanFilter) -> Report:
    """The assumptions of a Kalman filter's model, on the built filter: a
    :class:`~lookout.analysis.conditions.Report` of R > 0 (the measurement noise, so S is
    invertible), Q >= 0 (the intensities q, S, q_d; then Q_d >= 0 too) and P_0 >= 0
    (finite: where P_0 is the steady state, that it exists)."""
    r = np.asarray(observer.measurement_covariance, dtype=float)
    q = np.asarray(observer.process_noise, dtype=float)
    s = np.asarray(observer.state_noise, dtype=float)
    p0 = np.asarray(observer.initial_covariance, dtype=float)

    def least(values) -> float:
        values = np.asarray(values, dtype=float)
        return float("nan") if not np.all(np.isfinite(values)) else float(values.min(initial=np.inf))

    measurement = Condition(
        "measurement_noise_positive",
        "R > 0",
        "measurement noise positive definite",
        f"{SOURCE}: v_k ~ N(0, R), R > 0",
        [
            Inequality.check("variances", "min_i R_ii > 0", least(np.diag(r)), ">", 0.0, units="", source=SOURCE),
            Inequality.check(
                "correlation", "lambda_min(D^-1/2 R D^-1/2) > 0", _correlation_minimum(r), ">", 0.0, units="", source=SOURCE, tolerance=1e-12
            ),
        ],
        quantities={"measurement_std": np.sqrt(np.abs(np.diag(r))).tolist()},
    )
    intensities = [
        Inequality.check("process_noise", "min_i q_i >= 0", least(q) if q.size else 0.0, ">=", 0.0, units="", source=SOURCE),
        Inequality.check("state_noise", "min_i S_ii >= 0", least(s) if s.size else 0.0, ">=", 0.0, units="", source=SOURCE),
    ]
    process = Condition(
        "process_noise_nonnegative",
        "Q >= 0",
        "process noise intensities non-negative",
        f"{SOURCE}: white process noise, Q >= 0",
        intensities,
        quantities={"process_noise": q.tolist(), "state_noise": s.tolist()},
    )
    initial = Condition(
        "initial_covariance_nonnegative",
        "P_0 >= 0",
        "initial covariance positive semi-definite",
        f"{SOURCE}: x_0 ~ N(x^_0, P_0)",
        [
            Inequality.check("variances", "min_i P0_ii >= 0", least(np.diag(p0)), ">=", 0.0, units="", source=SOURCE),
            Inequality.check(
                "correlation", "lambda_min(D^-1/2 P_0 D^-1/2) >= 0", _correlation_minimum(p0), ">=", 0.0, units="", source=SOURCE, tolerance=1e-12
            ),
        ],
    )
    return Report(
        f"{type(observer).__name__}: the noise model's conditions",
        [measurement, process, initial],
        notes=["no lookout design command for the Kalman filters: their parameters are docs/kalman-filters.md's"],
    )


__all__ = ["SOURCE", "check_kalman_filter"]
