"""Families of gains whose condition is their sign: backstepping controllers whose
Lyapunov function's derivative is negative for any positive gains.

A gain that must be positive is ``exp(t)``; one that may be zero and is zero in the
scenario stays zero (zero switches its term off: a structural choice, not a value to
tune), a positive one is ``exp(t)``. :meth:`PositiveGains.check` reads the signs from
the built component, so it checks what runs, not the parametrization.

- :class:`ObserverBacksteppingFamily`: Kim (2002) observer backstepping, eqs. (18)-(26):
  with V_con of (29) (weighted by P1, see :mod:`lookout.controllers.backstepping`),
  V_con' <= -e'^T C1 e' - e_I^T K_I C1 K_I e_I - z1^T D1 z1 - z2^T (C2 + D2) z2 (30)
  for C1, C2, P1 > 0 and K_I, d_i >= 0 (no estimation error; with it, the nonlinear
  damping D1, D2 of (26) bounds the observer's terms).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Self

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout.tuning.families import Family

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.sim import Scenario


@dataclass(frozen=True)
class Gain:
    """One tuned field of a component."""

    field: str  # the component's attribute and the scenario file's key
    symbol: str  # the paper's symbol
    units: str
    allow_zero: bool = False


class PositiveGains(Family):
    """Gains of :attr:`role` (``"controller"``) parametrized by their logarithm; entries that
    are zero where :attr:`Gain.allow_zero` stay zero."""

    role: str = "controller"
    fields: tuple[Gain, ...] = ()
    condition_key: str = ""
    condition_name: str = ""
    condition_title: str = ""
    source: str = ""

    def __init__(self, scenario: Scenario):
        component = getattr(scenario, self.role)
        self.shapes = tuple(np.shape(getattr(component, g.field)) for g in self.fields)
        self.tuned = tuple(
            np.asarray(getattr(component, g.field), dtype=float).ravel() > 0 if g.allow_zero else np.ones(int(np.prod(shape, dtype=int)), dtype=bool)
            for g, shape in zip(self.fields, self.shapes)
        )
        self.keys = tuple(f"{self.role}.{g.field}" for g in self.fields)

    @classmethod
    def of(cls, scenario: Scenario) -> Self:
        component = getattr(scenario, cls.role)
        for gain in cls.fields:
            value = np.asarray(getattr(component, gain.field), dtype=float)
            if np.any(value < 0) or (not gain.allow_zero and np.any(value <= 0)):
                raise ValueError(
                    f"{cls.condition_name}: {gain.field} ({gain.symbol}) must be {'>= 0' if gain.allow_zero else '> 0'}; got {value.tolist()}"
                )
        return cls(scenario)

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        out, start = [], 0
        for shape, tuned in zip(self.shapes, self.tuned):
            count = int(tuned.sum())
            full = jnp.zeros(tuned.size).at[np.flatnonzero(tuned)].set(jnp.exp(theta[start : start + count]))
            out.append(full.reshape(shape))
            start += count
        return tuple(out)

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        parts = []
        for gain, value, tuned in zip(self.fields, gains, self.tuned):
            value = np.asarray(value, dtype=float).ravel()
            if np.any(value[tuned] <= 0):
                raise ValueError(f"{self.condition_name}: {gain.field} ({gain.symbol}) must be positive; got {value.tolist()}")
            parts.append(np.log(value[tuned]))
        return np.concatenate(parts)

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        component = getattr(scenario, self.role)
        component = eqx.tree_at(
            lambda c: tuple(getattr(c, g.field) for g in self.fields),
            component,
            tuple(jnp.asarray(v, dtype=float).reshape(shape) for v, shape in zip(gains, self.shapes)),
        )
        return eqx.tree_at(lambda s: getattr(s, self.role), scenario, component)

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        component = getattr(scenario, self.role)
        return tuple(np.asarray(getattr(component, g.field), dtype=float) for g in self.fields)

    def check(self, scenario: Scenario) -> Report:
        from lookout.analysis.conditions import Condition, Inequality, Report

        component = getattr(scenario, self.role)
        inequalities = [
            Inequality.check(
                gain.symbol,
                f"min {gain.symbol} {'>=' if gain.allow_zero else '>'} 0",
                float(np.min(np.asarray(getattr(component, gain.field), dtype=float))),
                ">=" if gain.allow_zero else ">",
                0.0,
                units=gain.units,
                source=self.source,
                tolerance=0.0,
            )
            for gain in self.fields
        ]
        return Report(self.name, [Condition(self.condition_key, self.condition_name, self.condition_title, self.source, inequalities)])


class ObserverBacksteppingFamily(PositiveGains):
    """Kim (2002) observer backstepping (module docstring): K_I, C1, C2, d1..d6 and P1."""

    name = "observer backstepping (Kim 2002): K_I, C1, C2, d, P1 positive, so V_con' <= 0 (30)"
    design = "the signs of (29)-(30)"
    fields = (
        Gain("integral_gain", "K_I", "1/s", allow_zero=True),
        Gain("position_gain", "C1", "1/s"),
        Gain("velocity_gain", "C2", "1/s"),
        Gain("damping_weights", "d", "s", allow_zero=True),
        Gain("coupling_gain", "P1", "1/s2"),
    )
    condition_key = "lyapunov_30"
    condition_name = "(30)"
    condition_title = "V_con' <= 0 without estimation error: C1, C2, P1 > 0, K_I, d >= 0"
    source = "Kim (2002), eqs. (29)-(30); P1 of derivations K3"
