"""Campaign overhead and throughput on this machine.

(a) bare: ``simulate_batch`` of the campaign's chunks, one after another, in this
    process (the same batches, compiled beforehand), nothing else: what a user would
    write by hand, with every run's records;
(a2) bare summarized: ``metrics.summarize`` of the same chunks (the metrics
    accumulated in the engine's scan, no records), nothing else;
(b) campaign, in this process (``--workers 0``): the same chunks through
    ``run_campaign``: metrics accumulated per chunk, each chunk written to the Zarr
    store with its completion record (compiled beforehand, so (b) - (a) is the
    overhead against (a), and (b) - (a2) the cost of chunks, store and records);
(c) campaign on a local dask cluster of 1 worker and (d) of 2 workers, from a cold
    start: cluster start-up, each worker's compilation and the chunks.

Prints wall seconds, runs per second and simulated seconds per wall second, and the
overheads (b)/(a) - 1 (target <= 10 %) and (b)/(a2) - 1.
Usage: python benchmarks/campaign.py [--points 32] [--seeds 64] [--chunk-runs 32] [--duration 1500]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import lookout

lookout.configure_cpu()  # before JAX computes anything


def main() -> None:
    import jax

    from lookout.scenario import metrics as metric_module
    from lookout.sim import keys_of_seeds, simulate_batch
    from lookout.studies.campaign import _point_scenario, campaign_from_document, compute_chunk
    from lookout.studies.execute import run_campaign

    parser = argparse.ArgumentParser()
    parser.add_argument("--points", type=int, default=32)
    parser.add_argument("--seeds", type=int, default=64)
    parser.add_argument("--chunk-runs", type=int, default=32)
    parser.add_argument("--duration", type=float, default=1500.0)
    parser.add_argument("--skip-dask", action="store_true")
    args = parser.parse_args()

    values = [0.4 + 0.6 * i / max(1, args.points - 1) for i in range(args.points)]
    document = {
        "scenario": {"template": "fossen-strand-1999", "case": "paper", "settings": {"duration": args.duration}},
        "seeds_per_point": args.seeds,
        "chunk_runs": args.chunk_runs,
        "metrics": ["rms_error:position", "rms_error:velocity", "max_excursion:position", "settling_time:bias_force", "rms_input:force"],
        "sweep": {"kind": "grid", "axes": [{"field": "wave_frequency", "values": values}]},
    }
    campaign = campaign_from_document(document, "<benchmark>")
    chunks = campaign.chunks()
    runs = len(chunks) * campaign.chunk_runs
    simulated = runs * args.duration
    canonical = campaign.canonical()
    print(f"{len(chunks)} chunks of {campaign.chunk_runs} runs, {runs} runs of {args.duration:g} s; devices: {jax.devices()}")

    # compile every path once
    compute_chunk(canonical, 0, chunks[0].seeds)
    jax.block_until_ready(simulate_batch(_point_scenario(canonical, 0), keys_of_seeds(list(chunks[0].seeds))).truth)
    folder = Path(tempfile.mkdtemp(prefix="lookout-bench-"))

    def bare() -> float:
        start = time.perf_counter()
        for chunk in chunks:
            trajectory = simulate_batch(_point_scenario(canonical, chunk.point), keys_of_seeds(list(chunk.seeds)))
            jax.block_until_ready(trajectory.truth)
        return time.perf_counter() - start

    def summarized() -> float:
        start = time.perf_counter()
        for chunk in chunks:
            scenario = _point_scenario(canonical, chunk.point)
            metric_module.summarize(scenario, keys_of_seeds(list(chunk.seeds)), metric_module.resolve(list(campaign.metric_names), scenario))
        return time.perf_counter() - start

    def in_process(name: str) -> float:
        start = time.perf_counter()
        run_campaign(campaign, folder / name, workers=0, say=lambda text: None)
        return time.perf_counter() - start

    rows = []
    for repeat in range(3):
        rows.append((bare(), summarized(), in_process(f"in-process-{repeat}.zarr")))
    for a, a2, b in rows:
        print(
            f"(a) bare {a:7.2f} s   (a2) bare summarized {a2:7.2f} s   (b) campaign in process {b:7.2f} s   overhead vs (a) {b / a - 1:+.1%}, vs (a2) {b / a2 - 1:+.1%}"
        )
    best_a, best_a2, best_b = (min(r[i] for r in rows) for i in range(3))
    print(
        f"best: (a) {best_a:.2f} s, {runs / best_a:.0f} runs/s, {simulated / best_a:.3g} simulated s / s; (a2) {best_a2:.2f} s; "
        f"(b) {best_b:.2f} s, {runs / best_b:.0f} runs/s, overhead vs (a) {best_b / best_a - 1:+.1%}, vs (a2) {best_b / best_a2 - 1:+.1%}"
    )
    if not args.skip_dask:
        for workers in (1, 2):
            start = time.perf_counter()
            messages = []
            run_campaign(campaign, folder / f"dask-{workers}.zarr", workers=workers, say=messages.append)
            wall = time.perf_counter() - start
            calibration = next((m for m in messages if m.startswith("calibration")), "")
            print(
                f"({'c' if workers == 1 else 'd'}) {workers} dask worker(s), cold: {wall:7.2f} s, {runs / wall:.0f} runs/s, {simulated / wall:.3g} simulated s / s  [{calibration}]"
            )
    shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
