"""The adaptive manipulator observer's family: Calugi (2002), master thesis, Lund,
chapter 4, the discrete observer (4.34)-(4.35) with Theorem 4.1, and, under the adaptive
observer backstepping of chapter 5 (5.9), its closed-loop condition (5.28).

The conditions (read as in :mod:`lookout.analysis.adaptive_manipulator`), with
``sigma(K) = inf_q lambda_min(K M(q) + M(q) K) / 2``::

    (4.a)  sigma > C_M w_max + beta
    (4.b)  sigma > beta + C_M (w_max + |e(0)| sqrt(p_u / p_l)),   e = (x1~, theta~),
           p_l = min(M_m, 1/gamma_max), p_u = max(M_M, 1/gamma_min)
    (5.28) sigma > C_M w_max + C_M |x1~(0)| + p/4,                p = sum_i 1/d_i

(beta = 0, the margin ``lookout design adaptive-arm`` takes by default; (4.b) is the
region of Theorem 4.1 solved for sigma, which implies (4.a)). Each is a lower bound,
``floor(Gamma)``, on sigma(K), and sigma is positively homogeneous in K
(sigma(s u) = s sigma(u)). So K keeps the scenario's direction u = K / max K and its
scale is parametrized above the floor::

    Gamma = exp(g)
    K     = u (floor(Gamma) (1 + INSIDE) / sigma(u) + exp(b))

and every theta gives sigma(K) = floor(Gamma)(1 + INSIDE) + exp(b) sigma(u) > floor(Gamma):
Theorem 4.1 ((4.a) and the region (4.b)) and, with the backstepping controller, (5.28)
hold by construction for the speed, initial errors and damping weights of the start.
Only the scale is tuned, not the ratios between the joints: sigma(u) is positive only
for directions u near I when M(q) is not diagonal (K M + M K is indefinite for skewed
enough K), and a direction outside that cone has no scale that satisfies (4.a).

Checked at every accepted step: Theorem 4.1 by
:func:`~lookout.analysis.adaptive_manipulator.check_theorem_4_1`, (5.28) by
:func:`~lookout.analysis.adaptive_manipulator.check_5_28` (what
``lookout design adaptive-arm`` runs), and the discrete form's ``|1 - Delta K_i| < 1``
((4.34); derivations-thesis-ch3-6.md, ch. 4), an upper bound on K that is checked, not
parametrized: the tuner halves a step that crosses it.

w_max is measured as for the velocity observer
(:func:`lookout.tuning.families.velocity.peak_speed`): the largest joint speed of the
scenario's runs, measured again at every check when the controller reads the
estimate (the backstepping controller does: the motion then depends on K and Gamma).
theta~(0) = theta - theta_hat(0) with theta the parameters' reference (the model's
values, the truth when the observer's model is the plant's).

(5.28) belongs to this family, not to a family of the controller: it is a floor on the
observer's sigma(K) for the controller's d, which stays as the scenario has it (the
controller's ``observer_gain``, K of Omega (5.11), is set with the observer's K). A
controller family tuning C1, C2, d would need (5.28) and Theorem 4.1 checked again
as well (w_max moves with every gain of the closed loop), and a joint tuning's report
takes each condition from one family only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout.tuning.families import Family, component_as
from lookout.tuning.families.velocity import INSIDE, SPEED_SEEDS, peak_speed, reads_estimate, same_model, speed_source, unbounded_speed

#: beta of Theorem 4.1 (the design command's default).
MARGIN = 0.0
#: Starts tried when the scenario's own K is below the floor: the floor's scale times these.
CANDIDATE_FACTORS = (1.1, 1.5, 2.0, 4.0)
SOURCE = "Calugi (2002)"

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.controllers.adaptive_backstepping import AdaptiveObserverBackstepping
    from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver
    from lookout.sim import Scenario


def _observer(scenario: Scenario) -> AdaptiveManipulatorObserver:
    from lookout.observers.adaptive_manipulator import AdaptiveManipulatorObserver

    return component_as(scenario.observer, AdaptiveManipulatorObserver, "observer")


def _controller(scenario: Scenario) -> AdaptiveObserverBackstepping:
    from lookout.controllers.adaptive_backstepping import AdaptiveObserverBackstepping

    return component_as(scenario.controller, AdaptiveObserverBackstepping, "controller")


@dataclass(frozen=True, eq=False)
class AdaptiveManipulatorFamily(Family):
    """The adaptive observer's K (its scale, along the scenario's direction) and Gamma
    (per parameter), above the floor of Theorem 4.1 and (5.28) by construction (module
    docstring)."""

    direction: np.ndarray  # u = K / max K of the scenario
    sigma_unit: float  # sigma(u), by injection_bound
    coriolis: float  # C_M
    min_inertia: float  # M_m
    max_inertia: float  # M_M
    max_speed: float  # w_max at the start
    velocity_error: np.ndarray  # x1~(0)
    theta_error: np.ndarray  # theta~(0)
    sample_period: float  # Delta of (4.34)
    damping: float | None  # p = sum 1/d_i of the backstepping controller at the start, None without one
    closed_loop: bool
    name: str = "adaptive manipulator (Calugi 2002): K above Theorem 4.1's (and (5.28)'s) floor, Gamma; |1 - Delta K| < 1 checked"
    design: str = "lookout design adaptive-arm --max-speed W, W the runs' largest speed"
    keys: tuple[str, ...] = ("observer.gain", "observer.adaptation_gain")

    @classmethod
    def of(cls, scenario: Scenario) -> AdaptiveManipulatorFamily:
        """The family of ``scenario``'s adaptive observer; a ValueError names the condition
        when none of its gains can satisfy it: Gamma = 0 (Theorem 4.1 needs Gamma > 0), a
        direction of K with sigma <= 0, the controller's K differing from the observer's
        ((5.11)), or a floor on sigma that needs max K >= 2 / Delta ((4.34))."""
        from lookout.analysis.adaptive_manipulator import injection_bound
        from lookout.analysis.velocity import configuration_bounds
        from lookout.controllers.adaptive_backstepping import AdaptiveObserverBackstepping

        observer = _observer(scenario)
        parameters = observer.parameters
        gain = np.asarray(observer.gain, dtype=float)
        adaptation = np.asarray(observer.adaptation_gain, dtype=float)
        if np.any(adaptation <= 0):
            raise ValueError(
                f"Theorem 4.1 needs Gamma > 0; got adaptation_gain {adaptation.tolist()} (Gamma = 0 freezes a parameter: "
                "the chapter-2 velocity observer, not the adaptive one)"
            )
        try:
            bounds = configuration_bounds(parameters.model(parameters.reference))
        except ValueError as error:
            raise ValueError(f"Theorem 4.1: {error}") from None
        direction = gain / gain.max()
        sigma_unit = injection_bound(parameters, direction)
        if not sigma_unit > 0:
            raise ValueError(
                f"Theorem 4.1: sigma = inf_q lambda_min(K M + M K)/2 is {sigma_unit:.4g} <= 0 along K = {gain.tolist()} "
                "(K M + M K is indefinite), so no scale of it satisfies (4.a); make K's joints more alike"
            )
        backstepping = isinstance(scenario.controller, AdaptiveObserverBackstepping)
        damping = None
        if backstepping:
            controller = _controller(scenario)
            copy = np.asarray(controller.observer_gain, dtype=float)
            if not np.allclose(copy, gain, rtol=1e-12, atol=0.0):
                raise ValueError(f"(5.11): the controller's observer_gain {copy.tolist()} is not the observer's gain K {gain.tolist()}")
            damping = float(np.sum(1.0 / np.asarray(controller.damping_weights, dtype=float)))
        guess = scenario.initial_estimate
        velocity_error = np.asarray(scenario.initial_state.qdot, dtype=float) - np.asarray(guess.velocity, dtype=float)
        theta_error = np.asarray(parameters.reference, dtype=float) - np.asarray(guess.theta, dtype=float)
        keys = cls.keys + (("controller.observer_gain",) if backstepping else ())
        family = cls(
            direction,
            float(sigma_unit),
            bounds.coriolis_bound,
            bounds.min_inertia,
            bounds.max_inertia,
            0.0,
            velocity_error,
            theta_error,
            float(observer.sample_period),
            damping,
            reads_estimate(scenario),
            keys=keys,
        )
        family.feasible()  # at w_max = 0 first (the floor grows with it): refused before any simulation
        speed = peak_speed(scenario)
        if not math.isfinite(speed):
            raise ValueError(
                f"Theorem 4.1: the joint speed of the scenario's runs (seeds {SPEED_SEEDS[0]}..{SPEED_SEEDS[-1]}) is not finite, "
                "so no w_max bounds it"
            )
        family = dataclasses.replace(family, max_speed=speed)
        family.feasible()
        return family

    @property
    def backstepping(self) -> bool:
        return self.damping is not None

    # -- the floor -------------------------------------------------------------------

    def floor(self, adaptation: Array | np.ndarray, xp: ModuleType = np) -> float | Array:
        """The largest of the lower bounds on sigma(K) (module docstring) for Gamma =
        ``adaptation``: (4.b) (which implies (4.a)) and (5.28); ``xp`` numpy or jax.numpy."""
        c_m, w = self.coriolis, self.max_speed
        error = float(np.linalg.norm(np.concatenate([self.velocity_error, self.theta_error])))
        p_l = xp.minimum(self.min_inertia, 1.0 / xp.max(adaptation))
        p_u = xp.maximum(self.max_inertia, 1.0 / xp.min(adaptation))
        floor = MARGIN + c_m * (w + error * xp.sqrt(p_u / p_l)) if c_m > 0 else MARGIN + 0.0 * p_l
        if self.damping is not None:  # self.backstepping
            floor = xp.maximum(floor, c_m * w + c_m * float(np.linalg.norm(self.velocity_error)) + self.damping / 4.0)
        return floor

    def best_adaptation(self, adaptation: npt.ArrayLike) -> np.ndarray:
        """Gamma moved to the nearest values with 1/gamma_i in [M_m, M_M], where p_u/p_l,
        and with it the floor, is least."""
        return np.clip(np.asarray(adaptation, dtype=float), 1.0 / self.max_inertia, 1.0 / self.min_inertia)

    def feasible(self) -> None:
        """A ValueError naming Theorem 4.1 (or (5.28)) and (4.34) when the least floor over
        Gamma (1/gamma_i in [M_m, M_M]) needs max K >= 2/Delta along the scenario's
        direction of K. With K = k I that is every diagonal K: sigma(K) <= M_m max K
        (x^T K M x = lambda_min x^T K x for the eigenvector x of lambda_min(M))."""
        adaptation = np.full(self.theta_error.size, 1.0 / math.sqrt(self.min_inertia * self.max_inertia))  # p_l = M_m, p_u = M_M
        floor = float(self.floor(adaptation))
        needed = floor * (1.0 + INSIDE) / self.sigma_unit
        limit = 2.0 / self.sample_period
        if needed >= limit:
            speed = f"w_max = {self.max_speed:.4g} rad/s" if self.max_speed > 0 else "even at w_max = 0"
            which = "Theorem 4.1 and (5.28)" if self.backstepping else "Theorem 4.1"
            raise ValueError(
                f"{which}: sigma(K) > {floor:.4g} (C_M = {self.coriolis:.4g}, {speed}, |e(0)| = "
                f"{np.linalg.norm(np.concatenate([self.velocity_error, self.theta_error])):.4g}) needs max K >= {needed:.4g} 1/s, but (4.34) "
                f"needs |1 - Delta K| < 1, K < 2/Delta = {limit:.4g} 1/s"
            )

    # -- the family --------------------------------------------------------------------

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, ...]:
        adaptation = jnp.exp(theta[1:])
        scale = self.floor(adaptation, jnp) * (1.0 + INSIDE) / self.sigma_unit + jnp.exp(theta[0])
        gain = jnp.asarray(self.direction) * scale
        return (gain, adaptation, gain) if self.backstepping else (gain, adaptation)

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        gain, adaptation = (np.atleast_1d(np.asarray(g, dtype=float)) for g in gains[:2])
        scale = gain.max()
        if not np.allclose(gain, self.direction * scale, rtol=1e-9, atol=0.0):
            raise ValueError(f"the observer gain K {gain.tolist()} is not along the tuned direction {self.direction.tolist()}")
        if np.any(adaptation <= 0):
            raise ValueError(f"Theorem 4.1 needs Gamma > 0; got adaptation_gain {adaptation.tolist()}")
        excess = scale - float(self.floor(adaptation)) * (1.0 + INSIDE) / self.sigma_unit
        if not excess > 0:
            raise ValueError(
                f"Theorem 4.1: the observer gain K {gain.tolist()} is below its floor: sigma(K) = {scale * self.sigma_unit:.4g} "
                f"must exceed {float(self.floor(adaptation)):.4g}"
            )
        return np.concatenate([[math.log(excess)], np.log(adaptation)])

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        gain = jnp.asarray(gains[0], dtype=float)
        scenario = eqx.tree_at(
            lambda s: (s.observer.gain, s.observer.adaptation_gain),
            scenario,
            (gain, jnp.broadcast_to(jnp.asarray(gains[1], dtype=float), _observer(scenario).adaptation_gain.shape)),
        )
        if self.backstepping:  # K of Omega (5.11) is the observer's
            scenario = eqx.tree_at(lambda s: s.controller.observer_gain, scenario, gain)
        return scenario

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        observer = _observer(scenario)
        own = (np.asarray(observer.gain, dtype=float), np.asarray(observer.adaptation_gain, dtype=float))
        return (*own, np.asarray(_controller(scenario).observer_gain, dtype=float)) if self.backstepping else own

    def candidates(self, scenario: Scenario) -> Iterator[tuple[np.ndarray, ...]]:
        """The scenario's Gamma, then Gamma moved to where the floor is least
        (:meth:`best_adaptation`); with each, K's scale raised to
        :data:`CANDIDATE_FACTORS` times the floor's where it is below."""
        gain, adaptation = self.current(scenario)[:2]
        options = [adaptation]
        if not np.allclose(self.best_adaptation(adaptation), adaptation):
            options.append(self.best_adaptation(adaptation))
        for gamma in options:
            least = float(self.floor(gamma)) / self.sigma_unit
            for factor in CANDIDATE_FACTORS:
                scale = max(float(gain.max()), least * factor)
                if scale * self.sample_period >= 2.0:  # outside (4.34)'s |1 - Delta K| < 1
                    continue
                out = (self.direction * scale, gamma)
                yield (*out, out[0]) if self.backstepping else out

    def check(self, scenario: Scenario) -> Report:
        """Theorem 4.1 (and (5.28) under the backstepping controller) as ``lookout design
        adaptive-arm`` checks them, with w_max measured (again, in closed loop), and
        ``|1 - Delta K| < 1`` of (4.34)."""
        from lookout.analysis.adaptive_manipulator import check_5_28, check_theorem_4_1
        from lookout.analysis.conditions import Condition, Inequality, Report

        observer = _observer(scenario)
        gain = np.asarray(observer.gain, dtype=float)
        speed = peak_speed(scenario) if self.closed_loop else self.max_speed
        if not math.isfinite(speed):
            return Report(
                f"{SOURCE}, Theorem 4.1: adaptive observer",
                [unbounded_speed("theorem_4_1", "Theorem 4.1", "adaptive observer: x1~ -> 0, theta~ bounded", f"{SOURCE}, Theorem 4.1")],
                notes=[speed_source(self.closed_loop)],
            )
        parts = [
            check_theorem_4_1(
                observer.parameters,
                gain,
                np.asarray(observer.adaptation_gain, dtype=float),
                speed,
                margin=MARGIN,
                initial_error=(self.velocity_error, self.theta_error),
            )
        ]
        if self.backstepping:
            parts.append(
                check_5_28(
                    observer.parameters,
                    gain,
                    np.asarray(_controller(scenario).damping_weights, dtype=float),
                    speed,
                    initial_error=self.velocity_error,
                )
            )
        source = f"{SOURCE}, eq. (4.34) (derivations-thesis-ch3-6.md, ch. 4)"
        step = self.sample_period * gain
        discrete = Condition(
            "discrete_4_34",
            "(4.34)",
            "the discrete observer's step: |1 - Delta K_i| < 1",
            source,
            [
                Inequality.check("Delta K", "max_i Delta K_i < 2", float(step.max()), "<", 2.0, units="1", source=source),
                Inequality.check("Delta K > 0", "min_i Delta K_i > 0", float(step.min()), ">", 0.0, units="1", source=source),
            ],
        )
        notes = [speed_source(self.closed_loop)] + [note for part in parts for note in part.notes]
        if not same_model(scenario, observer.parameters.model(observer.parameters.reference)):
            notes.append("the observer's model at the parameters' reference differs from the plant's: Theorem 4.1 assumes it is the truth")
        return Report(
            f"{SOURCE}: " + " and ".join(part.conditions[0].name for part in parts) + " and (4.34)",
            [condition for part in parts for condition in part.conditions] + [discrete],
            {part.conditions[0].key: part.quantities for part in parts},
            notes=notes,
        )


__all__ = ["AdaptiveManipulatorFamily"]
