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
that makes its signed volume ``sum_i A_i (x_i - c) . n_i`` over core points
positive (3 x the enclosed volume of a closed surface, whatever ``c``).
The flips are applied in the final write pass
(:func:`heatcurv.fits.principal.PrincipalCurvatures.flipped`'s convention: the
normal and mean curvature negated, ``k1' = -k2``, ``k2' = -k1``, ``d1`` and
``d2`` swapped, the Gaussian curvature unchanged).
"""

from __future__ import annotations

import numpy as np

from .output import PATCH_SHIFT, gather_records

__all__ = ["seam_flips", "VOTE_COSINE"]

#: Shared points whose two normals are closer than this to perpendicular do not vote.
VOTE_COSINE = 0.5


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
    keys, volumes, pairs, votes = [], [], [], []
    for tile, path in sorted(tile_files.items()):
        with np.load(path) as data:
            base = np.int64(tile) << PATCH_SHIFT
            keys.append(base | data["volume_labels"])
            volumes.append(data["volumes"])
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
    keys, volumes = np.concatenate(keys), np.concatenate(volumes)
    order = np.argsort(keys)
    keys, volumes = keys[order], volumes[order]
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
    signed = np.where(bits, -volumes, volumes)
    objects, obj = np.unique(roots, return_inverse=True)
    total = np.bincount(obj, weights=signed, minlength=len(objects))
    flip = bits ^ (total[obj] < 0)
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
