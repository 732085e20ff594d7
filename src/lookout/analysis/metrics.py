"""Metrics on simulation results: estimation errors, RMS, settling time, decay rate."""

from __future__ import annotations

from typing import cast

import numpy as np
import numpy.typing as npt
import xarray as xr

from lookout import _validation as check
from lookout._math import ssa


def estimation_errors(ds: xr.Dataset) -> xr.Dataset:
    """Truth minus estimate for every variable ``v`` that has an estimate ``v_hat``.

    Angles (variables with the attribute ``angle = 1``) are differenced through
    ``ssa``. Each error keeps the variable's name, units and frame.
    """
    errors = {}
    for name in ds.data_vars:
        estimate = f"{name}_hat"
        if estimate not in ds:
            continue
        error = ds[name] - ds[estimate]
        if ds[name].attrs.get("angle"):
            error = xr.apply_ufunc(lambda a: np.asarray(ssa(a)), error)
        attrs = {key: ds[name].attrs[key] for key in ("units", "frame", "angle") if key in ds[name].attrs}
        errors[name] = error.assign_attrs(attrs, long_name=f"estimation error of {ds[name].attrs.get('long_name', name)}")
    return xr.Dataset(errors)


def earth_frame_velocity(heading: npt.ArrayLike, velocity: npt.ArrayLike) -> np.ndarray:
    """North and east components of a body-frame velocity: the first two rows of J(psi) nu.

    Parameters
    ----------
    heading : array_like
        psi in radians, shape ``S``.
    velocity : array_like, shape ``S + (k,)``, k >= 2
        Body-frame [surge, sway, ...] components.

    Returns
    -------
    numpy.ndarray, shape ``S + (2,)``
    """
    psi, v = np.asarray(heading), np.asarray(velocity)
    c, s = np.cos(psi), np.sin(psi)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def rms_over(errors: xr.Dataset, start: float) -> xr.Dataset:
    """RMS of each error over time >= ``start`` (s)."""
    window = errors.sel(time=errors.time >= start)
    return cast(xr.Dataset, np.sqrt((window**2).mean("time")))  # numpy ufuncs return a Dataset for a Dataset; numpy's stubs say ndarray


def settling_time(error: npt.ArrayLike, time: npt.ArrayLike, final_rms: npt.ArrayLike, *, tolerance: float = 0.10) -> float | np.ndarray:
    """First time t from which the RMS of ``error`` over [t, end] is within (1 + tolerance) x ``final_rms``.

    A stochastic error never stays pointwise below its RMS, and a short moving RMS
    of it fluctuates by tens of percent; the RMS of the whole remaining tail is the
    steady measure of "from here on, the error is at its final level". The tail
    RMS is computed for every start time with one reversed cumulative sum.

    Parameters
    ----------
    error : array_like, shape ``S + (n_time,)``
        Errors, time along the last axis (any leading axes: runs, DOFs).
    time : array_like, shape (n_time,)
    final_rms : array_like, shape ``S``

    Returns
    -------
    float or ndarray of shape ``S``
        Settling time in seconds (``time[0]`` if settled from the start; NaN if never).
    """
    error = np.asarray(error, dtype=float)
    time = np.asarray(time, dtype=float)
    count = np.arange(error.shape[-1], 0, -1)
    tail_power = np.flip(np.cumsum(np.flip(error**2, axis=-1), axis=-1), axis=-1) / count
    inside = np.sqrt(tail_power) <= (1.0 + tolerance) * np.asarray(final_rms, dtype=float)[..., None]
    settled = np.where(inside.any(axis=-1), time[np.argmax(inside, axis=-1)], np.nan)
    return float(settled) if settled.ndim == 0 else settled


def fit_decay_rate(time: npt.ArrayLike, magnitude: npt.ArrayLike, *, upper: float = 1e-1, lower: float = 1e-9) -> dict[str, float]:
    """Fit ``magnitude ~ c exp(-rate t)`` by least squares on log(magnitude).

    Uses the samples between the first time the magnitude falls below ``upper``
    times its initial value and the first time it falls below ``lower`` times it
    (after the initial transient, before round-off).

    Returns
    -------
    dict
        ``rate`` (1/s), ``time_constant`` (s), ``r_squared``, ``t_start``, ``t_end``.
    """
    time = np.asarray(time, dtype=float)
    magnitude = np.asarray(magnitude, dtype=float)
    initial = magnitude[0]
    if not initial > 0:
        raise check.ParameterError("magnitude", "magnitude must start positive to fit a decay rate")
    relative = magnitude / initial
    below_upper = np.nonzero(relative < upper)[0]
    if below_upper.size == 0:
        raise check.ParameterError("magnitude", f"magnitude never falls below {upper:g} of its initial value; cannot fit a decay")
    first = below_upper[0]
    below_lower = np.nonzero(relative < lower)[0]
    last = below_lower[0] if below_lower.size else relative.size
    t, y = time[first:last], np.log(relative[first:last])
    if t.size < 3:
        raise check.ParameterError("too", "too few samples between the fit bounds to fit a decay rate")
    slope, intercept = np.polyfit(t, y, 1)
    fitted = slope * t + intercept
    r_squared = 1.0 - np.sum((y - fitted) ** 2) / np.sum((y - y.mean()) ** 2)
    return {"rate": float(-slope), "time_constant": float(-1.0 / slope), "r_squared": float(r_squared), "t_start": float(t[0]), "t_end": float(t[-1])}
