"""Mean-curvature normal and signed mean curvature (paper eqs 2.10-2.12).

The Laplace-Beltrami operator applied to the coordinates gives the
mean-curvature normal (eq 2.10)

    K_i = 1/(4 pi t_i^2) sum_j W_ij (x_i - x_j) A_j  ~  2 kappa_M(x_i) n_i,

from which the paper reads the mean curvature in two ways:

* ``"norm"`` (eq 2.11): ``kappa_M = 1/2 |K|``, signed by ``K . n``. Robust to
  a poor normal but wrong near the border of open surfaces, where ``K`` has a
  large tangential part.
* ``"projection"`` (eq 2.12): ``kappa_M = 1/2 K . n``, a quadrature of the
  edge normal curvatures ``kN_ij = 2 (xi-xj).n / |xi-xj|^2`` with weights
  ``W_ij |xi-xj|^2 A_j / (8 pi t_i^2)``; the tangential part drops out.

Sign convention: positive where the surface bends away from its normal; a
sphere with outward normals has ``kappa_M = +1/R``.
"""

from __future__ import annotations

import numpy as np

from .._kernels import segment as kernels
from ..errors import HeatcurvError
from ..geometry.neighbourhood import Neighbourhood
from .kernel import diffusion_time, laplacian_normalisation

__all__ = ["mean_curvature_normal", "mean_curvature", "edge_normal_curvatures"]


def mean_curvature_normal(
    points: np.ndarray,
    nbhd: Neighbourhood,
    weights: np.ndarray | None,
    areas: np.ndarray,
    h: np.ndarray,
    m: float = 0.25,
) -> np.ndarray:
    """The mean-curvature normal ``K = L x`` of eq 2.10, without assembling ``L``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct (centred) points.
    nbhd : Neighbourhood
        Neighbour pairs.
    weights : ndarray, shape (nnz,) or None
        ``W_ij``; None computes the heat kernel ``exp(-|xi - xj|^2 / (4 m h_i^2))``
        pair by pair without storing it.
    areas : ndarray, shape (n,)
        Per-point areas ``A_j``.
    h : ndarray, shape (n,)
        Spacing per point.
    m : float, optional
        Diffusion-time constant.

    Returns
    -------
    ndarray, shape (n, 3)
        ``K_i``, approximately ``2 kappa_M n_i``.
    """
    inv_4t = 1.0 / (4.0 * diffusion_time(h, m))
    has_weights = weights is not None
    w = np.asarray(weights, dtype=np.float64) if has_weights else np.empty(0)
    sums = kernels.kappa_normal_sums(points, nbhd.indptr, nbhd.indices, nbhd.distances, inv_4t, w, areas, has_weights)
    return laplacian_normalisation(h, m)[:, None] * sums


def mean_curvature(K: np.ndarray, normals: np.ndarray, formula: str = "projection") -> np.ndarray:
    """Signed mean curvature from the mean-curvature normal.

    Parameters
    ----------
    K : ndarray, shape (n, 3)
        Mean-curvature normal from :func:`mean_curvature_normal`.
    normals : ndarray, shape (n, 3)
        Unit, consistently oriented normals; they fix the sign.
    formula : {"projection", "norm"}, optional
        ``"projection"``: ``1/2 K . n`` (eq 2.12); ``"norm"``: ``1/2 |K|``
        with the sign of ``K . n`` (eq 2.11).

    Returns
    -------
    ndarray, shape (n,)
        ``kappa_M`` per point.
    """
    proj = np.einsum("ij,ij->i", K, normals)
    if formula == "projection":
        return 0.5 * proj
    if formula == "norm":
        return 0.5 * np.linalg.norm(K, axis=1) * np.where(proj < 0, -1.0, 1.0)
    raise HeatcurvError(f"mean-curvature formula must be 'projection' (eq 2.12) or 'norm' (eq 2.11), got {formula!r}")


def edge_normal_curvatures(points: np.ndarray, nbhd: Neighbourhood, normals: np.ndarray) -> np.ndarray:
    """Normal curvature of every neighbour edge, ``kN_ij = 2 (xi-xj).n_i / |xi-xj|^2`` (eq 2.12).

    The curvature of the circle through ``x_i`` and ``x_j`` tangent to the
    plane normal to ``n_i`` at ``x_i``; exact for any two points of a circle.

    Returns
    -------
    ndarray, shape (nnz,)
    """
    rows = nbhd.rows
    diff = points[rows] - points[nbhd.indices]
    return 2.0 * np.einsum("ij,ij->i", diff, normals[rows]) / nbhd.distances**2
