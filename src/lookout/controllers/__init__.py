"""Controllers and open-loop input generators."""

from .backstepping import ObserverBackstepping as ObserverBackstepping
from .backstepping import VectorialBackstepping as VectorialBackstepping
from .open_loop import NoControl as NoControl
from .open_loop import SinusoidalInput as SinusoidalInput
from .pid import PidController as PidController
from .tracking import TrackingController as TrackingController
