"""The Bode figure of the error loops h0, hB and h (Fossen & Strand 1999, Fig. 6):
:func:`plot_bode`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.artist import Artist
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import NullLocator

from lookout.plotting._common import _minus, _runs

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: The frequencies of the tuning rule (48): dataset variable, legend label, gid, style.
_MARKERS: tuple[tuple[str, str, str, dict[str, Any]], ...] = (
    ("bias_filter_frequency", "1/T", "marker_1/T", {"color": "tab:purple", "ls": ":", "lw": 1.3}),
    ("bias_gain_ratio", "λ/κ", "marker_lambda/kappa", {"color": "tab:olive", "ls": "-.", "lw": 1.2}),
    ("wave_frequency", r"$\omega_o$", "marker_w_o", {"color": "tab:cyan", "ls": "--", "lw": 1.2}),
    ("cutoff_frequency", r"$\omega_c$", "marker_w_c", {"color": "tab:brown", "ls": (0, (6, 2, 1, 2, 1, 2)), "lw": 1.2}),
)
_CURVES: dict[str, dict[str, Any]] = {
    "h0": {"color": "tab:blue", "lw": 1.3},
    "hB": {"color": "tab:green", "lw": 1.3, "ls": "--"},
    "h": {"color": "k", "lw": 1.1},
}
_SPR_STYLE: dict[str, Any] = {"color": "tab:red", "ls": ":", "lw": 1.2}
_VIOLATION_STYLE: dict[str, Any] = {"color": "tab:red", "alpha": 0.18, "lw": 0, "zorder": 0.5}


_REQUIRED = (
    "h0_magnitude",
    "h0_phase_deg",
    "hB_phase_deg",
    "h_phase_deg",
) + tuple(marker[0] for marker in _MARKERS)


def _per_dof(response: xr.Dataset, name: str, dof: str) -> tuple[np.ndarray, str]:
    """The values of ``name`` (``hB_magnitude``, ``h_magnitude``, ``velocity_injection_gain``)
    for ``dof`` and their unit.

    :func:`lookout.analysis.frequency_response` splits these by kind of DOF, since a
    force per metre and a moment per radian share no unit: ``<name>_translation`` over
    ``translation`` (surge, sway) and ``<name>_yaw``. A variable ``name`` over ``dof``
    with one unit is read too.
    """
    if name in response.variables and "dof" in response[name].dims:
        variable = response[name].sel(dof=dof)
    elif f"{name}_translation" in response.variables and "translation" in response.coords and dof in response["translation"].values.tolist():
        variable = response[f"{name}_translation"].sel(translation=dof)
    elif f"{name}_{dof}" in response.variables:
        variable = response[f"{name}_{dof}"]
    else:
        raise ValueError(
            f"response must be a frequency_response() Dataset; it has no {name!r} for the DOF {dof!r} ({name}_translation or {name}_{dof})"
        )
    return np.asarray(variable.values, dtype=float), str(variable.attrs.get("units", ""))


def minimum_phase_of_h(response: xr.Dataset, dof: str) -> tuple[float, float]:
    """Minimum phase of h (deg) over frequencies up to 10 w_c, and where (rad/s)
    (:func:`lookout.analysis.minimum_phase_in_band` on the dataset's grid)."""
    from lookout.analysis import minimum_phase_in_band

    return minimum_phase_in_band(
        response["frequency"].values, response["h_phase_deg"].sel(dof=dof).values, float(response["cutoff_frequency"].sel(dof=dof))
    )


def plot_bode(response: xr.Dataset, *, title: str | None = None) -> Figure:
    """Bode plot of the error loops h0, hB and h = hB h0 of all three DOFs.

    Fossen & Strand (1999), Fig. 6 (and the tuning behind Figs. 9–11): one column
    per degree of freedom (surge, sway, yaw). Because hB and h carry units that
    differ by DOF, they are shown normalized by the velocity injection gain kappa:
    hB/kappa is dimensionless and h/kappa, like h0, is in seconds. Rows:

    1. magnitude of h0 and h/kappa in dB re 1 s;
    2. magnitude of hB/kappa in dB (dimensionless);
    3. phase of h0, hB and h in degrees, with the SPR bound at -90 deg and the
       minimum phase of h below 10 w_c written on the panel;
    4. the margin of the phase of h to -90 deg on a log axis, so that a margin of
       a fraction of a degree is readable.

    Every panel marks the frequencies of the tuning rule (48),
    1/T << lambda/kappa < w_o < w_c, with vertical lines (gids ``marker_1/T``,
    ``marker_lambda/kappa``, ``marker_w_o``, ``marker_w_c``).

    Parameters
    ----------
    response : xarray.Dataset
        From :func:`lookout.analysis.frequency_response`: ``h0_magnitude`` and the
        ``*_phase_deg`` variables with dims (frequency, dof); per DOF
        ``bias_filter_frequency``, ``bias_gain_ratio``, ``wave_frequency`` and
        ``cutoff_frequency`` (rad/s); and hB, h and kappa, which have one unit per
        kind of DOF, as ``hB_magnitude_translation``, ``h_magnitude_translation``,
        ``velocity_injection_gain_translation`` over ``translation`` (surge, sway)
        and ``hB_magnitude_yaw``, ``h_magnitude_yaw``, ``velocity_injection_gain_yaw``.
    title : str, optional
        Figure title; default "Error-loop frequency response h0, hB, h
        (Fossen & Strand 1999, Fig. 6)".

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If a required variable, or hB, h or kappa of one of its DOFs, is missing
        from ``response``.
    """
    missing = [name for name in _REQUIRED if name not in response.variables]
    if missing:
        raise ValueError(f"response must be a frequency_response() Dataset; missing variables {missing}")
    frequency = np.asarray(response["frequency"].values, dtype=float)
    dofs = response["dof"].values.tolist()  # one column per loop, however many

    fig, axes = plt.subplots(
        4,
        len(dofs),
        figsize=(13 * len(dofs) / 3, 10),
        layout="constrained",
        sharex=True,
        sharey="row",
        squeeze=False,
        gridspec_kw={"height_ratios": (1.0, 0.8, 1.0, 0.8)},
    )
    magnitude, gain, phase, margin = axes
    # every DOF's hB, h and kappa are there before anything is drawn
    split = {dof: {name: _per_dof(response, name, dof) for name in ("hB_magnitude", "h_magnitude", "velocity_injection_gain")} for dof in dofs}
    for column, dof in enumerate(dofs):
        kappa_values, unit = split[dof]["velocity_injection_gain"]
        kappa = float(kappa_values)
        curve = {"h0": response["h0_magnitude"].sel(dof=dof).values, "hB": split[dof]["hB_magnitude"][0], "h": split[dof]["h_magnitude"][0]}
        angle = {name: response[f"{name}_phase_deg"].sel(dof=dof).values for name in ("h0", "hB", "h")}

        ax = magnitude[column]
        ax.semilogx(frequency, 20 * np.log10(curve["h0"]), **_CURVES["h0"], label="$h_0$")
        ax.semilogx(frequency, 20 * np.log10(curve["h"] / kappa), **_CURVES["h"], label=r"$h/\kappa$")
        ax.set_title(f"{dof}:  κ = {kappa:.3g} {unit}".rstrip(), fontsize=10)

        ax = gain[column]
        ax.semilogx(frequency, 20 * np.log10(curve["hB"] / kappa), **_CURVES["hB"], label=r"$h_B/\kappa$")

        ax = phase[column]
        for name, label in (("h0", "$h_0$"), ("hB", "$h_B$"), ("h", "$h$")):
            ax.semilogx(frequency, angle[name], **_CURVES[name], label=label)
        ax.axhline(-90.0, **_SPR_STYLE, label="−90° (SPR bound)")
        lowest, where = minimum_phase_of_h(response, dof)
        ax.plot([where], [lowest], "o", color="k", ms=4, zorder=4)
        text = _minus(f"min phase of h {lowest:.2f}° at {where:.3g} rad/s\nmargin {lowest + 90.0:.2f}° to -90° ($\\omega \\leq 10\\,\\omega_c$)")
        ax.text(
            0.98,
            0.97,
            text,
            transform=ax.transAxes,
            fontsize=8,
            va="top",
            ha="right",
            gid="min_phase_annotation",
            bbox={"boxstyle": "round,pad=0.3", "facecolor": "white", "edgecolor": "0.7", "alpha": 0.9},
        )

        ax = margin[column]
        distance = angle["h"] + 90.0
        positive = np.where(distance > 0, distance, np.nan)
        ax.semilogx(frequency, positive, **_CURVES["h"], label=r"$\angle h + 90°$")
        if lowest > -90.0:
            ax.plot([where], [lowest + 90.0], "o", color="k", ms=4, zorder=4)
        # where the phase of h is at or below -90 deg the margin has no log value: shade it
        for start, stop in _runs(frequency, distance <= 0):
            for panel in (phase[column], ax):
                panel.axvspan(start, stop, **_VIOLATION_STYLE, label="SPR violated: phase of h ≤ −90°")
        ax.axvspan(10.0 * float(response["cutoff_frequency"].sel(dof=dof)), frequency[-1], color="0.5", alpha=0.15, lw=0)
        ax.set_yscale("log")

        for ax in axes[:, column]:
            for variable, label, gid, style in _MARKERS:
                ax.axvline(float(response[variable].sel(dof=dof)), **style, label=label, gid=gid, zorder=1.5)
            ax.grid(alpha=0.3, which="major")
            # no minor ticks: on 12 log axes they were 1100 tick objects and 4 of the 5 s it took to save
            ax.xaxis.set_minor_locator(NullLocator())
            ax.yaxis.set_minor_locator(NullLocator())

    magnitude[0].set_ylabel("magnitude (dB re 1 s)\n$h_0$ and $h/\\kappa$")
    gain[0].set_ylabel("magnitude (dB)\n$h_B/\\kappa$ (dimensionless)")
    phase[0].set_ylabel("phase (deg)")
    margin[0].set_ylabel("margin to −90°\n$\\angle h + 90°$ (deg)")
    for ax in margin:
        ax.set_xlabel("frequency ω (rad/s)")
    # -120 to 90 deg holds a passing design's phases (h0's notch lead stays below +90 deg);
    # a deeper minimum or a higher peak widens it; the band above the top tick holds the
    # minimum-phase note, clear of every curve
    phases = np.asarray(response[["h0_phase_deg", "hB_phase_deg", "h_phase_deg"]].to_array().values, dtype=float)
    bottom = min(-120.0, 30.0 * np.floor(np.nanmin(phases) / 30.0))
    top = max(90.0, 30.0 * np.ceil(np.nanmax(phases) / 30.0))
    phase[0].set_ylim(bottom, top + 60.0)
    phase[0].set_yticks(np.arange(bottom, top + 1.0, 30.0))
    margins = np.asarray(response["h_phase_deg"].values, dtype=float) + 90.0
    positive = margins[margins > 0]
    low = min(0.1, 0.5 * positive.min()) if positive.size else 0.1
    margin[0].set_ylim(low, 200.0)
    magnitude[0].set_xlim(frequency[0], frequency[-1])

    # one legend for the whole figure, below the panels, so that none covers a curve
    def legend_style(name: str, **extra: Any) -> dict[str, Any]:
        return {k: v for k, v in {**_CURVES[name], **extra}.items() if k != "zorder"}

    handles: list[Artist] = [
        Line2D([], [], **legend_style("h0"), label="$h_0$"),
        Line2D([], [], **legend_style("hB"), label=r"$h_B$ (magnitude: $h_B/\kappa$)"),
        Line2D([], [], **legend_style("h"), label=r"$h$ (magnitude: $h/\kappa$; margin $\angle h + 90°$)"),
        Line2D([], [], **_SPR_STYLE, label="−90° (SPR bound)"),
        Patch(facecolor="0.5", alpha=0.3, label=r"$\omega > 10\,\omega_c$ (margin not judged)"),
    ]
    if np.any(margins <= 0):
        handles.append(Patch(**{k: v for k, v in _VIOLATION_STYLE.items() if k != "zorder"}, label="SPR violated: phase of h ≤ −90°"))
    handles += [Line2D([], [], **style, label=label) for _, label, _, style in _MARKERS]
    fig.legend(
        handles=handles,
        loc="outside lower center",
        ncols=5,
        fontsize=9,
        frameon=False,
        title=r"markers: the tuning rule (48), $1/T \ll \lambda/\kappa < \omega_o < \omega_c$",
        title_fontsize=9,
    )
    fig.suptitle(title if title is not None else "Error-loop frequency response h0, hB, h (Fossen & Strand 1999, Fig. 6)")
    return fig
