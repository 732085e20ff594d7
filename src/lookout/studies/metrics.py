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

Every campaign also keeps ``diverged``: a non-finite truth or estimate anywhere in
the run, or, with a divergence limit, the estimation or tracking error of the
limit's signal beyond it at any time. A diverged run's metrics are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

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


def _norm(values: np.ndarray, vector: bool) -> np.ndarray:
    """|values| per (run, time): the norm over the last axis of a vector signal."""
    return np.sqrt((values**2).sum(axis=-1)) if vector else np.abs(values)


def _difference(a, b, signal) -> np.ndarray:
    difference = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    return np.asarray(ssa(difference)) if signal.angle else difference


def _rms(values: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(values**2, axis=-1))


def reduce(trajectory, metrics: list[Metric], *, after: float | None = None, divergence: tuple[str, float] | None = None) -> dict[str, np.ndarray]:
    """Each metric per run (shape ``(runs,)``) and ``diverged`` (bool), from a batched
    :class:`~lookout.Trajectory`.

    ``divergence = (signal, limit)`` also marks a run diverged when the estimation
    error or the tracking error of ``signal`` exceeds ``limit`` at any time.
    """
    time = np.asarray(trajectory.time)
    after = time[-1] / 2.0 if after is None else after
    window = time >= after - 1e-9 * max(1.0, abs(after))
    if not window.any():
        raise ValueError(f"after ({after:g} s) is past the end of the run ({time[-1]:g} s)")
    record = trajectory.signals
    truth_signals = {s.name: s for s in record.truth}
    input_signals = {s.name: s for s in record.input.signals}
    applied = record.input.split(np.asarray(trajectory.applied))
    truth = {k: np.asarray(v) for k, v in trajectory.truth.items()}
    estimate = {k: np.asarray(v) for k, v in trajectory.estimate.items()}
    n_runs = next(iter(truth.values())).shape[0]

    finite = np.ones(n_runs, dtype=bool)
    for group in (truth, estimate):
        for array in group.values():
            finite &= np.isfinite(array).reshape(array.shape[0], -1).all(axis=1)

    def error_norm(signal_name: str) -> np.ndarray:
        signal = truth_signals[signal_name]
        return _norm(_difference(truth[signal_name], estimate[signal_name], signal), bool(signal.labels))

    def tracking_norm(signal_name: str) -> np.ndarray:
        signal = truth_signals[signal_name]
        return _norm(_difference(truth[signal_name], np.asarray(trajectory.reference[f"{signal_name}_desired"]), signal), bool(signal.labels))

    diverged = ~finite
    if divergence is not None:
        signal_name, limit = divergence
        for norm in ([error_norm(signal_name)] if signal_name in estimate else []) + (
            [tracking_norm(signal_name)] if f"{signal_name}_desired" in trajectory.reference else []
        ):
            worst = np.where(np.isfinite(norm), norm, np.inf).max(axis=-1)
            diverged |= worst > limit

    out: dict[str, np.ndarray] = {}
    with np.errstate(invalid="ignore", over="ignore"):
        for metric in metrics:
            kind, name = metric.kind, metric.signal
            if kind in ("rms_error", "max_error", "settling_time"):
                norm = error_norm(name)
            elif kind in ("rms_tracking", "max_tracking"):
                norm = tracking_norm(name)
            elif kind == "max_excursion":
                signal = truth_signals[name]
                base = trajectory.reference.get(f"{name}_desired")
                base = np.asarray(base) if base is not None else truth[name][:, :1]
                norm = _norm(_difference(truth[name], base, signal), bool(signal.labels))
            elif kind in ("rms_input", "max_input"):
                norm = _norm(applied[name], bool(input_signals[name].labels))
            else:  # final
                array = truth[name] if name in truth else estimate[name]
                array = np.asarray(array)[:, -1]
                out[metric.variable] = np.sqrt((array.reshape(n_runs, -1) ** 2).sum(axis=1))
                continue
            part = norm[:, window]
            if kind.startswith("rms"):
                result = _rms(part)
            elif kind == "settling_time":
                from lookout.analysis import settling_time

                result = np.asarray(settling_time(norm, time, _rms(part)), dtype=float).reshape(n_runs)
            elif kind == "max_excursion":
                result = norm.max(axis=-1)
            else:
                result = part.max(axis=-1)
            out[metric.variable] = np.asarray(result, dtype=float)
    for variable in out:
        out[variable] = np.where(diverged, np.nan, out[variable])
    out["diverged"] = diverged
    return out
