"""Outward orientation across tiles: one flip bit per patch, then one global sign per object.

``up`` and ``viewpoint`` decide every normal's side from its own reference
direction, so tiles need nothing more. ``outward`` propagates one side over
the whole surface (:mod:`heatcurv.orient.orientation`), which a tile can do only
over its own piece: each tile orients its pieces internally and the driver
makes the pieces agree.

A *patch* is a connected piece of a tile's surface (a tile cutting a torus's
tube holds two); each may have been given either side, so the unknowns are one
flip bit per patch (SCALE.md decision 6 asks one per tile; a tile holding two
pieces of an object needs one per piece). Every point a tile has in its halo
is a core point of another tile: the two normals computed for it vote on
whether the two patches agree (``+1``) or not (``-1``; normals within 60
degrees of perpendicular do not vote). The bits follow from the votes along a
maximum spanning forest of the patch graph (Kruskal, heaviest margins first,
with parity in the union-find), and each connected object then gets the sign
that makes its outward vote ``sum_i A_i (x_i - c) . n_i`` over its core points
positive, ``c`` its area-weighted centroid, as in memory
(:func:`heatcurv.orient.orientation.orient`; 3 x the enclosed volume of a
closed surface, whatever ``c``): each patch's moments (:func:`patch_moments`)
sum to the object's, so the object's centroid is known only once the patches
are joined.
The flips are applied in the final write pass
(:func:`heatcurv.fits.principal.PrincipalCurvatures.flipped`'s convention: the
normal and mean curvature negated, ``k1' = -k2``, ``k2' = -k1``, ``d1`` and
``d2`` swapped, the Gaussian curvature unchanged).
"""

from __future__ import annotations

import numpy as np

from .output import PATCH_SHIFT, gather_records

__all__ = ["seam_flips", "patch_moments", "VOTE_COSINE", "MOMENTS"]

#: Shared points whose two normals are closer than this to perpendicular do not vote.
VOTE_COSINE = 0.5
#: The columns of :func:`patch_moments`: ``sum A``, ``sum A x`` (3), ``sum A n`` (3), ``sum A n . x``.
MOMENTS = ("area", "area_x", "area_y", "area_z", "area_nx", "area_ny", "area_nz", "area_n_dot_x")


def patch_moments(x: np.ndarray, normals: np.ndarray, area: np.ndarray, label: np.ndarray,
                  n_labels: int) -> np.ndarray:
    """Each patch's sums of :data:`MOMENTS`, shape (n_labels, 8): an object's outward vote from its patches'.

    ``sum_i A_i (x_i - c) . n_i = sum A n . x - c . sum A n`` with ``c = sum A x / sum A``,
    so the vote of a union of patches, each turned or not, follows from these sums.

    Parameters
    ----------
    x : ndarray, shape (m, 3)
        The core points in the cloud's frame (:meth:`heatcurv.choice.choices.CloudFrame.to_stage`).
    normals : ndarray, shape (m, 3)
        Their normals as the tile oriented them.
    area : ndarray, shape (m,)
        Their weights in the vote (the orientation's areas; 0 for outliers and repeated duplicates).
    label : ndarray, shape (m,), int
        Their patches, ``0 <= label < n_labels``.
    n_labels : int
    """
    area = np.nan_to_num(area)
    columns = [area, *(area[:, None] * x).T, *(area[:, None] * normals).T, area * np.einsum("ij,ij->i", normals, x)]
    return np.column_stack([np.bincount(label, weights=c, minlength=n_labels) for c in columns])


def _outward_votes(moments: np.ndarray, bits: np.ndarray, obj: np.ndarray, n_objects: int) -> np.ndarray:
    """Each object's outward vote (:func:`patch_moments`) with its patches turned where ``bits``, shape (n_objects,)."""
    turned = np.where(bits[:, None], -1.0, 1.0) * moments
    turned[:, :4] = moments[:, :4]  # the areas and the area-weighted positions do not turn
    total = np.stack([np.bincount(obj, weights=turned[:, k], minlength=n_objects) for k in range(len(MOMENTS))], 1)
    centroid = total[:, 1:4] / np.maximum(total[:, :1], np.finfo(float).tiny)
    return total[:, 7] - np.einsum("ij,ij->i", centroid, total[:, 4:7])


def _find(parent: dict, parity: dict, a):
    """Root of ``a`` and ``a``'s parity relative to it (path compression)."""
    path = []
    while parent[a] != a:
        path.append(a)
        a = parent[a]
    root, acc = a, 0
    for node in reversed(path):
        acc ^= parity[node]
        parity[node] = acc
        parent[node] = root
    return root, (parity[path[0]] if path else 0)


def seam_flips(tile_files: dict, results_path) -> tuple[np.ndarray, np.ndarray, dict]:
    """The flip bit of every patch of a tiled run oriented ``outward``.

    Parameters
    ----------
    tile_files : dict of int to str
        Each tile's result file (:func:`.tasks.tile_path`).
    results_path : str
        The index-addressed ``results.rec`` holding every core row.

    Returns
    -------
    keys : ndarray, shape (p,), int64
        Patch keys (``tile << 32 | label``), sorted.
    flip : ndarray, shape (p,), bool
        Whether to flip each patch.
    report : dict
        ``patches``, ``seams`` (patch pairs sharing points), ``objects``
        (connected groups of patches), ``disagreeing`` (shared points whose
        normals still point to opposite sides after the flips: pieces the
        tile's own orientation could not keep consistent) and ``shared``.
    """
    keys, moments, pairs, votes = [], [], [], []
    for tile, path in sorted(tile_files.items()):
        with np.load(path) as data:
            base = np.int64(tile) << PATCH_SHIFT
            keys.append(base | data["moment_labels"])
            moments.append(data["moments"])
            halo_rows = data["halo_rows"]
            if not len(halo_rows):
                continue
            owner = gather_records(results_path, np.sort(halo_rows))
            order = np.argsort(halo_rows)
            mine_patch = (base | data["halo_patch"])[order]
            dot = np.einsum("ij,ij->i", data["halo_normals"][order], owner["normals"])
            vote = (np.abs(dot) >= VOTE_COSINE) & (owner["computed"] == 1)
            pairs.append(np.column_stack([mine_patch[vote], owner["patch"][vote]]))
            votes.append(np.sign(dot[vote]).astype(np.int64))
    keys, moments = np.concatenate(keys), np.concatenate(moments)
    order = np.argsort(keys)
    keys, moments = keys[order], moments[order]
    edges, margins, against, shared = np.zeros((0, 2), np.int64), np.zeros(0, np.int64), np.zeros(0), 0
    if pairs:
        pairs, votes = np.concatenate(pairs), np.concatenate(votes)
        shared = len(votes)
        pairs = np.sort(pairs, axis=1)
        edges, inverse = np.unique(pairs, axis=0, return_inverse=True)
        margins = np.bincount(inverse.ravel(), weights=votes, minlength=len(edges)).astype(np.int64)
        against = np.bincount(inverse.ravel(), weights=votes < 0, minlength=len(edges))
    parent = {int(k): int(k) for k in keys}
    parity = {int(k): 0 for k in keys}
    for e in np.argsort(-np.abs(margins), kind="stable"):  # one loop over patch pairs, not points
        a, b = int(edges[e, 0]), int(edges[e, 1])
        if margins[e] == 0 or a not in parent or b not in parent:
            continue
        ra, pa = _find(parent, parity, a)
        rb, pb = _find(parent, parity, b)
        if ra == rb:
            continue
        want = 0 if margins[e] > 0 else 1  # the parity a and b must differ by
        parent[rb] = ra
        parity[rb] = pa ^ pb ^ want
    bits = np.zeros(len(keys), dtype=bool)
    roots = np.zeros(len(keys), dtype=np.int64)
    for i, k in enumerate(keys):
        roots[i], bits[i] = _find(parent, parity, int(k))
    objects, obj = np.unique(roots, return_inverse=True)
    flip = bits ^ (_outward_votes(moments, bits, obj, len(objects))[obj] < 0)
    disagreeing = 0
    # a halo piece with no core point of its own tile has no flip bit (a wide halo reaches one)
    known = np.isin(edges, keys).all(axis=1) if len(margins) else np.zeros(0, dtype=bool)
    if known.any():
        fa = flip[np.searchsorted(keys, edges[known, 0])]
        fb = flip[np.searchsorted(keys, edges[known, 1])]
        agree = margins[known] + against[known]  # (+1 votes) - (-1 votes) + (-1 votes)
        # votes against the final bits: on an edge whose patches flip alike, the -1 votes; else the +1 votes
        disagreeing = int(np.sum(np.where(fa == fb, against[known], agree)))
    report = {"patches": int(len(keys)), "seams": int(len(edges)), "objects": int(len(objects)),
              "disagreeing": disagreeing, "shared": int(shared)}
    return keys, flip, report
