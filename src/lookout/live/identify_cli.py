"""``lookout identify LOG --thrust THRUST.csv``: a vessel's M and D from its log.

The log is replayed with the observer without a hull model on its own sensors (as
``lookout replay LOG`` without a scenario), smoothed, and M and D are fitted to it
(:func:`lookout.tuning.identify.identify`). The folder gets the session
(``session.nc``), the identified vessel in a scenario file (``identified.toml``: the
given scenario with its ``[plant.vessel]`` replaced, or a DP scenario of the log's
sensors with an extended Kalman filter on the identified model), the numbers
(``identification.json``) and the prediction against the held-out log (``fit.png``).
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Annotated

import typer

from lookout._validation import InputError

#: The share of a log's span its thrust must cover (the rest: the edges of two logs
#: started a little apart).
MOST_UNCOVERED = 0.98


def _session_dataset(log: str, thrust: str, waves: bool, variation: float | None, folder: Path, say):
    """Replay ``log`` with the model-free observer on its own sensors into
    ``folder/session.nc``, smoothed: ``(Dataset, filter, sensors measured)``."""
    import xarray as xr

    from lookout.live.cli import REPLAY_BATCH, _gates, _inner_of, _model_free_session, _on_event, _outputs, smoothed_session
    from lookout.live.options import MAX_GAP, Gates
    from lookout.live.run import check_replay, replay
    from lookout.results import write_netcdf

    gates = _gates(Gates.min_quality, Gates.max_hdop, None, None, Gates.position_timeout, Gates.heading_timeout, None)
    session = _model_free_session(log, None, waves, None, gates, _on_event(say), say, REPLAY_BATCH, variation)
    try:
        check = check_replay(session, log, thrust, MAX_GAP)
    except ValueError as error:
        raise InputError(str(error)) from None
    assert check.thrust is not None  # a thrust log was given
    covered = min(check.thrust.newest, check.log.newest) - max(check.thrust.first, check.log.first)
    if covered < MOST_UNCOVERED * check.log.span:
        raise InputError(
            f"--thrust {thrust} covers {max(covered, 0.0):.1f} s of the log's {check.log.span:.1f} s: M and D fitted where the thrust is unknown would be wrong; "
            "give the thrust of the whole log, or cut the log to the thrust's span"
        )
    path = folder / "session.nc"
    write, close, _ = _outputs(session, str(path), None, "no scenario: the model-free observer", f"identification from {log}", 1000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            replay(session, log, thrust=thrust, emit=write, check=check)
        finally:
            close()
    observer = _inner_of(session)
    with xr.open_dataset(path) as opened:
        ds, _ = smoothed_session(opened.load(), observer)
    write_netcdf(ds, path, history="smoothed (Rauch-Tung-Striebel) for the identification")
    return ds, observer


def _arrays(ds, observer):
    """``(step, measured, thrust, states, sigma)`` of a smoothed session for
    :func:`~lookout.tuning.identify.identify`: a fix only at its own sample (a held one is
    not new), NaN in an outage."""
    import numpy as np

    times = ds["time"].values
    step = float(np.median(np.diff(times)))
    position = ds["measured_position"].values[0].copy()
    heading = ds["measured_heading"].values[0].copy()
    position[ds["outage_position"].values[0] > 0] = np.nan
    heading[ds["outage_heading"].values[0] > 0] = np.nan
    period = float(observer.channel_periods[0])
    due = np.isclose(times / period, np.round(times / period), atol=1e-6)
    position[~due] = np.nan
    measured = np.concatenate([position, heading[:, None]], axis=1)
    thrust = np.concatenate([ds["force_applied"].values[0], ds["moment_applied"].values[0][:, None]], axis=1)
    states = np.concatenate(
        [
            ds["position_smoothed"].values[0],
            ds["heading_smoothed"].values[0][:, None],
            ds["velocity_smoothed"].values[0],
            ds["yaw_rate_smoothed"].values[0][:, None],
        ],
        axis=1,
    )
    sigma = np.sqrt(np.diagonal(np.asarray(observer.measurement_covariance)))
    return step, measured, thrust, states, sigma


def _scenario_document(result, scenario_file: str | None, ds, observer) -> dict:
    """The scenario written with the identified vessel."""
    import numpy as np

    vessel = {"kind": "custom", "mass_matrix": result.mass_matrix.tolist(), "damping_matrix": result.damping_matrix.tolist()}
    if scenario_file is not None:
        import tomllib

        document = tomllib.loads(Path(scenario_file).read_text())
        document.setdefault("plant", {})["vessel"] = vessel
        return document
    sigma = np.sqrt(np.diagonal(np.asarray(observer.measurement_covariance)))
    span = float(ds["time"].values[-1])
    return {
        "simulation": {"duration": round(span, 6), "sample_period": float(observer.filter_period), "plant_step": float(observer.plant_step)},
        "plant": {
            "kind": "dp-vessel",
            "vessel": vessel,
            "bias": {
                "kind": "gauss-markov",
                "time_constant": 1000.0,
                "std": np.maximum(np.std(result.bias, axis=0), 1.0).tolist(),
            },
            "waves": {"kind": "linear", "peak_frequency": 0.8976, "damping_ratio": 0.1, "amplitude": [0.0, 0.0, 0.0]},
            "initial": {"bias": np.mean(result.bias, axis=0).tolist()},
        },
        "sensor": {"kind": "position-heading", "noise_std": sigma.tolist(), "sample_period": [float(p) for p in observer.channel_periods]},
        # the filter on the identified model, from a start as uncertain as a DP vessel's
        # first fix leaves it (the calm sea's wave states reach no noise: P_0 given)
        "observer": {
            "kind": "ekf",
            "initial_std": {"eta": [5.0, 5.0, 0.05], "nu": [0.5, 0.5, 0.005], "bias": [5e3, 5e3, 1e5], "wave_state": [0.0] * 6},
        },
    }


def _figure(result, path: Path) -> None:
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    labels = ("position north (m)", "position east (m)", "heading (deg)")
    for index, (axis, label) in enumerate(zip(axes, labels)):
        scale = math.degrees(1.0) if index == 2 else 1.0
        shown = np.isfinite(result.measured[:, index])
        axis.plot(result.times[shown], scale * result.measured[shown, index], ".", color="0.6", markersize=2, label="measured")
        axis.plot(result.times, scale * result.predicted[:, index], color="tab:orange", linewidth=1.2, label="predicted, window by window")
        axis.axvspan(result.held_out_from, result.times[-1], color="tab:blue", alpha=0.12, label="held out (not fitted)")
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    axes[0].legend(loc="upper left", fontsize=8, ncol=3)
    validation = result.validation_rms
    figure.suptitle(
        f"lookout identify: each window simulated with the identified M and D from its start; held out: RMS {validation[0]:.2f} m, "
        f"{validation[1]:.2f} m, {math.degrees(validation[2]):.2f} deg",
        fontsize=10,
    )
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def identify_command(
    log: Annotated[str, typer.Argument(metavar="LOG", help="A log with position and heading (raw NMEA, TIME SENTENCE lines, or CSV).")],
    thrust: Annotated[
        str | None, typer.Option(metavar="THRUST.csv", help="The thrust applied, time,surge,sway,yaw (N, N, N m): needed to identify M and D.")
    ] = None,
    scenario_file: Annotated[
        str | None,
        typer.Option("--scenario", metavar="SCENARIO.toml", help="A scenario whose [plant.vessel] the identified one replaces in the written file."),
    ] = None,
    out: Annotated[
        str, typer.Option(metavar="FOLDER", help="Where session.nc, identified.toml, identification.json and fit.png go.")
    ] = "out/identify",
    waves: Annotated[
        bool, typer.Option("--waves", help="The vessel is in waves: the observer filters the wave motion out (lookout replay --waves).")
    ] = False,
    window: Annotated[
        float, typer.Option(metavar="SECONDS", help="Seconds per window of the fit (the environment's force one constant in each).")
    ] = 300.0,
    variation: Annotated[
        float | None,
        typer.Option(
            metavar="DEGREES",
            help="Magnetic variation, east positive, for magnetic headings (HDG, HDM) that carry none (lookout replay --variation).",
        ),
    ] = None,
) -> None:
    """Identify a vessel's M and D from a log with thrust, and write the vessel in a scenario file."""
    import numpy as np

    from lookout._commandline import output_folder
    from lookout.live.cli import _existing_file, _format
    from lookout.tuning.identify import identify

    if thrust is None:
        raise InputError(
            "identify needs --thrust THRUST.csv (time,surge,sway,yaw): M and D show only in the response to a known force; "
            f"without thrust, lookout replay {log} runs the observer without a hull model"
        )
    for option, path in (("LOG", log), ("--thrust", thrust), ("--scenario", scenario_file)):
        _existing_file(option, path)
    if _format("--thrust", thrust) != "csv-thrust":
        raise InputError(f"--thrust {thrust} must be a CSV log whose first line is time,surge,sway,yaw")
    if not (math.isfinite(window) and window > 0):
        raise InputError(f"--window must be a finite positive number of seconds; got {window:g}")
    from lookout.live.cli import _check_variation

    _check_variation(variation)
    from lookout.io.logs import scan_log

    try:
        span = scan_log(log, "LOG").span
    except ValueError as error:
        raise InputError(str(error)) from None
    if window > 0.5 * span:
        raise InputError(f"--window {window:g} s is longer than half the log ({span:.1f} s): give a shorter window or a longer log")
    if scenario_file is not None:
        from lookout.studies.cli import _scenario

        _scenario(scenario_file, 1, None)  # a scenario that does not compose is refused before any work
    folder = output_folder("--out", out)

    def say(text: str) -> None:
        typer.echo(text, err=True)

    ds, observer = _session_dataset(log, thrust, waves, variation, folder, say)
    step, measured, applied, states, sigma = _arrays(ds, observer)
    result = identify(step, measured, applied, states, sigma, window=window)
    if not (np.all(np.isfinite(result.validation_rms)) and np.all(np.isfinite(result.mass_matrix)) and np.all(np.isfinite(result.damping_matrix))):
        (folder / "session.nc").unlink(missing_ok=True)
        raise InputError(f"{log}: the fit diverged (its prediction is not finite): is the thrust the one applied to this vessel over this log?")
    document = _scenario_document(result, scenario_file, ds, observer)
    from lookout.scenario._toml import write as write_toml
    from lookout.scenario.file import composition_comments

    write_toml(
        folder / "identified.toml",
        document,
        composition_comments(document),
        f"lookout identify {log} --thrust {thrust}: M and D identified from the log (lookout.tuning.identify)",
    )
    numbers = {
        "mass_matrix": result.mass_matrix.tolist(),
        "damping_matrix": result.damping_matrix.tolist(),
        "equation_error_mass_matrix": result.first_mass_matrix.tolist(),
        "equation_error_damping_matrix": result.first_damping_matrix.tolist(),
        "bias_per_window": result.bias.tolist(),
        "fit_rms": {"north_m": result.fit_rms[0], "east_m": result.fit_rms[1], "heading_rad": result.fit_rms[2]},
        "validation_rms": {"north_m": result.validation_rms[0], "east_m": result.validation_rms[1], "heading_rad": result.validation_rms[2]},
        "held_out_from_s": result.held_out_from,
        "window_s": window,
    }
    (folder / "identification.json").write_text(json.dumps(numbers, indent=2) + "\n")
    _figure(result, folder / "fit.png")
    np.set_printoptions(precision=4)
    print(f"M =\n{result.mass_matrix}\nD =\n{result.damping_matrix}")
    validation = result.validation_rms
    print(
        f"held-out prediction RMS {validation[0]:.2f} m north, {validation[1]:.2f} m east, {math.degrees(validation[2]):.2f} deg; "
        f"written: {folder / 'identified.toml'}, {folder / 'identification.json'}, {folder / 'fit.png'}, {folder / 'session.nc'}"
    )


def register(app: typer.Typer) -> None:
    """Add ``identify`` to the ``lookout`` command."""
    app.command("identify")(identify_command)


__all__ = ["identify_command", "register"]
