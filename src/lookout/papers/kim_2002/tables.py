"""Kim (2002): the summary as terminal tables."""

from __future__ import annotations

from lookout.papers._report import Table, mean_and_spread, significant, sweep_rows


def tables(summary: dict) -> list[Table]:
    """Closed-loop metrics per observer; the sweep per gain set."""
    rows = []
    for observer, values in summary["observers"].items():

        def cell(name, scale=1.0, digits=3):
            entry = values[name]
            if entry["mean"] is None:
                return "-"
            if summary["runs"] > 1:
                return mean_and_spread(entry["mean"] * scale, entry["std"] * scale)
            return significant(entry["mean"] * scale, digits)

        rows.append(
            (
                observer,
                cell("tracking_rms_m"),
                cell("position_error_rms_m"),
                cell("bias_error_rms_n", 1e-3),
                cell("thrust_peak_n", 1e-3),
                cell("time_saturated", 100.0),
                f"{values['diverged']}/{summary['runs']}",
            )
        )
    error = summary["config"]["model_error"]
    result = [
        Table(
            f"Closed loop, {summary['config']['gains']} observer gains; model error M x {1 + error['mass']:g}, D x {1 + error['damping']:g}, F {error['force'] / 1e3:g} kN",
            ("observer", "track", "pos err", "bias err", "peak", "sat.", "diverged"),
            tuple(rows),
            "RMS over the run. track: |LF position - reference| (m);\n"
            "pos err (m), bias err (kN): estimation errors; peak: largest applied force (kN);\n"
            "sat.: % of the time a command exceeds its limit;\n"
            "diverged: non-finite, or the vessel or its estimate > 100 m off",
        )
    ]
    if summary.get("sweep"):
        for gains, observers in summary["sweep"].items():
            result.append(
                Table(
                    f"Sweep, {gains} observer gains: RMS tracking error (m) against model error",
                    ("model error", *observers),
                    sweep_rows(observers),
                    "mean over the seeds that did not diverge;\n(k/n div.): k of n seeds diverged",
                )
            )
    return result
