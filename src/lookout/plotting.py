"""Figures drawn from xarray Datasets (matplotlib, no display needed)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

_PANELS = {
    "surge": (("eta", "x (m)", 1.0), ("nu", "u (m/s)", 1.0), ("wave", "x_w (m)", 1.0), ("bias", "b_x (kN)", 1e-3)),
    "sway": (("eta", "y (m)", 1.0), ("nu", "v (m/s)", 1.0), ("wave", "y_w (m)", 1.0), ("bias", "b_y (kN)", 1e-3)),
    "yaw": (
        ("eta", "psi (deg)", np.degrees(1.0)),
        ("nu", "r (deg/s)", np.degrees(1.0)),
        ("wave", "psi_w (deg)", np.degrees(1.0)),
        ("bias", "b_psi (kN m)", 1e-3),
    ),
}


def plot_estimates(ds: xr.Dataset, dof: str, *, run: int = 0, title: str | None = None):
    """True states (grey) and estimates (black) of one DOF: position, velocity, wave, bias.

    The layout of Fossen & Strand (1999), Figs. 9–11. Angles are shown in degrees.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if dof not in _PANELS:
        raise ValueError(f"dof must be one of {list(_PANELS)}; got {dof!r}")
    fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
    time = ds.time.values
    for ax, (name, label, scale) in zip(axes.ravel(), _PANELS[dof]):
        truth = ds[name].isel(run=run).sel(dof=dof).values
        estimate = ds[f"{name}_hat"].isel(run=run).sel(dof=dof).values
        if name == "eta" and dof == "yaw":
            truth, estimate = np.unwrap(truth), np.unwrap(estimate)
        ax.plot(time, truth * scale, color="0.65", lw=1.2, label="true")
        ax.plot(time, estimate * scale, color="k", lw=0.8, label="estimate")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(title or f"{dof}: true (grey) and estimated (black)")
    fig.tight_layout()
    return fig


def plot_bode(response: xr.Dataset, *, dof: str = "surge", title: str | None = None):
    """Bode plot of h0, hB and h for one DOF (Fossen & Strand 1999, Fig. 6).

    Parameters
    ----------
    response : xarray.Dataset
        From :func:`lookout.analysis.frequency_response`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, (mag, phase) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    w = response.frequency.values
    styles = {"h0": ("h0", "-"), "hB": ("hB", "--"), "h": ("h = hB h0", "-")}
    for name, (label, style) in styles.items():
        colour = "k" if name == "h" else "0.5"
        mag.semilogx(w, 20 * np.log10(response[f"{name}_magnitude"].sel(dof=dof).values), style, color=colour, label=label)
        phase.semilogx(w, response[f"{name}_phase_deg"].sel(dof=dof).values, style, color=colour, label=label)
    phase.axhline(-90, color="r", lw=0.8, ls=":", label="-90 deg (SPR bound)")
    mag.set_ylabel("magnitude (dB)")
    phase.set_ylabel("phase (deg)")
    phase.set_xlabel("frequency (rad/s)")
    for ax in (mag, phase):
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle(title or f"Error-loop frequency response, {dof}")
    fig.tight_layout()
    return fig
