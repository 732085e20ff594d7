"""The observer benchmark's results: one Dataset, tables, figures and an HTML page.

:func:`collect` reads the campaign stores of a benchmark (one per observer,
:mod:`lookout.studies.benchmark`) into one :class:`xarray.Dataset` over
``(observer, condition, seed)``, with each observer's cost and what it is given.
:func:`write_results` writes, into the benchmark's folder:

- ``benchmark.nc``: that Dataset (NetCDF, CF attributes);
- ``table.md``: the tables in Markdown (what docs/choosing-an-observer.md quotes), and
  ``table.csv``: one row per observer, condition and metric (median, 10th and 90th
  percentiles over the seeds, runs diverged);
- ``figures/``: per RMS metric, its median per condition and observer (bars, 10-90 %
  spread as whiskers, on a log scale); the cost per sample; the outage's drift and
  recovery;
- ``report.html``: one self-contained page with the tables and the figures, linking
  each observer's campaign report (``reports/<store>.html``, the campaign report of
  :mod:`lookout.studies.report`).

Medians and percentiles are over the runs that did not diverge; a cell whose runs
diverged says how many.

**Which observer to pick** (:func:`recommend`), per condition, from the measured table:

1. The lead metric is, of ``recommend_by`` (the spec's; by default every
   ``rms_tracking`` metric, which only a closed loop has, then every ``rms_error``
   metric, in the spec's order: :func:`lead_metrics`), the one that the most observers
   have at the condition, the first of those on a tie (the DP vessel's position: every
   observer estimates it; an arm's joint rate, which the velocity observer estimates
   and its joint angle not).
2. An observer with a diverged run at the condition is not considered (and is named).
3. The others are ranked by their median over the seeds. Walking down the ranking,
   an observer is *clearly worse* than the best when its median is more than
   :data:`MARGIN` above the best's and the best has the lower value on enough of the
   paired seeds (every observer runs the same seeds) that a one-sided sign test
   rejects "either is as likely to be lower" at :data:`SIGN_LEVEL` (Conover, *Practical
   Nonparametric Statistics*, 3rd ed., Wiley 1999, Section 3.4, the sign test: under
   the null hypothesis the number of seeds the best wins is Binomial(n, 1/2)): all 4
   of 4 seeds, 12 of 16. The observers above the first clearly worse one are tied with
   the best; of them the cheapest (µs per sample; costs within :data:`COST_TIE` of the
   lowest count as equal, and then the lower median) is recommended, and the first
   clearly worse one is the "next" it is compared with (the ratio of the medians, and
   the costs).
4. With fewer seeds than the sign test needs (3 or fewer at 10 %), nothing can be
   separated: the lowest median is named, marked provisional.
"""

from __future__ import annotations

import csv
import html
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.figure import Figure

#: Percentiles of the spread.
LOW, HIGH = 10, 90
#: A median within this fraction of its column's best is marked best too (the Kalman
#: filters often tie to three digits).
TIE = 0.01
#: Kinds of metric with a table and a figure per condition.
PER_CONDITION = ("rms_error", "rms_tracking")
#: The recommendation: an observer is clearly worse than the best only if its median is
#: more than this fraction above the best's ...
MARGIN = 0.05
#: ... and a one-sided sign test over the paired seeds rejects a tie at this level.
SIGN_LEVEL = 0.10
#: Of the observers tied with the best, the cheapest is recommended; costs within this
#: fraction of the lowest count as equal (a timing's noise), and then the lower median.
COST_TIE = 0.10


def lead_metrics(metrics: Iterable[str]) -> list[str]:
    """The metrics that may lead the recommendation by default: every ``rms_tracking``
    metric (a closed loop's: what its user feels), then every ``rms_error`` metric, in
    the order of ``metrics`` (``KIND:SIGNAL``). At a condition, the one of them that
    the most observers have leads (the first of those)."""
    tracking = [name for name in metrics if name.startswith("rms_tracking:")]
    errors = [name for name in metrics if name.startswith("rms_error:")]
    return tracking + errors


def collect(
    stores: Mapping[str, str | Path | Sequence[str | Path]],
    costs: dict[str, float],
    told: dict[str, str],
    *,
    metrics: Sequence[str] = (),
    title: str = "",
    command: str = "",
    changes: dict[str, str] | None = None,
    conditions: list[str] | None = None,
    recommend_by: list[str] | None = None,
    skipped: Sequence[str] = (),
) -> xr.Dataset:
    """The benchmark's results as one Dataset over ``(observer, condition, seed)``:
    every metric of any observer (NaN where an observer does not estimate the signal,
    or does not run at the condition), in the order of ``metrics`` (``KIND:SIGNAL``;
    others after, by name), then ``diverged``, ``cost`` (us per sample) and ``told``
    per observer, and what each condition changes (``changes``: condition name ->
    words). An observer's results may be in several stores (a closed-loop condition
    is a campaign of its own); ``conditions`` orders them (default: as the stores
    have them). Attributes: ``recommend_by`` (JSON; default :func:`lead_metrics`) and
    ``skipped`` (JSON: what was not run, and why)."""
    import xarray as xr

    from lookout.studies.store import CampaignStore

    grids = {name: [CampaignStore(path).grid() for path in ([paths] if isinstance(paths, (str, Path)) else paths)] for name, paths in stores.items()}
    every = [grid for found in grids.values() for grid in found]
    if conditions is None:
        conditions = list(dict.fromkeys(str(c) for grid in every for c in grid["condition"].values))
    seeds = every[0]["seed"].values
    variables: dict[str, dict] = {}
    for grid in every:
        for name, array in grid.data_vars.items():
            if name not in variables and array.dims == ("condition", "seed"):
                variables[str(name)] = dict(array.attrs)  # a store names its variables with strings
    observers = list(stores)
    order = [name.replace(":", "__") for name in metrics]
    ranked = sorted(variables, key=lambda name: (name == "diverged", order.index(name) if name in order else len(order), name))
    data: dict[str, Any] = {}
    for name in ranked:
        attrs = variables[name]
        values = np.full((len(observers), len(conditions), len(seeds)), np.nan)
        for i, observer in enumerate(observers):
            for grid in grids[observer]:
                if name not in grid:
                    continue
                for k, condition in enumerate(str(c) for c in grid["condition"].values):
                    if condition in conditions:
                        values[i, conditions.index(condition)] = grid[name].values[k]
        data[name] = (("observer", "condition", "seed"), values, attrs)
    data["cost"] = (
        ("observer",),
        np.asarray([costs[o] for o in observers]),
        {"units": "us", "long_name": "cost per sample of the observer alone (one run, compiled)"},
    )
    ds = xr.Dataset(
        data,
        coords={
            "observer": ("observer", np.asarray(observers, dtype=object), {"long_name": "observer"}),
            "condition": ("condition", np.asarray(conditions, dtype=object), {"long_name": "condition (one change from the baseline)"}),
            "seed": ("seed", seeds, {"long_name": "PRNG seed of the run"}),
            "told": ("observer", np.asarray([told[o] for o in observers], dtype=object), {"long_name": "what the observer is given"}),
            "changes": (
                "condition",
                np.asarray([(changes or {}).get(c, "") for c in conditions], dtype=object),
                {"long_name": "what the condition changes from the baseline"},
            ),
        },
        attrs={
            "title": title,
            "Conventions": "CF-1.10",
            "history": command,
            "source": "lookout benchmark observers",
            "recommend_by": json.dumps(list(recommend_by) if recommend_by else lead_metrics(metrics)),
            "skipped": json.dumps(list(skipped)),
        },
    )
    return ds


# ------------------------------------------------------------------ which observer to pick


def sign_test_wins(n: int, level: float = SIGN_LEVEL) -> int | None:
    """The fewest of ``n`` paired seeds the better observer must win for a one-sided sign
    test to reject a tie at ``level`` (Conover 1999, Section 3.4): the smallest k with
    P(Binomial(n, 1/2) >= k) <= ``level``; None when not even n of n does."""
    needed, tail = None, 0
    for k in range(n, -1, -1):
        tail += math.comb(n, k)
        if tail / 2**n > level:
            break
        needed = k
    return needed


@dataclass(frozen=True)
class Recommendation:
    """Which observer to pick at one condition, and the numbers that say so (the rule:
    the module docstring)."""

    condition: str
    observer: str | None  # None: no observer has a value of a lead metric without diverging
    metric: str | None  # its variable, e.g. rms_error__position
    label: str  # e.g. "RMS position error"
    units: str
    value: float  # the observer's median of the metric
    cost: float  # its us per sample
    tied: tuple[str, ...] = ()  # observers not clearly worse than the best (the pick is the cheapest of them and the best)
    next: str | None = None  # the first clearly worse observer
    ratio: float = math.nan  # next's median / the pick's
    next_cost: float = math.nan
    seeds: int = 0
    provisional: bool = False  # too few seeds to separate any two observers
    excluded: tuple[str, ...] = ()  # observers with a diverged run here, "name (k of n runs diverged)"
    cheaper: bool = True  # cheaper than each observer it ties with by more than COST_TIE (else as cheap, and the lower median)

    def text(self) -> str:
        """One line: "rough sea: ekf, RMS position error 0.41 m, 1.8x better than passive
        (next), at 12 us per sample against 1.1 us"."""
        if self.observer is None:
            line = f"{self.condition}: no observer to recommend ({'every observer diverged' if self.excluded else 'no lead metric has a value'})"
        else:
            cheaper = (
                f"the {'cheaper' if len(self.tied) == 1 else 'cheapest'}" if self.cheaper else f"as cheap (within {COST_TIE:.0%}), the lower median"
            )
            pick = self.observer + (f" (tied with {', '.join(self.tied)}; {cheaper})" if self.tied else "")
            units = f" {self.units}" if self.units and self.units != "1" else ""
            line = f"{self.condition}: {pick}, {self.label} {_number(self.value)}{units}"
            if self.next is not None:
                line += (
                    f", {_ratio(self.ratio)} than {self.next} (next)"
                    if self.provisional is False
                    else f", {_ratio(self.ratio)} than {self.next} by the medians"
                )
                line += f", at {_number(self.cost)} us per sample against {_number(self.next_cost)} us"
            else:
                line += f", at {_number(self.cost)} us per sample" + (" (the only observer measured)" if not self.tied else "")
            if self.provisional:
                line += f"; provisional: {self.seeds} seed{'s' * (self.seeds != 1)} cannot separate observers (a sign test at {SIGN_LEVEL:.0%} needs {_fewest_seeds()})"
        if self.excluded:
            line += f"; not considered: {', '.join(self.excluded)}"
        return line

    def as_dict(self) -> dict:
        found = asdict(self)
        found["text"] = self.text()
        return found


def _fewest_seeds() -> int:
    return next(n for n in range(1, 64) if sign_test_wins(n) is not None)


def _ratio(ratio: float) -> str:
    if not np.isfinite(ratio):
        return "infinitely better"
    if ratio < 1.0:
        return f"{1 / ratio:.3g}x worse"  # only with too few seeds to call the order (provisional)
    return f"{ratio:.0f}x better" if ratio >= 10 else f"{ratio:.1f}x better" if ratio >= 1.1 else f"{ratio:.2f}x better"


_LABELS = {
    "rms_error": "RMS {} error",
    "max_error": "largest {} error",
    "rms_tracking": "RMS {} tracking error",
    "max_tracking": "largest {} tracking error",
    "settling_time": "settling time of the {} error",
    "outage_drift": "{} drift in the outage",
    "recovery_time": "recovery time of {}",
    "max_excursion": "largest {} excursion",
    "rms_input": "RMS {}",
    "max_input": "largest {}",
}


def short_label(name: str) -> str:
    """``rms_error__position`` -> ``RMS position error``."""
    kind, signal = _metric_parts(name)
    return _LABELS.get(kind, kind.replace("_", " ") + " of {}").format(signal.replace("_", " "))


def recommend(ds: xr.Dataset) -> list[Recommendation]:
    """The recommendation per condition of a benchmark's Dataset (:func:`collect`), by
    the rule of the module docstring."""
    lead = [name.replace(":", "__") for name in json.loads(ds.attrs.get("recommend_by") or "[]")]
    lead = [name for name in lead if name in ds] or [
        n for n in (x.replace(":", "__") for x in lead_metrics([v.replace("__", ":") for v in _variables(ds)])) if n in ds
    ]
    observers = [str(o) for o in ds.observer.values]
    cost = np.asarray(ds.cost.values, dtype=float)
    found = []
    for j, condition in enumerate(str(c) for c in ds.condition.values):
        diverged = ds["diverged"].values[:, j, :]
        excluded, candidates = [], []
        for i, name in enumerate(observers):
            finished = np.isfinite(diverged[i])
            bad = int(np.sum(diverged[i][finished] > 0.5))
            if bad:
                excluded.append(f"{name} ({bad} of {int(finished.sum())} runs diverged)")
            elif finished.any():
                candidates.append(i)
        # the lead metric: of the lead metrics, the one the most observers have here (the first of those)
        coverage = {m: sum(bool(np.isfinite(ds[m].values[i, j]).any()) for i in candidates) for m in lead}
        metric = max(lead, key=lambda m: (coverage[m], -lead.index(m))) if lead and max(coverage.values()) > 0 else None
        if metric is None:
            found.append(Recommendation(condition, None, None, "", "", math.nan, math.nan, excluded=tuple(excluded)))
            continue
        values = ds[metric].values[:, j, :]
        median = {i: float(np.median(values[i][np.isfinite(values[i])])) for i in candidates if np.isfinite(values[i]).any()}
        ranking = sorted(median, key=lambda i: (median[i], observers[i]))
        best = ranking[0]
        paired = [np.isfinite(values[best]) & np.isfinite(values[i]) for i in ranking]
        seeds = int(max(p.sum() for p in paired))
        provisional = sign_test_wins(seeds) is None

        def clearly_worse(i: int) -> bool:
            both = np.isfinite(values[best]) & np.isfinite(values[i])
            needed = sign_test_wins(int(both.sum()))
            wins = int(np.sum(values[best][both] < values[i][both]))
            return needed is not None and wins >= needed and median[i] > (1.0 + MARGIN) * median[best]

        if provisional:
            group, following = [best], (ranking[1] if len(ranking) > 1 else None)
        else:
            following = next((i for i in ranking[1:] if clearly_worse(i)), None)
            group = ranking[: ranking.index(following)] if following is not None else ranking
        lowest = min(cost[i] for i in group)
        pick = min(group, key=lambda i: (cost[i] > (1.0 + COST_TIE) * lowest, median[i]))
        cheaper = all(cost[i] > (1.0 + COST_TIE) * cost[pick] for i in group if i != pick)
        ratio = (median[following] / median[pick] if median[pick] > 0 else math.inf) if following is not None else math.nan
        found.append(
            Recommendation(
                condition,
                observers[pick],
                metric,
                short_label(metric),
                ds[metric].attrs.get("units", ""),
                median[pick],
                float(cost[pick]),
                tuple(observers[i] for i in group if i != pick),
                None if following is None else observers[following],
                ratio,
                math.nan if following is None else float(cost[following]),
                seeds,
                provisional,
                tuple(excluded),
                cheaper,
            )
        )
    return found


def overall(recommendations: list[Recommendation]) -> str:
    """One line: which observer is recommended at how many conditions."""
    counts: dict[str, int] = {}
    for each in recommendations:
        if each.observer is not None:
            counts[each.observer] = counts.get(each.observer, 0) + 1
    ranked = sorted(counts.items(), key=lambda item: -item[1])
    return f"over {len(recommendations)} condition{'s' * (len(recommendations) != 1)}: " + (
        ", ".join(f"{name} recommended at {count}" for name, count in ranked) or "no recommendation"
    )


def recommendation_rule() -> str:
    """The rule, in one paragraph (for the tables and the report)."""
    return (
        f"Per condition, by {{lead}}: observers with a diverged run are not considered; "
        f"the others are ranked by their median; an observer is clearly worse than the best when its median is more than {MARGIN:.0%} above "
        f"and the best is lower on enough of the paired seeds for a one-sided sign test at {SIGN_LEVEL:.0%} ({sign_test_wins(4)} of 4, "
        f"{sign_test_wins(16)} of 16); the observers ranked above the first clearly worse one tie with the best, and the cheapest of them "
        f"is recommended (costs within {COST_TIE:.0%} count as equal, and then the lower median)."
    )


def _variables(ds: xr.Dataset) -> list[str]:
    """The names of the data variables of a benchmark's Dataset (strings, as :func:`collect`
    and NetCDF give them)."""
    return [str(name) for name in ds.data_vars]


def _metric_parts(name: str) -> tuple[str, str]:
    kind, _, signal = name.partition("__")
    return kind, signal


def _statistics(values: np.ndarray, diverged: np.ndarray) -> tuple[float, float, float, int, int]:
    """(median, low, high, runs diverged, runs) of one cell, over the runs that did not diverge."""
    finished = np.isfinite(diverged)
    bad = int(np.sum(diverged[finished] > 0.5))
    good = values[finished & (diverged < 0.5) & np.isfinite(values)]
    if good.size == 0:
        return np.nan, np.nan, np.nan, bad, int(finished.sum())
    low, median, high = np.percentile(good, [LOW, 50, HIGH])
    return float(median), float(low), float(high), bad, int(finished.sum())


def _number(value: float) -> str:
    if not np.isfinite(value):
        return "—"
    if value == 0:
        return "0"
    if abs(value) >= 1e4 or abs(value) < 1e-2:
        return f"{value:.2e}"
    return f"{value:.3g}"


def metric_label(ds: xr.Dataset, name: str) -> str:
    attrs = ds[name].attrs
    kind, signal = _metric_parts(name)
    return f"{kind.replace('_', ' ')} of {signal.replace('_', ' ')} ({attrs.get('units', '')})"


def cell_table(ds: xr.Dataset, name: str) -> tuple[list[str], list[list[str]]]:
    """Rows observer, columns condition: the median of ``name`` (the best of each column,
    and those within :data:`TIE` of it, marked **bold** in Markdown), with the runs
    diverged where any did."""
    header = ["observer"] + [str(c) for c in ds.condition.values]
    medians = np.full((ds.sizes["observer"], ds.sizes["condition"]), np.nan)
    cells = []
    for i in range(ds.sizes["observer"]):
        statistics = []
        for j in range(ds.sizes["condition"]):
            median, _, _, bad, runs = _statistics(ds[name].values[i, j], ds["diverged"].values[i, j])
            medians[i, j] = median
            statistics.append((median, bad, runs))
        cells.append(statistics)
    best = np.nanmin(np.where(np.isfinite(medians), medians, np.inf), axis=0)
    rows = []
    for i, observer in enumerate(ds.observer.values):
        row = [str(observer)]
        for j, (median, bad, runs) in enumerate(cells[i]):
            text = _number(median)
            if np.isfinite(median) and np.isfinite(best[j]) and median <= best[j] * (1.0 + TIE):
                text = f"**{text}**"
            if bad:
                text += f" ({bad}/{runs} diverged)"
            row.append(text)
        rows.append(row)
    return header, rows


def summary_table(ds: xr.Dataset, outage: tuple[str, str | None] | None, convergence: str | None) -> tuple[list[str], list[list[str]]]:
    """One row per observer: what it is given, its cost, runs diverged, and (where the
    metrics hold them) its convergence time at the baseline and its outage drift and
    recovery."""
    header = ["observer", "given", "cost (µs/sample)", "runs diverged"]
    if convergence:
        header.append(f"converges in (s), {ds.condition.values[0]}")
    if outage:
        header += ["outage drift", "recovery (s)"]
    rows = []
    for i, observer in enumerate(ds.observer.values):
        diverged = ds["diverged"].values[i]
        finished = np.isfinite(diverged)
        row = [
            str(observer),
            str(ds.told.values[i]),
            _number(float(ds.cost.values[i])),
            f"{int(np.sum(diverged[finished] > 0.5))} of {int(finished.sum())}",
        ]
        if convergence:
            median = _statistics(ds[convergence].values[i, 0], diverged[0])[0] if convergence in ds else np.nan
            row.append(_number(median))
        if outage:
            drift_name, recovery_name = outage
            values = ds[drift_name].values[i]
            j = int(np.argmax(np.isfinite(values).any(axis=1))) if np.isfinite(values).any() else 0
            drift = _statistics(values[j], diverged[j])[0]
            recovery = _statistics(ds[recovery_name].values[i, j], diverged[j])[0] if recovery_name in ds else np.nan
            units = ds[drift_name].attrs.get("units", "")
            row += [f"{_number(drift)} {units}" if np.isfinite(drift) else "—", _number(recovery)]
        rows.append(row)
    return header, rows


def _markdown(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell.replace("|", "/") for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def _names(ds: xr.Dataset) -> tuple[list[str], tuple[str, str | None] | None, str | None]:
    """(per-condition metrics, (drift, recovery) names or None, convergence name or None)."""
    names = _variables(ds)
    metrics = [n for n in names if "__" in n and _metric_parts(n)[0] in PER_CONDITION]
    drift = next((n for n in names if n.startswith("outage_drift__")), None)
    recovery = next((n for n in names if n.startswith("recovery_time__")), None)
    convergence = next((n for n in names if n.startswith("settling_time__")), None)
    return metrics, ((drift, recovery) if drift else None), convergence


def markdown(ds: xr.Dataset) -> str:
    """The benchmark's tables in Markdown."""
    metrics, outage, convergence = _names(ds)
    parts = [f"### {ds.attrs.get('title', 'benchmark')}", ""]
    if ds.attrs.get("history"):
        parts += [f"`{ds.attrs['history']}`", ""]
    seeds = ds.sizes["seed"]
    parts += [
        f"Each cell: the median over {seeds} seeds (the same seeds for every observer); **bold**: the best of the column and those "
        f"within {TIE:.0%} of it; —: no value (the observer does not estimate the signal; for the outage, no outage or no recovery "
        "within the run).",
        "",
    ]
    recommendations = recommend(ds)
    parts += ["#### Which observer", ""] + [f"- {each.text()}" for each in recommendations] + ["", overall(recommendations) + ".", ""]
    parts += [rule_text(ds), ""]
    parts += [_markdown(*conditions_table(ds)), ""]
    parts += [_markdown(*summary_table(ds, outage, convergence)), ""]
    skipped = json.loads(ds.attrs.get("skipped") or "[]")
    if skipped:
        parts += ["Not run:", ""] + [f"- {line}" for line in skipped] + [""]
    for name in metrics:
        parts += [f"#### {metric_label(ds, name)}", "", _markdown(*cell_table(ds, name)), ""]
    return "\n".join(parts)


def rule_text(ds: xr.Dataset) -> str:
    """The recommendation's rule with this benchmark's lead metrics."""
    lead = [short_label(name.replace(":", "__")) for name in json.loads(ds.attrs.get("recommend_by") or "[]")]
    words = (
        f"the {lead[0]}"
        if len(lead) == 1
        else f"the one of {', '.join(lead)} that the most observers have there (the first on a tie)"
        if lead
        else "the RMS errors"
    )
    return recommendation_rule().format(lead=words)


def conditions_table(ds: xr.Dataset) -> tuple[list[str], list[list[str]]]:
    """What each condition changes from the baseline."""
    return ["condition", "changes"], [[str(c), str(w) or "nothing (the baseline)"] for c, w in zip(ds.condition.values, ds.changes.values)]


def rows_csv(ds: xr.Dataset) -> list[dict]:
    """One row per observer, condition and metric: median, percentiles, runs diverged."""
    rows = []
    for name in [n for n in _variables(ds) if "__" in n]:
        for i, observer in enumerate(ds.observer.values):
            for j, condition in enumerate(ds.condition.values):
                median, low, high, bad, runs = _statistics(ds[name].values[i, j], ds["diverged"].values[i, j])
                rows.append(
                    {
                        "observer": observer,
                        "condition": condition,
                        "metric": name.replace("__", ":"),
                        "units": ds[name].attrs.get("units", ""),
                        "median": median,
                        f"p{LOW}": low,
                        f"p{HIGH}": high,
                        "runs": runs,
                        "diverged": bad,
                        "cost_us": float(ds.cost.values[i]),
                    }
                )
    return rows


# ------------------------------------------------------------------ figures


def _colors(count: int):
    import matplotlib

    palette = matplotlib.colormaps["tab10"]
    return [palette(i % 10) for i in range(count)]


def metric_figure(ds: xr.Dataset, name: str) -> Figure:
    """Median per condition and observer (markers), 10-90 % whiskers, log scale."""
    import matplotlib.pyplot as plt

    observers, conditions = list(ds.observer.values), list(ds.condition.values)
    figure, ax = plt.subplots(figsize=(11.0, 4.2), dpi=100, layout="constrained")
    width = 0.8 / len(observers)
    x = np.arange(len(conditions))
    for i, (observer, color) in enumerate(zip(observers, _colors(len(observers)))):
        stats = [_statistics(ds[name].values[i, j], ds["diverged"].values[i, j]) for j in range(len(conditions))]
        median = np.asarray([s[0] for s in stats])
        low = np.asarray([s[1] for s in stats])
        high = np.asarray([s[2] for s in stats])
        if not np.isfinite(median).any():
            continue
        position = x - 0.4 + width * (i + 0.5)
        # markers, not bars: a bar's length means nothing on a log scale
        ax.errorbar(
            position, median, yerr=[median - low, high - median], fmt="o", color=color, markersize=5, elinewidth=1.2, capsize=2.5, label=str(observer)
        )
        for j, s in enumerate(stats):
            if s[3]:
                ax.annotate(
                    f"{s[3]} div.",
                    (position[j], np.nanmax([median[j], 1e-300]) if np.isfinite(median[j]) else 1.0),
                    fontsize=7,
                    ha="center",
                    va="bottom",
                    rotation=90,
                )
    _log_axis(ax.yaxis)
    ax.set_xticks(x, conditions, rotation=20, ha="right")
    for edge in x[:-1] + 0.5:
        ax.axvline(edge, color="0.85", linewidth=0.8)
    ax.set_xlim(-0.5, len(conditions) - 0.5)
    ax.set_ylabel(metric_label(ds, name))
    ax.set_title(f"{metric_label(ds, name)}: median over {ds.sizes['seed']} seeds, whiskers {LOW}-{HIGH} %")
    ax.grid(axis="y", which="both", alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False, title="observer")
    return figure


def _log_axis(axis) -> None:
    """A log scale whose ticks read as plain numbers (0.3, 1, 2), not powers of ten."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    if axis is axis.axes.yaxis:
        axis.axes.set_yscale("log")
    else:
        axis.axes.set_xscale("log")
    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(FuncFormatter(lambda value, _: ""))


def cost_figure(ds: xr.Dataset) -> Figure:
    """Cost per sample of each observer alone (log scale)."""
    import matplotlib.pyplot as plt

    figure, ax = plt.subplots(figsize=(7.0, 0.5 + 0.45 * ds.sizes["observer"]), dpi=100, layout="constrained")
    observers = list(ds.observer.values)
    cost = ds.cost.values
    ax.barh(np.arange(len(observers)), cost, color=_colors(len(observers)))
    for i, value in enumerate(cost):
        ax.annotate(f" {_number(float(value))} µs", (value, i), va="center", fontsize=8)
    ax.set_yticks(np.arange(len(observers)), observers)
    ax.invert_yaxis()
    _log_axis(ax.xaxis)
    ax.set_xlim(right=ax.get_xlim()[1] * 4)
    ax.set_xlabel("µs per sample (the observer alone, one run, compiled)")
    ax.set_title("what each observer costs")
    ax.grid(axis="x", which="both", alpha=0.3)
    return figure


def outage_figure(ds: xr.Dataset, drift: str, recovery: str | None) -> Figure:
    """The outage condition: drift of the estimate during it and recovery after it."""
    import matplotlib.pyplot as plt

    observers = list(ds.observer.values)
    values = ds[drift].values
    j = int(np.argmax(np.isfinite(values).any(axis=(0, 2)))) if np.isfinite(values).any() else 0
    panels = [drift] + ([recovery] if recovery else [])
    figure, axes = plt.subplots(1, len(panels), figsize=(11.0, 3.6), dpi=100, layout="constrained", squeeze=False)
    for ax, name in zip(axes[0], panels):
        stats = [_statistics(ds[name].values[i, j], ds["diverged"].values[i, j]) for i in range(len(observers))]
        median = np.asarray([s[0] for s in stats])
        low = np.asarray([s[1] for s in stats])
        high = np.asarray([s[2] for s in stats])
        ax.bar(np.arange(len(observers)), np.where(np.isfinite(median), median, 0.0), color=_colors(len(observers)))
        ax.errorbar(np.arange(len(observers)), median, yerr=[median - low, high - median], fmt="none", ecolor="black", elinewidth=0.8, capsize=3)
        for i, value in enumerate(median):
            if not np.isfinite(value):
                ax.annotate("no value", (i, 0.0), ha="center", va="bottom", fontsize=8, color="0.4", rotation=90)
        ax.set_xticks(np.arange(len(observers)), observers, rotation=20, ha="right")
        ax.set_ylabel(metric_label(ds, name))
        ax.grid(axis="y", alpha=0.3)
    figure.suptitle(f"{ds.condition.values[j]}: median over {ds.sizes['seed']} seeds, whiskers {LOW}-{HIGH} %")
    return figure


def figures(ds: xr.Dataset) -> dict[str, Figure]:
    """File name -> matplotlib figure, for every figure of the benchmark."""
    metrics, outage, _ = _names(ds)
    found = {f"{name}.png": metric_figure(ds, name) for name in metrics}
    found["cost.png"] = cost_figure(ds)
    if outage:
        found["outage.png"] = outage_figure(ds, *outage)
    return found


# ------------------------------------------------------------------ writing


def _markdown_cell(text: str) -> str:
    """A Markdown cell as HTML (bold and nothing else)."""
    escaped = html.escape(text)
    if escaped.startswith("**"):
        head, _, rest = escaped[2:].partition("**")
        return f"<b>{head}</b>{rest}"
    return escaped


def _html_table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "\n".join("<tr>" + "".join(f"<td>{_markdown_cell(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1400px; padding: 0 1em; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
img { max-width: 100%; height: auto; }
figure { margin: 1em 0; }
code { background: #f5f5f5; padding: 0 0.2em; }
"""


def write_results(ds: xr.Dataset, folder: Path, reports: dict[str, Path] | None = None) -> dict[str, Path]:
    """Write ``benchmark.nc``, ``table.md``, ``table.csv``, ``figures/*.png`` and
    ``report.html`` into ``folder``; return name -> path."""
    import base64
    import io

    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    written = {}
    netcdf = ds.copy()
    for name in ("observer", "condition", "told", "changes"):
        netcdf[name] = netcdf[name].astype(str)
    path = folder / "benchmark.nc"
    netcdf.to_netcdf(path)
    written["netcdf"] = path
    text = markdown(ds)
    (folder / "table.md").write_text(text + "\n", encoding="utf-8")
    written["table"] = folder / "table.md"
    rows = rows_csv(ds)
    with open(folder / "table.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    written["csv"] = folder / "table.csv"
    images = {}
    figure_folder = folder / "figures"
    figure_folder.mkdir(exist_ok=True)
    for name, figure in figures(ds).items():
        buffer = io.BytesIO()
        figure.savefig(buffer, format="png", dpi=150)
        plt.close(figure)
        images[name] = buffer.getvalue()
        (figure_folder / name).write_bytes(images[name])
    written["figures"] = figure_folder
    metrics, outage, convergence = _names(ds)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f"<title>{html.escape(ds.attrs.get('title', 'benchmark'))}</title>",
        f"<style>{STYLE}</style>",
        "</head>",
        "<body>",
        f"<h1>{html.escape(ds.attrs.get('title', 'benchmark'))}</h1>",
    ]
    if ds.attrs.get("history"):
        parts.append(f"<p>Made by <code>{html.escape(ds.attrs['history'])}</code>.</p>")
    parts.append(
        f"<p>Medians over {ds.sizes['seed']} seeds, the same for every observer; the best of each column, and those within "
        f"{TIE:.0%} of it, in bold; —: no value (the observer does not estimate the signal; for the outage, no outage or no "
        "recovery within the run).</p>"
    )
    recommendations = recommend(ds)
    items = "".join(f"<li>{html.escape(each.text())}</li>" for each in recommendations)
    parts += [
        "<h2>Which observer</h2>",
        f"<ul>{items}</ul>",
        f"<p>{html.escape(overall(recommendations))}.</p>",
        f"<p>{html.escape(rule_text(ds))}</p>",
    ]
    parts += ["<h2>The conditions</h2>", _html_table(*conditions_table(ds))]
    parts += ["<h2>The observers</h2>", _html_table(*summary_table(ds, outage, convergence))]
    skipped = json.loads(ds.attrs.get("skipped") or "[]")
    if skipped:
        parts += ["<p>Not run:</p>", "<ul>" + "".join(f"<li>{html.escape(line)}</li>" for line in skipped) + "</ul>"]
    parts += [f'<figure><img src="data:image/png;base64,{base64.b64encode(images["cost.png"]).decode()}" alt="cost per sample"></figure>']
    for name in metrics:
        parts += [
            f"<h2>{html.escape(metric_label(ds, name))}</h2>",
            _html_table(*cell_table(ds, name)),
            f'<figure><img src="data:image/png;base64,{base64.b64encode(images[name + ".png"]).decode()}" alt="{html.escape(name)}"></figure>',
        ]
    if outage:
        parts += [
            "<h2>The outage</h2>",
            f'<figure><img src="data:image/png;base64,{base64.b64encode(images["outage.png"]).decode()}" alt="outage"></figure>',
        ]
    if reports:
        links = "".join(f'<li><a href="{html.escape(str(path.relative_to(folder)))}">{html.escape(name)}</a></li>' for name, path in reports.items())
        parts += ["<h2>Each observer's campaign</h2>", f"<ul>{links}</ul>"]
    parts += ["</body>", "</html>"]
    (folder / "report.html").write_text("\n".join(parts) + "\n", encoding="utf-8")
    written["report"] = folder / "report.html"
    from lookout._json import json_safe

    summary = {
        "title": ds.attrs.get("title"),
        "cost_us": dict(zip(map(str, ds.observer.values), map(float, ds.cost.values))),
        "recommendations": [each.as_dict() for each in recommendations],
        "skipped": skipped,
    }
    (folder / "summary.json").write_text(json.dumps(json_safe(summary), indent=2, allow_nan=False) + "\n")
    return written
