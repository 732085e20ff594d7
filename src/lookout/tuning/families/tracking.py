"""Wondergem et al. (2009): the Earth-fixed observer's family (Proposition 3.1) and the
tracking controller's ((25)), checked by :func:`lookout.analysis.tracking.check_wondergem_2009`
(what ``lookout design tracking-gains`` runs) at the scenario's own start and reference.

Observer (6): L1, L2 per DOF. Proposition 3.1's (10b) and (11) are lower bounds on
lambda_min(L2) that do not depend on the gains, and (10a) and (13) lower bounds on
lambda_min(L1) that depend on L2 only through lambda_max(L2) in gamma1 (and only when the
initial estimate is off, eta~(0) != 0): so ``L2 = b2 (1 + INSIDE) + exp(t2)`` with b2 the
larger of 1 and (11)'s right side, and ``L1 = b1 (1 + INSIDE) + exp(t1)`` with b1 the
larger of 1 and (13)'s right side at the starting L2, hold them by construction; (13) at
a larger L2 and (14) (lambda_max(L1) bounded by lambda_min(L1) when eta~(0) != 0) are
checked at every step.

Controller (23): Omega, Lambda per DOF, positive as exp(t); (25),
lambda_min(Q) > r_max + sqrt(lambda_max(P) / lambda_min(P)) ||x_e(0)||, is checked. It
depends on the initial tracking error: with the ship 10 m off the reference it asks for
Omega of several rad/s, so a scenario's controller is often left as it is (a note says
why) while its observer is tuned.

Proposition 3.3 (the combined scheme) is not imposed: on the reproduction's ellipse it
asks for L1 near 2.5e5 1/s (:mod:`lookout.analysis.tracking`), which no sampled observer
integrates; ``lookout design tracking-gains`` reports it.

The start and the reference's bounds are the scenario's: eta(0), nu(0) of the plant, the
observer's initial estimate as its ``init`` makes it, and the reference sampled over the
run (its yaw rate's largest magnitude, r_max of (25), and eta_ref, nu_ref at t_0).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from lookout.tuning.families import STABLE_STEP, Family, component_as, integration_stable

if TYPE_CHECKING:
    from lookout.analysis.conditions import Report
    from lookout.controllers.tracking import TrackingController
    from lookout.observers.earth_fixed import EarthFixedObserver
    from lookout.sim import Scenario

#: How far above a lower bound a parametrized gain stays (relative).
INSIDE = 1e-3
#: Prop. 3.1's velocity bound V_M (m/s) when the scenario gives none: the design rule's default.
VELOCITY_BOUND = 0.3


def _observer(scenario: Scenario) -> EarthFixedObserver:
    from lookout.observers.earth_fixed import EarthFixedObserver

    return component_as(scenario.observer, EarthFixedObserver, "observer")


def _controller(scenario: Scenario) -> TrackingController:
    from lookout.controllers.tracking import TrackingController

    return component_as(scenario.controller, TrackingController, "controller")


def _reference_data(scenario) -> dict:
    """eta_ref(0), nu_ref(0) and the largest |r_ref| over the run, from the scenario's
    reference stepped at its sample period (zero noise)."""
    from lookout.controllers.tracking import reference_velocity

    reference = scenario.reference
    count = int(round(scenario.duration / scenario.sample_period))
    dt = scenario.sample_period
    normals = jnp.zeros(reference.noise_size)

    def body(state, t):
        state, sample = reference.step(state, t, dt, normals)
        return state, reference_velocity(sample)

    _, (eta_ref, nu_ref, _) = jax.lax.scan(body, reference.init(), jnp.arange(count) * dt)
    return {
        "reference_position0": np.asarray(eta_ref[0]),
        "reference_velocity0": np.asarray(nu_ref[0]),
        "yaw_rate_max": float(np.abs(np.asarray(nu_ref[:, 2])).max()),
    }


def _start(scenario) -> dict:
    """eta(0), nu(0), eta_hat(0) and the Earth-frame velocity estimate at t_0."""
    state = scenario.initial_state
    eta0 = np.asarray(state.eta, dtype=float)
    observer = scenario.observer
    y0 = jnp.asarray(eta0)
    out = observer.output(observer.init(y0, scenario.initial_estimate), y0)
    return {
        "eta0": eta0,
        "nu0": np.asarray(state.nu, dtype=float),
        "eta_hat0": np.asarray(out["position"].tolist() + [float(out["heading"])]),
        "velocity_hat0": np.append(np.asarray(out["position_rate"]), float(out["heading_rate"])),
    }


class _Wondergem(Family):
    """The check both families share: check_wondergem_2009 at the scenario's start."""

    design = "lookout design tracking-gains"
    condition = ""

    def __init__(self, scenario: Scenario, velocity_bound: float = VELOCITY_BOUND):
        from lookout.controllers.tracking import TrackingController
        from lookout.observers.earth_fixed import EarthFixedObserver

        if not isinstance(scenario.observer, EarthFixedObserver):
            raise ValueError(
                f"{self.condition}: Wondergem et al.'s conditions need the Earth-fixed observer (6); got {type(scenario.observer).__name__}"
            )
        if not isinstance(scenario.controller, TrackingController):
            raise ValueError(
                f"{self.condition}: Wondergem et al.'s conditions need the tracking controller (23); got {type(scenario.controller).__name__}"
            )
        self.velocity_bound = velocity_bound
        self.context = {**_start(scenario), **_reference_data(scenario)}

    def report(self, scenario: Scenario) -> Report:
        from lookout.analysis.tracking import check_wondergem_2009

        observer, controller = _observer(scenario), _controller(scenario)
        return check_wondergem_2009(
            observer.ship,
            observer_gains=(np.asarray(observer.position_gain), np.asarray(observer.velocity_gain)),
            natural_frequency=np.asarray(controller.natural_frequency),
            damping_ratio=np.asarray(controller.damping_ratio),
            velocity_bound=self.velocity_bound,
            **self.context,
        )

    def check(self, scenario: Scenario) -> Report:
        from lookout.analysis.conditions import Report

        report = self.report(scenario)
        return Report(report.title, [report[self.condition]], report.quantities, report.summary, report.notes)


class EarthFixedFamily(_Wondergem):
    """L1, L2 of the Earth-fixed observer (6) inside Proposition 3.1 (module docstring)."""

    name = "earth-fixed (Wondergem et al. 2009): L1, L2 above Proposition 3.1's bounds, (13) and (14) checked"
    keys = ("observer.position_gain", "observer.velocity_gain")
    condition = "observer_3_1"

    def __init__(self, scenario: Scenario, velocity_bound: float = VELOCITY_BOUND):
        super().__init__(scenario, velocity_bound)
        inequalities = {item.name: item for item in self.report(scenario)[self.condition].inequalities}
        self.low2 = max(1.0, float(inequalities["(11)"].right))
        self.low1 = max(1.0, float(inequalities["(13)"].right))
        observer = _observer(scenario)
        # the observer's integration step: the plant's when integrated jointly with it
        self.step = scenario.plant_step if scenario.observer_mode == "continuous" else scenario.sample_period / observer.steps_per_sample
        self.stable = STABLE_STEP[observer.method] / self.step  # the largest L1 the integration keeps stable
        if 1.5 * self.low1 >= self.stable:
            need = int(np.ceil(1.5 * self.low1 * scenario.sample_period / STABLE_STEP[observer.method]))
            if scenario.observer_mode == "continuous":
                raise ValueError(
                    f"Proposition 3.1 needs L1 > {self.low1:.4g} 1/s (its (13)), which {observer.method} at the plant step "
                    f"{scenario.plant_step:g} s integrates only below {self.stable:.4g} 1/s; shorten simulation.plant_step"
                )
            raise ValueError(
                f"Proposition 3.1 needs L1 > {self.low1:.4g} 1/s (its (13)), which {observer.method} at {observer.steps_per_sample} "
                f"step(s) per {scenario.sample_period:g} s sample integrates only below {self.stable:.4g} 1/s; set "
                f"observer.steps_per_sample to at least {need}"
            )

    def check(self, scenario: Scenario) -> Report:
        """Prop. 3.1 and the integration's stability: L1's fastest error pole, near -L1,
        inside the method's stable step (a gain set that cannot be integrated is refused)."""
        from lookout.analysis.conditions import Report

        report = super().check(scenario)
        observer = _observer(scenario)
        fastest = float(np.max(np.asarray(observer.position_gain)))
        integration = integration_stable(self.step, fastest, observer.method, "L1", "lookout")
        return Report(report.title, [*report.conditions, integration], report.quantities, report.summary, report.notes)

    @classmethod
    def of(cls, scenario: Scenario) -> EarthFixedFamily:
        return cls(scenario)

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, Array]:
        return self.low1 * (1.0 + INSIDE) + jnp.exp(theta[:3]), self.low2 * (1.0 + INSIDE) + jnp.exp(theta[3:6])

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        l1, l2 = (np.asarray(g, dtype=float) * np.ones(3) for g in gains)
        gap1, gap2 = l1 - self.low1 * (1.0 + INSIDE), l2 - self.low2 * (1.0 + INSIDE)
        if np.any(gap1 <= 0) or np.any(gap2 <= 0):
            raise ValueError(
                f"Proposition 3.1: L1 = {l1.tolist()} must exceed {self.low1:.4g} ((10a), (13)) and L2 = {l2.tolist()} must exceed "
                f"{self.low2:.4g} ((10b), (11))"
            )
        return np.concatenate([np.log(gap1), np.log(gap2)])

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        return eqx.tree_at(
            lambda s: (s.observer.position_gain, s.observer.velocity_gain),
            scenario,
            tuple(jnp.broadcast_to(jnp.asarray(g, dtype=float), (3,)) for g in gains),
        )

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        observer = _observer(scenario)
        return tuple(np.asarray(g, dtype=float) * np.ones(3) for g in (observer.position_gain, observer.velocity_gain))

    def candidates(self, scenario: Scenario) -> Iterator[tuple[np.ndarray, ...]]:
        """Each gain raised to 1.5 times its bound where it is below (then 2.25, 3.375
        times, within what the integration keeps stable)."""
        l1, l2 = self.current(scenario)
        for factor in (1.5, 2.25, 3.375):
            yield (np.minimum(np.maximum(l1, factor * self.low1), 0.9 * self.stable), np.maximum(l2, factor * self.low2))


class TrackingFamily(_Wondergem):
    """Omega, Lambda of the tracking controller (23), positive, (25) checked."""

    name = "tracking controller (Wondergem et al. 2009): Omega, Lambda positive, (25) checked"
    keys = ("controller.natural_frequency", "controller.damping_ratio")
    condition = "controller_25"

    @classmethod
    def of(cls, scenario: Scenario) -> TrackingFamily:
        return cls(scenario)

    def gains(self, theta: Array | np.ndarray) -> tuple[Array, Array]:
        return jnp.exp(theta[:3]), jnp.exp(theta[3:6])

    def theta(self, gains: Sequence[ArrayLike]) -> np.ndarray:
        values = np.concatenate([np.asarray(g, dtype=float) * np.ones(3) for g in gains])
        if np.any(values <= 0):
            raise ValueError(f"(25): Omega and Lambda must be positive; got {values.tolist()}")
        return np.log(values)

    def apply(self, scenario: Scenario, gains: Sequence[ArrayLike]) -> Scenario:
        return eqx.tree_at(
            lambda s: (s.controller.natural_frequency, s.controller.damping_ratio),
            scenario,
            tuple(jnp.broadcast_to(jnp.asarray(g, dtype=float), (3,)) for g in gains),
        )

    def current(self, scenario: Scenario) -> tuple[np.ndarray, ...]:
        controller = _controller(scenario)
        return tuple(np.asarray(g, dtype=float) * np.ones(3) for g in (controller.natural_frequency, controller.damping_ratio))
