"""The docs, the README, the examples and the source describe lookout as it is.

Which issue or work session changed what is history: it belongs in commit messages and,
for measurements, in dated benchmark sections that name commits. A phrase such as
"issue 10", "the next issue", "this session's changes" or "the first-user clean-up"
tells a user nothing about lookout, and goes stale. A live session (``lookout live``,
``lookout.live.Session``) is a product concept and is not history.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Each pattern (case-insensitive) names one way of speaking of the project's history.
HISTORY = {
    "an issue by number (issue 10)": r"\bissues? #?\d+",
    "an issue by its place or subject (the next issue, the thruster issue)": r"\b(?:this|that|(?:the|a|an) (?!same\b|known\b|open\b)[\w-]+) issue\b",
    "the issue as a source (the issue's target, as the issue names it)": r"\bthe issue\b",
    "a work session (this session)": r"\bthis session\b",
    "a work session by its rank (second session)": r"\b(?:first|second|third|fourth|fifth|sixth|seventh|eighth|ninth|tenth) session\b",
    "a work session as a time (in the same session)": r"\bin the same session\b|\(same session\b",
    "a clean-up or trial by its occasion": r"\bfirst[- ]user (?:clean-?up|trial|fixes)\b",
}
COMPILED = {name: re.compile(pattern, re.IGNORECASE) for name, pattern in HISTORY.items()}


def _files() -> list[Path]:
    found = [ROOT / "README.md"]
    found += sorted((ROOT / "docs").rglob("*.md"))
    found += sorted((ROOT / "docs").rglob("*.py"))
    found += sorted((ROOT / "src").rglob("*.py"))
    found += sorted((ROOT / "benchmarks").glob("*.py"))
    found += sorted((ROOT / "examples").rglob("*.toml"))
    return [path for path in found if "__pycache__" not in path.parts]


FILES = _files()


def history_phrases(text: str) -> list[tuple[int, str, str]]:
    """(line number, matched phrase, pattern name) of every history phrase in ``text``."""
    hits = []
    for number, line in enumerate(text.splitlines(), start=1):
        taken: list[tuple[int, int]] = []  # one report per phrase, from the first pattern that finds it
        for name, pattern in COMPILED.items():
            for match in pattern.finditer(line):
                if all(match.end() <= start or match.start() >= end for start, end in taken):
                    taken.append(match.span())
                    hits.append((number, match.group(0), name))
    return sorted(hits)


def test_the_scan_covers_the_docs_readme_source_benchmarks_and_examples():
    relative = {path.relative_to(ROOT).as_posix() for path in FILES}
    for expected in (
        "README.md",
        "docs/benchmarks.md",
        "docs/reproductions.md",
        "docs/tuning.md",
        "src/lookout/sim/filtering.py",
        "src/lookout/live/session.py",
        "benchmarks/throughput.py",
    ):
        assert expected in relative, expected
    assert sum(name.startswith("src/") for name in relative) >= 50


@pytest.mark.parametrize(
    "phrase",
    [
        "The engine contract (issue 10)",
        "Thrusters (Issue 27, part 2)",
        "the next issue, `lookout tune`, may reorder the table",
        "noise tuning is the next issue's subject",
        "the conditions of the thruster issue will exercise it",
        "the issue's target is at most 4x",
        "lookout.filter, as the issue and the docs name it",
        "This session changed the Stepper in three ways",
        "the code before this session's two changes",
        "2026-11-22, Third session, three runs",
        "Replaced in the second session of 2026-11-22",
        "From dfa7674 until the first-user clean-up",
        "batch 2.53e5 -> 2.75e5 in the same session",
        "(same session) The sampled passive observer",
    ],
)
def test_history_phrases_are_found(phrase):
    assert history_phrases(phrase), phrase


@pytest.mark.parametrize(
    "phrase",
    [
        "A live session steps the observer at its sample period",
        "`lookout.live.Session` keeps the compiled step; `Session.warm_up` compiles it",
        "the session's NetCDF file is synced every 1024 steps",
        "a killed session loses at most those",
        "2026-11-22, commit 8df8082, three runs",
        "the same issue arises at every sample",
        "round trips to NetCDF; the next step; the previous call's t",
        "the target is at most 4x: **not met**",
    ],
)
def test_product_language_is_not_history(phrase):
    assert not history_phrases(phrase), history_phrases(phrase)


@pytest.mark.parametrize("path", FILES, ids=lambda path: path.relative_to(ROOT).as_posix())
def test_no_history_phrases(path):
    hits = history_phrases(path.read_text(encoding="utf-8"))
    where = path.relative_to(ROOT).as_posix()
    assert not hits, "\n".join(f"{where}:{number}: {phrase!r} ({name})" for number, phrase, name in hits)
