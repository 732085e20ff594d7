"""Tunable families: the gains a tuner may change, parametrized so that every value of the
parameters satisfies the paper's conditions by construction, and the conditions
checked by the analysis the ``lookout design`` commands use.

A family maps unconstrained parameters theta (any real vector, what the optimizer
moves) to the component's gains, and back; every theta gives gains inside the
conditions that can be written as a parametrization; the conditions that can only be
checked are checked on each accepted step (:meth:`Family.check`), and the tuner
backtracks until they hold.

The families so far:

- :class:`PassiveFamily`: Fossen & Strand's (1999) passive observer, Kappa and Lambda
  per DOF, inside the tuning rule (48), ``10/T <= lambda/kappa < w_o < w_c``, by
  construction (w_o and w_c are the sea's and the notch's, not tuned); SPR of each
  loop h = hB h0 (Theorem 1) checked with the KYP certificate of
  :func:`lookout.analysis.check_spr` at every accepted step.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

#: "<<" of the tuning rule (48), as the design command reads it (check_tuning_rule's default).
MUCH_LESS = 10.0
#: How far inside its interval lambda/kappa stays: the open interval of (48) as a closed
#: one a rounding cannot leave.
INSIDE = 1e-3


class Family(abc.ABC):
    """Gains of one component, parametrized inside its conditions."""

    name: str
    #: the composition's key of each tuned gain (``observer.velocity_injection_gain``)
    keys: tuple[str, ...]

    @abc.abstractmethod
    def gains(self, theta) -> tuple:
        """The gains of ``theta`` (traceable), in the order of :attr:`keys`."""

    @abc.abstractmethod
    def theta(self, gains) -> np.ndarray:
        """The parameters of ``gains`` (which must satisfy the conditions)."""

    @abc.abstractmethod
    def apply(self, component, gains):
        """``component`` with ``gains`` (traceable: ``eqx.tree_at``)."""

    @abc.abstractmethod
    def current(self, component) -> tuple:
        """The component's own gains, in the order of :attr:`keys`."""

    @abc.abstractmethod
    def check(self, component):
        """The conditions, as the ``lookout design`` command checks them: a
        :class:`~lookout.analysis.conditions.Report`."""


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

    low: np.ndarray         # 10 / T per DOF (rad/s)
    high: np.ndarray        # w_o per DOF (rad/s)
    wave_damping: np.ndarray
    name: str = "passive (Fossen & Strand 1999): Kappa, Lambda, w_c, zeta_n inside (48), SPR checked"
    keys: tuple[str, ...] = ("observer.velocity_injection_gain", "observer.bias_injection_gain", "observer.cutoff_frequency", "observer.notch_damping")

    @classmethod
    def of(cls, observer) -> "PassiveFamily":
        """The family of ``observer``; a ValueError names (48) when no Kappa, Lambda can
        satisfy it (10/T not below w_o in some DOF)."""
        low = MUCH_LESS / np.asarray(observer.bias_time_constant, dtype=float)
        high = np.asarray(observer.wave_frequency, dtype=float)
        for dof, (a, b) in zip(("surge", "sway", "yaw"), zip(low, high)):
            if not a < b:
                raise ValueError(
                    f"tuning rule (48): 10/T ({a:.4g} rad/s) is not below w_o ({b:.4g} rad/s) in {dof}, so no Kappa, Lambda satisfies "
                    "1/T << lambda/kappa < w_o; lengthen bias_time_constant or check the wave frequency"
                )
        return cls(low, high, np.asarray(observer.wave_damping, dtype=float))

    def gains(self, theta):
        a, b, c, d = theta[:3], theta[3:6], theta[6:9], theta[9:]
        kappa = jnp.exp(a)
        corner = self.low + (self.high - self.low) * (INSIDE + (1.0 - 2.0 * INSIDE) * jax.nn.sigmoid(b))
        return kappa, kappa * corner, self.high * (1.0 + INSIDE) + jax.nn.softplus(c), self.wave_damping * (1.0 + INSIDE) + jax.nn.softplus(d)

    def theta(self, gains) -> np.ndarray:
        kappa, lam, cutoff, notch = (np.asarray(g, dtype=float) for g in gains)
        corner = lam / kappa
        fraction = ((corner - self.low) / (self.high - self.low) - INSIDE) / (1.0 - 2.0 * INSIDE)
        if np.any(fraction <= 0) or np.any(fraction >= 1):
            raise ValueError(
                f"the starting gains are outside the tuning rule (48): lambda/kappa = {np.round(corner, 6).tolist()} rad/s, "
                f"and (48) needs {np.round(self.low, 6).tolist()} <= lambda/kappa < {np.round(self.high, 6).tolist()}"
            )
        return np.concatenate([np.log(kappa), np.log(fraction / (1.0 - fraction)), _softplus_inverse(cutoff - self.high * (1.0 + INSIDE)),
                               _softplus_inverse(notch - self.wave_damping * (1.0 + INSIDE))])

    def apply(self, observer, gains):
        from lookout.observers.passive import notch_gains

        kappa, lam, cutoff, notch = (jnp.asarray(g) for g in gains)
        k1, k2, k3 = notch_gains(jnp.asarray(self.high), jnp.asarray(self.wave_damping), notch, cutoff)
        return eqx.tree_at(
            lambda o: (o.velocity_injection_gain, o.bias_injection_gain, o.wave_injection_gain, o.position_injection_gain),
            observer, (kappa, lam, jnp.concatenate([k1, k2]), k3),
        )

    def current(self, observer) -> tuple:
        """The observer's own gains of :attr:`keys` (w_c is its K2, zeta_n from its K1's k2)."""
        k2 = np.asarray(observer.wave_injection_gain, dtype=float)[3:]
        notch = self.wave_damping + k2 / (2.0 * self.high)  # eq. (46) solved for zeta_n
        return (np.asarray(observer.velocity_injection_gain, dtype=float), np.asarray(observer.bias_injection_gain, dtype=float),
                np.asarray(observer.position_injection_gain, dtype=float), notch)

    def check(self, observer):
        from lookout.analysis import check_passive_observer

        return check_passive_observer(observer, much_less_factor=MUCH_LESS)


def _softplus_inverse(value) -> np.ndarray:
    value = np.asarray(value, dtype=float)
    if np.any(value <= 0):
        raise ValueError(f"the starting gains are outside their chain (w_o < w_c, zeta < zeta_n); got a gap of {value.tolist()}")
    return value + np.log(-np.expm1(-value))


def family_of(observer) -> Family:
    """The tunable family of ``observer``; a ValueError lists the observers that have one."""
    from lookout.observers.passive import PassiveObserver
    from lookout.registry import kind_of

    if isinstance(observer, PassiveObserver):
        return PassiveFamily.of(observer)
    raise ValueError(f"observer {kind_of(observer)} has no tunable family yet (tunable: passive)")
