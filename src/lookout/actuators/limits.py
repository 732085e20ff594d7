"""Actuators without a state: the command limited entry by entry, or unchanged
(:class:`IdealActuator`, defined beside the contract in :mod:`lookout.null_components`
as the engine's default)."""

from __future__ import annotations

from typing import final

import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import StatelessActuator
from lookout.declare import Context, Value, component
from lookout.null_components import IdealActuator as IdealActuator  # defined beside the contract, the engine's default


def _limit_vector(limit, size: int | None):
    """``limit`` as a float vector (a scalar broadcast to ``size``), shape checked."""
    array: Array | np.ndarray
    if check.is_concrete(limit):
        array = np.asarray(limit, dtype=float)
    else:
        array = jnp.asarray(limit, dtype=float)
    if array.ndim == 0:
        if size is None:
            raise check.ParameterError("limit", "limit is a scalar: give size, the number of input entries")
        return jnp.broadcast_to(jnp.asarray(array), (size,))
    if array.ndim != 1 or array.shape[0] == 0 or (size is not None and array.shape != (size,)):
        expected = f"({size},)" if size is not None else "(n,) with n >= 1"
        raise check.ParameterError("limit", f"limit must be a scalar or have shape {expected}; got shape {array.shape}")
    return jnp.asarray(array)


@component(
    "actuator",
    "thrust-limits",
    summary="Symmetric magnitude saturation per input entry: applied = clip(u, -limit, limit).",
    parameters=(
        Value(
            "limit",
            "array",
            "Largest magnitude of each entry, in the units of the plant's input; > 0, inf for an unlimited entry; NaN is rejected.",
            shape="(n,) or scalar",
        ),
        Context("size", "n, when limit is a scalar."),
    ),
)
@final
class SaturatingActuator(StatelessActuator):
    """Symmetric magnitude saturation per input entry: applied = clip(u, -limit, limit).

    Each entry of the plant's input (e.g. surge force, sway force, yaw moment of a
    vessel) is limited independently (a box, not a thrust-allocation polytope).
    A NaN commanded entry stays NaN (``clip`` propagates it): the plant then goes
    non-finite and the run's status says so, rather than a failed controller being
    silently replaced by a bounded number. :meth:`saturated` gives the mask of the
    entries that the limits cut (for a "time saturated" metric).

    Parameters
    ----------
    limit : array_like, shape (n,) or scalar
        Largest magnitude of each entry, in the units of the plant's input; > 0,
        ``inf`` for an unlimited entry; NaN is rejected.
    size : int, optional
        n, when ``limit`` is a scalar.
    """

    limit: Array

    def __init__(self, limit: npt.ArrayLike, *, size: int | None = None):
        self.limit = _limit_vector(limit, size)

    def __check_init__(self):
        if not check.is_concrete(self.limit):
            return
        array = np.asarray(self.limit, dtype=float)
        if np.any(np.isnan(array)) or np.any(array <= 0):
            raise check.ParameterError("limit", f"limit must be positive (inf for no limit); got {check._fmt(array)}")

    def _check_shape(self, u: Array) -> None:
        if jnp.shape(u)[-1:] != self.limit.shape:
            raise ValueError(f"SaturatingActuator has {self.limit.shape[0]} limits; the commanded input has shape {jnp.shape(u)}")

    def apply(self, u: ArrayLike) -> Array:
        """``clip(u, -limit, limit)``; NaN entries stay NaN."""
        u = jnp.asarray(u)
        self._check_shape(u)
        return jnp.clip(u, -self.limit, self.limit)

    def saturated(self, u: ArrayLike) -> Array:
        """Boolean mask, shape of ``u``: True where ``|u| > limit`` (the applied entry differs).

        NaN entries are False (not saturated; check finiteness separately).
        """
        u = jnp.asarray(u)
        self._check_shape(u)
        return jnp.abs(u) > self.limit
