"""The survey phase of a tiled run: the cloud-wide kernel choice every tile gets (its context).

One round (:func:`.tasks.run_survey`) for at most :data:`ONE_ROUND_TILES`
tiles, else two rounds (:mod:`heatcurv.choice.survey`): :func:`.tasks.run_keys`
on every tile (its core's sampling keys over a thin halo), joined into the
cloud's sample centres; :func:`.tasks.run_centres` on the tiles holding some
(the candidates' fits at those centres only, over the points within their
reach); merged by :func:`.compute.merge_rounds` into the context every tile gets
(the halo). The survey's halo (decided in the plan, which budgets the survey's
workers with it) bounds both rounds. A resumed run reads ``context.json``.
"""

from __future__ import annotations

import time

import numpy as np

from ..choice.survey import CandidatesShort, FitsNotSurveyed
from . import compute, job
from .context import SurveyContext, read_context, write_context
from .job import Job, Phase
from .neighbours import remove_halo_lists
from .plan import TilePlan
from .tasks import CentresTask, KeysTask, SurveyTask, run_centres, run_keys, run_survey

__all__ = ["survey", "survey_order", "ONE_ROUND_TILES"]

#: A cloud of at most this many tiles is surveyed in one round (:func:`.tasks.run_survey`), others in two
#: (:func:`.tasks.run_keys`, :func:`.tasks.run_centres`); both choose the same kernel bit for bit. Round 2's
#: cost falls with the centres per tile (2000 / tiles); one round's with the lists its surveys share
#: (:func:`.neighbours.halo_lists`), and its tiles read its areas and outlier flags: one round is the faster
#: at 16 and at 64 tiles, clean or noisy (docs/how_it_works.md, thresholds); the crossing above is an estimate.
ONE_ROUND_TILES = 64


def survey(run: Job, plan: TilePlan, timings: dict, bar) -> SurveyContext:
    """The survey phase: the context every tile gets, from ``context.json`` if a resumed run has it."""
    context_file = run.work / "context.json"
    if context_file.exists():
        return read_context(context_file)
    bar.stage("survey")
    tic = time.perf_counter()
    phase = job.phase(run, plan, list(plan.survey_halos), "survey")
    if len(plan.tiling.counts) <= ONE_ROUND_TILES:
        context = _one_round(run, plan, phase)
    else:
        context = _two_rounds(run, plan, phase)
    write_context(context_file, context)
    remove_halo_lists(run.work)
    timings["survey"] += time.perf_counter() - tic
    return context


def _one_round(run: Job, plan: TilePlan, phase: Phase, bounded: bool = True) -> SurveyContext:
    """One round (:func:`heatcurv.choice.survey.survey_part`): the cloud's centres fill so few tiles that round 2 would
    compute as much as one round does, after round 1. Each tile fits its candidates below the key bound; when they
    fall short of the cloud's centres (:class:`~heatcurv.choice.survey.CandidatesShort`), again without it."""
    n_tiles = len(plan.tiling.counts)
    specs = {t: SurveyTask(str(run.work), t, phase.options, plan.stats, plan.survey_halos[t], bounded)
             for t in survey_order(plan.tiling, phase.workers)}
    surveys = {}
    job.submit(phase.executor, phase.workers, run_survey, specs, surveys.__setitem__, run.say, "survey of tile",
               n_tiles)
    try:
        return compute.merge_surveys([surveys[t] for t in range(n_tiles)], plan.stats, run.options)
    except CandidatesShort as short:
        if not bounded:
            raise
        run.say(f"{short}: surveying again with every tile's candidates")
        return _one_round(run, plan, phase, bounded=False)


def survey_order(tiling, workers: int) -> list[int]:
    """The tiles in the order a one-round survey submits them: each as far from the ``workers - 1`` before it as
    can be (the largest least distance between box centres; ties: the lower number).

    Tiles surveyed at once cannot read each other's lists (:mod:`.neighbours`): apart, each finds its
    neighbours' lists, core and halo, written by the surveys before it.
    """
    n = len(tiling.counts)
    centres = np.array([np.add(*tiling.box(t)) / 2.0 for t in range(n)]).reshape(n, -1)
    order, left = [0] if n else [], list(range(1, n))
    while left:
        recent = centres[order[-max(workers - 1, 1):]]
        gaps = np.linalg.norm(centres[left][:, None, :] - recent[None, :, :], axis=2).min(axis=1)
        order.append(left.pop(int(np.argmax(gaps))))
    return order


def _two_rounds(run: Job, plan: TilePlan, phase: Phase) -> SurveyContext:
    """Two rounds (:mod:`heatcurv.choice.survey`): every tile's keys over a thin halo, then the candidates' fits at the
    cloud's sample centres only, over the points within their reach (the same fits, bit for bit); the survey's halo
    bounds both. The noise gate's candidates first: a clean cloud is decided by them, a noisy one fits them all."""
    n_tiles = len(plan.tiling.counts)
    specs = {t: KeysTask(str(run.work), t, phase.options, plan.stats, plan.key_halos[t]) for t in range(n_tiles)}
    keys = {}
    job.submit(phase.executor, phase.workers, run_keys, specs, keys.__setitem__, run.say, "keys of tile", n_tiles)
    centres = compute.plan_centres([keys[t] for t in range(n_tiles)], plan.stats, run.options)
    try:
        return _fit_centres(run, plan, phase, centres, compute.gate_levels(run.options))
    except FitsNotSurveyed:
        return _fit_centres(run, plan, phase, centres, None)


def _fit_centres(run: Job, plan: TilePlan, phase: Phase, centres, levels) -> SurveyContext:
    """Round 2 of the survey: the candidates' fits (the first ``levels``, None: all) at the centres of every tile."""
    n_tiles = len(plan.tiling.counts)
    specs = {t: CentresTask(str(run.work), t, phase.options, plan.stats, centres, centres.of_tile(t), levels)
             for t in range(n_tiles)}
    specs = {t: spec for t, spec in specs.items() if spec.places.size}
    parts = {}
    job.submit(phase.executor, phase.workers, run_centres, specs, parts.__setitem__, run.say, "survey of tile", n_tiles)
    return compute.merge_rounds([p for t in sorted(parts) for p in parts[t]], centres, plan.stats, run.options)
