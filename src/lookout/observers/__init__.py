"""Observers: one module per family."""

from .passive import PassiveObserver as PassiveObserver
from .passive import injection_gains_from_normalized as injection_gains_from_normalized
from .passive import notch_filter_gains as notch_filter_gains
