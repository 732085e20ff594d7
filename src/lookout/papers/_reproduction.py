"""The shape every reproduction has: data (its cases, each a composition of registered
components) plus checks (what it simulates, its metrics, figures and summary).

A paper module defines its pydantic ``Config``, a ``composition(config, case)`` that
returns the case as a composition (:mod:`lookout.composition`), a ``run`` that
simulates and writes its results, and ``tables`` for the terminal; then one subclass of
:class:`Reproduction` that names them, and ``REPRODUCTION``, its instance, which
:data:`lookout.papers.REPRODUCTIONS` gives by name. The scenario of a case, the
batches a run simulates (for the memory estimate), the presets of scenario files and
``--write-scenario`` all come from ``composition``: nothing else builds a scenario.
"""

from __future__ import annotations

import abc
from pathlib import Path
from typing import Callable, ClassVar


class Reproduction(abc.ABC):
    """A reproduced publication (see the module docstring)."""

    #: the name ``lookout reproduce`` takes (a key of :data:`lookout.papers.CATALOG`)
    name: ClassVar[str]
    #: the settings (pydantic, strict), with the paper's values as defaults
    Config: ClassVar[type]
    #: the cases, each a composition; the first is the default (a preset NAME is NAME:first)
    cases: ClassVar[tuple[str, ...]]

    @property
    def title(self) -> str:
        from lookout.papers import CATALOG

        return CATALOG[self.name].title

    @abc.abstractmethod
    def composition(self, config, case: str) -> dict:
        """The case as a composition: one table per component, every number given."""

    def scenario(self, config, case: str | None = None):
        """The :class:`~lookout.sim.Scenario` of ``case`` (the first when None)."""
        from lookout.composition import compose

        return compose(self.composition(config, self.cases[0] if case is None else case)).scenario

    def batches(self, config) -> list[tuple]:
        """(scenario, runs) of each vmapped batch :meth:`run` simulates, for the memory
        estimate before running: by default each case with ``config.runs`` runs."""
        return [(self.scenario(config, case), config.runs) for case in self.cases]

    @abc.abstractmethod
    def run(self, config, out: Path, *, progress: Callable | None = None) -> dict:
        """Simulate, write the NetCDF, figures and summary.json under ``out``; the summary."""

    @abc.abstractmethod
    def tables(self, summary: dict) -> list:
        """The summary as :class:`~lookout.papers._report.Table` s for the terminal."""
