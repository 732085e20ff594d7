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

import math
import os
import time
from dataclasses import dataclass
from typing import Callable

from lookout.studies.campaign import Campaign, compute_chunk
from lookout.studies.store import CampaignStore

#: As in the CLI: a chunk's peak memory is about this many times its records.
PEAK_MEMORY_PER_RECORD_BYTE = 4
#: What a chunk needs besides its records (the JAX runtime and compiled programs).
WORKER_BASE_BYTES = 600e6
#: A dask campaign in which no chunk finishes for max(STALL_SECONDS, STALL_CALIBRATIONS x
#: the calibration chunk's time) submits its unfinished chunks again.
STALL_SECONDS = 60.0
STALL_CALIBRATIONS = 5.0
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


def _bytes(count: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{count:.0f} B"


def record_bytes(campaign: Campaign, scenario) -> int:
    """Bytes one run of a chunk holds per recorded sample: every recorded signal when
    trajectories are kept (the chunk is simulated with its records), else the series
    its metrics keep (one number per settling time; the metrics accumulate in the
    engine's scan). From the signals' sizes, without tracing a sample."""
    import jax.numpy as jnp

    itemsize = jnp.zeros(()).dtype.itemsize
    if campaign.settings.trajectories is None:
        return sum(1 for name in campaign.metric_names if name.startswith("settling_time:")) * itemsize
    signals = scenario.record_signals
    size = sum(s.size for s in (*signals.truth, *signals.estimate, *signals.extra, *signals.reference))
    return int((size + signals.measurement.size + 2 * signals.input.size) * itemsize)


def chunk_memory(campaign: Campaign) -> float:
    """Bytes one chunk needs on its worker: what its runs hold per record while they
    are reduced, and the runtime."""
    from lookout.studies.campaign import _point_scenario

    scenario = _point_scenario(campaign.canonical(), 0)
    return PEAK_MEMORY_PER_RECORD_BYTE * campaign.chunk_runs * scenario.n_records * record_bytes(campaign, scenario) + WORKER_BASE_BYTES


def check_memory(campaign: Campaign, available: float | None, workers: int) -> float:
    """Refuse (ValueError, with the numbers) a chunk that will not fit a worker."""
    need = chunk_memory(campaign)
    if available is not None and need > available:
        from lookout.studies.campaign import _point_scenario

        scenario = _point_scenario(campaign.canonical(), 0)
        raise ValueError(
            f"chunk_runs {campaign.chunk_runs} needs about {_bytes(need)} per chunk ({campaign.chunk_runs} runs x {scenario.n_records} records x "
            f"{record_bytes(campaign, scenario)} B x {PEAK_MEMORY_PER_RECORD_BYTE}, + {_bytes(WORKER_BASE_BYTES)} runtime), and a worker has "
            f"{_bytes(available)} ({workers} worker(s)): set a smaller chunk_runs (a divisor of seeds_per_point) or fewer workers"
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


def run_campaign(
    campaign: Campaign,
    path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    say: Callable[[str], None] = print,
    progress: Callable[[int, int], None] | None = None,
    available_memory: Callable[[], int | None] | None = None,
) -> dict:
    """Compute the chunks of ``campaign`` missing from the store at ``path``.

    Returns ``{"chunks": total, "computed": this call, "done": done now, "seconds": wall}``.
    """
    store = CampaignStore.open_or_create(path, campaign)
    chunks = campaign.chunks()
    done = store.done()
    pending = [chunk for chunk in chunks if chunk.index not in done]
    if not pending:
        say(f"{path}: all {len(chunks)} chunks are done; nothing to compute")
        return {"chunks": len(chunks), "computed": 0, "done": len(chunks), "seconds": 0.0}
    if done:
        say(f"{path}: resuming: {len(done)} of {len(chunks)} chunks done, {len(pending)} to compute")
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
        memory = f"about {_bytes(estimate.chunk_bytes)} per chunk"
        if estimate.available_bytes is not None:
            memory += f" of {_bytes(estimate.available_bytes)} a worker has"
        say(f"{estimate.chunks} chunks of {campaign.chunk_runs} runs ({len(campaign.points)} points x {campaign.settings.seeds_per_point} seeds), {estimate.pending} to compute; {memory}")

    def calibrate(estimate: Estimate, result: dict) -> None:
        """The first chunk gives the compile time, the first compiled chunk the rest."""
        seconds = float(result["seconds"])
        if estimate.compile_seconds is None and not result["compiled"]:
            estimate.compile_seconds = seconds
            say(f"first chunk: {seconds:.1f} s with compilation")
        elif estimate.chunk_seconds is None and result["compiled"]:
            estimate.chunk_seconds = seconds
            remaining = max(0, estimate.pending - count["computed"])
            estimate.compile_seconds = max(0.0, (estimate.compile_seconds or seconds) - seconds)
            total = estimate.chunk_seconds * math.ceil(remaining / max(1, estimate.workers))
            say(
                f"calibration chunk: {seconds:.2f} s compiled ({estimate.compile_seconds:.1f} s to compile); "
                f"the other {remaining} chunks on {estimate.workers} worker(s): about {total:.0f} s"
            )

    memory = available_memory or _available_memory
    if scheduler is None and workers == 0:
        available = memory()
        estimate = Estimate(check_memory(campaign, available, 1), available, len(chunks), len(pending), 1)
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
        from dask.distributed import Client, LocalCluster

        cluster = None
        if scheduler is None:
            workers = workers or os.cpu_count() or 1
            available = memory()
            per_worker = None if available is None else available / workers
            estimate = Estimate(check_memory(campaign, per_worker, workers), per_worker, len(chunks), len(pending), workers)
            cluster = LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0",
                env=_local_env(), memory_limit=0,
            )
            client = Client(cluster)
        else:
            client = Client(scheduler, timeout="20s")
            info = client.scheduler_info()["workers"]
            limits = [w.get("memory_limit") or None for w in info.values()]
            per_worker = min(limits) if limits and all(limits) else None
            workers = max(1, len(info))
            estimate = Estimate(check_memory(campaign, per_worker, workers), per_worker, len(chunks), len(pending), workers)
        try:
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
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    seconds = time.perf_counter() - start
    return {"chunks": len(chunks), "computed": len(pending), "done": count["done"], "seconds": seconds}


def _worker(client, future) -> str:
    """Which worker computed ``future`` (as far as the scheduler still knows)."""
    try:
        who = client.who_has([future]).get(future.key)
        return who[0] if who else "dask"
    except Exception:  # the record is for people: never fail a campaign over it
        return "dask"


def _available_memory() -> int | None:
    from lookout.cli import available_memory

    return available_memory()
