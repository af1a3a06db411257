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

An object too flat for its vote to tell (``|vote| <= TUNING.weak_vote *
sum_i A_i |(x_i - c) . n_i|``) takes, as in memory, the flat convention: its
summed normal along the least-variance axis of its points, that axis's largest
coordinate positive. The strength does not add up from the patches' sums once
``c`` is known, but its Cauchy-Schwarz bound ``sqrt(sum A sum A |x - c|^2)``
does: only an object under that bound (an open, nearly flat one; never a
closed surface, whose vote is three times its volume) costs a pass over the
results (:func:`_flat_objects`), which sums the strength and the moments of
the convention exactly.

The flips are applied in the final write pass
(:func:`heatcurv.fits.principal.PrincipalCurvatures.flipped`'s convention: the
normal and mean curvature negated, ``k1' = -k2``, ``k2' = -k1``, ``d1`` and
``d2`` swapped, the Gaussian curvature unchanged).
"""

from __future__ import annotations

import numpy as np

from ..orient.orientation import coordinate_convention
from ..tuning import TUNING
from .output import PATCH_SHIFT, gather_records, read_results

__all__ = ["seam_flips", "patch_moments", "VOTE_COSINE", "MOMENTS"]

#: Shared points whose two normals are closer than this to perpendicular do not vote.
VOTE_COSINE = 0.5
#: The columns of :func:`patch_moments`: ``sum A``, ``sum A x`` (3), ``sum A n`` (3), ``sum A n . x``, ``sum A |x|^2``.
MOMENTS = ("area", "area_x", "area_y", "area_z", "area_nx", "area_ny", "area_nz", "area_n_dot_x", "area_x_squared")


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
    columns = [area, *(area[:, None] * x).T, *(area[:, None] * normals).T, area * np.einsum("ij,ij->i", normals, x),
               area * np.einsum("ij,ij->i", x, x)]
    return np.column_stack([np.bincount(label, weights=c, minlength=n_labels) for c in columns])


def _object_votes(moments: np.ndarray, bits: np.ndarray, obj: np.ndarray, n_objects: int):
    """Each object's outward vote (:func:`patch_moments`) with its patches turned where ``bits``.

    Returns
    -------
    vote : ndarray, shape (n_objects,)
        ``sum A n . (x - c)``.
    centroid : ndarray, shape (n_objects, 3)
        ``c``, the area-weighted centroid.
    bound : ndarray, shape (n_objects,)
        ``sqrt(sum A sum A |x - c|^2)``, at least the vote's strength ``sum A |n . (x - c)|``.
    area : ndarray, shape (n_objects,)
        ``sum A``.
    """
    turned = np.where(bits[:, None], -1.0, 1.0) * moments
    # the areas, the area-weighted positions and their squares do not turn
    turned[:, :4], turned[:, 8] = moments[:, :4], moments[:, 8]
    total = np.stack([np.bincount(obj, weights=turned[:, k], minlength=n_objects) for k in range(len(MOMENTS))], 1)
    area = total[:, 0]
    centroid = total[:, 1:4] / np.maximum(area, np.finfo(float).tiny)[:, None]
    vote = total[:, 7] - np.einsum("ij,ij->i", centroid, total[:, 4:7])
    spread = total[:, 8] - 2.0 * np.einsum("ij,ij->i", centroid, total[:, 1:4]) + area * np.sum(centroid**2, axis=1)
    return vote, centroid, np.sqrt(area * np.maximum(spread, 0.0)), area


def _object_signs(moments, bits, obj, n_objects: int, results) -> tuple[np.ndarray, np.ndarray]:
    """Each object's sign, ``+1`` or ``-1``, that turns its normals (as turned by ``bits``) outward, or to the
    flat convention where its vote is too weak (module docstring); and whether it took the convention.

    ``results``: ``(results_path, source, frame, keys)``, read by :func:`_flat_objects` for the objects
    whose vote is under the strength's bound.
    """
    vote, centroid, bound, area = _object_votes(moments, bits, obj, n_objects)
    sign = np.where(vote < 0, -1.0, 1.0)
    flat = (area > 0) & (np.abs(vote) <= TUNING.weak_vote * bound)  # may be too flat: the bound is not the strength
    if flat.any():
        results_path, source, frame, keys = results
        strength, convention = _flat_objects(results_path, source, frame, keys, bits, obj, centroid, flat)
        flat &= (np.abs(vote) <= TUNING.weak_vote * strength) & (convention != 0)
        sign[flat] = convention[flat]
    return sign, flat


def _flat_objects(results_path, source, frame, keys, bits, obj, centroid, candidate, chunk: int = 1 << 20):
    """The objects among ``candidate`` too flat for their outward vote, and the side the flat convention gives them.

    One pass over the input and ``results.rec`` sums, for each candidate object, the vote's strength
    ``sum A |n . (x - c)|`` and, over its points of positive weight (in memory: the distinct points that are
    not outliers), their number, ``sum x``, ``sum x x^T`` and ``sum n`` with its patches turned where
    ``bits``: the moments of :func:`heatcurv.orient.orientation._component_signs`' convention.

    Returns
    -------
    strength : ndarray, shape (n_objects,)
        0 for the objects not among ``candidate``.
    convention : ndarray, shape (n_objects,)
        ``+1`` or ``-1``: the sign that turns the object's normals (as turned by ``bits``) to the convention's
        side; 0 for the objects not among ``candidate``.
    """
    n_objects = len(candidate)
    strength, count = np.zeros(n_objects), np.zeros(n_objects)
    first, second, normal = np.zeros((n_objects, 3)), np.zeros((n_objects, 3, 3)), np.zeros((n_objects, 3))
    for start, points, _ in source.chunks(chunk):
        block = read_results(results_path, start, start + len(points))
        at = np.clip(np.searchsorted(keys, block["patch"]), 0, max(len(keys) - 1, 0))
        mine = (block["computed"] == 1) & (keys[at] == block["patch"]) & candidate[obj[at]]
        if not mine.any():
            continue
        o, x, weight = obj[at[mine]], frame.to_stage(points[mine]), block["vote_weight"][mine]
        n = np.where(bits[at[mine]][:, None], -1.0, 1.0) * block["vote_normal"][mine]
        strength += np.bincount(o, weights=weight * np.abs(np.einsum("ij,ij->i", n, x - centroid[o])),
                                minlength=n_objects)
        member = weight > 0
        o, x, n = o[member], x[member], n[member]
        count += np.bincount(o, minlength=n_objects)
        for k in range(3):
            first[:, k] += np.bincount(o, weights=x[:, k], minlength=n_objects)
            normal[:, k] += np.bincount(o, weights=n[:, k], minlength=n_objects)
            for j in range(3):
                second[:, k, j] += np.bincount(o, weights=x[:, k] * x[:, j], minlength=n_objects)
    convention = np.zeros(n_objects)
    for c in np.flatnonzero(candidate & (count > 0)):
        # the points' scatter about the area-weighted centroid, whose least-variance axis is memory's last SVD axis
        scatter = second[c] - np.outer(centroid[c], first[c]) - np.outer(first[c], centroid[c])
        scatter += count[c] * np.outer(centroid[c], centroid[c])
        axis = coordinate_convention(np.linalg.eigh(scatter)[1][:, 0])
        convention[c] = -1.0 if normal[c] @ axis < 0 else 1.0
    return strength, convention


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


def seam_flips(tile_files: dict, results_path, source, frame) -> tuple[np.ndarray, np.ndarray, dict]:
    """The flip bit of every patch of a tiled run oriented ``outward``.

    Parameters
    ----------
    tile_files : dict of int to str
        Each tile's result file (:func:`.tasks.tile_path`).
    results_path : str
        The index-addressed ``results.rec`` holding every core row.
    source : heatcurv.tiles.sources.Source
        The input, read for the coordinates where an object may be too flat for its vote.
    frame : heatcurv.choice.choices.CloudFrame
        The whole cloud's frame (the tiles' moments are in its coordinates).

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
        tile's own orientation could not keep consistent), ``shared`` and
        ``flat_objects`` (objects that took the flat convention).
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
    sign, flat = _object_signs(moments, bits, obj, len(objects), (results_path, source, frame, keys))
    flip = bits ^ (sign[obj] < 0)
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
              "disagreeing": disagreeing, "shared": int(shared), "flat_objects": int(flat.sum())}
    return keys, flip, report
