"""Reproduced publications: one module (or package) each, data plus checks.

Every module defines its pydantic ``Config`` (seed, runs, duration and the paper's
settings), ``composition(config, case)`` (each case as a composition of registered
components, :mod:`lookout.scenario.composition`), ``run(config, out, progress=None) -> summary``
(simulates, writes NetCDF, figures and summary.json), ``tables(summary)`` (the summary
for the terminal), and ``REPRODUCTION``: its :class:`~lookout.papers._reproduction.Reproduction`.
Importing this package enables float64 (via :mod:`lookout`).

:data:`CATALOG` names them without importing them (``lookout list`` reads it);
:data:`REPRODUCTIONS` gives each one's ``REPRODUCTION``, its module imported when it is
first asked for.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from typing import NamedTuple

import lookout as _lookout  # noqa: F401  (enables jax_enable_x64)


class Entry(NamedTuple):
    """A reproduction: its module (in this package) and its title."""

    module: str
    title: str


#: name -> (module, title), in the order `lookout list` shows them; each module's
#: NAME and TITLE are these (tests/test_cli.py checks)
CATALOG: dict[str, Entry] = {
    "fossen-strand-1999": Entry("fossen_strand_1999", "Fossen & Strand (1999): passive observer on Northern Clipper, simulation study (Section 6.1)"),
    "calugi-2002-velocity-observer": Entry(
        "calugi_2002_velocity_observer", "Calugi (2002), ch. 2: reduced-order velocity observer on four manipulators (Section 2.3)"
    ),
    "calugi-2002-parameter-estimation": Entry(
        "calugi_2002_parameter_estimation", "Calugi (2002), ch. 3: on-line parameter estimation (Middleton–Goodwin) on the pendulum, Figs. 3.2–3.3"
    ),
    "calugi-2002-adaptive-observer": Entry(
        "calugi_2002_adaptive_observer",
        "Calugi (2002), ch. 4: adaptive observer with resetting on a pendulum of unknown mass (Section 4.8, Figs. 4.2–4.3)",
    ),
    "calugi-2002-backstepping": Entry(
        "calugi_2002_backstepping", "Calugi (2002), ch. 5: adaptive observer backstepping on a two-link arm, m2 unknown (Section 5.3, Figs. 5.1–5.2)"
    ),
    "calugi-2002-furuta": Entry("calugi_2002_furuta", "Calugi (2002), ch. 6: the Furuta pendulum experiments I–IV in simulation (Figs. 6.2–6.18)"),
    "kim-2002": Entry("kim_2002", "Kim (2002): sliding-mode observer and observer backstepping on Northern Clipper (Section 5, Figs. 4-8)"),
    "calugi-2003": Entry(
        "calugi_2003", "Calugi, Robertsson & Johansson (2003): adaptive observer (unknown m11) and vectorial backstepping (Section V)"
    ),
    "wondergem-2009": Entry(
        "wondergem_2009", "Wondergem, Lefeber, Pettersen & Nijmeijer (2009): output-feedback tracking of Cybership II (Section 5, Table 1)"
    ),
}


class _Reproductions(Mapping):
    """name -> its :class:`~lookout.papers._reproduction.Reproduction`, importing the
    module when it is first asked for."""

    def __getitem__(self, name: str):
        return importlib.import_module(f"{__name__}.{CATALOG[name].module}").REPRODUCTION

    def __iter__(self) -> Iterator[str]:
        return iter(CATALOG)

    def __len__(self) -> int:
        return len(CATALOG)


#: name -> Reproduction, in the order `lookout list` shows them
REPRODUCTIONS: Mapping = _Reproductions()
