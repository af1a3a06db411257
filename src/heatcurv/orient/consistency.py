"""Normals of the winding field itself, solved from no orientation: a second opinion on every side.

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
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .._kernels.dipoles import GRADIENT, TRANSPOSED, WINDING, dipole_sums
from ..tuning import TUNING

__all__ = ["DipoleGrid", "WIDTHS", "field_normals", "object_groups", "roughness"]

#: the smoothing width's narrowest and widest value in the scaled box: Lin et al.'s preset for real scans
WIDTHS = (0.01, 0.04)
#: points a grid cell aims at
CELL_POINTS = 32
#: nearest points whose heights over a point's tangent plane measure the cloud's roughness
ROUGHNESS_NEIGHBOURS = 8


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
