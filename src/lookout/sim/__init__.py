"""Sampled-data simulation: integrators and the engine."""

from .engine import Scenario as Scenario
from .engine import simulate as simulate
from .engine import simulate_batch as simulate_batch
from .integrators import euler_step as euler_step
from .integrators import rk4_step as rk4_step
from .engine import MAX_SEED as MAX_SEED
from .engine import record_nbytes as record_nbytes
from .engine import seed_keys as seed_keys
from .engine import integer_ratio as integer_ratio
