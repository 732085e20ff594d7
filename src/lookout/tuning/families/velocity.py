"""The velocity observer's family: Calugi (2002), master thesis, Lund, Section 2.2, the
reduced-order observer (2.6)-(2.7) with the gain condition of Theorem 2.1.

Theorem 2.1 (with the friction term phi of :mod:`lookout.analysis.velocity`) asks::

    sigma + min(phi, 0) > 3 C_M w_max / M_m,        sigma = lambda_min(K) = min_i K_i

and the region (2.13) asks ``M_m (sigma + min(phi, 0)) / C_M - 2 w_max > |x1~(0)|``.
Both are lower bounds on every K_i, so the gain is parametrized per joint as::

    K_i = floor (1 + INSIDE) + exp(t_i),
    floor = max(3 C_M w_max / M_m, C_M (|x1~(0)| + 2 w_max) / M_m) - min(phi, 0)

and every theta satisfies both by construction; they are checked at every accepted step
by :func:`lookout.analysis.velocity.velocity_observer_condition` (the same bounds M_m,
C_M, phi of :func:`lookout.analysis.velocity.configuration_bounds`).

What the condition needs and where it comes from:

* M_m, C_M, phi: the observer's model, over the configuration space
  (:func:`~lookout.analysis.velocity.configuration_bounds`), once. The theorem takes
  the observer's model to be the plant's; a note says when they differ.
* w_max of (2.2), a bound on ``|q'(t)|``: the scenario holds none, so it is measured,
  as the reproduction of chapter 2 does (:mod:`lookout.papers.calugi_2002_velocity_observer`):
  the largest joint-space speed of the scenario's runs with seeds :data:`SPEED_SEEDS`,
  at its recorded samples (:func:`peak_speed`). With a controller that reads no
  estimate (an open-loop input) the motion does not depend on the gain, so it is
  measured once; with one that does, the speeds change with the gain, and
  :meth:`VelocityFamily.check` measures them again for the gains it checks (the
  parametrization then holds the conditions for the speeds of the start only).
* |x1~(0)| = |q'(0) - x1_hat(0)|: the plant's initial velocity and the observer's guess.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout.sim import Summary
from lookout.tuning.families import Family, component_as

if TYPE_CHECKING:
    from lookout.analysis.conditions import Condition, Report
    from lookout.analysis.velocity import ConfigurationBounds
    from lookout.models.manipulators import ManipulatorModel
    from lookout.observers.velocity import VelocityObserver
    from lookout.sim import Scenario

#: How far above its floor the gain stays: the strict inequalities of Theorem 2.1 and
#: (2.13) as closed ones a rounding cannot leave.
INSIDE = 1e-3
#: Seeds of the runs whose largest joint speed is w_max.
SPEED_SEEDS = (0, 1, 2, 3)
#: Starts tried when the scenario's own gain is below the floor: the floor times these.
CANDIDATE_FACTORS = (1.1, 1.5, 2.0, 4.0)
#: The plant's joint velocity signals (revolute, prismatic).
VELOCITY_SIGNALS = ("joint_rate", "joint_speed")


def _observer(scenario: Scenario) -> VelocityObserver:
    from lookout.observers.velocity import VelocityObserver

    return component_as(scenario.observer, VelocityObserver, "observer")


class PeakSpeed(Summary):
    """The largest Euclidean norm of the joint velocities over a run's records (NaN once
    they are not finite): the measured w_max of (2.2)."""

    names: tuple[str, ...] = eqx.field(static=True)

    def init(self, record: Any) -> Array:
        return jnp.zeros(())

    def update(self, accumulated: Array, index: Array, record: Any) -> tuple[Array, None]:
        truth = record[0]
        velocity = jnp.concatenate([jnp.ravel(truth[name]) for name in self.names])
        speed = jnp.sqrt(jnp.sum(velocity**2))
        return jnp.maximum(accumulated, speed), None  # NaN propagates


def peak_speed(scenario: Scenario, seeds: Sequence[int] = SPEED_SEEDS) -> float:
    """The largest ``|q'|`` (joint-space 2-norm) at the records of ``scenario``'s runs with
    ``seeds`` (inf when a run is not finite); a ValueError when the plant has no joint
    velocities."""
    from lookout.sim import keys_of_seeds, summarize_batch

    names = tuple(s.name for s in scenario.plant.variable_signals if s.name in VELOCITY_SIGNALS)
    if not names:
        raise ValueError(f"the plant records no joint velocity ({' or '.join(VELOCITY_SIGNALS)}), so w_max cannot be measured")
    accumulated, _ = summarize_batch(scenario, keys_of_seeds(list(seeds)), PeakSpeed(names))
    values = np.asarray(accumulated, dtype=float)
    return float(values.max()) if np.all(np.isfinite(values)) else math.inf


def initial_velocity_error(scenario: Scenario, guess: npt.ArrayLike) -> float:
    """|q'(0) - x1_hat(0)|: the plant's initial joint velocity against ``guess``."""
    qdot = np.asarray(scenario.initial_state.qdot, dtype=float)
    return float(np.linalg.norm(qdot - np.asarray(guess, dtype=float)))


def reads_estimate(scenario: Scenario) -> bool:
    """Whether the controller closes the loop on the observer (then the motion, and with
    it w_max, depends on the observer's gains)."""
    return bool(tuple(scenario.controller.estimate_needs))


def speed_source(closed_loop: bool) -> str:
    """How w_max was found, for the reports' notes."""
    seeds = f"seeds {SPEED_SEEDS[0]}..{SPEED_SEEDS[-1]}"
    how = "measured again for these gains (the controller reads the estimate)" if closed_loop else "measured once (the controller reads no estimate)"
    return f"w_max: the largest |q'| at the records of the scenario's runs ({seeds}), {how}"


def unbounded_speed(key: str, name: str, title: str, source: str) -> Condition:
    """A failing condition for runs whose speed is not finite (no w_max bounds it)."""
    from lookout.analysis.conditions import Condition, Inequality

    return Condition(
        key,
        name,
        title,
        source,
        (
            Inequality.check(
                "w_max", "w_max < inf: the runs' largest |q'| is finite", math.inf, "<", float(np.finfo(float).max), units="rad/s", source=source
            ),
        ),
    )


def same_model(scenario: Scenario, model: ManipulatorModel) -> bool:
    """Whether ``model`` is the plant's own (Theorem 2.1 and 4.1 assume it)."""
    plant_model = getattr(scenario.plant, "model", None)
    return plant_model is not None and bool(eqx.tree_equal(plant_model, model))


@dataclass(frozen=True, eq=False)
class VelocityFamily(Family):
    """The velocity observer's K (per joint), above Theorem 2.1's and (2.13)'s floor by
    construction (module docstring): ``K = floor (1 + INSIDE) + exp(t)``."""

    bounds: ConfigurationBounds  # of the observer's model
    max_speed: float  # w_max measured at the start (rad/s)
    initial_error: float  # |x1~(0)|
    floor: float  # the gain every K_i must exceed (1/s)
    closed_loop: bool  # the controller reads the estimate: w_max measured per check
    name: str = "velocity (Calugi 2002): K above Theorem 2.1's and (2.13)'s floor, checked with w_max measured"
    design: str = "lookout.analysis.velocity_observer_condition with w_max the runs' largest speed"
    keys: tuple[str, ...] = ("observer.gain",)

    @classmethod
    def of(cls, scenario: Scenario) -> VelocityFamily:
        """The family of ``scenario``'s velocity observer; a ValueError names Theorem 2.1
        when its bounds are not defined (M depends on a prismatic coordinate) or the
        runs' speed is not finite."""
        from lookout.analysis.velocity import configuration_bounds

        observer = _observer(scenario)
        try:
            bounds = configuration_bounds(observer.model)
        except ValueError as error:
            raise ValueError(f"Theorem 2.1: {error}") from None
        speed = peak_speed(scenario)
        if not math.isfinite(speed):
            raise ValueError(
                f"Theorem 2.1: the joint speed of the scenario's runs (seeds {SPEED_SEEDS[0]}..{SPEED_SEEDS[-1]}) is not finite, "
                "so no w_max bounds it"
            )
        initial_error = initial_velocity_error(scenario, scenario.initial_estimate)
        return cls(bounds, speed, initial_error, gain_floor(bounds, speed, initial_error), reads_estimate(scenario))

    def gains(self, theta: Array | np.ndarray) -> tuple[Array]:
        return (self.floor * (1.0 + INSIDE) + jnp.exp(theta),)

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        gain = np.atleast_1d(np.asarray(gains[0], dtype=float))
        excess = gain - self.floor * (1.0 + INSIDE)
        if np.any(excess <= 0):
            raise ValueError(
                f"Theorem 2.1: the velocity observer gain {np.round(gain, 6).tolist()} 1/s is not above its floor "
                f"{self.floor * (1.0 + INSIDE):.6g} 1/s (3 C_M w_max / M_m and (2.13) with w_max = {self.max_speed:.4g} rad/s)"
            )
        return np.log(excess)

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        gain = jnp.broadcast_to(jnp.asarray(gains[0], dtype=float), _observer(scenario).gain.shape)
        return eqx.tree_at(lambda s: s.observer.gain, scenario, gain)

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        return (np.asarray(_observer(scenario).gain, dtype=float),)

    def candidates(self, scenario: Scenario) -> Iterator[tuple[np.ndarray, ...]]:
        """The scenario's gain raised, joint by joint, to :data:`CANDIDATE_FACTORS` times
        the floor where it is below (nearest first)."""
        own = np.asarray(_observer(scenario).gain, dtype=float)
        for factor in CANDIDATE_FACTORS:
            yield (np.maximum(own, self.floor * factor),)

    def check(self, scenario: Scenario) -> Report:
        """Theorem 2.1 and region (2.13), as
        :func:`~lookout.analysis.velocity.velocity_observer_condition` checks them, with
        w_max measured (again, for a controller that reads the estimate)."""
        from lookout.analysis.conditions import Report
        from lookout.analysis.velocity import velocity_observer_condition

        observer = _observer(scenario)
        speed = peak_speed(scenario) if self.closed_loop else self.max_speed
        if not math.isfinite(speed):
            return Report(
                "Calugi (2002), Theorem 2.1: velocity observer",
                [unbounded_speed("theorem_2_1", "Theorem 2.1", "velocity observer: x1~ -> 0 exponentially", "Calugi (2002), Theorem 2.1, eq. (2.2)")],
                notes=[speed_source(self.closed_loop)],
            )
        result = velocity_observer_condition(
            observer.model, np.asarray(observer.gain, dtype=float), speed, initial_error=self.initial_error, bounds=self.bounds
        )
        notes = [speed_source(self.closed_loop)]
        if not same_model(scenario, observer.model):
            notes.append("the observer's model differs from the plant's: Theorem 2.1 assumes they are the same")
        return result.report.extended(notes=notes)


def gain_floor(bounds: ConfigurationBounds, max_speed: float, initial_error: float) -> float:
    """The gain every K_i must exceed for Theorem 2.1 and (2.13) (module docstring), in
    the analysis's own arithmetic."""
    c_max, low, phi = bounds.coriolis_bound, bounds.min_inertia, bounds.friction_bound
    needed = max(3.0 * c_max * max_speed / low, c_max * (initial_error + 2.0 * max_speed) / low)
    return needed - min(phi, 0.0)


__all__ = ["VelocityFamily", "gain_floor", "peak_speed"]
