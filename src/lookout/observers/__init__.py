"""Observers: one module per observer family."""

from .adaptive_dp import AdaptiveObserver as AdaptiveObserver
from .adaptive_dp import InertiaParametrization as InertiaParametrization
from .adaptive_manipulator import AdaptiveManipulatorObserver as AdaptiveManipulatorObserver
from .earth_fixed import EarthFixedObserver as EarthFixedObserver
from .model_free import ModelFreeFilter as ModelFreeFilter
from .passive import CUTOFF_RATIO as CUTOFF_RATIO
from .passive import PAPER_CUTOFF_FREQUENCY as PAPER_CUTOFF_FREQUENCY
from .passive import PassiveObserver as PassiveObserver
from .passive import default_cutoff_frequency as default_cutoff_frequency
from .passive import injection_gains_from_normalized as injection_gains_from_normalized
from .passive import notch_filter_gains as notch_filter_gains
from .sliding_mode import SlidingModeObserver as SlidingModeObserver
from .sliding_mode import saturation as saturation
from .smoothing import smooth as smooth
from .velocity import VelocityObserver as VelocityObserver
