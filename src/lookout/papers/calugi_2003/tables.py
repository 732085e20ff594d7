"""Calugi et al. (2003): the summary as terminal tables."""

from __future__ import annotations

import numpy as np

from lookout.papers._report import Table, significant, sweep_rows
from lookout.papers.calugi_2003.config import GAIN_SETS


def tables(summary: dict) -> list[Table]:
    """Closed-loop metrics and condition verdicts per gain set; the Delta sweep; theta convergence."""
    rows = []
    for name, values in summary["gain_sets"].items():
        verdicts = values["conditions"]["verdicts"]
        rows.append(
            (
                name,
                "-" if None in values["tracking_rms_m"] else significant(float(np.mean(values["tracking_rms_m"]))),
                "-" if None in values["velocity_error_rms_m_s"] else significant(float(np.mean(values["velocity_error_rms_m_s"]))),
                "-" if None in values["final_theta_ratio"] else f"{np.mean(values['final_theta_ratio']):.4f}",
                "/".join("ok" if verdicts[key] == "holds" else "FAIL" for key in ("observer_22", "closed_loop_57", "closed_loop_58")),
                f"{values['diverged']}/{summary['runs']}",
            )
        )
    result = [
        Table(
            f"Closed loop, Delta = {summary['config']['sample_interval']:g} s, {summary['config']['duration']:g} s",
            ("gains", "track", "vel err", "theta/m11", "(22)/(57)/(58)", "diverged"),
            tuple(rows),
            "RMS over the run. track: |eta - eta_d| horizontal (m); vel err: |nu - nu_hat| (m/s);\ntheta/m11: final estimate; conditions: ok = holds",
        )
    ]
    if summary.get("interval_sweep"):
        sweep = summary["interval_sweep"]
        result.append(
            Table("Delta sweep: RMS tracking error (m)", ("Delta (s)", *sweep), sweep_rows(sweep), "mean over the seeds that did not diverge")
        )
    if summary.get("theta_convergence"):
        conv = summary["theta_convergence"]
        conv_rows = []
        for noise, by_reference in conv.items():
            for reference, by_gamma in by_reference.items():
                for gamma, by_initial in by_gamma.items():
                    conv_rows.append((noise, reference, gamma, " ".join(f"{v:.3f}" for v in by_initial.values())))
        starts = " ".join(next(iter(next(iter(next(iter(conv.values())).values())).values())).keys())
        result.append(
            Table("theta_hat(T) / m11 from several starts (printed gains)", ("noise", "setpoint", "Gamma", f"from {starts}"), tuple(conv_rows), "")
        )
    if summary.get("discretization_order"):
        order = summary["discretization_order"]
        order_rows = []
        for name in (key for key in order if key in GAIN_SETS):
            for key, label in (("position", "eta (m)"), ("velocity_hat", "nu_hat (m/s)"), ("theta_ratio", "theta/m11")):
                entry = order[name][key]
                order_rows.append((name, label, *(f"{v:.3g}" for v in entry["difference"].values()), f"{entry['order']:.3f}"))
        intervals = list(next(iter(order[GAIN_SETS[0]].values()))["difference"])
        result.append(
            Table(
                f"Discrete (65)-(67) against continuous (13)-(15) in closed loop, no noise, Gamma = {order['gamma']:g}",
                ("gains", "largest difference", *(f"Delta {d} s" for d in intervals), "order"),
                tuple(order_rows),
                f"over {order['duration_s']:g} s; order: slope of log difference against log Delta",
            )
        )
    if summary.get("noise_drift"):
        drift = summary["noise_drift"]
        drift_rows = []
        for name in (key for key in drift if key in GAIN_SETS):
            for interval, by_level in drift[name].items():
                for level, entry in by_level.items():
                    drift_rows.append(
                        (
                            name,
                            interval,
                            level,
                            f"{entry['measured_rate']:.3g}",
                            f"{entry['measured_rate_error']:.2g}",
                            f"{entry['predicted_rate']:.3g}",
                            f"{entry['measured_rate'] / entry['predicted_rate']:.2f}",
                        )
                    )
        result.append(
            Table(
                f"Drift of theta_hat caused by noise, Gamma = {drift['gamma']:g} (kg/s)",
                ("gains", "Delta (s)", "noise (m)", "measured", "std err", "predicted", "ratio"),
                tuple(drift_rows),
                f"measured: mean slope over the first {drift['window_s']:g} s from theta_hat = m11, {drift['seeds']} seeds, and its standard error;\n"
                "predicted: -Gamma g k2 (1 + Delta k2) sigma^2 / Delta (analysis.adaptive_dp.noise_drift_rate)",
            )
        )
    return result
