"""Plants as continuous-time vector fields."""

from .vessel import DOF as DOF
from .vessel import DPVessel as DPVessel
from .vessel import VesselPlant as VesselPlant
from .vessel import VesselState as VesselState
from .vessel import northern_clipper as northern_clipper
