"""Earth-fixed nonlinear observer for a ship at speed: Wondergem et al. (2009), eq. (6).

Wondergem, M., Lefeber, E., Pettersen, K. Y. and Nijmeijer, H. (2009), "Output
feedback tracking of ships", Section 3. The ship in Earth-fixed form (1)–(2),
``M*(psi) eta'' + C*(psi, eta') eta' + d*(psi, eta') = J(psi) tau``, position and
heading measured. The observer, in the only reading that makes the error dynamics
(8) exact (the Nicosia–Tomei / Berghuis observer of the paper's refs. [3], [4];
derivations-wondergem-2009.md, section 2, verified here by the error dynamics below),
with eta~ = eta - eta_hat (heading through ``ssa``)::

    eta_hat' = zeta + L1 eta~  =: v_hat                                            (6a)
    zeta'    = -M*^-1 [C*(psi, v_hat) v_hat + d*(psi, v_hat) - J(psi) tau] + L2 eta~  (6b)

The model terms use v_hat = eta_hat' (the estimate of eta'), not the state zeta; the
printed dots and hats were lost in extraction. Without inverting M*, (6b) is
``zeta' = J(psi) [S(r_hat) nu_hat + M^-1 (tau - C(nu_hat) nu_hat - D nu_hat -
D_n(nu_hat))] + L2 eta~`` with nu_hat = J^T(psi) v_hat (:meth:`Cybership.earth_acceleration`).

Error dynamics: eta~' = eta' - v_hat, and eta~'' = eta'' - zeta' - L1 eta~' gives, with
eta'' = -M*^-1 [C* eta' + d* - J tau] and the same tau in both,

    eta~'' + L1 eta~' + L2 eta~ = -M*^-1 [C*(eta') eta' - C*(v_hat) v_hat] - M*^-1 [d*(eta') - d*(v_hat)]   (8)

whose right side vanishes when eta' = v_hat: with a matched model the linear part
s^2 + L1 s + L2 governs the errors near zero: (s + 5)(s + 10) for the paper's L1 = 15 I,
L2 = 50 I (:mod:`lookout.papers.wondergem_2009`).

Choices
-------
* The heading in M*, C*, d*, J(psi) tau and nu_hat is the **measured** one (the paper
  takes the heading as measured exactly); eta_hat still carries psi_hat, which the
  controller of (23) uses. When the heading sample is missing, psi_hat stands in.
* The estimate reported as ``velocity``/``yaw_rate`` is nu_hat = J^T(psi) v_hat with
  the measured heading at the sample; v_hat itself (Earth frame) is the extra
  ``position_rate``/``heading_rate``.
* Initial velocity. The paper's "initial velocity estimate [0.5, 0.5, -0.5]" can be
  v_hat(0) (``initial_velocity="estimate"``, the default: zeta(0) = v - L1 eta~(0)) or
  the state zeta(0) (``initial_velocity="state"``): derivations section 9 asks to say
  which; the reproduction sweeps both. The choice is an array leaf, so runs with
  either choice vmap together.
* Missing samples (NaN): the injection terms are zero on a missing channel.
* Sampled implementation: ``method="rk4"`` integrates (6) by ``steps_per_sample`` RK4
  steps with the measurement and tau held; ``method="euler"`` takes forward-Euler
  steps, as the basin implementation did at 20 Hz (derivations section 9).
"""

from __future__ import annotations

import math
from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import rotate_transpose, ssa
from lookout.components import EARTH_FIXED, ContinuousObserver, Layout, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Range, Rule, Value, component, initial_values
from lookout.models.cybership import CYBERSHIP_SIGNALS, Cybership
from lookout.models.vessel import VESSEL_INPUT
from lookout.observers.start import from_first_measurement
from lookout.sensors import POSITION_HEADING
from lookout.sim.integrators import integrate_sample

METHODS = ("rk4", "euler")
INITIAL_VELOCITY = ("estimate", "state")

ESTIMATE_SIGNALS = tuple(s for s in CYBERSHIP_SIGNALS if s.name in ("position", "heading", "velocity", "yaw_rate"))
EXTRA_SIGNALS = (
    *(
        s.renamed(s.name.replace("measured_", "innovation_"), "innovation eta - eta_hat (eq. 6), " + s.name.split("_", 1)[1])
        for s in POSITION_HEADING.signals
    ),
    Signal("position_rate", "m/s", "estimated Earth-fixed velocity v_hat = eta_hat' (eq. 6a)", EARTH_FIXED, ("north", "east"), "earth_axis"),
    Signal("heading_rate", "rad/s", "estimated heading rate, third entry of v_hat", EARTH_FIXED),
)


@final
class EarthFixedEstimate(eqx.Module):
    """The observer's state: eta_hat (m, m, rad) and zeta (m/s, m/s, rad/s), Earth-fixed."""

    eta: Array
    zeta: Array


@final
class EarthFixedGuess(eqx.Module):
    """An initial estimate: eta_hat(0) and a velocity estimate (Earth frame, m/s, m/s, rad/s)
    that :meth:`EarthFixedObserver.init` assigns to v_hat(0) or to zeta(0)."""

    eta: Array
    velocity: Array


def _gain(name: str, value) -> Array:
    array = np.asarray(value, dtype=float) if check.is_concrete(value) else value
    if check.is_concrete(value) and array.ndim == 2:
        if array.shape != (3, 3) or np.any(array != np.diag(np.diag(array))):
            raise check.ParameterError(check.key(name), f"{name} must be a scalar, 3 diagonal entries or a diagonal 3x3 matrix; got {array.tolist()}")
        array = np.diag(array)
    return jnp.asarray(check.vector(name, array))


#: The keys of the ``wondergem-2009`` rules of the Earth-fixed observer and the tracking
#: controller: both take the same reference and start (the observer is built before the reference).
WONDERGEM_RULE_VALUES = (
    Value("reference_position", "array", "eta_ref(0): the reference's position north, east (m) and heading (rad) at t_0.", shape="(3,)"),
    Value(
        "reference_velocity", "array", "nu_ref(0): the reference's body-frame velocity surge, sway (m/s) and yaw rate (rad/s) at t_0.", shape="(3,)"
    ),
    Value("reference_yaw_rate_max", "float", "r_ref^max, the largest |r_ref| of the reference (rad/s).", range=NON_NEGATIVE),
    Value("reference_speed_max", "float", "sup ||nu_ref|| of the reference (m/s and rad/s in one norm, as the paper's).", range=NON_NEGATIVE),
    Value(
        "reference_acceleration_max",
        "float",
        "sup ||nu_ref'|| of the reference (m/s^2 and rad/s^2 in one norm), its smooth part.",
        range=NON_NEGATIVE,
    ),
    Value("start_position", "array", "eta(0): the ship's initial position north, east (m) and heading (rad).", shape="(3,)"),
    Value("start_velocity", "array", "nu(0): the ship's initial body-frame velocity (m/s, m/s, rad/s).", shape="(3,)"),
    Value(
        "estimate_position",
        "array",
        "eta_hat(0), the observer's initial position estimate (m, m, rad); default start_position, the estimate started at the measurement.",
        shape="(3,)",
    ),
    Value("estimate_velocity", "array", "v_hat(0) = eta_hat'(0), the initial Earth-frame velocity estimate (m/s, m/s, rad/s).", shape="(3,)"),
    Value("damping_ratio", "float", "lambda of Lambda = lambda I, the relative damping of the error dynamics (19) (1).", range=POSITIVE),
    Value("velocity_bound", "float", "V_M of Prop. 3.1, a bound on the ship's speed ||eta'|| (m/s).", range=NON_NEGATIVE),
    Value("margin", "float", "Factor by which L1 and L2 exceed their largest lower bound (1).", range=Range(1.0, math.inf, False, False)),
)


@component(
    "observer",
    "earth-fixed",
    summary="The observer (6) of Wondergem et al. (2009) for a Cybership model.",
    family="lookout.tuning.families.tracking:EarthFixedFamily",
    rules={
        "gains": Rule(
            None,
            (
                Part(
                    "ship",
                    "The observer's model (it may differ from the plant: linear damping only in the basin scheme); in a composition, the plant's unless given.",
                ),
                Value("position_gain", "array", "L1 (1/s) of (6a), positive: a scalar, its diagonal (3,) or a diagonal 3x3 matrix."),
                Value("velocity_gain", "array", "L2 (1/s^2) of (6b), positive: a scalar, its diagonal (3,) or a diagonal 3x3 matrix."),
                Value("steps_per_sample", "int", "Integration steps of predict per sample."),
                Value("method", "str", "How predict integrates (6) between samples.", choices=("rk4", "euler")),
                Value(
                    "initial_velocity",
                    "str",
                    "Which of v_hat(0) or zeta(0) the guess's velocity is (module docstring).",
                    choices=("estimate", "state"),
                ),
            ),
        ),
        "wondergem-2009": Rule(
            "lookout.analysis.tracking:wondergem_2009_observer",
            (
                Part("ship", "The observer's model (M, D and D_n); in a composition, the plant's unless given."),
                *WONDERGEM_RULE_VALUES,
                Value("steps_per_sample", "int", "Integration steps of the observer's predict per sample."),
                Value("method", "str", "How the observer's predict integrates (6) between samples.", choices=("rk4", "euler")),
                Value(
                    "initial_velocity",
                    "str",
                    "Which of v_hat(0) or zeta(0) the guess's velocity is (module docstring).",
                    choices=("estimate", "state"),
                ),
            ),
        ),
    },
)
@final
class EarthFixedObserver(ContinuousObserver):
    """The observer (6) of Wondergem et al. (2009) for a :class:`Cybership` model.

    Parameters
    ----------
    ship : Cybership
        The observer's model (it may differ from the plant: linear damping only in the
        basin scheme); in a composition, the plant's unless given.
    position_gain : array_like
        L1 (1/s) of (6a), positive: a scalar, its diagonal (3,) or a diagonal 3x3 matrix.
    velocity_gain : array_like
        L2 (1/s^2) of (6b), positive: a scalar, its diagonal (3,) or a diagonal 3x3 matrix.
    steps_per_sample : int
        Integration steps of :meth:`predict` per sample.
    method : {"rk4", "euler"}
        How :meth:`predict` integrates (6) between samples.
    initial_velocity : {"estimate", "state"}
        Which of v_hat(0) or zeta(0) the guess's velocity is (module docstring).
    """

    ship: Cybership
    position_gain: Array
    velocity_gain: Array
    velocity_is_state: Array
    steps_per_sample: int = eqx.field(static=True)
    method: str = eqx.field(static=True)
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    #: what it reads (position and heading) and the applied thrust; any step dt
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    sample_period: None = eqx.field(static=True)

    def __init__(
        self,
        ship: Cybership,
        position_gain: npt.ArrayLike,
        velocity_gain: npt.ArrayLike,
        *,
        steps_per_sample: int = 1,
        method: str = "rk4",
        initial_velocity: str = "estimate",
    ):
        if not isinstance(ship, Cybership):
            raise check.ParameterError("ship", f"ship must be a Cybership; got {type(ship).__name__}")
        self.ship = ship
        self.position_gain = _gain("position_gain (L1)", position_gain)
        self.velocity_gain = _gain("velocity_gain (L2)", velocity_gain)
        if not (isinstance(steps_per_sample, int) and not isinstance(steps_per_sample, bool) and steps_per_sample >= 1):
            raise check.ParameterError("steps_per_sample", f"steps_per_sample must be a positive integer; got {steps_per_sample!r}")
        if method not in METHODS:
            raise check.ParameterError("method", f"method must be one of {', '.join(map(repr, METHODS))}; got {method!r}")
        if initial_velocity not in INITIAL_VELOCITY:
            raise check.ParameterError(
                "initial_velocity", f"initial_velocity must be one of {', '.join(map(repr, INITIAL_VELOCITY))}; got {initial_velocity!r}"
            )
        self.steps_per_sample = steps_per_sample
        self.method = method
        self.velocity_is_state = jnp.asarray(initial_velocity == "state")
        # every field set here (see SlidingModeObserver.__init__)
        self.estimate_signals, self.extra_signals = ESTIMATE_SIGNALS, EXTRA_SIGNALS
        self.measurement_layout, self.input_layout, self.sample_period = POSITION_HEADING, VESSEL_INPUT, None

    def __check_init__(self):
        check.positive("position_gain (L1)", self.position_gain)
        check.positive("velocity_gain (L2)", self.velocity_gain)

    @initial_values(
        Value("eta", "array", "eta_hat(0): position north, east (m) and heading (rad); default the first measurement.", shape="(3,)"),
        Value("velocity", "array", "The Earth-frame velocity (m/s, m/s, rad/s) of v_hat(0) or zeta(0) (initial_velocity).", shape="(3,)"),
    )
    def guess(self, eta: npt.ArrayLike | None = None, velocity: npt.ArrayLike = 0.0) -> EarthFixedGuess:
        """An initial estimate: eta_hat(0) = ``eta`` (the first measurement unless given)
        and the Earth-frame ``velocity``.

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            eta_hat(0): position north, east (m) and heading (rad); default the first
            measurement.
        velocity : array_like, shape (3,)
            The Earth-frame velocity (m/s, m/s, rad/s) of v_hat(0) or zeta(0) (``initial_velocity``).
        """
        return EarthFixedGuess(jnp.asarray(check.vector("eta", eta)), jnp.asarray(check.vector("velocity", velocity)))

    def innovation(self, estimate: EarthFixedEstimate, measurement: Array) -> Array:
        """eta~ = y - eta_hat, heading through ssa, zero on missing channels."""
        error = measurement - estimate.eta
        error = error.at[2].set(ssa(error[2]))
        return jnp.where(jnp.isfinite(measurement), error, 0.0)

    def heading(self, estimate: EarthFixedEstimate, measurement: Array) -> Array:
        """The heading of the model terms: measured, or psi_hat when the sample is missing."""
        return jnp.where(jnp.isfinite(measurement[2]), measurement[2], estimate.eta[2])

    def init(self, y0: Array, guess: EarthFixedGuess) -> EarthFixedEstimate:
        """eta_hat(0) from the guess, or y_0 where the guess leaves it to the first
        measurement (:mod:`lookout.observers.start`); zeta(0) = v - L1 eta~(0) (v is
        v_hat(0)) or v (v is zeta(0))."""
        eta = from_first_measurement(guess.eta, y0, angles=(2,))
        start = EarthFixedEstimate(eta, jnp.zeros(3))
        zeta = jnp.where(self.velocity_is_state, guess.velocity, guess.velocity - self.position_gain * self.innovation(start, y0))
        return EarthFixedEstimate(eta, zeta)

    def update(self, estimate: EarthFixedEstimate, t: ArrayLike, measurement: Array) -> EarthFixedEstimate:
        """No discrete correction: the measurement enters through (6)."""
        del t, measurement
        return estimate

    def rates(self, estimate: EarthFixedEstimate, eta_tilde: Array, heading: Array, tau: Array) -> EarthFixedEstimate:
        """(6a)–(6b) for a given innovation and heading."""
        v_hat = estimate.zeta + self.position_gain * eta_tilde
        return EarthFixedEstimate(eta=v_hat, zeta=self.ship.earth_acceleration(heading, v_hat, tau) + self.velocity_gain * eta_tilde)

    def vector_field(self, t: ArrayLike, estimate: EarthFixedEstimate, measurement: Array, tau: Array) -> EarthFixedEstimate:
        """Right-hand side of (6) with the measurement ``measurement``."""
        del t
        return self.rates(estimate, self.innovation(estimate, measurement), self.heading(estimate, measurement), tau)

    def predict(self, estimate: EarthFixedEstimate, t: ArrayLike, measurement: Array, tau: Array, dt: ArrayLike) -> EarthFixedEstimate:
        """Advance over one sample with the measurement and tau held: ``steps_per_sample``
        RK4 or forward-Euler steps of (6); the heading of the result wrapped."""
        heading = self.heading(estimate, measurement)

        def field(time, x):
            del time
            return self.rates(x, self.innovation(x, measurement), heading, tau)

        # one step inline; more as a loop (unroll_limit=1), so that the program (and its
        # gradient, which tuning compiles) does not grow with steps_per_sample
        return integrate_sample(field, t, estimate, dt, self.steps_per_sample, method=self.method, normalize=self.normalize, unroll_limit=1)

    def normalize(self, estimate: EarthFixedEstimate) -> EarthFixedEstimate:
        """Heading of eta_hat wrapped to [-pi, pi)."""
        return EarthFixedEstimate(estimate.eta.at[2].set(ssa(estimate.eta[2])), estimate.zeta)

    def output(self, estimate: EarthFixedEstimate, measurement: Array) -> dict[str, Array]:
        """eta_hat, nu_hat = J^T(psi) v_hat, the innovation and v_hat."""
        eta_tilde = self.innovation(estimate, measurement)
        v_hat = estimate.zeta + self.position_gain * eta_tilde
        nu_hat = rotate_transpose(self.heading(estimate, measurement), v_hat)
        return {
            "position": estimate.eta[:2],
            "heading": estimate.eta[2],
            "velocity": nu_hat[:2],
            "yaw_rate": nu_hat[2],
            "innovation_position": eta_tilde[:2],
            "innovation_heading": eta_tilde[2],
            "position_rate": v_hat[:2],
            "heading_rate": v_hat[2],
        }


__all__ = ["EarthFixedEstimate", "EarthFixedGuess", "EarthFixedObserver"]
