"""Controllers and open-loop input generators."""

from .open_loop import NoControl as NoControl
from .open_loop import SinusoidalInput as SinusoidalInput
from .backstepping import ObserverBackstepping as ObserverBackstepping
from .backstepping import VectorialBackstepping as VectorialBackstepping
from .tracking import TrackingController as TrackingController
from .pid import PidController as PidController
