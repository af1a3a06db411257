"""The point-cloud Laplace-Beltrami operator of the heat kernel (paper eqs 2.4, 2.5, 2.9).

    (L f)_i = 1/(4 pi t_i^2) sum_{j in B(x_i)} exp(-|xi-xj|^2/(4 t_i)) (f_i - f_j) A_j

with ``t_i = m h_i^2``; at ``m = 1/4`` the factor is ``4/(pi h^4)`` (eq 2.9).
This is the *positive* operator of the heat equation ``u_t + Delta u = 0``
(eq 2.1): ``L 1 = 0`` and on a sphere of radius R the coordinate functions are
eigenfunctions, ``L z = 2 z / R^2``. Applied to the coordinates it gives the
mean-curvature normal, ``L x = 2 kappa_M n`` (eq 2.10).

With the global spacing, ``diag(A) L`` is symmetric (the weights are); ``L``
itself is not, because the areas ``A_j`` multiply the columns.

:func:`heatcurv.laplacian` (in :mod:`heatcurv.operators.operator`) is the one-call front end.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..geometry.neighbourhood import Neighbourhood
from .kernel import laplacian_normalisation

__all__ = ["laplace_beltrami_matrix"]


def laplace_beltrami_matrix(
    nbhd: Neighbourhood, weights: np.ndarray, areas: np.ndarray, h: np.ndarray, m: float = 0.25
) -> sp.csr_matrix:
    """Assemble the sparse matrix ``L`` of eq 2.9.

    Parameters
    ----------
    nbhd : Neighbourhood
        Neighbour pairs.
    weights : ndarray, shape (nnz,)
        ``W_ij`` from :func:`heatcurv.operators.kernel.heat_kernel_weights`.
    areas : ndarray, shape (n,)
        Per-point areas ``A_j``.
    h : ndarray, shape (n,)
        Spacing per point.
    m : float, optional
        Diffusion-time constant.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n, n)
        ``L_ij = -c_i W_ij A_j`` off the diagonal and ``L_ii = c_i sum_j W_ij A_j``
        with ``c_i = 1/(4 pi t_i^2)``; every row sums to zero.
    """
    n = nbhd.n_points
    c_pair = np.repeat(laplacian_normalisation(h, m), nbhd.counts)
    coupling = c_pair * weights * areas[nbhd.indices]
    off = sp.csr_matrix((-coupling, nbhd.indices, nbhd.indptr), shape=(n, n))
    return (off + sp.diags(nbhd.segment_sum(coupling))).tocsr()

