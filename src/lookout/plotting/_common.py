"""Small helpers that several figures share."""

from __future__ import annotations

import numpy as np


def _runs(x: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """The (first, last) x of each run of consecutive True values of ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(float(x[start]), float(x[stop - 1])) for start, stop in zip(edges[::2], edges[1::2])]


def _minus(text: str) -> str:
    return text.replace("-", "\N{MINUS SIGN}")
