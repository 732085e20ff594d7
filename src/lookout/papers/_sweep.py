"""A reproduction's sweep as a campaign: the same spec, store and metrics as
``lookout campaign run`` (:mod:`lookout.studies`), computed in this process.

A paper module writes its sweep as a campaign document (its base case as the
scenario, its axes, the campaign metrics it reports); :func:`run_sweep` validates it,
computes its chunks into a store beside the reproduction's other results and returns
the store as a grid. The store can be read, reported (``lookout campaign report``)
and resumed like any campaign's.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path


def whole_run_campaign(scenario: dict, *, seeds: int, seed: int, metrics: list[str], divergence: tuple[str, float], axes: dict[str, dict]) -> dict:
    """A grid campaign whose metrics cover the whole run (``after = 0``): ``axes`` maps
    an axis name to its cases (label -> key path -> value); ``divergence`` is
    (signal, limit)."""
    return {
        "scenario": scenario,
        "seeds_per_point": seeds,
        "seed": seed,
        "metrics": list(metrics),
        "after": 0.0,
        "divergence": {"signal": divergence[0], "limit": divergence[1]},
        "sweep": {"kind": "grid", "axes": [{"name": name, "labels": list(cases), "cases": list(cases.values())} for name, cases in axes.items()]},
    }


def run_sweep(document: dict, store: Path, *, source: str, progress: Callable[[float, float], None] | None = None):
    """Compute the campaign ``document`` into the store at ``store`` and return it as a
    grid (:meth:`lookout.studies.store.CampaignStore.grid`).

    A store there that holds another campaign (an earlier reproduction with other
    settings) is replaced, as the reproduction's other files are; one that holds this
    campaign is resumed. ``progress(done, total)`` counts chunks."""
    from lookout.studies.campaign import campaign_from_document
    from lookout.studies.execute import run_campaign
    from lookout.studies.store import CampaignStore

    campaign = campaign_from_document(document, source)
    held = CampaignStore(store)
    if held.campaign_document() is not None:
        try:
            held.holds(campaign)
        except ValueError:  # another campaign's store, written by this reproduction before
            shutil.rmtree(store)
    run_campaign(campaign, store, workers=0, say=lambda text: None, progress=progress)
    return CampaignStore(store).grid()
