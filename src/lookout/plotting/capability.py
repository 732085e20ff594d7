"""The DP capability polar (``lookout capability``,
:mod:`lookout.actuators.capability`): the largest environmental force per direction,
intact and after each single thruster failure."""

from __future__ import annotations

from collections.abc import Mapping
from typing import cast

import numpy as np
import numpy.typing as npt
from matplotlib.figure import Figure
from matplotlib.projections.polar import PolarAxes


def plot_capability(directions: npt.ArrayLike, found: Mapping[str, npt.ArrayLike], *, title: str = "DP capability") -> Figure:
    """A polar figure of each case of ``found`` (name -> force in N at each of
    ``directions``, rad): the direction the environment comes from, 0 ahead at the top
    and 90 deg from starboard to the right, the force in kN; ``intact`` in black, each
    thruster out of service in a colour of its own, the closed curve of each case."""
    betas = np.asarray(directions, dtype=float)
    figure = Figure(figsize=(7.5, 7.0), layout="constrained")
    axes = cast(PolarAxes, figure.add_subplot(projection="polar"))
    axes.set_theta_zero_location("N")
    axes.set_theta_direction(-1)
    axes.set_rlabel_position(202.5)  # the force labels between the curves of the lower left
    closed = np.append(betas, betas[0])
    for index, (name, values) in enumerate(found.items()):
        kilo = np.append(np.asarray(values, dtype=float), np.asarray(values, dtype=float)[0]) / 1e3
        intact = name == "intact"
        axes.plot(
            closed,
            kilo,
            color="black" if intact else f"C{index - 1}",
            linewidth=2.2 if intact else 1.3,
            linestyle="-" if intact else "--",
            label=name if intact else f"{name} out",
        )
    axes.set_title(f"{title}\nlargest force held (kN) by the direction it comes from", fontsize=10)
    axes.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)
    return figure


__all__ = ["plot_capability"]
