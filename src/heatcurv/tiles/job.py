"""What every phase of a tiled run shares: the job it was asked, how a phase runs its tiles, the one loop.

:class:`Job` is the run's arguments, checked before the first pass over the input
(:func:`heatcurv.tiles.driver.compute_file`); :func:`phase` chooses a phase's
workers and executor within the budget; :func:`submit` runs a phase's tasks on
any executor (:mod:`.executors`), restarting a broken process pool.
"""

from __future__ import annotations

import concurrent.futures as cf
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from ..errors import HeatcurvError
from .executors import SerialExecutor, kill_workers
from .plan import (
    BYTES_PER_POINT,
    DRIVER_MEMORY,
    PhaseWorkers,
    TilePlan,
    budget_refusal,
    halo_points,
    phase_workers,
    plan_workers,
)

__all__ = ["Job", "Phase", "phase", "submit", "task_threads", "warm_workers", "version", "RETRIES"]

#: Times a tile is resubmitted after its worker process died.
RETRIES = 2


@dataclass(frozen=True)
class Job:
    """What a tiled run is asked for, checked before the first pass (:func:`heatcurv.tiles.driver.compute_file`)."""

    src: Path
    dst: Path
    source: object  # .sources.Source
    work: Path  # the scratch directory
    root: Path  # the directory that holds it
    options: dict  # the estimator keywords (estimator_options)
    threads: int  # threads of a tile computed in this process
    budget: int
    requested: int  # tiles asked to run at once
    cpus: int
    scheduler: object  # a name or a Dask client
    in_process: bool  # a tile may run in this process when no worker fits
    pools: object  # .executors.Pools: the executor the phases share
    fields: tuple
    dtype: str
    progress: bool
    say: object  # callable


@dataclass(frozen=True)
class Phase:
    """How a parallel phase submits its tiles (:func:`phase`)."""

    executor: object  # executor(workers), for submit
    workers: int
    options: dict  # the tasks' estimator options


def phase(run: Job, plan: TilePlan, halo, name: str) -> Phase:
    """The workers, executor and task options of a phase whose tiles read ``halo`` (one, or one per tile).

    A run of one tile, or a phase whose tile fits only in this process, runs serially here with the run's threads.
    """
    n_tiles = len(plan.tiling.counts)
    fit = _phase_workers(plan.tiling, plan.stats, halo, run.budget, run.requested, run.cpus, plan.tile_size, name,
                         run.in_process)
    serial = fit.in_process or (n_tiles == 1 and isinstance(run.scheduler, str))
    workers = max(1, min(n_tiles, fit.count))
    if serial or n_tiles == 1 or run.scheduler == "serial":
        threads = run.threads  # the tiles run in this process
    elif isinstance(run.scheduler, str) and run.scheduler == "processes":
        threads = task_threads(run.threads, run.cpus, workers)
    else:  # a Dask worker's threads are its own; a thread pool's tasks share this process
        threads = 1
    executor = partial(run.pools.open, "serial" if serial else run.scheduler, budget=max(run.budget - DRIVER_MEMORY, 1),
                       threads=threads)
    return Phase(executor, workers, dict(run.options, workers=threads))


def warm_workers(run: Job, points: int, tile_size: int, warm) -> None:
    """Start the worker processes the survey will likely ask for while the driver still plans.

    A spawned worker imports heatcurv before its first task (about a second);
    started here, it does so while the driver reads and tiles the cloud
    instead of at the survey's start. Local process pools only, and a cloud of
    more than one tile: a survey that asks for other workers (the budget with
    the survey's halo, fewer tiles) closes these (:class:`.executors.Pools`).
    ``warm``: a function the workers run (:func:`.tasks.warm_up`).
    """
    if run.scheduler != "processes" or points <= tile_size:
        return
    workers = min(-(-points // tile_size), plan_workers(max(run.budget - DRIVER_MEMORY, 0), run.requested,
                                                         tile_size, run.cpus))
    if workers >= 1:
        run.pools.start(run.scheduler, workers, max(run.budget - DRIVER_MEMORY, 1),
                        task_threads(run.threads, run.cpus, workers), warm)


def task_threads(threads: int, cpus: int, workers: int) -> int:
    """The threads of each of ``workers`` local worker processes: the run's ``threads`` (-1: the ``cpus``) shared.

    A budget that holds fewer workers than there are cores leaves the others to the workers' own threads
    (the k-d tree's queries and the compiled kernels) instead of idle.
    """
    return max(1, (cpus if threads == -1 else threads) // workers)


def _phase_workers(tiling, stats, halo, budget: int, requested: int, cpus: int, tile_size: int, phase: str,
                   in_process: bool) -> PhaseWorkers:
    """How a phase runs its tiles with this halo (one, or one per tile) within the budget; an error if no tile fits.

    The error names the budget the largest tile needs and a smaller ``--tile-size`` (this tiling is the plan's:
    a resumed run keeps it).
    """
    points = halo_points(tiling, stats, halo)
    fit = phase_workers(points, budget, requested, cpus, in_process)
    if fit is None:
        raise budget_refusal(int(points.max()), budget, tile_size, phase, True, in_process)
    return fit


def submit(executor, workers: int, fn, specs: dict, on_done, say, what: str, total: int) -> str:
    """Run ``fn(spec)`` for every spec, at most ``2 x slots`` in flight; ``on_done(key, result)`` in this process.

    A worker process that dies breaks the pool: a new pool takes the unfinished
    specs, at most :data:`RETRIES` times for a spec that was running. Any other
    exception ends the run with one message naming the tile.
    """
    pending = dict(specs)
    attempts = dict.fromkeys(specs, 0)
    name = "serial"
    while pending:
        inflight, current = {}, None
        try:
            with executor(workers) as (ex, slots, name):
                queue = list(pending)
                limit = 1 if isinstance(ex, SerialExecutor) else 2 * slots  # a serial submit runs the task
                try:
                    while queue or inflight:
                        while queue and len(inflight) < limit:
                            key = queue.pop(0)
                            inflight[ex.submit(fn, pending[key])] = key
                        done, _ = cf.wait(list(inflight), return_when=cf.FIRST_COMPLETED)
                        for future in done:
                            key = current = inflight.pop(future)
                            result = future.result()
                            on_done(key, result)
                            del pending[key]
                except BrokenProcessPool:
                    raise
                except BaseException as exc:
                    kill_workers(ex)
                    if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                        raise
                    where = f"{what} {current} of {total}" if current is not None else what
                    message = str(exc) if isinstance(exc, HeatcurvError) else f"{type(exc).__name__}: {exc}"
                    raise HeatcurvError(f"{where} failed: {message}") from exc
        except BrokenProcessPool:
            running = list(inflight.values()) + ([current] if current is not None and current in pending else [])
            for key in running:
                attempts[key] += 1
            worst = max(running, key=lambda k: attempts[k], default=None)
            if worst is not None and attempts[worst] > RETRIES:
                raise HeatcurvError(
                    f"{what} {worst}: a worker process died computing it {attempts[worst]} times (out of memory? "
                    f"estimated {BYTES_PER_POINT} bytes per point); pass a smaller --tile-size or --max-memory. "
                    "From a Python script: workers are spawned, so the script must call compute_file under "
                    "`if __name__ == '__main__':` (else every worker dies at start)"
                ) from None
            say(f"a worker process died; restarting the pool for {len(pending)} unfinished {what}(s)")
    return name


def version() -> str:
    from .. import __version__

    return __version__
