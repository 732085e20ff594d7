"""Reports as strict JSON: plain Python numbers, lists and strings; non-finite numbers as None."""

from __future__ import annotations

import math


def finite_or_none(value):
    """``float(value)``, or None when it is not finite (NaN and Infinity are not JSON)."""
    value = float(value)
    return value if math.isfinite(value) else None


def json_safe(value):
    """``value`` with NumPy arrays and scalars made plain, non-finite floats None, and a
    complex number as ``{"real": ..., "imag": ...}``."""
    import numpy as np  # here, not at the top: the command's modules import this one, and `lookout --help` needs no NumPy

    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return finite_or_none(value)
    if isinstance(value, complex):
        return {"real": finite_or_none(value.real), "imag": finite_or_none(value.imag)}
    return value
