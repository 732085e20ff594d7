"""Environmental disturbances: bias (Gauss–Markov), first-order wave motion, and
unmodelled body-fixed forces (model error)."""

from .bias import GaussMarkovBias as GaussMarkovBias
from .waves import LinearWaveModel as LinearWaveModel
from .disturbance import BodyDisturbance as BodyDisturbance
