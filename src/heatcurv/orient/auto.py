"""``orient="auto"`` without a viewpoint: whether a cloud is an open surface over a plane, decided on a sample.

:func:`auto_policy` reads the 2000 sample centres of the kernel choice (a
tiled run's survey holds the same centres, so it decides alike): ``"up"``
for an open surface over the horizontal plane, the same along the cloud's
own axis for an open surface over another plane, ``"outward"`` for anything
else (:mod:`heatcurv.orient.orientation` then orients by that policy).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from .._kernels import segment as kernels
from ..geometry.neighbourhood import knn_neighbourhood
from ..tuning import TUNING
from .enclosure import vertical_sums
from .orientation import AutoPolicy, coordinate_convention, edge_agreement, tree_sides

__all__ = ["AUTO_NEIGHBOURS", "auto_policy", "convex_side"]

#: Nearest sample points each sample normal and the sample's spanning tree use.
AUTO_NEIGHBOURS = 16


def auto_policy(centres: np.ndarray, noise: float = 0.0) -> AutoPolicy:
    """``orient="auto"`` without a viewpoint: ``"up"`` for an open surface over the ground plane, else ``"outward"``.

    A surface whose consistent orientation puts every normal's ``n_z`` on the
    same side is a graph over the horizontal plane (terrain, roofs, a scan
    from above), where "up" is the side everyone expects; a closed surface has
    ``sum_i A_i n_z,i = 0`` (divergence theorem), as much facing down as up,
    whichever way it is turned. So the sample's PCA normals (each point's
    :data:`AUTO_NEIGHBOURS` nearest) are oriented consistently by the spanning
    tree of :func:`heatcurv.orient.orientation.orient` (its trees joined
    across narrow gaps, :func:`_joined_trees`), and the cloud is
    oriented ``"up"`` when at least ``TUNING.auto_share`` of them lie within 45
    degrees of vertical (some ground: a street between tall facades has a
    seventh) and at most ``TUNING.auto_down_share`` of the ``sum |n_z|`` of the
    flat ones (``TUNING.auto_flatness``: not a tree crown's scatter) that face
    up or down at all (``|n_z| >= TUNING.auto_wall_cosine``: not a wall, whose
    ``n_z`` is noise) faces down, counted per point and per the area each
    stands for (``TUNING.auto_area_range``), the larger, and at most
    ``TUNING.auto_layered_share`` of the flat points lie straight over or
    under another sheet, seen along
    ``z`` or along the cloud's own axis (:func:`_layered_share`: a thin closed
    object, whose two sides the tree can orient alike) and at most
    ``TUNING.auto_split_share`` have balls whose residuals split in two layers
    (:func:`_split_share`: the same object thinner still). Under noise as
    thick as the sample's balls almost none of them is flat and the tests
    read noise, so at least ``TUNING.auto_flat_share`` of the sample must be
    flat (a sphere of 5000 points with noise of 3 % of its diagonal has
    0.25 % of its sample flat, and those few may all face up).

    A cloud that fails this test along ``z``, or passes it with fewer than
    ``TUNING.auto_level_share`` of its normals within 45 degrees of vertical,
    is tested again along the axis of its flat sample normals (the top
    eigenvector of ``sum_i n_i n_i^T``): a
    surface over a plane that is not horizontal (a terrain tile turned in a
    scanner's frame, a range scan seen from the side, a facade) is then
    oriented ``"up"`` along that axis (:attr:`AutoPolicy.towards`), towards
    its convex side (:func:`convex_side`), so that its sheets get one side
    each point by point, as terrain does, instead of the spanning tree's
    sides, which a tree crown's scatter carries at random; failing there, it
    keeps the verdict along ``z``. A closed surface fails along every axis
    (its outward normals face every way alike).

    Parameters
    ----------
    centres : ndarray, shape (q, 3)
        A sample of the cloud's distinct points spread over it, any order (they
        are sorted first, so that the same set decides alike): the scale
        choice's ``n_sub`` centres.
    noise : float, optional
        The cloud's noise, length units (:func:`heatcurv.choice.scale.centre_noise`,
        the scale choice's ``sigma``).

    Returns
    -------
    AutoPolicy
    """
    centres = np.asarray(centres, dtype=np.float64)
    centres = centres[np.lexsort(centres.T[::-1])]
    q = centres.shape[0]
    if q < 4:
        return AutoPolicy("outward", 0.0, 0.0)
    k = min(AUTO_NEIGHBOURS, q - 1)
    tree = cKDTree(centres)
    nbhd = knn_neighbourhood(centres, k, tree=tree, workers=1)
    # plain PCA of each point and its k nearest: the eigenvector of the smallest eigenvalue
    near = centres[tree.query(centres, k + 1)[1]]
    spread = near - near.mean(axis=1, keepdims=True)
    eigenvalues, eigenvectors = np.linalg.eigh(np.einsum("nki,nkj->nij", spread, spread))
    normals = eigenvectors[:, :, 0]
    flat = eigenvalues[:, 0] <= TUNING.auto_flatness * eigenvalues[:, 1]
    oriented, _, labels = tree_sides(centres, normals, nbhd)
    spacing = float(np.median(nbhd.distances[nbhd.indptr[:-1]]))  # to each point's nearest: rows nearest first
    oriented, labels = _joined_trees(centres, oriented, labels, spacing)
    split = _split_share(centres, normals, tree, spacing)  # the balls' split needs no vertical: read once
    # each centre's share of the surface: the sample is as dense as the cloud, so a centre stands for an area
    # in proportion to its k nearest's disc; the down share sums n_z over area (the divergence theorem), not
    # over points, each area kept within TUNING.auto_area_range of the median so that a stray point far from
    # the surface weighs no more than a few centres
    area = nbhd.radius**2
    typical = float(np.median(area))
    area = np.clip(area, typical / TUNING.auto_area_range, typical * TUNING.auto_area_range)
    sample = _Sample(centres, normals, flat, oriented, labels, spacing, noise, split, area)
    # the flat normals' own axis: a surface over a plane turned away from horizontal, a plate's normal
    axis = np.linalg.eigh(np.einsum("ni,nj->ij", normals[flat], normals[flat]))[1][:, -1] if flat.any() else None
    vertical = _over_plane(sample, np.array([0.0, 0.0, 1.0]), axis)
    if axis is None or (vertical.mode == "up" and vertical.vertical >= TUNING.auto_level_share):
        return vertical
    # a cloud with little ground is over its own plane if it is (a scan from the side), else over the
    # horizontal one if it is (a street between tall facades)
    tilted = _over_plane(sample, axis, axis)
    if tilted.mode != "up":
        return vertical
    towards, convex = convex_side(centres, oriented, axis)
    return replace(tilted, towards=tuple(float(c) for c in towards), convex=convex)


def _joined_trees(centres: np.ndarray, oriented: np.ndarray, labels: np.ndarray, spacing: float) -> tuple:
    """The sample's spanning trees joined across narrow gaps: ``oriented`` and ``labels``, shapes as given.

    Keys that vary smoothly over a symmetric cloud (a lattice on a sphere,
    whose points all lie at one distance from the centroid) can leave bands
    of it without a sample point; the sample's forest then falls into
    pieces, each of which is a graph over some plane, and a closed surface
    would pass for an open one. So the two largest-enough trees (at least
    ``TUNING.auto_join_share`` of the sample each) whose nearest points are
    closest are joined, repeatedly, while those points are at most
    ``TUNING.auto_join_reach`` sample spacings apart and their normals'
    agreement (:func:`heatcurv.orient.orientation.edge_agreement`) is clear
    (``|s| >= 0.5``): the smaller tree is flipped to agree with the larger.
    Separate objects further apart keep their own trees.

    Parameters
    ----------
    centres, oriented : ndarray, shape (q, 3)
        The sample and its normals oriented tree by tree.
    labels : ndarray, shape (q,)
        Each point's tree.
    spacing : float
        The median distance from a sample point to its nearest.
    """
    oriented, labels = oriented.copy(), labels.copy()
    while True:
        sizes = np.bincount(labels)
        large = np.flatnonzero(sizes >= TUNING.auto_join_share * labels.size)
        if large.size < 2:
            break
        in_large = np.isin(labels, large)
        gap, a, b = np.inf, -1, -1
        for tree in large:
            mine, others = np.flatnonzero(labels == tree), np.flatnonzero(in_large & (labels != tree))
            distance, nearest = cKDTree(centres[others]).query(centres[mine])
            k = int(np.argmin(distance))
            if distance[k] < gap:
                gap, a, b = float(distance[k]), int(mine[k]), int(others[nearest[k]])
        agreement = float(edge_agreement(centres, oriented, np.array([a]), np.array([b]))[0])
        if gap > TUNING.auto_join_reach * spacing or abs(agreement) < 0.5:
            break
        smaller, larger = sorted((labels[a], labels[b]), key=lambda tree: sizes[tree])
        if agreement < 0:
            oriented[labels == smaller] *= -1.0
        labels[labels == smaller] = larger
    return oriented, np.unique(labels, return_inverse=True)[1]


class _Sample(NamedTuple):
    """What :func:`auto_policy` measured on its sample (q points)."""

    centres: np.ndarray  # (q, 3), sorted
    normals: np.ndarray  # (q, 3), unoriented PCA normals
    flat: np.ndarray  # (q,), bool: TUNING.auto_flatness
    oriented: np.ndarray  # (q, 3), the normals oriented by the spanning tree
    labels: np.ndarray  # (q,), the tree's components
    spacing: float  # median distance to the nearest sample point
    noise: float  # the cloud's noise, length units
    split: float  # _split_share
    area: np.ndarray  # (q,), the area each centre stands for


def _over_plane(sample: _Sample, up: np.ndarray, axis: np.ndarray | None) -> AutoPolicy:
    """:func:`auto_policy`'s test with the unit vector ``up``, shape (3,), as the vertical.

    The sample is turned so that ``up`` is ``+z``. The layered share is the
    larger of the one seen along ``up`` and the one seen along the flat
    normals' own ``axis``, shape (3,) (a thin plate turned away from ``up``
    lies one face over the other along its own normal only).
    """
    centres, normals, oriented = _in_frame(sample, up)
    flat, labels, spacing, noise, split = sample.flat, sample.labels, sample.spacing, sample.noise, sample.split
    nz, n_comp = oriented[:, 2], int(labels.max()) + 1
    # per component, the smaller of the upward and downward sums of n_z over its flat points that are not walls
    # (either side: the tree's root chose it); counted per centre and per area, the larger: a small closed object
    # on wide terrain faces down over few square metres but many points, a sparse half over few points but
    # much area, and either makes the cloud no terrain
    down = max(_down_share(nz, weight, flat, labels, n_comp) for weight in (np.ones_like(nz), sample.area))
    share = float(np.mean(np.abs(nz) >= TUNING.auto_vertical_cosine))
    layered = _layered_share(centres, normals, flat, noise, spacing)
    if axis is not None and not np.array_equal(axis, up):
        along, turned, _ = _in_frame(sample, axis)
        layered = max(layered, _layered_share(along, turned, flat, noise, spacing))
    # a sample with (almost) no flat balls shows no surface: its few flat points' n_z say nothing of a plane
    flat_share = float(flat.mean())
    terrain = share >= TUNING.auto_share and down <= TUNING.auto_down_share and flat_share >= TUNING.auto_flat_share
    mode = "up" if terrain and layered <= TUNING.auto_layered_share and split <= TUNING.auto_split_share else "outward"
    return AutoPolicy(mode, share, down, layered, split, flat_share)


def _down_share(nz: np.ndarray, weight: np.ndarray, flat: np.ndarray, labels: np.ndarray, n_comp: int) -> float:
    """The share of ``sum w |n_z|`` (flat, not walls) on each component's less-faced side, over all components."""
    upward, downward = vertical_sums(nz, weight, flat, labels, n_comp)
    total = float((upward + downward).sum())
    return float(np.minimum(upward, downward).sum() / total) if total > 0 else 0.0


def _in_frame(sample: _Sample, up: np.ndarray) -> tuple:
    """The sample's centres, normals and oriented normals, each shape (q, 3), turned so that ``up`` is ``+z``."""
    if np.array_equal(up, (0.0, 0.0, 1.0)):
        return sample.centres, sample.normals, sample.oriented
    basis = _frame(up)
    return sample.centres @ basis.T, sample.normals @ basis.T, sample.oriented @ basis.T


def _frame(up: np.ndarray) -> np.ndarray:
    """A right-handed orthonormal basis, shape (3, 3), rows x, y, z, whose third row is the unit vector ``up``."""
    helper = np.eye(3)[np.argmin(np.abs(up))]
    x = np.cross(helper, up)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(up, x), up])


def convex_side(centres: np.ndarray, oriented: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, bool]:
    """``axis`` or ``-axis``: the side a surface over the plane across ``axis`` bulges out to; whether it could tell.

    The sample's normals within 45 degrees of the axis, each turned to face
    it, vote as the outward vote does (``sum_i n_i . (x_i - c)``, 0 on a
    plane). A curved surface (a face, a scan of a round object) votes clearly;
    a vote below ``TUNING.convex_vote`` of its strength (a terrain tile, whose
    sheet is nearly flat, a saddle) could turn over between a cloud and its
    random half, so the axis's largest coordinate is made positive instead,
    a convention on the coordinates.
    """
    facing = oriented @ axis
    steep = np.abs(facing) >= TUNING.auto_vertical_cosine
    radial = np.where(facing < 0, -1.0, 1.0) * np.einsum("ij,ij->i", oriented, centres - centres.mean(axis=0))
    vote, strength = radial[steep].sum(), np.abs(radial[steep]).sum()
    if not abs(vote) >= TUNING.convex_vote * strength:
        return coordinate_convention(axis), False
    return (axis if vote > 0 else -axis), True


def _split_share(centres: np.ndarray, normals: np.ndarray, tree: cKDTree, spacing: float) -> float:
    """Share of the sample whose balls' residuals split in two layers (``TUNING.auto_split_share``).

    The ball is the point's ``TUNING.auto_split_neighbours`` nearest sample points, read as
    :func:`heatcurv.flags.sheets.layered_balls` reads a point's ball, with the median sample spacing as the spacing.

    Parameters
    ----------
    centres, normals : ndarray, shape (q, 3)
        The sample and its unoriented PCA normals.
    tree : cKDTree
        Of ``centres``.
    spacing : float
        The median distance from a sample point to its nearest.

    Returns
    -------
    float
    """
    k = min(TUNING.auto_split_neighbours, centres.shape[0] - 1)
    if k < 6:
        return 0.0
    ball = knn_neighbourhood(centres, k, tree=tree, workers=1)
    moments = kernels.quadric_residual_moments(centres, normals, ball.indptr, ball.indices,
                                               np.full(centres.shape[0], spacing))
    split = (moments[:, 0] > TUNING.layer_residual * spacing) & (moments[:, 1] < TUNING.layer_kurtosis)
    return float(np.count_nonzero(split) / centres.shape[0])


def _layered_share(centres: np.ndarray, normals: np.ndarray, flat: np.ndarray, noise: float, spacing: float) -> float:
    """Share of the flat, near-vertical sample points with a second sheet over or under them (``auto_layered_share``).

    The other point is a second sheet of the same thin object: higher than
    ``TUNING.auto_layer_height`` sample spacings and ``TUNING.auto_layer_noise``
    times the noise, and at most ``TUNING.auto_layer_reach`` sample spacings
    away (not the facade across a street).

    Parameters
    ----------
    centres, normals : ndarray, shape (q, 3)
        The sample and its unoriented PCA normals, in the frame whose ``z`` is the vertical.
    flat : ndarray, shape (q,), bool
        Flat sample points (``TUNING.auto_flatness``); those whose normal lies
        within 45 degrees of vertical count.
    noise : float
        The cloud's noise, length units.
    spacing : float
        The median distance from a sample point to its nearest.

    Returns
    -------
    float
        0 when fewer than two points count.
    """
    rows = np.flatnonzero(flat & (np.abs(normals[:, 2]) >= TUNING.auto_vertical_cosine))
    if rows.size < 2:
        return 0.0
    # pairs within one spacing of each other seen from above, at any height
    pairs = cKDTree(centres[rows, :2]).query_pairs(spacing, output_type="ndarray")
    # ordered both ways: a point over another is layered, and so is the one under it
    first, second = rows[np.concatenate([pairs[:, 0], pairs[:, 1]])], rows[np.concatenate([pairs[:, 1], pairs[:, 0]])]
    offset = centres[second] - centres[first]
    height = np.abs(np.einsum("ij,ij->i", offset, normals[first]))
    lateral = np.sqrt(np.maximum(np.einsum("ij,ij->i", offset, offset) - height**2, 0.0))
    over = (height > lateral) & (height > max(TUNING.auto_layer_height * spacing, TUNING.auto_layer_noise * noise))
    over &= height <= TUNING.auto_layer_reach * spacing
    return float(np.unique(first[over]).size / rows.size)
