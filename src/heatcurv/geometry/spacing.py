"""The inherent distance parameter h of the heat kernel (paper section 2.1).

The heat-diffusion time is tied to the sampling by ``t = m h^2`` (eq 2.8).
Two choices of ``h`` come from the paper:

* global (eq 2.6): ``h = mean_i min_j |xi - xj|``, the mean nearest-neighbour
  distance, one value for the whole cloud; the Laplace matrix is then
  symmetric up to the areas.
* local (eq 2.7): ``h_i = (1 - gamma) min_j |xi - xj| + gamma max_j |xi - xj|``
  over the ``k`` nearest neighbours of each point, for non-uniform clouds.

A third choice is ours (the default estimator's):

* density: ``h_i = d_k(i) / alpha`` with ``d_k(i)`` the distance to the
  ``k``-th nearest neighbour, so the ball of radius ``alpha h_i`` holds exactly
  ``k`` neighbours wherever the cloud is dense or sparse. On irregular
  (random) samples eq 2.6 measures about half the typical spacing, because
  nearest neighbours are closer than the mean spacing; a count-based radius
  does not depend on how regular the sampling is.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..errors import HeatcurvError

__all__ = ["global_spacing", "local_spacing", "density_spacing", "spacing"]


def _knn_distances(points: np.ndarray, k: int, tree: cKDTree | None, workers: int) -> np.ndarray:
    """Distances to the ``k`` nearest other points, shape ``(n, k)``, ascending."""
    if tree is None:
        tree = cKDTree(points)
    if k >= points.shape[0]:
        raise HeatcurvError(f"need more than {k} points to find {k} neighbours, got {points.shape[0]}")
    dist, _ = tree.query(points, k=k + 1, workers=workers)
    return dist[:, 1:]  # column 0 is the point itself (the points are distinct)


def global_spacing(points: np.ndarray, tree: cKDTree | None = None, workers: int = -1) -> float:
    """Mean nearest-neighbour distance, eq 2.6.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    tree : scipy.spatial.cKDTree, optional
        A tree already built on ``points``.
    workers : int, optional
        Threads for the k-d tree query (-1: all cores).

    Returns
    -------
    float
        ``h = (1/n) sum_i min_{j != i} |xi - xj|``.
    """
    return float(_knn_distances(points, 1, tree, workers)[:, 0].mean())


def local_spacing(
    points: np.ndarray,
    gamma: float = 0.25,
    k: int = 8,
    tree: cKDTree | None = None,
    workers: int = -1,
) -> np.ndarray:
    """Per-point spacing, eq 2.7.

    ``h_i = (1 - gamma) d_1(i) + gamma d_k(i)`` with ``d_1`` and ``d_k`` the
    nearest and the ``k``-th nearest neighbour distance. The paper takes the
    min and max over the neighbours without fixing their number; we take the
    ``k`` nearest (default 8, one ring of a regular grid).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    gamma : float, optional
        Blend between nearest (0) and farthest (1) neighbour; the paper
        recommends 0.1-0.5.
    k : int, optional
        Number of nearest neighbours the min and max run over.
    tree : scipy.spatial.cKDTree, optional
        A tree already built on ``points``.
    workers : int, optional
        Threads for the k-d tree query.

    Returns
    -------
    ndarray, shape (n,)
        ``h_i`` for each point.
    """
    if not 0.0 <= gamma <= 1.0:
        raise HeatcurvError(f"gamma must lie in [0, 1], got {gamma}")
    if k < 1:
        raise HeatcurvError(f"k must be at least 1, got {k}")
    dist = _knn_distances(points, k, tree, workers)
    return (1.0 - gamma) * dist[:, 0] + gamma * dist[:, -1]


def density_spacing(
    points: np.ndarray,
    k: int = 60,
    alpha: float = 2.0,
    tree: cKDTree | None = None,
    workers: int = -1,
) -> np.ndarray:
    """Per-point spacing from the local density, ``h_i = d_k(i) / alpha``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    k : int, optional
        Neighbours the ball of radius ``alpha h_i`` is to hold.
    alpha : float, optional
        Ball radius in units of ``h``.
    tree : scipy.spatial.cKDTree, optional
        A tree already built on ``points``.
    workers : int, optional
        Threads for the k-d tree query.

    Returns
    -------
    ndarray, shape (n,)
        ``h_i``.
    """
    if k < 1:
        raise HeatcurvError(f"k must be at least 1, got {k}")
    return _knn_distances(points, k, tree, workers)[:, -1] / alpha


def spacing(
    points: np.ndarray,
    kind: str = "global",
    gamma: float = 0.25,
    k: int = 8,
    tree: cKDTree | None = None,
    workers: int = -1,
    alpha: float = 2.0,
) -> np.ndarray:
    """Spacing ``h`` per point: eq 2.6 (``kind="global"``), eq 2.7 (``"local"``) or ``"density"``.

    ``k`` is the neighbour count of eq 2.7's min/max (``"local"``) or of the
    density radius (``"density"``); ``alpha`` is used by ``"density"`` only.

    Returns
    -------
    ndarray, shape (n,)
        ``h_i``; all equal for the global spacing.
    """
    if kind == "global":
        return np.full(points.shape[0], global_spacing(points, tree, workers))
    if kind == "local":
        return local_spacing(points, gamma=gamma, k=k, tree=tree, workers=workers)
    if kind == "density":
        return density_spacing(points, k=k, alpha=alpha, tree=tree, workers=workers)
    raise HeatcurvError(f"spacing must be 'global' (eq 2.6), 'local' (eq 2.7) or 'density', got {kind!r}")
