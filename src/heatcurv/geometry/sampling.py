"""Subsets of a cloud drawn from its geometry, so that no result depends on the input's point order.

Some stages work on a subset of the points: the kernel check measures a
sample of balls, the kernel choice fits a sample of centres, and wide kernels
are fitted at anchors (:mod:`heatcurv.fits.anchors`, :func:`key_thinning`). A
subset drawn with a random generator over row numbers changes when the rows
are permuted, and the k-d tree's leaf order (the stages' row order) changes
with any rotation or translation: results then moved by up to 1.3 % (mean
curvature) and 5.7 % (area) under a rotation of a noisy cloud.

Here every point gets a pseudo-random key computed from quantities a rigid
motion, a uniform scaling and a permutation leave unchanged (up to rounding):
its distance to the cloud's centroid and the size of its neighbourhood (the
k-th and the nearest neighbour's distances, or the count in a fixed ball), the
lengths relative to the cloud's root-mean-square radius (a quantity a tiled
run knows before it reads any tile, :mod:`heatcurv.choice.choices`). A subset of size ``s`` is the
``s`` points with the smallest keys.

On a cloud with a symmetry of its own (the vertices of a UV sphere, a grid on a
surface of revolution) every point of a ring has the same features, so an
invariant key would take whole rings or none: a sample of a few rings far apart,
which the orientation read as terrain (a UV sphere of 8000 vertices or more
came out "up", half of it inside out and reliable). A point with such a twin
among its nearest neighbours (features equal within :data:`TIE_TOLERANCE`)
takes its key from its position instead (:func:`position_keys`): the same in
every tile, and unchanged by a translation or a uniform scaling, but not by a
rotation; on a symmetric cloud a rotation of the whole maps its rings onto
themselves anyway.
"""

from __future__ import annotations

import numpy as np

from .neighbourhood import Neighbourhood

__all__ = ["geometric_keys", "key_sample", "key_spread", "key_thinning", "draw_subset", "position_keys",
           "shifted_keys"]

#: Multiplier of the invariant features before their fractional part is taken: large enough that
#: neighbouring points' keys are unrelated (features differ by about 1e-3 between neighbours),
#: small enough that rounding (1e-16 relative; 1e-10 after a translation by 1e6 times the
#: cloud's size) moves a key by far less than the gap between keys (1 / n).
KEY_SPREAD = 2.0**12
_GOLDEN = 0.6180339887498949
_SILVER = 0.4142135623730951
#: Relative difference within which two neighbours' features are equal (a symmetric image): coordinates
#: written with 6 decimals move them by about 1e-7; a random sample's neighbours differ by 1e-3 or more
#: (a random torus has no such pair, a LiDAR tile 1 point in 10 000; the mirror pairs of CGAL's cow 78 of
#: its 2903 vertices, nine of its twelve models none).
TIE_TOLERANCE = 1e-5
#: Nearest neighbours searched for a point's symmetric image.
TIE_NEIGHBOURS = 8
#: Grid of the positions :func:`position_keys` hashes, in root-mean-square radii: coarse beside the rounding of
#: float32 coordinates near the cloud (6e-8), so that it rarely moves a point to another cell.
_POSITION_STEP = 2.0**-16


def geometric_keys(points: np.ndarray, nbhd: Neighbourhood, frame=None) -> np.ndarray:
    """A pseudo-random number in [0, 1) per point, from its geometry alone.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    nbhd : Neighbourhood
        Each point's neighbours: the k nearest (rows sorted by distance), or
        a ball of one radius.
    frame : heatcurv.choice.choices.CloudFrame, optional
        The whole cloud's frame (its centroid, root-mean-square radius and
        size) when ``points`` are a part of it: a point gets the same key in
        every part that holds it. Default: the frame of ``points`` itself.

    Returns
    -------
    ndarray, shape (n,)
        Keys invariant under permutation, rotation, translation and uniform
        scaling of ``points`` (to rounding).
    """
    if frame is None:
        centre = points.mean(axis=0)
        d = points - centre
        scale = float(np.sqrt(np.mean(np.einsum("ij,ij->i", d, d))))
        n_cloud = points.shape[0]
    else:
        centre, scale, n_cloud = np.asarray(frame.centroid), float(frame.rms_radius), int(frame.n_points)
    centred = points - centre
    r = np.sqrt(np.einsum("ij,ij->i", centred, centred))
    counts = nbhd.counts
    if nbhd.by_distance:
        # k nearest: the ball radius (k-th distance) and the nearest neighbour's distance
        local = nbhd.radius + np.where(counts > 0, nbhd.distances[np.minimum(nbhd.indptr[:-1], nbhd.n_pairs - 1)], 0.0)
        local = local / max(scale, np.finfo(float).tiny)
    else:
        # one radius for all: how many neighbours the ball holds (a number: no unit to divide) and its nearest
        # one's distance (the count alone takes a few values, and on a sphere, whose points all have the same r,
        # the smallest keys would crowd into the bands of one count)
        nearest = np.zeros(counts.shape[0])
        filled = counts > 0
        if filled.any():
            nearest[filled] = np.minimum.reduceat(nbhd.distances, nbhd.indptr[:-1][filled])
        local = counts * 1e-3 + nearest / max(scale, np.finfo(float).tiny)
    radius = r / max(scale, np.finfo(float).tiny)
    keys = np.modf((_GOLDEN * radius + _SILVER * local) * key_spread(n_cloud))[0]
    twin = _has_twin(radius, local, nbhd)
    keys[twin] = position_keys(centred[twin] / max(scale, np.finfo(float).tiny))
    return keys


def _has_twin(radius: np.ndarray, local: np.ndarray, nbhd: Neighbourhood) -> np.ndarray:
    """Points with a symmetric image among their :data:`TIE_NEIGHBOURS` nearest, shape (n,), bool: a
    neighbour whose both features are within :data:`TIE_TOLERANCE` of the point's."""
    near = nbhd.nearest(TIE_NEIGHBOURS + 1)
    start, counts = near.indptr[:-1], near.counts
    twin = np.zeros(nbhd.n_points, dtype=bool)
    # one rank of neighbours at a time, the radius first: most pairs fail it, and the rest are few to gather
    for rank in range(int(counts.max(initial=0))):
        rows = np.flatnonzero(counts > rank)
        other = near.indices[start[rows] + rank]
        keep = (other != rows) & (np.abs(radius[other] - radius[rows]) <= TIE_TOLERANCE * np.abs(radius[rows]))
        rows, other = rows[keep], other[keep]
        twin[rows[np.abs(local[other] - local[rows]) <= TIE_TOLERANCE * np.abs(local[rows])]] = True
    return twin


def position_keys(scaled: np.ndarray) -> np.ndarray:
    """A pseudo-random number in [0, 1) per position, shape (n,): a hash of its cell of a grid of step
    :data:`_POSITION_STEP`.

    Parameters
    ----------
    scaled : ndarray, shape (n, 3)
        Positions relative to the cloud's centroid, in its root-mean-square radius.
    """
    cell = np.clip(np.round(scaled / _POSITION_STEP), -(2.0**62), 2.0**62).astype(np.int64).view(np.uint64)
    h = cell[:, 0] * np.uint64(0x9E3779B97F4A7C15) ^ cell[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
    h ^= cell[:, 2] * np.uint64(0x165667B19E3779F9)
    # the finaliser of splitmix64: every input bit reaches every output bit
    h ^= h >> np.uint64(30)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(27)
    h *= np.uint64(0x94D049BB133111EB)
    h ^= h >> np.uint64(31)
    return (h >> np.uint64(11)).astype(np.float64) / 2.0**53


def key_spread(n_points: int) -> float:
    """The multiplier of the features for a cloud of ``n_points`` (:data:`KEY_SPREAD`, growing as sqrt(n) past 1e6).

    Neighbouring points' features differ by about a spacing over the cloud's
    radius, which shrinks as ``n^-1/2``: the multiplier grows with it so that
    neighbours' keys stay unrelated on clouds of 1e8 points and more.
    """
    return KEY_SPREAD * max(1.0, float(np.sqrt(n_points / 1e6)))


def key_sample(keys: np.ndarray, size: int, seed: int = 0) -> np.ndarray:
    """The ``size`` points with the smallest keys (shifted by ``seed``), as sorted indices.

    Parameters
    ----------
    keys : ndarray, shape (n,)
        From :func:`geometric_keys`.
    size : int
        Points wanted (all of them if ``size >= n``).
    seed : int, optional
        Different seeds give different (independent-looking) subsets.

    Returns
    -------
    ndarray of int64, shape (min(size, n),)
        Increasing indices.
    """
    n = keys.shape[0]
    if size >= n:
        return np.arange(n)
    shifted = shifted_keys(keys, seed)
    return np.sort(np.argpartition(shifted, size - 1)[:size] if size > 0 else np.empty(0, dtype=np.int64))


def shifted_keys(keys: np.ndarray, seed: int = 0) -> np.ndarray:
    """``keys`` shifted by ``seed`` (mod 1): the order :func:`key_sample` draws in, shape as ``keys``."""
    return np.modf(keys + _GOLDEN * (seed % 1_000_003))[0]


def key_thinning(keys: np.ndarray, fraction, seed: int = 0) -> np.ndarray:
    """The points whose key (shifted by ``seed``) is below ``fraction``: a subset of local density ``fraction``.

    Parameters
    ----------
    keys : ndarray, shape (n,)
        From :func:`geometric_keys`.
    fraction : float or ndarray, shape (n,)
        Share of the points kept, per point where it varies (1: every point).
    seed : int, optional
        As :func:`key_sample`.

    Returns
    -------
    ndarray of int64, shape (m,)
        Increasing indices.
    """
    return np.flatnonzero(shifted_keys(keys, seed) < fraction)


def draw_subset(n: int, size: int, seed: int = 0, keys: np.ndarray | None = None) -> np.ndarray:
    """Sorted indices of ``min(size, n)`` of ``n`` points: by ``keys`` if given (:func:`key_sample`), else seeded rows.

    Without keys (a caller that has no neighbourhood, e.g. the stages' public functions
    called directly) the subset is a seeded random choice of the rows, which depends on
    their order.
    """
    if keys is not None:
        return key_sample(keys, size, seed)
    return np.sort(np.random.default_rng(seed).choice(n, min(size, n), replace=False))
