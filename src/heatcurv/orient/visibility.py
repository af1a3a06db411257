"""The side a point's rays escape from: outward for the points the winding number cannot vouch for.

On a closed surface every ray leaving a point inwards hits the surface again,
while some of the rays leaving it outwards reach the open space around the
object. This needs no orientation of the surface at all: each occluder is an
unoriented disc (a point, its normal's axis, a radius), so the test holds
where the winding number's field does not: on a part whose patch the
spanning tree turned over together with its neighbours, or one that straddles
both sides of a leg (the field around such a spot is made by the same wrong
normals, and its levels disagree with every side; :mod:`.enclosure` flags
it).

For each tested point, :data:`CONE` rays fan out around ``+n`` and as many
around ``-n``; a ray *escapes* when it leaves the cloud's bounding box without
crossing a disc farther than :data:`REACH` spacings from its point (nearer ones
are the point's own surface). The point's vote is the share of its rays along
``+n`` that escape minus the share along ``-n``; a vote below
``-TUNING.escape_margin`` turns the point over. Points in a closed pocket (an
armpit, the gap between two legs) see no escape either way (vote 0) and keep
their side.

On a noisy cloud a point's own surface is a layer as thick as the noise: a
point low in it sees its neighbours' discs above it, and on an open noisy tube
its outward rays stop there while its inward ones leave through the ends. So
hits within :data:`NOISE_CLEARANCE` noise deviations (along a slanted ray, as
far as it takes to cross that layer) are the point's own surface too
(:func:`own_layer`), but only where the kernel choice's residual is
noise: on a coarse mesh the residual is the facets' misfit, as large as its
thin parts are thick, and widening the clearance there would hide the far side
of a leg.

The occluders are the winding number's sources (every point of a small cloud,
a sample of a large one: the same sample in a tiled run), their discs as wide as
the distance to their :data:`DISC_NEIGHBOURS`-th nearest source, so that a
sampled cloud has no holes for a ray to slip through.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .._kernels.visibility import escaping_rays
from ..geometry.validation import row_hashes
from ..tuning import TUNING

__all__ = ["CONE", "DISC_NEIGHBOURS", "MAX_TESTED", "NOISE_CLEARANCE", "REACH", "escape_votes", "escaping_turns",
           "lowest_keys", "own_layer"]

#: The rays around each side of a normal: (angle from the normal in degrees, rays at that angle).
CONE = ((0.0, 1), (30.0, 6), (60.0, 8))
#: An occluder's disc reaches its this-many-th nearest occluder.
DISC_NEIGHBOURS = 6
#: Hits nearer than this many median occluder spacings are the point's own surface.
REACH = 1.5
#: Hits nearer than this many noise deviations are the point's own surface: two points of one noisy
#: surface lie up to about three deviations either side of it.
NOISE_CLEARANCE = 6.0
#: Most points tested in one cloud (those of lowest coordinate rank, :func:`lowest_keys`).
MAX_TESTED = 100_000


def own_layer(sigma: float, rise: float) -> float:
    """How far from its point, along the normal, a ray's hits are the point's own surface (besides :data:`REACH`).

    Parameters
    ----------
    sigma : float
        The kernel choice's noise (:attr:`heatcurv.choice.scale.ScaleChoice.sigma`), in the points' unit.
    rise : float
        Its :attr:`heatcurv.choice.scale.ScaleChoice.residual_rise` (NaN: not measured).

    Returns
    -------
    float
        ``NOISE_CLEARANCE * sigma`` where the residual is noise (``rise <= TUNING.noise_rise``), else 0.
    """
    return NOISE_CLEARANCE * sigma if rise <= TUNING.noise_rise else 0.0


def escape_votes(points: np.ndarray, normals: np.ndarray, occluders: np.ndarray,
                 occluder_normals: np.ndarray, layer: float = 0.0) -> np.ndarray:
    """The share of each point's rays that escape along its normal minus the share that escape against it.

    Parameters
    ----------
    points : ndarray, shape (m, 3)
        The tested points.
    normals : ndarray, shape (m, 3)
        Their unit normals.
    occluders : ndarray, shape (s, 3)
        The discs' centres (``s >= DISC_NEIGHBOURS + 1``).
    occluder_normals : ndarray, shape (s, 3)
        The discs' unit axes (either sign).
    layer : float, optional
        The thickness of the point's own surface (:func:`own_layer`): a ray at angle ``a``
        from the normal ignores hits within ``layer / cos(a)`` too.

    Returns
    -------
    ndarray, shape (m,)
        Votes in ``[-1, 1]``: 1 when every ray along the normal escapes and
        none against it.
    """
    m = points.shape[0]
    if m == 0:
        return np.zeros(0)
    distance = cKDTree(occluders).query(occluders, k=DISC_NEIGHBOURS + 1)[0]
    spacing = float(np.median(distance[:, 1]))
    radius = distance[:, DISC_NEIGHBOURS]
    # a sparse spot's disc is no wider than twice the median's (the grid's cells are as wide as the widest)
    radius = np.clip(radius, 1e-3 * spacing, 2.0 * np.median(radius))
    # one grid for both fans: the points twice, along their normals, then against them
    # a slanted ray meets a neighbour's disc in the layer farther from its point, by 1 / cos of its angle
    slant = np.concatenate([np.full(count, 1.0 / np.cos(np.radians(angle))) for angle, count in CONE])
    escaped = escaping_rays(np.concatenate([points, points]), np.concatenate([_fan(normals), _fan(-normals)]),
                            np.maximum(REACH * spacing, layer * slant), occluders, occluder_normals, radius)
    return (escaped[:m] - escaped[m:]) / sum(count for _, count in CONE)


def escaping_turns(points: np.ndarray, normals: np.ndarray, tested: np.ndarray, occluders: np.ndarray,
                   occluder_normals: np.ndarray, layer: float = 0.0) -> np.ndarray:
    """The tested points whose rays escape clearly more against their normal than along it.

    Parameters
    ----------
    points, normals : ndarray, shape (n, 3)
    tested : ndarray, shape (n,), bool
        The points to test; past :data:`MAX_TESTED`, those of lowest coordinate
        rank (:func:`heatcurv.geometry.validation.row_hashes`, the same in any
        tile).
    occluders, occluder_normals : ndarray, shape (s, 3)
    layer : float, optional
        As :func:`escape_votes`.

    Returns
    -------
    ndarray, shape (n,), bool
        Points to turn over: a vote below ``-TUNING.escape_margin``.
    """
    rows = np.flatnonzero(tested)
    rows = rows[lowest_keys(row_hashes(points[rows]))]
    turn = np.zeros(points.shape[0], dtype=bool)
    votes = escape_votes(points[rows], normals[rows], occluders, occluder_normals, layer)
    turn[rows[votes < -TUNING.escape_margin]] = True
    return turn


def lowest_keys(keys: np.ndarray, limit: int = MAX_TESTED) -> np.ndarray:
    """Positions of the ``limit`` lowest ``keys`` (all when fewer), sorted, shape (min(len(keys), limit),)."""
    if keys.size <= limit:
        return np.arange(keys.size)
    return np.sort(np.argpartition(keys, limit)[:limit])


def _fan(normals: np.ndarray) -> np.ndarray:
    """The :data:`CONE` directions around each normal, shape (m, rays, 3)."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(normals, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(normals, u)
    directions = []
    for ring, (angle, count) in enumerate(CONE):
        polar = np.radians(angle)
        for k in range(count):
            turn = 2.0 * np.pi * (k + 0.5 * (ring % 2 == 0)) / count  # the rings' rays staggered
            tangent = np.cos(turn) * u + np.sin(turn) * v
            directions.append(np.cos(polar) * normals + np.sin(polar) * tangent)
    return np.stack(directions, axis=1)
