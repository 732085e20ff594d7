"""What ``--spec`` takes: a benchmark spec, or a scenario file made a benchmark."""

from __future__ import annotations

from pathlib import Path

from lookout.scenario._toml import FileError, read
from lookout.scenario.file import CAMPAIGN_ONLY
from lookout.studies.benchmark.from_scenario import scenario_benchmark
from lookout.studies.benchmark.spec import Benchmark, file_form, spec_benchmark


def load_benchmark(path: str | Path) -> Benchmark:
    """Read and validate the benchmark spec, or the scenario file, at ``path`` (one-line
    FileError on bad input)."""
    path = Path(path)
    document, text = read(path)
    try:
        form = file_form(document)
    except ValueError as error:
        raise FileError(f"{path}: {error}") from None
    if form == "campaign":
        raise FileError(
            f"{path}: is a campaign spec ({', '.join(sorted(set(document) & CAMPAIGN_ONLY))}): run it with lookout campaign run {path}; "
            "--spec takes a benchmark spec or a scenario file"
        )
    if form == "scenario":
        return scenario_benchmark(path, document, text)
    return spec_benchmark(path, document, text)
