"""The plan of a tiled run: streaming statistics, the tiles, the memory budget, the scratch files.

Tiling
------
One streaming pass gives the :class:`CloudStats` (count, bounding box,
centroid), a second the histogram of the points over a fine grid of the
bounding box (at most :data:`FINE_CELLS` cells, at most 256 along an axis).
The tiles are boxes of whole fine cells found by a k-d split of that
histogram: a box holding more than ``tile_size`` points is cut across its
longest side where the count is halved, so tiles hold about the same number
of points whatever the density. A third pass scatters each point's float64
coordinates and its row number into two scratch files, tile after tile (a
counting sort, SCALE.md decision 3), so that a tile's core is one contiguous
slice ``[start, stop)`` of them; within a tile the points keep the input order.

Halos are not stored: a tile reads the slices of the tiles whose boxes meet
its box widened by the halo and keeps the points inside it. So a tile whose
certificate fails can widen its halo without re-tiling, and the scratch holds
each point once (24 + 8 bytes), whatever the halo.

Memory
------
The estimator needs about :data:`BYTES_PER_POINT` bytes per point (measured,
see docs/tiles.md) plus a fixed :data:`WORKER_OVERHEAD` per process. The budget
(``max_memory``) is for the whole run, the driver (:data:`DRIVER_MEMORY`) and
all workers together; by default :data:`BUDGET_FRACTION` of the memory
available (``MemAvailable`` of ``/proc/meminfo``; elsewhere psutil if
installed, else the free pages).

A worker holds its tile's core *and halo* points, and the two parallel phases
read different halos: the survey's is as wide as the widest candidate kernel's
ball (:func:`heatcurv.tiles.compute.survey_halo`, one per tile, stored in the
plan), the tiles' is the one the survey's choices need. Each phase runs as
many tiles at once as the budget holds with *its* halo
(:func:`halo_points`, :func:`fitting_workers`).

Fitting the budget
------------------
The plan fits the budget by itself (:func:`phase_workers`), for each phase
with the largest tile's core + halo points ``p``:

1. ``w`` worker processes (threads, Dask workers), the most of the requested
   that fit: ``DRIVER_MEMORY + w x (WORKER_OVERHEAD + BYTES_PER_POINT x p)``;
2. else one tile at a time in the driver's own process (local schedulers
   only), which has the interpreter and the libraries loaded already:
   ``DRIVER_MEMORY + BYTES_PER_POINT x p`` (:func:`in_process_memory`);
3. else, unless the tile size was given, smaller tiles: the driver tiles
   again (two more passes over the input) at a smaller tile size, down to
   :data:`MIN_TILE_SIZE` core points.

It refuses only when one tile of :data:`MIN_TILE_SIZE` core points (or of the
given tile size) with its halo does not fit in the driver's process (with a
Dask scheduler: beside the driver, in one worker process), and the message
names that minimum budget (:func:`budget_refusal`). The survey's halo is the
widest candidate's ball whatever the tile, so a cloud's minimum is about the
driver plus the points within that ball of a small tile. Whatever the cloud, no budget below
:func:`smallest_budget` (``DRIVER_MEMORY + BYTES_PER_POINT x MIN_TILE_SIZE``,
630 MB) can hold a tiled run: it is refused before the file is read.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from dataclasses import asdict, dataclass

import numpy as np

from ..choice.choices import FrameStats
from ..errors import HeatcurvError
from .sources import Source

__all__ = [
    "CloudStats", "Tiling", "BYTES_PER_POINT", "WORKER_OVERHEAD", "BUDGET_FRACTION", "FINE_CELLS",
    "available_memory", "default_budget", "parse_size", "size_text", "scan_stats", "make_tiling", "scatter",
    "options_hash", "check_disk", "read_rows", "in_memory_bytes", "DRIVER_MEMORY", "halo_points",
    "fitting_workers", "worker_memory", "MIN_TILE_SIZE", "PhaseWorkers", "phase_workers", "in_process_memory",
    "smallest_budget", "check_smallest_budget", "budget_refusal", "fit_tiles", "TilePlan",
]

#: Estimator memory per point of a tile (core + halo), bytes: measured 1.18 kB per point at 1M points of
#: a torus (1.3 kB at 0.4M), above the process's own.
BYTES_PER_POINT = 1300
#: Memory of a worker process before it computes anything (interpreter, numpy, numba, heatcurv), bytes.
WORKER_OVERHEAD = 400 * 2**20
#: Memory the driver keeps for itself out of the budget (chunks of the streaming passes, a window of
#: ``results.rec``, the final write), bytes.
DRIVER_MEMORY = 600 * 2**20
#: The default budget: this share of the memory available when the run starts.
BUDGET_FRACTION = 0.6
#: The smallest tile the plan shrinks to, core points (the command line's least ``--tile-size``).
MIN_TILE_SIZE = 1000
#: Cells of the fine histogram grid the tiles are made of.
FINE_CELLS = 1 << 21


@dataclass(frozen=True)
class CloudStats:
    """Streaming statistics of the whole cloud, one pass.

    Attributes
    ----------
    count : int
        Rows of the file.
    finite : int
        Rows with finite coordinates (the others are not computed).
    low, high : tuple of float, length 3
        Bounding box of the finite points.
    centroid : tuple of float, length 3
        Their mean.
    rms_radius : float
        Root-mean-square distance of the finite points from ``centroid`` (with
        the centroid: the sampling keys' frame, :class:`heatcurv.choice.choices.CloudFrame`).
    distinct : int
        Distinct points (0 until :func:`distinct_frame` has counted them; then
        ``centroid`` and ``rms_radius`` are those of the distinct points, as in
        memory).
    """

    count: int
    finite: int
    low: tuple
    high: tuple
    centroid: tuple
    rms_radius: float = float("nan")
    distinct: int = 0

    @property
    def diagonal(self) -> float:
        """Length of the bounding box's diagonal."""
        return float(np.linalg.norm(np.subtract(self.high, self.low)))


def available_memory() -> int:
    """Bytes of memory available now (Linux ``MemAvailable``; psutil or free pages elsewhere)."""
    try:
        with open("/proc/meminfo") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except ImportError:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))


def default_budget(points: int | None = None) -> int:
    """The default ``max_memory``: :data:`BUDGET_FRACTION` of :func:`available_memory`, at least a small cloud's need.

    Parameters
    ----------
    points : int, optional
        Points of the cloud a tiled run is planned for. When given, the budget
        is at least what one tile of ``min(points, 10 x MIN_TILE_SIZE)`` points
        needs in the driver's process (:func:`in_process_memory`; the whole
        cloud, for a small one), as long as that much memory is available: a
        small cloud is not refused because the share of a busy machine's free
        memory is below the model's fixed reservations.
    """
    available = available_memory()
    budget = int(BUDGET_FRACTION * available)
    if points is not None:
        budget = max(budget, min(available, in_process_memory(min(int(points), 10 * MIN_TILE_SIZE))))
    return budget


_UNITS = {"": 1, "B": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def parse_size(value) -> int:
    """``"3G"``, ``"500M"``, ``"1.5 GB"``, ``"2GiB"`` or a byte count -> bytes (binary units)."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        size = int(value)
    else:
        match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([KMGT]?)(I?B)?\s*", str(value).upper())
        if match is None:
            raise HeatcurvError(f"expected a memory size such as 3G, 500M or 2000000000, got {value!r}")
        size = int(float(match[1]) * _UNITS[match[2]])
    if size <= 0:
        raise HeatcurvError(f"a memory size must be positive, got {value!r}")
    return size


def size_text(nbytes: float) -> str:
    """Bytes in plain words: ``1.5 GB``, ``300 MB``."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{int(nbytes)} bytes"


def scan_stats(source: Source, skip_nonfinite: bool = False) -> CloudStats:
    """One streaming pass: count, bounding box and centroid of the finite points.

    Raises
    ------
    HeatcurvError
        On non-finite coordinates unless ``skip_nonfinite``, and on fewer than
        two finite points.
    """
    # the moments as heatcurv.choice.choices.FrameStats sums them (about the first row: UTM coordinates
    # keep their precision), so the tiles' frame is the in-memory one to rounding
    frame = FrameStats()
    count, bad = 0, []
    for start, points, _ in source.chunks():
        ok = np.isfinite(points).all(axis=1)
        count += len(points)
        if not ok.all():
            if not skip_nonfinite:
                rows = start + np.flatnonzero(~ok)[:5]
                raise HeatcurvError(
                    f"{source.path}: points have NaN or infinite coordinates (rows {', '.join(map(str, rows))}, "
                    "counted from 0); remove them or pass --skip-nonfinite"
                )
            bad.append(int((~ok).sum()))
            points = points[ok]
        frame.add(points)
    if frame.n < 2:
        raise HeatcurvError(f"{source.path}: fewer than two points with finite coordinates")
    whole = frame.frame()
    centroid = whole.centroid * whole.unit + whole.offset
    return CloudStats(count, frame.n, tuple(frame.low.tolist()), tuple(frame.high.tolist()), tuple(centroid.tolist()),
                      whole.rms_radius * whole.unit)


@dataclass(frozen=True)
class Tiling:
    """Tiles as boxes of a fine grid, and where each tile's core lies in the scratch files.

    Attributes
    ----------
    origin : tuple of float, length 3
        Corner of the fine grid (the bounding box's low corner).
    cell : tuple of float, length 3
        Size of a fine cell along each axis.
    shape : tuple of int, length 3
        Fine cells along each axis.
    cells : list of tuple
        Each tile's cell-index box ``(i0, j0, k0, i1, j1, k1)`` (upper bounds excluded).
    counts : list of int
        Core points of each tile.
    """

    origin: tuple
    cell: tuple
    shape: tuple
    cells: list
    counts: list

    @property
    def offsets(self) -> np.ndarray:
        """Start of each tile's slice in the scratch files, shape (T + 1,)."""
        return np.concatenate([[0], np.cumsum(self.counts, dtype=np.int64)])

    def box(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """Tile ``t``'s core box ``(low, high)`` in input coordinates, shape (3,) each."""
        c = np.asarray(self.cells[t], dtype=float)
        origin, cell = np.asarray(self.origin), np.asarray(self.cell)
        return origin + c[:3] * cell, origin + c[3:] * cell

    def cell_of(self, points: np.ndarray) -> np.ndarray:
        """Fine-cell number of each point, shape (k,) int64 (points outside: the nearest cell)."""
        idx = np.floor((points - np.asarray(self.origin)) / np.asarray(self.cell)).astype(np.int64)
        np.clip(idx, 0, np.asarray(self.shape) - 1, out=idx)
        return np.ravel_multi_index(idx.T, self.shape)

    def lookup(self) -> np.ndarray:
        """Tile number of every fine cell, shape (prod(shape),) int32."""
        table = np.full(self.shape, -1, dtype=np.int32)
        for t, (i0, j0, k0, i1, j1, k1) in enumerate(self.cells):
            table[i0:i1, j0:j1, k0:k1] = t
        return table.ravel()

    def overlapping(self, low: np.ndarray, high: np.ndarray) -> list[int]:
        """Tiles whose core boxes meet the box ``[low, high]``."""
        out = []
        for t in range(len(self.cells)):
            a, b = self.box(t)
            if np.all(a <= high) and np.all(b >= low):
                out.append(t)
        return out

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> Tiling:
        return cls(tuple(data["origin"]), tuple(data["cell"]), tuple(data["shape"]),
                   [tuple(c) for c in data["cells"]], list(data["counts"]))


@dataclass(frozen=True)
class TilePlan:
    """The plan of a tiled run, as ``plan.json`` holds it: what a resumed run needs before the survey.

    Attributes
    ----------
    identity : dict
        What a resumed run must match: the plan's and heatcurv's versions, the
        source file (path, size, modification time), the options' hash, and
        the tile size if one was given.
    tiling : Tiling
    stats : CloudStats
        With the distinct points' frame (:func:`distinct_frame`).
    tile_size : int
        Core points a tile was to hold at most (the plan's, after
        :func:`fit_tiles`).
    survey_halos, key_halos : tuple of float
        Each tile's survey halo and keys' halo (:func:`heatcurv.tiles.compute.survey_halo`,
        :func:`heatcurv.tiles.compute.key_halo`), input units.
    """

    identity: dict
    tiling: Tiling
    stats: CloudStats
    tile_size: int
    survey_halos: tuple
    key_halos: tuple

    def to_json(self) -> dict:
        """The plan as ``plan.json`` holds it (read by the tasks: :func:`heatcurv.tiles.tasks.load_plan`)."""
        return {"identity": self.identity, "tiling": self.tiling.to_json(), "stats": asdict(self.stats),
                "tile_size": int(self.tile_size), "survey_halos": list(self.survey_halos),
                "key_halos": list(self.key_halos)}

    @classmethod
    def from_json(cls, data: dict) -> TilePlan:
        stats = CloudStats(**{k: tuple(v) if isinstance(v, list) else v for k, v in data["stats"].items()})
        return cls(data["identity"], Tiling.from_json(data["tiling"]), stats, int(data["tile_size"]),
                   tuple(data["survey_halos"]), tuple(data["key_halos"]))


def _fine_grid(stats: CloudStats):
    extent = np.maximum(np.subtract(stats.high, stats.low), 0.0)
    longest = float(extent.max()) or 1.0
    # cubic cells: at most 256 along the longest side and FINE_CELLS in all
    side = max(longest / 256, float(np.prod(np.maximum(extent, longest * 1e-9)) / FINE_CELLS) ** (1 / 3))
    shape = np.maximum(1, np.ceil(extent / side)).astype(int)
    while shape.prod() > FINE_CELLS:
        side *= 1.1
        shape = np.maximum(1, np.ceil(extent / side)).astype(int)
    cell = np.where(extent > 0, extent / shape, 1.0) * (1 + 1e-12)
    return np.asarray(stats.low), cell, tuple(int(s) for s in shape)


def make_tiling(source: Source, stats: CloudStats, tile_size: int) -> Tiling:
    """The second pass: a histogram over the fine grid, cut into tiles of at most ``tile_size`` points.

    A box is cut across its longest side (in length units) at the cell boundary
    nearest half its count; a single cell holding more than ``tile_size`` points
    stays one tile (the memory check says whether it fits).
    """
    origin, cell, shape = _fine_grid(stats)
    hist = np.zeros(int(np.prod(shape)), dtype=np.int64)
    grid = Tiling(tuple(origin.tolist()), tuple(cell.tolist()), shape, [], [])
    for _, points, _ in source.chunks():
        points = points[np.isfinite(points).all(axis=1)]
        hist += np.bincount(grid.cell_of(points), minlength=hist.size)
    hist = hist.reshape(shape)
    boxes, counts, stack = [], [], [(0, 0, 0) + shape]
    while stack:
        box = stack.pop()
        sub = hist[box[0]:box[3], box[1]:box[4], box[2]:box[5]]
        total = int(sub.sum())
        if total == 0:
            continue
        sizes = np.array(box[3:]) - np.array(box[:3])
        if total <= tile_size or sizes.max() == 1:
            boxes.append(box)
            counts.append(total)
            continue
        lengths = np.where(sizes > 1, sizes * cell, -1.0)
        axis = int(np.argmax(lengths))
        profile = np.cumsum(sub.sum(axis=tuple(a for a in range(3) if a != axis)))
        cut = int(np.clip(np.searchsorted(profile, total / 2), 0, sizes[axis] - 2)) + 1
        low, high = list(box), list(box)
        high[3 + axis] = low[axis] = box[axis] + cut
        stack += [tuple(high), tuple(low)]
    order = sorted(range(len(boxes)), key=lambda t: boxes[t])  # a deterministic, spatially coherent order
    return Tiling(grid.origin, grid.cell, shape, [boxes[t] for t in order], [counts[t] for t in order])


def scatter(source: Source, tiling: Tiling, directory) -> None:
    """The third pass: coordinates and row numbers into ``points.f8`` and ``rows.i8``, tile after tile.

    Files: ``points.f8`` (N, 3) float64 and ``rows.i8`` (N,) int64, N the finite
    points, written with positioned writes (no memory map grows the process).
    """
    lookup = tiling.lookup()
    cursor = tiling.offsets[:-1].copy()
    points_path, rows_path = os.path.join(directory, "points.f8"), os.path.join(directory, "rows.i8")
    with open(points_path, "wb") as pf, open(rows_path, "wb") as rf:
        total = int(tiling.offsets[-1])
        pf.truncate(total * 24)
        rf.truncate(total * 8)
        for start, points, _ in source.chunks():
            rows = start + np.arange(len(points), dtype=np.int64)
            ok = np.isfinite(points).all(axis=1)
            if not ok.all():
                points, rows = points[ok], rows[ok]
            tiles = lookup[tiling.cell_of(points)]
            order = np.argsort(tiles, kind="stable")
            tiles, points, rows = tiles[order], np.ascontiguousarray(points[order]), rows[order]
            bounds = np.flatnonzero(np.diff(tiles)) + 1
            for a, b in zip(np.concatenate([[0], bounds]), np.concatenate([bounds, [len(tiles)]])):
                t = int(tiles[a])
                at = int(cursor[t])
                os.pwrite(pf.fileno(), points[a:b].tobytes(), at * 24)
                os.pwrite(rf.fileno(), rows[a:b].tobytes(), at * 8)
                cursor[t] += b - a
    if not np.array_equal(cursor, tiling.offsets[1:]):
        raise HeatcurvError(f"cannot tile {source.path}: the file changed while it was read (point counts differ)")


def read_rows(directory, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates (k, 3) and row numbers (k,) of scratch slice ``[start, stop)``."""
    k = stop - start
    points = np.fromfile(os.path.join(directory, "points.f8"), dtype=np.float64, count=3 * k, offset=24 * start)
    rows = np.fromfile(os.path.join(directory, "rows.i8"), dtype=np.int64, count=k, offset=8 * start)
    return points.reshape(k, 3), rows


def distinct_frame(directory, tiling, stats: CloudStats) -> CloudStats:
    """``stats`` with the centroid, rms radius and count of the distinct points, tile by tile from the scratch.

    The sampling keys' frame counts exact duplicates once, as in memory
    (:func:`heatcurv.choice.choices.frame_of`); duplicates share a position, so they
    share a tile.
    """
    from dataclasses import replace

    from ..choice.choices import CloudFrame, FrameStats
    from ..geometry.validation import bounding_box_frame

    offset, unit = bounding_box_frame(np.asarray(stats.low), np.asarray(stats.high))
    frame = CloudFrame(offset, unit, stats.finite, np.zeros(3), 1.0)
    moments = FrameStats()
    offsets = tiling.offsets
    for tile in range(len(tiling.counts)):
        points, _ = read_rows(directory, int(offsets[tile]), int(offsets[tile + 1]))
        moments.add_distinct(points, frame)
    whole = moments.frame()
    centroid = whole.centroid * whole.unit + whole.offset
    return replace(stats, centroid=tuple(centroid.tolist()), rms_radius=whole.rms_radius * whole.unit,
                   distinct=moments.n)


def options_hash(options: dict) -> str:
    """A stable hash of the estimator options (and anything else JSON can hold)."""
    text = json.dumps(options, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def check_disk(directory, needed: int, what: str) -> None:
    """Fail before the run if ``directory``'s file system has less than ``needed`` bytes free."""
    free = shutil.disk_usage(directory).free
    if free < needed:
        raise HeatcurvError(
            f"not enough disk space for {what} in {directory}: about {size_text(needed)} needed, "
            f"{size_text(free)} free; choose another directory with --scratch (scratch=...)"
        )


def worker_memory(points: int) -> int:
    """Estimated peak memory of one worker computing a tile of ``points`` points (core + halo), bytes."""
    return WORKER_OVERHEAD + BYTES_PER_POINT * int(points)


def plan_workers(budget: int, requested: int | None, tile_points: int, cpus: int) -> int:
    """How many tiles can be computed at once: the cores asked for, as many as the budget holds."""
    want = cpus if requested in (None, -1) else int(requested)
    fit = budget // worker_memory(tile_points)
    return int(max(0, min(want, fit)))


def in_process_memory(points: int) -> int:
    """Estimated peak memory of a run computing one tile of ``points`` points (core + halo) at a time in the
    driver's process, bytes: :data:`DRIVER_MEMORY` (which holds the interpreter and libraries a worker process
    loads again, :data:`WORKER_OVERHEAD`) plus :data:`BYTES_PER_POINT` per point."""
    return DRIVER_MEMORY + BYTES_PER_POINT * int(points)


def smallest_budget() -> int:
    """The least budget any tiled run can fit: one tile of :data:`MIN_TILE_SIZE` points, no halo, in process."""
    return in_process_memory(MIN_TILE_SIZE)


def check_smallest_budget(budget: int) -> None:
    """Refuse a budget below :func:`smallest_budget`, naming it (in whole MiB, as ``--max-memory`` takes it)."""
    if budget < smallest_budget():
        raise HeatcurvError(
            f"a memory budget of {size_text(budget)} is too small for a tiled run: the driver keeps "
            f"{size_text(DRIVER_MEMORY)} and the smallest tile ({MIN_TILE_SIZE} points, no halo) needs "
            f"{size_text(BYTES_PER_POINT * MIN_TILE_SIZE)}; pass a --max-memory of at least "
            f"{-(-smallest_budget() // 2**20)}M"
        )


@dataclass(frozen=True)
class PhaseWorkers:
    """How a parallel phase runs its tiles within the budget (:func:`phase_workers`).

    Attributes
    ----------
    count : int
        Tiles computed at once.
    in_process : bool
        One tile at a time in the driver's process (no worker process).
    memory : int
        The phase's estimated peak, driver included, bytes.
    """

    count: int
    in_process: bool
    memory: int


def phase_workers(points, budget: int, requested: int, cpus: int, in_process: bool = True) -> PhaseWorkers | None:
    """The most tiles the budget lets a phase run at once; one in the driver's process if no worker fits.

    Parameters
    ----------
    points : array_like of int, shape (T,)
        Core + halo points of each tile in this phase (:func:`halo_points`).
    budget : int
        The whole run's budget, bytes.
    requested, cpus : int
        Tiles asked to run at once (-1 or None: ``cpus``), and the cores.
    in_process : bool
        Whether a tile may run in the driver's process (a local scheduler).

    Returns
    -------
    PhaseWorkers or None
        None when not even one tile fits in the driver's process.
    """
    largest = int(np.max(points)) if len(points) else 0
    fit = plan_workers(max(budget - DRIVER_MEMORY, 0), requested, largest, cpus)
    if fit >= 1:
        return PhaseWorkers(fit, False, DRIVER_MEMORY + fit * worker_memory(largest))
    if in_process and in_process_memory(largest) <= budget:
        return PhaseWorkers(1, True, in_process_memory(largest))
    return None


def budget_refusal(largest: int, budget: int, tile_size: int, phase: str, given: bool, in_process: bool = True
                   ) -> HeatcurvError:
    """The error of a budget that holds no tile of ``largest`` points (core + halo) of the smallest tiling tried.

    It names the budget that would fit that tile (in the driver's process, or
    in one worker process for a Dask scheduler) and, when the tile size was
    given, a smaller one.
    """
    need = in_process_memory(largest) if in_process else DRIVER_MEMORY + worker_memory(largest)
    minimum = -(-need // 2**20) * 2**20  # in whole MiB, as --max-memory takes it
    where = "" if in_process else " and one worker process"
    advice = (f"pass a smaller --tile-size (now {tile_size}) or a --max-memory of at least {minimum // 2**20}M"
              if given else f"the smallest tiles ({tile_size} points) need a --max-memory of at least "
              f"{minimum // 2**20}M")
    return HeatcurvError(
        f"a tile of about {largest} points (core and halo{', the survey' if phase == 'survey' else ''}) needs "
        f"about {size_text(need)} with the driver{where}, more than the budget of {size_text(budget)} leaves for "
        f"one worker; {advice} (the model: the driver {size_text(DRIVER_MEMORY)}, a worker process "
        f"{size_text(WORKER_OVERHEAD)}, {BYTES_PER_POINT} bytes per point of a tile's core and halo)"
    )


def smaller_tile_size(tile_size: int, largest: int, budget: int) -> int:
    """The next tile size to try when a tile of ``largest`` points (core + halo) at ``tile_size`` does not fit
    in the driver's process: at most half, in proportion to what the budget holds, at least :data:`MIN_TILE_SIZE`."""
    holds = max(budget - DRIVER_MEMORY, 0) // BYTES_PER_POINT
    return max(MIN_TILE_SIZE, min(tile_size // 2, int(tile_size * holds / max(largest, 1))))


def fit_tiles(measure, tile_size: int, budget: int, requested: int, cpus: int, *, in_process: bool = True,
              given: bool = False, say=None):
    """Tile the cloud at ``tile_size``, and at smaller sizes while its largest survey tile does not fit the budget.

    Parameters
    ----------
    measure : callable
        ``measure(tile_size) -> (largest, tiled)``: tiles the cloud and returns
        the core + survey-halo points of its largest tile and whatever the
        caller keeps of that tiling (the driver: the tiling, the scratch files,
        the halos).
    tile_size : int
        The first tile size tried (core points).
    budget, requested, cpus, in_process
        As :func:`phase_workers`.
    given : bool
        The tile size was asked for: it is not made smaller.
    say : callable, optional
        Told each time the cloud is tiled again.

    Returns
    -------
    tile_size : int
    tiled
        ``measure``'s second value at that size.
    workers : PhaseWorkers
        How the survey fits.

    Raises
    ------
    HeatcurvError
        When even the smallest tile tried (``tile_size`` if given, else down
        to :data:`MIN_TILE_SIZE`) does not fit in the driver's process; the
        message names the budget it needs (:func:`budget_refusal`).
    """
    tile_size = int(tile_size)
    while True:
        largest, tiled = measure(tile_size)
        fit = phase_workers([largest], budget, requested, cpus, in_process)
        if fit is not None:
            return tile_size, tiled, fit
        if given or tile_size <= MIN_TILE_SIZE:
            raise budget_refusal(largest, budget, tile_size, "survey", given, in_process)
        smaller = smaller_tile_size(tile_size, largest, budget)
        if say is not None:
            say(f"a tile of {tile_size} points with the survey's halo (about {largest} points) does not fit the "
                f"budget of {size_text(budget)}: tiling again at {smaller} points")
        tile_size = smaller


def halo_points(tiling: Tiling, stats: CloudStats, halo) -> np.ndarray:
    """Estimated core + halo points of each tile: its count times the volume its halo box adds (clipped to the cloud).

    Parameters
    ----------
    tiling : Tiling
    stats : CloudStats
        The cloud's bounding box clips each halo box.
    halo : float or array_like, shape (T,)
        Halo width, one for all tiles or one per tile (length units; NaN: none).

    Returns
    -------
    ndarray of int64, shape (T,)
        Points each tile holds with its halo, assuming the density of its core
        box inside the halo box.
    """
    lo_c, hi_c = np.asarray(stats.low, dtype=float), np.asarray(stats.high, dtype=float)
    halos = np.broadcast_to(np.nan_to_num(np.asarray(halo, dtype=float), nan=0.0), (len(tiling.counts),))
    out = np.empty(len(tiling.counts), dtype=np.int64)
    for t, count in enumerate(tiling.counts):
        low, high = tiling.box(t)
        low, high = np.maximum(low, lo_c), np.minimum(high, hi_c)
        side = high - low
        wide = np.minimum(high + halos[t], hi_c) - np.maximum(low - halos[t], lo_c)
        ratio = np.prod(np.where(side > 0, wide / np.where(side > 0, side, 1), 1.0))
        out[t] = int(count * ratio)
    return out


def fitting_workers(points, budget: int, requested: int, cpus: int, tile_size: int, phase: str = "tiles") -> int:
    """Tiles the budget lets run at once when each holds ``points`` (core + halo); an error if not one fits.

    Parameters
    ----------
    points : array_like of int, shape (T,)
        Core + halo points of each tile in this phase (:func:`halo_points`).
    budget : int
        The whole run's budget, bytes; the driver's :data:`DRIVER_MEMORY` is taken off first.
    requested, cpus : int
        Tiles asked to run at once (-1 or None: ``cpus``), and the cores.
    tile_size : int
        The tile size, for the message.
    phase : str
        ``"survey"`` or ``"tiles"``, for the message.

    Returns
    -------
    int
        At least 1: ``min(requested, (budget - DRIVER_MEMORY) // worker_memory(max(points)))``.

    Raises
    ------
    HeatcurvError
        When not even one worker with the largest tile fits.
    """
    largest = int(np.max(points)) if len(points) else 0
    fit = plan_workers(max(budget - DRIVER_MEMORY, 0), requested, largest, cpus)
    if fit < 1:
        raise HeatcurvError(
            f"a tile of about {largest} points (core and halo{', the survey' if phase == 'survey' else ''}) needs "
            f"about {size_text(worker_memory(largest))}, more than the budget of {size_text(budget)} leaves for one "
            f"worker; pass a smaller --tile-size (now {tile_size}) or a larger --max-memory"
        )
    return fit


def default_tile_size(budget: int, workers: int, halo_share: float = 1.0, in_process: bool = False) -> int:
    """Core points per tile: what ``budget / workers`` holds with a halo of ``halo_share`` x the core, at most 2M.

    ``in_process``: one tile at a time in the driver's process, which has no
    :data:`WORKER_OVERHEAD` of its own (``budget`` is what the driver leaves).
    """
    per = budget if in_process else budget / max(workers, 1) - WORKER_OVERHEAD
    return int(max(10_000, min(2_000_000, per / (BYTES_PER_POINT * (1 + halo_share)))))


#: Bytes per point an in-memory ``heatcurv compute`` needs beyond the estimate: the file as read and the written copy.
READ_BYTES_PER_POINT = 200
#: Bytes of a text file per point, to guess a text cloud's size from the file's (a line of x y z and a few fields).
TEXT_BYTES_PER_POINT = 30


def in_memory_bytes(path) -> tuple[int, int]:
    """``(points, bytes)``: the point count (from the header; text: guessed from the size) and the memory an
    in-memory run of the file would need."""
    from pathlib import Path

    from .sources import TILED_READ, open_source

    path = Path(path)
    try:
        if path.suffix.lower() in TILED_READ:
            count = open_source(path).count
        else:
            count = path.stat().st_size // TEXT_BYTES_PER_POINT
    except (HeatcurvError, OSError):
        return 0, 0  # the in-memory reader says what is wrong with the file
    return count, WORKER_OVERHEAD + (BYTES_PER_POINT + READ_BYTES_PER_POINT) * count
