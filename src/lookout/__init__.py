"""lookout: nonlinear observers and observer-based output-feedback control.

lookout computes in float64 (ship models span 1e-4 to 1e10), so importing it
enables ``jax_enable_x64``. Use float32 only as an explicit opt-in.
"""

import jax as _jax

_jax.config.update("jax_enable_x64", True)

from ._math import rotation as rotation  # noqa: E402
from ._math import ssa as ssa  # noqa: E402
from .controllers import SinusoidalThrust as SinusoidalThrust  # noqa: E402
from .environment import GaussMarkovBias as GaussMarkovBias  # noqa: E402
from .environment import LinearWaveModel as LinearWaveModel  # noqa: E402
from .models import DPVessel as DPVessel  # noqa: E402
from .models import VesselPlant as VesselPlant  # noqa: E402
from .models import VesselState as VesselState  # noqa: E402
from .models import northern_clipper as northern_clipper  # noqa: E402
from .observers import PassiveObserver as PassiveObserver  # noqa: E402
from .observers import injection_gains_from_normalized as injection_gains_from_normalized  # noqa: E402
from .observers import notch_filter_gains as notch_filter_gains  # noqa: E402
from .results import Trajectory as Trajectory  # noqa: E402
from .sensors import PositionHeadingSensor as PositionHeadingSensor  # noqa: E402
from .sim import Scenario as Scenario  # noqa: E402
from .sim import simulate as simulate  # noqa: E402
from .sim import simulate_batch as simulate_batch  # noqa: E402

__version__ = "0.1.0"
