"""The sliding-mode observer's family: Kim (2002), eqs. (6)-(7), and its conditions of
Section 3.2.

The passive part (H1..H4 = K1, K2, Lambda, Kappa) is parametrized as the passive
observer's (:class:`~lookout.tuning.families.passive.PassiveFamily`): inside
Fossen & Strand's tuning rule (48) by construction, which Kim's (14) presupposes. The
switching gain Kbar and the boundary layer eps are tuned on a log scale (positive by
construction; an axis with Kbar = 0 keeps it, since 0 turns the switching off there).
Checked at every accepted step, by :func:`lookout.analysis.sliding_mode.check_kim_2002`
(what ``lookout design sliding-mode-observer`` runs): (48), (14) through its KYP
certificate, and the corrected error system (8)-(10) stable both with Kbar = 0 and
inside the boundary layer (H2 + Kbar/eps).

The switching term is Kbar sat(y~/eps) (the observer's choice, see
:mod:`lookout.observers.sliding_mode`), Lipschitz in the gains and the state: its
derivative, which the gradient through the simulation uses, exists except on the
layer's edges (a set of measure zero that a run crosses at isolated instants), so
the gradient needs no smoothed sign, and the metrics reported are those of the exact
term.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout.tuning.families import component_as
from lookout.tuning.families.passive import PassiveFamily

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.observers.passive import PassiveObserver
    from lookout.observers.sliding_mode import SlidingModeObserver
    from lookout.sim import Scenario


def _observer(scenario: Scenario) -> SlidingModeObserver:
    from lookout.observers.sliding_mode import SlidingModeObserver

    return component_as(scenario.observer, SlidingModeObserver, "observer")


@dataclass(frozen=True, kw_only=True)
class SlidingModeFamily(PassiveFamily):
    """Kim's (2002) observer: the passive part's Kappa (H4), Lambda (H3), w_c, zeta_n as
    :class:`PassiveFamily`, then ``Kbar = exp(e)`` on the axes where it is positive and
    ``eps = exp(f)``."""

    switching: np.ndarray  # bool per axis: Kbar tuned there (it is positive)
    fixed_switching: np.ndarray  # Kbar where not tuned (zeros)
    name: str = "sliding-mode (Kim 2002): H4, H3, w_c, zeta_n inside (48), Kbar, eps; (14) and the error systems checked"
    design: str = "lookout design sliding-mode-observer"
    keys: tuple[str, ...] = PassiveFamily.keys + ("observer.switching_gain", "observer.boundary_layer")

    @classmethod
    def of(cls, scenario: Scenario) -> SlidingModeFamily:
        kbar = np.asarray(_observer(scenario).switching_gain, dtype=float) * np.ones(3)
        return cls(*cls.chain(cls.passive(scenario)), switching=kbar > 0, fixed_switching=np.where(kbar > 0, 0.0, kbar))

    @staticmethod
    def passive(scenario: Scenario) -> PassiveObserver:
        return _observer(scenario).passive

    @staticmethod
    def with_passive(scenario: Scenario, passive: PassiveObserver) -> Scenario:
        return eqx.tree_at(lambda s: s.observer.passive, scenario, passive)

    def _switching(self, e):
        full = jnp.zeros(3).at[np.flatnonzero(self.switching)].set(jnp.exp(e))
        return jnp.where(jnp.asarray(self.switching), full, jnp.asarray(self.fixed_switching))

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        count = int(self.switching.sum())
        return (*super().gains(theta[:12]), self._switching(theta[12 : 12 + count]), jnp.exp(theta[12 + count : 15 + count]))

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        kbar, eps = (np.asarray(g, dtype=float) * np.ones(3) for g in gains[4:6])
        return np.concatenate([super().theta(gains[:4]), np.log(kbar[self.switching]), np.log(eps)])

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        scenario = super().apply(scenario, gains[:4])
        return eqx.tree_at(
            lambda s: (s.observer.switching_gain, s.observer.boundary_layer),
            scenario,
            (jnp.asarray(gains[4], dtype=float), jnp.asarray(gains[5], dtype=float)),
        )

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        observer = _observer(scenario)
        return (
            *super().current(scenario),
            np.asarray(observer.switching_gain, dtype=float) * np.ones(3),
            np.asarray(observer.boundary_layer, dtype=float) * np.ones(3),
        )

    def candidates(self, scenario: Scenario) -> Iterator[tuple[np.ndarray, ...]]:
        rest = self.current(scenario)[4:]
        for gains in super().candidates(scenario):
            yield (*gains, *rest)

    def check(self, scenario: Scenario) -> Report:
        from lookout.analysis.sliding_mode import check_kim_2002
        from lookout.models.vessel import DPVessel

        observer = _observer(scenario)
        passive = observer.passive
        vessel = DPVessel(np.asarray(passive.mass_matrix), np.asarray(passive.damping_matrix))
        return check_kim_2002(observer, vessel)
