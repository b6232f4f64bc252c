"""Chunks of Monte Carlo runs as Dask distributed tasks (``navsim run --executor dask``).

Needs the optional extra (``pip install navsim[dask]``); nothing else in navsim imports Dask.
Without a scheduler address a ``LocalCluster`` of one single-threaded process per worker is
started for the run and closed after it. The flight is flown once by the driver and shared
with the workers: on a local cluster as the path of its cached ``.npz`` (the workers load it);
on a remote scheduler the :class:`~navsim.flight.truth.Truth` is scattered to every worker,
so the workers need no shared filesystem. A chunk whose task raises or whose worker dies is
retried once; a chunk that fails twice marks its runs failed and the others complete.
"""

from __future__ import annotations

import uuid

from navsim.foundations.errors import NavsimError

RETRIES = 1


class ExecutorError(NavsimError):
    """The Dask executor cannot start: the extra is missing or the scheduler is unreachable."""

    exit_code = 2


def import_distributed():
    try:
        import distributed
    except ImportError:
        raise ExecutorError("--executor dask needs Dask distributed: pip install 'navsim[dask]'") from None
    return distributed


def _task(fn, truth, rest, runs):
    """Worker side of one chunk: ``fn((truth, *rest, runs))`` (``truth`` a Truth or its path)."""
    return fn((truth, *rest, runs))


def open_client(workers: int, scheduler: str | None):
    """A ``distributed.Client`` on ``scheduler``, or on a new ``LocalCluster`` of ``workers``
    single-threaded processes; returns ``(client, cluster or None)``."""
    distributed = import_distributed()
    if scheduler:
        try:
            return distributed.Client(scheduler, timeout="30s"), None
        except (OSError, TimeoutError) as exc:
            raise ExecutorError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
    import dask

    # a chunk whose worker process dies is retried once too, then flagged (KilledWorker); one
    # chunk on a worker at a time (none waits there, so a dying worker takes only its own chunk's
    # retry with it); no statistical profiler sampling the chunk's thread every 10 ms (it cost
    # 10 % of a chunk with two workers on two cores). A remote cluster keeps its own settings.
    with dask.config.set({"distributed.scheduler.allowed-failures": RETRIES,
                          "distributed.scheduler.worker-saturation": 1.0,
                          "distributed.worker.profile.enabled": False}):
        cluster = distributed.LocalCluster(n_workers=max(workers, 1), threads_per_worker=1, processes=True,
                                           dashboard_address=None)
    return distributed.Client(cluster), cluster


def _error(future) -> str:
    if future.status == "cancelled":          # lost: the scheduler or the cluster went away
        return "cancelled: the Dask scheduler lost the task (cluster shut down or scheduler restarted)"
    exc = future.exception()
    return f"{type(exc).__name__}: {exc}"


def run_chunks_dask(fn, chunks, truth, truth_path, rest: tuple, workers: int, scheduler: str | None = None,
                    progress=None, on_part=None):
    """Run ``fn((truth, *rest, chunk))`` for each chunk as a Dask task.

    Parameters
    ----------
    fn : callable
        The chunk worker (:func:`navsim.experiment.runner._chunk`), importable on the workers.
    chunks : list of range
        Run indices of each chunk.
    truth, truth_path : Truth, Path
        The flight and its cached file.
    rest : tuple
        The worker's arguments between the truth and the runs (scenario, seed).
    workers : int
        Processes of the ``LocalCluster`` (ignored with ``scheduler``).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``).
    progress, on_part : callable, optional
        ``progress(runs_finished)``; ``on_part(part)`` receives each finished chunk as it arrives
        (otherwise the parts are returned).

    Returns
    -------
    tuple
        ``(parts, failed, interrupted)`` as :func:`navsim.experiment.runner.run_chunks`.
    """
    parts, failed, interrupted = [], {}, False
    if not chunks:
        return parts, failed, interrupted
    distributed = import_distributed()
    keep = on_part or parts.append
    client, cluster = open_client(workers, scheduler)
    try:
        shared = client.scatter(truth, broadcast=True) if scheduler else str(truth_path)
        tag = uuid.uuid4().hex[:12]                  # keys unique on a scheduler shared by many runs
        futures = {client.submit(_task, fn, shared, rest, ch, retries=RETRIES, pure=False,
                                 key=f"navsim-chunk-{ch[0]}-{ch[-1]}-{tag}"): ch for ch in chunks}
        try:
            for fut in distributed.as_completed(futures):
                ch = futures.pop(fut)
                if fut.status == "finished":
                    keep(fut.result())
                else:
                    failed.update({r: _error(fut) for r in ch})
                fut.release()
                if progress:
                    progress(len(ch))
        except KeyboardInterrupt:
            interrupted = True
            client.cancel(list(futures))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return parts, failed, interrupted
