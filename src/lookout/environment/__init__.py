"""Environmental disturbances: bias (Gauss–Markov), first-order wave motion (linear
second-order model, or long-crested JONSWAP waves), and unmodelled body-fixed forces
(model error)."""

from .bias import GaussMarkovBias as GaussMarkovBias
from .disturbance import BodyDisturbance as BodyDisturbance
from .jonswap import JonswapWaves as JonswapWaves
from .jonswap import jonswap_spectrum as jonswap_spectrum
from .jonswap import peak_frequency as peak_frequency
from .jonswap import spectral_moment as spectral_moment
from .waves import LinearWaveModel as LinearWaveModel

__all__ = [
    "BodyDisturbance",
    "GaussMarkovBias",
    "JonswapWaves",
    "LinearWaveModel",
    "jonswap_spectrum",
    "peak_frequency",
    "spectral_moment",
]
