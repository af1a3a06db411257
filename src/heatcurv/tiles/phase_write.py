"""The write phase of a tiled run: the output in input order, atomically, with the run's parameters."""

from __future__ import annotations

import time
from functools import partial

from . import compute, job
from .context import SurveyContext
from .job import Job
from .output import write_output
from .plan import TilePlan

__all__ = ["write"]

def write(run: Job, plan: TilePlan, context: SurveyContext, medians: dict, flips, timings: dict, bar) -> dict:
    """The write phase: the output in input order, atomically; the parameters written into it."""
    from ..io.atomic import atomic_write

    parameters = {
        "heatcurv": job.version(), "tiled": True, "options": run.options, "tile_size": plan.tile_size,
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
