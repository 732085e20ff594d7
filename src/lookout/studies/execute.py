"""Running a campaign's chunks: in this process, on a local dask cluster, or on any
dask.distributed cluster, with estimates (memory up front, time from the first
chunks) and resume from the store.

- ``workers=0``: every chunk in this process, one after another.
- ``workers=N`` (default: one per core): a ``LocalCluster`` of N single-threaded
  worker processes bound to 127.0.0.1, each running one chunk (one vmapped batch) at
  a time with one XLA device, so N workers use N cores.
- ``scheduler="tcp://host:port"``: an existing cluster whose workers have lookout
  installed; nothing else changes. A worker whose JAX sees a GPU runs its chunks there.

The driver alone writes the store: workers return a chunk's metrics (a few numbers
per run), and the driver writes the chunk's region and then its completion record.
A worker that dies mid-chunk loses only that task, which the scheduler gives to
another worker; a driver that dies leaves the store with complete chunks only, and
the next ``run`` computes the rest.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from lookout import _resources
from lookout._resources import PEAK_MEMORY_PER_RECORD_BYTE, format_bytes
from lookout._validation import one_line
from lookout.studies.campaign import Campaign, compute_chunk
from lookout.studies.store import CampaignStore

if TYPE_CHECKING:
    from dask.distributed import LocalCluster

    from lookout.sim import Scenario

#: What a chunk needs besides its records (the JAX runtime and compiled programs).
WORKER_BASE_BYTES = 600e6
#: A dask campaign in which no chunk finishes for max(STALL_SECONDS, STALL_CALIBRATIONS x
#: the calibration chunk's time) submits its unfinished chunks again.
STALL_SECONDS = 60.0
STALL_CALIBRATIONS = 5.0
#: Compiled chunks per worker over which the driver times the campaign before it
#: says how long the rest will take.
CALIBRATION_CHUNKS_PER_WORKER = 2
#: How long the driver waits for a scheduler to answer.
SCHEDULER_TIMEOUT = "20s"
#: How often the driver looks for finished chunks.
POLL_SECONDS = 0.05


@dataclass
class Estimate:
    """Memory per chunk (up front) and time (from the first chunks: one that compiles,
    then one that runs compiled)."""

    chunk_bytes: float
    available_bytes: float | None
    chunks: int
    pending: int
    workers: int
    chunk_seconds: float | None = None
    compile_seconds: float | None = None
    #: the driver's clock when the first compiled chunk came, and how many came since
    first_compiled: float | None = None
    compiled_since: int = 0
    #: chunks that came with compilation (one per worker and program), and without
    compiling_done: int = 0
    compiled_seen: int = 0


def record_bytes(campaign: Campaign, scenario: Scenario) -> int:
    """Bytes one run of a chunk holds per recorded sample: every recorded signal when
    trajectories are kept (the chunk is simulated with its records), else the series
    its metrics keep (one number per settling time; the metrics accumulate in the
    engine's scan). From the signals' sizes, without tracing a sample."""
    import jax.numpy as jnp

    from lookout.sim import record_nbytes

    if campaign.settings.trajectories is None:
        from lookout.scenario.metrics import SERIES_KINDS

        return sum(1 for name in campaign.metric_names if name.partition(":")[0] in SERIES_KINDS) * jnp.zeros(()).dtype.itemsize
    return record_nbytes(scenario)


def chunk_memory(campaign: Campaign) -> float:
    """Bytes one chunk needs on its worker: what its runs hold per record while they
    are reduced, what the scan holds per record whatever the runs (times, indices,
    windows), and the runtime; for the longest run of the sweep."""
    from lookout.sim.memory import RECORD_OVERHEAD_BYTES
    from lookout.studies.campaign import _point_scenario

    scenario = _point_scenario(campaign.canonical(), 0)
    records = max(campaign.records, scenario.n_records)
    from lookout.sim import working_nbytes

    per_record = PEAK_MEMORY_PER_RECORD_BYTE * campaign.chunk_runs * record_bytes(campaign, scenario) + RECORD_OVERHEAD_BYTES
    return records * per_record + campaign.chunk_runs * working_nbytes(scenario) + WORKER_BASE_BYTES


def check_memory(campaign: Campaign, available: float | None, workers: int) -> float:
    """Refuse (ValueError, with the numbers) a chunk that will not fit a worker."""
    need = chunk_memory(campaign)
    if available is not None and need > available:
        from lookout.sim import working_nbytes
        from lookout.sim.memory import RECORD_OVERHEAD_BYTES
        from lookout.studies.campaign import _point_scenario

        scenario = _point_scenario(campaign.canonical(), 0)
        records = max(campaign.records, scenario.n_records)
        working = working_nbytes(scenario)
        steps = f", + {campaign.chunk_runs} runs x {format_bytes(working)} while a sample is taken" if working > 2**20 else ""
        raise ValueError(
            f"chunk_runs {campaign.chunk_runs} needs about {format_bytes(need)} per chunk ({records} records x ({campaign.chunk_runs} runs x "
            f"{record_bytes(campaign, scenario)} B x {PEAK_MEMORY_PER_RECORD_BYTE} + {RECORD_OVERHEAD_BYTES} B){steps}, + {format_bytes(WORKER_BASE_BYTES)} runtime), "
            f"and a worker has {format_bytes(available)} ({workers} worker(s)): set a smaller chunk_runs (a divisor of seeds_per_point), "
            "a shorter duration, or fewer workers"
        )
    return need


def _local_env() -> dict:
    """XLA options of a local worker: this process's, with one device (a worker is one
    core's worth), so a chunk compiles to the same arithmetic on a worker as here."""
    import re

    from lookout import SMALL_LOOP_BYTES

    flags = os.environ.get("XLA_FLAGS", "")
    flags = re.sub(r"--xla_force_host_platform_device_count=\S+", "", flags)
    if "xla_cpu_small_while_loop_byte_threshold" not in flags:
        flags += f" --xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}"
    return {"XLA_FLAGS": " ".join((flags + " --xla_force_host_platform_device_count=1").split())}


def local_cluster(workers: int) -> LocalCluster:
    """A ``LocalCluster`` of ``workers`` single-threaded worker processes bound to
    127.0.0.1, each with one XLA device (:func:`_local_env`)."""
    from dask.distributed import LocalCluster

    return LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        env=_local_env(),
        memory_limit=0,
    )


class SchedulerError(ConnectionError):
    """The dask scheduler given cannot be reached (the message names the address)."""


#: A file of the store takes at least one file-system block.
FILE_BLOCK_BYTES = 4096
#: The store's metadata (Zarr JSON, the campaign document) besides the chunks.
STORE_METADATA_BYTES = 1e6


def store_bytes(campaign: Campaign, chunks: int) -> float:
    """Disk that ``chunks`` chunks of ``campaign`` take in its store, at most: every kept
    number uncompressed, and a file-system block per variable's chunk and per record."""
    from lookout.studies.campaign import _point_scenario, kept_values

    scenario = _point_scenario(campaign.canonical(), 0)
    variables = len(campaign.metric_names) + 1 + len(campaign.settings.trajectories.signals if campaign.settings.trajectories else ())
    per_chunk = campaign.chunk_runs * 8 * kept_values(campaign.settings, scenario) + (variables + 1) * FILE_BLOCK_BYTES
    return chunks * per_chunk + STORE_METADATA_BYTES


def check_disk(campaign: Campaign, path: str | Path, pending: int, free: float | None = None) -> float:
    """Refuse (ValueError naming the store's file system) a campaign whose store will
    not fit on the disk, before the store exists."""
    need = store_bytes(campaign, pending)
    free = _resources.free_disk(path) if free is None else free
    _resources.refuse_unless_it_fits(
        need,
        f"the store {path} ({pending} chunks x {campaign.chunk_runs} runs)",
        "free some space, give --out on another disk, or use fewer seeds or points",
        available=free,
        resource="disk space",
    )
    return need


def run_campaign(
    campaign: Campaign,
    path: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    say: Callable[[str], None] = print,
    progress: Callable[[int, int], None] | None = None,
    available_memory: Callable[[], int | None] | None = None,
    free_disk: Callable[[Path], int | None] | None = None,
) -> dict:
    """Compute the chunks of ``campaign`` missing from the store at ``path``.

    Everything is checked before the store exists: a store at ``path`` holds this
    campaign or nothing, a chunk fits a worker's memory, the store fits the disk, and
    the scheduler answers. A store this call created is removed again if the call
    fails before a chunk is written, so a refused or failed start leaves nothing
    behind (and a corrected spec is not blocked by an empty store).

    Returns ``{"chunks": total, "computed": this call, "done": done now, "seconds": wall}``.
    """
    store = CampaignStore(path)
    resumed = store.holds(campaign)
    chunks = campaign.chunks()
    done = store.done() if resumed else {}
    pending = [chunk for chunk in chunks if chunk.index not in done]
    if not pending:
        say(f"{path}: all {len(chunks)} chunks are done; nothing to compute")
        store.consolidate()
        return {"chunks": len(chunks), "computed": 0, "done": len(chunks), "seconds": 0.0}
    memory = available_memory or _resources.available_memory
    local = scheduler is None and workers == 0
    if scheduler is None:
        workers = 1 if local else workers or os.cpu_count() or 1
        available = memory()
        per_worker = None if available is None else available / workers
        estimate = Estimate(check_memory(campaign, per_worker, workers), per_worker, len(chunks), len(pending), workers)
    disk = check_disk(campaign, path, len(pending), None if free_disk is None else free_disk(Path(path)))
    client = cluster = None
    if not local:
        from dask.distributed import Client

        if scheduler is None:
            assert workers is not None  # set above when there is no scheduler
            cluster = local_cluster(workers)
            client = Client(cluster)
        else:
            try:
                client = Client(scheduler, timeout=SCHEDULER_TIMEOUT)
                info = client.scheduler_info()["workers"]
            except Exception as error:  # an address dask cannot parse, or a scheduler that does not answer
                if client is not None:
                    client.close()
                raise SchedulerError(f"cannot reach the scheduler ({one_line(error) or type(error).__name__})") from None
            limits = [w.get("memory_limit") or None for w in info.values()]
            per_worker = min(limit for limit in limits if limit is not None) if limits and all(limits) else None
            workers = max(1, len(info))
            try:
                estimate = Estimate(check_memory(campaign, per_worker, workers), per_worker, len(chunks), len(pending), workers)
            except ValueError:
                client.close()
                raise
    created = not resumed
    try:
        if created:
            store._create(campaign)
        else:
            say(f"{path}: resuming: {len(done)} of {len(chunks)} chunks done, {len(pending)} to compute")
        return _compute(campaign, store, chunks, pending, done, estimate, disk, client, say, progress)
    except BaseException:
        if created and not store.done():
            shutil.rmtree(store.path, ignore_errors=True)  # nothing of value: leave no store behind
        raise
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


def _compute(campaign, store, chunks, pending, done, estimate: Estimate, disk: float, client, say, progress) -> dict:
    """The chunk loop of :func:`run_campaign`: in this process (``client`` None) or on dask."""
    start = time.perf_counter()
    canonical = campaign.canonical()
    count = {"done": len(done), "computed": 0}

    def finished(chunk, result, worker):
        store.write_chunk(campaign, chunk, result, worker=worker)
        count["done"] += 1
        count["computed"] += 1
        calibrate(estimate, result)
        if progress is not None:
            progress(count["done"], len(chunks))

    def announce(estimate: Estimate) -> None:
        memory = f"about {format_bytes(estimate.chunk_bytes)} per chunk"
        if estimate.available_bytes is not None:
            memory += f" of {format_bytes(estimate.available_bytes)} a worker has"
        say(
            f"{estimate.chunks} chunks of {campaign.chunk_runs} runs ({len(campaign.points)} points x {campaign.settings.seeds_per_point} seeds), "
            f"{estimate.pending} to compute; {memory}; at most {format_bytes(disk)} on disk"
        )

    def calibrate(estimate: Estimate, result: dict) -> None:
        """The first chunk gives the compile time; the estimate of the rest comes from the
        driver's clock over compiled chunks once every worker has compiled (each worker's
        first chunk compiles; until the last of them is done, fewer workers deliver), over
        CALIBRATION_CHUNKS_PER_WORKER chunks per worker: what the store receives per
        second, with the workers sharing the machine, the scheduling and the writes
        included, not one chunk's own time."""
        seconds = float(result["seconds"])
        if not result["compiled"]:
            estimate.compiling_done += 1
            if estimate.compile_seconds is None:
                estimate.compile_seconds = seconds
                say(f"first chunk: {seconds:.1f} s with compilation")
            return
        estimate.compiled_seen += 1
        # wait for every worker's compiling chunk, unless one never comes (a worker that
        # died while compiling and compiles again): then the others' chunks set the pace
        waiting = estimate.compiling_done < min(estimate.workers, estimate.pending)
        if estimate.chunk_seconds is not None or (waiting and estimate.compiled_seen <= CALIBRATION_CHUNKS_PER_WORKER * estimate.workers):
            return
        now = time.monotonic()
        if estimate.first_compiled is None:
            estimate.first_compiled = now
            return
        estimate.compiled_since += 1
        if estimate.compiled_since < CALIBRATION_CHUNKS_PER_WORKER * max(1, estimate.workers):
            return
        remaining = max(0, estimate.pending - count["computed"])
        estimate.chunk_seconds = (now - estimate.first_compiled) / estimate.compiled_since  # wall time per chunk, all workers together
        say(
            f"calibration: {estimate.compiled_since + 1} compiled chunks, one every {estimate.chunk_seconds:.2f} s on {estimate.workers} worker(s); "
            f"the other {remaining} chunks: about {estimate.chunk_seconds * remaining:.0f} s"
        )

    if client is None:
        announce(estimate)
        # a chunk is written by one writer thread while the next one computes (XLA
        # releases the GIL); at most one write is pending, and an error in it stops the run
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="lookout-store") as writer:
            writing = None
            for chunk in pending:
                result = compute_chunk(canonical, chunk.point, chunk.seeds)
                if writing is not None:
                    writing.result()
                writing = writer.submit(finished, chunk, result, "local")
            if writing is not None:
                writing.result()
    else:
        say(f"dask scheduler: {client.scheduler.address}; dashboard: {client.dashboard_link or 'not available (install bokeh)'}")
        announce(estimate)
        fingerprint = campaign.fingerprint()

        def submit(chunk, attempt=0):
            key = f"{chunk.key}-{fingerprint}" + (f"-retry{attempt}" if attempt else "")
            return client.submit(compute_chunk, canonical, chunk.point, chunk.seeds, key=key, pure=False)

        # A killed worker's tasks go to the others. Dask has known cases where such a
        # task stays "processing" on no live worker (dask/distributed#3196, #6263), and
        # as_completed can wait forever after a worker restarts (dask/dask#8882, seen
        # here: a test hung with it). So the driver polls, and if no chunk finishes for
        # `stall` seconds (after the first, which compiles), the unfinished ones are
        # submitted again under new keys. Runs are deterministic: a repeat changes nothing.
        stall = None
        futures = {submit(chunk): chunk for chunk in pending}
        attempt = 0
        last = time.monotonic()
        while futures:
            # poll (Future.done is cheap and needs no event loop of this thread's own)
            ready = [future for future in futures if future.done()]
            if not ready:
                if stall is not None and time.monotonic() - last > stall:
                    attempt += 1
                    say(f"no chunk finished in {stall:.0f} s: submitting the {len(futures)} unfinished chunks again (attempt {attempt + 1})")
                    stale = list(futures)
                    futures = {submit(chunk, attempt=attempt): chunk for chunk in futures.values()}
                    client.cancel(stale)
                    last = time.monotonic()
                time.sleep(POLL_SECONDS)
                continue
            last = time.monotonic()
            for future in ready:
                result = future.result()
                finished(futures.pop(future), result, _worker(client, future))
                future.release()  # a stored chunk's result is not needed again, even if its worker dies
                if stall is None:
                    stall = max(STALL_SECONDS, STALL_CALIBRATIONS * float(result["seconds"]))
    store.consolidate()
    seconds = time.perf_counter() - start
    return {"chunks": len(chunks), "computed": len(pending), "done": count["done"], "seconds": seconds}


def _worker(client, future) -> str:
    """Which worker computed ``future`` (as far as the scheduler still knows)."""
    try:
        who = client.who_has([future]).get(future.key)
        return who[0] if who else "dask"
    except Exception:  # the record is for people: never fail a campaign over it
        return "dask"
