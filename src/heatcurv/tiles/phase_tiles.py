"""The tiles phase of a tiled run: every tile computed with its halo, stored as it finishes; then the cloud's flags.

:func:`.tasks.run_tile` runs on every tile not done yet, at most ``2 x slots``
in flight; each finished tile's rows are appended to the bucket files of
their input rows (:class:`TileStore`), and every :data:`SLIM_POINTS` core points
the buckets are fsynced and the stored tiles' files slimmed
(:func:`.output.slim_tiles`). Once every tile is in, the buckets are merged
into the index-addressed ``results.rec`` and :func:`cloud_flags` compares each
point with the whole cloud's medians.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

from ..choice.plan import noise_swamps_balls, plan_fit
from . import job
from .compute import resolved_options
from .context import SurveyContext
from .job import Job
from .medians import apply_cloud_flags
from .output import create_results, is_stored, merge_buckets, prepare_buckets, slim_tiles, store_tile
from .plan import TilePlan
from .progressbar import TileProgress
from .tasks import TileTask, run_tile, tile_path

__all__ = ["TileStore", "cloud_flags", "compute_tiles", "SLIM_POINTS"]

#: Core points of stored tiles after which :func:`.output.slim_tiles` fsyncs the buckets and slims their
#: files (about 350 MB of rows): the scratch stays near one copy of the results, the loop rarely waits.
SLIM_POINTS = 2_000_000


class TileStore:
    """Finished tiles into the buckets, then ``results.rec``; the progress bar (:func:`compute_tiles`).

    ``unslimmed``: tile file -> core points whose rows are in the buckets,
    not yet fsynced and slimmed (:func:`.output.slim_tiles`); ``results``:
    what each tile computed here returned.
    """

    def __init__(self, run: Job):
        self.run = run
        self.path = run.work / "results.rec"
        self.buckets = run.work / "buckets"
        self.bar = TileProgress(run.progress, 1, 1)
        self.unslimmed = {}
        self.results = {}

    def resume(self, plan: TilePlan) -> set:
        """Create ``results.rec`` and the buckets (kept if tiles are stored), store finished tiles; the tiles done."""
        n_tiles = len(plan.tiling.counts)
        work = self.run.work
        done = {t for t in range(n_tiles) if os.path.exists(tile_path(work, t))}
        stored = {t for t in done if is_stored(tile_path(work, t))}
        kept = create_results(self.path, plan.stats.count, keep=bool(stored))
        prepare_buckets(self.buckets, keep=kept)
        if not kept and stored:
            # their rows were in a results.rec that is gone: those tiles are computed again
            for t in stored:
                os.unlink(tile_path(work, t))
            self.run.say(f"{len(stored)} finished tile(s) must be computed again: {self.path} is missing")
            done -= stored
        for t in sorted(done - stored):
            self.unslimmed[tile_path(work, t)] = store_tile(self.buckets, tile_path(work, t), t)
        if done:
            self.run.say(f"resuming: {len(done)} of {n_tiles} tiles already computed in {work}")
        self.bar.close()
        self.bar = TileProgress(self.run.progress, plan.stats.finite, n_tiles)
        self.bar.skip(sum(plan.tiling.counts[t] for t in done), len(done))
        return done

    def finished(self, tile: int, result: dict) -> None:
        """A tile computed: its rows into the buckets; every :data:`SLIM_POINTS` points, fsync and slim."""
        path = tile_path(self.run.work, tile)
        self.unslimmed[path] = store_tile(self.buckets, path, tile)
        self.results[tile] = result
        self.bar(result["points"])
        if sum(self.unslimmed.values()) >= SLIM_POINTS:
            self.slim()

    def slim(self) -> None:
        """Make the stored tiles' rows durable and slim their files."""
        slim_tiles(self.buckets, list(self.unslimmed))
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


def compute_tiles(run: Job, plan: TilePlan, context: SurveyContext, store: TileStore, timings: dict):
    """The tiles phase: every tile not done yet, stored, then merged; ``(scheduler name, workers, resumed)``."""
    n_tiles = len(plan.tiling.counts)
    phase = job.phase(run, plan, float(context.halo), "tiles")
    done = store.resume(plan)
    tic = time.perf_counter()
    specs = {t: TileTask(str(run.work), t, phase.options, context) for t in range(n_tiles) if t not in done}
    name = job.submit(phase.executor, phase.workers, run_tile, specs, store.finished, run.say, "tile", n_tiles)
    store.slim()
    store.bar.stage("merging")
    merge_buckets(store.path, store.buckets)
    timings["tiles"] = time.perf_counter() - tic
    return name, phase.workers, len(done)


def cloud_flags(run: Job, plan: TilePlan, context: SurveyContext, timings: dict) -> dict:
    """The flags that compare each point with the whole cloud's medians, once every tile is in."""
    tic = time.perf_counter()
    scale = context.choices.scale
    fit = plan_fit(resolved_options(run.options), scale)  # the in-memory run's plan, whose misfit bound it takes
    medians = apply_cloud_flags(run.work / "results.rec", plan.stats.count, plan.stats.finite,
                                swamped=noise_swamps_balls(scale), misfit_factor=fit.misfit_factor)
    timings["reliability"] = time.perf_counter() - tic
    return medians


def _cleanup(work: Path, keep_done: bool) -> str:
    """Remove temporaries (and everything unless finished tiles are kept); say what is left."""
    for stray in [*work.glob("tiles/*.tmp.npz"), *work.glob("knn/*.tmp.npy")]:  # results, neighbour lists
        stray.unlink(missing_ok=True)
    done = sorted(work.glob("tiles/tile_*.npz"))  # after the strays, whose names start alike
    if keep_done and done:  # results.rec and the buckets hold the rows of the tiles already stored
        return f"{len(done)} finished tile(s) are kept in {work}: run the same command again to resume, or delete it"
    shutil.rmtree(work, ignore_errors=True)
    return ""
