"""Every file in examples/ works as its header says: a scenario file composes and runs
(20 simulated seconds here, with finite estimates; a sensor's failures moved into them),
a campaign spec validates (every point built, every metric applicable)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import jax
import numpy as np
import pytest

from lookout.scenario._toml import read
from lookout.scenario.composition import compose, simulate
from lookout.studies.campaign import load_campaign

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.toml"))
SECONDS = 20.0


def test_there_are_examples_of_each_kind():
    campaigns = [path for path in EXAMPLES if "scenario" in tomllib.loads(path.read_text())]
    assert len(campaigns) >= 3 and len(EXAMPLES) - len(campaigns) >= 6, [path.name for path in EXAMPLES]


@pytest.mark.slow
@pytest.mark.parametrize("path", EXAMPLES, ids=lambda path: path.name)
def test_each_example_runs_as_its_header_says(path):
    document, _ = read(path)  # as lookout reads it: plugin files relative to the example
    header = path.read_text().split("\n\n", 1)[0]
    if "scenario" in document:
        assert "lookout campaign run examples/" + path.name in header
        campaign = load_campaign(path)
        assert len(campaign.points) >= 1
        return
    assert "lookout run examples/" + path.name in header
    composition = compose(document)
    period = composition.simulation.sample_period * composition.simulation.record_every
    duration = round(np.ceil(SECONDS / period - 1e-9)) * period
    # a sensor's failures start before the run's end: each moved into the short run, at its place in the long one
    scale = duration / composition.simulation.duration
    for table in document.get("sensors", {}).values():
        for failure in table.get("failures", []):
            failure["start"] = round(failure["start"] * scale / period) * period
            if "duration" in failure:
                failure["duration"] = max(period, round(failure["duration"] * scale / period) * period)
    document.setdefault("simulation", {})["duration"] = duration
    short = compose(document)
    trajectory = simulate(short)
    assert all(np.isfinite(np.asarray(leaf)).all() for leaf in jax.tree.leaves(trajectory.estimate)), path.name
