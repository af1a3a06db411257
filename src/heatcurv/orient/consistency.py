"""Normals of the winding field itself, solved from no orientation, and the seams of sheets: second opinions.

:mod:`heatcurv.orient.enclosure` chooses the side of each patch of the
spanning tree, so its answer starts from the tree's normals. This module
asks the winding number alone, by the iteration of Lin, Shi and Liu 2024
("Fast and globally consistent normal orientation based on the winding number
normal consistency", ACM ToG 43(6)), which knows no normal at the start:

* the unknowns are one vector ``mu_i`` a point (its area over ``4 pi`` times
  its outward normal), starting at 0; ``A mu`` is the winding number at every
  point and ``G mu`` minus its gradient, both over the pairs at least the
  smoothing width ``w`` apart (:mod:`heatcurv._kernels.dipoles`);
* each of ``iterations`` steps takes one steepest-descent step on
  ``|A mu - 1/2|^2`` (a point of a closed surface sits where the field
  jumps from 1 to 0) with an exact line search, then keeps each ``|mu_i|``
  and turns ``mu_i`` along ``G mu`` (the field's own normal there), while
  ``w`` falls linearly from the widest width to the narrowest;
* the points are first scaled into the box ``[-1/1.1, 1/1.1]`` along their
  longest side, and the widths are the authors' preset for real scans
  (:data:`WIDTHS`), both widened together where the points are rougher than
  the narrowest allows: at widths below the noise, the field's normals follow
  each point's scatter instead of the surface (docs/how_it_works.md,
  thresholds).

The directions ``G mu`` after the last step are the field's normals. Where a
tree-oriented normal points against them, two methods that share nothing but
the points disagree about the side, and the point's side is in doubt.

The sums run over a one-level grid (:class:`DipoleGrid`): a cell counts as one
dipole for points farther than twice its side from its centre, the authors'
criterion for their octree's nodes. The widths and the cells are fractions of
the box, which the preset expects one object to fill: the objects of a cloud
are solved in groups of nearby ones (:func:`object_groups`), each in its box.

The field cannot see one mistake: where closed surfaces pass through each
other, their parts inside each other turned over leave a field as clean as
the right sides. Each surface's sheet goes on smoothly through the other, and
its normals turn over where it enters: :func:`split_sheets` finds such seams
and flags the side they contradict.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .._kernels.dipoles import GRADIENT, TRANSPOSED, WINDING, dipole_sums
from ..tuning import TUNING

__all__ = ["DipoleGrid", "WIDTHS", "field_normals", "noise_scatter", "object_groups", "roughness",
           "split_sheets"]

#: the smoothing width's narrowest and widest value in the scaled box: Lin et al.'s preset for real scans
WIDTHS = (0.01, 0.04)
#: points a grid cell aims at
CELL_POINTS = 32
#: nearest points whose heights over a point's tangent plane measure the cloud's roughness
ROUGHNESS_NEIGHBOURS = 8
#: nearest sources a source's sheet is followed to (:func:`split_sheets`)
SHEET_NEIGHBOURS = 8
#: the noise's scatter over a tangent plane: this many robust standard deviations of the heights of the
#: ``NOISE_NEIGHBOURS`` nearest points over it (:func:`noise_scatter`)
NOISE_CLEARANCE, NOISE_NEIGHBOURS = 2.0, 6


def field_normals(points: np.ndarray, widths: tuple[float, float] = WIDTHS,
                  iterations: int | None = None, axes: np.ndarray | None = None) -> np.ndarray:
    """The winding field's unit normals at the points, solved from no orientation (module docstring).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        At least two distinct points; cost about ``n * (a few hundred)`` pair terms a sum, four sums a step.
    widths : (float, float), optional
        The smoothing width's narrowest and widest value, in the box the points are scaled into.
    iterations : int, optional
        Steps of the iteration (``TUNING.field_iterations`` by default); at least 2.
    axes : ndarray, shape (n, 3), optional
        Unit normals of either sign: with them both widths grow, in proportion, until the narrowest is
        ``TUNING.field_roughness`` times the points' :func:`roughness`.

    Returns
    -------
    ndarray, shape (n, 3)
        Unit vectors, pointing out of what the points enclose.
    """
    iterations = TUNING.field_iterations if iterations is None else int(iterations)
    if iterations < 2:
        raise ValueError(f"the winding field's iteration needs at least 2 steps, got {iterations}")
    low, high = points.min(axis=0), points.max(axis=0)
    scaled = (points - (low + high) / 2.0) * (2.0 / (np.max(high - low) * 1.1))
    grid = DipoleGrid(scaled)
    narrow, wide = widths
    if axes is not None:  # noise would turn the field's normals at widths below it
        factor = max(1.0, TUNING.field_roughness * roughness(scaled, axes) / narrow)
        narrow, wide = narrow * factor, wide * factor
    mu = np.zeros((points.shape[0], 3))
    half = np.full(points.shape[0], 0.5)
    for step in range(iterations):
        width = narrow + (iterations - 1 - step) / (iterations - 1) * (wide - narrow)
        descent = grid.sum(TRANSPOSED, half - grid.sum(WINDING, mu, width)[:, 0], width)
        change = grid.sum(WINDING, descent, width)[:, 0]
        mu = mu + descent * (np.sum(descent * descent) / max(np.sum(change * change), np.finfo(float).tiny))
        direction = grid.sum(GRADIENT, mu, width)
        direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), np.finfo(float).tiny)
        mu = direction * np.linalg.norm(mu, axis=1, keepdims=True)
    return direction


def object_groups(x: np.ndarray, objects: np.ndarray) -> np.ndarray:
    """The group of every source, shape (m,), int, numbered from 0: objects whose boxes lie within
    ``TUNING.field_group_gap`` times the smaller box's size of each other, joined.

    The winding field's own normals (:func:`field_normals`) are smoothed
    over widths that are fractions of the box they are solved in, and the pairs nearer than the width
    are left out of the sums: over a box much larger than an object (two parts a hundred sizes
    apart) the width spans the object, its own sources drop out, and its normals follow the other
    object's field. Objects that nest or lie close (a cavity inside a shell, the pieces of one
    sampled surface) stay in one group, whose field still sees them together.

    Parameters
    ----------
    x : ndarray, shape (m, 3)
        The sources.
    objects : ndarray, shape (m,), int
        Their objects (:func:`heatcurv.orient.enclosure.source_objects`).

    Returns
    -------
    ndarray of int, shape (m,)
    """
    _, inverse = np.unique(objects, return_inverse=True)
    k = int(inverse.max()) + 1
    if k == 1:
        return np.zeros(x.shape[0], dtype=np.int64)
    low, high = np.full((k, 3), np.inf), np.full((k, 3), -np.inf)
    np.minimum.at(low, inverse, x)
    np.maximum.at(high, inverse, x)
    size = np.max(high - low, axis=1)
    # candidate pairs by their boxes' centres, then the gap between the boxes along the axis that parts them most
    centre = (low + high) / 2.0
    reach = (np.sqrt(3.0) + TUNING.field_group_gap) * float(size.max())
    pairs = cKDTree(centre).query_pairs(reach, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    gap = np.max(np.maximum(low[i] - high[j], low[j] - high[i]), axis=1)
    near = gap <= TUNING.field_group_gap * np.minimum(size[i], size[j])
    graph = sp.csr_matrix((np.ones(np.count_nonzero(near)), (i[near], j[near])), shape=(k, k))
    return csgraph.connected_components(graph, directed=False)[1][inverse]


def noise_scatter(heights: np.ndarray) -> np.ndarray:
    """How far off a tangent plane noise puts points, shape (m,): :data:`NOISE_CLEARANCE` robust standard
    deviations (1.4826 median absolute heights) of the :data:`NOISE_NEIGHBOURS` nearest.

    Parameters
    ----------
    heights : ndarray, shape (m, k)
        Each point's nearest neighbours' absolute heights over its tangent plane, nearest first
        (not the point itself).
    """
    return NOISE_CLEARANCE * 1.4826 * np.median(heights[:, :NOISE_NEIGHBOURS], axis=1)


def split_sheets(x: np.ndarray, normals: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Sources whose side a smooth sheet's continuation contradicts, shape (m,), bool.

    Two nearest sources are on one smooth sheet when each lies within
    ``TUNING.seam_tilt`` (a sine) of the other's tangent plane, or within the
    noise's scatter of it (:func:`noise_scatter`), and their normals'
    axes agree (``|cos| >= TUNING.seam_parallel``). Along such pairs whose normals
    agree closely (``cos >= TUNING.seam_along``: where two surfaces cross, the
    fitted normals bend from one to the other, and a looser test would join
    them), the sources fall into consistently oriented regions; at least
    ``TUNING.seam_pairs`` pairs on one sheet whose normals point opposite ways
    (more of them on a seam than on a fold, below) join two regions into one
    sheet whose normals turn over along a seam. That is
    what the winding number leaves where closed surfaces pass through each other
    (a sphere through a torus): with the parts of each inside the other turned
    over, the field is 1 inside their union and 0 in the overlap, as clean as the
    right answer. The regions joined by seams are made consistent (each seam
    turns one side), and each such sheet is given the side that makes its
    signed volume about its centroid, ``sum_i A_i (x_i - c) . n_i``, positive
    (outward, as the divergence theorem has it for a closed sheet); a source
    whose side this contradicts is in doubt, and so is every source of a sheet
    whose seams cannot all be made consistent. A pair facing opposite ways is
    on a seam only where each lies on the other's outer side as it would on one
    sheet (with one normal turned, the heights of each over the other's tangent
    plane have opposite signs); the two faces of a thin part folded at a knife
    edge (a plate's rim) each lie behind the other, and in a crease in front.

    Parameters
    ----------
    x, normals : ndarray, shape (m, 3)
        Sources and their oriented unit normals.
    weight : ndarray, shape (m,)
        Their areas.

    Returns
    -------
    ndarray of bool, shape (m,)
    """
    m = x.shape[0]
    k = min(SHEET_NEIGHBOURS, m - 1)
    doubt = np.zeros(m, dtype=bool)
    if k < 1:
        return doubt
    idx = cKDTree(x).query(x, k + 1)[1][:, 1:]
    offset = x[idx] - x[:, None, :]
    length = np.maximum(np.linalg.norm(offset, axis=2), np.finfo(float).tiny)
    # heights over each end's tangent plane, within the tilt or the noise's scatter there
    signed = np.einsum("ijk,ik->ij", offset, normals)
    signed_back = -np.einsum("ijk,ijk->ij", offset, normals[idx])
    height, back = np.abs(signed), np.abs(signed_back)
    scatter = noise_scatter(height)
    level = (height <= np.maximum(TUNING.seam_tilt * length, scatter[:, None])) & (
        back <= np.maximum(TUNING.seam_tilt * length, scatter[idx]))
    cosine = np.einsum("ijk,ik->ij", normals[idx], normals)
    sheet = level & (np.abs(cosine) >= TUNING.seam_parallel)
    rows, cols = np.repeat(np.arange(m), k), idx.ravel()
    along = (sheet & (cosine >= TUNING.seam_along)).ravel()
    n_region, region = csgraph.connected_components(
        sp.csr_matrix((np.ones(np.count_nonzero(along)), (rows[along], cols[along])), shape=(m, m)), directed=False)
    # pairs on one sheet facing opposite ways: on a seam each lies on the other's outer side, as on one
    # smooth sheet; two faces folded at a knife edge (a thin plate's rim) each lie behind the other (in front,
    # in a crease). Two regions are joined by a seam where enough such pairs join them, more seams than folds
    opposite = (sheet & (cosine < 0)).ravel()
    ends, first = np.unique(np.sort(np.column_stack([rows[opposite], cols[opposite]]), axis=1), axis=0,
                            return_index=True)
    is_seam = (signed * signed_back <= 0).ravel()[opposite][first]
    a, b = np.sort(region[ends], axis=1).T
    apart = a != b
    pairs, which, count = np.unique(np.column_stack([a, b])[apart], axis=0, return_inverse=True,
                                    return_counts=True)
    seam_count = np.bincount(which.ravel(), weights=is_seam[apart], minlength=len(pairs))
    pairs = pairs[(seam_count >= TUNING.seam_pairs) & (2 * seam_count > count)]
    if not pairs.size:
        return doubt
    seams = sp.csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n_region, n_region))
    n_sheet, sheet_of = csgraph.connected_components(seams, directed=False)
    # each seam turns one side: a region's parity is that of its depth in a breadth-first tree of its sheet
    parity = np.zeros(n_region, dtype=np.int64)
    for root in np.unique(pairs[:, 0][np.unique(sheet_of[pairs[:, 0]], return_index=True)[1]]):
        order, parent = csgraph.breadth_first_order(seams, root, directed=False, return_predecessors=True)
        for child in order[1:]:
            parity[child] = parity[parent[child]] ^ 1
    sign = np.where(parity[region] == 1, -1.0, 1.0)
    joined = np.bincount(sheet_of[np.unique(pairs)], minlength=n_sheet) > 0
    member = joined[sheet_of[region]]
    # the side of each joined sheet: its signed volume about its centroid
    owner = sheet_of[region][member]
    total = np.bincount(owner, weights=weight[member], minlength=n_sheet)
    centre = np.column_stack([np.bincount(owner, weights=weight[member] * x[member, d], minlength=n_sheet)
                              for d in range(3)]) / np.maximum(total, np.finfo(float).tiny)[:, None]
    volume = np.bincount(owner, weights=weight[member] * sign[member] * np.einsum(
        "ij,ij->i", x[member] - centre[owner], normals[member]), minlength=n_sheet)
    sign[member] *= np.where(volume[owner] < 0, -1.0, 1.0)
    doubt[member] = sign[member] < 0
    # a seam that the parities do not resolve (an odd cycle of seams): the whole sheet is in doubt
    unresolved = parity[pairs[:, 0]] == parity[pairs[:, 1]]
    doubt |= np.isin(sheet_of[region], sheet_of[pairs[unresolved, 0]])
    return doubt


def roughness(x: np.ndarray, axes: np.ndarray) -> float:
    """The median height of the :data:`ROUGHNESS_NEIGHBOURS` nearest points over each point's tangent plane.

    Parameters
    ----------
    x : ndarray, shape (n, 3)
    axes : ndarray, shape (n, 3)
        Unit normals of either sign.

    Returns
    -------
    float
        In the unit of ``x``: the noise, plus what the curvature lifts the neighbours by.
    """
    nearest = cKDTree(x).query(x, min(ROUGHNESS_NEIGHBOURS, x.shape[0] - 1) + 1)[1][:, 1:]
    return float(np.median(np.abs(np.einsum("ikj,ij->ik", x[nearest] - x[:, None, :], axes))))


class DipoleGrid:
    """Points sorted into the cells of a uniform grid of about :data:`CELL_POINTS` points a cell.

    Parameters
    ----------
    x : ndarray, shape (n, 3)
        The points, spread over a surface (the cell's side grows with the square root of its points).
    """

    def __init__(self, x: np.ndarray):
        extent = float(np.max(np.ptp(x, axis=0)))
        self.side = extent * (CELL_POINTS / x.shape[0]) ** 0.5
        key = np.floor((x - x.min(axis=0)) / self.side).astype(np.int64)
        flat = (key[:, 0] * (key[:, 1].max() + 1) + key[:, 1]) * (key[:, 2].max() + 1) + key[:, 2]
        self.order = np.argsort(flat, kind="stable")
        self.start = np.append(np.unique(flat[self.order], return_index=True)[1], x.shape[0]).astype(np.int64)
        self.x = np.ascontiguousarray(x[self.order])

    def sum(self, kind: int, values: np.ndarray, width: float) -> np.ndarray:
        """One sum of :mod:`heatcurv._kernels.dipoles` at every point, shape (n, 3), in the points' order.

        Parameters
        ----------
        kind : int
            ``WINDING`` (result in the first column), ``TRANSPOSED`` (``values`` a scalar a point) or ``GRADIENT``.
        values : ndarray, shape (n, 3) or (n,)
        width : float
        """
        sorted_values = np.zeros((self.x.shape[0], 3))
        column = values.reshape(self.x.shape[0], -1)
        sorted_values[:, : column.shape[1]] = column[self.order]
        out = np.empty((self.x.shape[0], 3))
        out[self.order] = dipole_sums(kind, self.x, sorted_values, self.start, 2.0 * self.side, width)
        return out
