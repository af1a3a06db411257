"""The tasks a tiled run submits: module-level functions of a small spec, importable by any worker.

A spec is a frozen :class:`Task` (the scratch directory, a tile number, the
estimator options, and what its kind of task needs: the cloud's statistics, a
halo, the survey's context): the task reads its points from the
scratch files itself (the cluster contract: every worker sees the same file
system), computes through :mod:`.compute`, checks the certificate and writes
its core rows to ``tiles/tile_NNNNN.npz`` atomically (a temporary file moved
into place), which is also the tile's done marker. It returns a few numbers.

Certificate (SCALE.md decision 4): a core point's values depend on no point
farther than ``DEPTH x support`` (its support radius, which
:func:`.compute.compute_tile` returns). The tile had every point of the cloud
inside its halo box; so each core point's dependency ball must lie inside that
box, except across a side where the box already reaches past the cloud's
bounding box. Otherwise the tile widens its halo to what the failing points
need (x :data:`.compute.HALO_MARGIN`) and computes again, at most
:data:`WIDENINGS` times, then fails with a message: never silently wrong.
"""

from __future__ import annotations

import ctypes
import functools
import json
import os
import resource
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import HeatcurvError
from . import compute
from .context import SurveyContext
from .neighbours import (
    core_lists,
    core_values,
    halo_lists,
    known_neighbours,
    write_halo_lists,
    write_lists,
    write_values,
)
from .orient import MOMENTS
from .plan import CloudStats, Tiling, read_rows
from .winding import tile_sources

if TYPE_CHECKING:
    from ..choice.survey import CentrePlan

__all__ = [
    "Task", "SurveyTask", "KeysTask", "CentresTask", "TileTask", "warm_up", "run_survey", "run_keys", "run_centres",
    "run_tile", "tile_points", "certificate", "tile_path", "WIDENINGS",
]

#: Times a tile may widen its halo before the run fails.
WIDENINGS = 3
#: Environment variable of the fault-injection hook the tests use: ``fail:T`` raises in tile T,
#: ``interrupt:T`` raises KeyboardInterrupt there (Ctrl-C in a serial run), ``kill:T:FILE`` ends the
#: worker process at tile T once (FILE records that it did).
FAULT_VARIABLE = "HEATCURV_TILES_FAULT"


@dataclass(frozen=True)
class Task:
    """What every task gets: where the scratch files are (every worker sees the same file system), its tile, the
    estimator keywords (:func:`heatcurv.tiles.driver.estimator_options`, ``workers`` set for the phase)."""

    scratch: str
    tile: int
    options: dict


@dataclass(frozen=True)
class SurveyTask(Task):
    """:func:`run_survey`: the cloud's statistics, the survey halo (None: :func:`.compute.survey_halo`) and whether
    the candidates are those below the key bound (:func:`heatcurv.choice.survey.key_bound`)."""

    stats: CloudStats
    halo: float | None = None
    bounded: bool = True


@dataclass(frozen=True)
class KeysTask(Task):
    """:func:`run_keys`: the cloud's statistics and the keys' halo (about one operator ball)."""

    stats: CloudStats
    halo: float


@dataclass(frozen=True)
class CentresTask(Task):
    """:func:`run_centres`: the cloud's sample centres, the tile's among them (``places``, indices into
    ``plan``), and the candidates to fit (``levels``: the noise gate's first ones, None: all)."""

    stats: CloudStats
    plan: CentrePlan
    places: np.ndarray
    levels: int | None = None


@dataclass(frozen=True)
class TileTask(Task):
    """:func:`run_tile`: the survey's context (its halo, unless ``halo`` is given)."""

    context: SurveyContext
    halo: float | None = None


def tile_path(scratch, tile: int) -> str:
    """The result file of tile ``tile`` (its existence marks the tile done)."""
    return os.path.join(scratch, "tiles", f"tile_{tile:05d}.npz")


def load_plan(scratch) -> dict:
    """The plan file of a scratch directory (``plan.json``)."""
    with open(os.path.join(scratch, "plan.json")) as stream:
        return json.load(stream)


def tile_points(scratch, tiling: Tiling, tile: int, halo: float):
    """Core and halo points of a tile: the core slice, then the neighbours' points inside the widened box.

    Returns
    -------
    points : ndarray, shape (m, 3)
    rows : ndarray, shape (m,), int64
        Input row of each point.
    core : ndarray, shape (m,), bool
        The first ``counts[tile]`` rows.
    low, high : ndarray, shape (3,)
        The halo box.
    positions : ndarray, shape (m,), int64
        Each point's position in the scratch files.
    """
    offsets = tiling.offsets
    points, rows = read_rows(scratch, int(offsets[tile]), int(offsets[tile + 1]))
    low, high = tiling.box(tile)
    low, high = low - halo, high + halo
    parts, part_rows = [points], [rows]
    part_positions = [np.arange(int(offsets[tile]), int(offsets[tile + 1]), dtype=np.int64)]
    for other in tiling.overlapping(low, high):
        if other == tile:
            continue
        p, r = read_rows(scratch, int(offsets[other]), int(offsets[other + 1]))
        inside = np.all((p >= low) & (p <= high), axis=1)
        parts.append(p[inside])
        part_rows.append(r[inside])
        part_positions.append(int(offsets[other]) + np.flatnonzero(inside))
    core = np.zeros(sum(len(p) for p in parts), dtype=bool)
    core[: len(points)] = True
    return np.concatenate(parts), np.concatenate(part_rows), core, low, high, np.concatenate(part_positions)


def certificate(points: np.ndarray, support: np.ndarray, box: tuple, halo_box: tuple, cloud: tuple) -> float:
    """The halo a tile's core points need: 0 if every dependency ball lies inside what the tile had.

    Parameters
    ----------
    points : ndarray, shape (c, 3)
        Core points.
    support : ndarray, shape (c,)
        Their support radii; the dependency radius is ``DEPTH x support``.
    box, halo_box, cloud : tuple of ndarray, shape (3,)
        ``(low, high)`` of the core box, the halo box and the cloud's bounding box.

    Returns
    -------
    float
        The largest distance a dependency ball reaches beyond the core box on
        a side where the halo box is inside the cloud (the halo needed), or 0
        when every ball lies inside the halo box.
    """
    reach = compute.DEPTH * np.asarray(support, dtype=float)[:, None]
    low, high = box
    open_low = halo_box[0] > cloud[0]  # sides where points beyond the halo box exist
    open_high = halo_box[1] < cloud[1]
    beyond = np.concatenate([
        np.where(open_low, reach - (points - low), -np.inf), np.where(open_high, reach - (high - points), -np.inf)
    ], axis=1)
    need = float(np.max(beyond, initial=-np.inf)) if len(points) else -np.inf
    halo = float(np.min(np.concatenate([low - halo_box[0], halo_box[1] - high])))
    return need if need > halo else 0.0


def _fault(tile: int) -> None:
    """The tests' fault-injection hook (see :data:`FAULT_VARIABLE`)."""
    fault = os.environ.get(FAULT_VARIABLE)
    if not fault:
        return
    parts = fault.split(":", 2)
    if int(parts[1]) != tile:
        return
    if parts[0] == "fail":
        raise RuntimeError(f"injected failure in tile {tile}")
    if parts[0] == "interrupt":
        raise KeyboardInterrupt
    if parts[0] == "kill" and not os.path.exists(parts[2]):
        open(parts[2], "w").close()
        os._exit(17)


def _peak_bytes() -> int:
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


#: The advice of a survey's failed certificate (a tile's own says a smaller tile: its halo grew too wide).
LARGER_TILES = "; pass a larger tile size or report this"


def _certified(scratch, tiling, tile: int, halo: float, cloud, evaluate, what: str, advice: str):
    """Read a tile with a halo, evaluate it, and widen the halo until the certificate holds.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(points, core, positions, halo_box) -> (result, centres, reach)``:
        given what :func:`tile_points` read, the tile's
        result, and the positions (shape (c, 3)) and radii (shape (c,)) whose
        balls must lie inside what was read (:func:`certificate`).
    what, advice : str
        The failure message's subject and its closing advice.

    Returns
    -------
    tuple
        ``(result, points, rows, core, halo, widened)`` of the certified read.

    Raises
    ------
    HeatcurvError
        After :data:`WIDENINGS` widenings (each to the certificate's need
        times :data:`.compute.HALO_MARGIN`).
    """
    for widened in range(WIDENINGS + 1):
        points, rows, core, low, high, positions = tile_points(scratch, tiling, tile, halo)
        result, centres, reach = evaluate(points, core, positions, (low, high))
        need = certificate(centres, reach, tiling.box(tile), (low, high), cloud)
        if need == 0.0:
            return result, points, rows, core, halo, widened
        if widened == WIDENINGS:
            raise HeatcurvError(
                f"{what}: the certificate failed after {WIDENINGS} widenings of the halo (last {halo:.6g}, "
                f"needed {need:.6g}){advice}"
            )
        halo = need * compute.HALO_MARGIN


@functools.cache
def _libc_malloc_trim():
    """glibc's ``malloc_trim``, loaded once per process; None where there is no glibc."""
    try:
        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


def _malloc_trim() -> None:
    """Hand the memory this process freed back to the system (glibc's ``malloc_trim``; nothing elsewhere)."""
    trim = _libc_malloc_trim()
    if trim is not None:
        trim(0)


def _releases_memory(task):
    """Run ``task(spec)`` and then :func:`_malloc_trim`: a worker holds between tasks only what it keeps.

    The workers run glibc's adaptive ``malloc`` (:func:`.executors.open_executor`), which keeps freed
    memory for the next allocation; a Dask worker whose resident memory stayed above its pause
    threshold (80 % of its limit) after a task would take no other.
    """

    @functools.wraps(task)
    def run(spec):
        try:
            return task(spec)
        finally:
            _malloc_trim()

    return run


def warm_up() -> None:
    """Nothing: a new worker process imports this module (and heatcurv) to run it (:func:`.job.warm_workers`)."""


@_releases_memory
def run_survey(spec: SurveyTask):
    """Survey one tile: fit the candidate kernels at its sample centres (:func:`.compute.survey_tile`).

    The tile's core and a halo as wide as the widest candidate's ball
    (``spec.halo``, the plan's; else :func:`.compute.survey_halo`); the
    certificate checks every centre's reach and widens the halo as
    :func:`run_tile` does.
    """
    scratch, tile, stats, options = spec.scratch, spec.tile, spec.stats, spec.options
    plan = load_plan(scratch)
    tiling = Tiling.from_json(plan["tiling"])
    cloud = (np.asarray(plan["stats"]["low"]), np.asarray(plan["stats"]["high"]))
    offsets = tiling.offsets
    core_points, _ = read_rows(scratch, int(offsets[tile]), int(offsets[tile + 1]))
    # the driver's (the plan budgets the survey's workers with it); the same function of the same core
    halo = float(spec.halo) if spec.halo is not None else compute.survey_halo(core_points, stats, options)

    def survey(points, core, positions, halo_box):
        def keep(op, outliers):  # what the tile phase reads instead of computing it again
            lists = core_lists(op.prepared, op.neighbourhood, core, positions, halo_box, cloud)
            if lists is not None and op.area_solve.solver == "density":
                write_values(scratch, tile, core_values(op.prepared, op.areas, outliers, core, lists))
            write_lists(scratch, tile, lists)
            if lists is not None:  # and the halo's, for the surveys of the tiles not surveyed yet
                write_halo_lists(scratch, tile, halo_lists(scratch, offsets, op.prepared, op.neighbourhood, core,
                                                           positions, halo_box, cloud))

        # the halo's neighbourhoods where the surveys of the tiles holding it have written them already
        knn = known_neighbours(scratch, offsets, positions)
        part = compute.survey_tile(points, core, stats, options, keep, spec.bounded, knn)
        centres, reach = compute.survey_reach(part, stats)
        return part, centres, reach / compute.DEPTH

    return _certified(scratch, tiling, tile, halo, cloud, survey, f"survey of tile {tile}", LARGER_TILES)[0]


@_releases_memory
def run_keys(spec: KeysTask):
    """Round 1 of the survey on one tile: its core's sampling keys and candidate centres (:func:`.compute.key_tile`).

    The tile's core and a halo of about one operator ball (``spec.halo``);
    the certificate checks every core point's ball (its key reads no farther)
    and widens the halo as :func:`run_tile` does.

    Returns
    -------
    heatcurv.choice.survey.KeySurvey
    """
    scratch, tile, stats, options = spec.scratch, spec.tile, spec.stats, spec.options
    plan = load_plan(scratch)
    tiling = Tiling.from_json(plan["tiling"])
    cloud = (np.asarray(plan["stats"]["low"]), np.asarray(plan["stats"]["high"]))
    halo = float(spec.halo)

    def keys(points, core, positions, halo_box):
        part, reach, (prepared, nbhd) = compute.key_tile(points, core, stats, options)
        # the core's neighbourhoods, which the tile phase reads instead of querying them again
        write_lists(scratch, tile, core_lists(prepared, nbhd, core, positions, halo_box, cloud))
        return part, points[core], reach / compute.DEPTH

    return _certified(scratch, tiling, tile, halo, cloud, keys, f"keys of tile {tile}", LARGER_TILES)[0]


@_releases_memory
def run_centres(spec: CentresTask):
    """Round 2 of the survey on one tile: the candidates' fits at its centres of the cloud's sample.

    Reads the tile with a halo holding every centre's guessed reach
    (:func:`.compute.centre_reach`), keeps the points within each centre's
    reach and fits there (:func:`.compute.fit_tile_centres`). The certificate:
    each centre's measured reach (its widest ball plus two operator balls)
    within its guess (the tile reads the largest guess around its box, so
    every guessed ball lies inside), and more points kept than the widest
    candidate holds; else the guess of the centres that failed is widened and
    they alone are fitted again, at most :data:`WIDENINGS` times.

    Returns
    -------
    list of heatcurv.choice.survey.CentreFitsPart
        The centres fitted at the first try, then those fitted again (a
        centre's fits do not depend on the others').
    """
    scratch, tile, stats, options = spec.scratch, spec.tile, spec.stats, spec.options
    centres_plan, places = spec.plan, np.asarray(spec.places, dtype=np.int64)
    levels = spec.levels  # the noise gate's candidates only (heatcurv.choice.survey.GATE_LEVELS), or all
    tiling = Tiling.from_json(load_plan(scratch)["tiling"])
    frame = compute.cloud_frame(stats)
    centres = centres_plan.positions[places] * frame.unit + frame.offset
    guess = compute.centre_reach(centres_plan, places, stats, options, levels)
    done = []
    for widened in range(WIDENINGS + 1):
        # the centres are core points and the halo the largest guess: every guessed ball lies in the box read
        points, _, _, _, _, positions = tile_points(scratch, tiling, tile, float(guess.max()))
        keep = np.flatnonzero(_within(points, centres, guess, int(options.get("workers", 1))))
        if keep.size > int(centres_plan.widths(places, levels).max()):
            # the neighbourhoods round 1 queried (heatcurv.tiles.neighbours)
            knn = known_neighbours(scratch, tiling.offsets, positions[keep])
            part, reach, _ = compute.fit_tile_centres(points[keep], stats, options, centres_plan, places, levels, knn)
            ok = reach <= guess
            done.append(part.take(ok))
            if ok.all():
                return done
            # only the centres whose reach passed their guess are fitted again, with a wider one
            places, centres, guess = places[~ok], centres[~ok], np.maximum(guess[~ok], reach[~ok] * compute.HALO_MARGIN)
        else:  # fewer points than the widest kernel holds: a fit would take them all
            guess = guess * 2.0
        if widened == WIDENINGS:
            raise HeatcurvError(
                f"survey of tile {tile}: the centres' certificate failed after {WIDENINGS} widenings (widest reach "
                f"{float(guess.max()):.6g}); pass a larger tile size or report this"
            )


def _within(points: np.ndarray, centres: np.ndarray, radius: np.ndarray, workers: int = 1) -> np.ndarray:
    """Whether each point lies within ``radius`` of some centre, shape (m,).

    One tree over the points and a ball query per centre: the work is the
    balls' points, not every point against every centre (a tile's gate round
    keeps a few thousand points of a tile and halo of hundreds of thousands).
    """
    from scipy.spatial import cKDTree

    out = np.zeros(len(points), dtype=bool)
    if len(centres):
        balls = cKDTree(points).query_ball_point(centres, radius, workers=workers)
        out[np.concatenate([np.asarray(b, dtype=np.int64) for b in balls])] = True
    return out


@_releases_memory
def run_tile(spec: TileTask) -> dict:
    """Compute one tile, check its certificate (widening the halo if needed) and write its result file.

    Returns
    -------
    dict
        ``tile``, ``points`` (core), ``halo_points``, ``halo`` (width used),
        ``widened`` (times), ``seconds``, ``peak`` (the worker process's peak memory, bytes).
    """
    tic = time.perf_counter()
    scratch, tile, context, options = spec.scratch, spec.tile, spec.context, spec.options
    _fault(tile)
    plan = load_plan(scratch)
    tiling = Tiling.from_json(plan["tiling"])
    cloud = (np.asarray(plan["stats"]["low"]), np.asarray(plan["stats"]["high"]))
    halo = float(context.halo if spec.halo is None else spec.halo)

    def tile_values(points, core, positions, _):
        knn = known_neighbours(scratch, tiling.offsets, positions)
        out = compute.compute_tile(points, core, context, options, knn)
        return out, points[core], out["support"]

    out, points, rows, core, halo, widened = _certified(
        scratch, tiling, tile, halo, cloud, tile_values, f"tile {tile}",
        ": some point's values depend on points farther than the halo; pass a smaller tile size or report this",
    )
    c = int(core.sum())
    patch = np.asarray(out["patch"], dtype=np.int64)
    arrays = {name: np.asarray(out[name]) for name in compute.RESULT_FIELDS}
    # the winding step's patches (each within one seam piece) and sources, and the pieces' outward votes, which
    # the driver sums per object (heatcurv.tiles.winding, heatcurv.tiles.orient)
    if compute.orients_outward(options, context.choices):
        winding = None if out["winding"] is None else {k: v[core] for k, v in out["winding"].items()}
        arrays.update(tile_sources(context.choices.frame, points[core], rows[core], patch[core], arrays, winding))
    else:
        arrays["winding"] = arrays["winding_fine"] = np.zeros(c, dtype=np.int64)
        arrays["vote_weight"], arrays["vote_normal"] = np.zeros(c), np.zeros((c, 3), dtype=np.float32)
        arrays["moment_labels"] = np.unique(patch[core])
        arrays["moments"] = np.zeros((len(arrays["moment_labels"]), len(MOMENTS)))
    # the second-sheet pairs the driver settles (heatcurv.tiles.sheets), input rows
    sheet_rows, sheet_columns = out.get("sheet_pairs") or (np.zeros(0, np.int64), np.zeros(0, np.int64))
    arrays["sheet_rows"], arrays["sheet_columns"] = rows[sheet_rows], rows[sheet_columns]
    path = tile_path(scratch, tile)
    temporary = f"{path}.{os.getpid()}.tmp.npz"
    try:
        np.savez(temporary, rows=rows[core], patch=patch[core],
                 halo_rows=rows[~core], halo_normals=np.asarray(out["halo_normals"]), halo_patch=patch[~core],
                 **arrays)
        os.replace(temporary, path)
    except BaseException:
        if os.path.exists(temporary):
            os.unlink(temporary)
        raise
    return {
        "tile": tile, "points": c, "halo_points": int(len(points) - c), "halo": halo, "widened": widened,
        "seconds": time.perf_counter() - tic, "peak": _peak_bytes(),
    }
