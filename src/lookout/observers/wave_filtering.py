"""The wave-filtering observers' shared structure: what a controller may read of them.

Fossen & Strand's passive observer (1999, eqs. 22–26) and Kim's sliding-mode observer
(2002, eqs. 6–7, the passive one plus a switching term) have the same model-based
structure: a vessel model M, D, a wave model (w_o, zeta) and the injection gains K2 (H2)
and Kappa / gamma (H4), and a switching gain Kbar (zero for the passive observer).
Kim's observer backstepping (2002, eqs. 18–26) reads them for its nonlinear damping;
it takes any observer of this class, and refuses others by their type, not by a test
of which concrete class they are.
"""

from __future__ import annotations

import abc
from typing import NamedTuple

from jax import Array

from lookout.components import ContinuousObserver


class WaveFilterGains(NamedTuple):
    """The model and gains of a wave-filtering observer, SI."""

    mass_matrix: Array
    damping_matrix: Array
    wave_frequency: Array
    wave_damping: Array
    #: K2 = H2 (1/s), diagonal
    position_injection_gain: Array
    #: Kappa / gamma = H4 (N/m, N/m, N m/rad), diagonal
    velocity_injection_gain: Array
    #: Kbar (m/s, m/s, rad/s), diagonal; zero for the passive observer
    switching_gain: Array


class WaveFilteringObserver(ContinuousObserver):
    """A DP observer with a vessel model, a wave model and the injection structure of
    Fossen & Strand (1999), eqs. (22)–(26); a controller may read its gains."""

    @abc.abstractmethod
    def wave_filter_gains(self) -> WaveFilterGains:
        """The observer's model and injection gains (for a controller's damping terms)."""
