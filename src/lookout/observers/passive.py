"""Passive nonlinear observer with wave filtering and bias estimation.

Fossen, T. I. and Strand, J. P. (1999), "Passive nonlinear observer design for
ships using Lyapunov methods", Automatica 35, 3–16. Equations (22)–(26):

    xi_hat'  = Omega xi_hat + K1 y~                                   (22)
    eta_hat' = J(y) nu_hat + K2 y~                                    (23)
    b_hat'   = -T^{-1} b_hat + (1/gamma) Lambda y~                    (24)
    M nu_hat' = -D nu_hat + J^T(y) b_hat + tau + (1/gamma) J^T(y) Kappa y~   (25)
    y_hat    = eta_hat + Gamma xi_hat,   y~ = y - y_hat              (26)

Choices made where the paper is silent or garbled (see docs/reproductions.md):

* The heading component of ``y~`` is ``ssa(y_psi - y_hat_psi)``, so the observer is
  continuous across the +-pi wrap of a gyro compass.
* J(y) is built from the measured heading; if the heading sample is missing it is
  built from the estimated heading ``y_hat_psi``.
* A missing (NaN) channel contributes zero innovation: the observer predicts.
* Between samples the continuous-time observer needs y(t), which a sampled sensor
  does not give. ``hold="measurement"`` (the default, and what the reproduction
  uses) holds y_k and J(y_k) over the sample. ``hold="innovation"`` holds the
  innovation y~_k instead, i.e. the output y(t) = y_hat(t) + y~_k, and builds J
  from that output's heading at each RK4 stage (J(y_k) at t_k): the observer's copy
  of the model then runs free between samples, so from a perfect start without
  noise or waves it reproduces the plant exactly. The two differ by O(h) in the
  observer period h: +2.3 % in RMS position error at h = 0.1 s, +0.4 % at 0.02 s
  (docs/reproductions.md).
* Gains are stated in SI. The paper's Kappa = diag(0.1, 0.1, 0.01) and
  Lambda = 0.1 Kappa of eq. (60) are read as gains of the normalized ("bis")
  model and converted by :func:`injection_gains_from_normalized`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, TypeVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec, rotate, rotate_transpose, ssa
from lookout.components import EARTH_FIXED, Layout, Signal
from lookout.declare import POSITIVE, Part, Rule, Value, component, initial_values
from lookout.models.vessel import VESSEL_INPUT, VESSEL_SIGNALS, DPVessel, VesselState
from lookout.observers.start import from_first_measurement
from lookout.observers.wave_filtering import WaveFilterGains, WaveFilteringObserver
from lookout.sensors import POSITION_HEADING
from lookout.sim.integrators import integrate_sample

#: The innovation y~ = y - y_hat (eq. 26), an extra output of the observer.
INNOVATION_SIGNALS = tuple(
    signal.renamed(signal.name.replace("measured_", "innovation_"), "innovation y - y_hat (eq. 26), " + signal.name.split("_", 1)[1])
    for signal in POSITION_HEADING.signals
)

#: The observer's extra outputs: the innovation and the predicted wave heading rate.
WAVE_FILTER_EXTRAS = INNOVATION_SIGNALS + (
    Signal("wave_heading_rate", "rad/s", "predicted rate of the wave-induced heading (wave model part)", EARTH_FIXED),
)

GRAVITY = 9.81

#: What :meth:`PassiveObserver.predict` holds over a sample period.
HOLDS = ("measurement", "innovation")

#: NumPy arrays (a design) or JAX arrays (a tuner's traced gains), the same for every argument.
_Gains = TypeVar("_Gains", np.ndarray, Array)


def notch_filter_gains(
    wave_frequency: npt.ArrayLike, wave_damping: npt.ArrayLike, notch_damping: npt.ArrayLike, cutoff_frequency: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wave-filter gains of Fossen & Strand (1999), eqs. (45)–(47).

    With these gains the position-error transfer function h0_i(s) of eq. (42)
    equals the notch shape (44)::

        k1_i = -2 (zeta_n_i - zeta_i) w_c_i / w_o_i
        k2_i =  2 (zeta_n_i - zeta_i) w_o_i
        k3_i =  w_c_i

    (eq. 45 is garbled in the extracted text; this form is the one that makes
    (42) equal (44) and reproduces K1 of eq. 59.)

    Parameters
    ----------
    wave_frequency : array_like, shape (3,)
        Dominating wave frequency w_o per DOF (rad/s).
    wave_damping : array_like, shape (3,)
        Wave model relative damping zeta.
    notch_damping : array_like, shape (3,)
        Notch damping zeta_n > zeta.
    cutoff_frequency : array_like, shape (3,)
        Filter cut-off w_c > w_o (rad/s).

    Returns
    -------
    tuple of ndarray
        ``(k1, k2, k3)``, each of shape (3,): K1 = [diag(k1); diag(k2)], K2 = diag(k3).
    """
    w_o = check.vector("wave_frequency", wave_frequency)
    zeta = check.vector("wave_damping", wave_damping)
    zeta_n = check.vector("notch_damping", notch_damping)
    w_c = check.vector("cutoff_frequency", cutoff_frequency)
    check.positive("wave_frequency", w_o)
    check.positive("wave_damping", zeta)
    check.positive("cutoff_frequency", w_c)
    if np.any(zeta_n <= zeta):
        raise check.ParameterError(
            "notch_damping", f"notch_damping must exceed wave_damping (zeta_n > zeta); got {zeta_n.tolist()} <= {zeta.tolist()}"
        )
    if np.any(w_c <= w_o):
        raise check.ParameterError(
            "cutoff_frequency",
            f"cutoff_frequency must exceed wave_frequency (w_c > w_o); got {w_c.tolist()} <= {w_o.tolist()} rad/s",
        )
    return notch_gains(w_o, zeta, zeta_n, w_c)


def notch_gains(wave_frequency: _Gains, wave_damping: _Gains, notch_damping: _Gains, cutoff_frequency: _Gains) -> tuple[_Gains, _Gains, _Gains]:
    """Eqs. (45)–(47) without the checks of :func:`notch_filter_gains`: NumPy or JAX
    arrays (a tuner differentiates through it)."""
    spread = notch_damping - wave_damping
    k1 = -2.0 * spread * cutoff_frequency / wave_frequency  # eq. (45)
    k2 = 2.0 * spread * wave_frequency  # eq. (46)
    k3 = cutoff_frequency  # eq. (47)
    return k1, k2, k3


#: The paper's cut-off w_c (rad/s) and its ratio to the wave frequency, eq. (59).
PAPER_CUTOFF_FREQUENCY = 1.1
CUTOFF_RATIO = 1.1 / 0.8976


def default_cutoff_frequency(wave_frequency: npt.ArrayLike) -> np.ndarray | np.float64:
    """A cut-off w_c for any wave frequency: ``max(1.1 rad/s, CUTOFF_RATIO * w_o)``.

    Fossen & Strand (1999) use w_c = 1.1 rad/s for w_o = 0.8976 rad/s (eq. 59), and
    keep K2 = diag(w_c) independent of w_o when K1 is gain-scheduled (Remark 2). This
    rule keeps their w_c for slower waves and, for faster ones, their ratio
    w_c / w_o = 1.1 / 0.8976 (about 1.2255), so that w_o < w_c of (48) holds for any
    wave period. With the paper's Kappa, Lambda and T, SPR then holds for wave periods
    from 3 s to 60 s; scaling w_c with w_o for slower waves too breaks SPR below
    w_o = 0.79 rad/s (periods above 7.9 s) although (48) still holds
    (docs/reproductions.md). An explicit w_c overrides it.
    """
    return np.maximum(PAPER_CUTOFF_FREQUENCY, CUTOFF_RATIO * np.asarray(wave_frequency, dtype=float))


#: The velocity loop's bandwidth sqrt(Kappa_i / M_ii) as a fraction of w_o_i, in
#: :func:`tuning_rule_gains`: Fossen & Strand's (60) on the Northern Clipper gives 0.094
#: to 0.118 (surge, sway, yaw).
VELOCITY_BANDWIDTH_RATIO = 0.1


def tuning_rule_gains(
    mass_matrix: npt.ArrayLike, wave_frequency: npt.ArrayLike, bias_time_constant: npt.ArrayLike, velocity_bandwidth: npt.ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Kappa and Lambda for a vessel of mass matrix M inside the tuning rule (48).

    Fossen & Strand (1999), eq. (48): ``1/T_i << Lambda_i / Kappa_i < w_o_i`` (their
    K3 / K4). This rule (lookout's choice) puts the ratio at the geometric middle of that
    interval, ``Lambda_i / Kappa_i = sqrt(w_o_i / T_i)``, and sizes Kappa so that the
    low-frequency loop M_ii nu' = -Kappa_i eta~ has the natural frequency
    ``velocity_bandwidth`` (default :data:`VELOCITY_BANDWIDTH_RATIO` w_o, a decade below
    the waves): ``Kappa_i = M_ii velocity_bandwidth_i^2``. On the Northern Clipper it
    gives Kappa 0.72, 1.13 and 0.88 times the paper's (60) and Lambda 0.60, 0.94 and 0.73 times.

    Parameters
    ----------
    mass_matrix : array_like, shape (3, 3)
        M (kg, kg m^2).
    wave_frequency : array_like, shape (3,)
        w_o (rad/s).
    bias_time_constant : array_like, shape (3,)
        T (s).
    velocity_bandwidth : array_like, shape (3,), optional
        The low-frequency loop's natural frequency (rad/s).

    Returns
    -------
    tuple of ndarray
        ``(Kappa, Lambda)``: N/m, N/m, N m/rad and the same per second.
    """
    w_o = check.vector("wave_frequency", wave_frequency)
    period = check.vector("bias_time_constant", bias_time_constant)
    bandwidth = VELOCITY_BANDWIDTH_RATIO * w_o if velocity_bandwidth is None else check.vector("velocity_bandwidth", velocity_bandwidth)
    check.positive("velocity_bandwidth", bandwidth)
    kappa = np.diag(np.asarray(mass_matrix, dtype=float)) * bandwidth**2
    return kappa, kappa * np.sqrt(w_o / period)


def wave_frequency_of(waves: object) -> np.ndarray:
    """The dominating frequency (rad/s, per DOF) of a plant's wave model: a linear
    model's w0, or a JONSWAP sea's spectral peak."""
    if hasattr(waves, "peak_frequency") and not callable(waves.peak_frequency):
        return check.vector("wave peak_frequency", waves.peak_frequency)
    if hasattr(waves, "mean_period"):
        from lookout.environment.jonswap import peak_frequency

        return check.vector("wave peak_frequency", float(peak_frequency(waves.mean_period)))
    raise check.ParameterError(
        "wave_frequency", f"wave_frequency: give it (the wave model {type(waves).__name__} has no dominating frequency to take)"
    )


def injection_gains_from_normalized(
    velocity_gain: npt.ArrayLike, bias_gain: npt.ArrayLike, *, mass: float, length: float, gravity: float = GRAVITY
) -> tuple[np.ndarray, np.ndarray]:
    """Convert Kappa and Lambda from the normalized ("bis") system to SI.

    The bis system scales force by m g, moment by m g L, length by L and time by
    sqrt(L/g). Kappa maps a position error (m, or rad) to a force (N, or N m) and
    Lambda maps it to a force rate, so::

        Kappa_SI  = Kappa_bis  * [m g / L, m g / L, m g L]
        Lambda_SI = Lambda_bis * [m g / L, m g / L, m g L] / sqrt(L / g)

    Parameters
    ----------
    velocity_gain, bias_gain : array_like, shape (3,)
        Diagonals of Kappa and Lambda in bis units.
    mass : float
        Vessel mass m (kg).
    length : float
        Vessel length L (m).
    gravity : float
        g (m/s^2).

    Returns
    -------
    tuple of ndarray
        ``(velocity_gain_si, bias_gain_si)``: N/m, N/m, N m/rad and the same per second.
    """
    check.positive("mass", mass)
    check.positive("length", length)
    check.positive("gravity", gravity)
    force = mass * gravity
    scale = np.array([force / length, force / length, force * length])
    time_scale = np.sqrt(length / gravity)
    velocity = check.vector("velocity_injection_gain (normalized)", velocity_gain)
    bias = check.vector("bias_injection_gain (normalized)", bias_gain)
    return velocity * scale, bias * scale / time_scale


@component(
    "observer",
    "passive",
    summary="Fossen & Strand (1999) passive observer, eqs. (22)–(26), gains in SI.",
    family="lookout.tuning.families.passive:PassiveFamily",
    rules={
        "fossen-strand-1999": Rule(
            "design",
            (
                Part("vessel", "The observer's vessel model (M, D); in a composition, the plant's unless given."),
                Part("waves", "The sea to tune for when wave_frequency is not given (in a composition, the plant's).", from_plant=True),
                Value("wave_frequency", "array", "w_o (rad/s); default the dominating frequency of waves.", shape="(3,)", range=POSITIVE),
                Value("wave_damping", "array", "zeta of the observer's wave model (1); the paper's 0.1.", shape="(3,)", range=POSITIVE),
                Value("notch_damping", "array", "zeta_ni of the notch filter, eq. (45) (1); the paper's 1.", shape="(3,)", range=POSITIVE),
                Value(
                    "cutoff_frequency",
                    "array",
                    "w_ci of the low-pass filter, eq. (45), above wave_frequency (rad/s); default max(1.1 rad/s, 1.2255 w_o), the paper's ratio.",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value(
                    "velocity_injection_gain", "array", "Kappa (N/m, N/m, N m/rad); default from the tuning rule (48).", shape="(3,)", range=POSITIVE
                ),
                Value(
                    "bias_injection_gain",
                    "array",
                    "Lambda (N/(m s), N/(m s), N m/(rad s)); default from the tuning rule (48).",
                    shape="(3,)",
                    range=POSITIVE,
                ),
                Value("bias_time_constant", "array", "T, the observer's bias time constants (s); the paper's 1000 s.", shape="(3,)", range=POSITIVE),
                Value(
                    "velocity_bandwidth", "array", "sqrt(Kappa_i / M_ii) of the default Kappa (rad/s); default 0.1 w_o.", shape="(3,)", range=POSITIVE
                ),
                Value("lyapunov_weight", "float", "gamma, the weight of the kinetic-energy term of the Lyapunov function (49) (1).", range=POSITIVE),
                Value("steps_per_sample", "int", "RK4 steps of predict per sample period.", range=POSITIVE),
                Value(
                    "hold",
                    "str",
                    "What predict holds over a sample: y_k and J(y_k) (default), or the innovation y~_k, with J from the held output y_hat + y~_k at each stage (see the module docstring).",
                    choices=("measurement", "innovation"),
                ),
            ),
        ),
        "gains": Rule(
            None,
            (
                Value("mass_matrix", "array", "The observer's model M (symmetric positive definite) and D (SI).", shape="(3, 3)"),
                Value("damping_matrix", "array", "The observer's model M (symmetric positive definite) and D (SI).", shape="(3, 3)"),
                Value("wave_frequency", "array", "The observer's wave frequencies w_oi of Omega (rad/s).", shape="(3,)", range=POSITIVE),
                Value("wave_damping", "array", "The observer's wave damping ratios zeta_i of Omega (1).", shape="(3,)", range=POSITIVE),
                Value("wave_injection_gain", "array", "Diagonals of K1: [k1_1, k1_2, k1_3, k2_1, k2_2, k2_3] (eq. 40; 1, 1/s).", shape="(6,)"),
                Value("position_injection_gain", "array", "Diagonal of K2 (1/s).", shape="(3,)", range=POSITIVE),
                Value("velocity_injection_gain", "array", "Diagonal of Kappa = K3 (N/m, N/m, N m/rad).", shape="(3,)", range=POSITIVE),
                Value("bias_injection_gain", "array", "Diagonal of Lambda = K4 (N/(m s), N/(m s), N m/(rad s)).", shape="(3,)", range=POSITIVE),
                Value("bias_time_constant", "array", "Diagonal of T, the observer's bias time constants (s).", shape="(3,)", range=POSITIVE),
                Value("lyapunov_weight", "float", "gamma, the weight of the kinetic-energy term of the Lyapunov function (49) (1).", range=POSITIVE),
                Value("steps_per_sample", "int", "RK4 steps of predict per sample period.", range=POSITIVE),
                Value(
                    "hold",
                    "str",
                    "What predict holds over a sample: y_k and J(y_k) (default), or the innovation y~_k, with J from the held output y_hat + y~_k at each stage (see the module docstring).",
                    choices=("measurement", "innovation"),
                ),
            ),
        ),
    },
)
@final
class PassiveObserver(WaveFilteringObserver):
    """Fossen & Strand (1999) passive observer, eqs. (22)–(26), gains in SI.

    Use :meth:`design` to synthesize the wave-filter gains from the wave and notch
    parameters. The state is a :class:`~lookout.models.VesselState` of estimates.
    A continuous-time observer: :meth:`update` changes nothing, :meth:`predict`
    integrates (22)–(25) over the sample with the measurement held.

    Parameters
    ----------
    mass_matrix, damping_matrix : array_like, shape (3, 3)
        The observer's model M (symmetric positive definite) and D (SI).
    wave_frequency : array_like, shape (3,), positive
        The observer's wave frequencies w_oi of Omega (rad/s).
    wave_damping : array_like, shape (3,), positive
        The observer's wave damping ratios zeta_i of Omega (1).
    wave_injection_gain : array_like, shape (6,)
        Diagonals of K1: [k1_1, k1_2, k1_3, k2_1, k2_2, k2_3] (eq. 40; 1, 1/s).
    position_injection_gain : array_like, shape (3,), positive
        Diagonal of K2 (1/s).
    velocity_injection_gain : array_like, shape (3,), positive
        Diagonal of Kappa = K3 (N/m, N/m, N m/rad).
    bias_injection_gain : array_like, shape (3,), positive
        Diagonal of Lambda = K4 (N/(m s), N/(m s), N m/(rad s)).
    bias_time_constant : array_like, shape (3,), positive
        Diagonal of T, the observer's bias time constants (s).
    lyapunov_weight : float, positive
        gamma, the weight of the kinetic-energy term of the Lyapunov function (49) (1).
    steps_per_sample : int, positive
        RK4 steps of :meth:`predict` per sample period.
    hold : {"measurement", "innovation"}
        What :meth:`predict` holds over a sample: y_k and J(y_k) (default), or the
        innovation y~_k, with J from the held output y_hat + y~_k at each stage (see
        the module docstring).
    """

    mass_matrix: Array
    damping_matrix: Array
    mass_inverse: Array
    wave_frequency: Array
    wave_damping: Array
    wave_injection_gain: Array
    position_injection_gain: Array
    velocity_injection_gain: Array
    bias_injection_gain: Array
    bias_time_constant: Array
    lyapunov_weight: Array
    steps_per_sample: int = eqx.field(static=True)
    hold: str = eqx.field(static=True)
    estimate_signals: tuple[Signal, ...] = eqx.field(static=True)
    extra_signals: tuple[Signal, ...] = eqx.field(static=True)
    #: what it reads (position and heading) and the applied thrust; any step dt
    measurement_layout: Layout = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    sample_period: None = eqx.field(static=True)

    def __init__(
        self,
        mass_matrix: npt.ArrayLike,
        damping_matrix: npt.ArrayLike,
        wave_frequency: npt.ArrayLike,
        wave_damping: npt.ArrayLike,
        wave_injection_gain: npt.ArrayLike,
        position_injection_gain: npt.ArrayLike,
        velocity_injection_gain: npt.ArrayLike,
        bias_injection_gain: npt.ArrayLike,
        bias_time_constant: npt.ArrayLike,
        lyapunov_weight: ArrayLike = 1.0,
        steps_per_sample: int = 1,
        hold: str = "measurement",
    ):
        check.symmetric_positive_definite("mass_matrix", mass_matrix, size=3)
        check.square("damping_matrix", damping_matrix)
        self.mass_matrix = jnp.asarray(mass_matrix, dtype=float)
        self.damping_matrix = jnp.asarray(damping_matrix, dtype=float)
        self.mass_inverse = jnp.linalg.inv(self.mass_matrix)
        self.wave_frequency = jnp.asarray(check.vector("wave_frequency", wave_frequency))
        self.wave_damping = jnp.asarray(check.vector("wave_damping", wave_damping))
        self.wave_injection_gain = jnp.asarray(check.vector("wave_injection_gain", wave_injection_gain, 6))
        self.position_injection_gain = jnp.asarray(check.vector("position_injection_gain", position_injection_gain))
        self.velocity_injection_gain = jnp.asarray(check.vector("velocity_injection_gain", velocity_injection_gain))
        self.bias_injection_gain = jnp.asarray(check.vector("bias_injection_gain", bias_injection_gain))
        self.bias_time_constant = jnp.asarray(check.vector("bias_time_constant", bias_time_constant))
        self.lyapunov_weight = jnp.asarray(lyapunov_weight, dtype=float)
        if not (isinstance(steps_per_sample, int) and steps_per_sample >= 1):
            raise check.ParameterError("steps_per_sample", f"steps_per_sample must be a positive integer; got {steps_per_sample!r}")
        self.steps_per_sample = steps_per_sample
        if hold not in HOLDS:
            raise check.ParameterError("hold", f"hold must be one of {', '.join(map(repr, HOLDS))}; got {hold!r}")
        self.hold = hold
        self.estimate_signals = VESSEL_SIGNALS
        self.extra_signals = WAVE_FILTER_EXTRAS
        self.measurement_layout, self.input_layout, self.sample_period = POSITION_HEADING, VESSEL_INPUT, None

    def __check_init__(self):
        check.positive("wave_frequency", self.wave_frequency)
        check.positive("wave_damping", self.wave_damping)
        check.finite("wave_injection_gain", self.wave_injection_gain)
        check.positive("position_injection_gain", self.position_injection_gain)
        check.positive("velocity_injection_gain", self.velocity_injection_gain)
        check.positive("bias_injection_gain", self.bias_injection_gain)
        check.positive("bias_time_constant", self.bias_time_constant)
        check.positive("lyapunov_weight", self.lyapunov_weight)

    @classmethod
    def design(
        cls,
        vessel: DPVessel,
        *,
        waves: object | None = None,
        wave_frequency: npt.ArrayLike | None = None,
        wave_damping: npt.ArrayLike = 0.1,
        notch_damping: npt.ArrayLike = 1.0,
        cutoff_frequency: npt.ArrayLike | None = None,
        velocity_injection_gain: npt.ArrayLike | None = None,
        bias_injection_gain: npt.ArrayLike | None = None,
        bias_time_constant: npt.ArrayLike = 1000.0,
        velocity_bandwidth: npt.ArrayLike | None = None,
        lyapunov_weight: ArrayLike = 1.0,
        steps_per_sample: int = 1,
        hold: str = "measurement",
    ) -> PassiveObserver:
        """Observer for ``vessel`` with K1, K2 from eqs. (45)–(47) and, unless given,
        Kappa and Lambda inside the tuning rule (48) (:func:`tuning_rule_gains`).

        The defaults are the paper's choices of Section 6.1 (zeta = 0.1, zeta_n = 1,
        T = 1000 s) and rules for the rest, so that ``kind = "passive"`` alone gives an
        observer for any DP vessel model.

        Parameters
        ----------
        vessel : DPVessel
            The observer's vessel model (M, D); in a composition, the plant's unless given.
        waves : LinearWaveModel or JonswapWaves, optional
            The sea to tune for when wave_frequency is not given (in a composition, the plant's).
        wave_frequency : array_like, shape (3,), positive, optional
            w_o (rad/s); default the dominating frequency of ``waves``.
        wave_damping : array_like, shape (3,), positive
            zeta of the observer's wave model (1); the paper's 0.1.
        notch_damping : array_like, shape (3,), positive
            zeta_ni of the notch filter, eq. (45) (1); the paper's 1.
        cutoff_frequency : array_like, shape (3,), positive, optional
            w_ci of the low-pass filter, eq. (45), above wave_frequency (rad/s); default
            max(1.1 rad/s, 1.2255 w_o), the paper's ratio.
        velocity_injection_gain : array_like, shape (3,), positive, optional
            Kappa (N/m, N/m, N m/rad); default from the tuning rule (48).
        bias_injection_gain : array_like, shape (3,), positive, optional
            Lambda (N/(m s), N/(m s), N m/(rad s)); default from the tuning rule (48).
        bias_time_constant : array_like, shape (3,), positive
            T, the observer's bias time constants (s); the paper's 1000 s.
        velocity_bandwidth : array_like, shape (3,), positive, optional
            sqrt(Kappa_i / M_ii) of the default Kappa (rad/s); default 0.1 w_o.
        """
        if wave_frequency is None:
            if waves is None:
                raise check.ParameterError("wave_frequency", "wave_frequency: give it (there is no wave model to take it from)")
            wave_frequency = wave_frequency_of(waves)
        if cutoff_frequency is None:
            cutoff_frequency = default_cutoff_frequency(check.vector("wave_frequency", wave_frequency))
        if velocity_injection_gain is None or bias_injection_gain is None:
            kappa, lam = tuning_rule_gains(vessel.mass_matrix, wave_frequency, bias_time_constant, velocity_bandwidth)
            velocity_injection_gain = kappa if velocity_injection_gain is None else velocity_injection_gain
            bias_injection_gain = lam if bias_injection_gain is None else bias_injection_gain
        k1, k2, k3 = notch_filter_gains(wave_frequency, wave_damping, notch_damping, cutoff_frequency)
        return cls(
            vessel.mass_matrix,
            vessel.damping_matrix,
            wave_frequency=wave_frequency,
            wave_damping=wave_damping,
            wave_injection_gain=np.concatenate([k1, k2]),
            position_injection_gain=k3,
            velocity_injection_gain=velocity_injection_gain,
            bias_injection_gain=bias_injection_gain,
            bias_time_constant=bias_time_constant,
            lyapunov_weight=lyapunov_weight,
            steps_per_sample=steps_per_sample,
            hold=hold,
        )

    def wave_filter_gains(self) -> WaveFilterGains:
        """M, D, the wave model, K2 and Kappa / gamma; no switching term."""
        return WaveFilterGains(
            self.mass_matrix,
            self.damping_matrix,
            self.wave_frequency,
            self.wave_damping,
            self.position_injection_gain,
            self.velocity_injection_gain / self.lyapunov_weight,
            jnp.zeros(3),
        )

    def wave_injection_matrix(self) -> np.ndarray:
        """K1 as the 6x3 matrix of eq. (40)."""
        gains = np.asarray(self.wave_injection_gain)
        return np.vstack([np.diag(gains[:3]), np.diag(gains[3:])])

    def position_injection_matrix(self) -> np.ndarray:
        """K2 as the 3x3 matrix of eq. (41)."""
        return np.diag(np.asarray(self.position_injection_gain))

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
        return VesselState.build(eta, nu, bias, wave_state)

    def init(self, y0: Array, guess: VesselState) -> VesselState:
        """The estimate at t_0 is the guess, with eta_hat(0) = y_0 - eta_w_hat(0) (eq. 12
        without noise) where the guess leaves eta to the first measurement
        (:mod:`lookout.observers.start`). Fossen & Strand (1999) do not state eta_hat(0)."""
        measured = jnp.asarray(y0, dtype=float) - guess.wave
        return eqx.tree_at(lambda s: s.eta, guess, from_first_measurement(guess.eta, measured, angles=(2,)))

    def update(self, estimate: VesselState, t: ArrayLike, measurement: Array) -> VesselState:
        """No discrete correction: the measurement enters through (22)–(25)."""
        del t, measurement
        return estimate

    def innovation(self, estimate: VesselState, measurement: Array) -> Array:
        """y~ = y - y_hat (eq. 26) with wrapped heading; zero on missing channels."""
        predicted = estimate.eta + estimate.wave
        error = measurement - predicted
        error = error.at[2].set(ssa(error[2]))
        return jnp.where(jnp.isfinite(measurement), error, 0.0)

    def normalize(self, estimate: VesselState) -> VesselState:
        """Heading wrapped to [-pi, pi) (after a joint integration with the plant)."""
        return estimate.wrapped()

    def rotation_heading(self, estimate: VesselState, measurement: Array) -> Array:
        """Heading of J(y) in eqs. (23), (25): the measured one, or the predicted
        ``psi_hat + psi_hat_w`` when the heading sample is missing."""
        return jnp.where(jnp.isfinite(measurement[2]), measurement[2], estimate.eta[2] + estimate.wave[2])

    def vector_field(self, t: ArrayLike, estimate: VesselState, measurement: Array, tau: Array, heading: Array | None = None) -> VesselState:
        """Right-hand side of eqs. (22)–(25) for a measurement held at ``measurement``.

        ``heading`` is the heading of J(y); by default :meth:`rotation_heading` of
        ``estimate`` (what the continuous-time observer uses).
        """
        del t
        y_tilde = self.innovation(estimate, measurement)
        heading = self.rotation_heading(estimate, measurement) if heading is None else heading
        return self.rates(estimate, y_tilde, heading, tau)

    def rates(self, estimate: VesselState, y_tilde: Array, heading: Array, tau: Array) -> VesselState:
        """Eqs. (22)–(25) for a given innovation y~ and heading of J(y)."""
        xi1, xi2 = estimate.wave_state[:3], estimate.wave_state[3:]
        w0, zeta, k = self.wave_frequency, self.wave_damping, self.wave_injection_gain
        # Fossen & Strand (1999), eq. (22), Omega of eq. (11), K1 of eq. (40)
        wave_rate = jnp.concatenate([xi2 + k[:3] * y_tilde, -(w0**2) * xi1 - 2.0 * zeta * w0 * xi2 + k[3:] * y_tilde])
        # eq. (23)
        eta_rate = rotate(heading, estimate.nu) + self.position_injection_gain * y_tilde
        inv_gamma = 1.0 / self.lyapunov_weight
        # eq. (24)
        bias_rate = -estimate.bias / self.bias_time_constant + inv_gamma * self.bias_injection_gain * y_tilde
        # eq. (25)
        force = (
            -matvec(self.damping_matrix, estimate.nu)
            + rotate_transpose(heading, estimate.bias + inv_gamma * self.velocity_injection_gain * y_tilde)
            + tau
        )
        return VesselState(eta=eta_rate, nu=matvec(self.mass_inverse, force), bias=bias_rate, wave_state=wave_rate)

    def predict(self, estimate: VesselState, t: ArrayLike, measurement: Array, tau: Array, dt: ArrayLike) -> VesselState:
        """Advance the estimate over one sample period with tau held.

        Integrates (22)–(25) by ``steps_per_sample`` RK4 steps of ``dt /
        steps_per_sample`` and wraps the heading of the result. With
        ``hold="measurement"``, ``measurement`` and the heading of J(y)
        (:meth:`rotation_heading` at ``t``) are held over the sample; with
        ``hold="innovation"``, the innovation at ``t`` is held and J is built from
        the heading of y_hat + y~ at each stage.
        """
        return predict_sample(self, self.rates, estimate, t, measurement, tau, dt)

    def output(self, estimate: VesselState, measurement: Array) -> dict[str, Array]:
        """The estimate as named quantities, the innovation y~ at the sample, and the
        predicted wave heading rate (what a controller needs for dJ(y)/dt)."""
        innovation = self.innovation(estimate, measurement)
        return {
            **estimate.signals(),
            "innovation_position": innovation[:2],
            "innovation_heading": innovation[2],
            "wave_heading_rate": wave_heading_rate(estimate, self.wave_frequency, self.wave_damping),
        }


def wave_heading_rate(estimate: VesselState, wave_frequency: Array, wave_damping: Array) -> Array:
    """The wave model's part of d(psi_w)/dt = d(xi_6)/dt: -w_3^2 xi_3 - 2 zeta_3 w_3 xi_6.

    Kim (2002), eq. (22), reads J'(y) = J(y) S(mu) with mu = [0, 0, r + psi_w']; the
    observer backstepping controller needs the estimate of psi_w', which this gives
    without the injection term (derivations-kim-calugi-2003.md, K3).
    """
    w3, zeta3 = wave_frequency[2], wave_damping[2]
    return -(w3**2) * estimate.wave_state[2] - 2.0 * zeta3 * w3 * estimate.wave_state[5]


class _SampledObserver(Protocol):
    """What :func:`predict_sample` reads of a wave-filtering vessel observer (the passive
    and the sliding-mode observers)."""

    @property
    def hold(self) -> str: ...

    @property
    def steps_per_sample(self) -> int: ...

    def innovation(self, estimate: VesselState, measurement: Array) -> Array: ...

    def rotation_heading(self, estimate: VesselState, measurement: Array) -> Array: ...

    def normalize(self, estimate: VesselState) -> VesselState: ...


def predict_sample(
    observer: _SampledObserver,
    rates: Callable[[VesselState, Array, Array, Array], VesselState],
    estimate: VesselState,
    t: ArrayLike,
    measurement: Array,
    tau: Array,
    dt: ArrayLike,
) -> VesselState:
    """One sample of a wave-filtering vessel observer: ``observer.steps_per_sample`` RK4
    steps of ``rates(estimate, y_tilde, heading, tau)`` with what ``observer.hold``
    says held (see :meth:`PassiveObserver.predict`); the heading of the result wrapped.

    Shared by the passive observer and the sliding-mode observer of Kim (2002), which
    adds its switching term to the passive observer's rates.
    """
    if observer.hold == "innovation":
        y_tilde = observer.innovation(estimate, measurement)

        def field(time, x):
            del time
            # J(y) of the held output y = y_hat + y~_k: the paper's J(y_k) at t_k
            return rates(x, y_tilde, x.eta[2] + x.wave[2] + y_tilde[2], tau)

    else:
        # J(y) held over the sample like y itself: with the heading missing, the
        # predicted heading at t (not at each RK4 stage) stands in for the sample
        heading = observer.rotation_heading(estimate, measurement)

        def field(time, x):
            del time
            return rates(x, observer.innovation(x, measurement), heading, tau)

    return integrate_sample(field, t, estimate, dt, observer.steps_per_sample, normalize=observer.normalize)
