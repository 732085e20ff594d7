"""Simulation results: labelled records, an xarray Dataset, CF-style NetCDF.

Names, units and frames come from the components' signals
(:mod:`lookout.components`), never from here: a plant variable ``position`` is
recorded as ``position`` and its estimate as ``position_hat``; a vector signal has a
label dimension (``earth_axis`` with ``north, east``; ``joint`` with the joint
names); every variable has one unit that UDUNITS parses.
"""

from __future__ import annotations

import datetime
import os
from collections.abc import Hashable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np
import xarray as xr

from lookout.components import Layout, Signal

#: NetCDF conventions the files follow.
CONVENTIONS = "CF-1.10"


@dataclass(frozen=True)
class RecordSignals:
    """What a run records, and how it is labelled."""

    truth: tuple[Signal, ...]
    estimate: tuple[Signal, ...]
    extra: tuple[Signal, ...]
    measurement: Layout
    reference: tuple[Signal, ...]
    input: Layout
    actuation: tuple[Signal, ...] = ()

    def variables(self) -> list[tuple[str, str, Signal]]:
        """``(group, variable name, signal)`` for every recorded quantity, in order.

        Groups: ``truth``, ``estimate``, ``measurement``, ``reference``,
        ``command``, ``applied``, ``actuation``. An estimate of a plant variable is named
        ``<name>_hat``; the observer's extra outputs (innovations, parameter
        estimates) keep their names; inputs are ``<name>_commanded`` and
        ``<name>_applied``; the actuator's outputs (each thruster's thrust) keep their names.
        """
        rows = [("truth", s.name, s) for s in self.truth]
        rows += [("estimate", f"{s.name}_hat", s) for s in self.estimate]
        rows += [("estimate", s.name, s) for s in self.extra]
        rows += [("measurement", s.name, s) for s in self.measurement.signals]
        rows += [("reference", s.name, s) for s in self.reference]
        rows += [("command", f"{s.name}_commanded", s) for s in self.input.signals]
        rows += [("applied", f"{s.name}_applied", s) for s in self.input.signals]
        rows += [("actuation", s.name, s) for s in self.actuation]
        names = [name for _, name, _ in rows]
        duplicated = sorted({name for name in names if names.count(name) > 1})
        if duplicated:
            raise ValueError(f"recorded variable names collide: {duplicated}")
        return rows


def _version() -> str:
    from lookout import __version__

    return __version__


class Trajectory(eqx.Module):
    """Recorded run(s): time, truths, estimates, measurements, references, inputs.

    Attributes
    ----------
    time : ndarray, shape (n_time,)
        Sample times (s).
    truth : dict of Array
        ``plant.variables`` of the state at each recorded sample, shape ``([run,] time, ...)``.
    estimate : dict of Array
        ``observer.output`` at each recorded sample.
    measurement : Array, shape ``([run,] time, n_y)``
        The measurement the observer used (held samples; NaN where a channel's last
        sample was a dropout).
    reference : dict of Array
        The reference samples.
    command, applied : Array, shape ``([run,] time, n_u)``
        Commanded and applied input.
    actuation : dict of Array
        The actuator's outputs (:attr:`~lookout.components.Actuator.output_signals`),
        empty for an actuator without any.
    signals : RecordSignals
        Names, units and frames.
    batched : bool
        Whether arrays carry a leading run axis.
    attrs : dict
        Scenario settings stored with the results.
    """

    time: Any
    truth: Any
    estimate: Any
    measurement: Any
    reference: Any
    command: Any
    applied: Any
    signals: RecordSignals = eqx.field(static=True)
    batched: bool = eqx.field(static=True, default=False)
    attrs: dict = eqx.field(static=True, default_factory=dict)
    actuation: Any = eqx.field(default_factory=dict)

    def _groups(self) -> dict[str, dict]:
        return {
            "truth": self.truth,
            "estimate": self.estimate,
            "measurement": self.signals.measurement.split(np.asarray(self.measurement)),
            "reference": self.reference,
            "command": self.signals.input.split(np.asarray(self.command)),
            "applied": self.signals.input.split(np.asarray(self.applied)),
            "actuation": self.actuation,
        }

    def to_xarray(self) -> xr.Dataset:
        """Dataset with dims ``run``, ``time`` and one label dimension per kind of vector.

        Every variable carries ``units``, ``long_name`` and ``frame`` attributes;
        angles carry ``angle = 1`` (their differences wrap). ``status`` per run is
        ``"finite"`` or ``"diverged"`` (a non-finite truth or estimate).
        """

        def runs(array) -> np.ndarray:
            array = np.asarray(array)
            return array if self.batched else array[None]

        groups = self._groups()
        data: dict[str, Any] = {}
        label_coords: dict[str, tuple[str, ...]] = {}
        finite = None
        for group, name, signal in self.signals.variables():
            values = runs(groups[group][signal.name])
            dims = ("run", "time") + ((signal.dim,) if signal.labels else ())
            if signal.labels:
                assert signal.dim is not None  # a signal with labels names their dimension
                known = label_coords.setdefault(signal.dim, signal.labels)
                if known != signal.labels:
                    raise ValueError(f"dimension {signal.dim!r} has labels {known} and {signal.labels} (signal {signal.name!r})")
            long_name = f"estimated {signal.long_name}" if group == "estimate" and signal in self.signals.estimate else signal.long_name
            if group == "command":
                long_name = f"commanded {signal.long_name}"
            elif group == "applied":
                long_name = f"applied {signal.long_name}"
            attrs = {"units": signal.units, "long_name": long_name, "frame": signal.frame, "angle": int(signal.angle)}
            data[name] = (dims, values, attrs)
            if group in ("truth", "estimate"):
                ok = np.isfinite(values).reshape(values.shape[0], -1).all(axis=1)
                finite = ok if finite is None else finite & ok
        n_runs = next(iter(data.values()))[1].shape[0] if data else 1
        if finite is None:
            finite = np.ones(n_runs, dtype=bool)
        data["status"] = (("run",), np.where(finite, "finite", "diverged").astype(object), {"long_name": "run status"})
        coords: dict[str, Any] = {
            "run": np.arange(n_runs),
            "time": ("time", np.asarray(self.time), {"units": "s", "long_name": "time since the start of the run", "standard_name": "time"}),
        }
        for dim, labels in label_coords.items():
            coords[dim] = (dim, list(labels))
        attrs = {key: (str(value) if isinstance(value, (list, tuple)) else value) for key, value in self.attrs.items()}
        attrs.update({"Conventions": CONVENTIONS, "source": f"lookout {_version()}", "lookout_version": _version()})
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def to_netcdf(self, path: str | Path) -> Path:
        """Write :meth:`to_xarray` to a compressed NetCDF-4 file and return its path."""
        return write_netcdf(self.to_xarray(), path)


def limited(commanded: np.ndarray, applied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where an actuator changed a command, and where both are finite: ``(limited,
    finite)``, boolean like ``commanded`` (applied differs from commanded by more than
    1e-9 of the largest command)."""
    commanded, applied = np.asarray(commanded, dtype=float), np.asarray(applied, dtype=float)
    finite = np.isfinite(commanded) & np.isfinite(applied)
    size = np.max(np.abs(commanded[finite]), initial=0.0)
    changed = np.zeros(commanded.shape, dtype=bool)
    changed[finite] = np.abs(commanded[finite] - applied[finite]) > 1e-9 * size
    return changed, finite


def limited_fraction(ds: xr.Dataset) -> dict[str, tuple[float, int]]:
    """For each input component of a run's Dataset (``force (surge)``, ...) and a
    thruster allocation's shortfall (``allocation``): the largest fraction of a run's
    records the actuator limited it, and that run."""
    out: dict[str, tuple[float, int]] = {}
    runs = ds.sizes.get("run", 1)
    for name in ds.data_vars:
        if not isinstance(name, str):  # a results Dataset names its variables with strings
            continue
        base = name[: -len("_commanded")]
        if not name.endswith("_commanded") or f"{base}_applied" not in ds:
            continue
        commanded, applied = ds[name], ds[f"{base}_applied"]
        extra = [dim for dim in commanded.dims if dim not in ("run", "time")]
        labels = [None] if not extra else list(ds[extra[0]].values)
        for label in labels:
            wanted = commanded if label is None else commanded.sel({extra[0]: label})
            got = applied if label is None else applied.sel({extra[0]: label})
            fractions = []
            for run in range(runs):
                changed, finite = limited(wanted.values[run], got.values[run])
                fractions.append(changed.sum() / max(int(finite.sum()), 1))
            key = base + ("" if label is None else f" ({label})")
            out[key] = (float(max(fractions)), int(np.argmax(fractions)))
    if "allocation_saturated" in ds:
        values = np.asarray(ds["allocation_saturated"].values, dtype=float).reshape(runs, -1)
        fractions = np.nanmean(values, axis=1)
        out["force (allocation short of it)"] = (float(np.max(fractions)), int(np.argmax(fractions)))
    return out


def write_netcdf(ds: xr.Dataset, path: str | Path, *, history: str = "written", unlimited_dims: tuple[str, ...] = ()) -> Path:
    """Write ``ds`` as compressed NetCDF-4 with a CF ``history`` line; return the path.

    Numeric variables are deflated (zlib, level 4, with byte shuffling); the
    ``history`` attribute gains a line with the time, lookout's version and
    ``history``. ``unlimited_dims`` may grow later (a live session appends along ``time``).
    """
    path = Path(path)
    ds = ds.copy()
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    line = f"{stamp}: lookout {_version()}: {history}"
    previous = ds.attrs.get("history")
    ds.attrs["history"] = f"{previous}\n{line}" if previous else line
    # every file lookout writes says what it follows and who wrote it
    ds.attrs.setdefault("Conventions", CONVENTIONS)
    ds.attrs.setdefault("lookout_version", _version())
    encoding: dict[Hashable, dict[str, Any]] = {
        name: {"zlib": True, "complevel": 4, "shuffle": True}
        for name, variable in ds.variables.items()
        if np.issubdtype(variable.dtype, np.number) and variable.ndim > 0
    }
    for name, settings in encoding.items():  # a growing dimension in chunks of 1024 (netCDF's default is 1)
        dims = ds[name].dims
        if any(dim in unlimited_dims for dim in dims):
            settings["chunksizes"] = tuple(1024 if dim in unlimited_dims else ds.sizes[dim] for dim in dims)
    # written beside and renamed into place: a write that fails leaves no half file
    partial = path.with_name(path.name + ".partial")
    try:
        ds.to_netcdf(partial, engine="netcdf4", encoding=encoding, unlimited_dims=list(unlimited_dims))
        os.replace(partial, path)
    except OSError as error:
        raise OSError(error.errno, f"cannot write {path}: {error.strerror or error}") from None
    finally:
        partial.unlink(missing_ok=True)
    return path
