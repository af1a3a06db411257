"""Inside and outside across tiles: the winding number's patch signs and flags over the whole cloud.

In memory, a closed cloud's outward orientation is finished by the
generalised winding number (:mod:`heatcurv.enclosure`): the spanning forest is
cut into patches, each patch gets the side that makes the field about 1 inside
and 0 outside, and the points whose side the field contradicts are flagged.
Without it the two sides of a thin part (a leg, an ear) can both be oriented
by one wrong edge of the tree, and the part comes out inside out, flagged
reliable.

A tile cuts its own spanning forest into patches of the size the whole
cloud's would have (:func:`heatcurv.enclosure.patches`, each also within one
seam piece of :mod:`.orient`) and keeps a sample of its core points as
sources: those whose coordinate rank (:func:`heatcurv.enclosure.source_keys`,
the same for a point in any tile) is below a threshold chosen for about
:data:`heatcurv.enclosure.MAX_SOURCES` sources over the whole cloud. The driver,
once the seam flips are known, gathers every tile's sources, turns their
normals by the seam flips, and solves the same energy for the sides of all
patches of all tiles (:func:`heatcurv.enclosure.patch_sides`). A closed cloud's
patch flips are then applied with the seam flips in the output pass, and a
point is flagged (not ``reliable``) when it is a disagreeing source, or when
more than half of the sources within its fit radius disagree, as in memory.

The patches differ from the in-memory run's (a tile's forest is not the whole
cloud's), so on a thin part the two runs can end with different sides or
flags; neither leaves a part inside out and reliable where the other flags it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..enclosure import MAX_SOURCES, patch_sides, source_keys
from .output import PATCH_SHIFT, SOURCE_KEYS, read_results, write_records

__all__ = ["WindingSides", "tile_sources", "winding_sides", "flag_unsupported"]


def _threshold(cloud_points: int) -> np.uint64:
    """The rank below which a point is a source: about :data:`MAX_SOURCES` of ``cloud_points`` (all of fewer)."""
    if cloud_points <= MAX_SOURCES:
        return np.uint64(2**64 - 1)
    return np.uint64((2**64 * MAX_SOURCES) // cloud_points)


def tile_sources(stage_points: np.ndarray, rows: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                 excluded: np.ndarray, label: np.ndarray, seam: np.ndarray, cloud_points: int) -> dict:
    """A tile's share of the winding step's sources: the arrays of :data:`.output.SOURCE_KEYS`.

    Parameters
    ----------
    stage_points : ndarray, shape (c, 3)
        The tile's core points in the whole cloud's frame
        (:meth:`heatcurv.choices.CloudFrame.to_stage`).
    rows : ndarray, shape (c,), int
        Their input rows.
    normals : ndarray, shape (c, 3)
        Their normals as the tile oriented them.
    areas : ndarray, shape (c,)
        Their areas, in the frame's unit.
    excluded : ndarray, shape (c,), bool
        Outliers: neither sources nor counted in the area.
    label, seam : ndarray, shape (c,), int
        Their winding patch and seam piece within the tile.
    cloud_points : int
        Points of the whole cloud.

    Returns
    -------
    dict
        ``winding_*`` arrays of the sources, and ``winding_total``: the summed
        area of the core points not excluded (the sources' areas are scaled to it).
    """
    chosen = ~excluded & (source_keys(stage_points) <= _threshold(cloud_points))
    return {
        "winding_rows": rows[chosen], "winding_x": stage_points[chosen], "winding_normals": normals[chosen],
        "winding_area": np.abs(areas[chosen]), "winding_label": label[chosen], "winding_seam": seam[chosen],
        "winding_total": np.array(np.abs(areas[~excluded]).sum()),
    }


@dataclass(frozen=True)
class WindingSides:
    """The winding step of a tiled run.

    Attributes
    ----------
    keys : ndarray, shape (p,), int64
        Winding patch keys (``tile << 32 | label``), sorted.
    flip : ndarray, shape (p,), bool
        Patches to turn over (after the seam flips); all False when not ``closed``.
    rows : ndarray, shape (m,), int64
        The sources' input rows, sorted.
    x : ndarray, shape (m, 3)
        Their positions, the frame's coordinates.
    bad : ndarray, shape (m,), bool
        Sources whose side the field contradicts.
    closed : bool
        Whether the cloud encloses a volume (:class:`heatcurv.enclosure.PatchSides`).
    agreement : float
    """

    keys: np.ndarray
    flip: np.ndarray
    rows: np.ndarray
    x: np.ndarray
    bad: np.ndarray
    closed: bool
    agreement: float


def winding_sides(tile_files: dict, seam_keys: np.ndarray, seam_flip: np.ndarray) -> WindingSides | None:
    """Every tile's sources, turned by the seam flips, and the sides of all winding patches.

    Parameters
    ----------
    tile_files : dict of int to str
        Each tile's result file, holding :data:`.output.SOURCE_KEYS`.
    seam_keys, seam_flip : ndarray
        :func:`heatcurv.tiles.orient.seam_flips`' patch keys and flips.

    Returns
    -------
    WindingSides or None
        None when fewer than 16 sources were drawn (as in memory: too few to judge).
    """
    parts = {key: [] for key in SOURCE_KEYS}
    for tile, path in sorted(tile_files.items()):
        with np.load(path) as data:
            base = np.int64(tile) << PATCH_SHIFT
            for key in SOURCE_KEYS:
                value = data[key]
                if key in ("winding_label", "winding_seam"):
                    value = base | value.astype(np.int64)
                parts[key].append(np.atleast_1d(value))
    arrays = {key: np.concatenate(value) for key, value in parts.items()}
    rows = arrays["winding_rows"].astype(np.int64)
    if rows.size < 16:
        return None
    order = np.argsort(rows)
    rows, x, nrm = rows[order], arrays["winding_x"][order], arrays["winding_normals"][order]
    area, label, seam = arrays["winding_area"][order], arrays["winding_label"][order], arrays["winding_seam"][order]
    at = np.clip(np.searchsorted(seam_keys, seam), 0, max(len(seam_keys) - 1, 0))
    turned = (seam_keys[at] == seam) & seam_flip[at] if len(seam_keys) else np.zeros(rows.size, dtype=bool)
    nrm = np.where(turned[:, None], -nrm, nrm)
    keys, index = np.unique(label, return_inverse=True)
    weight = area * (arrays["winding_total"].sum() / area.sum())
    sides = patch_sides(x, nrm, weight, index, keys.size)
    flip = (sides.sign < 0) if sides.closed else np.zeros(keys.size, dtype=bool)
    return WindingSides(keys, flip, rows, x, sides.bad, sides.closed, sides.agreement)


def flag_unsupported(results_path, source, frame, sides: WindingSides, chunk: int = 1 << 20) -> dict:
    """Clear ``reliable`` in ``results.rec`` where the winding number contradicts a point's side (closed clouds).

    A source is flagged when it disagrees (:attr:`WindingSides.bad`); any other
    point when more than half of the sources within its fit radius do (none
    when no source is that near).

    Parameters
    ----------
    results_path : str
        ``results.rec``.
    source : heatcurv.tiles.sources.Source
        The input, read for the coordinates.
    frame : heatcurv.choices.CloudFrame
        The whole cloud's frame.
    sides : WindingSides

    Returns
    -------
    dict
        ``turned`` (points the patch flips turn over) and ``unsupported`` (points flagged).
    """
    turned = unsupported = 0
    tree, bad_tree = cKDTree(sides.x), cKDTree(sides.x[sides.bad]) if sides.bad.any() else None
    for start, points, _ in source.chunks(chunk):
        stop = start + len(points)
        block = read_results(results_path, start, stop)
        computed = block["computed"] == 1
        at = np.clip(np.searchsorted(sides.keys, block["winding"]), 0, len(sides.keys) - 1)
        turned += int(np.sum(computed & (sides.keys[at] == block["winding"]) & sides.flip[at]))
        if bad_tree is None:
            continue
        x = frame.to_stage(points)
        radius = block["fit_radius"] / frame.unit
        near = computed & ~(block["outlier"] == 1)
        flagged = np.zeros(len(points), dtype=bool)
        if near.any():
            total = tree.query_ball_point(x[near], radius[near], return_length=True)
            against = bad_tree.query_ball_point(x[near], radius[near], return_length=True)
            flagged[near] = against > 0.5 * total
        lo, hi = np.searchsorted(sides.rows, [start, stop])
        flagged[sides.rows[lo:hi] - start] = sides.bad[lo:hi]
        flagged &= computed
        unsupported += int(flagged.sum())
        if flagged.any():
            rows = np.flatnonzero(flagged)
            changed = block[rows].copy()
            changed["reliable"] = 0
            write_records(results_path, changed, rows + start)
    return {"turned": turned, "unsupported": unsupported}
