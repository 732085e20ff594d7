"""Calugi, Robertsson & Johansson (2003): the adaptive DP observer's family, which holds the
gains that the paper's conditions (22), (57) and (58) couple, and the vectorial
backstepping controller's family, which holds C1 and C2, which enter none of them.

The conditions (read as in :mod:`lookout.analysis.adaptive_dp`), with
sigma1 = lambda_min(sym K1), sigma2 = min_theta lambda_min(sym(M(theta) K2)),
D_min = min_theta lambda_min(sym D), k = (1 + K_max)^2 / 4 (the theta box is the
observer's parametrization)::

    (22)  sigma1 > k / (sigma2 + D_min),   sigma2 > 0                    observer
    (57)  sigma1 > g1/4 + k / (sigma2 + D_min - g2/4)                    closed loop
    (58)  sigma2 > max(0, g2/4 - D_min)                                  closed loop
          g1 = sum_1..3 p_i/d_i + sum_4..6 1/d_i,  g2 = sum_4..6 1/d_i   (53), P1 = diag(p_i)

Split. (57) and (58) bind the observer's K1, K2 to the controller's d and P1, and C1,
C2 appear in none of them (V' of (56) has -z'C_z z, C_z = diag(C1, C2) of (44),
negative for any positive C1, C2). So the observer's family (:class:`AdaptiveDPFamily`)
holds K1, K2, Gamma and, under the vectorial backstepping controller, its d and P1
(keys ``controller.damping_weights``, ``controller.coupling_gain``), and reports all of
(22), (57), (58) (:func:`~lookout.analysis.adaptive_dp.check_calugi_2003`, what
``lookout design adaptive-observer`` runs); the controller's family
(:class:`VectorialBacksteppingFamily`) holds C1, C2 and reports their signs. Every
coupled condition then belongs to one family, whichever components are tuned (observer,
controller or both), and each condition is reported once in a joint tuning. The
controller's family is only built for a loop that (22), (57), (58) prove at the
scenario's own gains: tuning C1, C2 alone keeps that proof (they are not in it).

Parametrization (all by construction when every vertex M(theta) of the box is diagonal,
as the supply vessel (59) with theta = m11 is; otherwise (22b)/(58)'s sigma2 > 0 is
checked only)::

    K2_i        = exp(a_i)                       sigma2 > 0 (diagonal M: sym(M K2) = diag(m_i k2_i))
    Gamma_jj    = exp(c_j)                       (zeros stay zero: adaptation off there)
    d_i         = exp(e_i),  i = 1..3
    d_i         = b (1 + INSIDE) + exp(e_i), i = 4..6,  b = 3 / (4 D_min)   (g2/4 < D_min: (58))
    p_i         = exp(f_i)
    K1_i        = floor (1 + INSIDE) + exp(t_i),  floor = g1/4 + k / (D_min - g2/4)

``floor`` bounds the right sides of (57) and (22a) at sigma2 = 0 (both fall as sigma2
grows), so (22), (57), (58) hold for every theta. The floor depends on d and P1 of the
same family (traceable), not on the other family's gains. Without the backstepping
controller (an open-loop input) only (22) applies: floor = k / D_min, and d, P1 are not
in the family.

Checked at every accepted step, besides (22), (57), (58): the sampled observer's
integration, an upper bound on K1 and K2 that is not parametrized (the tuner halves a
step that crosses it): the discrete form (65)-(66) has eta~(i) ~ (I - Delta K1) eta~(i-1)
and nu_hat(i) = (I - Delta K2) nu_hat(i-1) + ..., so ``Delta K < 2``; the continuous
form (13)-(14) integrated by RK4 at step h needs ``h K < 2.785``.

Numbers the scenario does not hold, taken as the design command and the reproduction
take them: the model bounds (9)-(11) from the observer's known model with its unknown
entries over the parametrization's box (the design command's ``--theta-bounds``; the
model is taken as the truth, with a note when the plant's differs); D_min =
lambda_min(sym D), the design command's reading (no ``d_min``). The candidates are
:func:`~lookout.analysis.adaptive_dp.satisfying_gains` from the scenario's gains, at the
reproduction's speed (:data:`lookout.papers.calugi_2003.config.DESIGN_SPEED`, 1 m/s) and
usability (``step x rate <= 0.5``, its default), the printed gains giving the
reproduction's ``satisfying`` set
(K1 = 0.3 I, d = 13, 13, 13, 3.5, 3.5, 3.5 s at Delta = 0.1 s). At Delta >= 0.2 s no
route is usable for the printed gains, and the scenario is refused.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Self

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout.tuning.families import Family, component_as, integration_stable
from lookout.tuning.families.positive import Gain, PositiveGains

if TYPE_CHECKING:
    from lookout.analysis.conditions import Condition, Report
    from lookout.controllers.backstepping import VectorialBackstepping
    from lookout.models.vessel import DPVessel
    from lookout.observers.adaptive_dp import AdaptiveObserver
    from lookout.sim import Scenario

#: How far above its floor a parametrized gain stays (relative).
INSIDE = 1e-3
#: Candidates' factor on K1's floor in the open loop ((22) only).
CANDIDATE_FACTORS = (1.5, 2.0, 4.0)
PAPER = "Calugi et al. (2003)"
#: The analysis' matrix letter of each kind of unknown entry.
_LETTERS = {"mass": "M", "damping": "D", "stiffness": "K"}


def _closed_loop(scenario: Scenario) -> bool:
    from lookout.controllers.backstepping import VectorialBackstepping

    return isinstance(scenario.controller, VectorialBackstepping)


def _observer(scenario: Scenario) -> AdaptiveObserver:
    from lookout.observers.adaptive_dp import AdaptiveObserver

    return component_as(scenario.observer, AdaptiveObserver, "observer")


def _controller(scenario: Scenario) -> VectorialBackstepping:
    from lookout.controllers.backstepping import VectorialBackstepping

    return component_as(scenario.controller, VectorialBackstepping, "controller")


@dataclass(frozen=True, eq=False)
class AdaptiveDPFamily(Family):
    """K1, K2, Gamma of the adaptive observer (13)-(15)/(65)-(67) and, under the vectorial
    backstepping controller, its d and P1: (22), (57), (58) by construction (module
    docstring), checked with :func:`~lookout.analysis.adaptive_dp.check_calugi_2003`."""

    vessel: DPVessel  # the analysis' DPVessel: the observer's model at theta_ref
    theta_bounds: list  # [[lower, upper], ...] per unknown
    unknown: tuple  # (("M", 0, 0),) ...
    damping_min: float  # D_min (kg/s)
    coupling: float  # k = (1 + K_max)^2 / 4
    diagonal_mass: bool  # every vertex M(theta) diagonal: sigma2 > 0 by construction
    gamma_tuned: np.ndarray | None  # bool per diagonal entry of Gamma (diagonal Gamma), or None
    gamma_matrix: np.ndarray  # Gamma of the scenario ((p, p))
    closed_loop: bool  # the controller is VectorialBackstepping: d, P1 in the family
    form: str  # "discrete" or "continuous"
    step: float  # the observer's integration step (s)
    model_notes: tuple = ()
    name: str = "adaptive DP observer (Calugi et al. 2003): K1 above the floor of (22)/(57), K2, Gamma, d, P1; integration checked"
    design: str = "lookout design adaptive-observer"
    keys: tuple[str, ...] = ("observer.position_gain", "observer.velocity_gain", "observer.adaptation_gain")

    @classmethod
    def of(cls, scenario: Scenario) -> AdaptiveDPFamily:
        """The family of ``scenario``'s adaptive observer; a ValueError names (10) when
        D_min <= 0 (then no K1 satisfies (22) for every positive K2)."""
        from lookout.analysis.adaptive_dp import model_bounds
        from lookout.models.vessel import DPVessel
        from lookout.observers.adaptive_dp import AdaptiveObserver

        observer = scenario.observer
        if not isinstance(observer, AdaptiveObserver):
            raise ValueError(f"(22): Calugi et al.'s conditions need the adaptive observer (13)-(15); got {type(observer).__name__}")
        parametrization = observer.parametrization
        lower, upper = np.asarray(parametrization.lower, dtype=float), np.asarray(parametrization.upper, dtype=float)
        notes = []
        reference = np.asarray(observer.initial_theta, dtype=float)
        plant_vessel = getattr(scenario.plant, "vessel", None)
        if isinstance(plant_vessel, DPVessel):
            truth = np.asarray(parametrization.values(plant_vessel), dtype=float)
            if np.all((lower <= truth) & (truth <= upper)):
                reference = truth
            else:
                notes.append(
                    f"the plant's {', '.join(parametrization.names)} = {truth.tolist()} is outside the observer's bounds: the model bounds "
                    "(9)-(11) are taken over the bounds, with the initial estimate as theta"
                )
        matrices = [np.asarray(m, dtype=float) for m in parametrization.matrices(jnp.asarray(reference))]
        vessel = DPVessel(*matrices)
        if isinstance(plant_vessel, DPVessel) and not all(
            np.allclose(a, np.asarray(b, dtype=float), rtol=1e-12, atol=0.0)
            for a, b in zip(matrices, (plant_vessel.mass_matrix, plant_vessel.damping_matrix, plant_vessel.stiffness_matrix))
        ):
            notes.append("the observer's known model differs from the plant's: (22), (57), (58) take the observer's model as the truth")
        unknown = tuple((_LETTERS[kind], row, col) for kind, row, col in parametrization.unknowns)
        box = np.stack([lower, upper], axis=1).tolist()
        bounds = model_bounds(vessel, box, unknown=unknown)
        if not bounds.damping_min > 0:
            raise ValueError(
                f"(10): D_min = lambda_min(sym D) = {bounds.damping_min:.4g} kg/s is not positive (over the theta box), so no "
                "K1 satisfies (22) for every K2; the family needs a damped model"
            )
        diagonal = True
        for corner in itertools.product(*box):
            mass = np.asarray(parametrization.matrices(jnp.asarray(corner, dtype=float))[0])
            diagonal &= bool(np.allclose(mass, np.diag(np.diag(mass)), rtol=0.0, atol=0.0))
        gamma = np.asarray(observer.adaptation_gain, dtype=float)
        gamma_tuned = np.diag(gamma) > 0 if np.allclose(gamma, np.diag(np.diag(gamma)), rtol=0.0, atol=0.0) else None
        closed_loop = _closed_loop(scenario)
        if observer.form == "discrete":
            step = float(scenario.sample_period)
        else:
            step = float(scenario.plant_step) if scenario.observer_mode == "continuous" else float(scenario.sample_period) / observer.steps_per_sample
        keys = cls.keys + (("controller.damping_weights", "controller.coupling_gain") if closed_loop else ())
        return cls(
            vessel,
            box,
            unknown,
            float(bounds.damping_min),
            (1.0 + float(bounds.stiffness_max)) ** 2 / 4.0,
            diagonal,
            gamma_tuned,
            gamma,
            closed_loop,
            observer.form,
            step,
            tuple(notes),
            keys=keys,
        )

    # -- the floor ---------------------------------------------------------------------

    @property
    def weight_floor(self) -> float:
        """b = 3 / (4 D_min): d_4..6 > b keeps g2/4 < D_min ((58) with sigma2 > 0)."""
        return 3.0 / (4.0 * self.damping_min)

    def floor(self, d: Array | np.ndarray | None = None, p1: Array | np.ndarray | None = None, xp: ModuleType = np) -> float | Array:
        """The floor of sigma1: g1/4 + k / (D_min - g2/4) ((57) at sigma2 = 0), or k / D_min
        ((22a) at sigma2 = 0) without the backstepping controller (``d``, ``p1`` are the
        controller's, needed with it; ``xp`` numpy or jax.numpy)."""
        if not self.closed_loop:
            return self.coupling / self.damping_min
        if d is None or p1 is None:
            raise TypeError("the floor of (57) needs the backstepping controller's d and P1")
        g2 = xp.sum(1.0 / d[3:])
        g1 = xp.sum(p1 / d[:3]) + g2
        return g1 / 4.0 + self.coupling / (self.damping_min - g2 / 4.0)

    # -- the family ----------------------------------------------------------------------

    @property
    def _gamma_count(self) -> int:
        return 1 if self.gamma_tuned is None else int(self.gamma_tuned.sum())

    def _gamma(self, c):
        if self.gamma_tuned is None:  # a non-diagonal Gamma: its scale
            return jnp.exp(c[0]) * jnp.asarray(self.gamma_matrix / np.abs(self.gamma_matrix).max())
        full = jnp.zeros(self.gamma_tuned.size).at[np.flatnonzero(self.gamma_tuned)].set(jnp.exp(c))
        return full

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        t, a = theta[:3], theta[3:6]
        count = self._gamma_count
        gamma = self._gamma(theta[6 : 6 + count])
        k2 = jnp.exp(a)
        if not self.closed_loop:
            k1 = self.floor(xp=jnp) * (1.0 + INSIDE) + jnp.exp(t)
            return k1, k2, gamma
        e, f = theta[6 + count : 12 + count], theta[12 + count : 15 + count]
        d = jnp.concatenate([jnp.exp(e[:3]), self.weight_floor * (1.0 + INSIDE) + jnp.exp(e[3:])])
        p1 = jnp.exp(f)
        k1 = self.floor(d, p1, jnp) * (1.0 + INSIDE) + jnp.exp(t)
        return k1, k2, gamma, d, p1

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        k1, k2 = (np.asarray(g, dtype=float) * np.ones(3) for g in gains[:2])
        gamma = np.asarray(gains[2], dtype=float)
        if self.closed_loop:
            d, p1 = np.asarray(gains[3], dtype=float) * np.ones(6), np.asarray(gains[4], dtype=float) * np.ones(3)
            if np.any(d <= 0) or np.any(p1 <= 0):
                raise ValueError(f"(57): d and P1 must be positive; got d = {d.tolist()}, P1 = {p1.tolist()}")
            gap = d[3:] - self.weight_floor * (1.0 + INSIDE)
            if np.any(gap <= 0):
                raise ValueError(f"(58): d4..6 = {d[3:].tolist()} s must exceed 3/(4 D_min) = {self.weight_floor:.4g} s")
            floor = float(self.floor(d, p1))
            tail = [np.log(d[:3]), np.log(gap), np.log(p1)]
        else:
            floor, tail = float(self.floor()), []
        excess = k1 - floor * (1.0 + INSIDE)
        if np.any(excess <= 0):
            which = "(57)" if self.closed_loop else "(22)"
            raise ValueError(f"{which}: K1 = {k1.tolist()} 1/s is not above its floor {floor:.4g} 1/s (sigma1 must exceed it)")
        if np.any(k2 <= 0):
            raise ValueError(f"(22): K2 must be positive; got {k2.tolist()}")
        if self.gamma_tuned is None:
            scale = np.abs(gamma).max()
            gamma_theta = [np.log([scale])]
        else:
            gamma = np.diag(gamma) if gamma.ndim == 2 else gamma * np.ones(self.gamma_tuned.size)
            if np.any(gamma[self.gamma_tuned] <= 0):
                raise ValueError(f"Gamma must be positive where it is tuned; got {gamma.tolist()}")
            gamma_theta = [np.log(gamma[self.gamma_tuned])]
        return np.concatenate([np.log(excess), np.log(k2), *gamma_theta, *tail])

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        k1, k2, gamma = (jnp.asarray(g, dtype=float) for g in gains[:3])
        gamma = jnp.diag(jnp.broadcast_to(gamma, (self.gamma_matrix.shape[0],))) if gamma.ndim < 2 else gamma
        scenario = eqx.tree_at(
            lambda s: (s.observer.position_gain, s.observer.velocity_gain, s.observer.adaptation_gain),
            scenario,
            (jnp.broadcast_to(k1, (3,)), jnp.broadcast_to(k2, (3,)), gamma),
        )
        if self.closed_loop:
            d, p1 = (jnp.asarray(g, dtype=float) for g in gains[3:5])
            scenario = eqx.tree_at(
                lambda s: (s.controller.damping_weights, s.controller.coupling_gain),
                scenario,
                (jnp.broadcast_to(d, (6,)), jnp.broadcast_to(p1, (3,))),
            )
        return scenario

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        observer = _observer(scenario)
        gamma = np.asarray(observer.adaptation_gain, dtype=float)
        own = (
            np.asarray(observer.position_gain, dtype=float) * np.ones(3),
            np.asarray(observer.velocity_gain, dtype=float) * np.ones(3),
            gamma if self.gamma_tuned is None else np.diag(gamma).copy(),
        )
        if not self.closed_loop:
            return own
        controller = _controller(scenario)
        return (
            *own,
            np.asarray(controller.damping_weights, dtype=float) * np.ones(6),
            np.asarray(controller.coupling_gain, dtype=float) * np.ones(3),
        )

    def candidates(self, scenario: Scenario) -> Iterator[tuple[np.ndarray, ...]]:
        """Under the backstepping controller: the gains :func:`~lookout.analysis.adaptive_dp.satisfying_gains`
        proposes from the scenario's (K1 and d moved, K2, C1, C2, P1 kept), when its route
        is usable at the reproduction's DESIGN_SPEED (1 m/s) and the controller's sample period (the
        reproduction's ``satisfying`` set, from the printed gains); in the open loop, K1
        raised to :data:`CANDIDATE_FACTORS` times the floor of (22)."""
        from lookout.analysis.adaptive_dp import satisfying_gains
        from lookout.papers.calugi_2003.config import DESIGN_SPEED

        own = self.current(scenario)
        k1, k2, gamma = own[:3]
        if not self.closed_loop:
            for factor in CANDIDATE_FACTORS:
                yield (np.maximum(k1, factor * float(self.floor())), k2, gamma)
            return
        d, p1 = own[3:]
        controller = _controller(scenario)
        try:
            proposal = satisfying_gains(
                self.vessel,
                K1=k1,
                K2=k2,
                d=d,
                C1=np.asarray(controller.position_gain, dtype=float),
                C2=np.asarray(controller.velocity_gain, dtype=float),
                theta_bounds=self.theta_bounds,
                unknown=self.unknown,
                coupling_gain=p1,
                step=float(scenario.sample_period),
                speed=DESIGN_SPEED,
            )
        except ValueError:
            return
        chosen = next(route for route in proposal.routes if route.name == proposal.route)
        if chosen.usable:
            yield (np.diag(proposal.K1).copy(), k2, gamma, np.asarray(proposal.d, dtype=float), p1)

    def integration(self, scenario: Scenario) -> Condition:
        """The sampled observer's integration ((65)-(66), or RK4 of (13)-(14)): an upper
        bound on K1 and K2, checked."""
        from lookout.analysis.conditions import Condition, Inequality

        observer = _observer(scenario)
        fastest = float(max(np.max(np.asarray(observer.position_gain)), np.max(np.asarray(observer.velocity_gain))))
        if self.form == "discrete":
            source = f"{PAPER}, eqs. (65)-(66) (|1 - Delta K| < 1)"
            return Condition(
                "integration_65_66",
                "(65)-(66)",
                "the discrete observer's steps (I - Delta K1), (I - Delta K2) contract",
                source,
                [Inequality.check("Delta max K", "Delta max(K1, K2) < 2", self.step * fastest, "<", 2.0, units="1", source=source)],
            )
        return integration_stable(self.step, fastest, "rk4", "K1, K2", f"{PAPER}, eqs. (13)-(14), integrated by RK4 (lookout)")

    def check(self, scenario: Scenario) -> Report:
        """(22), (57), (58) as ``lookout design adaptive-observer`` checks them (only (22)
        without the backstepping controller) and the integration's bound."""
        from lookout.analysis.adaptive_dp import check_calugi_2003, observer_condition_22
        from lookout.analysis.conditions import Report

        observer = _observer(scenario)
        k1, k2 = np.asarray(observer.position_gain, dtype=float), np.asarray(observer.velocity_gain, dtype=float)
        notes = list(self.model_notes)
        if not self.diagonal_mass:
            notes.append("M(theta) is not diagonal at every vertex of the box: sigma2 > 0 ((22b), (58)) is checked, not parametrized")
        if self.closed_loop:
            controller = _controller(scenario)
            report = check_calugi_2003(
                self.vessel,
                K1=k1,
                K2=k2,
                d=np.asarray(controller.damping_weights, dtype=float),
                theta_bounds=self.theta_bounds,
                unknown=self.unknown,
                coupling_gain=np.asarray(controller.coupling_gain, dtype=float),
            )
            return Report(
                report.title + " and the observer's integration",
                [*report.conditions, self.integration(scenario)],
                report.quantities,
                report.summary,
                [*report.notes, *notes],
            )
        c22 = observer_condition_22(self.vessel, K1=k1, K2=k2, theta_bounds=self.theta_bounds, unknown=self.unknown)
        return Report(f"{PAPER}: condition (22) and the observer's integration", [c22, self.integration(scenario)], notes=notes)


class VectorialBacksteppingFamily(PositiveGains):
    """C1, C2 of the vectorial backstepping controller (36), positive as exp(t): V' of (56)
    has -z'C_z z with C_z = diag(C1, C2) (44), and (57)-(58) do not involve them. Built only
    for a loop that (22), (57), (58) prove at the scenario's gains (module docstring)."""

    name = "vectorial backstepping (Calugi et al. 2003): C1, C2 positive, so -z'C_z z < 0 in (56)"
    design = "the signs of C1, C2 ((44), (56))"
    fields = (Gain("position_gain", "C1", "1/s"), Gain("velocity_gain", "C2", "1/s"))
    condition_key = "backstepping_56"
    condition_name = "(56)"
    condition_title = "-z'C_z z negative definite: C1, C2 > 0 (they are not in (57)-(58))"
    source = f"{PAPER}, eqs. (44), (56)"

    @classmethod
    def of(cls, scenario: Scenario) -> Self:
        """A ValueError when the scenario's own gains do not satisfy the observer family's
        conditions ((22), (57), (58), the integration): C1, C2 would then be tuned in a loop
        that the paper does not prove, and tuning them cannot change that."""
        family = super().of(scenario)
        observer = AdaptiveDPFamily.of(scenario)
        report = observer.check(scenario)
        if not report.holds:
            failing = ", ".join(key for key, verdict in report.verdicts.items() if verdict != "holds")
            raise ValueError(
                f"C1, C2 are tuned only in a loop that (22), (57), (58) prove, and the scenario's gains fail {failing} "
                f"({observer.design} shows why); tune the observer (its family moves K1, K2, d, P1 inside) and start from its result"
            )
        return family


__all__ = ["AdaptiveDPFamily", "VectorialBacksteppingFamily"]
