"""The composition matrix: every registered observer (the example plugin's too) on every
registered plant.

Each plant is taken in the first reproduction case that has it (its sea, its sensor,
its time grid), or in the observer's own first case (a reproduction case, else an example file) when that case has this plant, and
run open loop (no controller, no reference); each observer kind is put in with the
values it requires and the parts that are not models (its unknown parameters) taken
from its first case, its model from the plant, the rest from its defaults and design
rules for the plant at hand. Each pair either composes and runs 20
simulated seconds with finite estimates, or is refused in one line that names the
observer and what it lacks. docs/architecture.md holds the table this test computes
(`LOOKOUT_WRITE_MATRIX=1 pytest tests/test_composition_matrix.py` rewrites it); the
test fails when the table and the registry disagree.
"""

from __future__ import annotations

import copy
import os
import re
from pathlib import Path

import jax
import numpy as np
import pytest

from lookout.scenario import registry
from lookout.scenario.composition import CompositionError, compose
from lookout.sim import simulate

DOCS = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
EXAMPLE_PLUGIN = Path(__file__).resolve().parents[1] / "examples" / "plugins" / "luenberger.py"
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
BEGIN, END = "<!-- composition matrix: begin -->", "<!-- composition matrix: end -->"
DURATION = 20.0

pytestmark = pytest.mark.xdist_group("composition_matrix")


def _first_table(role: str, kind: str) -> dict | None:
    """The table of ``kind`` in the first reproduction case that uses it."""
    for name, case in registry.presets():
        document = registry.preset(name, case)
        table = document.get(role)
        if isinstance(table, dict) and table.get("kind") == kind:
            return document
    return None


#: Observers that read a sensor suite's IMU, which no reproduction case has: their first
#: case is their example file.
SUITE_ONLY = {"ins"}


def _home(kind: str) -> dict | None:
    """The observer's first case: the first reproduction case that uses it, else the first
    example file that does (an observer no paper uses, such as the IMU-aided one, whose
    sensor suite no reproduction case has)."""
    import tomllib

    found = _first_table("observer", kind)
    if found is not None or kind not in SUITE_ONLY:
        return found
    for path in sorted(EXAMPLES.glob("*.toml")):
        document = tomllib.loads(path.read_text())
        if "plugins" not in document and "preset" not in document and document.get("observer", {}).get("kind") == kind:
            return document
    return None


#: Roles of the models a plant offers (plant.models()): an observer takes them from the plant.
MODEL_ROLES = {"vessel", "ship", "model"}


def open_loop(document: dict) -> dict:
    """``document`` without controller and reference (and a suite's failures), one run of
    about 20 s (a whole number of its samples)."""
    base = copy.deepcopy(document)
    base["controller"], base["reference"], base["actuator"] = {"kind": "none"}, {"kind": "none"}, {"kind": "ideal"}
    for table in base.get("sensors", {}).values():  # an example's failures come later than 20 s
        table.pop("failures", None)
    period = base["simulation"]["sample_period"]
    base["simulation"] = {**base["simulation"], "duration": round(np.ceil(DURATION / period - 1e-9)) * period, "runs": 1, "record_every": 1}
    return base


def plant_bases() -> dict[str, dict]:
    """Each plant kind's base composition: its first case, open loop. A registered plant
    that no reproduction case uses has no base: the test fails naming it."""
    bases, missing = {}, []
    for each in registry.kinds("plant"):
        document = _first_table("plant", each.name)
        if document is None:
            missing.append(each.name)
        else:
            bases[each.name] = open_loop(document)
    assert not missing, f"plants without a base composition (no reproduction case uses them): {', '.join(missing)}"
    return bases


def observer_table(kind: str) -> dict:
    """The kind with the values it requires and its parts that are not models, as its
    first case gives them."""
    table = {"kind": kind}
    home = _home(kind)
    if home is None:
        return table
    given = home["observer"]
    design = given.get("design")
    if design is not None:
        table["design"] = design
    for p in registry.kind("observer", kind).parameters(design):
        if p.required and p.name in given and (p.sort == "value" or (p.sort == "part" and p.role not in MODEL_ROLES)):
            table[p.name] = copy.deepcopy(given[p.name])
    return table


def base_for(plant: str, observer: str, bases: dict) -> dict:
    """The observer's own first case when it has this plant, else the plant's first case."""
    home = _home(observer)
    if home is not None and home["plant"]["kind"] == plant:
        return open_loop(home)
    return bases[plant]


def outcome(plant: str, base: dict, observer: str) -> str:
    document = copy.deepcopy(base_for(plant, observer, {plant: base}))
    document["observer"] = observer_table(observer)
    try:
        composition = compose(document)
    except CompositionError as error:
        return f"refused: {error}"
    trajectory = simulate(composition.scenario, jax.random.key(0))
    finite = all(np.isfinite(np.asarray(leaf)).all() for leaf in jax.tree.leaves(trajectory.estimate))
    if not finite:
        return "diverges"
    start_error = off_the_first_measurement(composition.scenario, trajectory)
    return f"starts off its first measurement: {start_error}" if start_error else "runs"


def off_the_first_measurement(scenario, trajectory) -> str:
    """Where the estimate at t_0 of a measured variable (``measured_X`` of the sensor, ``X``
    of the estimate) differs from the first measurement, for a guess that leaves it to the
    measurement (every observer's default): "" when none does."""
    if hasattr(scenario.sensor, "instrument_layout"):
        # a filter on a suite starts at the weighted fit of its instruments, each at its lever
        # arm, not at the combining stage's measured_position
        return ""
    measured = scenario.sensor.measurement_layout.split(np.asarray(trajectory.measurement)[0])
    estimate = trajectory.estimate
    for name, value in measured.items():
        signal = name.removeprefix("measured_")
        if signal not in estimate or not np.all(np.isfinite(value)):
            continue
        start = np.asarray(estimate[signal])[0]
        difference = np.abs(np.angle(np.exp(1j * (start - value)))) if name == "measured_heading" else np.abs(start - value)
        if np.max(difference) > 1e-9 * (1.0 + np.max(np.abs(value))):
            return f"{signal} starts at {np.round(start, 6).tolist()}, the first measurement is {np.round(value, 6).tolist()}"
    return ""


def test_every_pair_runs_or_is_refused_every_kind_is_in_and_the_docs_hold_the_matrix():
    """One test computes the matrix once (38 s) and checks it three ways: each pair runs
    or is refused in one line naming the observer; every kind is in it; and
    docs/architecture.md holds it. The example plugin's observer is registered first:
    a kind of one's own is in the matrix as lookout's are."""
    registry.load_plugin(EXAMPLE_PLUGIN)
    bases = plant_bases()
    matrix = {(observer.name, plant): outcome(plant, base, observer.name) for observer in registry.kinds("observer") for plant, base in bases.items()}
    check_runs_or_refused(matrix)
    check_every_kind(matrix)
    check_the_doc(matrix)


def render(matrix: dict[tuple[str, str], str]) -> str:
    plants = sorted({plant for _, plant in matrix}, key=[k.name for k in registry.kinds("plant")].index)
    observers = [k.name for k in registry.kinds("observer")]
    lines = ["| observer \\ plant | " + " | ".join(plants) + " |", "|---|" + "---|" * len(plants)]
    for observer in observers:
        cells = []
        for plant in plants:
            result = matrix[(observer, plant)]
            cells.append("runs" if result == "runs" else ("**diverges**" if result == "diverges" else "refused"))
        lines.append(f"| {observer} | " + " | ".join(cells) + " |")
    reasons = [
        f"- {observer} on {plant}: {result[len('refused: ') :]}" for (observer, plant), result in matrix.items() if result.startswith("refused")
    ]
    return "\n".join(lines) + "\n\nWhy each refused pair is refused (the message `Scenario` or the composition gives):\n\n" + "\n".join(reasons)


def check_runs_or_refused(matrix):
    for (observer, plant), result in matrix.items():
        assert result != "diverges", f"observer {observer} on plant {plant} composes but its estimates are not finite after {DURATION:g} s"
        assert not result.startswith("starts off"), f"observer {observer} on plant {plant} {result}"
        if result.startswith("refused"):
            message = result[len("refused: ") :]
            assert "\n" not in message and f"observer {observer}" in message or message.startswith("observer"), (observer, plant, message)


def check_every_kind(matrix):
    assert {plant for _, plant in matrix} == {k.name for k in registry.kinds("plant")}
    assert {observer for observer, _ in matrix} == {k.name for k in registry.kinds("observer")}
    # each observer runs on at least one plant: no kind is registered that nothing can use
    for observer in {observer for observer, _ in matrix}:
        assert any(result == "runs" for (o, _), result in matrix.items() if o == observer), observer


def check_the_doc(matrix):
    table = render(matrix)
    text = DOCS.read_text()
    if os.environ.get("LOOKOUT_WRITE_MATRIX"):
        before, _, rest = text.partition(BEGIN)
        _, _, after = rest.partition(END)
        DOCS.write_text(f"{before}{BEGIN}\n{table}\n{END}{after}" if BEGIN in text else f"{text}\n{BEGIN}\n{table}\n{END}\n")
        text = DOCS.read_text()
    found = re.search(re.escape(BEGIN) + r"\n(.*?)\n" + re.escape(END), text, re.DOTALL)
    assert found, f"docs/architecture.md has no composition matrix between {BEGIN} and {END}"
    assert found.group(1) == table, "docs/architecture.md's composition matrix differs from the registry's: rerun with LOOKOUT_WRITE_MATRIX=1"
