"""Figures drawn from xarray Datasets (matplotlib, no display needed).

Two figures, after Fossen & Strand (1999), Figs. 6 and 9–11:

* :func:`plot_estimates` -- true and estimated signals, one panel each (labels,
  units and frames from the Dataset), full run and a zoomed window;
* :func:`plot_bode` -- the frequency response of the error loops h0, hB and h of
  all three degrees of freedom, with the frequencies of the tuning rule (48).

And the figures of ``lookout run``, for any composition, found from the Dataset's
names (``<name>_hat``, ``theta_<name>``, ``measured_<name>``, ``<name>_desired``,
``<name>_commanded`` / ``<name>_applied``), drawn as :func:`plot_estimates` draws:

* :func:`plot_run_estimates` -- every estimate against its truth;
* :func:`plot_run_reference` -- the reference against the truth;
* :func:`plot_run_input` -- the commanded and the applied input;
* :func:`plot_run_sensor_references` -- a sensor suite's position and heading
  references against the truth, failures shaded.

The modules: :mod:`~lookout.plotting.series` (:func:`plot_estimates`,
:func:`plot_trajectories`), :mod:`~lookout.plotting.run_figures` (the figures of
``lookout run``, and :func:`plot_run_thrusters`),
:mod:`~lookout.plotting.suite_references` (:func:`plot_run_sensor_references`),
:mod:`~lookout.plotting.capability` (:func:`plot_capability`, the DP capability polar),
:mod:`~lookout.plotting.bode`
(:func:`plot_bode`), and ``_panels``: the panel of a full run and its zooms that the
time-series figures share.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")  # before pyplot is imported: no display needed

from lookout.plotting._panels import (  # noqa: E402
    DENSE_CYCLES,
    ENVELOPE_BINS,
    SPIKE_FRACTION,
    SPIKE_RATIO,
    is_dense,
    zoom_window,
)
from lookout.plotting._panels import _panel_layout as _panel_layout  # noqa: E402
from lookout.plotting.bode import minimum_phase_of_h, plot_bode  # noqa: E402
from lookout.plotting.capability import plot_capability  # noqa: E402
from lookout.plotting.run_figures import (  # noqa: E402
    RUN_FIGURE_COLUMNS,
    RUN_FIGURE_ROWS,
    plot_run_estimates,
    plot_run_input,
    plot_run_reference,
    plot_run_thrusters,
    run_estimates,
    run_inputs,
    run_references,
)
from lookout.plotting.run_figures import _continuous_degrees as _continuous_degrees  # noqa: E402
from lookout.plotting.series import plot_estimates, plot_trajectories  # noqa: E402
from lookout.plotting.suite_references import plot_run_sensor_references  # noqa: E402

__all__ = [
    "DENSE_CYCLES",
    "ENVELOPE_BINS",
    "RUN_FIGURE_COLUMNS",
    "RUN_FIGURE_ROWS",
    "SPIKE_FRACTION",
    "SPIKE_RATIO",
    "is_dense",
    "minimum_phase_of_h",
    "plot_bode",
    "plot_estimates",
    "plot_run_estimates",
    "plot_run_input",
    "plot_run_reference",
    "plot_capability",
    "plot_run_sensor_references",
    "plot_run_thrusters",
    "plot_trajectories",
    "run_estimates",
    "run_inputs",
    "run_references",
    "zoom_window",
]
