"""Per-run metrics of a campaign, reduced where the runs are computed.

A metric is named ``KIND:SIGNAL``, with SIGNAL a recorded quantity of the scenario
(a plant variable such as ``position``, or an input such as ``force``), and gives
one number per run. Vector signals are measured by their Euclidean norm over their
components (one unit per signal, so the norm has it too); an angle's error is
wrapped to [-pi, pi). Windows start at ``after`` seconds (default: half the run).

=================  ==============================================================
kind               per run
=================  ==============================================================
``rms_error``      RMS over t >= after of |x - x_hat| (estimation error)
``max_error``      largest |x - x_hat| over t >= after
``settling_time``  first t from which the RMS of |x - x_hat| over [t, end] is within
                   10 % of its RMS over t >= after (:func:`lookout.analysis.settling_time`)
``rms_tracking``   RMS over t >= after of |x - x_desired| (the reference's signal)
``max_tracking``   largest |x - x_desired| over t >= after
``max_excursion``  largest |x - x_desired| over the whole run, or |x - x(0)| without a
                   reference (how far the vessel or arm strays)
``rms_input``      RMS over t >= after of |u_applied| for the input signal u
``max_input``      largest |u_applied| over t >= after
``final``          |x| (or |x_hat|, for an observer's own output) at the last record
``outage_drift``   largest |x - x_hat| while the sensor's outage lasts
``recovery_time``  time from the outage's end until the RMS of |x - x_hat| over the
                   next outage-length window is back within 25 % of its RMS over the
                   same length of time before the outage
``mean_power``     mean over t >= after of the thrusters' power as a fraction of the
                   installed power (signal ``thrust``: a thruster actuator's delivered
                   thrust; the actuator's ``relative_power``)
``time_at_limit``  fraction of t >= after with some thruster within 1 % of its largest
                   or smallest thrust (signal ``thrust``; the actuator's ``at_limit``)
``rejected_after``  time from ``after`` to the first record at which the reference
                   handling has rejected the sensor named by SIGNAL (its recorded
                   ``SIGNAL.accepted`` is 0; ``[references] kind = "dp-class"``); NaN
                   when it is never rejected
``rejected_time``  fraction of t >= after with that sensor rejected
=================  ==============================================================

The two thruster metrics take the scenario's actuator's thrust limits (its
``layout.max_thrust`` and ``layout.min_thrust``) and its functions of the delivered thrust
(:class:`lookout.actuators.ThrusterSystem`'s ``relative_power`` and ``at_limit``), so
this module needs no actuator module.

The two outage metrics need a sensor with an outage (its ``outage_signals``,
``outage_start`` and ``outage_duration``); without one, or with an outage of 0 s,
they are NaN, as a recovery time is when the error does not come back within the run.

Every campaign also keeps ``diverged``: a non-finite truth or estimate at any record,
or, with a divergence limit, the estimation or tracking error of the limit's signal
beyond it at any record. A diverged run's metrics are NaN.

:func:`summarize` accumulates the metrics inside the engine's scan
(:class:`MetricSummary`, :func:`lookout.sim.summarize_batch`), so the records are
never held; :func:`reduce` computes the same per-record terms from a recorded batch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout._math import ssa
from lookout._validation import ParameterError
from lookout.results import RecordSignals, Trajectory
from lookout.sim import Scenario, Summary, summarize_batch

#: kind -> (what it needs, description)
KINDS = {
    "rms_error": ("estimate", "RMS estimation error"),
    "max_error": ("estimate", "largest estimation error"),
    "settling_time": ("estimate", "settling time of the estimation error"),
    "rms_tracking": ("reference", "RMS tracking error"),
    "max_tracking": ("reference", "largest tracking error"),
    "max_excursion": ("truth", "largest excursion"),
    "rms_input": ("input", "RMS applied input"),
    "max_input": ("input", "largest applied input"),
    "final": ("any", "final value"),
    "outage_drift": ("estimate", "largest estimation error during the sensor outage"),
    "recovery_time": ("estimate", "recovery time after the sensor outage"),
    "mean_power": ("thrusters", "mean power as a fraction of the installed power"),
    "time_at_limit": ("thrusters", "fraction of the time with a thruster at a thrust limit"),
    "rejected_after": ("stage", "time to the first rejection"),
    "rejected_time": ("stage", "fraction of the time rejected"),
}
#: The reference handling's metrics: of a sensor's recorded ``NAME.accepted`` channel.
STAGE_KINDS = ("rejected_after", "rejected_time")
#: The kinds that average a per-record value over the window (no square root).
MEAN_KINDS = ("mean_power", "time_at_limit")
#: time_at_limit: a thrust within this fraction of the largest thrust of a limit is at
#: it (:data:`lookout.actuators.thrusters.AT_LIMIT`: a lagging thrust reaches a limit
#: only in the limit of time).
AT_LIMIT_TOLERANCE = 0.01
#: The thruster metrics' functions of the delivered thrust: the actuator's attribute of
#: each (``relative_power(thrust, largest)``; ``at_limit(thrust, largest, smallest,
#: tolerance)``, per thruster).
THRUST_MEASURES = {"mean_power": "relative_power", "time_at_limit": "at_limit"}
#: The kinds that keep the error's norm at every record (reduced when the run ends).
SERIES_KINDS = ("settling_time", "recovery_time")
#: recovery_time: back within this fraction above the error's level before the outage.
RECOVERY_TOLERANCE = 0.25


@dataclass(frozen=True)
class Metric:
    """One metric: ``kind`` of ``signal``, with its units and a description."""

    kind: str
    signal: str
    units: str
    description: str
    #: the thrusters' (largest, smallest) thrust, for the thruster metrics
    thrust_limits: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    #: the actuator's function of the delivered thrust, for the thruster metrics
    #: (:data:`THRUST_MEASURES`)
    measure: Callable | None = None
    #: the measurement channel of the reference handling's metrics (``NAME.accepted``)
    channel: str | None = None

    @property
    def name(self) -> str:
        return f"{self.kind}:{self.signal}"

    @property
    def variable(self) -> str:
        """Its variable name in a store (``rms_error__position``)."""
        return f"{self.kind}__{self.signal}"


def _signals(scenario) -> dict[str, dict]:
    record = scenario.record_signals
    return {
        "truth": {s.name: s for s in record.truth},
        "estimate": {s.name: s for s in record.estimate},
        "extra": {s.name: s for s in record.extra},
        "reference": {s.name: s for s in record.reference},
        "input": {s.name: s for s in record.input.signals},
    }


def resolve(names: list[str], scenario: Scenario) -> list[Metric]:
    """The metrics ``names`` for ``scenario``; a ValueError names the first that is unknown
    or does not apply (a kind, or a signal the scenario does not record)."""
    signals = _signals(scenario)
    metrics = []
    for name in names:
        kind, _, signal = name.partition(":")
        if kind not in KINDS or not signal:
            raise ValueError(f"{name!r} is not a metric: write KIND:SIGNAL with KIND one of {', '.join(KINDS)}")
        needs, description = KINDS[kind]
        truth = signals["truth"].get(signal)
        if needs == "estimate":
            found = signals["estimate"].get(signal)
            if found is None:
                raise ValueError(f"{name!r}: the observer estimates no {signal!r} (it estimates {', '.join(signals['estimate']) or 'nothing'})")
        elif needs == "reference":
            found = truth if f"{signal}_desired" in signals["reference"] else None
            if found is None:
                tracked = [r[: -len("_desired")] for r in signals["reference"] if r.endswith("_desired")]
                raise ValueError(f"{name!r}: the reference gives no desired {signal!r} (it tracks {', '.join(tracked) or 'nothing'})")
        elif needs == "truth":
            found = truth
            if found is None:
                raise ValueError(f"{name!r}: the plant has no variable {signal!r} (it has {', '.join(signals['truth'])})")
        elif needs == "input":
            found = signals["input"].get(signal)
            if found is None:
                raise ValueError(f"{name!r}: the plant has no input {signal!r} (its inputs: {', '.join(signals['input'])})")
        elif needs == "stage":
            channel = f"{signal}.accepted"
            if channel not in scenario.sensor.measurement_layout.names:
                raise ValueError(
                    f'{name!r}: the sensor records no {channel!r} (a [references] kind = "dp-class" stage records it for each reference and gyrocompass)'
                )
            units = "s" if kind == "rejected_after" else "1"
            metrics.append(Metric(kind, signal, units, f"{description} of sensor {signal} by the reference handling", channel=channel))
            continue
        elif needs == "thrusters":
            layout = getattr(scenario.actuator, "layout", None)
            measure = getattr(type(scenario.actuator), THRUST_MEASURES[kind], None)
            if signal != "thrust" or layout is None or measure is None:
                raise ValueError(f'{name!r}: write {kind}:thrust, with a thruster actuator ([actuator] kind = "thrusters")')
            limits = (tuple(map(float, layout.max_thrust)), tuple(map(float, layout.min_thrust)))
            metrics.append(Metric(kind, signal, "1", f"{description} (thrusters)", limits, measure))
            continue
        else:
            found = truth or signals["extra"].get(signal)
            if found is None:
                raise ValueError(
                    f"{name!r}: no recorded {signal!r} (plant variables: {', '.join(signals['truth'])}; observer outputs: {', '.join(signals['extra']) or 'none'})"
                )
        units = "s" if kind in ("settling_time", "recovery_time") else found.units
        metrics.append(Metric(kind, signal, units, f"{description} of {found.long_name}"))
    return metrics


def _norm(values, vector: bool):
    """|values|: the norm over the last axis of a vector signal. Its gradient is 0, not
    NaN, at a zero vector (sqrt's derivative is infinite at 0: the inner ``where`` keeps
    it out of the gradient, as tuning differentiates through an error that starts at 0)."""
    if not vector:
        return jnp.abs(values)
    square = jnp.sum(values**2, axis=-1)
    positive = square > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, square, 1.0)), 0.0)


def _difference(a, b, angle: bool):
    difference = a - b
    return ssa(difference) if angle else difference


def _settling_time(norm, time, final_rms, tolerance: float = 0.10):
    """:func:`lookout.analysis.settling_time` in JAX (the same tail-RMS rule)."""
    count = jnp.arange(norm.shape[-1], 0, -1)
    tail_power = jnp.flip(jnp.cumsum(jnp.flip(norm**2, axis=-1), axis=-1), axis=-1) / count
    inside = jnp.sqrt(tail_power) <= (1.0 + tolerance) * final_rms[..., None]
    return jnp.where(inside.any(axis=-1), time[jnp.argmax(inside, axis=-1)], jnp.nan)


def _recovery_time(norm, time, before, start, end):
    """First time after the outage's end (records ``start`` to ``end``) from which the
    RMS of ``norm`` over the next outage-length window is within
    :data:`RECOVERY_TOLERANCE` of its RMS over the window before the outage (records
    ``before`` to ``start``), counted from the end; NaN when there is no outage or the
    error does not come back."""
    n = norm.shape[-1]
    index = jnp.arange(n)
    power = jnp.concatenate([jnp.zeros(norm.shape[:-1] + (1,)), jnp.cumsum(norm**2, axis=-1)], axis=-1)  # power[i] = sum of the first i
    level = jnp.sqrt((power[..., start] - power[..., before]) / jnp.maximum(start - before, 1))
    length = jnp.maximum(end - start, 1)
    stop = jnp.minimum(index + length, n)
    ahead = jnp.sqrt((jnp.take(power, stop, axis=-1) - power[..., :-1]) / (stop - index))
    back = (index >= end) & (ahead <= (1.0 + RECOVERY_TOLERANCE) * level[..., None])
    found = back.any(axis=-1) & (end > start) & (start > before)
    return jnp.where(found, time[jnp.argmax(back, axis=-1)] - time[jnp.minimum(end, n - 1)], jnp.nan)


@dataclass(frozen=True)
class _Plan:
    """What a :class:`MetricSummary` computes: static, so one compiled program per campaign."""

    metrics: tuple[tuple[str, str, str, bool, bool], ...]  # (variable, kind, signal, vector, angle)
    divergence: tuple[str, float, bool, bool] | None  # (signal, limit, vector, angle)
    thrust_limits: tuple[tuple[float, ...], tuple[float, ...]] | None = None  # (largest, smallest)
    #: the names of the recorded truths and estimates, sorted: the causes of a failed run
    #: are their non-finite values, in this order, then the divergence limit's errors
    truths: tuple[str, ...] = ()
    estimates: tuple[str, ...] = ()
    #: the divergence limit's errors checked: "estimation" and/or "tracking"
    limit_errors: tuple[str, ...] = ()
    limit_units: str = ""
    #: the thruster metrics' functions of the thrust, the actuator's: (variable, function)
    thrust_measures: tuple[tuple[str, Callable], ...] = ()
    #: the reference handling's metrics: (variable, offset of the channel in the measurement)
    channels: tuple[tuple[str, int], ...] = ()

    @property
    def causes(self) -> tuple[str, ...]:
        """Why a run failed, in words, one per cause index (:func:`diverged_where`)."""
        words = [f"{name} is not finite" for name in self.truths] + [f"{name}_hat is not finite" for name in self.estimates]
        if self.divergence is not None:
            name, limit = self.divergence[:2]
            words += [
                f"the {which} error of {name} is beyond the divergence limit {limit:g} {self.limit_units}".rstrip() for which in self.limit_errors
            ]
        return tuple(words)


class MetricSummary(Summary):
    """The metrics of a run, accumulated record by record (:class:`lookout.sim.Summary`).

    Each record contributes :meth:`terms`: the squared norms (for RMS values and
    settling times) and norms (for maxima) of the window's records, the final values,
    and whether it is finite and within the divergence limit. In the engine's scan
    (:func:`lookout.sim.summarize_batch`) they are summed, maximized and kept as the
    run goes, so a campaign never holds the records; on a recorded
    :class:`~lookout.Trajectory` (:func:`reduce`) the same terms are reduced over the
    time axis. Settling times need the whole error history: its norm is the one
    series kept per record. :meth:`finish` turns the accumulation into the metrics.
    """

    plan: _Plan = eqx.field(static=True)
    layout: Any = eqx.field(static=True)  # the input layout (to split the applied input)
    first: int = eqx.field(static=True)  # first record of the window t >= after
    n_records: int = eqx.field(static=True)
    #: records of the sensor's outage: the window before it starts, its first, and the
    #: first after it (arrays, so that outages of other lengths share one program)
    outage: Any = (0, 0, 0)

    def _origins(self) -> tuple[str, ...]:
        """Signals whose excursion is measured from their first record (no reference)."""
        return tuple(name for _, kind, name, _, _ in self.plan.metrics if kind == "max_excursion")

    def terms(self, index: Array, record: Any, origin: dict[str, Array]) -> tuple[dict[str, Any], dict[str, Array]]:
        """One record's contribution (one run): see the class docstring."""
        truth, estimate, measurement, reference, _, applied, actuation = record
        inputs = self.layout.split(applied)
        window = index >= self.first

        def error(name, vector, angle):
            return _norm(_difference(truth[name], estimate[name], angle), vector)

        def tracking(name, vector, angle):
            return _norm(_difference(truth[name], reference[f"{name}_desired"], angle), vector)

        power, peak, final, series = {}, {}, {}, {}
        offsets = dict(self.plan.channels)
        for variable, kind, name, vector, angle in self.plan.metrics:
            if kind in STAGE_KINDS:
                rejected = window & (jnp.asarray(measurement)[offsets[variable]] < 0.5)
                if kind == "rejected_time":
                    power[variable] = rejected.astype(float)
                else:  # the latest of -index: minus the first rejected record
                    peak[variable] = jnp.where(rejected, -jnp.asarray(index, dtype=float), -jnp.inf)
                continue
            if kind == "final":
                value = truth[name] if name in truth else estimate[name]
                final[variable] = jnp.sqrt(jnp.sum(jnp.asarray(value) ** 2))
                continue
            if kind in MEAN_KINDS:
                assert self.plan.thrust_limits is not None  # a thruster metric carries the thrusters' limits (resolve)
                largest, smallest = self.plan.thrust_limits
                thrust = actuation["thrust"]
                measure = dict(self.plan.thrust_measures)[variable]
                if kind == "mean_power":
                    value = measure(thrust, largest)
                else:
                    value = jnp.any(measure(thrust, largest, smallest, AT_LIMIT_TOLERANCE)).astype(float)
                power[variable] = jnp.where(window, value, 0.0)
                continue
            if kind in ("rms_error", "max_error", "settling_time", "outage_drift", "recovery_time"):
                norm = error(name, vector, angle)
            elif kind in ("rms_tracking", "max_tracking"):
                norm = tracking(name, vector, angle)
            elif kind == "max_excursion":
                base = reference[f"{name}_desired"] if f"{name}_desired" in reference else origin[name]
                norm = _norm(_difference(truth[name], base, angle), vector)
            else:  # rms_input, max_input
                norm = _norm(inputs[name], vector)
            if kind == "recovery_time":
                series[variable] = norm
            elif kind == "outage_drift":
                _, start, end = self.outage
                peak[variable] = jnp.where((index >= start) & (index < end), norm, -jnp.inf)
            elif kind.startswith("rms") or kind == "settling_time":
                power[variable] = jnp.where(window, norm**2, 0.0)
                if kind == "settling_time":
                    series[variable] = norm
            elif kind == "max_excursion":
                peak[variable] = norm
            else:
                peak[variable] = jnp.where(window, norm, -jnp.inf)
        return {"power": power, "peak": peak, "final": final, "failed": self.failures(truth, estimate, reference)}, series

    def failures(self, truth: dict[str, Array], estimate: dict[str, Array], reference: dict[str, Array]) -> Array:
        """One record's causes of a failed run, a bool per :attr:`_Plan.causes`: each
        truth and estimate not finite, then each error of the divergence limit's signal
        beyond the limit."""
        plan = self.plan
        flags = [~jnp.all(jnp.isfinite(jnp.asarray(truth[name]))) for name in plan.truths]
        flags += [~jnp.all(jnp.isfinite(jnp.asarray(estimate[name]))) for name in plan.estimates]
        if plan.divergence is not None:
            name, limit, vector, angle = plan.divergence
            for which in plan.limit_errors:
                base = estimate[name] if which == "estimation" else reference[f"{name}_desired"]
                norm = _norm(_difference(truth[name], base, angle), vector)
                flags.append(jnp.where(jnp.isfinite(norm), norm, jnp.inf) > limit)
        return jnp.asarray(flags, dtype=bool).reshape(len(plan.causes)) if flags else jnp.zeros((0,), dtype=bool)

    # the engine's Summary interface
    def init(self, record: Any) -> dict[str, Any]:
        truth = record[0]
        zeros = lambda shape: jnp.zeros(shape.shape, shape.dtype)
        (terms, _) = jax.eval_shape(lambda r: self.terms(jnp.asarray(0), r, {n: r[0][n] for n in self._origins()}), record)
        return {
            "power": {v: jnp.zeros(()) for v in terms["power"]},
            "peak": {v: jnp.asarray(-jnp.inf) for v in terms["peak"]},
            "final": {v: jnp.zeros(()) for v in terms["final"]},
            "failed_at": jnp.asarray(-1),
            "cause": jnp.asarray(-1),
            "origin": {n: zeros(truth[n]) for n in self._origins()},
        }

    def update(self, accumulated: Any, index: Array, record: Any) -> tuple[dict[str, Any], dict[str, Array]]:
        origin = {n: jnp.where(index == 0, record[0][n], accumulated["origin"][n]) for n in self._origins()}
        terms, series = self.terms(index, record, origin)
        first = (accumulated["failed_at"] < 0) & jnp.any(terms["failed"])
        return {
            "power": {v: accumulated["power"][v] + terms["power"][v] for v in terms["power"]},
            "peak": {v: jnp.maximum(accumulated["peak"][v], terms["peak"][v]) for v in terms["peak"]},
            "final": terms["final"],
            "failed_at": jnp.where(first, index, accumulated["failed_at"]),
            "cause": jnp.where(first, _first_cause(terms["failed"]), accumulated["cause"]),
            "origin": origin,
        }, series

    def finish(self, accumulated: dict[str, Any], series: dict[str, Array], time: Array, *, where: bool = False) -> dict:
        """Each metric per run and ``diverged``, from a batch's accumulation and series
        (leading run axis); a diverged run's metrics are NaN. With ``where``, also
        ``diverged_at`` (the first failed record, -1 for none) and ``diverged_cause``
        (its index into :attr:`causes`, the first cause of that record; -1 for none)."""
        count = self.n_records - self.first
        out = {}
        for variable, kind, _, _, _ in self.plan.metrics:
            if kind == "final":
                out[variable] = accumulated["final"][variable]
            elif kind == "rejected_after":
                first = -accumulated["peak"][variable]
                found = jnp.isfinite(first)
                out[variable] = jnp.where(found, time[jnp.where(found, first, 0).astype(int)] - time[self.first], jnp.nan)
            elif kind == "rejected_time":
                out[variable] = accumulated["power"][variable] / count
            elif kind == "recovery_time":
                out[variable] = _recovery_time(series[variable], time, *self.outage)
            elif kind in MEAN_KINDS:
                out[variable] = accumulated["power"][variable] / count
            elif kind.startswith("rms") or kind == "settling_time":
                rms = jnp.sqrt(accumulated["power"][variable] / count)
                out[variable] = rms if kind != "settling_time" else _settling_time(series[variable], time, rms)
            elif kind == "outage_drift":
                drift = accumulated["peak"][variable]
                out[variable] = jnp.where(jnp.isfinite(drift), drift, jnp.nan)
            else:
                out[variable] = accumulated["peak"][variable]
        diverged = accumulated["failed_at"] >= 0
        out = {variable: jnp.where(diverged, jnp.nan, value) for variable, value in out.items()}
        out["diverged"] = diverged
        if where:
            out["diverged_at"] = accumulated["failed_at"]
            out["diverged_cause"] = accumulated["cause"]
        return out

    @property
    def causes(self) -> tuple[str, ...]:
        """Why a run failed, in words, by ``diverged_cause``."""
        return self.plan.causes


def outage_of(scenario: Scenario) -> tuple[float, float] | None:
    """(start, duration) of the sensor's outage in ``scenario`` (s), or None."""
    outage = scenario.sensor.outage
    return None if outage is None else (float(outage.start), float(outage.duration))


def summary(
    record: RecordSignals,
    time: np.ndarray,
    metrics: list[Metric],
    *,
    after: float | None = None,
    divergence: tuple[str, float] | None = None,
    outage: tuple[float, float] | None = None,
) -> MetricSummary:
    """The :class:`MetricSummary` of ``metrics`` for runs recording ``record`` at
    ``time``: the window t >= ``after`` (default half the run), ``divergence =
    (signal, limit)``, which also marks a run diverged when the estimation error or
    the tracking error of ``signal`` exceeds ``limit`` at any record, and the sensor's
    ``outage = (start, duration)`` (s) for the outage metrics."""
    after = time[-1] / 2.0 if after is None else after
    window = time >= after - 1e-9 * max(1.0, abs(after))
    if not window.any():
        raise ValueError(f"after ({after:g} s) is past the end of the run ({time[-1]:g} s)")
    shapes = (
        {s.name: s for s in record.truth}
        | {s.name: s for s in record.input.signals}
        | {s.name: s for s in record.extra}
        | {s.name: s for s in record.actuation}
    )
    rows = tuple(
        (m.variable, m.kind, m.signal, False, False)
        if m.channel is not None
        else (m.variable, m.kind, m.signal, bool(shapes[m.signal].labels), bool(shapes[m.signal].angle))
        for m in metrics
    )
    offsets = dict(zip(record.measurement.names, np.cumsum([0] + [signal.size for signal in record.measurement.signals])))
    channels = tuple((m.variable, int(offsets[m.channel])) for m in metrics if m.channel is not None)
    thrust_limits = next((m.thrust_limits for m in metrics if m.thrust_limits is not None), None)
    limit = None
    limit_errors: tuple[str, ...] = ()
    if divergence is not None:
        if divergence[0] not in {s.name for s in record.truth}:
            raise ParameterError(
                "divergence.signal",
                f"the divergence limit's signal must be a plant variable ({', '.join(s.name for s in record.truth)}); got {divergence[0]!r}",
            )
        signal = shapes[divergence[0]]
        limit = (divergence[0], float(divergence[1]), bool(signal.labels), bool(signal.angle))
        limit_errors = tuple(
            which
            for which, present in (
                ("estimation", divergence[0] in {s.name for s in record.estimate}),
                ("tracking", f"{divergence[0]}_desired" in {s.name for s in record.reference}),
            )
            if present
        )
    windows: tuple[int, ...] = (0, 0, 0)
    if outage is not None:
        start, duration = outage
        windows = tuple(int(np.searchsorted(time, edge - 1e-9 * max(1.0, abs(edge)))) for edge in (start - duration, start, start + duration))
    plan = _Plan(
        rows,
        limit,
        thrust_limits,
        tuple(sorted(s.name for s in record.truth)),
        tuple(sorted(s.name for s in record.estimate)),
        limit_errors,
        shapes[divergence[0]].units if divergence is not None else "",
        tuple((m.variable, m.measure) for m in metrics if m.measure is not None),
        channels,
    )
    return MetricSummary(plan, record.input, int(np.argmax(window)), len(time), tuple(jnp.asarray(i) for i in windows))


def _first_cause(failed: Array) -> Array:
    """The index of the first true flag of one record's causes (-1 when there are none)."""
    return jnp.argmax(failed) if failed.shape[-1] else jnp.asarray(-1)


@eqx.filter_jit
def _finish(summary: MetricSummary, accumulated, series, time, where: bool = False):
    return summary.finish(accumulated, series, time, where=where)


@eqx.filter_jit
def _reduce_records(summary: MetricSummary, records, time, where: bool = False):
    """The terms of every record of a batch ``(run, time, ...)``, reduced over time."""
    n_time = time.shape[0]
    origin = {n: records[0][n][:, 0] for n in summary._origins()}
    per_record = jax.vmap(summary.terms, in_axes=(0, 0, None))  # over time
    terms, series = jax.vmap(per_record, in_axes=(None, 0, 0))(jnp.arange(n_time), records, origin)  # over runs
    accumulated: dict[str, Any] = {
        "power": {v: a.sum(axis=1) for v, a in terms["power"].items()},
        "peak": {v: a.max(axis=1) for v, a in terms["peak"].items()},
        "final": {v: a[:, -1] for v, a in terms["final"].items()},
    }
    failed = terms["failed"]  # (run, time, cause)
    any_failed = failed.any(axis=2)
    first = jnp.argmax(any_failed, axis=1)
    accumulated["failed_at"] = jnp.where(any_failed.any(axis=1), first, -1)
    accumulated["cause"] = jnp.where(
        any_failed.any(axis=1), jax.vmap(_first_cause)(jnp.take_along_axis(failed, first[:, None, None], axis=1)[:, 0]), -1
    )
    return summary.finish(accumulated, series, time, where=where)


def summarize(
    scenario: Scenario,
    keys: Array,
    metrics: list[Metric],
    *,
    after: float | None = None,
    divergence: tuple[str, float] | None = None,
    outage: tuple[float, float] | None = None,
    where: bool = False,
) -> dict[str, np.ndarray]:
    """Simulate the runs of ``keys`` and return each metric per run (shape ``(runs,)``)
    and ``diverged``, without holding their records: the metrics accumulate in the
    engine's scan (:func:`lookout.sim.summarize_batch`). Equals :func:`reduce` of
    ``simulate_batch(scenario, keys)`` to rounding (sums taken in another order).
    ``outage`` defaults to the scenario's sensor's (:func:`outage_of`); ``where``: see
    :meth:`MetricSummary.finish`."""
    time = scenario.record_times
    outage = outage_of(scenario) if outage is None else outage
    plan = summary(scenario.record_signals, time, metrics, after=after, divergence=divergence, outage=outage)
    accumulated, series = summarize_batch(scenario, keys, plan)
    result = _finish(plan, accumulated, series, jnp.asarray(time), where)
    return {name: np.asarray(value) for name, value in result.items()}


def reduce(
    trajectory: Trajectory,
    metrics: list[Metric],
    *,
    after: float | None = None,
    divergence: tuple[str, float] | None = None,
    outage: tuple[float, float] | None = None,
    where: bool = False,
) -> dict[str, np.ndarray]:
    """Each metric per run (shape ``(runs,)``) and ``diverged`` (bool), from a batched
    :class:`~lookout.Trajectory`, in one jitted program on the device that holds the
    runs (only these numbers are copied back). The same terms as :func:`summarize`;
    ``outage = (start, duration)`` is the sensor's outage, for the outage metrics;
    ``where``: see :meth:`MetricSummary.finish`.
    """
    time = np.asarray(trajectory.time)
    plan = summary(trajectory.signals, time, metrics, after=after, divergence=divergence, outage=outage)
    return _reduced(plan, trajectory, where)


def _reduced(plan: MetricSummary, trajectory, where: bool) -> dict[str, np.ndarray]:
    records = (
        trajectory.truth,
        trajectory.estimate,
        trajectory.measurement,
        trajectory.reference,
        trajectory.command,
        trajectory.applied,
        trajectory.actuation,
    )
    result = _reduce_records(plan, records, jnp.asarray(np.asarray(trajectory.time)), where)
    return {name: np.asarray(value) for name, value in result.items()}


@dataclass(frozen=True)
class Failure:
    """Why and where a run failed: its first failed record, that record's time (s) and
    the first cause found there (a non-finite truth or estimate, or an error beyond the
    divergence limit)."""

    record: int
    time: float
    cause: str

    def __str__(self) -> str:
        return f"at t = {self.time:g} s (record {self.record}): {self.cause}"


def failures(trajectory: Trajectory, divergence: tuple[str, float] | None = None) -> list[Failure | None]:
    """Per run of a batched :class:`~lookout.Trajectory`, its :class:`Failure` or None:
    the one rule of a failed run that ``lookout run``, campaigns and the benchmark share
    (a non-finite truth or estimate at any record, or with ``divergence = (signal,
    limit)`` the estimation or tracking error of ``signal`` beyond ``limit``)."""
    time = np.asarray(trajectory.time)
    plan = summary(trajectory.signals, time, [], divergence=divergence)
    values = _reduced(plan, trajectory, where=True)
    return [
        None if at < 0 else Failure(int(at), float(time[at]), plan.causes[int(cause)])
        for at, cause in zip(values["diverged_at"], values["diverged_cause"])
    ]
