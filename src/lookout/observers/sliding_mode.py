"""Sliding-mode robust observer for dynamic positioning.

Kim, M.-H. (2002), "Design and analysis of dynamic positioning system using a
nonlinear robust observer", eqs. (6)–(7), corrected as derived in
``derivations-kim-calugi-2003.md`` (K1, K2)::

    xi_hat'   = A_w xi_hat + H1 y~
    eta_hat'  = J(y) nu_hat + H2 y~ + Kbar sat(s / eps)
    b_hat'    = -T^{-1} b_hat + H3 y~
    M nu_hat' = -D nu_hat + tau + J^T(y) b_hat + J^T(y) H4 y~
    y_hat     = eta_hat + C_w xi_hat,   y~ = y - y_hat

The printed text injects "y_hat" everywhere; an observer is driven by the output
error, so every injection is y~ (NOTES.md). Without the switching term this is the
passive observer of Fossen & Strand (1999), eqs. (22)–(25), with gamma = 1,
K1 = H1, K2 = H2, Lambda = H3 and Kappa = H4: this class is that observer plus the
switching term, and with Kbar = 0 it gives the passive observer's estimates.

The switching signal (choice)
-----------------------------
The text says sat(z) with z "defined later"; the only later definition is the
garbled C of (10). The Lyapunov derivative (17) needs z~ = C x~ = H4 y~ - b~ (the
passive output of the linear error system), which contains the unmeasured bias
error. Its measured part is H4 y~; with diagonal H4 and a componentwise sat this is
``s_i = y~_i`` with a boundary layer ``eps_i`` per axis in m, m, rad, which is what
is implemented::

    sat(y~_i / eps_i) = clip(y~_i / eps_i, -1, 1)

The vector sat of (7) (z / |z|) is not used: the three axes have different units,
so the norm of y~ mixes metres and radians. Inside the layer the term adds
Kbar_i / eps_i to H2_i; outside it is a bounded velocity injection of size Kbar_i.
With this signal, (17) keeps the dissipative -y~^T H4 Kbar sat(y~/eps) but gains a
term bounded by 2 sum_i Kbar_i |b~_i|: the result is ultimate boundedness, not the
asymptotic stability claimed (docs/reproductions.md).
"""

from __future__ import annotations

from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout.components import EARTH_FIXED, Layout, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Rule, Value, component, initial_values
from lookout.models.vessel import EARTH_AXES, VESSEL_INPUT, VESSEL_SIGNALS, DPVessel, VesselState
from lookout.observers.passive import WAVE_FILTER_EXTRAS, PassiveObserver, predict_sample
from lookout.observers.wave_filtering import WaveFilterGains, WaveFilteringObserver
from lookout.sensors import POSITION_HEADING

#: The switching term Kbar sat(y~ / eps) of eq. (6), an extra output.
SWITCHING_SIGNALS = (
    Signal("switching_position", "m/s", "switching term Kbar sat(y~/eps) of eq. (6), position", EARTH_FIXED, EARTH_AXES, "earth_axis"),
    Signal("switching_heading", "rad/s", "switching term Kbar sat(y~/eps) of eq. (6), heading", EARTH_FIXED),
)

#: The boundary layer eps of :func:`lookout.analysis.sliding_mode.kim_2002_observer` when none is given (m, m,
#: rad; lookout's choice: a few times a DGNSS fix's and a gyro's noise).
DEFAULT_BOUNDARY_LAYER = (1.0, 1.0, 0.02)


def saturation(x: ArrayLike, width: ArrayLike = 1.0) -> Array:
    """sat(x / width) of Kim (2002), eq. (7), componentwise: x / width clipped to [-1, 1].

    Continuous, odd, |sat| <= 1, and equal to sign(x) for |x| >= width.
    """
    return jnp.clip(jnp.asarray(x) / width, -1.0, 1.0)


@component(
    "observer",
    "sliding-mode",
    summary="Kim (2002) sliding-mode observer, eqs. (6)–(7): a passive observer plus Kbar sat(y~/eps).",
    family="lookout.tuning.families.sliding_mode:SlidingModeFamily",
    rules={
        "kim-2002": Rule(
            "lookout.analysis.sliding_mode:kim_2002_observer",
            (
                Part("vessel", "The observer's vessel model (M, D); in a composition, the plant's unless given."),
                Part("waves", "The sea to tune for when wave_frequency is not given (in a composition, the plant's).", from_plant=True),
                Value(
                    "wave_frequency",
                    "array",
                    "The observer's wave frequencies w_oi (rad/s); default the dominating frequency of waves.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("wave_damping", "array", "The observer's wave damping ratios zeta_i (1).", shape="(3,)", range=POSITIVE),
                Value("notch_damping", "array", "zeta_ni of the notch filter, Fossen & Strand (45) (1).", shape="(3,)", range=POSITIVE),
                Value(
                    "cutoff_frequency",
                    "array",
                    "w_ci of the low-pass filter (45), above wave_frequency (rad/s); default as the passive observer's.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value(
                    "velocity_injection_gain",
                    "array",
                    "Diagonal of H4 (N/m, N/m, N m/rad); default from the tuning rule (48) of the passive observer.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value(
                    "bias_injection_gain",
                    "array",
                    "Diagonal of H3 (N/(m s), N/(m s), N m/(rad s)); default from the tuning rule (48).",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("bias_time_constant", "array", "The observer's bias time constants T (s).", shape="(3,)", range=POSITIVE),
                Value("velocity_bandwidth", "array", "sqrt(H4_i / M_ii) of the default H4 (rad/s); default 0.1 w_o.", shape="(3,)", range=POSITIVE),
                Value(
                    "switching_gain",
                    "array",
                    "Kbar = diag(rho_i) (m/s, m/s, rad/s); zero gives the passive observer.",
                    shape="(3,)",
                    range=NON_NEGATIVE,
                ),
                Value(
                    "boundary_layer",
                    "array",
                    "eps_i (m, m, rad), the width of the saturation's linear zone; default 1 m, 1 m, 0.02 rad.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("steps_per_sample", "int", "RK4 steps of predict per sample period.", range=POSITIVE),
                Value("hold", "str", "What predict holds over a sample (as the passive observer's).", choices=("measurement", "innovation")),
            ),
        ),
        "gains": Rule(
            "from_gains",
            (
                Part("vessel", "The observer's vessel model (M, D); in a composition, the plant's unless given."),
                Value("velocity_injection_gain", "array", "Diagonal of H4 (N/m, N/m, N m/rad).", shape="(3,)", range=POSITIVE),
                Value("bias_injection_gain", "array", "Diagonal of H3 (N/(m s), N/(m s), N m/(rad s)).", shape="(3,)", range=POSITIVE),
                Part("waves", "The sea to tune for when wave_frequency is not given (in a composition, the plant's).", from_plant=True),
                Value(
                    "wave_frequency",
                    "array",
                    "The observer's wave frequencies w_oi (rad/s); default the dominating frequency of waves.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("wave_damping", "array", "The observer's wave damping ratios zeta_i (1).", shape="(3,)", range=POSITIVE),
                Value("notch_damping", "array", "zeta_ni of the notch filter, Fossen & Strand (45) (1).", shape="(3,)", range=POSITIVE),
                Value(
                    "cutoff_frequency",
                    "array",
                    "w_ci of the low-pass filter (45), above wave_frequency (rad/s); default as the passive observer's.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("bias_time_constant", "array", "The observer's bias time constants T (s).", shape="(3,)", range=POSITIVE),
                Value(
                    "switching_gain",
                    "array",
                    "Kbar = diag(rho_i) (m/s, m/s, rad/s); zero gives the passive observer.",
                    shape="(3,)",
                    range=NON_NEGATIVE,
                ),
                Value(
                    "boundary_layer",
                    "array",
                    "eps_i (m, m, rad), the width of the saturation's linear zone; default 1 m, 1 m, 0.02 rad.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("steps_per_sample", "int", "RK4 steps of predict per sample period.", range=POSITIVE),
                Value("hold", "str", "What predict holds over a sample (as the passive observer's).", choices=("measurement", "innovation")),
            ),
        ),
    },
)
@final
class SlidingModeObserver(WaveFilteringObserver):
    """Kim (2002) sliding-mode observer, eqs. (6)–(7): a passive observer plus Kbar sat(y~/eps).

    Use :func:`lookout.analysis.sliding_mode.kim_2002_observer` (H1, H2 from the wave model by Fossen & Strand (45)–(47), as
    Kim's (A.3) does, and gains verified against (14)) or :meth:`from_gains` (H3, H4 as
    given, (14) not asked: the Kim reproduction's printed (A.4),
    :func:`lookout.papers.kim_2002.printed_observer`). The state is a
    :class:`~lookout.models.VesselState` of estimates.

    Parameters
    ----------
    passive : PassiveObserver
        The observer without the switching term (gamma = 1, Kappa = H4, Lambda = H3).
    switching_gain : array_like, shape (3,)
        Kbar = diag(rho_i) >= 0 (m/s, m/s, rad/s); zero gives the passive observer.
    boundary_layer : array_like, shape (3,)
        eps_i > 0 (m, m, rad), the width of the saturation's linear zone.
    """

    passive: PassiveObserver
    switching_gain: Array
    boundary_layer: Array
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    #: what it reads (position and heading) and the applied thrust; any step dt
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    sample_period: None = eqx.field(static=True)

    def __init__(self, passive: PassiveObserver, switching_gain: npt.ArrayLike, boundary_layer: npt.ArrayLike):
        if not isinstance(passive, PassiveObserver):
            raise check.ParameterError("passive", f"passive must be a PassiveObserver; got {type(passive).__name__}")
        self.passive = passive
        self.switching_gain = jnp.asarray(check.vector("switching_gain", switching_gain))
        self.boundary_layer = jnp.asarray(check.vector("boundary_layer", boundary_layer))
        # every field set here: a field left at its class default changes how equinox
        # flattens an instance once it has been through tree_map (a stacked batch)
        self.estimate_signals, self.extra_signals = VESSEL_SIGNALS, WAVE_FILTER_EXTRAS + SWITCHING_SIGNALS
        self.measurement_layout, self.input_layout, self.sample_period = POSITION_HEADING, VESSEL_INPUT, None

    def __check_init__(self):
        check.positive("switching_gain", self.switching_gain, allow_zero=True)
        check.positive("boundary_layer", self.boundary_layer)

    @classmethod
    def from_gains(
        cls,
        vessel: DPVessel,
        *,
        velocity_injection_gain: npt.ArrayLike,
        bias_injection_gain: npt.ArrayLike,
        waves: object | None = None,
        wave_frequency: npt.ArrayLike | None = None,
        wave_damping: npt.ArrayLike = 0.1,
        notch_damping: npt.ArrayLike = 1.0,
        cutoff_frequency: npt.ArrayLike | None = None,
        bias_time_constant: npt.ArrayLike = 1000.0,
        switching_gain: npt.ArrayLike = 0.0,
        boundary_layer: npt.ArrayLike = DEFAULT_BOUNDARY_LAYER,
        steps_per_sample: int = 1,
        hold: str = "measurement",
    ) -> SlidingModeObserver:
        """Observer for ``vessel`` with the given H4 and H3 (SI) and H1, H2 from Fossen &
        Strand's (45)–(47), as (6)–(7) with gains that (14) is not asked of: Kim's
        printed (A.4), which violate it (:func:`lookout.analysis.sliding_mode.kim_2002_observer` refuses them), run as printed.

        Parameters
        ----------
        vessel : DPVessel
            The observer's vessel model (M, D); in a composition, the plant's unless given.
        velocity_injection_gain : array_like, shape (3,), positive
            Diagonal of H4 (N/m, N/m, N m/rad).
        bias_injection_gain : array_like, shape (3,), positive
            Diagonal of H3 (N/(m s), N/(m s), N m/(rad s)).
        waves : LinearWaveModel or JonswapWaves, optional
            The sea to tune for when wave_frequency is not given (in a composition, the plant's).
        wave_frequency : array_like, shape (3,), positive, optional
            The observer's wave frequencies w_oi (rad/s); default the dominating frequency of ``waves``.
        wave_damping : array_like, shape (3,), positive
            The observer's wave damping ratios zeta_i (1).
        notch_damping : array_like, shape (3,), positive
            zeta_ni of the notch filter, Fossen & Strand (45) (1).
        cutoff_frequency : array_like, shape (3,), positive, optional
            w_ci of the low-pass filter (45), above wave_frequency (rad/s); default as the passive observer's.
        bias_time_constant : array_like, shape (3,), positive
            The observer's bias time constants T (s).
        switching_gain : array_like, shape (3,), non-negative
            Kbar = diag(rho_i) (m/s, m/s, rad/s); zero gives the passive observer.
        boundary_layer : array_like, shape (3,), positive
            eps_i (m, m, rad), the width of the saturation's linear zone; default 1 m, 1 m, 0.02 rad.
        steps_per_sample : int, positive
            RK4 steps of predict per sample period.
        hold : {"measurement", "innovation"}
            What predict holds over a sample (as the passive observer's).
        """
        passive = PassiveObserver.design(
            vessel,
            waves=waves,
            wave_frequency=wave_frequency,
            wave_damping=wave_damping,
            notch_damping=notch_damping,
            cutoff_frequency=cutoff_frequency,
            velocity_injection_gain=velocity_injection_gain,
            bias_injection_gain=bias_injection_gain,
            bias_time_constant=bias_time_constant,
            lyapunov_weight=1.0,
            steps_per_sample=steps_per_sample,
            hold=hold,
        )
        return cls(passive, switching_gain, boundary_layer)

    def wave_filter_gains(self) -> WaveFilterGains:
        """The passive part's model and gains, and Kbar."""
        return self.passive.wave_filter_gains()._replace(switching_gain=self.switching_gain)

    # The gains under Kim's names ------------------------------------------------
    def gains(self) -> dict[str, np.ndarray]:
        """H1 (6x3), H2, H3, H4 (3x3) and Kbar (3x3) as matrices, SI."""
        p = self.passive
        return {
            "H1": p.wave_injection_matrix(),
            "H2": p.position_injection_matrix(),
            "H3": np.diag(np.asarray(p.bias_injection_gain)),
            "H4": np.diag(np.asarray(p.velocity_injection_gain)),
            "Kbar": np.diag(np.asarray(self.switching_gain)),
        }

    @property
    def steps_per_sample(self) -> int:
        return self.passive.steps_per_sample

    @property
    def hold(self) -> str:
        return self.passive.hold

    @initial_values(
        Value(
            "eta", "array", "Position north, east (m) and heading (rad); default the first measurement (less the guessed wave motion).", shape="(3,)"
        ),
        Value("nu", "array", "Velocity surge, sway (m/s) and yaw rate (rad/s).", shape="(3,)"),
        Value("bias", "array", "Bias forces and moment (N, N, N m).", shape="(3,)"),
        Value("wave_state", "array", "Wave-filter state [xi1, xi2] (m s, m s, rad s, m, m, rad).", shape="(6,)"),
    )
    def guess(
        self, eta: npt.ArrayLike | None = None, nu: npt.ArrayLike = 0.0, bias: npt.ArrayLike = 0.0, wave_state: npt.ArrayLike = 0.0
    ) -> VesselState:
        """An initial estimate (zeros unless given; eta the first measurement unless
        given), to pass to :meth:`init`.

        Parameters
        ----------
        eta : array_like, shape (3,), optional
            Position north, east (m) and heading (rad); default the first measurement
            (less the guessed wave motion).
        nu : array_like, shape (3,)
            Velocity surge, sway (m/s) and yaw rate (rad/s).
        bias : array_like, shape (3,)
            Bias forces and moment (N, N, N m).
        wave_state : array_like, shape (6,)
            Wave-filter state [xi1, xi2] (m s, m s, rad s, m, m, rad).
        """
        return self.passive.guess(eta, nu, bias, wave_state)

    def init(self, y0: Array, guess: VesselState) -> VesselState:
        """The estimate at t_0 is the guess, eta_hat(0) from the first measurement unless
        the guess gives it (as the passive observer's; Kim (2002) does not state it)."""
        return self.passive.init(y0, guess)

    def update(self, estimate: VesselState, t: ArrayLike, measurement: Array) -> VesselState:
        """No discrete correction: the measurement enters through (6)."""
        del t, measurement
        return estimate

    def innovation(self, estimate: VesselState, measurement: Array) -> Array:
        """y~ = y - y_hat with wrapped heading; zero on missing channels."""
        return self.passive.innovation(estimate, measurement)

    def rotation_heading(self, estimate: VesselState, measurement: Array) -> Array:
        """Heading of J(y): measured, or predicted when the heading sample is missing."""
        return self.passive.rotation_heading(estimate, measurement)

    def switching_term(self, y_tilde: Array) -> Array:
        """Kbar sat(y~ / eps) (m/s, m/s, rad/s), Earth-fixed."""
        return self.switching_gain * saturation(y_tilde, self.boundary_layer)

    def rates(self, estimate: VesselState, y_tilde: Array, heading: Array, tau: Array) -> VesselState:
        """Eq. (6): the passive observer's rates with Kbar sat(y~/eps) added to eta_hat'."""
        rates = self.passive.rates(estimate, y_tilde, heading, tau)
        return eqx.tree_at(lambda s: s.eta, rates, rates.eta + self.switching_term(y_tilde))

    def vector_field(self, t: ArrayLike, estimate: VesselState, measurement: Array, tau: Array, heading: Array | None = None) -> VesselState:
        """Right-hand side of eq. (6) for the measurement ``measurement``."""
        del t
        y_tilde = self.innovation(estimate, measurement)
        heading = self.rotation_heading(estimate, measurement) if heading is None else heading
        return self.rates(estimate, y_tilde, heading, tau)

    def predict(self, estimate: VesselState, t: ArrayLike, measurement: Array, tau: Array, dt: ArrayLike) -> VesselState:
        """One sample of (6), held as the passive observer's ``hold`` says."""
        return predict_sample(self, self.rates, estimate, t, measurement, tau, dt)

    def normalize(self, estimate: VesselState) -> VesselState:
        """Heading wrapped to [-pi, pi)."""
        return estimate.wrapped()

    def output(self, estimate: VesselState, measurement: Array) -> dict[str, Array]:
        """The passive observer's outputs and the switching term at the sample."""
        out = self.passive.output(estimate, measurement)
        switching = self.switching_term(self.innovation(estimate, measurement))
        return {**out, "switching_position": switching[:2], "switching_heading": switching[2]}
