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

import numpy as np

from ..errors import HeatcurvError
from . import compute, job
from .job import Job
from .neighbours import list_bytes
from .output import BUCKET_RECORD, RECORD
from .phase_tiles import SLIM_POINTS
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
PLAN_VERSION = 18


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
    neighbours = compute.operator_neighbours(run.options)
    output = stats.count * OUTPUT_BYTES
    same_disk = os.stat(run.work).st_dev == os.stat(run.dst.parent).st_dev
    # before anything is written, the least the scratch will hold (no halo): a disk too small fails now
    least = scratch_bytes(stats.finite, neighbours)
    _check_space(run, stats.finite, max(least["survey"], least["tiles"] + output * same_disk), output)
    job.warm_workers(run, stats.finite, tile_size, warm_up)  # their imports while this process tiles the cloud
    measure = partial(_tile_cloud, run.source, stats, run.work, run.options, timings, bar)
    tile_size, (tiling, stats, survey_halos, key_halos), _ = fit_tiles(
        measure, tile_size, run.budget, run.requested, run.cpus, in_process=run.in_process, given=given, say=run.say)
    plan = TilePlan(identity, tiling, stats, int(tile_size), tuple(survey_halos), tuple(key_halos))
    # the points are in scratch now: the halos' share, the rest of the scratch
    halo_rows = int((halo_points(tiling, stats, survey_halos) - np.asarray(tiling.counts)).sum())
    need = scratch_bytes(stats.finite, neighbours, halo_rows, in_flight=SLIM_POINTS + int(max(tiling.counts)))
    written = SCATTER_BYTES * stats.finite
    _check_space(run, stats.finite, max(need["survey"], need["tiles"] + output * same_disk) - written, output)
    _write_json(run.work / "plan.json", plan.to_json())
    run.say(f"tiled {run.src.name}: {stats.count} points in {len(tiling.counts)} tiles of at most {tile_size} "
            f"points (budget {size_text(run.budget)})")
    return plan


#: Bytes a point of the scratch's points in tile order (``points.f8`` and ``rows.i8``).
SCATTER_BYTES = 32
#: The share of the survey's halo rows whose lists it keeps, with a margin: those in tiles not surveyed yet
#: (the first tiles surveyed keep all of theirs, the last none: about half).
HALO_LIST_SHARE = 0.6
#: Bytes a halo row of a tile's result file keeps for the seam vote (its row, normal and patch).
STORED_HALO_BYTES = 40
#: Bytes a winding source of a tile's result file keeps (row, position, normal, area, labels, roundness).
SOURCE_BYTES = 96
#: Bytes a point of the output, allowed for (a LAZ of the default fields takes about 56, a PLY about 90).
OUTPUT_BYTES = 100


def scratch_bytes(points: int, neighbours: int, halo_rows: int = 0, in_flight: int = 0) -> dict:
    """The scratch's peak bytes in the survey and in the tiles phase.

    Both hold the points in tile order and every core point's neighbour list
    (:func:`.neighbours.list_bytes`). The survey also holds the lists its tiles
    queried for the halo points of tiles not surveyed yet (:data:`HALO_LIST_SHARE`),
    deleted when it ends. The tiles phase holds the buckets
    (:data:`.output.BUCKET_RECORD` a row; merged into ``results.rec`` a bucket at
    a time, never much more), the tiles' halo rows and winding sources (at most
    two per source the cloud has, :data:`heatcurv.orient.enclosure.MAX_SOURCES`),
    and the fields of up to ``in_flight`` core points whose files are not slimmed yet.

    Parameters
    ----------
    points : int
        The cloud's finite points.
    neighbours : int
        The operator's neighbour count (a list's length).
    halo_rows : int
        Halo rows summed over the tiles (:func:`.plan.halo_points` minus the cores).
    in_flight : int
        Core points whose tile files are not slimmed yet, at most.

    Returns
    -------
    dict
        ``{"survey": bytes, "tiles": bytes}``.
    """
    from ..orient.enclosure import MAX_SOURCES

    shared = SCATTER_BYTES * points + list_bytes(points, neighbours)
    survey = shared + int(HALO_LIST_SHARE * list_bytes(halo_rows, neighbours))
    tiles = (shared + BUCKET_RECORD.itemsize * points + STORED_HALO_BYTES * halo_rows
             + SOURCE_BYTES * min(points, 2 * MAX_SOURCES) + RECORD.itemsize * min(points, in_flight))
    return {"survey": survey, "tiles": tiles}


def _check_space(run: Job, points: int, scratch: int, output: int) -> None:
    """Fail if the scratch's disk has less than ``scratch`` bytes free (its peak, the output included when it is
    on the same disk), or the output's directory less than ``output``."""
    check_disk(run.work, scratch, f"the scratch files of {points} points")
    if run.dst.parent != run.root:
        check_disk(run.dst.parent, output, f"the output {run.dst.name}")


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
