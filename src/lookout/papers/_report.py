"""What a reproduction reports at the command line: tables of plain strings, and number formats."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from lookout._json import json_safe


@dataclass(frozen=True)
class Table:
    """A table for the terminal: a title, column names, rows of strings, a caption."""

    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...] = field(default_factory=tuple)
    caption: str = ""


def _decade(value: float) -> int:
    return math.floor(math.log10(abs(value))) if value and math.isfinite(value) else 0


def significant(value: float, digits: int = 3) -> str:
    """``value`` to ``digits`` significant digits, without exponent between 0.01 and 1e5."""
    exponent = _decade(value)
    if not math.isfinite(value) or not -2 <= exponent < 5:
        return f"{value:.{digits - 1}e}"
    return f"{round(value, digits - 1 - exponent):.{max(0, digits - 1 - exponent)}f}"


def mean_and_spread(mean: float, spread: float) -> str:
    """``mean ± spread``, both rounded to the same decimal place.

    That place keeps three significant digits of the mean, or two of the spread
    where the spread is smaller (at most four of the mean); outside 0.01 to 1e5 both share the mean's power
    of ten: ``(1.35 ± 0.07)e-4``.
    """
    exponent = _decade(mean if mean else spread)
    place = exponent - 2
    if spread and math.isfinite(spread):
        place = min(place, _decade(spread) - 1)
    place = max(place, exponent - 3)
    if -2 <= exponent < 5:
        decimals = max(0, -place)
        return f"{round(mean, -place):.{decimals}f} ± {round(spread, -place):.{decimals}f}"
    scale = 10.0**exponent
    decimals = exponent - place
    return f"({mean / scale:.{decimals}f} ± {spread / scale:.{decimals}f})e{exponent}"


def sweep_rows(columns: dict[str, dict[str, dict]], key: str = "tracking_rms_m") -> tuple[tuple[str, ...], ...]:
    """A sweep's table rows: ``columns`` maps a column (a gain set, an observer) to row
    label -> ``{key: mean or None, "diverged": k, "seeds": n}``; a cell is the mean to 3
    significant digits ("-" when every seed diverged) and "(k/n div.)" when some did."""
    labels = list(next(iter(columns.values())))
    rows = []
    for label in labels:
        row = [label]
        for cells in columns.values():
            entry = cells[label]
            text = "-" if entry[key] is None else significant(entry[key])
            if entry["diverged"]:
                text += f" ({entry['diverged']}/{entry['seeds']} div.)"
            row.append(text)
        rows.append(tuple(row))
    return tuple(rows)


def save_figures(figures: dict, out) -> list[str]:
    """Write each matplotlib figure of ``{filename: figure}`` to ``out`` at 110 dpi, close
    it, and return the file names."""
    import matplotlib.pyplot as plt

    for filename, figure in figures.items():
        figure.savefig(out / filename, dpi=110)
        plt.close(figure)
    return list(figures)


def summary_header(name: str, config, status, *, runs: int | None = None, seeds=None) -> dict:
    """The keys every reproduction's summary.json starts with: its name, settings, runs,
    seeds and each run's status (runs and seeds: the config's unless given)."""
    return {
        "reproduction": name,
        "config": config.model_dump(),
        "runs": config.runs if runs is None else runs,
        "seeds": list(config.seeds if seeds is None else seeds),
        "status": [str(value) for value in status],
    }


def write_summary(summary: dict, out) -> dict:
    """Write ``summary`` as strict JSON (NaN and inf as null, see :func:`json_safe`) to
    ``out / "summary.json"`` and return the JSON-safe copy."""
    import json

    safe = json_safe(summary)
    (out / "summary.json").write_text(json.dumps(safe, indent=2, allow_nan=False))
    return safe
