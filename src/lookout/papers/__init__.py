"""Reproduced publications: one module each, with a scenario, metrics and figures.

Importing this package enables float64 (via :mod:`lookout`).
"""

import lookout as _lookout  # noqa: F401  (enables jax_enable_x64)

from . import fossen_strand_1999

#: name -> module with NAME, TITLE, Config, build, run
REPRODUCTIONS = {fossen_strand_1999.NAME: fossen_strand_1999}
