"""The executors a tiled run submits its tasks to, all behind the ``concurrent.futures`` interface.

==================  ==========================================================
``scheduler``       executor
==================  ==========================================================
``"serial"``        :class:`SerialExecutor`: in this process, one task at a time
                    (chosen for a run of one tile; the kernels keep their
                    threads)
``"processes"``     :class:`concurrent.futures.ProcessPoolExecutor` (spawned
                    processes: numba's threads do not survive a fork)
``"threads"``       :class:`concurrent.futures.ThreadPoolExecutor`
``"dask"``          a local Dask cluster: ``LocalCluster(n_workers,
                    threads_per_worker=1, processes=True, memory_limit=budget /
                    n_workers, dashboard_address=None)``, its workers without
                    Dask's fixed ``malloc`` trim threshold
``"tcp://h:p"``     an existing Dask scheduler (workers started with ``dask
                    worker``; every worker must see the scratch directory)
a Dask ``Client``   that client's cluster
==================  ==========================================================

Dask is optional (``pip install "heatcurv[dask]"``) and imported only for the
last three. Dask's executor is ``Client.get_executor(pure=False)``; a worker
killed while computing a tile is replaced and the tile retried by Dask itself
(``distributed.scheduler.allowed-failures``, 3 by default). A Dask worker runs
single-threaded kernels (``workers=1`` in the estimator options; the BLAS and
OpenMP thread variables set to 1 in the processes started here); a local worker
process runs its share of the run's cores (:func:`heatcurv.tiles.job.task_threads`:
``threads`` here).

A run keeps its executor across its phases (:class:`Pools`): the survey's worker
processes, or local Dask cluster, compute the tiles too when the two phases ask
for the same workers, instead of each phase starting its own (a spawned
worker's imports and first compiled kernels take about 2-3 s).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
from contextlib import contextmanager

from ..errors import HeatcurvError

__all__ = ["SerialExecutor", "SCHEDULERS", "Pools", "open_executor", "thread_environment"]

#: The scheduler names (besides ``tcp://host:port`` addresses and Dask clients).
SCHEDULERS = ("processes", "threads", "dask", "serial")
#: How long to try reaching a Dask scheduler (``tcp://``) before giving up.
CONNECT_TIMEOUT = "20s"
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


class SerialExecutor(cf.Executor):
    """Runs each task when it is submitted, in this process; returns a finished future."""

    def submit(self, fn, /, *args, **kwargs):
        future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:
            if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                raise
            future.set_exception(exc)
        return future


@contextmanager
def thread_environment(threads: int = 1):
    """Processes started inside the block run ``threads`` BLAS/OpenMP/numba threads (this process is unchanged)."""
    previous = {name: os.environ.get(name) for name in _THREAD_VARIABLES}
    os.environ.update({name: str(int(threads)) for name in _THREAD_VARIABLES})
    try:
        yield
    finally:
        for name, value in previous.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _dask():
    try:
        import distributed
    except ImportError:
        raise HeatcurvError(
            "the dask schedulers need Dask: pip install \"heatcurv[dask]\" (dask[distributed])"
        ) from None
    return distributed


@contextmanager
def _adaptive_malloc():
    """Workers started inside the block keep glibc's adaptive ``malloc`` (Dask's nannies set a fixed trim threshold).

    Dask's default ``distributed.nanny.pre-spawn-environ`` gives each worker
    ``MALLOC_TRIM_THRESHOLD_`` (64 kB) to hand freed memory back to the
    system. Setting it also fixes glibc's mmap threshold, so every large numpy
    temporary of a tile is mapped and faulted in afresh, CPU time a process
    pool's workers do not spend. The memory a tile may hold is budgeted by
    :mod:`heatcurv.tiles.plan`, not by trimming.
    """
    import dask

    key = "distributed.nanny.pre-spawn-environ"
    environ = {name: value for name, value in dask.config.get(key, {}).items() if name != "MALLOC_TRIM_THRESHOLD_"}
    with dask.config.set({key: environ}):
        yield


def dask_slots(client) -> int:
    """Tasks a Dask cluster runs at once: its workers' threads."""
    return max(1, sum(client.nthreads().values()))


@contextmanager
def open_executor(scheduler, workers: int, budget: int, threads: int = 1):
    """Yield ``(executor, slots, name)`` for ``scheduler`` with ``workers`` local workers and ``budget`` bytes.

    ``slots`` is how many tasks run at once (a remote cluster's thread count);
    ``threads`` the threads of each local worker process (``"processes"``).
    The executor, and a cluster started here, are shut down on leaving.
    """
    if not isinstance(scheduler, str):  # a dask Client
        with scheduler.get_executor(pure=False) as executor:
            yield executor, dask_slots(scheduler), "dask client"
        return
    if scheduler == "serial":
        yield SerialExecutor(), 1, "serial"
    elif scheduler == "threads":
        with cf.ThreadPoolExecutor(max_workers=workers) as executor:
            yield executor, workers, "threads"
    elif scheduler == "processes":
        with thread_environment(threads):
            executor = cf.ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
        try:
            yield executor, workers, "processes"
        finally:
            executor.shutdown(wait=True, cancel_futures=True)
    elif scheduler == "dask":
        distributed = _dask()
        with thread_environment(), _adaptive_malloc():
            cluster = distributed.LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, memory_limit=max(1, budget // workers),
                dashboard_address=None,
            )
        try:
            with distributed.Client(cluster) as client, client.get_executor(pure=False) as executor:
                yield executor, workers, "dask"
        finally:
            cluster.close()
    elif scheduler.startswith("tcp://"):
        distributed = _dask()
        try:
            client = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT)
        except OSError as exc:
            raise HeatcurvError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        try:
            with client.get_executor(pure=False) as executor:
                yield executor, dask_slots(client), f"dask at {scheduler}"
        finally:
            client.close()
    else:
        raise HeatcurvError(f"unknown scheduler {scheduler!r}; choose {', '.join(SCHEDULERS)} or tcp://host:port")


class Pools:
    """The executor of a tiled run, kept open from one phase to the next while they ask for the same one.

    :meth:`open` yields what :func:`open_executor` yields; the executor stays
    open after the block, for the next phase, unless that phase asks for
    another (other workers, threads or scheduler) or the block raised (a
    broken pool, killed workers), which closes it. :meth:`close` when no
    phase needs workers any more: idle workers keep their memory.
    """

    def __init__(self):
        self._key = None
        self._opened = None
        self._entry = None

    @contextmanager
    def open(self, scheduler, workers: int, budget: int, threads: int = 1):
        """Yield ``(executor, slots, name)`` as :func:`open_executor` does, reusing the open one if it matches."""
        key = (scheduler if isinstance(scheduler, str) else id(scheduler), int(workers), int(budget), int(threads))
        if key != self._key:
            self.close()
            opened = open_executor(scheduler, workers, budget, threads)
            self._entry = opened.__enter__()
            self._opened, self._key = opened, key
        try:
            yield self._entry
        except BaseException:
            self.close()
            raise

    def start(self, scheduler, workers: int, budget: int, threads: int, warm) -> None:
        """Open the executor a phase will ask for ahead of it, each of its workers running ``warm()`` meanwhile."""
        with self.open(scheduler, workers, budget, threads) as (executor, slots, _):
            for _ in range(slots):
                executor.submit(warm)

    def close(self) -> None:
        """Shut the kept executor down (and a cluster started for it); nothing if none is open."""
        opened, self._opened, self._key, self._entry = self._opened, None, None, None
        if opened is not None:
            opened.__exit__(None, None, None)


def kill_workers(executor) -> None:
    """Stop what an executor runs, at once: Ctrl-C or a failed tile must not wait for the other tiles.

    A process pool's worker processes (those this run started) are terminated;
    a Dask executor's futures are cancelled (its workers stay up).
    """
    client, futures = getattr(executor, "_client", None), getattr(executor, "_futures", None)
    if client is not None and futures:
        try:
            client.cancel(list(futures))
        except Exception:  # a client already closing: nothing left to cancel
            pass
    processes = getattr(executor, "_processes", None) or {}
    for process in list(processes.values()):
        try:
            process.terminate()
        except (OSError, AttributeError):
            pass
