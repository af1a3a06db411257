"""Each point's nearest neighbours, queried once: the survey keeps them for the tile phase.

The ``neighbours`` nearest points of every point (the operator's ball,
:func:`heatcurv.geometry.neighbourhood.knn_neighbourhood`) are the largest
single cost of a tile: a k-d tree query over its core and its halo. The
survey of a tile queries them before (:func:`.tasks.run_survey` for the
operator it builds over the core and a wider halo; in a survey of two rounds,
:func:`.tasks.run_keys` for the keys), so it writes the neighbours of its core
points to ``knn/knn_NNNNN.npy`` (their scratch positions, one row of
``neighbours`` per core point, nearest first); a tile of the tile phase (and
a two-round survey's second round, :func:`.tasks.run_centres`) reads
the rows of its core and halo points from the files of the tiles that hold
them (:func:`known_neighbours`) and queries only the points whose neighbours
are not all among the points it read (the outer rim of its halo) or that no
file holds. A one-round survey reads them too, for its halo's points in the
tiles whose surveys finished before it, and writes the rows it queried for
its halo's points in the tiles not surveyed yet (``knn/halo_NNNNN.npy``,
:func:`halo_lists`), which those tiles' surveys read for their own cores (the
rest they query: what a survey finds depends on the order the tiles ran in,
what it computes does not; tiles surveyed at once run apart,
:func:`heatcurv.tiles.phase_survey.survey_order`).

A point's ``k`` nearest within the points a tile read are its ``k`` nearest in
the whole cloud when the whole cloud's are all among them, so a row read back
is the row the tile would query (up to the order of points tied at one
distance, which the operator's kernels weigh alike; the distances are
recomputed from the coordinates, as the k-d tree computes them). A survey
writes a core point's row only when its ball lies inside what the survey read
(or reaches past it only across the cloud's bounding box), else ``-1``.

A survey in one round also writes what its operator computed from those
lists at its core points (``knn/values_NNNNN.npy``, :func:`core_values`): each
one's density area (a function of its own list) and outlier flags (its
survey's halo holds every ball a flag reads). A tile whose points all have
them reads them (:meth:`StoredNeighbours.areas`,
:meth:`StoredNeighbours.outliers`) instead of computing them over its core and
halo again.
"""

from __future__ import annotations

import os

import numpy as np

from .._kernels.neighbours import stored_neighbours
from ..flags.outliers import Outliers
from ..geometry.neighbourhood import Neighbourhood, _index_dtype, block_ranges, knn_neighbourhood, rows_per_block
from ..geometry.validation import PreparedPoints

__all__ = ["core_lists", "core_values", "halo_lists", "write_lists", "write_values", "write_halo_lists",
           "remove_halo_lists", "known_neighbours", "StoredNeighbours", "lists_path", "values_path", "halo_path",
           "list_bytes", "VALUES"]

#: What a one-round survey stores per core point besides its list: its density area (the operator's units) and
#: its outlier flags as bits (:data:`OUTLIER_BITS`)
VALUES = np.dtype([("area", np.float64), ("outlier", np.uint8)])
#: The bit of each of :class:`heatcurv.flags.outliers.Outliers`' masks in ``VALUES["outlier"]``
OUTLIER_BITS = {"mask": 1, "detached": 2, "isolated": 4, "sparse": 8}


def list_bytes(points: int, neighbours: int) -> int:
    """Bytes of the neighbour files of ``points`` points (int32 positions where they fit, else int64), with
    their :data:`VALUES`."""
    return int(points) * (int(neighbours) * (4 if int(points) < np.iinfo(np.int32).max else 8) + VALUES.itemsize)


def _position_dtype(positions: np.ndarray):
    """int32 for scratch positions that fit, else int64 (as :func:`list_bytes`)."""
    return np.int32 if int(positions.max(initial=0)) < np.iinfo(np.int32).max else np.int64


def lists_path(scratch, tile: int) -> str:
    """The neighbour file of tile ``tile``'s core points."""
    return os.path.join(scratch, "knn", f"knn_{tile:05d}.npy")


def values_path(scratch, tile: int) -> str:
    """The file of tile ``tile``'s core points' :data:`VALUES`."""
    return os.path.join(scratch, "knn", f"values_{tile:05d}.npy")


def halo_path(scratch, tile: int) -> str:
    """The file of the lists tile ``tile``'s survey queried for its halo points (:func:`halo_lists`)."""
    return os.path.join(scratch, "knn", f"halo_{tile:05d}.npy")


def core_lists(prepared: PreparedPoints, nbhd: Neighbourhood, core: np.ndarray, positions: np.ndarray,
               halo_box: tuple, cloud: tuple) -> np.ndarray | None:
    """The scratch positions of each core point's nearest neighbours, from a query over a tile.

    The same for any rows of the tile (``core`` a mask of them): a survey
    stores its halo's too (:func:`halo_lists`).

    Parameters
    ----------
    prepared : PreparedPoints
        The distinct points of the tile's core and halo (the operator's).
    nbhd : Neighbourhood
        Their neighbourhood: each one's ``k`` nearest (the operator's with
        ``spacing="density"``, the default).
    core : ndarray, shape (m,), bool
        The tile's own rows (the first ones).
    positions : ndarray, shape (m,), int64
        Each row's position in the scratch files.
    halo_box, cloud : tuple of ndarray, shape (3,)
        ``(low, high)`` of the box read and of the cloud's bounding box, input units.

    Returns
    -------
    ndarray, shape (c, k), or None
        Row ``i``: the positions of core point ``i``'s ``k`` nearest, nearest
        first; ``-1`` where its ball is not certainly inside what was read.
        None when the neighbourhood is not a ``k``-nearest one (other options).
    """
    if not nbhd.by_distance or nbhd.n_points == 0:
        return None
    k = int(nbhd.counts[0])
    if k == 0 or not np.all(nbhd.counts == k):
        return None
    distinct = prepared.inverse[np.flatnonzero(core)]
    dtype = _position_dtype(positions)
    lists = np.empty((distinct.size, k), dtype=dtype)
    rows = nbhd.indices.reshape(-1, k)
    scratch_position = positions[prepared.first].astype(dtype)  # of each distinct point
    low, high = halo_box
    open_low, open_high = low > cloud[0], high < cloud[1]
    for lo, hi in block_ranges(distinct.size, rows_per_block(k)):  # a block at a time: the temporaries are int64
        mine = distinct[lo:hi]
        lists[lo:hi] = scratch_position[rows[mine]]
        # a ball reaching past the box read may miss a nearer point beyond it
        points = prepared.points[mine] * prepared.unit + prepared.offset
        radius = (nbhd.radius[mine] * prepared.unit)[:, None]
        inside = np.all(~open_low | (points - radius > low), axis=1)
        inside &= np.all(~open_high | (points + radius < high), axis=1)
        lists[lo + np.flatnonzero(~inside)] = -1
    return lists


def core_values(prepared: PreparedPoints, areas: np.ndarray, outliers, core: np.ndarray,
                lists: np.ndarray) -> np.ndarray:
    """Each core point's density area and outlier flags, as a tile would compute them.

    Parameters
    ----------
    prepared : PreparedPoints
        The distinct points of the tile's core and halo (the operator's).
    areas : ndarray, shape (n,)
        The operator's density areas of the distinct points.
    outliers : heatcurv.flags.outliers.Outliers
        Of the distinct points.
    core : ndarray, shape (m,), bool
        The tile's own rows.
    lists : ndarray, shape (c, k)
        Their :func:`core_lists`.

    Returns
    -------
    ndarray, shape (c,), dtype :data:`VALUES`
        ``area`` NaN where the list is not stored (:func:`core_lists`): its ball may reach past what was read.
    """
    distinct = prepared.inverse[np.flatnonzero(core)]
    values = np.empty(distinct.size, dtype=VALUES)
    values["area"] = np.where(lists[:, 0] >= 0, areas[distinct], np.nan)
    bits = np.zeros(distinct.size, dtype=np.uint8)
    for name, bit in OUTLIER_BITS.items():
        bits |= np.where(getattr(outliers, name)[distinct], bit, 0).astype(np.uint8)
    values["outlier"] = bits
    return values


def _write(path: str, array: np.ndarray) -> None:
    """``np.save`` atomically."""
    os.makedirs(os.path.dirname(path), exist_ok=True)
    temporary = f"{path}.{os.getpid()}.tmp.npy"
    try:
        np.save(temporary, array)
        os.replace(temporary, path)
    except BaseException:
        if os.path.exists(temporary):
            os.unlink(temporary)
        raise


def write_lists(scratch, tile: int, lists: np.ndarray | None) -> None:
    """Write a tile's :func:`core_lists` atomically (nothing when None)."""
    if lists is not None:
        _write(lists_path(scratch, tile), lists)


def write_values(scratch, tile: int, values: np.ndarray) -> None:
    """Write a tile's :func:`core_values` atomically."""
    _write(values_path(scratch, tile), values)


def halo_lists(scratch, offsets: np.ndarray, prepared: PreparedPoints, nbhd: Neighbourhood, core: np.ndarray,
               positions: np.ndarray, halo_box: tuple, cloud: tuple) -> np.ndarray | None:
    """The lists a survey queried for its halo points whose own tiles are not surveyed yet.

    Those tiles' surveys read them (:func:`known_neighbours`) instead of
    querying their cores' lists again; the survey of tiles run at once
    cannot. Arguments as :func:`core_lists` (``offsets`` as
    :func:`known_neighbours`).

    Returns
    -------
    ndarray, shape (h, k + 1), or None
        Per halo point whose ball lies inside what was read and whose tile
        has no list file: its scratch position, then its list. None when
        there is none.
    """
    home = np.searchsorted(offsets, positions, side="right") - 1
    pending = np.array([not os.path.exists(lists_path(scratch, int(t))) for t in range(len(offsets) - 1)])
    rows = ~core & pending[home]
    lists = core_lists(prepared, nbhd, rows, positions, halo_box, cloud) if rows.any() else None
    if lists is None:
        return None
    kept = lists[:, 0] >= 0
    return np.column_stack([positions[rows][kept].astype(lists.dtype), lists[kept]])


def write_halo_lists(scratch, tile: int, lists: np.ndarray | None) -> None:
    """Write a survey's :func:`halo_lists` atomically (nothing when None)."""
    if lists is not None:
        _write(halo_path(scratch, tile), lists)


def remove_halo_lists(scratch) -> None:
    """Delete every survey's halo lists: once every tile is surveyed, each tile's own lists hold them."""
    directory = os.path.join(scratch, "knn")
    if os.path.isdir(directory):
        for name in os.listdir(directory):
            if name.startswith("halo_"):
                os.unlink(os.path.join(directory, name))


def _read_lists(scratch, tile: int) -> np.ndarray | None:
    """A tile's neighbour file, or None when there is none (a two-round survey, other options)."""
    path = lists_path(scratch, tile)
    if not os.path.exists(path):
        return None
    return np.load(path)


def known_neighbours(scratch, offsets: np.ndarray, positions: np.ndarray) -> StoredNeighbours:
    """The ``knn`` argument of :func:`heatcurv.estimate` for a tile read from the scratch files.

    Parameters
    ----------
    scratch : str
        The scratch directory.
    offsets : ndarray, shape (t + 1,)
        Where each tile's points start in the scratch files.
    positions : ndarray, shape (m,), int64
        The scratch position of each point the tile read, in the order given to ``estimate``.

    Returns
    -------
    StoredNeighbours
    """
    return StoredNeighbours(scratch, np.asarray(offsets, dtype=np.int64), positions)


class StoredNeighbours:
    """What the surveys stored of a tile's points: their neighbourhoods, areas and outlier flags.

    Called as ``knn(prepared, tree, k, workers) -> Neighbourhood``: every
    distinct point's ``k`` nearest, read back where the survey wrote them and
    all of them are among the tile's points, else queried
    (:meth:`heatcurv.operators.operator.HeatKernelOperator.from_points`).
    """

    def __init__(self, scratch, offsets: np.ndarray, positions: np.ndarray):
        self.scratch, self.offsets, self.positions = scratch, offsets, positions
        self._rows = None  # the stored values per point read, once read
        self._listed = False  # the last call read stored lists of the width asked for

    def __call__(self, prepared, tree, k: int, workers: int = -1) -> Neighbourhood:
        X = prepared.points
        n = X.shape[0]
        # held only for this call
        lists, base, lookup = _stored_lists(self.scratch, self.offsets, self.positions, prepared.inverse)
        self._listed = lists is not None and lists.shape[1] == k
        if not self._listed:
            return knn_neighbourhood(X, k, tree=tree, workers=workers)
        indices, distances, known = stored_neighbours(X, prepared.first, lists, self.offsets, base, lookup,
                                                      _index_dtype(n))
        del lists, lookup
        ask = np.flatnonzero(~known)
        if ask.size:
            queried = knn_neighbourhood(X, k, tree=tree, workers=workers, queries=X[ask])
            indices[ask] = queried.indices.reshape(-1, k)
            distances[ask] = queried.distances.reshape(-1, k)
        return Neighbourhood(
            indptr=np.arange(0, n * k + 1, k, dtype=np.int64), indices=indices.reshape(-1),
            distances=distances.reshape(-1), radius=distances[:, -1].copy(), augmented=np.zeros(n, dtype=bool),
            by_distance=True,
        )

    def _values(self, prepared) -> np.ndarray | None:
        """The stored :data:`VALUES` of every distinct point, shape (n,); None unless the neighbourhoods were read
        back (the same lists, the same width) and every point's tile stored them."""
        if not self._listed:
            return None
        if self._rows is None:
            home = np.searchsorted(self.offsets, self.positions, side="right") - 1
            tiles = np.unique(home)
            paths = [values_path(self.scratch, int(tile)) for tile in tiles]
            if not all(os.path.exists(path) for path in paths):
                return None
            values = np.empty(self.positions.shape[0], dtype=VALUES)
            for tile, path in zip(tiles, paths):
                mine = np.flatnonzero(home == tile)
                values[mine] = np.load(path)[self.positions[mine] - self.offsets[tile]]
            if np.isnan(values["area"]).any():
                return None
            self._rows = values
        return self._rows[prepared.first]

    def areas(self, prepared) -> np.ndarray | None:
        """The stored density area of every distinct point of ``prepared`` (the operator's units), shape (n,),
        or None."""
        values = self._values(prepared)
        return None if values is None else values["area"].copy()

    def outliers(self, prepared) -> Outliers | None:
        """The stored outlier flags of every distinct point of ``prepared``, or None."""
        values = self._values(prepared)
        if values is None:
            return None
        bits = values["outlier"]
        return Outliers(**{name: (bits & bit) != 0 for name, bit in OUTLIER_BITS.items()})


def _stored_lists(scratch, offsets: np.ndarray, positions: np.ndarray, inverse: np.ndarray):
    """The stored lists of the points read (-1 rows where none is stored) and the map from scratch positions to them.

    Parameters
    ----------
    scratch, offsets, positions
        As :func:`known_neighbours`.
    inverse : ndarray, shape (m,), int64
        The distinct point of each point read.

    Returns
    -------
    lists : ndarray, shape (m, k), or None
        Per point read, its list (:func:`core_lists`); None when no tile read has one.
    base : ndarray, shape (t,), int64
        Where each tile's slice starts in ``lookup`` (-1: no point of it read).
    lookup : ndarray, int32 or int64
        The tiles' slices end to end: per scratch position, its distinct point, -1 if not read.
    """
    m = positions.shape[0]
    home = np.searchsorted(offsets, positions, side="right") - 1
    tiles = np.unique(home)
    lists = None
    base = np.full(len(offsets) - 1, -1, dtype=np.int64)
    dtype = _index_dtype(int(inverse.max(initial=0)) + 1)
    maps, start, unlisted = [], 0, []
    for tile in tiles:
        mine = np.flatnonzero(home == tile)
        count = int(offsets[tile + 1] - offsets[tile])
        local = np.full(count, -1, dtype=dtype)
        local[positions[mine] - offsets[tile]] = inverse[mine]
        base[tile], start = start, start + count
        maps.append(local)
        stored = _read_lists(scratch, int(tile))
        if stored is None:
            unlisted.append(int(tile))
            continue
        lists = _room_for(lists, m, stored)
        if stored.shape[1] == lists.shape[1]:
            lists[mine] = stored[positions[mine] - offsets[tile]]
    if unlisted:  # the lists other tiles' surveys queried for their halos, over these tiles' points
        lists = _halo_lists_read(scratch, tiles, positions, unlisted, offsets, lists)
    lookup = np.concatenate(maps) if maps else np.zeros(0, dtype=dtype)
    return lists, base, lookup


def _halo_lists_read(scratch, tiles: np.ndarray, positions: np.ndarray, unlisted: list, offsets: np.ndarray,
                     lists: np.ndarray | None) -> np.ndarray | None:
    """``lists`` (shape (m, k), or None) with the rows of the ``unlisted`` tiles' points that the halo lists of
    the ``tiles`` read hold."""
    order = np.argsort(positions, kind="stable")
    ranges = [(offsets[t], offsets[t + 1]) for t in unlisted]
    for tile in tiles.tolist():
        path = halo_path(scratch, tile)
        if not os.path.exists(path):
            continue
        stored = np.load(path)
        where = np.zeros(len(stored), dtype=bool)
        for lo, hi in ranges:
            where |= (stored[:, 0] >= lo) & (stored[:, 0] < hi)
        stored = stored[where]
        at = np.searchsorted(positions, stored[:, 0], sorter=order)
        found = at < len(order)
        rows = order[np.minimum(at, len(order) - 1)]
        found &= positions[rows] == stored[:, 0]
        if not found.any():
            continue
        lists = _room_for(lists, len(positions), stored[:, 1:])
        if stored.shape[1] - 1 == lists.shape[1]:
            lists[rows[found]] = stored[found, 1:]
    return lists


def _room_for(lists: np.ndarray | None, m: int, stored: np.ndarray) -> np.ndarray:
    """``lists`` (shape (m, k), -1 rows; made if None) of a type that holds ``stored``'s positions: a survey stores
    int32 positions where its tile's fit, int64 where they do not (beyond 2^31 points)."""
    if lists is None:
        return np.full((m, stored.shape[1]), -1, dtype=stored.dtype)
    return lists if lists.dtype.itemsize >= stored.dtype.itemsize else lists.astype(stored.dtype)
