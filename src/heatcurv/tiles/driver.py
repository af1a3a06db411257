"""The driver of a tiled run: plan, survey, compute the tiles, orient, write, one module per phase.

:func:`compute_file` checks its arguments (:func:`_settle`, a :class:`.job.Job`),
finds a plan to resume (:func:`.phase_plan.find_plan`) and runs these phases in
order, each timed in the report; they share :mod:`.job` (the workers of a phase,
one loop for every executor):

1. ``stats``, ``tiling``, ``scatter`` (:mod:`.phase_plan`): three streaming passes,
   the tiles fitted to the budget, a frozen :class:`.plan.TilePlan`.
2. ``survey`` (:mod:`.phase_survey`): the cloud-wide kernel choice, in one or two
   rounds, merged into the context every tile gets.
3. ``tiles`` (:mod:`.phase_tiles`): every tile not done yet, its rows appended to
   bucket files as it finishes, merged into ``results.rec`` at the end.
4. ``reliability`` (:func:`.phase_tiles.cloud_flags`): the flags against the whole cloud's medians.
5. ``orientation`` (:mod:`.phase_orient`): for ``outward``, the seams' flips, then
   a closed cloud's inside and outside by the winding number, and the second sheets
   the tiles could not settle (:mod:`.sheets`).
6. ``write`` (:mod:`.phase_write`): the output in input order, atomically (:mod:`.output`).

Scratch and resume
------------------
Scratch files live in ``<scratch>/.<output name>.heatcurv-tiles/``
(``scratch`` defaults to the output's directory): ``plan.json`` (the
:class:`.plan.TilePlan`: source identity, options hash, tiling, statistics,
halos), ``context.json`` (the survey's
:class:`.context.SurveyContext`), ``points.f8``,
``rows.i8``, ``knn/knn_NNNNN.npy`` (the survey's neighbour lists, :mod:`.neighbours`),
``buckets/bucket_NNNNNNN.rec`` (the finished tiles' rows by input row, :func:`.output.store_tile`),
``results.rec`` and ``tiles/tile_NNNNN.npz`` (one per finished
tile: its done marker; once its rows are in the buckets it keeps
only the seam vote's, the second sheets' and the winding step's inputs, :data:`.output.STORED_KEYS`
and :data:`.output.SOURCE_KEYS`). A run whose scratch
directory holds a plan with the same source file (path, size, modification
time), options and tile size resumes: finished tiles are not recomputed
(``resume=None``, the default; ``True`` requires such a plan, ``False`` starts
afresh); if ``results.rec`` is gone, the tiles stored in it are computed again.
A successful run removes its scratch directory. A failed run or Ctrl-C removes
the temporary files; if tiles were finished, it keeps them, the buckets, ``results.rec``
and the plan for a resume (the message says where), otherwise it removes the
directory.

Faults
------
An exception in a tile fails the run with one :class:`~heatcurv.errors.HeatcurvError`
naming the tile; no output file is written. A worker process that dies (out
of memory, killed) breaks a process pool: the pool is restarted and the
unfinished tiles resubmitted, at most :data:`.job.RETRIES` times per tile. Dask
replaces dead workers and retries their tasks itself.
"""

from __future__ import annotations

import os
import resource
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import HeatcurvError
from . import compute
from .context import SurveyContext
from .executors import SCHEDULERS, Pools
from .job import Job
from .output import DEFAULT_FIELDS, ERROR_FIELDS, TILED_FIELDS, TILED_WRITE
from .phase_orient import orient_cloud
from .phase_plan import find_plan, identity_of, make_plan
from .phase_survey import survey
from .phase_tiles import TileStore, cloud_flags, compute_tiles
from .phase_write import write
from .plan import TilePlan, check_smallest_budget, default_budget, parse_size
from .sources import TILED_READ, open_source

__all__ = ["compute_file", "TiledReport", "estimator_options"]

@dataclass
class TiledReport:
    """What a tiled run did (returned by :func:`compute_file`).

    Attributes
    ----------
    source, output : str
        The files read and written.
    points : int
        Rows of the input (and of the output).
    computed : int
        Points computed (the finite ones).
    tiles : int
        Tiles.
    tile_size : int
        Largest number of core points a tile was to hold.
    halo : float
        Halo width from the survey, length units (``widened`` tiles used more).
    widened : int
        Tiles whose certificate failed and which were computed again with a wider halo.
    resumed : int
        Tiles found finished in the scratch directory and not recomputed.
    scheduler : str
        The executor used.
    workers : int
        Tiles computed at once.
    budget : int
        The memory budget, bytes.
    peak_memory : dict
        ``driver`` (this process's peak resident memory), ``worker`` (the largest
        peak of a worker process), ``estimate`` (``driver + workers x worker``), bytes.
    timings : dict
        Seconds per phase: ``stats tiling scatter survey tiles orientation write``.
    context : dict
        The global choices every tile got, in plain numbers (:func:`.compute.describe`).
    orientation : dict or None
        The seam orientation's report (``outward`` only, :func:`.orient.seam_flips`),
        with the winding step's: ``closed``, ``undecided``, ``open_components`` (of which
        ``upward_components`` face ``+z``, ``orient="auto"``), ``agreement``,
        ``outside_share`` and, for a closed or undecided cloud, ``turned``, ``unsupported`` and ``escaped``
        (:func:`.winding.flag_unsupported`); ``second_sheet``: the points the driver found holding both sides
        of a thin part (:func:`.sheets.flag_second_sheets`; those a tile settled alone are not counted).
    parameters : dict
        Everything written into the output's VLR / PLY comment.
    scratch : str
        The scratch directory (removed after a successful run unless kept).
    tile_seconds : list of float
        The compute time in its worker of each tile this run computed (not the
        resumed ones), in tile order.
    tile_points : list of tuple of int
        The ``(core, halo)`` points of the same tiles.
    """

    source: str
    output: str
    points: int
    computed: int
    tiles: int
    tile_size: int
    halo: float
    widened: int
    resumed: int
    scheduler: str
    workers: int
    budget: int
    peak_memory: dict
    timings: dict
    context: dict
    orientation: dict | None
    parameters: dict
    scratch: str
    tile_seconds: list = field(default_factory=list)
    tile_points: list = field(default_factory=list)


def estimator_options(method: str, viewpoint, options: dict, source_kind: str) -> dict:
    """The estimator keywords every tile gets, validated; ``orient="auto"`` on LAS/LAZ is ``"up"`` (as the CLI)."""
    from ..options import resolve_options

    resolve_options(method, **options)  # bad values fail before any pass over the file
    out = dict(options, method=method)
    if viewpoint is not None:
        v = np.asarray(viewpoint, dtype=float)
        if v.shape != (3,) or not np.isfinite(v).all():
            raise HeatcurvError(f"a tiled run takes one viewpoint (x, y, z), got an array of shape {v.shape}")
        out["viewpoint"] = v.tolist()
    if out.get("orient") in (None, "auto") and viewpoint is None and source_kind == "las":
        out["orient"] = "up"
    return out


def compute_file(
    src, dst, *, method: str = "default", viewpoint=None, max_memory=None, tile_size=None, tile_workers=None,
    scheduler="processes", scratch=None, resume=None, fields=None, dtype=None, skip_nonfinite: bool = False,
    keep_scratch: bool = False, progress=None, log=None, **options,
) -> TiledReport:
    """Every curvature field of a point-cloud file of any size, computed in tiles, written in input order.

    Parameters
    ----------
    src : str or os.PathLike
        ``.las``, ``.laz``, binary ``.ply`` or ``.npy`` (streamed, never read whole).
    dst : str or os.PathLike
        ``.las``, ``.laz`` or ``.ply`` (:mod:`heatcurv.tiles.output`), written atomically.
    method, viewpoint, **options
        As :func:`heatcurv.estimate` (one viewpoint, shape (3,)); ``workers``
        is the threads of a tile computed in this process (serial runs).
        ``orient`` defaults to ``"up"`` for LAS/LAZ, as on the command line.
    max_memory : int or str, optional
        Budget of the whole run, all workers together (``"3G"``, ``"500M"``,
        bytes); default 60 % of the memory available, at least a small cloud's
        need (:func:`.plan.default_budget`). The plan fits it with fewer workers,
        then one tile at a time in this process, then smaller tiles
        (:mod:`.plan`, "Fitting the budget").
    tile_size : int, optional
        Core points per tile (default: what the budget holds, at most 2M;
        made smaller if the survey's tiles do not fit; a given size is kept).
    tile_workers : int, optional
        Tiles computed at once (-1 or None: every core, as many as the budget holds).
    scheduler : str or dask.distributed.Client, optional
        ``"processes"`` (default), ``"threads"``, ``"dask"`` (a local Dask
        cluster), ``"serial"``, ``"tcp://host:port"`` (a Dask scheduler) or a
        Dask ``Client`` (:mod:`heatcurv.tiles.executors`). A run of one tile
        runs in this process.
    scratch : str or os.PathLike, optional
        Directory for the scratch files (default: the output's directory).
    resume : bool or None, optional
        None: resume when the scratch directory holds a matching plan; True:
        require one; False: start afresh.
    fields : iterable of str, optional
        Fields to write (:data:`heatcurv.tiles.output.TILED_FIELDS`); default
        those of ``heatcurv compute``.
    dtype : {None, "float32", "float64"}, optional
        Type of the written float fields (default float32).
    skip_nonfinite : bool, optional
        Rows with NaN/inf coordinates get NaN (else they are an error).
    keep_scratch : bool, optional
        Keep the scratch directory after a successful run.
    progress : bool or None, optional
        A progress bar on stderr (None: when stderr is a terminal).
    log : callable, optional
        Called with one-line messages about the run.

    Returns
    -------
    TiledReport

    Raises
    ------
    HeatcurvError
        On bad options or input, too little memory or disk, a failed tile.
    """
    tic = time.perf_counter()
    run = _settle(src, dst, method, viewpoint, max_memory, tile_workers, scheduler, scratch, fields, dtype, progress,
                  log, options)
    identity = identity_of(run, tile_size, skip_nonfinite)
    plan = find_plan(run, identity, tile_size, resume)
    store = TileStore(run)
    timings = dict.fromkeys(("stats", "tiling", "scatter", "survey", "tiles", "orientation", "write"), 0.0)
    try:
        if plan is None:
            plan = make_plan(run, identity, tile_size, skip_nonfinite, timings, store.bar)
        context = survey(run, plan, timings, store.bar)
        name, workers, resumed = compute_tiles(run, plan, context, store, timings)
        run.pools.close()  # the last phase with workers: theirs is memory the phases left need
        medians = cloud_flags(run, plan, context, timings)
        flips, orientation = orient_cloud(run, plan, context, timings, store.bar)
        parameters = write(run, plan, context, medians, flips, timings, store.bar)
    except BaseException as exc:
        run.pools.close()
        store.abandon()
        if isinstance(exc, (HeatcurvError, KeyboardInterrupt, SystemExit)):
            raise
        raise HeatcurvError(f"tiled run of {run.src} failed: {type(exc).__name__}: {exc}") from exc
    store.bar.close()
    if not keep_scratch:
        shutil.rmtree(run.work, ignore_errors=True)
    timings["total"] = time.perf_counter() - tic
    return _report(run, plan, context, store, timings, name, workers, resumed, orientation, parameters)


def _settle(src, dst, method, viewpoint, max_memory, tile_workers, scheduler, scratch, fields, dtype, progress, log,
            options) -> Job:
    """Check the arguments (before any pass over the input) and settle the budget, the workers and the scratch."""
    from ..io.atomic import check_writable

    src, dst = Path(src), Path(dst)
    if dst.suffix.lower() not in TILED_WRITE:
        raise HeatcurvError(f"cannot write {dst}: a tiled run writes {' '.join(TILED_WRITE)}")
    if src.suffix.lower() not in TILED_READ:
        open_source(src)  # the message that says what to convert it to
    check_writable(dst)
    if dst.exists() and src.exists() and os.path.samefile(src, dst):
        raise HeatcurvError(f"cannot write {dst}: it is the input file")
    wanted = tuple(fields) if fields is not None else DEFAULT_FIELDS
    unknown = [n for n in wanted if n not in TILED_FIELDS]
    if unknown:
        raise HeatcurvError(f"a tiled run cannot write the field(s) {', '.join(unknown)} (sharp features are "
                            f"computed in memory only); choose from {', '.join(TILED_FIELDS)}")
    if dtype not in (None, "float32", "float64"):
        raise HeatcurvError(f"dtype must be float32 or float64, got {dtype!r}")
    if isinstance(scheduler, str) and scheduler not in SCHEDULERS and not scheduler.startswith("tcp://"):
        raise HeatcurvError(f"unknown scheduler {scheduler!r}; choose {', '.join(SCHEDULERS)} or tcp://host:port")
    source = open_source(src)
    budget = parse_size(max_memory) if max_memory is not None else default_budget(source.count)
    check_smallest_budget(budget)  # not even the smallest tile fits: say so before reading anything
    options = dict(options)
    threads = options.pop("workers", -1)
    # the standard errors widen every tile's halo: computed only when written
    options.setdefault("se", any(name in ERROR_FIELDS for name in wanted))
    est = estimator_options(method, viewpoint, options, source.kind)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    requested = cpus if tile_workers in (None, -1) else int(tile_workers)
    if requested < 1:
        raise HeatcurvError(f"tile_workers must be -1 or at least 1, got {tile_workers}")
    root = Path(scratch) if scratch is not None else dst.parent
    if not root.is_dir():
        raise HeatcurvError(f"the scratch directory {root} does not exist")
    return Job(
        src=src, dst=dst, source=source, work=root / f".{dst.name}.heatcurv-tiles", root=root, options=est,
        threads=threads, budget=budget, requested=requested, cpus=cpus, scheduler=scheduler,
        # a Dask cluster's workers are its own: only a local scheduler falls back to this process
        in_process=isinstance(scheduler, str) and scheduler in ("processes", "threads", "serial"),
        pools=Pools(), fields=wanted, dtype=dtype or "float32",
        progress=sys.stderr.isatty() if progress is None else bool(progress), say=log or _quiet,
    )


def _quiet(text: str) -> None:
    """The log of a run nobody listens to."""


def _report(run: Job, plan: TilePlan, context: SurveyContext, store: TileStore, timings: dict, name: str,
            workers: int, resumed: int, orientation, parameters: dict) -> TiledReport:
    results = store.results
    worker_peak = max([r["peak"] for r in results.values()], default=0)
    driver_peak = _peak()
    stats, n_tiles = plan.stats, len(plan.tiling.counts)
    run.say(f"computed {stats.finite} points in {n_tiles} tiles ({name}, {workers} at once) in "
            f"{timings['total']:.1f} s; wrote {run.dst}")
    return TiledReport(
        source=str(run.src), output=str(run.dst), points=stats.count, computed=stats.finite, tiles=n_tiles,
        tile_size=plan.tile_size, halo=float(context.halo), widened=sum(1 for r in results.values() if r["widened"]),
        resumed=resumed, scheduler=name, workers=workers, budget=run.budget,
        peak_memory={"driver": driver_peak, "worker": worker_peak, "estimate": driver_peak + workers * worker_peak},
        timings=timings, context=compute.describe(context, run.options), orientation=orientation, parameters=parameters,
        scratch=str(run.work), tile_seconds=[results[t]["seconds"] for t in sorted(results)],
        tile_points=[(results[t]["points"], results[t]["halo_points"]) for t in sorted(results)],
    )


def _peak() -> int:
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024
