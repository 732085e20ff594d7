"""The summary as tables for the terminal."""

from __future__ import annotations

import numpy as np

from lookout.analysis.conditions import inequalities_in
from lookout.papers._report import Table, significant
from lookout.papers.wondergem_2009.config import VELOCITY_BOUND


def tables(summary: dict) -> list[Table]:
    """Error index per condition against Table 1; the choice sweep's range."""
    rows, spreads = [], []
    for condition, values in summary["conditions"].items():
        index = np.asarray(values["error_index"], dtype=float)
        laps = np.asarray(values["lap_position_rms_m"], dtype=float).mean(axis=0)
        spreads.append(f"{condition} {index.min():.3g}-{index.max():.3g}")
        rows.append(
            (
                condition,
                significant(float(index.mean())),
                f"{values['table_1']:.5g}",
                "/".join(f"{100 * v:.2g}" if np.isfinite(v) else "-" for v in laps),
                f"{np.mean(values['time_saturated_s']):.1f}",
            )
        )
    horizons = ", ".join(f"{values['table_1_horizon_s']:g}" for values in summary["conditions"].values())
    runs = len(summary["seeds"])
    result = [
        Table(
            f"Error index (43) over [0, {summary['config']['duration']:g}] s",
            ("condition", "EI", "Table 1", "RMS error, laps 1/2/3/4 (cm)", "beyond a limit (s)"),
            tuple(rows),
            f"EI: mean over the runs{' (range: ' + '; '.join(spreads) + ')' if runs > 1 else ''}; Table 1 over its own t2 "
            f"({horizons} s). RMS: body-frame x-y position error.",
        )
    ]
    conditions, measured = summary.get("gain_conditions"), summary.get("gain_conditions_measured_start")
    if conditions and measured:
        sides = {item["name"]: item for item in inequalities_in(measured)}
        condition_rows = tuple(
            (
                item["name"],
                f"{item['left']:.4g}",
                f"{item['right']:.4g}",
                item["verdict"],
                *((f"{sides[item['name']]['right']:.4g}", sides[item["name"]]["verdict"]) if item["name"] in sides else ("-", "-")),
            )
            for item in inequalities_in(conditions)
        )
        result.append(
            Table(
                f"Gain conditions for the printed gains: (25), Proposition 3.1 (V_M = {VELOCITY_BOUND:g} m/s), Proposition 3.3",
                ("", "left", "right", "verdict", "right, eta_hat0 = eta0", "verdict"),
                condition_rows,
                "sufficient conditions, at the printed start and with the estimate started at the measurement (v_hat0 = 0)",
            )
        )
    proposal = (summary.get("gain_proposal") or {}).get("quantities", {}).get("proposal")
    if proposal and proposal["found"]:
        result.append(
            Table(
                "Gains the search proposes (eta_hat0 = eta0, v_hat0 = 0): every condition holds",
                ("Omega (rad/s)", "L1 (1/s)", "L2 (1/s2)", "eps3", "Euler step needed (s)"),
                (
                    (
                        f"{proposal['natural_frequency']:.4g} I",
                        f"{proposal['observer_gains']['L1']:.4g}",
                        f"{proposal['observer_gains']['L2']:.4g}",
                        f"{proposal['epsilon3']:.3g}",
                        f"{proposal['euler_step_max_s']:.3g}",
                    ),
                ),
                "lookout design tracking-gains --propose; the basin runs the scheme at 0.05 s",
            )
        )
    thrust = summary.get("reference_thrust")
    if thrust:
        result.append(
            Table(
                "Thrust of the reference, as a fraction of the limits (surge 2 N, sway 1.5 N, yaw 1.5 N m)",
                ("", "surge", "sway", "yaw"),
                (
                    ("on the ellipse: M nu_ref' + C nu_ref + D(nu_ref) nu_ref", *(f"{v:.3f}" for v in thrust["steady_fraction_of_limit"])),
                    ("speed step between laps: Kd (nu_ref+ - nu_ref-)", *(f"{v:.3f}" for v in thrust["lap_step_fraction_of_limit"])),
                ),
                "feasible below 1 (the initial transient is not included)",
            )
        )
    if summary.get("hold_study"):
        result.append(
            Table(
                "basin-calm: the 10 Hz measurement held over two 20 Hz steps, against 20 Hz measurements",
                ("case", "lap 4 e_x, e_y (m)", "EI", "> limit (s)", "|dF| (N)"),
                tuple(
                    (
                        row["case"],
                        f"{row['lap4_surge_error_m']:+.3f}, {row['lap4_sway_error_m']:+.3f}",
                        f"{row['error_index']:.3g}",
                        f"{row['time_beyond_limit_s']:.1f}",
                        f"{row['surge_command_step_N']:.2f}",
                    )
                    for row in summary["hold_study"]
                    if row["lap4_surge_error_m"] is not None
                ),
                "mean body-frame errors in lap 4 after its first 20 s; > limit: time some axis is commanded beyond its limit; "
                "|dF|: mean step-to-step change of the commanded surge force after 20 s",
            )
        )
    if summary.get("choice_sweep"):
        sweep = summary["choice_sweep"]
        sweep_rows = [(saturation, significant(values["min"]), significant(values["max"])) for saturation, values in sweep["by_saturation"].items()]
        result.append(
            Table(
                f"EI over the choices the paper leaves open ({sweep['condition']}; {len(sweep['runs'])} runs)",
                ("thrust limits", "min EI", "max EI"),
                tuple(sweep_rows),
                "start on the ellipse (4), direction (2), initial velocity as v_hat or zeta (2)",
            )
        )
    return result
