"""The shape every reproduction has: data (its cases, each a composition of registered
components) plus checks (what it simulates, its metrics, figures and summary).

A paper module defines its pydantic ``Config``, ``composition(config, case)`` (the case
as a composition, :mod:`lookout.scenario.composition`), ``run(config, out, *, progress=None)``
(simulates and writes its results, returns the summary) and ``tables(summary)`` (the
summary for the terminal), and names them in one :class:`Reproduction`,
``REPRODUCTION``, which :data:`lookout.papers.REPRODUCTIONS` gives by name. The scenario
of a case, the batches a run simulates (for the memory check before running), the
presets of scenario files and ``--write-scenario`` all come from ``composition``:
nothing else builds a scenario.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

_Built = TypeVar("_Built")


@dataclass(frozen=True)
class Reproduction:
    """A reproduced publication (see the module docstring).

    Parameters
    ----------
    name : str
        The name ``lookout reproduce`` takes (a key of :data:`lookout.papers.CATALOG`).
    Config : type
        The settings (pydantic, strict), with the paper's values as defaults.
    cases : tuple of str
        The cases; the first is the default (preset ``NAME`` is ``NAME:first``).
    composition : callable
        ``(config, case) -> dict``: the case as a composition, every number given.
    run : callable
        ``(config, out, *, progress=None) -> summary``: simulate, write NetCDF, figures
        and summary.json under ``out``.
    tables : callable
        ``(summary) -> list of Table``: the summary for the terminal.
    batches_of : callable, optional
        ``(config) -> [(scenario, runs), ...]``: what ``run`` simulates, when it is not one
        batch of ``config.runs`` runs per case (studies, sweeps, a subset of the cases).
    """

    name: str
    Config: type
    cases: tuple[str, ...]
    composition: Callable[..., dict]
    run: Callable[..., dict]
    tables: Callable[[dict], list]
    batches_of: Callable[..., list] | None = None

    @property
    def title(self) -> str:
        from lookout.papers import CATALOG

        return CATALOG[self.name].title

    def scenario(self, config, case: str | None = None):
        """The :class:`~lookout.sim.Scenario` of ``case`` (the first when None)."""
        from lookout.scenario.composition import compose

        return compose(self.composition(config, self.cases[0] if case is None else case)).scenario

    def batches(self, config) -> list[tuple]:
        """(scenario, runs) of each vmapped batch :attr:`run` simulates, for the memory
        estimate before running: ``batches_of(config)``, or each case with ``config.runs`` runs."""
        if self.batches_of is not None:
            return self.batches_of(config)
        return [(self.scenario(config, case), config.runs) for case in self.cases]


def simulate_cases(reproduction: Reproduction, config, cases, coordinate: str, *, progress: Callable | None = None, parts: int | None = None):
    """Each case's runs over the seeds of ``config``, simulated as ``lookout run`` simulates
    the case's file (:func:`lookout.scenario.composition.simulate`), one case after another, and
    concatenated along ``run`` with the case in the coordinate ``coordinate`` and the
    seeds in ``seed``; ``progress(done, total)`` covers the cases as the first
    ``len(cases)`` of ``parts``."""
    import numpy as np
    import xarray as xr

    from lookout.scenario.composition import compose, simulate

    parts = len(cases) if parts is None else parts
    datasets = []
    for index, case in enumerate(cases):
        step = None if progress is None else (lambda done, total, index=index: progress(index + done / total, parts))
        datasets.append(simulate(compose(reproduction.composition(config, case)), progress=step).to_xarray())
    batched = [ds if "run" in ds.dims else ds.expand_dims("run") for ds in datasets]
    ds = xr.concat(batched, dim="run", data_vars="all", coords="minimal", compat="override", join="override")
    labels = [case for case in cases for _ in range(config.runs)]
    seeds = [seed for _ in cases for seed in config.seeds]
    return ds.assign_coords(
        {
            coordinate: ("run", np.asarray(labels, dtype=object)),
            "seed": ("run", np.asarray(seeds, dtype=np.int64), {"long_name": "PRNG seed of the run"}),
        }
    )


def simulate_each(cases, simulate_case: Callable, out, filename: str, history: Callable[[str], str], *, progress: Callable | None = None):
    """For each case in order: ``scenario, ds = simulate_case(case, progress=step)``, the
    dataset written to ``out / filename.format(case=case)`` with ``history(case)``;
    yields ``(case, scenario, ds, written file name)``. ``progress(done, total)`` covers
    the cases, one part each."""
    from lookout.results import write_netcdf

    cases = list(cases)
    for index, case in enumerate(cases):
        step = None if progress is None else (lambda done, total, index=index: progress(index + done / total, len(cases)))
        scenario, ds = simulate_case(case, progress=step)
        name = filename.format(case=case)
        write_netcdf(ds, out / name, history=history(case))
        yield case, scenario, ds, name


def built_as(component: object, kind: type[_Built], what: str) -> _Built:
    """``component``, a part of a scenario a reproduction's composition builds, as the
    class the composition builds it as; a TypeError names ``what`` when it is another."""
    if not isinstance(component, kind):
        raise TypeError(f"{what} is a {type(component).__name__}, not a {kind.__name__}")
    return component
