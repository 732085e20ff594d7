"""Actuators: what the plant receives for a commanded input.

- :mod:`~lookout.actuators.limits`: the command unchanged, or limited entry by entry;
- :mod:`~lookout.actuators.layout`: a vessel's thrusters as data;
- :mod:`~lookout.actuators.allocation`: generalized force to thruster commands
  (weighted pseudo-inverse, or a QP with limits and slack);
- :mod:`~lookout.actuators.qp`: the small active-set QP solver;
- :mod:`~lookout.actuators.thrusters`: the thrusters as a stateful actuator;
- :mod:`~lookout.actuators.failures`: a thruster's failures (stop, stuck, reduced), as data;
- :mod:`~lookout.actuators.capability`: the largest environmental force a layout holds
  per direction, intact and after each single thruster failure.
"""

from lookout.actuators.allocation import Allocator as Allocator
from lookout.actuators.capability import capability as capability
from lookout.actuators.capability import single_failure_capability as single_failure_capability
from lookout.actuators.layout import ThrusterLayout as ThrusterLayout
from lookout.actuators.limits import IdealActuator as IdealActuator
from lookout.actuators.limits import SaturatingActuator as SaturatingActuator
from lookout.actuators.thrusters import ThrusterSystem as ThrusterSystem
