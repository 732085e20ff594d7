"""Checks of user-supplied parameters, each failing with one clear line.

Every message names the parameter and the violated condition, so the CLI can
print it as is. Checks run only on concrete values: inside ``jit``/``vmap`` the
fields are tracers and the checks are skipped (they already ran when the
concrete object was built).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

# numpy is imported inside each check: the command's modules import InputError from
# here, and `lookout --help` needs neither NumPy nor JAX


def is_concrete(value: Any) -> bool:
    """True when ``value`` can be converted to NumPy (it is not a JAX tracer)."""
    import numpy as np

    try:
        np.asarray(value)
    except Exception:  # jax tracers raise TracerArrayConversionError (a TypeError subclass)
        return False
    return True


def vector(name: str, value: Any, size: int = 3):
    """Broadcast a scalar or sequence to a float vector of ``size``, or fail naming ``name``.

    Returns a NumPy array for concrete values, and a JAX array for tracers (a
    component built inside ``jit`` or ``vmap``); the shape is checked either way.
    """
    import numpy as np

    if not is_concrete(value):
        import jax.numpy as jnp  # a tracer: JAX is imported already

        array = jnp.asarray(value, dtype=float)
        if array.ndim == 0:
            array = jnp.broadcast_to(array, (size,))
        if array.shape != (size,):
            raise ParameterError(key(name), f"{name} must be a scalar or have {size} entries; got shape {array.shape}")
        return array
    values = np.asarray(value, dtype=float)
    if values.ndim == 0:
        values = np.full(size, float(values))
    if values.shape != (size,):
        raise ParameterError(key(name), f"{name} must be a scalar or have {size} entries; got shape {values.shape}")
    return values


def finite(name: str, value: Any) -> None:
    """Fail unless every entry of ``value`` is finite."""
    import numpy as np

    if is_concrete(value) and not np.all(np.isfinite(np.asarray(value, dtype=float))):
        raise ParameterError(key(name), f"{name} must be finite; got {np.asarray(value).tolist()}")


def positive(name: str, value: Any, *, allow_zero: bool = False) -> None:
    """Fail unless every entry of ``value`` is > 0 (or >= 0 with ``allow_zero``)."""
    import numpy as np

    if not is_concrete(value):
        return
    finite(name, value)
    array = np.asarray(value, dtype=float)
    bad = array < 0 if allow_zero else array <= 0
    if np.any(bad):
        condition = "non-negative" if allow_zero else "positive"
        raise ParameterError(key(name), f"{name} must be {condition}; got {_fmt(array)}")


def symmetric_positive_definite(name: str, matrix: Any, *, size: int | None = None) -> None:
    """Fail unless ``matrix`` is a symmetric positive-definite (``size`` x ``size``) matrix."""
    import numpy as np

    if not is_concrete(matrix):
        return
    finite(name, matrix)
    array = np.asarray(matrix, dtype=float)
    if array.ndim != 2 or array.shape[0] != array.shape[1] or (size is not None and array.shape != (size, size)):
        expected = f"{size}x{size}" if size is not None else "square"
        raise ParameterError(key(name), f"{name} must be a {expected} matrix; got shape {array.shape}")
    scale = max(np.abs(array).max(), np.finfo(float).tiny)
    asymmetry = np.abs(array - array.T).max()
    if asymmetry > 1e-9 * scale:
        raise ParameterError(key(name), f"{name} must be symmetric; max |{name} - {name}^T| is {asymmetry:.3g}")
    smallest = np.linalg.eigvalsh(array).min()
    if smallest <= 0:
        raise ParameterError(key(name), f"{name} must be symmetric positive definite; its smallest eigenvalue is {smallest:.3g}")


def dissipative(name: str, matrix: Any) -> None:
    """Fail unless the symmetric part of the square ``matrix`` is positive semi-definite
    (a damping matrix D that dissipates energy: nu^T D nu >= 0 for every nu)."""
    import numpy as np

    if not is_concrete(matrix):
        return
    array = np.asarray(matrix, dtype=float)
    smallest = float(np.linalg.eigvalsh(0.5 * (array + array.T)).min())
    if smallest < -1e-12 * max(np.abs(array).max(), np.finfo(float).tiny):
        raise ParameterError(
            key(name),
            f"{name} must have a positive semi-definite symmetric part (damping dissipates energy: nu^T D nu >= 0); "
            f"the smallest eigenvalue of (D + D^T)/2 is {smallest:.3g}",
        )


def square(name: str, matrix: Any, *, size: int = 3) -> None:
    """Fail unless ``matrix`` is a finite ``size`` x ``size`` matrix."""
    import numpy as np

    if not is_concrete(matrix):
        return
    finite(name, matrix)
    shape = np.shape(matrix)
    if shape != (size, size):
        raise ParameterError(key(name), f"{name} must be a {size}x{size} matrix; got shape {shape}")


def _fmt(array: np.ndarray) -> str:
    import numpy as np

    return np.array2string(np.atleast_1d(array), precision=4, separator=", ", threshold=SHOWN_ENTRIES, edgeitems=SHOWN_ENTRIES // 2)


#: The most entries of an array a message shows (a longer one is summarized, so that a
#: message stays one short line whatever the size of what was given).
SHOWN_ENTRIES = 8


def short(value) -> str:
    """``value`` as a message shows it: its repr, or for a sequence of more than
    :data:`SHOWN_ENTRIES` numbers its first and last few and its size."""
    import numpy as np

    if isinstance(value, (list, tuple, np.ndarray)):
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            array = None
        if array is not None and array.size > SHOWN_ENTRIES:
            flat = array.ravel()
            half = SHOWN_ENTRIES // 2
            shown = ", ".join(repr(float(v)) for v in flat[:half]) + ", ..., " + ", ".join(repr(float(v)) for v in flat[-half:])
            return f"[{shown}] ({array.size} entries{f', shape {array.shape}' if array.ndim > 1 else ''})"
        if isinstance(value, tuple):
            return repr(list(value))
    text = repr(value)
    return text if len(text) <= 200 else text[:200] + "..."


def one_line(message) -> str:
    """``message`` (text or an exception) on one line: its whitespace runs made one space."""
    return " ".join(str(message).split())


class ParameterError(ValueError):
    """A refusal of one parameter: ``location`` is the key path it concerns, as data
    (``("wave_frequency",)``, ``("sensor", "sample_period")``), so that a scenario file's
    error names the key and its line without reading the message; ``str()`` is the
    message, one line."""

    def __init__(self, location, message: str):
        self.location = (location,) if isinstance(location, str) else tuple(location)
        super().__init__(message)


class FitError(ValueError):
    """Two parts of a scenario that do not fit together: ``parts`` names them (roles,
    or a role and a setting); ``str()`` is the message, one line naming both."""

    def __init__(self, parts: tuple[str, str], message: str):
        self.parts = tuple(parts)
        super().__init__(message)


def key(name: str) -> str:
    """The key a check's ``name`` concerns: its last word, without an index
    (``"sensor sample_period[2]"`` -> ``"sample_period"``)."""
    words = name.split()
    return words[-1].split("[")[0] if words else name


class InputError(Exception):
    """Bad user input at the command line, reported as one line with exit code 2
    (defined here, not in :mod:`lookout.cli`, so that ``python -m lookout.cli`` and the
    command modules it loads share one class)."""


def table_number(location: tuple, value: Any, *, positive: bool = False, allow_inf: bool = False, inf_means: str = "to the run's end") -> float:
    """A number of a table's key (a failure's start, duration, size): ``>= 0`` (``> 0``
    with ``positive``), finite unless ``allow_inf`` (inf then means ``inf_means``); a
    :class:`ParameterError` at ``location`` otherwise."""
    name = location[-1]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(location, f"{name} must be a number; got {short(value)}")
    number = float(value)
    if math.isnan(number) or (math.isinf(number) and not allow_inf) or number < 0 or (positive and number == 0):
        bound = "> 0" if positive else ">= 0"
        what = f"a number {bound} (inf: {inf_means})" if allow_inf else f"a finite number {bound}"
        raise ParameterError(location, f"{name} must be {what}; got {value}")
    return number
