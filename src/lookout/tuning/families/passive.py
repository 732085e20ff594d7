"""The passive observer's family: Fossen & Strand (1999), Kappa, Lambda, w_c and zeta_n
inside the tuning rule (48) by construction (w_o and w_c are the sea's and the notch's),
SPR of each loop h = hB h0 (Theorem 1) checked with the KYP certificate of
:func:`lookout.analysis.check_spr` at every accepted step.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout.tuning.families import Family, component_as

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.observers.passive import PassiveObserver
    from lookout.sim import Scenario

#: "<<" of the tuning rule (48), as the design command reads it (check_tuning_rule's default).
MUCH_LESS = 10.0
#: How far inside its interval lambda/kappa stays: the open interval of (48) as a closed
#: one a rounding cannot leave.
INSIDE = 1e-3
#: Gain sets :meth:`PassiveFamily.candidates` tries.
CANDIDATES = 17


@dataclass(frozen=True)
class PassiveFamily(Family):
    """The passive observer's Kappa, Lambda, cut-off w_c and notch damping zeta_n, inside
    the tuning rule (48) by construction (module docstring). Per DOF, with T, w_o and
    the wave damping zeta of the observer::

        kappa   = exp(a)
        lambda  = kappa (10/T + (w_o - 10/T) (INSIDE + (1 - 2 INSIDE) sigmoid(b)))
        w_c     = w_o (1 + INSIDE) + softplus(c)     (the chain 10/T <= lambda/kappa < w_o < w_c)
        zeta_n  = zeta (1 + INSIDE) + softplus(d)    (zeta_n > zeta, as (45)-(46) need)

    (the floors keep the strict inequalities where softplus rounds to 0).

    and K1, K2 from (45)-(47) (:func:`lookout.observers.passive.notch_gains`). w_o, zeta
    and T are the sea's and the bias model's: not tuned.
    """

    low: np.ndarray  # 10 / T per DOF (rad/s)
    high: np.ndarray  # w_o per DOF (rad/s)
    wave_damping: np.ndarray
    name: str = "passive (Fossen & Strand 1999): Kappa, Lambda, w_c, zeta_n inside (48), SPR checked"
    design: str = "lookout design passive-observer"
    keys: tuple[str, ...] = (
        "observer.velocity_injection_gain",
        "observer.bias_injection_gain",
        "observer.cutoff_frequency",
        "observer.notch_damping",
    )

    @classmethod
    def of(cls, scenario: Scenario) -> PassiveFamily:
        """The family of ``scenario``'s observer; a ValueError names (48) when no Kappa,
        Lambda can satisfy it (10/T not below w_o in some DOF)."""
        return cls(*cls.chain(cls.passive(scenario)))

    @staticmethod
    def chain(observer: PassiveObserver) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """10/T, w_o and zeta per DOF of a passive observer; a ValueError names (48) when
        10/T is not below w_o in some DOF."""
        low = MUCH_LESS / np.asarray(observer.bias_time_constant, dtype=float) * np.ones(3)
        high = np.asarray(observer.wave_frequency, dtype=float) * np.ones(3)
        for dof, (a, b) in zip(("surge", "sway", "yaw"), zip(low, high)):
            if not a < b:
                raise ValueError(
                    f"tuning rule (48): 10/T ({a:.4g} rad/s) is not below w_o ({b:.4g} rad/s) in {dof}, so no Kappa, Lambda satisfies "
                    "1/T << lambda/kappa < w_o; lengthen bias_time_constant or check the wave frequency"
                )
        return low, high, np.asarray(observer.wave_damping, dtype=float) * np.ones(3)

    @staticmethod
    def passive(scenario: Scenario) -> PassiveObserver:
        """The passive observer the gains belong to."""
        from lookout.observers.passive import PassiveObserver

        return component_as(scenario.observer, PassiveObserver, "observer")

    @staticmethod
    def with_passive(scenario: Scenario, passive: PassiveObserver) -> Scenario:
        """``scenario`` with ``passive`` in place of :meth:`passive` (traceable)."""
        return eqx.tree_at(lambda s: s.observer, scenario, passive)

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        a, b, c, d = theta[:3], theta[3:6], theta[6:9], theta[9:12]
        kappa = jnp.exp(a)
        corner = self.low + (self.high - self.low) * (INSIDE + (1.0 - 2.0 * INSIDE) * jax.nn.sigmoid(b))
        # jnp.add: what ndarray + Array runs (Array.__radd__), typed as JAX's
        return (
            kappa,
            kappa * corner,
            jnp.add(self.high * (1.0 + INSIDE), jax.nn.softplus(c)),
            jnp.add(self.wave_damping * (1.0 + INSIDE), jax.nn.softplus(d)),
        )

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        kappa, lam, cutoff, notch = (np.asarray(g, dtype=float) for g in gains[:4])
        corner = lam / kappa
        fraction = ((corner - self.low) / (self.high - self.low) - INSIDE) / (1.0 - 2.0 * INSIDE)
        if np.any(fraction <= 0) or np.any(fraction >= 1):
            raise ValueError(
                f"the starting gains are outside the tuning rule (48): lambda/kappa = {np.round(corner, 6).tolist()} rad/s, "
                f"and (48) needs {np.round(self.low, 6).tolist()} <= lambda/kappa < {np.round(self.high, 6).tolist()}"
            )
        return np.concatenate(
            [
                np.log(kappa),
                np.log(fraction / (1.0 - fraction)),
                _softplus_inverse(cutoff - self.high * (1.0 + INSIDE)),
                _softplus_inverse(notch - self.wave_damping * (1.0 + INSIDE)),
            ]
        )

    def candidates(self, scenario: Scenario) -> Iterator[tuple[np.ndarray, ...]]:
        """Gains inside (48) for a scenario whose own are outside it (Kim's printed H3/H4 =
        10 rad/s > w_o): Kappa kept, lambda/kappa moved into its interval, from the nearest
        end across to the other (in the parameter b, over :data:`CANDIDATES` points: SPR
        may hold only in part of it), w_c and zeta_n raised above their floors where they
        are below."""
        kappa, lam, cutoff, notch = (np.asarray(g, dtype=float) for g in self.current(scenario)[:4])
        fraction = ((lam / kappa - self.low) / (self.high - self.low) - INSIDE) / (1.0 - 2.0 * INSIDE)
        nearest = np.clip(fraction, 0.01, 0.99)
        b = np.log(nearest / (1.0 - nearest))
        c = _softplus_inverse(np.maximum(cutoff - self.high * (1.0 + INSIDE), 0.2 * self.high))
        d = _softplus_inverse(np.maximum(notch - self.wave_damping * (1.0 + INSIDE), self.wave_damping))
        for k in range(CANDIDATES):
            theta = np.concatenate([np.log(kappa), b * (1.0 - 2.0 * k / (CANDIDATES - 1)), c, d])
            yield tuple(np.asarray(g) for g in PassiveFamily.gains(self, jnp.asarray(theta)))

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        from lookout.observers.passive import notch_gains

        kappa, lam, cutoff, notch = (jnp.asarray(g) for g in gains[:4])
        k1, k2, k3 = notch_gains(jnp.asarray(self.high), jnp.asarray(self.wave_damping), notch, cutoff)
        passive = eqx.tree_at(
            lambda o: (o.velocity_injection_gain, o.bias_injection_gain, o.wave_injection_gain, o.position_injection_gain),
            self.passive(scenario),
            (kappa, lam, jnp.concatenate([k1, k2]), k3),
        )
        return self.with_passive(scenario, passive)

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        """The observer's own gains of :attr:`keys` (w_c is its K2, zeta_n from its K1's k2)."""
        observer = self.passive(scenario)
        k2 = np.asarray(observer.wave_injection_gain, dtype=float)[3:]
        notch = self.wave_damping + k2 / (2.0 * self.high)  # eq. (46) solved for zeta_n
        return (
            np.asarray(observer.velocity_injection_gain, dtype=float),
            np.asarray(observer.bias_injection_gain, dtype=float),
            np.asarray(observer.position_injection_gain, dtype=float),
            notch,
        )

    def check(self, scenario: Scenario) -> Report:
        from lookout.analysis import check_passive_observer

        return check_passive_observer(self.passive(scenario), much_less_factor=MUCH_LESS)


def _softplus_inverse(value) -> np.ndarray:
    value = np.asarray(value, dtype=float)
    if np.any(value <= 0):
        raise ValueError(f"the starting gains are outside their chain (w_o < w_c, zeta < zeta_n); got a gap of {value.tolist()}")
    return value + np.log(-np.expm1(-value))
