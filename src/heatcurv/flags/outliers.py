"""Outliers: stray points and islands that are not part of any surface the kernel can measure.

Range scans and LiDAR carry points that belong to no surface at the kernel's
scale: single points floating off the surface (dust, multipath, mixed pixels
at silhouettes) and small islands of a few dozen points far from everything
else. Their balls must hold ``k`` neighbours, so they reach out to whatever
lies nearest: the curvature there is meaningless, and the density area of a
point whose ball spans a void is huge (measured on an 86k-point face range
scan: 919 stray points carried 80 % of the total area, one point 32,000 mm^2
against 0.23 mm^2 typical). Four tests, free of any length threshold:

1. **Detached.** Link two points when each lies in the other's ball (a
   mutual-neighbour graph over 10 of each ball's neighbours, spread to its
   edge as for the orientation): the graph never bridges a gap that is wide
   compared with the balls on both sides, yet stays connected across the
   scan lines of an anisotropic scan. A point is detached when its component
   has fewer points than a typical ball (it cannot fill its own kernel) or
   when fewer than half of its ball's neighbours are in its own component
   (its kernel is dominated by another piece of the cloud). Single far points
   are components of one.
2. **Isolated.** A point much sparser than the surface around it: its own
   ``d_6`` more than ``TUNING.isolation_factor`` times the median ``d_6`` of its
   ball's neighbours, or its ball more than ``TUNING.ball_ratio_max`` times as wide
   as theirs (a point off the surface, or the veil of mixed pixels a range
   scanner leaves in the gaps at depth discontinuities; measured on the face
   scan: no point of the scan's main surface exceeds 1.7 in ball ratio).
3. **Sparse ball.** On a sampled surface the ball's radius ``R`` and the 6th
   neighbour's distance ``d_6`` obey ``(R / d_6)^2 ~ count / 6``. A point in a
   small tight cluster or a short trail inside a much emptier ball has
   ``(R / d_6)^2 > TUNING.sparse_factor * count / 6``: the density at the ball's scale
   is less than ``1 / TUNING.sparse_factor`` of the density at the point.
4. **Amid strays.** A point more than half of whose ball the three tests
   above flag: its kernel measures strays, not a surface (a trail of a few
   points along a scan line inside a veil, one spacing apart and many from
   anything else, whose area was two hundred times the typical one).

Outliers are flagged unreliable and get area 0: ``result.area.sum()`` is the
area of the measured surface, strays excluded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._kernels import graph as graph_kernels
from .._kernels import segment as kernels
from ..geometry.neighbourhood import Neighbourhood
from ..tuning import TUNING

__all__ = ["Outliers", "find_outliers", "neighbour_medians", "exceeds_neighbour_median"]

#: Neighbours per point in the mutual-neighbour graph.
LINK_NEIGHBOURS = 10
#: Rank of the neighbour whose distance is a point's local spacing.
SPACING_RANK = 6


@dataclass(frozen=True)
class Outliers:
    """Points that are not part of a measurable surface.

    Attributes
    ----------
    mask : ndarray, shape (n,), bool
        ``detached | isolated | sparse``, and the points whose balls are mostly those.
    detached : ndarray, shape (n,), bool
        Fewer than half of the ball's neighbours in the point's own component
        of the mutual-neighbour graph, or a component smaller than a typical ball
        (single far points and small islands).
    isolated : ndarray, shape (n,), bool
        Much sparser than its ball's neighbours (points off the surface, veils).
    sparse : ndarray, shape (n,), bool
        The ball is much emptier than the point's surroundings.
    """

    mask: np.ndarray
    detached: np.ndarray
    isolated: np.ndarray
    sparse: np.ndarray

    @property
    def count(self) -> int:
        """Number of outliers."""
        return int(self.mask.sum())


def find_outliers(points: np.ndarray, nbhd: Neighbourhood) -> Outliers:
    """Stray points and islands of a cloud (see the module's description).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    nbhd : Neighbourhood
        The kernel's ball of every point (``nbhd.radius`` its radius).

    Returns
    -------
    Outliers
    """
    near = nbhd.nearest(SPACING_RANK)
    counts = near.counts
    # d_6, or the farthest neighbour a sparser row has
    spacing = np.where(counts > 0, near.radius, np.inf)
    links = nbhd.spread(LINK_NEIGHBOURS)
    # mutual: i in j's ball as well as j in i's (an augmented row's far neighbours are not in its ball)
    mutual = (links.distances <= links.radius[links.rows]) & (links.distances <= nbhd.radius[links.indices])
    # components over the mutual pairs, compiled (a union-find over the CSR entries: no graph copy)
    n_comp, labels = graph_kernels.connected_components(links.indptr, links.indices, mutual)

    ball_counts = nbhd.counts
    # a component smaller than a typical ball cannot fill its own kernel
    too_small = np.bincount(labels, minlength=n_comp)[labels] < np.median(ball_counts)
    own_share = kernels.same_label_counts(labels, nbhd.indptr, nbhd.indices) / np.maximum(ball_counts, 1)
    detached = too_small | (own_share < TUNING.own_share)
    with np.errstate(divide="ignore", invalid="ignore"):
        sparse = (nbhd.radius / spacing) ** 2 > TUNING.sparse_factor * ball_counts / SPACING_RANK
    sparse &= ball_counts > SPACING_RANK
    isolated = exceeds_neighbour_median(spacing, TUNING.isolation_factor, nbhd)
    isolated |= exceeds_neighbour_median(nbhd.radius, TUNING.ball_ratio_max, nbhd)
    strays = detached | isolated | sparse
    # a point whose ball is mostly strays measures them, not a surface (a short trail in a veil)
    amid = kernels.flagged_within(strays, nbhd.indptr, nbhd.indices, nbhd.distances, nbhd.radius)
    amid_strays = ~strays & (amid[:, 1] > TUNING.own_share * ball_counts)
    return Outliers(strays | amid_strays, detached, isolated, sparse)


def exceeds_neighbour_median(values: np.ndarray, factor: float, nbhd: Neighbourhood) -> np.ndarray:
    """``values > factor * neighbour_medians(values, nbhd)``, shape (n,), bool, mostly without a median.

    With ``u_j = factor * values[j]`` (rounded, so still in the order of the
    values) and ``k = c // 2`` for a row of ``c`` neighbours: the value exceeds
    ``factor`` times the median when more than ``k`` of the ``u_j`` lie below
    it (the upper middle does), and does not when fewer than ``k`` do (the
    lower middle does not). Only an even row with exactly ``k`` below, its
    value between the two middles, needs the median itself. The same answer
    as through :func:`neighbour_medians` (two selections per point: 1.6 s on
    a million points; the counts 0.1 s); false for a row without neighbours.
    """
    counts = nbhd.counts
    below = kernels.counts_below(values, factor, values, nbhd.indptr, nbhd.indices)
    half = counts // 2
    exceeds = below > half
    undecided = np.flatnonzero((counts % 2 == 0) & (counts > 0) & (below == half))
    if undecided.size:
        median = neighbour_medians(values, nbhd.take_rows(undecided))
        exceeds[undecided] = values[undecided] > factor * median
    return exceeds


def neighbour_medians(values: np.ndarray, nbhd: Neighbourhood) -> np.ndarray:
    """Median of ``values[j]`` over each point's neighbours ``j``, shape (n,) (NaN where a row is empty).

    A compiled quickselect per row (:func:`heatcurv._kernels.segment.neighbour_medians`;
    the numpy sort it replaced took 1.8 s per call on a million points).
    """
    return kernels.neighbour_medians(values, nbhd.indptr, nbhd.indices)
