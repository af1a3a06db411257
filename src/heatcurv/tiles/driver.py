"""The driver of a tiled run: plan, survey, compute the tiles, orient, write. One loop for every executor.

:func:`compute_file` checks its arguments (:func:`_settle`), finds a plan to
resume (:func:`_find_plan`) and runs these phases, one function each (each
timed in the report):

1. ``stats``, ``tiling``, ``scatter`` (:func:`_make_plan`): three streaming passes
   over the input (:mod:`.plan`): statistics, the tiles, the points in tile order
   in scratch; tiled again at smaller sizes while the survey's tiles do not fit
   the budget (:func:`.plan.fit_tiles`). The result is a frozen :class:`.plan.TilePlan`.
2. ``survey`` (:func:`_survey`): one round (:func:`.tasks.run_survey`) for at most
   :data:`ONE_ROUND_TILES` tiles, else two rounds (:mod:`heatcurv.choice.survey`): :func:`.tasks.run_keys`
   on every tile (its core's sampling keys over a thin halo), joined into the
   cloud's sample centres; :func:`.tasks.run_centres` on the tiles holding
   some (the candidates' fits at those centres only, over the points within
   their reach); merged by :func:`.compute.merge_rounds` into the context every
   tile gets (the halo). The survey's halo (decided in the plan, which budgets
   the survey's workers with it) bounds both rounds.
3. ``tiles`` (:func:`_compute_tiles`): :func:`.tasks.run_tile` on every tile not done yet, at most
   ``2 x slots`` in flight; each finished tile is copied into the
   index-addressed ``results.rec``, and every :data:`SLIM_POINTS` core points
   ``results.rec`` is fsynced and the stored tiles' files slimmed
   (:func:`.output.slim_tiles`).
4. ``reliability`` (:func:`_cloud_flags`): the flags against the whole cloud's medians.
5. ``orientation`` (:func:`_orient`): for ``outward``, the flip bits of the seams (:mod:`.orient`),
   then a closed cloud's inside and outside by the winding number over every
   tile's sources (:mod:`.winding`: more flips, and flags).
6. ``write`` (:func:`_write`): the output in input order, atomically (:mod:`.output`).

Scratch and resume
------------------
Scratch files live in ``<scratch>/.<output name>.heatcurv-tiles/``
(``scratch`` defaults to the output's directory): ``plan.json`` (the
:class:`.plan.TilePlan`: source identity, options hash, tiling, statistics,
halos), ``context.json`` (the survey's
:class:`.context.SurveyContext`), ``points.f8``,
``rows.i8``, ``results.rec`` and ``tiles/tile_NNNNN.npz`` (one per finished
tile: its done marker; once its rows are copied into ``results.rec`` it keeps
only the seam vote's and the winding step's inputs, :data:`.output.STORED_KEYS`
and :data:`.output.SOURCE_KEYS`). A run whose scratch
directory holds a plan with the same source file (path, size, modification
time), options and tile size resumes: finished tiles are not recomputed
(``resume=None``, the default; ``True`` requires such a plan, ``False`` starts
afresh); if ``results.rec`` is gone, the tiles stored in it are computed again.
A successful run removes its scratch directory. A failed run or Ctrl-C removes
the temporary files; if tiles were finished, it keeps them, ``results.rec``
and the plan for a resume (the message says where), otherwise it removes the
directory.

Faults
------
An exception in a tile fails the run with one :class:`~heatcurv.errors.HeatcurvError`
naming the tile; no output file is written. A worker process that dies (out
of memory, killed) breaks a process pool: the pool is restarted and the
unfinished tiles resubmitted, at most :data:`RETRIES` times per tile. Dask
replaces dead workers and retries their tasks itself.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
import resource
import shutil
import sys
import time
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from ..choice.survey import FitsNotSurveyed
from ..errors import HeatcurvError
from . import compute
from .context import SurveyContext, read_context, write_context
from .executors import SCHEDULERS, SerialExecutor, kill_workers, open_executor
from .medians import apply_cloud_flags
from .output import (
    DEFAULT_FIELDS,
    RECORD,
    TILED_FIELDS,
    TILED_WRITE,
    create_results,
    is_stored,
    slim_tiles,
    store_tile,
    write_output,
)
from .plan import (
    BYTES_PER_POINT,
    DRIVER_MEMORY,
    CloudStats,
    PhaseWorkers,
    TilePlan,
    Tiling,
    budget_refusal,
    check_disk,
    check_smallest_budget,
    default_budget,
    default_tile_size,
    distinct_frame,
    fit_tiles,
    halo_points,
    make_tiling,
    options_hash,
    parse_size,
    phase_workers,
    plan_workers,
    read_rows,
    scan_stats,
    scatter,
    size_text,
)
from .progressbar import TileProgress
from .sources import TILED_READ, open_source
from .tasks import load_plan, run_centres, run_keys, run_survey, run_tile, tile_path

__all__ = ["compute_file", "TiledReport", "RETRIES", "DRIVER_MEMORY", "estimator_options"]

#: Times a tile is resubmitted after its worker process died.
RETRIES = 2
#: A cloud of at most this many tiles is surveyed in one round (:func:`.tasks.run_survey`), others in two
#: (:func:`.tasks.run_keys`, :func:`.tasks.run_centres`); both choose the same kernel bit for bit. Round 2's
#: cost falls with the centres per tile (2000 / tiles) and round 1 costs about 0.3 of one round, so two rounds
#: pay from about 64 tiles (31 centres a tile), an estimate (docs/how_it_works.md, thresholds).
ONE_ROUND_TILES = 63
#: Core points of stored tiles after which :func:`.output.slim_tiles` fsyncs ``results.rec`` and slims their
#: files (about 350 MB of rows): the scratch stays near one copy of the results, the loop rarely waits.
SLIM_POINTS = 2_000_000
#: Plan file version: a plan of another version is never resumed.
PLAN_VERSION = 9


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
        with the winding step's: ``closed``, ``undecided``, ``agreement``, ``outside_share`` and, for a
        closed or undecided cloud, ``turned`` and ``unsupported`` (:func:`.winding.flag_unsupported`).
    parameters : dict
        Everything written into the output's VLR / PLY comment.
    scratch : str
        The scratch directory (removed after a successful run unless kept).
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


def _write_json(path, data) -> None:
    import json

    temporary = f"{path}.{os.getpid()}.tmp"
    with open(temporary, "w") as stream:
        json.dump(data, stream, default=repr)
    os.replace(temporary, path)


def _identity(src: Path) -> dict:
    stat = src.stat()
    return {"path": str(src.resolve()), "size": stat.st_size, "mtime_ns": stat.st_mtime_ns}


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


def _tile_cloud(source, stats: CloudStats, work: Path, options: dict, timings: dict, bar, tile_size: int):
    """Tile the cloud (a histogram pass, a scatter pass into ``work``) and measure each tile's survey halo.

    Returns
    -------
    largest : int
        Core + survey-halo points of the largest tile (:func:`.plan.halo_points`).
    tiled : tuple
        ``(tiling, stats, survey_halos, key_halos)``, ``stats`` with the distinct points' frame.
    """
    bar.stage("tiling")
    tic = time.perf_counter()
    tiling = make_tiling(source, stats, int(tile_size))
    timings["tiling"] += time.perf_counter() - tic
    bar.stage("scattering")
    tic = time.perf_counter()
    scatter(source, tiling, work)
    stats = distinct_frame(work, tiling, stats)  # the keys' frame counts duplicates once, as in memory
    timings["scatter"] += time.perf_counter() - tic
    # the survey reads each tile with a halo as wide as the widest candidate's ball: decided here, so that
    # the survey's workers are budgeted with it, and the tiles made smaller if not one fits
    tic = time.perf_counter()
    survey_halos, key_halos = _survey_halos(work, tiling, stats, options)
    timings["survey"] += time.perf_counter() - tic  # the survey's first step, done here
    largest = int(halo_points(tiling, stats, survey_halos).max())
    return largest, (tiling, stats, survey_halos, key_halos)


def _survey_halos(work: Path, tiling: Tiling, stats: CloudStats, options: dict) -> tuple[list, list]:
    """Each tile's survey halo and keys' halo (:func:`.compute.survey_halo`, :func:`.compute.key_halo` of its
    core), read tile by tile from the scratch."""
    offsets = tiling.offsets
    survey, keys = [], []
    for t in range(len(tiling.counts)):
        core, _ = read_rows(work, int(offsets[t]), int(offsets[t + 1]))
        r0 = compute._core_ball(core, options)
        survey.append(float(compute.survey_halo(core, stats, options, r0)))
        keys.append(float(compute.key_halo(core, options, r0)))
    return survey, keys


def _cleanup(work: Path, keep_done: bool) -> str:
    """Remove temporaries (and everything unless finished tiles are kept); say what is left."""
    tiles = work / "tiles"
    done = sorted(tiles.glob("tile_*.npz")) if tiles.exists() else []
    for stray in (tiles.glob("*.tmp.npz") if tiles.exists() else []):
        stray.unlink(missing_ok=True)
    if keep_done and done:  # results.rec holds the rows of the tiles already stored
        return f"{len(done)} finished tile(s) are kept in {work}: run the same command again to resume, or delete it"
    shutil.rmtree(work, ignore_errors=True)
    return ""


def _peak() -> int:
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


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
    identity = _identity_of(run, tile_size, skip_nonfinite)
    plan = _find_plan(run, identity, tile_size, resume)
    store = _TileStore(run)
    timings = dict.fromkeys(("stats", "tiling", "scatter", "survey", "tiles", "orientation", "write"), 0.0)
    try:
        if plan is None:
            plan = _make_plan(run, identity, tile_size, skip_nonfinite, timings, store.bar)
        context = _survey(run, plan, timings, store.bar)
        name, workers, resumed = _compute_tiles(run, plan, context, store, timings)
        medians = _cloud_flags(run, plan, timings)
        flips, orientation = _orient(run, plan, context, timings, store.bar)
        parameters = _write(run, plan, context, medians, flips, timings, store.bar)
    except BaseException as exc:
        store.abandon()
        if isinstance(exc, (HeatcurvError, KeyboardInterrupt, SystemExit)):
            raise
        raise HeatcurvError(f"tiled run of {run.src} failed: {type(exc).__name__}: {exc}") from exc
    store.bar.close()
    if not keep_scratch:
        shutil.rmtree(run.work, ignore_errors=True)
    timings["total"] = time.perf_counter() - tic
    return _report(run, plan, context, store, timings, name, workers, resumed, orientation, parameters)


@dataclass(frozen=True)
class _Run:
    """What a tiled run is asked for, checked before the first pass (:func:`_settle`)."""

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
    fields: tuple
    dtype: str
    progress: bool
    say: object  # callable


def _settle(src, dst, method, viewpoint, max_memory, tile_workers, scheduler, scratch, fields, dtype, progress, log,
            options) -> _Run:
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
    est = estimator_options(method, viewpoint, options, source.kind)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    requested = cpus if tile_workers in (None, -1) else int(tile_workers)
    if requested < 1:
        raise HeatcurvError(f"tile_workers must be -1 or at least 1, got {tile_workers}")
    root = Path(scratch) if scratch is not None else dst.parent
    if not root.is_dir():
        raise HeatcurvError(f"the scratch directory {root} does not exist")
    return _Run(
        src=src, dst=dst, source=source, work=root / f".{dst.name}.heatcurv-tiles", root=root, options=est,
        threads=threads, budget=budget, requested=requested, cpus=cpus, scheduler=scheduler,
        # a Dask cluster's workers are its own: only a local scheduler falls back to this process
        in_process=isinstance(scheduler, str) and scheduler in ("processes", "threads", "serial"),
        fields=wanted, dtype=dtype or "float32",
        progress=sys.stderr.isatty() if progress is None else bool(progress), say=log or _quiet,
    )


def _quiet(text: str) -> None:
    """The log of a run nobody listens to."""


def _identity_of(run: _Run, tile_size, skip_nonfinite: bool) -> dict:
    """What a plan must match to be resumed: the plan's version, heatcurv's, the source file, the options."""
    identity = {"version": PLAN_VERSION, "heatcurv": _version(), "source": _identity(run.src),
                "options": options_hash(run.options), "skip_nonfinite": bool(skip_nonfinite)}
    if tile_size is not None:
        identity["tile_size"] = int(tile_size)
    return identity


def _find_plan(run: _Run, identity: dict, tile_size, resume) -> TilePlan | None:
    """The scratch directory's plan if it matches (a resume), else None with the directory emptied."""
    plan = None
    if (run.work / "plan.json").exists() and resume is not False:
        old = load_plan(run.work)
        if old.get("identity") == identity or (
            tile_size is None and {k: v for k, v in old.get("identity", {}).items() if k != "tile_size"} == identity
        ):
            plan = TilePlan.from_json(old)
    if resume and plan is None:
        raise HeatcurvError(f"nothing to resume: {run.work} holds no plan of this input with these options")
    if plan is None and run.work.exists():
        shutil.rmtree(run.work)
    run.work.mkdir(exist_ok=True)
    (run.work / "tiles").mkdir(exist_ok=True)
    return plan


def _make_plan(run: _Run, identity: dict, tile_size, skip_nonfinite: bool, timings: dict, bar) -> TilePlan:
    """The plan phase: statistics, the disk check, the tiles that fit the budget (:func:`.plan.fit_tiles`)."""
    bar.stage("statistics")
    tic = time.perf_counter()
    stats = scan_stats(run.source, skip_nonfinite)
    timings["stats"] = time.perf_counter() - tic
    given = tile_size is not None
    if tile_size is None:
        room = max(run.budget - DRIVER_MEMORY, 0)
        tile_size = default_tile_size(room, run.requested)
        if run.in_process and plan_workers(room, run.requested, 2 * tile_size, run.cpus) < 1:
            # no worker process holds a tile and its halo: one tile at a time in this process
            tile_size = default_tile_size(room, 1, in_process=True)
    # points.f8 + rows.i8 with the halos' copies (~1.25x), results.rec, the slimmed tile files (their
    # halo rows, normals and patches) and the few full ones in flight
    need = stats.finite * (48 + RECORD.itemsize + 48)
    check_disk(run.work, need, f"the scratch files of {stats.finite} points")
    if os.stat(run.work).st_dev == os.stat(run.dst.parent).st_dev:
        need += stats.count * 100
    check_disk(run.dst.parent, need if run.dst.parent == run.root else stats.count * 100, f"the output {run.dst.name}")
    measure = partial(_tile_cloud, run.source, stats, run.work, run.options, timings, bar)
    tile_size, (tiling, stats, survey_halos, key_halos), _ = fit_tiles(
        measure, tile_size, run.budget, run.requested, run.cpus, in_process=run.in_process, given=given, say=run.say)
    plan = TilePlan(identity, tiling, stats, int(tile_size), tuple(survey_halos), tuple(key_halos))
    _write_json(run.work / "plan.json", plan.to_json())
    run.say(f"tiled {run.src.name}: {stats.count} points in {len(tiling.counts)} tiles of at most {tile_size} "
            f"points (budget {size_text(run.budget)})")
    return plan


@dataclass(frozen=True)
class _Phase:
    """How a parallel phase submits its tiles (:func:`_phase`)."""

    executor: object  # executor(workers), for _run
    workers: int
    options: dict  # the tasks' estimator options


def _phase(run: _Run, plan: TilePlan, halo, name: str) -> _Phase:
    """The workers, executor and task options of a phase whose tiles read ``halo`` (one, or one per tile).

    A run of one tile, or a phase whose tile fits only in this process, runs serially here with the run's threads.
    """
    n_tiles = len(plan.tiling.counts)
    fit = _phase_workers(plan.tiling, plan.stats, halo, run.budget, run.requested, run.cpus, plan.tile_size, name,
                         run.in_process)
    serial = fit.in_process or (n_tiles == 1 and isinstance(run.scheduler, str))
    executor = partial(open_executor, "serial" if serial else run.scheduler, budget=max(run.budget - DRIVER_MEMORY, 1))
    threads = serial or n_tiles == 1 or run.scheduler == "serial"
    return _Phase(executor, max(1, min(n_tiles, fit.count)), dict(run.options, workers=run.threads if threads else 1))


def _survey(run: _Run, plan: TilePlan, timings: dict, bar) -> SurveyContext:
    """The survey phase: the context every tile gets, from ``context.json`` if a resumed run has it."""
    context_file = run.work / "context.json"
    if context_file.exists():
        return read_context(context_file)
    bar.stage("survey")
    tic = time.perf_counter()
    phase = _phase(run, plan, list(plan.survey_halos), "survey")
    if len(plan.tiling.counts) <= ONE_ROUND_TILES:
        context = _survey_one_round(run, plan, phase)
    else:
        context = _survey_two_rounds(run, plan, phase)
    write_context(context_file, context)
    timings["survey"] += time.perf_counter() - tic
    return context


def _survey_one_round(run: _Run, plan: TilePlan, phase: _Phase) -> SurveyContext:
    """One round (:func:`heatcurv.choice.survey.survey_part`): the cloud's centres fill so few tiles that round 2 would
    compute as much as one round does, after round 1."""
    n_tiles = len(plan.tiling.counts)
    specs = {t: {"scratch": str(run.work), "tile": t, "stats": plan.stats, "options": phase.options,
                 "halo": plan.survey_halos[t]} for t in range(n_tiles)}
    surveys = {}
    _run(phase.executor, phase.workers, run_survey, specs, surveys.__setitem__, run.say, "survey of tile", n_tiles)
    return compute.merge_surveys([surveys[t] for t in range(n_tiles)], plan.stats, run.options)


def _survey_two_rounds(run: _Run, plan: TilePlan, phase: _Phase) -> SurveyContext:
    """Two rounds (:mod:`heatcurv.choice.survey`): every tile's keys over a thin halo, then the candidates' fits at the
    cloud's sample centres only, over the points within their reach (the same fits, bit for bit); the survey's halo
    bounds both. The noise gate's candidates first: a clean cloud is decided by them, a noisy one fits them all."""
    n_tiles = len(plan.tiling.counts)
    specs = {t: {"scratch": str(run.work), "tile": t, "stats": plan.stats, "options": phase.options,
                 "halo": plan.key_halos[t]} for t in range(n_tiles)}
    keys = {}
    _run(phase.executor, phase.workers, run_keys, specs, keys.__setitem__, run.say, "keys of tile", n_tiles)
    centres = compute.plan_centres([keys[t] for t in range(n_tiles)], plan.stats, run.options)
    try:
        return _fit_centres(run, plan, phase, centres, compute.gate_levels(run.options))
    except FitsNotSurveyed:
        return _fit_centres(run, plan, phase, centres, None)


def _fit_centres(run: _Run, plan: TilePlan, phase: _Phase, centres, levels) -> SurveyContext:
    """Round 2 of the survey: the candidates' fits (the first ``levels``, None: all) at the centres of every tile."""
    n_tiles = len(plan.tiling.counts)
    specs = {t: {"scratch": str(run.work), "tile": t, "stats": plan.stats, "options": phase.options,
                 "plan": centres, "places": centres.of_tile(t), "levels": levels} for t in range(n_tiles)}
    specs = {t: spec for t, spec in specs.items() if spec["places"].size}
    parts = {}
    _run(phase.executor, phase.workers, run_centres, specs, parts.__setitem__, run.say, "survey of tile", n_tiles)
    return compute.merge_rounds([p for t in sorted(parts) for p in parts[t]], centres, plan.stats, run.options)


class _TileStore:
    """Finished tiles into ``results.rec``, and the progress bar (:func:`_compute_tiles`).

    ``unslimmed``: tile file -> core points whose rows are in ``results.rec``,
    not yet fsynced and slimmed (:func:`.output.slim_tiles`); ``results``:
    what each tile computed here returned.
    """

    def __init__(self, run: _Run):
        self.run = run
        self.path = run.work / "results.rec"
        self.bar = TileProgress(run.progress, 1, 1)
        self.unslimmed = {}
        self.results = {}

    def resume(self, plan: TilePlan) -> set:
        """Create ``results.rec`` (kept if tiles are stored in it) and store the finished tiles; the tiles done."""
        n_tiles = len(plan.tiling.counts)
        work = self.run.work
        done = {t for t in range(n_tiles) if os.path.exists(tile_path(work, t))}
        stored = {t for t in done if is_stored(tile_path(work, t))}
        if not create_results(self.path, plan.stats.count, keep=bool(stored)) and stored:
            # their rows were in a results.rec that is gone: those tiles are computed again
            for t in stored:
                os.unlink(tile_path(work, t))
            self.run.say(f"{len(stored)} finished tile(s) must be computed again: {self.path} is missing")
            done -= stored
        for t in sorted(done - stored):
            self.unslimmed[tile_path(work, t)] = store_tile(self.path, tile_path(work, t), t)
        if done:
            self.run.say(f"resuming: {len(done)} of {n_tiles} tiles already computed in {work}")
        self.bar.close()
        self.bar = TileProgress(self.run.progress, plan.stats.finite, n_tiles)
        self.bar.skip(sum(plan.tiling.counts[t] for t in done), len(done))
        return done

    def finished(self, tile: int, result: dict) -> None:
        """A tile computed: its rows into ``results.rec``; every :data:`SLIM_POINTS` points, fsync and slim."""
        path = tile_path(self.run.work, tile)
        self.unslimmed[path] = store_tile(self.path, path, tile)
        self.results[tile] = result
        self.bar(result["points"])
        if sum(self.unslimmed.values()) >= SLIM_POINTS:
            self.slim()

    def slim(self) -> None:
        """Make the stored tiles' rows durable and slim their files."""
        slim_tiles(self.path, list(self.unslimmed))
        self.unslimmed.clear()

    def abandon(self) -> None:
        """After a failure: keep what a resume can use (stored rows made durable, finished tiles), say where."""
        self.bar.close()
        if self.unslimmed:  # the stored tiles' rows made durable, their files slimmed (a resume finds both)
            try:
                self.slim()
            except Exception:
                pass  # a file left whole is stored again on resume
        left = _cleanup(self.run.work, keep_done=True)
        if left:
            self.run.say(left)


def _compute_tiles(run: _Run, plan: TilePlan, context: SurveyContext, store: _TileStore, timings: dict):
    """The tiles phase: every tile not done yet, stored as it finishes; ``(scheduler name, workers, resumed)``."""
    n_tiles = len(plan.tiling.counts)
    phase = _phase(run, plan, float(context.halo), "tiles")
    done = store.resume(plan)
    tic = time.perf_counter()
    specs = {t: {"scratch": str(run.work), "tile": t, "context": context, "options": phase.options}
             for t in range(n_tiles) if t not in done}
    name = _run(phase.executor, phase.workers, run_tile, specs, store.finished, run.say, "tile", n_tiles)
    store.slim()  # before the output takes its disk space
    timings["tiles"] = time.perf_counter() - tic
    return name, phase.workers, len(done)


def _cloud_flags(run: _Run, plan: TilePlan, timings: dict) -> dict:
    """The flags that compare each point with the whole cloud's medians, once every tile is in."""
    tic = time.perf_counter()
    medians = apply_cloud_flags(run.work / "results.rec", plan.stats.count)
    timings["reliability"] = time.perf_counter() - tic
    return medians


def _orient(run: _Run, plan: TilePlan, context: SurveyContext, timings: dict, bar):
    """The orientation phase (``outward`` only): the seams' flips, then a closed cloud's inside and outside by the
    winding number over every tile's sources; ``(flips, report)``, both None for other orientations."""
    if not compute.orients_outward(run.options, context.choices):
        return None, None
    from ..orient.enclosure import warn_undecided
    from .orient import seam_flips
    from .winding import flag_unsupported, winding_sides

    bar.stage("orientation")
    tic = time.perf_counter()
    results_path = run.work / "results.rec"
    tile_files = {t: tile_path(run.work, t) for t in range(len(plan.tiling.counts))}
    keys, flip, orientation = seam_flips(tile_files, results_path)
    flips = [("patch", keys, flip)]
    # a closed cloud's inside and outside, by the winding number over every tile's sources
    sides = winding_sides(tile_files, keys, flip)
    orientation["closed"] = bool(sides is not None and sides.closed)
    orientation["undecided"] = bool(sides is not None and sides.undecided)
    if sides is not None:
        orientation["agreement"], orientation["outside_share"] = sides.agreement, sides.outside_share
    if sides is not None and sides.undecided:
        warn_undecided(sides.agreement, sides.outside_share)
    if sides is not None and (sides.closed or sides.undecided):
        flips.append((sides.column, sides.keys, sides.flip))
        orientation.update(flag_unsupported(results_path, run.source, context.choices.frame, sides))
    timings["orientation"] = time.perf_counter() - tic
    return flips, orientation


def _write(run: _Run, plan: TilePlan, context: SurveyContext, medians: dict, flips, timings: dict, bar) -> dict:
    """The write phase: the output in input order, atomically; the parameters written into it."""
    from ..io.atomic import atomic_write

    parameters = {
        "heatcurv": _version(), "tiled": True, "options": run.options, "tile_size": plan.tile_size,
        "tiles": len(plan.tiling.counts), "halo": float(context.halo),
        "context": compute.describe(context, run.options), "medians": medians, "source": run.src.name,
    }
    bar.stage("writing")
    tic = time.perf_counter()
    atomic_write(run.dst, partial(write_output, dst=run.dst, source=run.source, stats=plan.stats,
                                  results_path=run.work / "results.rec", wanted=run.fields, dtype=run.dtype,
                                  flips=flips, parameters=parameters))
    timings["write"] = time.perf_counter() - tic
    return parameters


def _report(run: _Run, plan: TilePlan, context: SurveyContext, store: _TileStore, timings: dict, name: str,
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
    )


def _version() -> str:
    from .. import __version__

    return __version__


def _run(executor, workers: int, fn, specs: dict, on_done, say, what: str, total: int) -> str:
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
