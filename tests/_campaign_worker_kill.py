"""Run by tests/test_studies.py in a process of its own: a campaign on a 2-worker
LocalCluster, one worker SIGKILLed while it runs a chunk.

The dask cluster, its client and their event-loop threads live and die in this process,
never in a pytest worker, so whatever they leave behind at shutdown cannot crash or hang
the test run. Prints one JSON line: the campaign's result, the kill, and the messages.

    python tests/_campaign_worker_kill.py SPEC STORE
"""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

import lookout

lookout.configure_cpu(devices=2)  # as in the test session: batches take the sharded path

from dask.distributed import Client  # noqa: E402

from lookout.studies.campaign import load_campaign  # noqa: E402
from lookout.studies.execute import run_campaign  # noqa: E402


def main(spec: str, store: str) -> dict:
    messages, killed, outcome = [], {}, {}
    started, done = threading.Event(), threading.Event()

    def say(text):
        messages.append(text)
        if text.startswith("dask scheduler: "):
            outcome["address"] = text.split()[2].rstrip(";")
            started.set()

    def drive():
        try:
            outcome["result"] = run_campaign(load_campaign(spec), Path(store), workers=2, say=say)
        except BaseException as error:  # noqa: BLE001  (reported to the test)
            outcome["error"] = f"{type(error).__name__}: {error}"
        finally:
            started.set()
            done.set()

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    if not started.wait(120):
        return {"error": "the cluster did not start within 120 s", "messages": messages}
    records = Path(store) / "_lookout" / "chunks"
    if "address" in outcome:
        with Client(outcome["address"], timeout="30s") as watcher:
            deadline = time.monotonic() + 300
            while not done.is_set() and time.monotonic() < deadline and not killed:
                processing = {address: tasks for address, tasks in watcher.processing().items() if tasks}
                recorded = len(list(records.glob("chunk-*.json"))) if records.exists() else 0
                if recorded >= 1 and processing:
                    address = next(iter(processing))
                    pid = watcher.run(os.getpid, workers=[address])[address]
                    os.kill(pid, signal.SIGKILL)
                    killed.update(address=address, tasks=list(processing[address]), recorded=recorded)
                time.sleep(0.01)
    if not done.wait(300):
        return {"error": "the campaign did not finish within 300 s of the kill", "messages": messages, "killed": killed}
    thread.join()
    return {"result": outcome.get("result"), "error": outcome.get("error"), "killed": killed, "messages": messages}


if __name__ == "__main__":
    print(json.dumps(main(*sys.argv[1:3]), default=str))
    sys.stdout.flush()
    os._exit(0)  # the cluster's threads are not waited for: the test reads the store
