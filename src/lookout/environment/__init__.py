"""Environmental disturbances: bias (Gauss–Markov) and first-order wave motion."""

from .bias import GaussMarkovBias as GaussMarkovBias
from .waves import LinearWaveModel as LinearWaveModel
