"""The campaign engine: runs on a Dask cluster, each result stored as it arrives.

By default a ``dask.distributed.LocalCluster`` sized to the machine (one single-threaded worker process per core:
a run is pure Python and NumPy, one core each); given a scheduler address, the same campaign goes to an existing
cluster whose workers have the project installed. A bounded number of runs is in flight at once (two per worker),
so a campaign killed or interrupted loses at most those: every finished run is already in the store.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager

import dask
from distributed import Client, Future, LocalCluster, as_completed

from flyby.montecarlo.campaign import Campaign, failed_result, run_one
from flyby.montecarlo.progress import Progress
from flyby.montecarlo.store import ResultStore

IN_FLIGHT_PER_WORKER = 2  # one running, one queued: a worker never waits for the next run
# Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in its workers, which turns off glibc's dynamic mmap threshold: every
# frame-sized array is then mapped afresh and page-faulted (an image-level run took 14.3 s instead of 9.1 s, 5 s of
# it in the kernel). None unsets it (a value in the host's environment still wins). Dask's statistical profiler
# walks the running task's stack every 10 ms from a thread of its own: a centroid-level run took 16 % longer in a
# campaign with it (2.18 and 2.34 s against 1.80 and 1.97 s a run, four 60-run campaigns interleaved).
WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                 "distributed.worker.profile.enabled": False}


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None, processes: bool = True
                ) -> Iterator[Client]:
    """A client of the cluster at ``scheduler`` (tcp://HOST:8786), or of a LocalCluster of ``workers``
    single-threaded workers (default: one per core; ``processes=False`` keeps them in this process)."""
    if scheduler is not None:
        client = Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    # the diagnostics page on a free port of this host only: campaigns started side by side never collide; the
    # workers keep glibc's own heap tuning and run without Dask's profiler (``WORKER_CONFIG``)
    with dask.config.set(WORKER_CONFIG), LocalCluster(n_workers=n, threads_per_worker=1, processes=processes,
                      dashboard_address="127.0.0.1:0") as cluster, \
            Client(cluster) as client:
        yield client


def worker_count(client: Client) -> int:
    """Workers the scheduler knows now (at least 1, so a campaign waiting for workers still submits)."""
    return max(1, len(client.scheduler_info(n_workers=-1).get("workers", {})))


def run_campaign(client: Client, campaign: Campaign, runs: list[int], store: ResultStore, progress: Progress,
                 stop_after: int | None = None) -> int:
    """Run ``runs`` of ``campaign`` on the cluster, appending each result to ``store`` as it arrives; return how many
    were stored. ``stop_after`` stops (cancelling the runs in flight) once that many were stored, as a kill would.

    A run whose worker fails outside the run (killed, connection lost) is stored as a failure with the error.
    """
    payload = campaign.to_json()
    shared = client.scatter(payload, broadcast=True, hash=False)  # once to each worker; own key per campaign call
    token = uuid.uuid4().hex[:8]  # task keys of this call, apart from any other campaign on the cluster
    todo = iter(runs)
    pending = as_completed()
    in_flight: dict[Future, int] = {}

    def top_up() -> None:
        """Keep two runs per worker in flight (workers may join a remote cluster during the campaign)."""
        while len(in_flight) < IN_FLIGHT_PER_WORKER * worker_count(client):
            k = next(todo, None)
            if k is None:
                return
            fut = client.submit(run_one, shared, k, pure=False, key=f"flyby-run-{k}-{token}")
            in_flight[fut] = k
            pending.add(fut)

    top_up()
    stored = 0
    try:
        for fut in pending:
            k = in_flight.pop(fut)
            try:
                result = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker fails this run, never the campaign
                result = failed_result(campaign, k, f"{type(exc).__name__}: {exc}")
            store.append(result)
            stored += 1
            progress.update(result.ok, result.passed)
            if stop_after is not None and stored >= stop_after:
                break
            top_up()
    finally:
        for fut in in_flight:
            fut.cancel()
        progress.finish()
    return stored
