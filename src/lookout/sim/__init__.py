"""Sampled-data simulation: integrators and the engine."""

from .engine import Scenario as Scenario
from .engine import simulate as simulate
from .engine import simulate_batch as simulate_batch
from .integrators import euler_step as euler_step
from .integrators import rk4_step as rk4_step
