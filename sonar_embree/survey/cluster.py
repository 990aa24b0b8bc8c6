"""Dask for the package (the only module that imports dask and distributed): a client to run on, and a stream of
task results in submission order with back-pressure.

Batches (:mod:`sonar_embree.runs.batch`) and single lines (:func:`sonar_embree.survey.stream.render_line`) run their
pieces here: on the caller's client, on a running scheduler by address, or on a ``LocalCluster`` of single-threaded
worker processes started and stopped around the run (``NUMBA_NUM_THREADS=1`` in each: one process per core renders
more pings per second than one process with a thread per core, docs/benchmarks.md).
"""
from __future__ import annotations

import collections
import contextlib
import logging
import os

from ..errors import ConfigError

log = logging.getLogger(__name__)

#: What each LocalCluster worker process is started with: one Numba thread (the worker runs one task at a time).
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
#: Set before a LocalCluster's worker processes start, in place of Dask's default: its one-thread BLAS and OpenMP,
#: but not ``MALLOC_TRIM_THRESHOLD_=65536``. Setting that turns off glibc's adaptive mmap threshold, so every large
#: array of every block is a fresh mmap whose pages fault in on first touch: a worker's ping cost 7.0 ms against
#: 5.9 ms in process, and two workers side by side 8.1–9.3 ms each; without it 6.3 ms (docs/benchmarks.md).
PRE_SPAWN = {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1}
MALLOC_TRIM = "MALLOC_TRIM_THRESHOLD_"


def default_workers() -> int:
    """Worker processes of a LocalCluster by default: the CPU count, at most 8."""
    return max(1, min(os.cpu_count() or 1, 8))


def capped_workers(workers: int | None, what: str) -> int:
    """The local cluster's worker processes: ``workers`` (default :func:`default_workers`), at most the CPU count,
    with a one-line warning when capped (1000 processes on 2 cores only thrash, and leak semaphores when killed).
    ``what`` names the caller, as the warning starts it: "batch" (then "batch: workers=N") or a flag ending in a
    space ("--workers ": then "--workers N")."""
    cpus = os.cpu_count() or 1
    if workers is None:
        return default_workers()
    if workers > cpus:
        name = what if what.endswith(" ") else f"{what}: workers="
        log.warning("%s%d is more than the %d CPUs here; using %d", name, workers, cpus, cpus)
        return cpus
    return int(workers)


@contextlib.contextmanager
def client_for(client=None, scheduler: str | None = None, workers: int | None = None, dashboard: str | None = None,
               what: str = "batch"):
    """The client to run on: ``client`` itself, one connected to ``scheduler`` (``tcp://host:8786``), or a quiet
    LocalCluster's of ``workers`` single-threaded processes (default :func:`default_workers`); ``dashboard`` its
    dashboard address (default none, and no HTTP port on a public interface)."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            own = Client(scheduler, timeout="20s")
        except OSError as exc:
            raise ConfigError(f"{what}: cannot reach the Dask scheduler at {scheduler!r} ({exc})") from None
        with own:
            yield own
        return
    import dask

    http = {} if dashboard else {"dashboard": False, "dashboard_address": "127.0.0.1:0"}
    with dask.config.set({"distributed.scheduler.http.routes": [] if not dashboard else
                          dask.config.get("distributed.scheduler.http.routes"),
                          "distributed.nanny.pre-spawn-environ": PRE_SPAWN}), _without_env(MALLOC_TRIM):
        cluster = LocalCluster(n_workers=capped_workers(workers, what), threads_per_worker=1, processes=True,
                               dashboard_address=dashboard, silence_logs=logging.ERROR, scheduler_kwargs=http,
                               env=dict(WORKER_ENV))
    with cluster, Client(cluster) as own:
        yield own


@contextlib.contextmanager
def _without_env(name: str):
    """This process's environment without ``name`` while workers are spawned (they inherit it): an earlier Dask
    cluster in this process leaves ``MALLOC_TRIM_THRESHOLD_`` set here, a Nanny setting it before it spawns."""
    saved = os.environ.pop(name, None)
    try:
        yield
    finally:
        if saved is not None:
            os.environ[name] = saved


def lazy_zeros(shape, dtype, chunks):
    """A dask array of zeros (never computed: a Zarr store's template)."""
    import dask.array as da

    return da.zeros(shape, dtype=dtype, chunks=chunks)


def as_completed(futures=()):
    """distributed.as_completed (futures as they finish; more may be added)."""
    from distributed import as_completed as completed

    return completed(list(futures))


def threads_of(client) -> int:
    """Worker threads of the client's cluster (at least 1)."""
    return sum(client.nthreads().values()) or 1


def in_order(client, fn, calls, max_in_flight: int, key_prefix: str):
    """Results of ``fn(*args)`` for each ``(key, args)`` of ``calls``, yielded in ``calls``' order, at most
    ``max_in_flight`` submitted and not yet yielded (a lazy iterable of any length runs in bounded memory). A task's
    exception is raised here; the tasks still pending are cancelled."""
    queue = collections.deque()
    calls = iter(calls)

    def submit_more():
        while len(queue) < max_in_flight:
            nxt = next(calls, None)
            if nxt is None:
                return
            key, args = nxt
            queue.append(client.submit(fn, *args, pure=False, key=f"{key_prefix}-{key}"))

    try:
        submit_more()
        while queue:
            fut = queue.popleft()
            result = fut.result()
            fut.release()
            submit_more()
            yield result
    finally:
        if queue:
            client.cancel(list(queue))
