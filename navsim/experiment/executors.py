"""Where the chunks of Monte Carlo runs go: the local pool of forked workers (:func:`local_pool`,
one a Monte Carlo or, inside :func:`lend_pool`, one kept for the many Monte Carlos of a budget, a
sweep or a tuning) or Dask distributed tasks (``navsim run --executor dask``).

Needs the optional extra (``pip install navsim[dask]``); nothing else in navsim imports Dask.
Without a scheduler address a ``LocalCluster`` of one single-threaded process per worker is
started for the run and closed after it. The flight is flown once by the driver and shared
with the workers: on a local cluster as the path of its cached ``.npz`` (the workers load it);
on a remote scheduler the :class:`~navsim.flight.truth.Truth` is scattered to every worker,
so the workers need no shared filesystem. A chunk whose task raises or whose worker dies is
retried once; a chunk that fails twice marks its runs failed and the others complete.
:func:`lend_client` connects (or starts the cluster) before the caller touches its output
folder, so an unreachable scheduler deletes nothing.

How runs stop, whatever runs them: :func:`stop_on_sigterm` makes a SIGTERM (Slurm, Kubernetes,
Dask stopping a job) act as Ctrl-C does (:class:`Terminated`, a ``KeyboardInterrupt``: the
finished chunks are kept), and :func:`children_die_with_parent` makes the processes forked for
a run (the local pool's workers) end with the process that started them, also when that one is
killed with SIGKILL.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import multiprocessing
import os
import signal
import threading
import time
import uuid
from concurrent.futures import ProcessPoolExecutor

from navsim.experiment.options import RunOptions
from navsim.foundations.errors import UsageError

RETRIES = 1
#: seconds a connection to a Dask scheduler may take
CONNECT_TIMEOUT_S = 10
#: exit code of a command stopped by SIGTERM (128 + 15, as a shell reports it)
TERMINATED_EXIT = 128 + signal.SIGTERM
#: how often a worker without ``prctl`` looks whether its parent is still there, s
PARENT_POLL_S = 1.0
_PR_SET_PDEATHSIG = 1
#: how the local pool starts its workers: forked where the system can (the die-with-parent hook
#: runs at fork; Python 3.14 makes forkserver Linux's default), else the system's default
POOL_CONTEXT = (multiprocessing.get_context("fork") if "fork" in multiprocessing.get_all_start_methods()
                else None)


class ExecutorError(UsageError):
    """The Dask executor cannot start: the extra is missing, the scheduler is unreachable or
    is not a Dask scheduler."""

    exit_code = 2


class Terminated(KeyboardInterrupt):
    """A SIGTERM, handled as Ctrl-C is (what finished is kept) and reported as terminated."""


class StopState:
    """What :func:`stop_on_sigterm` saw: ``terminated`` once a SIGTERM came."""

    terminated = False


@contextlib.contextmanager
def stop_on_sigterm():
    """While inside: a SIGTERM raises :class:`Terminated` in the main thread (and terminates the
    local pool's workers); yields a :class:`StopState`. Nothing changes outside the main thread."""
    state = StopState()

    def handler(signum, frame):
        state.terminated = True
        for child in multiprocessing.active_children():  # the pool's workers stop with us
            if "Dask" not in child.name:                  # a Dask cluster is closed by its client
                with contextlib.suppress(OSError, AttributeError):
                    child.terminate()
        raise Terminated()

    if threading.current_thread() is not threading.main_thread():
        yield state
        return
    earlier = signal.signal(signal.SIGTERM, handler)
    try:
        yield state
    finally:
        signal.signal(signal.SIGTERM, earlier)


def die_with_parent() -> None:
    """In a worker process: end (SIGTERM, its default action) when the parent ends. Linux:
    ``prctl(PR_SET_PDEATHSIG)``; elsewhere a thread that polls the parent's pid."""
    with contextlib.suppress(ValueError):                # not the parent's Terminated handler
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    parent = os.getppid()
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0) == 0:
            if os.getppid() != parent:                   # it died before prctl took effect
                os.kill(os.getpid(), signal.SIGTERM)
            return
    except (OSError, AttributeError):
        pass
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True, name="navsim-parent-watch").start()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_S)
    os.kill(os.getpid(), signal.SIGTERM)


_DIE_WITH_PARENT = []


def _after_fork_in_child() -> None:
    if _DIE_WITH_PARENT:
        _DIE_WITH_PARENT.clear()
        die_with_parent()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


@contextlib.contextmanager
def children_die_with_parent():
    """While inside: every process forked from this one (the local pool's workers, started with
    ``fork``) calls :func:`die_with_parent` first, so none outlives a killed run."""
    _DIE_WITH_PARENT.append(True)
    try:
        yield
    finally:
        with contextlib.suppress(IndexError):
            _DIE_WITH_PARENT.pop()


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
            return distributed.Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s"), None
        except (OSError, TimeoutError) as exc:
            raise ExecutorError(f"cannot reach the Dask scheduler at {scheduler} within {CONNECT_TIMEOUT_S} s: "
                                f"{exc}") from None
        except Exception as exc:             # garbage read as a message (a 3 EiB frame): not Dask
            raise ExecutorError(f"{scheduler} is not a Dask scheduler (its answer could not be read: "
                                f"{type(exc).__name__}: {exc}); give the address of a running "
                                "dask scheduler (tcp://host:8786)") from None
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


def run_chunks_dask(fn, chunks, truth, truth_path, rest: tuple, options: RunOptions, on_part=None):
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
    options : navsim.experiment.options.RunOptions
        Its ``workers`` (the processes of the ``LocalCluster``, ignored with ``scheduler``),
        ``scheduler`` (the address of a running Dask scheduler, ``tcp://host:8786``; None: a
        ``LocalCluster``) and ``progress`` (called ``progress(runs_finished)``).
    on_part : callable, optional
        ``on_part(part)`` receives each finished chunk as it arrives (otherwise the parts are
        returned).

    Returns
    -------
    tuple
        ``(parts, failed, interrupted)`` as :func:`navsim.experiment.runner.run_chunks`.
    """
    workers, scheduler, progress = options.workers, options.scheduler, options.progress
    parts, failed, interrupted = [], {}, False
    if not chunks:
        return parts, failed, interrupted
    distributed = import_distributed()
    keep = on_part or parts.append
    lent = _LENT.get((workers, scheduler))
    client, cluster = lent if lent is not None else open_client(workers, scheduler)
    try:
        shared = client.scatter(truth, broadcast=True) if scheduler or truth_path is None else str(truth_path)
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
        if lent is None:
            _close(client, cluster)
    return parts, failed, interrupted


def _close(client, cluster) -> None:
    client.close()
    if cluster is not None:
        cluster.close()


#: (workers, scheduler) -> (client, cluster) opened by :func:`lend_client`
_LENT: dict = {}
#: the pool lent by :func:`lend_pool`, per thread (a notebook's threads do not share one):
#: ``lent`` is None outside, else ``[workers, pool]`` (the pool None until the first Monte Carlo)
_THREAD = threading.local()


@contextlib.contextmanager
def lend_pool():
    """While inside, the local executor keeps one pool of worker processes and hands it to every
    Monte Carlo of this thread (:func:`local_pool`), instead of starting one for each and shutting
    it down after: a verb that runs many (a budget's, a sweep's, a tuning's) pays the workers'
    start, their imports and their loading of the compiled kernels once. Nested: the outermost
    lends. A Monte Carlo of another worker count replaces the pool (one pool's idle workers at a
    time)."""
    if getattr(_THREAD, "lent", None) is not None:
        yield
        return
    _THREAD.lent = [0, None]
    try:
        yield
    finally:
        _, pool = _THREAD.lent
        _THREAD.lent = None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


def _new_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of ``workers`` forked processes, each ending with this one (:func:`die_with_parent`
    as its initializer, whoever forks it)."""
    return ProcessPoolExecutor(max_workers=workers, mp_context=POOL_CONTEXT, initializer=die_with_parent)


def _give_up(pool: ProcessPoolExecutor) -> None:
    """Stop ``pool`` as a Ctrl-C stops a Monte Carlo: what is queued cancelled, the running chunks
    waited for and the workers ended (in one call: a first ``shutdown(wait=False)`` would drop
    the executor's thread, and a second could no longer wait), so a lent pool is never left
    computing behind the caller's back."""
    pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def local_pool(workers: int):
    """A ``ProcessPoolExecutor`` of ``workers`` (:data:`POOL_CONTEXT`): the lent one where
    :func:`lend_pool` is open in this thread (a broken one, or one of another size, replaced),
    else one of its own, shut down on leaving. Ctrl-C gives the pool up (:func:`_give_up`)."""
    lent = getattr(_THREAD, "lent", None)
    pool = lent[1] if lent is not None and lent[0] == workers else None
    if pool is None or getattr(pool, "_broken", False):      # set by concurrent.futures when a worker died
        if lent is not None and lent[1] is not None:
            lent[1].shutdown(wait=False, cancel_futures=True)
        pool = _new_pool(workers)
        if lent is not None:
            lent[:] = [workers, pool]
    try:
        yield pool
    except KeyboardInterrupt:
        _give_up(pool)
        if lent is not None and lent[1] is pool:
            lent[:] = [0, None]
        raise
    finally:
        if lent is None:
            pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def lend_client(workers: int, scheduler: str | None):
    """Connect to ``scheduler`` (or start the ``LocalCluster`` of ``workers``) now, and have
    :func:`run_chunks_dask` use that client while inside; closed on leaving. An
    :class:`ExecutorError` when it cannot start, before the caller has touched anything."""
    if (workers, scheduler) in _LENT:
        yield _LENT[(workers, scheduler)][0]
        return
    client, cluster = open_client(workers, scheduler)
    _LENT[(workers, scheduler)] = (client, cluster)
    try:
        yield client
    finally:
        del _LENT[(workers, scheduler)]
        _close(client, cluster)
