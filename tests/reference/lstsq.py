"""numpy weighted least squares per point, over CSR neighbour pairs: the reference of the chord fit's solve.

The default estimator's fit (:func:`heatcurv.fits.chordfit.chord_fit`) accumulates its
normal equations pair by pair in compiled code and solves them by Cholesky
(:func:`heatcurv._kernels.chordfit.solve_compiled`). Here the same weighted least
squares is written with numpy on padded per-point blocks and solved by LAPACK
(``numpy.linalg.solve``), for the tests (``tests/test_chordfit.py``,
``tests/test_kernels_chordfit.py``) and the benchmarks that try fit variants. The
blocks are sized by heatcurv's block-size policy (:func:`heatcurv.geometry.neighbourhood.rows_per_block`),
and the :class:`~heatcurv.geometry.neighbourhood.Neighbourhood` container, the only things taken from heatcurv.
"""

from __future__ import annotations

import numpy as np

from heatcurv.geometry.neighbourhood import Neighbourhood, block_ranges, rows_per_block

__all__ = ["ridge_solve", "segment_lstsq", "solve_normal_equations"]


def segment_lstsq(
    nbhd: Neighbourhood,
    design: np.ndarray,
    response: np.ndarray,
    weights: np.ndarray,
    ridge: float = 1e-10,
    contrast: np.ndarray | None = None,
    noise_scale: np.ndarray | None = None,
    jacobi: bool = False,
):
    """Weighted least squares for every point's neighbour pairs at once.

    Minimises ``sum_j w_ij (y_ij - X_ij . beta_i)^2`` for each point ``i``.

    Parameters
    ----------
    nbhd : Neighbourhood
        CSR neighbour pairs; rows are the points.
    design : ndarray, shape (nnz, p)
        ``X_ij``.
    response : ndarray, shape (nnz,)
        ``y_ij``.
    weights : ndarray, shape (nnz,)
        ``w_ij >= 0``.
    ridge : float, optional
        Tikhonov term relative to the trace of each normal matrix, so that
        rank-deficient neighbourhoods give a finite (flagged) answer.
    contrast : ndarray, shape (p,), optional
        A linear combination ``c . beta`` whose variance per unit noise
        variance, ``c^T G^-1 (X^T W^2 S^2 X) G^-1 c``, is also returned.
    noise_scale : ndarray, shape (nnz,), optional
        ``S``: the standard deviation of each response per unit noise
        (default 1, homoscedastic).
    jacobi : bool, optional
        The ridge relative to each diagonal entry instead of the trace (:func:`ridge_solve`).

    Returns
    -------
    beta : ndarray, shape (n, p)
        Coefficients.
    rss : ndarray, shape (n,)
        Weighted residual sum of squares.
    well_posed : ndarray, shape (n,), bool
        Whether the normal matrix was well conditioned (reciprocal condition
        number above 1e-10).
    variance : ndarray, shape (n,)
        Only with ``contrast``: the variance factor of ``c . beta``.
    """
    n, p = nbhd.n_points, design.shape[1]
    G = np.zeros((n, p, p))
    r = np.zeros((n, p))
    yy = np.zeros(n)
    G2 = np.zeros((n, p, p)) if contrast is not None else None
    counts = nbhd.counts
    # Rows are padded to a common length and multiplied as batched matrices
    # (X^T W X per point); blocks of BLOCK_PAIRS padded pairs (the block-size policy) bound the memory.
    width = max(int(counts.max()) if n else 1, 1)
    for lo, hi in block_ranges(n, rows_per_block(width)):
        a, b = nbhd.indptr[lo], nbhd.indptr[hi]
        if a == b:
            continue
        local_rows = np.repeat(np.arange(hi - lo), counts[lo:hi])
        slot = np.arange(b - a) - (nbhd.indptr[lo:hi] - a)[local_rows]
        Xp = np.zeros((hi - lo, width, p))
        wp = np.zeros((hi - lo, width))
        yp = np.zeros((hi - lo, width))
        Xp[local_rows, slot] = design[a:b]
        wp[local_rows, slot] = weights[a:b]
        yp[local_rows, slot] = response[a:b]
        wXp = Xp * wp[:, :, None]
        G[lo:hi] = np.matmul(wXp.transpose(0, 2, 1), Xp)
        r[lo:hi] = np.einsum("mcp,mc->mp", wXp, yp)
        yy[lo:hi] = np.einsum("mc,mc->m", wp * yp, yp)
        if G2 is not None:
            s2 = wp * wp
            if noise_scale is not None:
                sp_ = np.zeros((hi - lo, width))
                sp_[local_rows, slot] = noise_scale[a:b]
                s2 = s2 * sp_ * sp_
            G2[lo:hi] = np.matmul((Xp * s2[:, :, None]).transpose(0, 2, 1), Xp)
    return solve_normal_equations(G, r, yy, ridge=ridge, contrast=contrast, G2=G2, jacobi=jacobi)


def ridge_solve(G: np.ndarray, r: np.ndarray, ridge: float = 1e-10, jacobi: bool = False):
    """Solve ``(G + ridge trace(G)/p I) beta = r`` for every point (the coefficients alone).

    With ``jacobi`` the ridge is ``ridge diag(G)`` instead (``trace(G) / p`` where a diagonal
    entry is 0): the same relative ridge whatever the columns' scales, so that it does not pull
    the coefficients of small columns (a low-noise refit's quartic terms) more than the others.

    Parameters
    ----------
    G : ndarray, shape (n, p, p)
        Normal matrices.
    r : ndarray, shape (n, p)
        Right-hand sides.
    ridge : float, optional
        Tikhonov term relative to ``trace(G) / p``.
    jacobi : bool, optional
        The ridge relative to each diagonal entry.

    Returns
    -------
    beta : ndarray, shape (n, p)
    Greg : ndarray, shape (n, p, p)
        The regularised normal matrices.
    """
    p = G.shape[-1]
    scale = np.maximum(np.trace(G, axis1=1, axis2=2) / p, 1e-300)
    if jacobi:
        diagonal = np.diagonal(G, axis1=1, axis2=2)
        Greg = G + ridge * (np.where(diagonal > 0, diagonal, scale[:, None])[:, :, None] * np.eye(p))
    else:
        Greg = G + (ridge * scale)[:, None, None] * np.eye(p)
    beta = np.linalg.solve(Greg, r[:, :, None])[:, :, 0]
    return beta, Greg


def solve_normal_equations(
    G: np.ndarray,
    r: np.ndarray,
    yy: np.ndarray,
    ridge: float = 1e-10,
    contrast: np.ndarray | None = None,
    G2: np.ndarray | None = None,
    jacobi: bool = False,
):
    """Solve accumulated weighted normal equations ``G beta = r`` for every point.

    The second half of :func:`segment_lstsq`. (:func:`heatcurv.fits.chordfit.chord_fit`
    accumulates its sums without per-pair arrays and solves them by Cholesky,
    :func:`heatcurv._kernels.chordfit.solve_compiled`, which the tests check
    against this function.)

    Parameters
    ----------
    G : ndarray, shape (n, p, p)
        ``X^T W X`` of each point.
    r : ndarray, shape (n, p)
        ``X^T W y``.
    yy : ndarray, shape (n,)
        ``y^T W y``.
    ridge : float, optional
        Tikhonov term relative to ``trace(G) / p``.
    contrast : ndarray, shape (p,), optional
        ``c`` of the variance factor ``c^T G^-1 G2 G^-1 c``.
    G2 : ndarray, shape (n, p, p), optional
        ``X^T W^2 S^2 X``; required with ``contrast``.
    jacobi : bool, optional
        The ridge relative to each diagonal entry (:func:`ridge_solve`).

    Returns
    -------
    beta, rss, well_posed[, variance]
        As :func:`segment_lstsq`.
    """
    n, p = r.shape
    beta, Greg = ridge_solve(G, r, ridge, jacobi)
    rss = np.maximum(yy - 2 * np.einsum("ij,ij->i", beta, r) + np.einsum("ij,ijk,ik->i", beta, G, beta), 0.0)
    evals = np.linalg.eigvalsh(G)
    well_posed = evals[:, 0] > 1e-10 * np.maximum(evals[:, -1], 1e-300)
    if contrast is None:
        return beta, rss, well_posed
    u = np.linalg.solve(Greg, np.broadcast_to(np.asarray(contrast, float), (n, p))[:, :, None])[:, :, 0]
    variance = np.einsum("ij,ijk,ik->i", u, G2, u)
    return beta, rss, well_posed, variance
