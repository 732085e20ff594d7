"""Simulation results: stacked arrays, converted to an xarray Dataset and NetCDF."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np
import xarray as xr

DOF = ("surge", "sway", "yaw")

#: name -> (long name, units per DOF)
VARIABLES = {
    "eta": ("low-frequency position and heading", "surge: m, sway: m, yaw: rad"),
    "nu": ("body-frame velocity", "surge: m/s, sway: m/s, yaw: rad/s"),
    "bias": ("Earth-fixed bias force and moment", "surge: N, sway: N, yaw: N m"),
    "wave": ("first-order wave-induced motion", "surge: m, sway: m, yaw: rad"),
}


class Trajectory(eqx.Module):
    """Recorded run(s): time, plant state, observer estimate, measurement, input.

    Attributes
    ----------
    time : ndarray, shape (n_time,)
        Sample times (s).
    state, estimate : VesselState
        Stacked states and estimates, shape ``([run,] time, ...)``.
    measurement : Array, shape ``([run,] time, 3)``
        The measurement the observer used at each sample (the held sensor
        samples; NaN where a channel's last sample was a dropout).
    control : Array, shape ``([run,] time, 3)``
        Input tau (N, N, N m).
    batched : bool
        Whether arrays carry a leading run axis.
    attrs : dict
        Scenario settings stored with the results.
    """

    time: Any
    state: Any
    estimate: Any
    measurement: Any
    control: Any
    batched: bool = eqx.field(static=True, default=False)
    attrs: dict = eqx.field(static=True, default_factory=dict)

    def to_xarray(self) -> xr.Dataset:
        """Dataset with dims ``run``, ``time``, ``dof``, units in attrs and a per-run ``status``.

        Variables: ``eta``, ``nu``, ``bias``, ``wave`` (true), the same with
        suffix ``_hat`` (estimates), ``measurement`` and ``tau``. ``status`` is
        ``"finite"`` or ``"diverged"`` (any non-finite state or estimate).
        """

        def runs(array) -> np.ndarray:
            array = np.asarray(array)
            return array if self.batched else array[None]

        data: dict[str, Any] = {}
        dims = ("run", "time", "dof")
        for name, (long_name, units) in VARIABLES.items():
            truth = runs(getattr(self.state, name))
            guess = runs(getattr(self.estimate, name))
            data[name] = (dims, truth, {"long_name": long_name, "units": units})
            data[f"{name}_hat"] = (dims, guess, {"long_name": f"estimated {long_name}", "units": units})
        data["measurement"] = (
            dims,
            runs(self.measurement),
            {"long_name": "measured position and heading (held samples; NaN = dropout)", "units": VARIABLES["eta"][1]},
        )
        data["tau"] = (dims, runs(self.control), {"long_name": "control forces and moment", "units": VARIABLES["bias"][1]})
        finite = np.ones(data["eta"][1].shape[0], dtype=bool)
        for name in VARIABLES:
            for key in (name, f"{name}_hat"):
                finite &= np.isfinite(data[key][1]).all(axis=(1, 2))
        data["status"] = (("run",), np.where(finite, "finite", "diverged").astype(object), {"long_name": "run status"})
        coords = {
            "run": np.arange(finite.size),
            "time": ("time", np.asarray(self.time), {"units": "s"}),
            "dof": list(DOF),
        }
        attrs = {key: (str(value) if isinstance(value, (list, tuple)) else value) for key, value in self.attrs.items()}
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def to_netcdf(self, path: str | Path) -> Path:
        """Write :meth:`to_xarray` to a NetCDF-4 file and return its path."""
        path = Path(path)
        self.to_xarray().to_netcdf(path, engine="netcdf4")
        return path
