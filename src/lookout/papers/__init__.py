"""Reproduced publications: one module each, with a scenario, metrics and figures.

Every module has ``NAME``, ``TITLE``, a pydantic ``Config`` (seed, runs, duration and
the paper's settings), ``scenarios(config)`` (what it will simulate, for estimates
before running), ``run(config, out, progress=None) -> summary`` (simulates, writes
NetCDF, figures and summary.json) and ``tables(summary)`` (the summary for the
terminal). Importing this package enables float64 (via :mod:`lookout`).
"""

import lookout as _lookout  # noqa: F401  (enables jax_enable_x64)

from . import (
    calugi_2002_adaptive_observer,
    calugi_2002_backstepping,
    calugi_2002_furuta,
    calugi_2002_parameter_estimation,
    calugi_2002_velocity_observer,
    calugi_2003,
    fossen_strand_1999,
    kim_2002,
    wondergem_2009,
)

#: name -> module, in the order `lookout list` shows them
REPRODUCTIONS = {module.NAME: module for module in (fossen_strand_1999, calugi_2002_velocity_observer, calugi_2002_parameter_estimation, calugi_2002_adaptive_observer, calugi_2002_backstepping, calugi_2002_furuta, kim_2002, calugi_2003, wondergem_2009)}
