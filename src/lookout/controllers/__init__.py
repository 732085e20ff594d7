"""Controllers and open-loop input generators."""

from .open_loop import SinusoidalThrust as SinusoidalThrust
