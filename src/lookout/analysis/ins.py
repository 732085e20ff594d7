"""The conditions of the IMU-aided observer (:mod:`lookout.observers.ins`), for
``lookout design``.

- **Observable from the aiding**: the filter's model linearized at its start (the
  observer's initial guess, the vessel at rest, the IMU reading zero) over one filter
  sample, with every aiding channel (position references, gyros, speed sensors; the
  IMU is the model's input) taken: the observability matrix
  ``[H; H F; ...; H F^(n-1)]`` has full rank n (Kalman's rank test, in the discrete
  form; Kailath (1980), Linear Systems, Section 2.3). Each state is scaled by its prior
  spread and each channel by its noise, so that the rank is judged in the units the
  filter weighs them by; the smallest singular value relative to the largest is the
  margin. Without a heading the gyro's bias is not observable, and at rest the
  accelerometers' biases are observable only through the heading.
- **The IMU at the filter's rate**: the IMU's reading is held over each filter sample, so
  its sample period must equal the filter's (a slower IMU would be integrated from a
  stale reading; a faster one's samples between the filter's would be left unused).
- **The Kalman filter's model**: R > 0, Q >= 0, P_0 >= 0
  (:func:`lookout.analysis.kalman.check_kalman_filter`).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout.analysis.conditions import Condition, Inequality, Report
from lookout.observers.ins import InertialNavigationFilter
from lookout.sensing.motion import InertialUnit
from lookout.sensing.suite import SensorSuite

#: Smallest singular value of the scaled observability matrix, relative to its largest,
#: that counts as full rank (double precision's rounding on matrices of this size is 1e-13).
RANK_TOLERANCE = 1e-9


def observability_margin(observer: InertialNavigationFilter, aiding: tuple[bool, ...] | None = None) -> float:
    """The smallest singular value over the largest of the scaled observability matrix of
    ``observer`` (an :class:`~lookout.observers.ins.InertialNavigationFilter`) at its
    initial guess (module docstring), from the channels ``aiding`` marks (default: all
    but the IMU's)."""
    transition, observation = (np.asarray(a, dtype=float) for a in _linearization(observer, float(observer.filter_period)))
    keep = ~np.asarray(observer.ignored_channels) if aiding is None else np.asarray(aiding, dtype=bool)
    noise = np.sqrt(np.diag(np.asarray(observer.measurement_covariance)))
    scale = np.sqrt(np.diag(np.asarray(observer.initial_covariance)))
    h = observation[keep] / noise[keep, None] * scale[None, :]
    f = transition * scale[None, :] / scale[:, None]
    n = f.shape[0]
    blocks, power = [], np.eye(n)
    for _ in range(n):
        blocks.append(h @ power)
        power = f @ power
    values = np.linalg.svd(np.vstack(blocks), compute_uv=False)
    return float(values[-1] / values[0]) if values[0] > 0 else 0.0


def _linearization(observer: InertialNavigationFilter, dt: float) -> tuple[Array, Array]:
    zero = observer.augmented(observer.guess())
    zero = jnp.where(jnp.isnan(zero), 0.0, zero)
    reading = jnp.zeros(3)
    transition, _, _ = observer.linearized(zero, 0.0, reading, dt)
    return transition, jax.jacfwd(lambda x: observer.measurement(x, reading))(zero)


def check_ins(composition: Any) -> Report:
    """The conditions of the module docstring for the composition's observer."""
    from lookout.analysis.kalman import check_kalman_filter

    observer = composition.scenario.observer
    source = "lookout.observers.ins"
    margin = observability_margin(observer)
    observable = Condition(
        "observable",
        "(O)",
        "observable from the aiding channels",
        f"{source}; Kailath (1980), Section 2.3",
        [
            Inequality.check(
                "O",
                "smallest / largest singular value of the scaled observability matrix",
                margin,
                ">",
                RANK_TOLERANCE,
                units="",
                source=source,
                tolerance=0.0,
            )
        ],
    )
    imu_period = float(_imu(observer).sample_period)
    rate = Condition(
        "imu_rate",
        "(I)",
        "the IMU sampled at every filter sample",
        source,
        [
            Inequality.check(
                "I",
                "IMU sample period = filter period",
                imu_period,
                "<=",
                float(observer.filter_period),
                units="s",
                source=source,
            ),
            Inequality.check(
                "I'",
                "filter period = IMU sample period",
                float(observer.filter_period),
                "<=",
                imu_period,
                units="s",
                source=source,
            ),
        ],
    )
    kalman = check_kalman_filter(observer)
    return Report(
        "IMU-aided observer (lookout.observers.ins)",
        (observable, rate, *kalman.conditions),
        quantities={"observability_margin": margin, "imu_period": imu_period, "filter_period": float(observer.filter_period)},
    )


def _imu(observer: InertialNavigationFilter) -> InertialUnit:
    suite = observer.sensor
    assert isinstance(suite, SensorSuite)  # the observer refuses any other sensor
    start = 0
    for each in suite.instruments:
        if start == observer.imu_start and isinstance(each, InertialUnit):
            return each
        start += each.size
    raise ValueError("the observer's IMU is not in its suite")


__all__ = ["RANK_TOLERANCE", "check_ins", "observability_margin"]
