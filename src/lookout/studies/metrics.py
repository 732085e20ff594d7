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
=================  ==============================================================

Every campaign also keeps ``diverged``: a non-finite truth or estimate at the end of
the run (a non-finite state stays non-finite), or, with a divergence limit, the
estimation or tracking error of the limit's signal beyond it at any time. A diverged
run's metrics are NaN.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from lookout._math import ssa

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
}


@dataclass(frozen=True)
class Metric:
    """One metric: ``kind`` of ``signal``, with its units and a description."""

    kind: str
    signal: str
    units: str
    description: str

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


def resolve(names: list[str], scenario) -> list[Metric]:
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
        else:
            found = truth or signals["extra"].get(signal)
            if found is None:
                raise ValueError(f"{name!r}: no recorded {signal!r} (plant variables: {', '.join(signals['truth'])}; observer outputs: {', '.join(signals['extra']) or 'none'})")
        units = "s" if kind == "settling_time" else found.units
        metrics.append(Metric(kind, signal, units, f"{description} of {found.long_name}"))
    return metrics


def _norm(values, vector: bool):
    """|values| per (run, time): the norm over the last axis of a vector signal."""
    return jnp.sqrt(jnp.sum(values**2, axis=-1)) if vector else jnp.abs(values)


def _difference(a, b, angle: bool):
    difference = a - b
    return ssa(difference) if angle else difference


def _rms(values):
    return jnp.sqrt(jnp.mean(values**2, axis=-1))


def _settling_time(norm, time, final_rms, tolerance: float = 0.10):
    """:func:`lookout.analysis.settling_time` in JAX (the same tail-RMS rule)."""
    count = jnp.arange(norm.shape[-1], 0, -1)
    tail_power = jnp.flip(jnp.cumsum(jnp.flip(norm**2, axis=-1), axis=-1), axis=-1) / count
    inside = jnp.sqrt(tail_power) <= (1.0 + tolerance) * final_rms[..., None]
    return jnp.where(inside.any(axis=-1), time[jnp.argmax(inside, axis=-1)], jnp.nan)


@dataclass(frozen=True)
class _Plan:
    """What :func:`_reduce` computes: static, so one compiled program per campaign."""

    metrics: tuple[tuple[str, str, str, bool, bool], ...]  # (variable, kind, signal, vector, angle)
    divergence: tuple[str, float, bool, bool] | None       # (signal, limit, vector, angle)


@functools.partial(jax.jit, static_argnames=("plan", "layout"))
def _reduce(plan: _Plan, layout, time, window, truth, estimate, reference, inputs):
    applied = layout.split(inputs)
    # A non-finite value in the state stays non-finite (NaN and inf propagate through
    # every later step), so the last record tells whether a run diverged; reading it,
    # not every record, keeps the reduction's memory traffic to the metrics' signals.
    leaves = [array[:, -1] for array in jax.tree.leaves((truth, estimate))]
    n_runs = leaves[0].shape[0]
    finite = jnp.ones(n_runs, dtype=bool)
    for array in leaves:
        finite &= jnp.isfinite(array).reshape(n_runs, -1).all(axis=1)

    def error(name, vector, angle):
        return _norm(_difference(truth[name], estimate[name], angle), vector)

    def tracking(name, vector, angle):
        return _norm(_difference(truth[name], reference[f"{name}_desired"], angle), vector)

    diverged = ~finite
    if plan.divergence is not None:
        name, limit, vector, angle = plan.divergence
        norms = ([error(name, vector, angle)] if name in estimate else []) + ([tracking(name, vector, angle)] if f"{name}_desired" in reference else [])
        for norm in norms:
            diverged |= jnp.where(jnp.isfinite(norm), norm, jnp.inf).max(axis=-1) > limit

    weight = window.astype(float)
    count = weight.sum()
    out = {}
    for variable, kind, name, vector, angle in plan.metrics:
        if kind in ("rms_error", "max_error", "settling_time"):
            norm = error(name, vector, angle)
        elif kind in ("rms_tracking", "max_tracking"):
            norm = tracking(name, vector, angle)
        elif kind == "max_excursion":
            base = reference[f"{name}_desired"] if f"{name}_desired" in reference else truth[name][:, :1]
            norm = _norm(_difference(truth[name], base, angle), vector)
        elif kind in ("rms_input", "max_input"):
            norm = _norm(applied[name], vector)
        else:  # final
            array = (truth[name] if name in truth else estimate[name])[:, -1]
            out[variable] = jnp.sqrt(jnp.sum(array.reshape(n_runs, -1) ** 2, axis=1))
            continue
        if kind.startswith("rms") or kind == "settling_time":
            rms = jnp.sqrt(jnp.sum(norm**2 * weight, axis=-1) / count)
            out[variable] = rms if kind != "settling_time" else _settling_time(norm, time, rms)
        elif kind == "max_excursion":
            out[variable] = norm.max(axis=-1)
        else:
            out[variable] = jnp.where(window, norm, -jnp.inf).max(axis=-1)
    out = {variable: jnp.where(diverged, jnp.nan, value) for variable, value in out.items()}
    out["diverged"] = diverged
    return out


def reduce(trajectory, metrics: list[Metric], *, after: float | None = None, divergence: tuple[str, float] | None = None) -> dict[str, np.ndarray]:
    """Each metric per run (shape ``(runs,)``) and ``diverged`` (bool), from a batched
    :class:`~lookout.Trajectory`, computed in one jitted program on the device that
    holds the runs (only these numbers are copied back).

    ``divergence = (signal, limit)`` also marks a run diverged when the estimation
    error or the tracking error of ``signal`` exceeds ``limit`` at any time.
    """
    time = np.asarray(trajectory.time)
    after = time[-1] / 2.0 if after is None else after
    window = time >= after - 1e-9 * max(1.0, abs(after))
    if not window.any():
        raise ValueError(f"after ({after:g} s) is past the end of the run ({time[-1]:g} s)")
    record = trajectory.signals
    shapes = {s.name: s for s in record.truth} | {s.name: s for s in record.input.signals} | {s.name: s for s in record.extra}
    rows = tuple((m.variable, m.kind, m.signal, bool(shapes[m.signal].labels), bool(shapes[m.signal].angle)) for m in metrics)
    limit = None
    if divergence is not None:
        signal = shapes[divergence[0]]
        limit = (divergence[0], float(divergence[1]), bool(signal.labels), bool(signal.angle))
    result = _reduce(_Plan(rows, limit), record.input, jnp.asarray(time), jnp.asarray(window), trajectory.truth, trajectory.estimate, trajectory.reference, trajectory.applied)
    return {name: np.asarray(value) for name, value in result.items()}
