"""The orientation phase of a tiled run (``outward``): the seams' flips, then a closed cloud's inside and outside.

The pieces' sides are made to agree across the seams (:mod:`.orient`), then the
winding number over every tile's sources decides a closed cloud's inside and
outside and flags what it contradicts (:mod:`.winding`), as
:mod:`heatcurv.orient.enclosure` does in memory; the second sheets the tiles
could not settle are judged with those signs (:mod:`.sheets`).
"""

from __future__ import annotations

import time

import numpy as np

from ..orient.enclosure import warn_undecided
from ..orient.visibility import own_layer
from . import compute
from .context import SurveyContext
from .job import Job
from .orient import seam_flips
from .plan import TilePlan
from .sheets import flag_second_sheets
from .tasks import tile_path
from .winding import flag_unsupported, winding_sides

__all__ = ["orient_cloud"]

def orient_cloud(run: Job, plan: TilePlan, context: SurveyContext, timings: dict, bar):
    """The orientation phase (``outward`` only): the seams' flips, then a closed cloud's inside and outside by the
    winding number over every tile's sources; ``(flips, report)``, both None for other orientations."""
    if not compute.orients_outward(run.options, context.choices):
        return None, None
    bar.stage("orientation")
    tic = time.perf_counter()
    results_path = run.work / "results.rec"
    tile_files = {t: tile_path(run.work, t) for t in range(len(plan.tiling.counts))}
    keys, flip, orientation = seam_flips(tile_files, results_path, run.source, context.choices.frame)
    flips = [("patch", keys, flip)]
    # a closed cloud's inside and outside, by the winding number over every tile's sources
    sides = winding_sides(tile_files, keys, flip, open_up=compute.orients_automatically(run.options))
    orientation["closed"] = bool(sides is not None and sides.closed)
    orientation["undecided"] = bool(sides is not None and sides.undecided)
    orientation["open_components"] = 0 if sides is None else sides.open_components
    orientation["upward_components"] = 0 if sides is None else sides.upward_components
    if sides is not None:
        orientation["agreement"], orientation["outside_share"] = sides.agreement, sides.outside_share
    if sides is not None and sides.undecided:
        warn_undecided(sides.agreement, sides.outside_share)
    if sides is not None and (sides.closed or sides.undecided or sides.upward_components):
        flips.append((sides.column, sides.keys, sides.flip))
        flips.append(("winding_fine", sides.fine_keys, sides.fine_flip))
    # the two sides of a thin part, once the normals' signs are final (before the rays, as in memory)
    orientation["second_sheet"] = flag_second_sheets(results_path, tile_files, flips)
    if sides is not None and (sides.closed or sides.undecided):
        alpha = compute.resolved_options(run.options).alpha
        scale = context.choices.scale
        report, escaping = flag_unsupported(results_path, run.source, context.choices.frame, sides, alpha, flips,
                                            own_layer(scale.sigma, scale.residual_rise))
        orientation.update(report)
        flips.append(("row", escaping, np.ones(escaping.size, dtype=bool)))
    timings["orientation"] = time.perf_counter() - tic
    return flips, orientation
