"""The plan phase of a tiled run: statistics, the tiles that fit the budget, the scratch; or a plan to resume.

Three streaming passes over the input (:mod:`.plan`): statistics, the tiles,
the points in tile order in scratch; tiled again at smaller sizes while the
survey's tiles do not fit the budget (:func:`.plan.fit_tiles`). The result is a
frozen :class:`.plan.TilePlan`, written to ``plan.json``; a run whose scratch
holds a matching plan resumes from it (:func:`find_plan`).
"""

from __future__ import annotations

import json
import os
import shutil
import time
from functools import partial
from pathlib import Path

from ..errors import HeatcurvError
from . import compute, job
from .job import Job
from .neighbours import list_bytes
from .output import BUCKET_RECORD
from .plan import (
    DRIVER_MEMORY,
    CloudStats,
    TilePlan,
    Tiling,
    check_disk,
    default_tile_size,
    distinct_frame,
    fit_tiles,
    halo_points,
    make_tiling,
    options_hash,
    plan_workers,
    read_rows,
    scan_stats,
    scatter,
    size_text,
)
from .tasks import load_plan, warm_up

__all__ = ["find_plan", "identity_of", "make_plan", "PLAN_VERSION"]

#: Plan file version: a plan of another version is never resumed.
PLAN_VERSION = 13


def identity_of(run: Job, tile_size, skip_nonfinite: bool) -> dict:
    """What a plan must match to be resumed: the plan's version, heatcurv's, the source file, the options."""
    identity = {"version": PLAN_VERSION, "heatcurv": job.version(), "source": _identity(run.src),
                "options": options_hash(run.options), "skip_nonfinite": bool(skip_nonfinite)}
    if tile_size is not None:
        identity["tile_size"] = int(tile_size)
    return identity


def find_plan(run: Job, identity: dict, tile_size, resume) -> TilePlan | None:
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


def make_plan(run: Job, identity: dict, tile_size, skip_nonfinite: bool, timings: dict, bar) -> TilePlan:
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
    # points.f8 + rows.i8 with the halos' copies (~1.25x), the buckets (merged into results.rec, a bucket
    # file deleted as its span is written: together never much more than the buckets), the slimmed tile files (their
    # halo rows, normals and patches) and the few full ones in flight, the survey's neighbour lists and, while
    # it runs, the lists its tiles queried for their halos (at most about half as many: heatcurv.tiles.neighbours)
    lists = list_bytes(stats.finite, compute.operator_neighbours(run.options))
    need = stats.finite * (48 + BUCKET_RECORD.itemsize + 48) + lists + lists // 2
    check_disk(run.work, need, f"the scratch files of {stats.finite} points")
    if os.stat(run.work).st_dev == os.stat(run.dst.parent).st_dev:
        need += stats.count * 100
    check_disk(run.dst.parent, need if run.dst.parent == run.root else stats.count * 100, f"the output {run.dst.name}")
    job.warm_workers(run, stats.finite, tile_size, warm_up)  # their imports while this process tiles the cloud
    measure = partial(_tile_cloud, run.source, stats, run.work, run.options, timings, bar)
    tile_size, (tiling, stats, survey_halos, key_halos), _ = fit_tiles(
        measure, tile_size, run.budget, run.requested, run.cpus, in_process=run.in_process, given=given, say=run.say)
    plan = TilePlan(identity, tiling, stats, int(tile_size), tuple(survey_halos), tuple(key_halos))
    _write_json(run.work / "plan.json", plan.to_json())
    run.say(f"tiled {run.src.name}: {stats.count} points in {len(tiling.counts)} tiles of at most {tile_size} "
            f"points (budget {size_text(run.budget)})")
    return plan


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


def _identity(src: Path) -> dict:
    stat = src.stat()
    return {"path": str(src.resolve()), "size": stat.st_size, "mtime_ns": stat.st_mtime_ns}


def _write_json(path, data) -> None:
    temporary = f"{path}.{os.getpid()}.tmp"
    with open(temporary, "w") as stream:
        json.dump(data, stream, default=repr)
    os.replace(temporary, path)
