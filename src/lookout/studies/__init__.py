"""Studies at scale: scenario files, campaigns over sweeps of them, their stores and reports.

- :mod:`lookout.scenario.file`: a scenario in a TOML file (``lookout run``).
- :mod:`lookout.scenario.metrics`: per-run metrics reduced where the runs are computed.
- :mod:`lookout.studies.campaign`: a campaign spec (base scenario, sweep axes, seeds,
  metrics) and its chunks.
- :mod:`lookout.studies.store`: the Zarr store with a completion record per chunk.
- :mod:`lookout.studies.execute`: running the chunks in one process or on dask.distributed.
- :mod:`lookout.studies.report`: the static HTML report.
"""
