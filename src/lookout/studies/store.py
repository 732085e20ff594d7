"""The campaign store: a Zarr store, one region per chunk, and a completion record per chunk.

Layout (``xarray.open_zarr(STORE)`` reads it as a Dataset)::

    STORE/
      zarr.json, <variable>/...     metrics over (point, seed); NaN where not yet computed
      _lookout/zarr.json            a Zarr group whose attributes hold the campaign and version
      _lookout/campaign.json        the campaign, scenario inlined (what resume compares)
      _lookout/chunks/chunk-000042.json   written after chunk 42's region: its record

Every metric is a float64 variable over ``(point, seed)``, Zarr-chunked as
``(1, chunk_runs)`` so that a chunk of the campaign is exactly one Zarr chunk per
variable and no two chunks ever share a file. ``diverged`` is 1.0 or 0.0. Each sweep
axis is a coordinate over ``point``. Kept trajectories are ``trajectory__NAME`` over
``(point, seed, kept_time, ...)``.

A chunk counts as done when its record exists. The record is written after the
chunk's data and renamed into place, so a store killed at any moment holds only
complete chunks with records; a chunk without one is computed again on resume and its
region overwritten with the same values (a run's numbers depend only on its seed and
sweep point). A chunk with a record is never written again.
"""

from __future__ import annotations

import datetime
import json
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lookout.studies.campaign import Campaign, Chunk, canonical_json, fingerprint_of

if TYPE_CHECKING:
    import xarray as xr

META = "_lookout"


def variable_name(label: str) -> str:
    """A store variable name for an axis label (``bias_std[0]`` -> ``bias_std_0``)."""
    return re.sub(r"_+$", "", re.sub(r"[^A-Za-z0-9_]+", "_", label))


def _version() -> str:
    from lookout import __version__

    return __version__


def _short(value) -> str:
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= 40 else text[:37] + "..."


def differences(held: Any, given: Any, prefix: str = "") -> list[str]:
    """``key: held -> given`` for every dotted key where two campaign documents differ
    (``scenario.settings.duration: 1500.0 -> 1000.0``), in key order."""
    if isinstance(held, dict) and isinstance(given, dict):
        result = []
        for key in sorted(set(held) | set(given)):
            name = f"{prefix}.{key}" if prefix else str(key)
            if key not in held:
                result.append(f"{name}: (absent) -> {_short(given[key])}")
            elif key not in given:
                result.append(f"{name}: {_short(held[key])} -> (absent)")
            else:
                result += differences(held[key], given[key], name)
        return result
    if isinstance(held, list) and isinstance(given, list) and len(held) == len(given):
        return [line for i, (a, b) in enumerate(zip(held, given)) for line in differences(a, b, f"{prefix}[{i}]")]
    if canonical_json({"v": held}) != canonical_json({"v": given}):
        return [f"{prefix or 'the document'}: {_short(held)} -> {_short(given)}"]
    return []


class CampaignStore:
    """Open with :meth:`open_or_create`; write with :meth:`write_chunk`."""

    def __init__(self, path: str | Path):
        self.path = Path(path)

    @property
    def records(self) -> Path:
        return self.path / META / "chunks"

    # ------------------------------------------------------------------ creation
    def holds(self, campaign: Campaign) -> bool:
        """True when the store exists and holds ``campaign`` (a resume), False when there
        is nothing at the path yet (or an empty folder); refused (ValueError) when it
        holds another campaign (saying which keys differ) or is not a campaign store.
        Writes nothing."""
        if not self.path.exists():
            return False
        if not self.path.is_dir():
            raise ValueError(f"{self.path} is a file, not a campaign store; give another --out")
        held = self.campaign_document()
        if held is None:
            if any(self.path.iterdir()):
                raise ValueError(f"{self.path} exists and is not a lookout campaign store; give another --out")
            return False
        if canonical_json(held) != campaign.canonical():
            changed = differences(held, campaign.document())
            shown = "; ".join(changed[:5]) + (f"; and {len(changed) - 5} more" if len(changed) > 5 else "")
            raise ValueError(
                f"{self.path} holds another campaign (fingerprint {self.fingerprint()}, this spec's is {campaign.fingerprint()}): "
                f"{shown}; resume it with its own spec, or give another --out"
            )
        return True

    @classmethod
    def open_or_create(cls, path: str | Path, campaign: Campaign) -> CampaignStore:
        """The store at ``path`` for ``campaign``: created if missing; refused (ValueError)
        if it holds another campaign or is not a campaign store."""
        store = cls(path)
        if not store.holds(campaign):
            store._create(campaign)
        return store

    def _create(self, campaign: Campaign) -> None:
        import dask.array as da
        import xarray as xr

        from lookout.scenario import metrics as metric_module

        scenario = campaign.base.build()
        metrics = metric_module.resolve(list(campaign.metric_names), scenario)
        n_points, n_seeds, size = len(campaign.points), len(campaign.seeds), campaign.chunk_runs
        data: dict[str, Any] = {}
        coords: dict[str, Any] = {
            "point": np.arange(n_points),
            "seed": ("seed", np.asarray(campaign.seeds, dtype=np.int64), {"long_name": "PRNG seed of the run"}),
        }

        def empty(shape, chunks):
            return da.full(shape, np.nan, dtype=np.float64, chunks=chunks)

        for metric in metrics:
            data[metric.variable] = (
                ("point", "seed"),
                empty((n_points, n_seeds), (1, size)),
                {"units": metric.units, "long_name": metric.description, "metric": metric.name},
            )
        data["diverged"] = (
            ("point", "seed"),
            empty((n_points, n_seeds), (1, size)),
            {"long_name": "1 if the run diverged, 0 if not", "metric": "diverged"},
        )
        for axis in campaign.axes:
            values = [axis.value_label(point[axis.label]) for point in campaign.points]
            # strings as variable-length strings: Zarr v3 has a spec for them, not for fixed-length ones
            coords[variable_name(axis.label)] = (
                "point",
                np.asarray(values, dtype=object if any(isinstance(v, str) for v in values) else None),
                {"long_name": axis.label, "fields": ", ".join(axis.fields), "scale": int(axis.scale)},
            )
        kept = campaign.settings.trajectories
        if kept is not None:
            signals = {name: signal for _, name, signal in scenario.record_signals.variables()}
            coords["kept_time"] = ("kept_time", scenario.record_times[:: kept.every], {"units": "s", "long_name": "time of the kept records"})
            for name in kept.signals:
                signal = signals[name]
                dims = ("point", "seed", "kept_time") + ((signal.dim,) if signal.labels else ())
                shape = (n_points, n_seeds, len(coords["kept_time"][1])) + ((len(signal.labels),) if signal.labels else ())
                if signal.labels:
                    coords[signal.dim] = (signal.dim, np.asarray(signal.labels, dtype=object))  # variable-length strings: Zarr v3 has a spec for them
                data[f"trajectory__{name}"] = (dims, empty(shape, (1, size) + shape[2:]), {"units": signal.units, "long_name": signal.long_name})
        ds = xr.Dataset(
            data,
            coords=coords,
            attrs={
                "title": f"lookout campaign over {campaign.base.title}",
                "lookout_version": _version(),
                "campaign_fingerprint": campaign.fingerprint(),
                "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                "chunk_runs": size,
                "sweep_kind": campaign.settings.sweep.kind,
                "axes": json.dumps([variable_name(axis.label) for axis in campaign.axes]),
            },
        )
        encoding = {name: {"chunks": tuple(array[1].chunksize)} for name, array in data.items()}
        ds.to_zarr(self.path, mode="w-", compute=False, encoding=encoding, consolidated=False)
        import zarr

        # the metadata group: the campaign (spec with the scenario inlined) and version as
        # attributes, the per-chunk records as files beside; xarray skips a subgroup
        zarr.open_group(str(self.path / META), mode="w", attributes={"campaign": campaign.canonical(), "lookout_version": _version()})
        self.consolidate()
        (self.path / META / "chunks").mkdir(parents=True, exist_ok=True)
        self._atomic_write(self.path / META / "campaign.json", json.dumps(campaign.document(), indent=1, sort_keys=True))

    def consolidate(self) -> None:
        """Consolidate the Zarr metadata (it does not change after creation), so that
        ``xarray.open_zarr(STORE)`` opens the store without a warning."""
        import warnings

        import zarr

        with warnings.catch_warnings():
            # Zarr v3 has no consolidated metadata in its specification yet, and the
            # _lookout group's JSON files are not Zarr nodes: both are said at each call
            warnings.simplefilter("ignore", UserWarning)
            zarr.consolidate_metadata(str(self.path))

    # ------------------------------------------------------------------ reading
    def campaign_document(self) -> dict | None:
        path = self.path / META / "campaign.json"
        return json.loads(path.read_text()) if path.exists() else None

    def fingerprint(self) -> str | None:
        document = self.campaign_document()
        return None if document is None else fingerprint_of(document)

    def done(self) -> dict[int, dict]:
        """Chunk index -> its completion record, for every finished chunk."""
        if not self.records.exists():
            return {}
        result = {}
        for path in self.records.glob("chunk-*.json"):
            record = json.loads(path.read_text())
            result[int(record["chunk"])] = record
        return result

    def open(self) -> xr.Dataset:
        """The store as an :class:`xarray.Dataset`."""
        import xarray as xr

        return xr.open_zarr(self.path, consolidated=False)

    def grid(self) -> xr.Dataset:
        """A grid campaign's store with the sweep point unfolded into one dimension per
        axis (in the axes' order, each with its values in the order the spec gives
        them) and ``seed``: ``(axis_1, ..., axis_n, seed)``."""
        import xarray as xr

        ds = self.open().load()
        if ds.attrs.get("sweep_kind") != "grid":
            raise ValueError(f"{self.path}: only a grid campaign's points form a grid; this one is a {ds.attrs.get('sweep_kind')}")
        names = json.loads(ds.attrs.get("axes", "[]"))
        levels = {}
        for name in names:
            values = ds[name].values.tolist()
            levels[name] = list(dict.fromkeys(values))
        shape = tuple(len(levels[name]) for name in names)
        data = {}
        for variable, array in ds.data_vars.items():
            if array.dims[:2] != ("point", "seed"):
                continue
            data[variable] = ((*names, *array.dims[1:]), array.values.reshape(shape + array.shape[1:]), array.attrs)
        coords = {name: (name, np.asarray(levels[name], dtype=ds[name].dtype), ds[name].attrs) for name in names}
        coords.update({name: coordinate for name, coordinate in ds.coords.items() if "point" not in coordinate.dims})
        return xr.Dataset(data, coords=coords, attrs=ds.attrs)

    # ------------------------------------------------------------------ writing
    @staticmethod
    def _atomic_write(path: Path, text: str) -> None:
        temporary = path.with_name(path.name + f".{os.getpid()}.tmp")
        temporary.write_text(text)
        os.replace(temporary, path)

    def write_chunk(self, campaign: Campaign, chunk: Chunk, result: dict, *, worker: str = "local") -> None:
        """Write ``result`` of :func:`~lookout.studies.campaign.compute_chunk` into the
        chunk's region, then its record. A chunk already recorded is refused."""
        import zarr

        record_path = self.records / f"{chunk.key}.json"
        if record_path.exists():
            raise ValueError(f"{chunk.key} of {self.path} is already written")
        try:
            if getattr(self, "_group", None) is None:
                self._group = zarr.open_group(str(self.path), mode="r+")
            group = self._group
            start = chunk.block * campaign.chunk_runs
            region = slice(start, start + len(chunk.seeds))
            for name, values in result.items():
                if name in ("seconds", "compiled"):
                    continue
                array = group[name]
                assert isinstance(array, zarr.Array)  # every result is an array of the store
                values = np.asarray(values, dtype=np.float64)
                array[chunk.point, region, ...] = values
            self._write_record(chunk, result, worker, record_path)
        except OSError as error:
            raise OSError(error.errno, f"cannot write {chunk.key} into the campaign store {self.path}: {error.strerror or error}") from None

    def _write_record(self, chunk: Chunk, result: dict, worker: str, record_path: Path) -> None:
        record = {
            "chunk": chunk.index,
            "point": chunk.point,
            "seeds": [chunk.seeds[0], chunk.seeds[-1]],
            "seconds": float(result.get("seconds", np.nan)),
            "compiled": bool(result.get("compiled", True)),
            "worker": worker,
            "finished": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        }
        self._atomic_write(record_path, json.dumps(record))


def status(path: str | Path) -> dict:
    """What a store holds: chunks and runs done, time spent, diverged runs, provenance."""
    store = CampaignStore(path)
    document = store.campaign_document()
    if document is None:
        raise ValueError(f"{store.path} holds no campaign.json: not a lookout campaign store")
    ds = store.open()
    done = store.done()
    chunk_runs = int(ds.attrs["chunk_runs"])
    points, seeds = ds.sizes["point"], ds.sizes["seed"]
    chunks = points * (seeds // chunk_runs)
    diverged = ds["diverged"].values
    return {
        "title": ds.attrs.get("title", ""),
        "chunks": chunks,
        "chunks_done": len(done),
        "runs": points * seeds,
        "runs_done": len(done) * chunk_runs,
        "complete": len(done) == chunks,
        "points": points,
        "seeds_per_point": seeds,
        "chunk_runs": chunk_runs,
        "sweep_kind": ds.attrs.get("sweep_kind"),
        "axes": json.loads(ds.attrs.get("axes", "[]")),
        "metrics": [
            str(ds[name].attrs.get("metric", name)) for name in ds.data_vars if name != "diverged" and not str(name).startswith("trajectory__")
        ],
        "chunk_seconds": float(sum(record.get("seconds", 0.0) for record in done.values())),
        "diverged": int(np.nansum(diverged)),
        "lookout_version": ds.attrs.get("lookout_version"),
        "created": ds.attrs.get("created"),
        "fingerprint": ds.attrs.get("campaign_fingerprint"),
        "scenario": document["scenario"].get("template")
        or ", ".join(
            f"{role} {document['scenario'][role]['kind']}" for role in ("plant", "observer") if isinstance(document["scenario"].get(role), dict)
        ),
    }
