"""Plants as continuous-time vector fields."""

from .cybership import Cybership as Cybership
from .cybership import CybershipPlant as CybershipPlant
from .cybership import CybershipState as CybershipState
from .cybership import cybership2 as cybership2
from .manipulators import CartPendulum as CartPendulum
from .manipulators import FreePendulum as FreePendulum
from .manipulators import FurutaPendulum as FurutaPendulum
from .manipulators import JointState as JointState
from .manipulators import ManipulatorModel as ManipulatorModel
from .manipulators import ManipulatorPlant as ManipulatorPlant
from .manipulators import TwoLinkArm as TwoLinkArm
from .parameters import AffineParameters as AffineParameters
from .parameters import ModelParameters as ModelParameters
from .parameters import PendulumInertia as PendulumInertia
from .vessel import DOF as DOF
from .vessel import DPVessel as DPVessel
from .vessel import VesselPlant as VesselPlant
from .vessel import VesselState as VesselState
from .vessel import northern_clipper as northern_clipper
