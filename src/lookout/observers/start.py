"""Where an observer starts: the states it measures from the first measurement.

An observer's initial guess (``observer.guess(...)``, a scenario's ``[observer.initial]``)
gives what is not measured (velocities, bias, wave state, parameters). A measured state
(a vessel's position and heading, an arm's joint angles) left out of the guess starts at
its first measurement: a vessel at 45 degrees starts its estimate at 45 degrees, not
at 0, so that its first readings are not taken for wild points and its wave estimate
does not swing while the heading settles. A state given in the guess starts where the
guess says (a study of convergence from a chosen error). Inside a guess, NaN marks a
state left to the first measurement; a channel missing in that measurement (NaN, a
dropout at t_0) starts at 0.
"""

from __future__ import annotations

from collections.abc import Iterable

import jax.numpy as jnp
from jax import Array

from lookout._math import ssa


def from_first_measurement(guessed: Array, measured: Array, angles: Iterable[int] = ()) -> Array:
    """``guessed`` with its NaN entries taken from ``measured`` (0 where that is NaN too),
    the ``angles`` entries (indices) wrapped to [-pi, pi).

    Parameters
    ----------
    guessed : Array, shape (n,)
        The guess of the measured states; NaN where the guess leaves them to the measurement.
    measured : Array, shape (n,)
        The first measurement of the same states (NaN: missing).
    angles : sequence of int
        Entries that are angles (a heading).
    """
    measured = jnp.asarray(measured, dtype=float)
    start = jnp.where(jnp.isnan(guessed), jnp.where(jnp.isfinite(measured), measured, 0.0), guessed)
    for index in angles:
        start = start.at[index].set(ssa(start[index]))
    return start
