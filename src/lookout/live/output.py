"""Where a live session's estimates go: JSON lines (stdout or UDP) and a NetCDF file.

The NetCDF file has the layout of a simulation's (:meth:`lookout.Trajectory.to_xarray`:
``position_hat``, ``innovation_position``, ``measured_position``, ``force_applied``, ...,
dims run, time and the label dims) with ``time`` unlimited, and a few variables of the
session's own: ``gated_<channel>`` and ``outage_<channel>`` flags and ``step_seconds``.
The first flush creates the file's missing folders, writes the file beside its name and
renames it into place; nothing is created before (a session that takes no step leaves
nothing). Every later flush appends the rows since the last one and syncs, so a
session that is killed loses at most the rows of one flush interval and leaves a file
that opens. :meth:`SessionWriter.remove` takes back what the writer created (a command
refused after it wrote).
"""

from __future__ import annotations

import json
import math
import socket
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import netCDF4
import numpy as np
import xarray as xr

from lookout._json import json_safe
from lookout.results import RecordSignals, Trajectory, write_netcdf

if TYPE_CHECKING:
    from lookout.components import Layout, Observer
    from lookout.io.geodesy import LocalFrame
    from lookout.live.session import Block


def json_line(block: Block, i: int, frame: LocalFrame | None = None, gated: object = (), outage: object = ()) -> str:
    """Step ``i`` of a :class:`~lookout.live.session.Block` as a JSON object on one
    line: ``time`` (the stream's clock), ``session_time``, each estimate by name (NaN as
    null), ``latitude_hat`` and ``longitude_hat`` when positions are fixes."""
    out = {"time": round(float(block.time[i]), 6), "session_time": round(float(block.session_time[i]), 6)}
    out.update({name: json_safe(np.asarray(value[i])) for name, value in block.estimate.items()})
    north, east = np.asarray(block.estimate["position"][i], dtype=float)[:2] if "position" in block.estimate else (math.nan, math.nan)
    if frame is not None and math.isfinite(north) and math.isfinite(east):  # a refused step's row is NaN
        latitude, longitude, _ = frame.geodetic(north, east, 0.0)
        out["latitude_hat"], out["longitude_hat"] = float(latitude), float(longitude)
    return json.dumps(out, separators=(",", ":"))


class Publisher:
    """Sends each step as a JSON line to stdout (``"-"``) or to ``udp://HOST:PORT``."""

    def __init__(self, target: str, frame_of: Callable[[], LocalFrame | None] | None = None):
        self.target = target
        self.frame_of = frame_of or (lambda: None)
        self._socket = None
        if target != "-":
            host, port = parse_udp(target, "--publish")
            try:  # resolved once, not at every send
                self._address = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)[0][4]
            except OSError as error:
                raise ValueError(f"--publish {target}: cannot resolve {host} ({error})") from None
            self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0
        self.failed = 0

    def __call__(self, block: Block) -> None:
        frame = self.frame_of()
        for i in range(len(block)):
            line = json_line(block, i, frame)
            if self._socket is None:
                sys.stdout.write(line + "\n")
            else:
                try:  # a network that refuses one datagram does not stop the session
                    self._socket.sendto(line.encode() + b"\n", self._address)
                except OSError:
                    self.failed += 1
                    continue
            self.sent += 1
        if self._socket is None:
            sys.stdout.flush()

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close()


def parse_udp(text: str, option: str, default_host: str = "127.0.0.1", any_port: bool = False) -> tuple[str, int]:
    """``(host, port)`` of ``udp://HOST:PORT`` (``udp://:PORT`` means ``default_host``;
    with ``any_port``, port 0 asks the system for a free one, to listen on).

    Raises
    ------
    ValueError
        Naming ``option`` when the text is not such an address.
    """
    if not isinstance(text, str) or not text.startswith("udp://"):
        raise ValueError(f"{option} must be udp://HOST:PORT; got {text!r}")
    host, _, port = text[len("udp://") :].rpartition(":")
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not (0 if any_port else 1) <= number < 65536:
        raise ValueError(f"{option} must be udp://HOST:PORT with a port in {0 if any_port else 1}..65535; got {text!r}")
    return host or default_host, number


class SessionWriter:
    """A NetCDF file of a session, appended every ``flush_every`` steps.

    Parameters
    ----------
    path : path
    observer : Observer
        Names, units and frames of the estimates, measurements and input (the observer
        the session wraps).
    attrs : dict
        Global attributes (scenario, source, frame).
    flush_every : int
        Steps between flushes.
    attrs_of : callable, optional
        Global attributes known only once data came (the frame's origin), asked at the first flush.
    measurement : Layout, optional
        The layout of the blocks' measurement (:attr:`lookout.live.Session.record_layout`);
        default the observer's.
    """

    def __init__(
        self,
        path: str | Path,
        observer: Observer,
        attrs: dict,
        flush_every: int = 100,
        attrs_of: Callable[[], dict] | None = None,
        measurement: Layout | None = None,
    ):
        self.path = Path(path)
        self.signals = RecordSignals(
            truth=(),
            estimate=tuple(observer.estimate_signals),
            extra=tuple(observer.extra_signals),
            measurement=observer.measurement_layout if measurement is None else measurement,
            reference=(),
            input=observer.input_layout,
        )
        self.attrs = dict(attrs)
        self.attrs_of = attrs_of or dict  # attributes known only once data came (the frame's origin)
        self.flush_every = int(flush_every)
        self._blocks: list = []
        self._kept = 0
        self.written = 0
        self._created: list[Path] = []  # the file, then the folders made for it (innermost first)

    def add(self, block: Block) -> None:
        """Keep ``block``; flush when ``flush_every`` steps are kept."""
        self._blocks.append(block)
        self._kept += len(block)
        if self._kept >= self.flush_every:
            self.flush()

    def _dataset(self) -> xr.Dataset:
        blocks = self._blocks
        names = list(blocks[0].estimate)
        estimates = {name: np.concatenate([b.estimate[name] for b in blocks]) for name in names}
        flags = {name: estimates.pop(name) for name in names if name.startswith(("gated_", "outage_"))}
        inputs = np.concatenate([b.input for b in blocks])
        trajectory = Trajectory(
            np.concatenate([b.session_time for b in blocks]),
            {},
            estimates,
            np.concatenate([b.measurement for b in blocks]),
            {},
            inputs,
            inputs,
            signals=self.signals,
            batched=False,
            attrs=self.attrs,
        )
        ds = trajectory.to_xarray()
        for name, values in flags.items():
            what = "rejected as a wild point" if name.startswith("gated_") else "older than its timeout: dead reckoning"
            ds[name] = (
                ("run", "time"),
                np.nan_to_num(values[None], nan=-1).astype("i1"),
                {"long_name": f"{name.split('_', 1)[1]} reading {what} (-1: a refused step)", "units": "1"},
            )
        ds["step_seconds"] = (
            ("run", "time"),
            np.concatenate([b.step_seconds for b in blocks])[None],
            {"long_name": "wall-clock time to compute the step", "units": "s"},
        )
        ds["clock_time"] = (
            ("time",),
            np.concatenate([b.time for b in blocks]),
            {"long_name": "time of the step on the stream's clock", "units": "s"},
        )
        return ds

    def flush(self) -> None:
        """Write the kept steps (the first flush creates the file)."""
        if not self._blocks:
            return
        ds = self._dataset()
        if self.written == 0:
            ds.attrs.update(self.attrs_of())
            folder = self.path.absolute().parent
            missing = []
            while not folder.exists():
                missing.append(folder)
                folder = folder.parent
            for each in reversed(missing):
                each.mkdir()
            self._created = [self.path, *missing]
            write_netcdf(ds, self.path, history="lookout live session", unlimited_dims=("time",))
        else:
            with netCDF4.Dataset(self.path, "a") as handle:
                start = self.written  # not the file's size: a failed append is written over
                for name, variable in ds.variables.items():
                    if "time" not in variable.dims:
                        continue
                    index = tuple(slice(start, start + ds.sizes["time"]) if dim == "time" else slice(None) for dim in variable.dims)
                    handle.variables[str(name)][index] = variable.values  # a results Dataset names its variables with strings
                handle.sync()
        self.written += self._kept
        self._blocks.clear()
        self._kept = 0

    def close(self) -> None:
        """Flush what is left."""
        self.flush()

    def remove(self) -> None:
        """Delete the file and the folders the writer created for it (a folder only if
        it is empty), and keep nothing more."""
        self._blocks.clear()
        self._kept = 0
        for path in self._created:
            try:
                path.unlink() if path == self.path else path.rmdir()
            except OSError:
                pass  # gone already, or a folder something else has written into since
        self._created = []
        self.written = 0
