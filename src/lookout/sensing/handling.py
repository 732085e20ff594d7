"""Position-reference handling as a DP system does it: each reference tested, rejected
when it fails, reinstated when it has recovered, and the accepted ones weighted
(``[references] kind = "dp-class"``; docs/failures.md).

The families of tests are those of the guidance for DP systems: IMO MSC/Circ.645
(Guidelines for vessels with dynamic positioning systems) and MSC.1/Circ.1580 ask that
the position references be monitored and a failed one rejected, and IMCA M 252
(Guidance on position reference systems and sensors for DP operations) and the class
rules (DNV) name the tests a DP system runs on them: freeze, variance, prediction,
median (divergence) and slow drift, with rejection and reinstatement by the system and
a weighting of the accepted references. The guidance says what to test, not with
which numbers: every threshold here is lookout's own, a parameter whose default and
its reason :class:`ReferenceHandler` gives.

At each sample where a position reference has a new fix, each reference is taken
back to the vessel's reference point with the combined heading (as
:class:`~lookout.sensing.combining.WeightedMean` does), and:

* a **tracker** of the reference point predicts where the fixes should be: a
  constant-velocity Kalman filter per axis, driven by a white acceleration of
  spectral density ``tracker_acceleration`` and fed by the accepted references' new
  fixes. A DP system tests a reference against its DP model's prediction; this stage
  runs inside the sensor suite, before any observer, and does not see one. Its own
  kinematic tracker keeps its output a measurement, the same whichever observer reads
  it, with no loop through the observer.
* a reference's **innovation** is its point less the tracker's prediction at the
  fix, before any fix of the step is fed. Every fix is compared at its own instant, so
  the references' rates and the vessel's motion between their fixes do not enter the
  tests that compare references with each other.
* **freeze**: its last ``freeze_samples`` samples each within ``freeze_tolerance``
  of the one before (the samples themselves, before the lever arm is taken back).
* **variance**: the mean square of its innovations over an exponential window of
  ``variance_samples`` fixes, less the tracker's predicted variance and less the
  excess that every reference shows (the median over the accepted ones: the tracker's
  own error, in a sea heavier than its model), against the variance it states for the
  fix (:meth:`~lookout.sensing.position.PositionReference.std_at`: a hydroacoustic
  reference's at the fix's slant range, the others' the same for every fix): it fails when the
  estimated standard deviation exceeds ``noise_factor`` times the stated one.
* **prediction**: the innovation's Mahalanobis distance ``|nu| / sqrt(P + e + R)``
  (P the tracker's predicted variance, e the common excess, R the stated variance),
  beyond ``prediction_gate``. A fix beyond the gate enters the variance window cut back
  to the gate and the drift fit not at all.
* **divergence**: the distance of its low-passed innovation (an exponential window of
  ``divergence_samples`` fixes) from the median of the other accepted references',
  beyond ``divergence_limit``.
* **drift**: the rate of its innovation (an exponentially weighted linear fit with
  time constant ``drift_window``, started from a healthy history) less the other
  accepted references' weighted mean rate, beyond ``drift_limit``; the tracker's own
  motion is common to every reference and cancels.
* a reference with no sample (NaN: a dropout) is rejected at once (reason 6).

Which test may reject. Of the accepted references that fail a test, at most one is
rejected per step (the single-failure assumption): the one whose statistic is the
furthest beyond its threshold, relative to it, with that test as the reason. Freeze
rejects always; prediction only while another accepted reference passes it (when all
fail, the tracker is what is wrong) and once the tracker has had a variance window of
fixes; variance, divergence and drift compare a reference with the others and reject
only with three or more accepted: with two, which one is wrong cannot be told, and
the stage raises ``references.position_alarm`` instead. A rejected reference keeps
being tested and is reinstated when its tests have passed for ``healthy_time``
seconds without a break. With every reference rejected the stage starts over: its
tracker waits for a first fix again.

The combined position is the weighted mean of the accepted references, each weighted
by the inverse of its estimated variance (the variance test's, floored by the stated
one) with three or more accepted, by its stated variance with two (each one's
innovations then show the two's disagreement as much as its noise).

The gyrocompasses: the heading is the circular median of the accepted ones
(:func:`~lookout.sensing.combining.circular_median`); each is tested for freeze
(``heading_freeze_tolerance``) and for its distance from the median of the other
accepted ones, beyond ``heading_divergence_limit``: rejected with three or more
accepted, ``references.heading_alarm`` with two. Missing samples, at most one
rejection per step and reinstatement as for the position references.

Recorded, after ``measured_position`` and ``measured_heading``, for each position
reference ``NAME`` (in the order of the names): ``NAME.accepted`` (1 accepted, 0
rejected), ``NAME.rejected_by`` (the reason, :data:`REASONS`), ``NAME.weight`` (its
share of the combined position), and the tests' statistics ``NAME.repeated_samples``,
``NAME.noise_ratio``, ``NAME.prediction_distance``, ``NAME.divergence`` (m) and
``NAME.drift_rate`` (m/s); for each gyrocompass its ``accepted``, ``rejected_by``,
``repeated_samples`` and ``divergence`` (rad); then ``references.position_alarm`` and
``references.heading_alarm``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple, final

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import ssa
from lookout.components import Signal
from lookout.declare import POSITIVE, Value, component
from lookout.sensing.combining import COMBINED_HEADING, COMBINED_POSITION, CombiningStage, circular_median
from lookout.sensing.heading import Gyrocompass
from lookout.sensing.instrument import HEADING, POSITION, Instrument
from lookout.sensing.position import PositionReference

#: The reason a reference is rejected (``NAME.rejected_by``), by code.
REASONS = {0: "none", 1: "freeze", 2: "variance", 3: "prediction", 4: "divergence", 5: "drift", 6: "missing"}
FREEZE, VARIANCE, PREDICTION, DIVERGENCE, DRIFT, MISSING = 1, 2, 3, 4, 5, 6

#: The tracker's initial velocity standard deviation (m/s): the vessel's speed is not
#: known at the first fix; 2 m/s covers a DP vessel's and its wave motion's, and the
#: first fixes correct it within seconds.
INITIAL_SPEED_STD = 2.0

_VARIANCE_FLOOR = 1e-12  # m^2: a reference stated noise-free still divides by something


class Tracker(NamedTuple):
    """The stage's constant-velocity Kalman filter of the reference point, per axis
    (north, east alike: every reference's noise is stated per axis, the same in both)."""

    position: Array  # (2,) m
    velocity: Array  # (2,) m/s
    covariance: Array  # (2, 2) of [position, velocity], each axis's
    time: Array  # s, of its last step
    started: Array  # bool: it has had a fix
    fed: Array  # steps it has been fed a fix at since it started


class PositionTests(NamedTuple):
    """Each position reference's state and its tests' memories (one row per reference)."""

    accepted: Array  # (N,) bool
    rejected_by: Array  # (N,) reason code
    healthy: Array  # (N,) bool: its tests pass
    healthy_since: Array  # (N,) s: since when (0 while a test fails)
    seen: Array  # (N,) bool: it has given a sample
    last_sample: Array  # (N, 2) its last finite sample, for the freeze test (0 before one)
    repeats: Array  # (N,) samples in a row within the tolerance of the one before
    fitted: Array  # (N,) bool: its drift fit has had a fix
    last_time: Array  # (N,) s of the drift fit's last fix (0 before one)
    prediction: Array  # (N,) Mahalanobis distance at its last fix
    mean: Array  # (N, 2) low-passed innovation (divergence test)
    variance: Array  # (N,) windowed mean square of the innovation about its low-passed value, per axis
    prediction_variance: Array  # (N,) the tracker's position variance, windowed alike
    moments: Array  # (N, 3) weighted sums of 1, tau, tau^2 (tau: time from its last fix)
    products: Array  # (N, 2, 2) weighted sums of nu and tau nu (the drift fit)


class HeadingTests(NamedTuple):
    """Each gyrocompass's state and its freeze test's memory."""

    accepted: Array
    rejected_by: Array
    healthy: Array
    healthy_since: Array
    seen: Array
    last_sample: Array
    repeats: Array


class HandlerMemory(NamedTuple):
    """The stage's memory: the position references', the tracker's, the gyrocompasses'."""

    positions: PositionTests
    tracker: Tracker
    headings: HeadingTests


def _positive(name: str, value: float) -> Array:
    number = float(value)
    if not (math.isfinite(number) and number > 0):
        raise check.ParameterError(name, f"{name} must be a finite number > 0; got {value}")
    return jnp.asarray(number)


def _count(name: str, value: float) -> Array:
    number = float(value)
    if not (math.isfinite(number) and number >= 1 and number == round(number)):
        raise check.ParameterError(name, f"{name} must be a whole number >= 1; got {value}")
    return jnp.asarray(number)


@component(
    "references",
    "dp-class",
    summary="Position-reference handling as a DP system does it: freeze, variance, prediction, divergence and drift tests, rejection and reinstatement, the accepted references weighted; the gyrocompasses voted.",
    parameters=(
        Value(
            "freeze_samples",
            "int",
            "Samples in a row, each within the freeze tolerance of the one before, that make a reference frozen.",
            range=POSITIVE,
        ),
        Value("freeze_tolerance", "float", "Change of a position sample (m, per axis) within which it counts as unchanged.", range=POSITIVE),
        Value("heading_freeze_tolerance", "float", "Change of a gyrocompass sample (rad) within which it counts as unchanged.", range=POSITIVE),
        Value(
            "noise_factor", "float", "Estimated over stated standard deviation beyond which a reference is too noisy (variance test).", range=POSITIVE
        ),
        Value("variance_samples", "int", "Fixes in the exponential window of the variance test.", range=POSITIVE),
        Value(
            "prediction_gate",
            "float",
            "Mahalanobis distance of a fix from the tracker's prediction beyond which it fails (prediction test).",
            range=POSITIVE,
        ),
        Value(
            "tracker_acceleration",
            "float",
            "Spectral density of the white acceleration that drives the tracker (m^2/s^3).",
            range=POSITIVE,
        ),
        Value("divergence_limit", "float", "Distance from the median of the other references beyond which a reference diverges (m).", range=POSITIVE),
        Value(
            "divergence_samples", "int", "Fixes in the exponential window that low-passes each innovation for the divergence test.", range=POSITIVE
        ),
        Value("drift_limit", "float", "Rate of a reference's difference from the others beyond which it drifts (m/s).", range=POSITIVE),
        Value("drift_window", "float", "Time constant of the exponentially weighted linear fit of the drift test (s).", range=POSITIVE),
        Value("healthy_time", "float", "Time a rejected reference's tests must pass without a break before it is reinstated (s).", range=POSITIVE),
        Value(
            "heading_divergence_limit",
            "float",
            "Distance of a gyrocompass from the median of the others beyond which it diverges (rad).",
            range=POSITIVE,
        ),
    ),
)
@final
class ReferenceHandler(CombiningStage):
    """Position-reference handling of a DP class (the module docstring: the tests, the
    tracker, rejection and reinstatement, what is recorded).

    The test families come from IMO MSC/Circ.645, MSC.1/Circ.1580 and IMCA M 252; the
    thresholds are lookout's, each a parameter (an array: a campaign sweeps it without
    compiling again) with the reason for its default below. The defaults are sized for
    the references of a DP vessel (DGNSS of 0.5 to 1 m, a hydroacoustic reference of
    about 1 m at 1 to 2 s) in a sea that moves the vessel by about a metre; a heavier
    sea wants a larger ``tracker_acceleration``.

    Parameters
    ----------
    freeze_samples : int, positive
        Samples in a row, each within the freeze tolerance of the one before, that make a
        reference frozen. The default, 10 (10 s of a 1 Hz DGNSS, 1 s of a 10 Hz
        gyrocompass): a reference with any noise never repeats itself ten times, and a
        frozen one is out within its tenth sample.
    freeze_tolerance : float, positive
        Change of a position sample (m, per axis) within which it counts as unchanged. The
        default, 1e-6 m: far below any reference's noise (centimetres at best) and above the
        rounding of a held value.
    heading_freeze_tolerance : float, positive
        Change of a gyrocompass sample (rad) within which it counts as unchanged. The
        default, 1e-6 rad: below a gyrocompass's noise. A gyrocompass whose output is
        quantized (0.1 deg in an HDT sentence) repeats itself at rest: raise it, or
        ``freeze_samples``, for one.
    noise_factor : float, positive
        Estimated over stated standard deviation beyond which a reference is too noisy
        (variance test). The default, 3: a healthy reference's ratio stays below 1.6 in a
        sea that moves the vessel by a metre (docs/failures.md), and one whose noise has
        tripled is out.
    variance_samples : int, positive
        Fixes in the exponential window of the variance test. The default, 20 (20 s of a 1
        Hz reference): long enough for a steady estimate, short enough to follow a noise
        that grows within a minute.
    prediction_gate : float, positive
        Mahalanobis distance of a fix from the tracker's prediction beyond which it fails
        (prediction test). The default, 5: for a Gaussian innovation of two axes a false
        rejection once in exp(12.5), 2.7e5, fixes (healthy fixes stay below 4.3 in a sea of
        a metre); a jump of five standard deviations of the innovation (about 7 m for a 1 m
        reference) is out at its first fix.
    tracker_acceleration : float, positive
        Spectral density of the white acceleration that drives the tracker (m^2/s^3). The
        default, 0.5: its prediction over a second allows for the wave motion of a sea that
        moves the vessel by a metre (3 sigma) at a 7 s period. A heavier sea's further error
        is common to every reference: the stage estimates it (the variance test's common
        excess) and widens the gate by it.
    divergence_limit : float, positive
        Distance from the median of the other references beyond which a reference diverges
        (m). The default, 5 m: twice the largest distance a healthy suite of 1 m references
        shows in a sea of a metre (2.6 m), and half a 10 m jump.
    divergence_samples : int, positive
        Fixes in the exponential window that low-passes each innovation for the divergence
        test. The default, 5: the difference's noise down by a factor of three, and a jump
        past the limit seen within three fixes.
    drift_limit : float, positive
        Rate of a reference's difference from the others beyond which it drifts (m/s). The
        default, 0.02 m/s: twice the largest rate a healthy suite shows (0.011 m/s; a
        DGNSS's Gauss-Markov error of 0.5 m and 5 min wanders at a few mm/s), and a drift of
        0.05 m/s is out within 90 s (docs/failures.md).
    drift_window : float, positive
        Time constant of the exponentially weighted linear fit of the drift test (s). The
        default, 60 s: the fit's rate of healthy fixes of 1 m at 1 Hz scatters by a few
        mm/s. The fit starts from a steady history of healthy fixes, so the test runs from
        the first fix.
    healthy_time : float, positive
        Time a rejected reference's tests must pass without a break before it is reinstated
        (s). The default, 30 s: three freeze windows and more than one variance window of a
        1 Hz reference; a reference that flickers stays out.
    heading_divergence_limit : float, positive
        Distance of a gyrocompass from the median of the others beyond which it diverges
        (rad). The default, 0.0175 (1 deg): five standard deviations of the difference of
        two gyrocompasses of 0.1 deg white noise and 0.1 deg slow error, and a heading error
        that moves an antenna 30 m away by half a metre.
    """

    freeze_samples: Array
    freeze_tolerance: Array
    heading_freeze_tolerance: Array
    noise_factor: Array
    variance_samples: Array
    prediction_gate: Array
    tracker_acceleration: Array
    divergence_limit: Array
    divergence_samples: Array
    drift_limit: Array
    drift_window: Array
    healthy_time: Array
    heading_divergence_limit: Array

    def __init__(
        self,
        freeze_samples: int = 10,
        freeze_tolerance: float = 1e-6,
        heading_freeze_tolerance: float = 1e-6,
        noise_factor: float = 3.0,
        variance_samples: int = 20,
        prediction_gate: float = 5.0,
        tracker_acceleration: float = 0.5,
        divergence_limit: float = 5.0,
        divergence_samples: int = 5,
        drift_limit: float = 0.02,
        drift_window: float = 60.0,
        healthy_time: float = 30.0,
        heading_divergence_limit: float = 0.0175,
    ):
        self.freeze_samples = _count("freeze_samples", freeze_samples)
        self.freeze_tolerance = _positive("freeze_tolerance", freeze_tolerance)
        self.heading_freeze_tolerance = _positive("heading_freeze_tolerance", heading_freeze_tolerance)
        self.noise_factor = _positive("noise_factor", noise_factor)
        self.variance_samples = _count("variance_samples", variance_samples)
        self.prediction_gate = _positive("prediction_gate", prediction_gate)
        self.tracker_acceleration = _positive("tracker_acceleration", tracker_acceleration)
        self.divergence_limit = _positive("divergence_limit", divergence_limit)
        self.divergence_samples = _count("divergence_samples", divergence_samples)
        self.drift_limit = _positive("drift_limit", drift_limit)
        self.drift_window = _positive("drift_window", drift_window)
        self.healthy_time = _positive("healthy_time", healthy_time)
        self.heading_divergence_limit = _positive("heading_divergence_limit", heading_divergence_limit)

    # ------------------------------------------------------------------ layout

    def signals(self, instruments: Sequence[Instrument], names: Sequence[str] = ()) -> tuple[Signal, ...]:
        """``measured_position`` (with a position reference and a gyrocompass),
        ``measured_heading`` (with a gyrocompass), then each reference's state and
        statistics and the two alarms (module docstring); names default to
        ``reference1``, ``reference2``, ..."""
        return tuple(signal for signal, _ in self._layout(instruments, names))

    def sources(self, instruments: Sequence[Instrument], names: Sequence[str] = ()) -> tuple[str, ...]:
        return tuple(source for _, source in self._layout(instruments, names))

    def _layout(self, instruments: Sequence[Instrument], names: Sequence[str]) -> list[tuple[Signal, str]]:
        names = tuple(names) or tuple(f"reference{i + 1}" for i in range(len(instruments)))
        gyros = [isinstance(each, Gyrocompass) for each in instruments]
        if not any(gyros):
            return []
        positions = any(isinstance(each, PositionReference) for each in instruments)
        layout: list[tuple[Signal, str]] = [(COMBINED_POSITION, POSITION)] if positions else []
        layout.append((COMBINED_HEADING, HEADING))
        for name, each in zip(names, instruments):
            if isinstance(each, PositionReference):
                layout += [(signal, POSITION) for signal in _position_signals(name)]
            elif isinstance(each, Gyrocompass):
                layout += [(signal, HEADING) for signal in _heading_signals(name)]
        if positions:
            layout.append(
                (
                    Signal("references.position_alarm", "1", "two accepted position references disagree (variance, divergence or drift): 1, else 0"),
                    POSITION,
                )
            )
        layout.append(
            (Signal("references.heading_alarm", "1", "two accepted gyrocompasses disagree beyond the divergence limit: 1, else 0"), HEADING)
        )
        return layout

    # ------------------------------------------------------------------ memory

    def initial_memory(self, instruments: Sequence[Instrument]) -> HandlerMemory:
        """Every reference accepted (as a DP operator selects them), no window filled,
        the tracker waiting for its first fix."""
        references = [each for each in instruments if isinstance(each, PositionReference)]
        n, g = len(references), sum(isinstance(each, Gyrocompass) for each in instruments)
        stated = _stated_variance(references)
        positions = PositionTests(
            accepted=jnp.ones(n, dtype=bool),
            rejected_by=jnp.zeros(n),
            healthy=jnp.zeros(n, dtype=bool),
            healthy_since=jnp.zeros(n),
            seen=jnp.zeros(n, dtype=bool),
            last_sample=jnp.zeros((n, 2)),
            repeats=jnp.zeros(n),
            fitted=jnp.zeros(n, dtype=bool),
            last_time=jnp.zeros(n),
            prediction=jnp.zeros(n),
            mean=jnp.zeros((n, 2)),
            # the windows start full of healthy fixes: the stated variance, and no drift
            variance=stated,
            prediction_variance=jnp.zeros(n),
            moments=jnp.stack([self._healthy_history(each.sample_period) for each in references]) if references else jnp.zeros((0, 3)),
            products=jnp.zeros((n, 2, 2)),
        )
        tracker = Tracker(jnp.zeros(2), jnp.zeros(2), jnp.zeros((2, 2)), jnp.asarray(0.0), jnp.asarray(False), jnp.asarray(0.0))
        off = jnp.zeros(g, dtype=bool)
        headings = HeadingTests(jnp.ones(g, dtype=bool), jnp.zeros(g), off, jnp.zeros(g), off, jnp.zeros(g), jnp.zeros(g))
        return HandlerMemory(positions, tracker, headings)

    def _healthy_history(self, period: float) -> Array:
        """The drift fit's weighted sums of 1, tau and tau^2 over an endless past of
        fixes every ``period`` seconds (tau = -k period, weights lambda^k, lambda =
        exp(-period / drift_window)), all of zero innovation: the fit starts as it
        stands in a steady state, its rate zero, rather than from two fixes whose rate
        is all noise."""
        decay = jnp.exp(-period / self.drift_window)
        ones = 1.0 / (1.0 - decay)
        first = decay / (1.0 - decay) ** 2
        second = decay * (1.0 + decay) / (1.0 - decay) ** 3
        return jnp.stack([ones, -period * first, period**2 * second])

    # ------------------------------------------------------------------ one step

    def step(
        self, memory: Any, instruments: Sequence[Instrument], samples: Sequence[Array], fresh: Array, held_heading: Array, t: ArrayLike
    ) -> tuple[Any, Array]:
        """``(memory, channels)``: the tests of the references with a new sample, the
        decisions, the combined position and heading and what is recorded of them."""
        t = jnp.asarray(t, dtype=float)
        gyros = [(i, each) for i, each in enumerate(instruments) if isinstance(each, Gyrocompass)]
        if not gyros:
            return memory, jnp.zeros(0)
        gyro_at = [i for i, _ in gyros]
        angles = jnp.stack([gyro.heading_of(samples[i]) for i, gyro in gyros])
        gyro_fresh = jnp.stack([fresh[i] for i in gyro_at])
        headings, heading, heading_channels, heading_alarm = self._headings(memory.headings, angles, gyro_fresh, t)
        headings = _where(jnp.any(gyro_fresh), headings, memory.headings)
        lever_heading = jnp.where(jnp.isfinite(heading), heading, held_heading)

        references = [(i, each) for i, each in enumerate(instruments) if isinstance(each, PositionReference)]
        reference_at = [i for i, _ in references]
        out: list[Array] = []
        channels: dict[int, Array] = {}
        positions, tracker = memory.positions, memory.tracker
        if references:
            raw = jnp.stack([samples[i] for i in reference_at])
            points = jnp.stack([each.reference_point(samples[i], lever_heading) for i, each in references])
            reference_fresh = jnp.stack([fresh[i] for i in reference_at])

            def tested(_):
                return self._positions(
                    memory.positions,
                    memory.tracker,
                    _stated_variance([each for _, each in references], raw),
                    jnp.asarray([each.sample_period for _, each in references]),
                    raw,
                    points,
                    reference_fresh,
                    t,
                )

            def held(_):
                # no reference has a new fix: the memory stays and the channels are not
                # taken (the suite holds them); NaN of their shapes
                _, _, *shapes = jax.eval_shape(tested, None)
                return (memory.positions, memory.tracker, *jax.tree.map(lambda a: jnp.full(a.shape, jnp.nan, a.dtype), shapes))

            # a branch, not a where: where the fixes' times are the same for a whole batch
            # (its runs share their sample periods), vmap keeps it a branch and the tests
            # run only at the steps with a new fix
            positions, tracker, position, position_channels, position_alarm = jax.lax.cond(jnp.any(reference_fresh), tested, held, None)
            out.append(position)
            channels.update({i: position_channels[k] for k, i in enumerate(reference_at)})
        out.append(jnp.reshape(heading, (1,)))
        channels.update({i: heading_channels[k] for k, i in enumerate(gyro_at)})
        out += [channels[i] for i in sorted(channels)]
        if reference_at:
            out.append(jnp.reshape(position_alarm, (1,)))
        out.append(jnp.reshape(heading_alarm, (1,)))
        return HandlerMemory(positions, tracker, headings), jnp.concatenate(out)

    def _headings(self, memory: HeadingTests, angles: Array, fresh: Array, t: Array) -> tuple[HeadingTests, Array, list[Array], Array]:
        """The gyrocompasses' tests and decisions, and the circular median of the accepted ones."""
        g = angles.shape[0]
        finite = jnp.isfinite(angles)
        new = fresh & finite
        same = memory.seen & (jnp.abs(ssa(jnp.where(finite, angles, 0.0) - memory.last_sample)) <= self.heading_freeze_tolerance)
        repeats = jnp.where(new, jnp.where(same, memory.repeats + 1.0, 0.0), memory.repeats)
        last_sample = jnp.where(new, angles, memory.last_sample)
        seen = memory.seen | new
        usable = memory.accepted & finite
        divergence = []
        for i in range(g):
            others = usable & (jnp.arange(g) != i)
            distance = jnp.abs(ssa(angles[i] - circular_median(jnp.where(others, angles, jnp.nan))))
            divergence.append(jnp.where(jnp.isfinite(distance), distance, 0.0))
        divergence_array = jnp.stack(divergence)
        count = jnp.sum(usable)
        others = count - usable
        ratios = jnp.stack([repeats / self.freeze_samples, divergence_array / self.heading_divergence_limit], axis=1)
        fails = jnp.stack([repeats >= self.freeze_samples, (divergence_array > self.heading_divergence_limit) & (others >= 1)], axis=1)
        may_reject = jnp.stack([fails[:, 0], fails[:, 1] & (count >= 3)], axis=1)
        accepted, rejected_by, healthy, healthy_since = _decide(
            memory.accepted,
            memory.rejected_by,
            memory.healthy,
            memory.healthy_since,
            finite,
            memory.seen,
            fails,
            may_reject,
            ratios,
            jnp.asarray([FREEZE, DIVERGENCE]),
            t,
            self.healthy_time,
        )
        heading = circular_median(jnp.where(accepted & finite, angles, jnp.nan))
        pair = (accepted & finite) & (jnp.sum(accepted & finite) == 2)
        alarm = jnp.any(pair & (divergence_array > self.heading_divergence_limit)).astype(float)
        channels = [jnp.stack([accepted[i].astype(float), rejected_by[i], repeats[i], divergence_array[i]]) for i in range(g)]
        return HeadingTests(accepted, rejected_by, healthy, healthy_since, seen, last_sample, repeats), heading, channels, alarm

    def _positions(
        self, memory: PositionTests, tracker: Tracker, stated: Array, periods: Array, raw: Array, points: Array, fresh: Array, t: Array
    ) -> tuple[PositionTests, Tracker, Array, list[Array], Array]:
        """The position references' tests and decisions, the tracker fed by the accepted
        ones, and the weighted mean of the accepted references."""
        n = points.shape[0]
        finite = jnp.all(jnp.isfinite(points), axis=1)
        new = fresh & finite
        a_low = 1.0 / self.divergence_samples
        a_var = 1.0 / self.variance_samples

        # the tracker's prediction at t (before any fix of this step is fed)
        dt = jnp.where(tracker.started, t - tracker.time, 0.0)
        transition = jnp.asarray([[1.0, 0.0], [0.0, 1.0]]) + dt * jnp.asarray([[0.0, 1.0], [0.0, 0.0]])
        process = self.tracker_acceleration * jnp.stack([jnp.stack([dt**3 / 3, dt**2 / 2]), jnp.stack([dt**2 / 2, dt])])
        covariance = transition @ tracker.covariance @ transition.T + process
        predicted = tracker.position + dt * tracker.velocity

        # the gate: the tracker's variance, its error beyond its model (in a sea heavier
        # than tracker_acceleration allows for: common to every reference) and the
        # reference's stated variance (not its estimate, which a jump would widen)
        listened = memory.accepted & tracker.started
        excess, _ = _estimated_variance(memory.variance, memory.prediction_variance, stated, listened)

        # innovations at the new fixes, learned once the tracker has started
        learn = new & tracker.started
        innovation = points - predicted
        distance = jnp.sqrt(jnp.sum(innovation**2, axis=1) / (covariance[0, 0] + excess + stated))
        prediction = jnp.where(learn, distance, jnp.where(new, 0.0, memory.prediction))
        mean = jnp.where(learn[:, None], memory.mean + a_low * (innovation - memory.mean), memory.mean)
        # a fix beyond the gate enters the variance window cut back to the gate (a sea
        # heavier than the tracker's model still widens it; a jump does not fill it for a
        # window after it ends), and enters the drift fit not at all (a step would hold
        # the fit's rate for minutes)
        inside = distance <= self.prediction_gate
        clipped = jnp.where(inside, 1.0, self.prediction_gate / jnp.where(inside, 1.0, distance))
        spread = jnp.where(
            learn, memory.variance + a_var * (jnp.sum((clipped[:, None] * innovation) ** 2, axis=1) / 2.0 - memory.variance), memory.variance
        )
        prediction_variance = jnp.where(
            learn, memory.prediction_variance + a_var * (covariance[0, 0] - memory.prediction_variance), memory.prediction_variance
        )
        _, estimated = _estimated_variance(spread, prediction_variance, stated, listened)

        # the freeze test, on the samples themselves
        same = memory.seen & jnp.all(jnp.abs(jnp.where(jnp.isfinite(raw), raw, 0.0) - memory.last_sample) <= self.freeze_tolerance, axis=1)
        repeats = jnp.where(new, jnp.where(same, memory.repeats + 1.0, 0.0), memory.repeats)
        last_sample = jnp.where(new[:, None], raw, memory.last_sample)
        seen = memory.seen | new

        # the drift fit: exponentially weighted least squares of the innovation on time,
        # its times counted back from the reference's last fix
        # (before its first fix, its healthy history's last fix is a period back)
        gap = jnp.where(memory.fitted, t - memory.last_time, periods)
        forget = jnp.exp(-gap / self.drift_window)
        s0, s1, s2 = memory.moments[:, 0], memory.moments[:, 1], memory.moments[:, 2]
        y0, y1 = memory.products[:, 0], memory.products[:, 1]
        shifted = jnp.stack([forget * s0 + 1.0, forget * (s1 - gap * s0), forget * (s2 - 2 * gap * s1 + gap**2 * s0)], axis=1)
        y1_shifted = forget[:, None] * (y1 - gap[:, None] * y0)
        y0_shifted = forget[:, None] * y0 + innovation
        fit = learn & inside
        moments = jnp.where(fit[:, None], shifted, memory.moments)
        products = jnp.where(fit[:, None, None], jnp.stack([y0_shifted, y1_shifted], axis=1), memory.products)
        last_time = jnp.where(fit, t, memory.last_time)
        fitted_once = memory.fitted | fit
        s0, s1, s2 = moments[:, 0], moments[:, 1], moments[:, 2]
        determinant = s0 * s2 - s1**2
        # the fit counts once it spans a window: the weighted variance of its times at
        # least that of a window's uniform spread, drift_window^2 / 12
        fitted = (s0 > 0) & (determinant >= s0**2 * self.drift_window**2 / 12.0)
        safe = jnp.where(fitted, determinant, 1.0)
        slope = jnp.where(fitted[:, None], (s0[:, None] * products[:, 1] - s1[:, None] * products[:, 0]) / safe[:, None], 0.0)

        # the comparisons with the other accepted references
        usable = memory.accepted & finite & tracker.started
        weight = 1.0 / jnp.maximum(jnp.maximum(estimated, stated), _VARIANCE_FLOOR)
        divergence, drift = [], []
        for i in range(n):
            others = usable & (jnp.arange(n) != i)
            median = jnp.nanmedian(jnp.where(others[:, None], mean, jnp.nan), axis=0)
            gap_i = jnp.sqrt(jnp.sum((mean[i] - median) ** 2))
            divergence.append(jnp.where(jnp.any(others), gap_i, 0.0))
            compared = others & fitted
            share = jnp.where(compared, weight, 0.0)
            rate = jnp.sum(share[:, None] * slope, axis=0) / jnp.where(jnp.any(compared), jnp.sum(share), 1.0)
            drift.append(jnp.where(jnp.any(compared) & fitted[i], jnp.sqrt(jnp.sum((slope[i] - rate) ** 2)), 0.0))
        divergence_array, drift_array = jnp.stack(divergence), jnp.stack(drift)
        noise_ratio = jnp.sqrt(estimated / jnp.maximum(stated, _VARIANCE_FLOOR))

        count = jnp.sum(usable)
        others_count = count - usable
        limits = (self.noise_factor, self.prediction_gate, self.divergence_limit, self.drift_limit)
        statistics = (noise_ratio, prediction, divergence_array, drift_array)
        ratios = jnp.stack([repeats / self.freeze_samples] + [s / limit for s, limit in zip(statistics, limits)], axis=1)
        fails = jnp.stack(
            [
                repeats >= self.freeze_samples,
                noise_ratio > self.noise_factor,
                prediction > self.prediction_gate,
                (divergence_array > self.divergence_limit) & (others_count >= 1),
                (drift_array > self.drift_limit) & (others_count >= 1),
            ],
            axis=1,
        )
        # a test against the tracker rejects only while another accepted reference passes
        # it (when every one fails, the tracker is what is wrong: a sea it is not tuned
        # to), and once the tracker has been fed a variance window of fixes (its start, and
        # the windows' first estimates of the sea, are no reference's fault); the tests
        # that compare a reference with the others reject with three or more accepted
        passing = usable[:, None] & ~fails[:, 1:3]
        another = ((jnp.sum(passing, axis=0) - passing) >= 1) & (tracker.fed >= self.variance_samples)
        may_reject = jnp.stack(
            [
                fails[:, 0],
                fails[:, 1] & another[:, 0] & (count >= 3),
                fails[:, 2] & another[:, 1],
                fails[:, 3] & (count >= 3),
                fails[:, 4] & (count >= 3),
            ],
            axis=1,
        )
        codes = jnp.asarray([FREEZE, VARIANCE, PREDICTION, DIVERGENCE, DRIFT])
        accepted, rejected_by, healthy, healthy_since = _decide(
            memory.accepted,
            memory.rejected_by,
            memory.healthy,
            memory.healthy_since,
            finite,
            memory.seen,
            fails,
            may_reject,
            ratios,
            codes,
            t,
            self.healthy_time,
        )
        alarm = ((count == 2) & jnp.any(usable & (fails[:, 1] | fails[:, 3] | fails[:, 4]))).astype(float)

        # the combined position: the accepted references' weighted mean, by their
        # estimated variances with three or more (with two, each one's innovations show
        # their disagreement as much as its noise, and weighting by them would hand the
        # tracker to one of the two: the stated variances weigh them)
        taken = accepted & finite
        variance = jnp.where(jnp.sum(taken) >= 3, jnp.maximum(jnp.maximum(estimated, stated), _VARIANCE_FLOOR), jnp.maximum(stated, _VARIANCE_FLOOR))
        weights = jnp.where(taken, 1.0 / variance, 0.0)
        total = jnp.sum(weights)
        position = jnp.sum(weights[:, None] * jnp.where(taken[:, None], points, 0.0), axis=0) / jnp.where(total > 0, total, 1.0)
        position = jnp.where(total > 0, position, jnp.nan)
        share = weights / jnp.where(total > 0, total, 1.0)

        tracker = self._track(tracker, covariance, predicted, points, accepted & new, variance, t)
        # with every reference rejected the stage starts over: the tracker waits for its
        # first fix again, and the tests against it forget what they saw of it
        lost = ~jnp.any(accepted)
        tracker = tracker._replace(started=tracker.started & ~lost, fed=jnp.where(lost, 0.0, tracker.fed))
        prediction = jnp.where(lost, 0.0, prediction)
        mean = jnp.where(lost, 0.0, mean)
        spread = jnp.where(lost, stated, spread)
        prediction_variance = jnp.where(lost, 0.0, prediction_variance)
        memory = PositionTests(
            accepted,
            rejected_by,
            healthy,
            healthy_since,
            seen,
            last_sample,
            repeats,
            fitted_once,
            last_time,
            prediction,
            mean,
            spread,
            prediction_variance,
            moments,
            products,
        )
        channels = [
            jnp.stack(
                [accepted[i].astype(float), rejected_by[i], share[i], repeats[i], noise_ratio[i], prediction[i], divergence_array[i], drift_array[i]]
            )
            for i in range(n)
        ]
        return memory, tracker, position, channels, alarm

    def _track(self, tracker: Tracker, covariance: Array, predicted: Array, points: Array, fed: Array, variance: Array, t: Array) -> Tracker:
        """The tracker corrected by each fed fix in turn (both axes alike), or started
        at the first fixes' weighted mean."""
        velocity = tracker.velocity
        position = predicted
        for i in range(points.shape[0]):
            gain = covariance[:, 0] / (covariance[0, 0] + variance[i])
            innovation = jnp.where(fed[i], points[i] - position, 0.0)
            use = fed[i] & tracker.started
            position = jnp.where(use, position + gain[0] * innovation, position)
            velocity = jnp.where(use, velocity + gain[1] * innovation, velocity)
            covariance = jnp.where(use, covariance - jnp.outer(gain, covariance[0, :]), covariance)
        # the start: the fed fixes' weighted mean, at rest, as uncertain as that mean
        weights = jnp.where(fed, 1.0 / variance, 0.0)
        total = jnp.sum(weights)
        start = ~tracker.started & (total > 0)
        mean = jnp.sum(weights[:, None] * jnp.where(fed[:, None], points, 0.0), axis=0) / jnp.where(total > 0, total, 1.0)
        initial = jnp.diag(jnp.stack([1.0 / jnp.where(total > 0, total, 1.0), jnp.asarray(INITIAL_SPEED_STD**2)]))
        return Tracker(
            jnp.where(start, mean, position),
            jnp.where(start, jnp.zeros(2), velocity),
            jnp.where(start, initial, covariance),
            t,
            tracker.started | start,
            tracker.fed + jnp.any(fed).astype(float),
        )


def _position_signals(name: str) -> tuple[Signal, ...]:
    return (
        Signal(f"{name}.accepted", "1", f"{name}: accepted by the reference handling (1) or rejected (0)"),
        Signal(
            f"{name}.rejected_by", "1", f"{name}: why it is rejected (0 none, 1 freeze, 2 variance, 3 prediction, 4 divergence, 5 drift, 6 missing)"
        ),
        Signal(f"{name}.weight", "1", f"{name}: its share of the combined position"),
        Signal(f"{name}.repeated_samples", "1", f"{name}: samples in a row unchanged (freeze test)"),
        Signal(f"{name}.noise_ratio", "1", f"{name}: estimated over stated noise standard deviation (variance test)"),
        Signal(f"{name}.prediction_distance", "1", f"{name}: Mahalanobis distance of its last fix from the tracker's prediction (prediction test)"),
        Signal(f"{name}.divergence", "m", f"{name}: distance of its low-passed innovation from the other references' median (divergence test)"),
        Signal(f"{name}.drift_rate", "m/s", f"{name}: rate of its difference from the other references (drift test)"),
    )


def _heading_signals(name: str) -> tuple[Signal, ...]:
    return (
        Signal(f"{name}.accepted", "1", f"{name}: accepted by the reference handling (1) or rejected (0)"),
        Signal(f"{name}.rejected_by", "1", f"{name}: why it is rejected (0 none, 1 freeze, 4 divergence, 6 missing)"),
        Signal(f"{name}.repeated_samples", "1", f"{name}: samples in a row unchanged (freeze test)"),
        Signal(f"{name}.divergence", "rad", f"{name}: distance from the other gyrocompasses' median (divergence test)"),
    )


def _stated_variance(references: Sequence[PositionReference], raw: Array | None = None) -> Array:
    """Each reference's stated variance per axis (m^2): its weight_std squared, or, given
    its samples ``raw`` (one row each), its std_at them squared (a hydroacoustic
    reference's at each fix's slant range)."""
    if not references:
        return jnp.zeros(0)
    if raw is None:
        return jnp.stack([jnp.asarray(each.weight_std(), dtype=float) ** 2 for each in references])
    return jnp.stack([jnp.asarray(each.std_at(raw[k]), dtype=float) ** 2 for k, each in enumerate(references)])


def _estimated_variance(spread: Array, prediction_variance: Array, stated: Array, listened: Array) -> tuple[Array, Array]:
    """``(excess, estimated)``: each reference's variance per axis (m^2) as its
    innovations show it, their mean square less the tracker's predicted variance and
    less the excess common to every reference, taken as the median excess over the
    stated variance among the ``listened`` (accepted) references: the tracker's own
    error beyond its model, which no reference is to blame for (a single failure at a
    time leaves most references healthy)."""
    beyond = spread - prediction_variance - stated
    excess = jnp.maximum(jnp.nanmedian(jnp.where(listened, beyond, jnp.nan)), 0.0)
    excess = jnp.where(jnp.any(listened), excess, 0.0)
    return excess, jnp.maximum(spread - prediction_variance - excess, 0.0)


def _decide(
    accepted: Array,
    rejected_by: Array,
    healthy: Array,
    healthy_since: Array,
    finite: Array,
    seen: Array,
    fails: Array,
    may_reject: Array,
    ratios: Array,
    codes: Array,
    t: Array,
    healthy_time: Array,
) -> tuple[Array, Array, Array, Array]:
    """``(accepted, rejected_by, healthy, healthy_since)`` after one step's decisions: a missing
    sample rejected at once (of a reference ``seen`` before: one that has given none
    yet is taken from its first); of the accepted ones that fail a test that may reject
    them, the one furthest beyond its threshold (relative to it); a rejected one whose
    tests have passed for ``healthy_time`` reinstated."""
    n = accepted.shape[0]
    passing = finite & ~jnp.any(fails, axis=1)
    healthy_since = jnp.where(passing, jnp.where(healthy, healthy_since, t), 0.0)
    missing = accepted & ~finite & seen
    rejected_by = jnp.where(missing, float(MISSING), rejected_by)
    accepted = accepted & ~missing
    score = jnp.where(may_reject & accepted[:, None], ratios, -jnp.inf)
    worst = jnp.max(score, axis=1)
    chosen = jnp.argmax(worst)
    rejected = (jnp.arange(n) == chosen) & jnp.isfinite(worst[chosen])
    rejected_by = jnp.where(rejected, codes[jnp.argmax(score[chosen])].astype(float), rejected_by)
    accepted = accepted & ~rejected
    back = ~accepted & ~rejected & passing & (t - healthy_since >= healthy_time)
    return accepted | back, jnp.where(back, 0.0, rejected_by), passing, healthy_since


def _where(condition: Array, new: Any, old: Any) -> Any:
    """``new`` where ``condition``, else ``old``, leaf by leaf."""
    return jax.tree.map(lambda a, b: jnp.where(condition, a, b), new, old)


__all__ = ["REASONS", "HandlerMemory", "ReferenceHandler"]
