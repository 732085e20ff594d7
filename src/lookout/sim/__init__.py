"""Sampled-data simulation: the engine, integrators, and observers on logs.

The contract (see :mod:`lookout.components` and docs/architecture.md): a
:class:`Scenario` holds a plant, a sensor, an observer, a reference, a controller and
an actuator; :func:`simulate` runs sample k in the order

    measure -> observer.update -> observer.output -> reference -> controller
    -> actuator -> record -> plant integrated over [t_k, t_k+1] (RK4 or Euler)
    and observer.predict over the same interval,

as one jitted nested ``lax.scan`` (:func:`simulate_batch`: ``vmap`` over keys and,
optionally, over the scenario's arrays). :func:`filter` runs an observer over a
recorded log in the same order, :class:`Stepper` one sample at a time.
"""

from .batch import simulate_batch as simulate_batch
from .batch import stack_scenarios as stack_scenarios
from .batch import summarize_batch as summarize_batch
from .filtering import Stepper as Stepper
from .filtering import filter as filter  # noqa: A004
from .integrators import euler_step as euler_step
from .integrators import rk4_step as rk4_step
from .loop import Summary as Summary
from .loop import simulate as simulate
from .memory import check_batch_memory as check_batch_memory
from .memory import record_nbytes as record_nbytes
from .memory import working_nbytes as working_nbytes
from .scenario import Scenario as Scenario
from .scenario import check_fit as check_fit
from .scenario import integer_ratio as integer_ratio
from .seeds import MAX_SEED as MAX_SEED
from .seeds import keys_of_seeds as keys_of_seeds
from .seeds import seed_keys as seed_keys
