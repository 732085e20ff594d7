"""What the tuning tests share: the gradient of the objective and its central differences
from one compiled function (``jax.value_and_grad``), so that each family's check
compiles the simulation once."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def gradient_and_central_differences(value, family, theta, keys, step: float = 1e-5) -> tuple[np.ndarray, np.ndarray]:
    """``(gradient, central differences)`` of ``value(family.gains(theta), keys)[0]`` at ``theta``."""
    both = jax.jit(jax.value_and_grad(lambda t: value(family.gains(t), keys)[0]))
    theta = jnp.asarray(theta)
    gradient = np.asarray(both(theta)[1])
    central = np.asarray([(both(theta.at[i].add(step))[0] - both(theta.at[i].add(-step))[0]) / (2 * step) for i in range(theta.size)])
    return gradient, central
