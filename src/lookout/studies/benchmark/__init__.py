"""The observer benchmark: every observer that fits a plant, on identical scenarios.

Which observer, for my vessel and my sea, at what cost? A **benchmark spec** (TOML; the
shipped ones are in ``lookout/studies/benchmarks/``, one per plant) names

- a base scenario (a composition, or a reproduction's case as a preset), run open loop
  with its own input, so that what the sensor measures does not depend on the observer;
- the observers to compare, each an ``[observer]`` table of the composition (a kind, its
  design rule and gains; the models it leaves out are the plant's);
- the conditions, each one change from the base: ``changes`` reach the whole
  composition (a calmer sea, lost fixes, an outage: the observers that take the sea
  from the plant are told; a whole table, such as ``controller = { kind = "pid" }`` with
  a ``reference`` table, closes the loop), ``truth_only`` reaches the plant alone (a
  model error: the observers keep the nominal model);
- the metrics (those of :mod:`lookout.scenario.metrics`; each observer is measured on
  the signals it estimates, a tracking metric where the condition has a reference), a
  divergence rule, and two sizes, ``full`` and ``quick`` (duration, seeds, when the
  outage starts);
- optionally ``recommend_by``: the metrics that lead the recommendation, in order
  (:mod:`lookout.studies.benchmark_report` states the rule).

A **scenario file** (``[plant]``, ``[sensor]``, ...; what ``lookout run`` takes) is a
benchmark too (:func:`~lookout.studies.benchmark.from_scenario.scenario_benchmark`): its plant, sensor and sea, every registered
observer kind that composes on them, its own observer as given, and the conditions of
the shipped benchmark of its plant kind (model errors relative to its own model), or
generic ones.

Each observer's benchmark is one campaign (:mod:`lookout.studies.campaign`): the base
scenario with that observer, and one sweep axis, ``condition``, with a case per
condition. A condition at which other metrics apply (a closed loop, whose tracking error
is measured) is a campaign of its own. Every campaign runs the same seeds at every
condition, so every observer sees the same plant, the same sea and the same
measurements, bit for bit, and the chunks run on dask as any campaign's, into a Zarr
store per campaign that a killed benchmark resumes.

A model error must not reach the observer's model: for a ``truth_only`` condition, the
benchmark gives the observer, explicitly, each model it would otherwise take from the
plant (``observer.vessel`` = the plant's nominal ``vessel`` table, a Kalman filter's
``observer.plant`` = the nominal plant) before it changes the plant (:func:`~lookout.studies.benchmark.run.model_pins`).

Besides the campaigns, each observer's **cost** is measured in the same run: the
observer alone (``observer.update``, ``output``, ``predict``) stepped over the
baseline's recorded measurements and inputs of one run, compiled, as
:func:`lookout.filter` runs it: microseconds per sample, the best of a few repeats.

The package's modules: :mod:`~lookout.studies.benchmark.spec` (a spec's settings, the
shipped specs, the base composition), :mod:`~lookout.studies.benchmark.from_scenario`
(a scenario file as a benchmark), :mod:`~lookout.studies.benchmark.load` (either, as
``--spec`` takes it) and :mod:`~lookout.studies.benchmark.run` (planning and running).
"""

from lookout.scenario._toml import FileError
from lookout.studies.benchmark.load import load_benchmark
from lookout.studies.benchmark.run import check_resources, observer_campaign, plan, prepare, run_benchmark
from lookout.studies.benchmark.spec import Benchmark, Size, base_document, file_form, shipped_plants, shipped_spec

__all__ = [
    "Benchmark",
    "FileError",
    "Size",
    "base_document",
    "check_resources",
    "file_form",
    "load_benchmark",
    "observer_campaign",
    "plan",
    "prepare",
    "run_benchmark",
    "shipped_plants",
    "shipped_spec",
]
