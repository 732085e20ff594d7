"""Planar kinematics shared by every model: rotation about z and angle wrapping.

One place only: every other module calls these, so the heading convention
(radians, wrapped to [-pi, pi)) is defined here once.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array


def ssa(angle: Array) -> Array:
    """Smallest signed angle: wrap ``angle`` (rad) to the interval [-pi, pi).

    Parameters
    ----------
    angle : array_like
        Angle or angle difference in radians, any shape.

    Returns
    -------
    Array
        The same angle modulo 2 pi, in [-pi, pi).
    """
    return jnp.mod(angle + jnp.pi, 2.0 * jnp.pi) - jnp.pi


def rotation(psi: Array) -> Array:
    """Rotation matrix J(psi) from body to Earth-fixed axes (Fossen & Strand 1999, eq. 2).

    Parameters
    ----------
    psi : array_like
        Heading in radians, scalar.

    Returns
    -------
    Array
        The 3x3 matrix [[c, -s, 0], [s, c, 0], [0, 0, 1]].
    """
    c, s = jnp.cos(psi), jnp.sin(psi)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [jnp.stack([c, -s, zero]), jnp.stack([s, c, zero]), jnp.stack([zero, zero, one])]
    )


def rotate(psi: Array, vector: Array) -> Array:
    """J(psi) @ vector, written out with cos/sin (cheaper than a 3x3 product under vmap).

    Parameters
    ----------
    psi : array_like
        Heading in radians.
    vector : array_like, shape (3,)
        Body-frame vector [surge, sway, yaw].

    Returns
    -------
    Array, shape (3,)
        The Earth-fixed vector.
    """
    c, s = jnp.cos(psi), jnp.sin(psi)
    return jnp.stack([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1], vector[2]])


def rotate_transpose(psi: Array, vector: Array) -> Array:
    """J(psi)^T @ vector: an Earth-fixed vector decomposed in body axes.

    Parameters
    ----------
    psi : array_like
        Heading in radians.
    vector : array_like, shape (3,)
        Earth-fixed vector [north, east, yaw].

    Returns
    -------
    Array, shape (3,)
        The body-frame vector.
    """
    c, s = jnp.cos(psi), jnp.sin(psi)
    return jnp.stack([c * vector[0] + s * vector[1], -s * vector[0] + c * vector[1], vector[2]])
