"""Second sheets across tiles: the pairs a tile could not settle, judged with the final signs of their normals.

A point whose ball holds a neighbour over or under it that faces the other
way sees both sides of a thin part (:mod:`heatcurv.flags.sheets`): area 0,
not reliable. Facing depends on the normals' signs, which a tile of a run
oriented ``outward`` does not know: the driver turns its seam pieces, its
winding patches and their finer pieces afterwards, and a leg whose two sides
a tile's tree oriented alike faces away only once the winding number has
turned one of them. A tile settles the pairs inside one such piece of its
core (:func:`heatcurv.tiles.compute.compute_tile`) and keeps the others
(``sheet_rows``, ``sheet_columns``: an end in the halo or in another piece);
:func:`flag_second_sheets` reads both ends' normals in ``results.rec``, turns
them by the flips, and flags ``p`` where they face away, as in memory.
"""

from __future__ import annotations

import numpy as np

from ..tuning import TUNING
from .output import chunk_flips, gather_records, write_records

__all__ = ["flag_second_sheets"]


def flag_second_sheets(results_path, tile_files: dict, flips) -> int:
    """Give area 0 and clear ``reliable`` in ``results.rec`` at the points whose unsettled pair faces away.

    Parameters
    ----------
    results_path : str
        ``results.rec``.
    tile_files : dict of int to str
        Each tile's result file, holding ``sheet_rows`` and ``sheet_columns``.
    flips : list
        The seam and winding flips (:func:`.output.chunk_flips`).

    Returns
    -------
    int
        Points flagged.
    """
    flagged = np.zeros(0, dtype=np.int64)
    for _, path in sorted(tile_files.items()):
        with np.load(path) as data:
            p, q = data["sheet_rows"], data["sheet_columns"]
        if not p.size:
            continue
        ends = np.unique(np.concatenate([p, q]))
        records = gather_records(results_path, ends)
        normals = np.where(chunk_flips(records, 0, flips, rows=ends)[:, None], -records["normals"],
                           records["normals"])
        at_p, at_q = np.searchsorted(ends, p), np.searchsorted(ends, q)
        away = np.einsum("ij,ij->i", normals[at_p], normals[at_q]) < -TUNING.sheet_aligned
        flagged = np.union1d(flagged, p[away])
    if flagged.size:
        changed = gather_records(results_path, flagged)
        changed["area"], changed["reliable"] = 0.0, 0
        write_records(results_path, changed, flagged)
    return int(flagged.size)
