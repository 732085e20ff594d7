"""What the tuning tests share: the gradient of the objective and its central differences
from one compiled function, the very program ``lookout tune`` compiles
(:func:`lookout.tuning.tune.value_and_gradient`): each family's check compiles the
simulation once, and a ``lookout tune`` test of the same scenario, horizon, objective and
number of training seeds loads that program from the persistent compilation cache."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from lookout.tuning.tune import value_and_gradient


def gradient_and_central_differences(value, family, theta, keys, step: float = 1e-5) -> tuple[np.ndarray, np.ndarray]:
    """``(gradient, central differences)`` of ``value(family.gains(theta), keys)[0]`` at ``theta``."""
    both = value_and_gradient(value, family)
    theta = jnp.asarray(theta)
    gradient = np.asarray(both(theta, keys)[1])
    objective = lambda t: both(t, keys)[0][0]  # noqa: E731
    central = np.asarray([(objective(theta.at[i].add(step)) - objective(theta.at[i].add(-step))) / (2 * step) for i in range(theta.size)])
    return gradient, central
