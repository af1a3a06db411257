"""The classical k-nearest-neighbour quadric fit, as a baseline for heatcurv.

This is the estimator most users know from PCL / CGAL-style pipelines
(osculating jets of degree 2, "quadric fitting"):

1. the ``k`` nearest neighbours of every point (the point itself included);
2. a PCA normal of that neighbourhood, given one consistent orientation with
   :func:`heatcurv.orient.normals.orient_normals` (the same rule heatcurv uses:
   outward on closed surfaces);
3. a local frame ``(e1, e2, n)`` at the point (``e1 x e2 = n``) and the
   least-squares fit of the height function
   ``z = a x^2 + b x y + c y^2 + d x + e y + f`` to the neighbours;
4. the *exact* differential geometry of the fitted graph at the point's foot
   ``(0, 0)``: full first and second fundamental forms (the gradient
   ``(d, e)`` is kept, not just the Hessian), the shape operator
   ``S = -I^{-1} II``, its eigenvalues ``k1 >= k2`` and eigenvectors mapped
   back to 3-D.

The reported normal is the fitted graph's normal at the foot (more accurate
than the PCA normal, which belongs to the neighbourhood's centroid), with the
orientation of step 2.  Signs follow heatcurv: a curvature is positive where
the surface bends away from the normal (sphere, outward normals: ``+1/R``),
and ``d1 x d2 = normals``.

Everything is vectorised over blocks of points (no per-point Python loop).

``centres=`` evaluates the fit at chosen points only, with their full
neighbourhoods in the whole cloud: the cost is then that of the centres
(about ``len(centres) * k``) plus one k-d tree of the cloud, which makes wide
fits (k in the thousands) on clouds of a million points affordable, e.g. for
an oracle that tries a ladder of k (``benchmarks/accuracy.py``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from numbers import Integral

import numpy as np
from scipy.spatial import cKDTree

from heatcurv.errors import HeatcurvError
from heatcurv.geometry.neighbourhood import Neighbourhood
from heatcurv.geometry.validation import prepare_normals, prepare_points
from heatcurv.orient.normals import orient_normals, tangent_frames

__all__ = ["QuadricOptions", "QuadricResult", "quadric_curvature"]

#: A fit whose design matrix has ``s_min / s_max`` below this (in scaled
#: coordinates) is marked unreliable: the neighbours (nearly) lie on a conic
#: or a line and the quadric is not determined.
RCOND_MIN = 1e-6

#: Neighbour rows held in memory at once (a block of ``b`` points holds
#: ``b * k`` rows, ~100 bytes each): the block shrinks for wide fits.
BLOCK_ROWS = 1 << 20

#: Nearest other centres per centre in the graph the normals of a
#: ``centres=`` evaluation are oriented over.
CENTRE_GRAPH_NEIGHBOURS = 10


@dataclass(frozen=True)
class QuadricOptions:
    """Settings of :func:`quadric_curvature`.

    Attributes
    ----------
    method : str
        Always ``"quadric"`` (a label, like :attr:`heatcurv.Options.method`).
    k : int
        Neighbours per fit, the point itself included.
    """

    method: str = "quadric"
    k: int = 40


@dataclass(frozen=True)
class QuadricResult:
    """Output of :func:`quadric_curvature`, one row per input point, in input order.

    With ``centres=`` one row per centre instead, in the order given.

    The fields mirror :class:`heatcurv.CurvatureResult` so that the same
    evaluation code (:func:`heatcurv.surfaces.accuracy.compare`) applies.

    Attributes
    ----------
    normals : ndarray, shape (n, 3)
        Unit normal of the fitted quadric at the point, oriented consistently
        (closed surfaces: outward); the caller's normals (normalised) if given.
    mean : ndarray, shape (n,)
        ``(k1 + k2) / 2``, positive where the surface bends away from the normal.
    gaussian : ndarray, shape (n,)
        ``k1 * k2``.
    k1, k2 : ndarray, shape (n,)
        Principal curvatures of the fitted quadric at the point, ``k1 >= k2``.
    d1, d2 : ndarray, shape (n, 3)
        Unit principal directions, tangent, ``d1 x d2 = normals``.
    area : ndarray, shape (n,)
        A simple k-NN area per point, ``pi r^2 / (k - 1)`` with ``r`` the
        neighbourhood radius: unbiased for area-uniform random samples of a
        plane (the ``k - 1``-th neighbour distance of a Poisson process) and
        of a sphere (a chord disc of radius ``r`` has area exactly
        ``pi r^2``); biased on regular lattices and at borders.
    reliable : ndarray of bool, shape (n,)
        False where the fit was ill-conditioned (``s_min / s_max <``
        :data:`RCOND_MIN`) or the neighbourhood has zero radius.
    spacing : ndarray, shape (n,)
        The neighbourhood radius ``r`` (distance to the farthest of the ``k``
        neighbours), named as in :class:`heatcurv.CurvatureResult`.
    support_radius : float
        The largest neighbourhood radius, ``max(spacing)``: how far from a
        point the data its values depend on can lie.  The border margin
        :func:`heatcurv.surfaces.accuracy.compare` uses by default
        (:func:`heatcurv.surfaces.accuracy.default_margin`).
    neighbours : ndarray of int, shape (n,)
        Neighbours per fit excluding the point itself (``k - 1``).
    options : QuadricOptions
    info : dict
        ``timings`` (seconds per stage), ``offset`` (the centring shift),
        ``centres`` (the indices of the input points the rows belong to, or
        None for every point).
    """

    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    area: np.ndarray
    reliable: np.ndarray
    spacing: np.ndarray
    neighbours: np.ndarray
    options: QuadricOptions
    info: dict = field(default_factory=dict)

    FIELDS = ("normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "area")

    def __len__(self) -> int:
        return int(self.mean.shape[0])

    def __repr__(self) -> str:
        return (
            f"QuadricResult(n={len(self)}, k={self.options.k}, "
            f"reliable={int(self.reliable.sum())}/{len(self)})"
        )

    @property
    def support_radius(self) -> float:
        """The largest neighbourhood radius, ``max(spacing)`` (see the class docstring)."""
        return float(np.max(self.spacing))

    def as_dict(self) -> dict:
        """The per-point arrays by name (``FIELDS`` plus ``reliable``)."""
        return {name: getattr(self, name) for name in self.FIELDS + ("reliable",)}


def _validate_k(k) -> int:
    if isinstance(k, bool) or not isinstance(k, Integral):
        raise HeatcurvError(f"k must be an integer, got {k!r}")
    if int(k) < 7:
        raise HeatcurvError(f"k must be at least 7 (the quadric has 6 coefficients), got {k}")
    return int(k)


def _validate_centres(centres, n: int) -> np.ndarray:
    """Indices of input points as an int64 array, shape (m,), m >= 1, each in ``[0, n)``."""
    arr = np.asarray(centres)
    if arr.size == 0:
        raise HeatcurvError("centres is empty: give at least one point index")
    if arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer) or arr.ndim != 1:
        raise HeatcurvError(
            f"centres must be a 1-D array of point indices (integers), got dtype {arr.dtype}, shape {arr.shape}"
        )
    if arr.min() < 0 or arr.max() >= n:
        raise HeatcurvError(f"centres must lie in [0, {n}) (indices of the {n} points), got {arr.min()}..{arr.max()}")
    return arr.astype(np.int64)


def _knn_neighbourhood(idx: np.ndarray, dist: np.ndarray) -> Neighbourhood:
    """CSR :class:`~heatcurv.geometry.neighbourhood.Neighbourhood` from k-NN arrays (shape (n, k)).

    The point itself is removed from its row; rows are sorted by index.
    """
    n, k = idx.shape
    rows = np.repeat(np.arange(n, dtype=np.int64), k)
    cols = idx.reshape(-1).astype(np.int64)
    d = dist.reshape(-1)
    keep = cols != rows
    rows, cols, d = rows[keep], cols[keep], d[keep]
    order = np.lexsort((cols, rows))
    rows, cols, d = rows[order], cols[order], d[order]
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    index_dtype = np.int32 if n < np.iinfo(np.int32).max else np.int64
    return Neighbourhood(
        indptr=indptr,
        indices=cols.astype(index_dtype),
        distances=d,
        radius=dist[:, -1].copy(),
        augmented=np.zeros(n, dtype=bool),
    )


def _pca_normals(X: np.ndarray, idx: np.ndarray, block: int) -> np.ndarray:
    """Smallest-eigenvalue eigenvector of each k-NN covariance (rows of ``idx``), shape (len(idx), 3)."""
    out = np.empty((idx.shape[0], 3))
    for s in range(0, idx.shape[0], block):
        nb = X[idx[s : s + block]]  # (b, k, 3)
        rel = nb - nb.mean(axis=1, keepdims=True)
        cov = np.matmul(rel.transpose(0, 2, 1), rel)
        out[s : s + block] = np.linalg.eigh(cov)[1][:, :, 0]
    return out


def _least_squares(A: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-norm least-squares solutions of ``A[b] c = z[b]`` and the singular values of ``A[b]``.

    ``A`` shape (b, k, 6), ``z`` shape (b, k).  Through the 6 x 6 Gram matrix
    ``A^T A`` (eigen-decomposed: ``V diag(S^2) V^T``, ``S`` the singular values
    of ``A``, ascending) and one step of iterative refinement, which brings
    the solution to the accuracy of an SVD of ``A`` for the well-conditioned
    fits of scaled coordinates (measured against the SVD formerly used: curvatures
    within 6e-14 relative on random, jittered and scan clouds, 1.3e-12 on a
    cylinder grid; exact quadrics still to 1e-10); singular values below
    ``RCOND_MIN * S_max`` are dropped, as in a pseudo-inverse.  Unlike a
    batched SVD of the tall ``(k, 6)`` matrices its cost stays ~``36 k``
    flops per fit: the SVD slowed down up to 70x once OpenBLAS threaded its
    ``k > ~1000`` factorisations on a busy machine (measured: 8.8 s instead
    of 0.12 s single-threaded for 1M rows, k = 1920).

    Returns
    -------
    coef : ndarray, shape (b, 6)
    S : ndarray, shape (b, 6)
        Ascending.
    """
    At = A.transpose(0, 2, 1)
    lam, V = np.linalg.eigh(np.matmul(At, A))
    S = np.sqrt(np.maximum(lam, 0.0))
    keep = S > RCOND_MIN * S[:, -1:]
    inv = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)  # 1 / S^2 on the kept subspace
    Vt = V.transpose(0, 2, 1)

    def solve(rhs):  # V diag(inv) V^T A^T rhs
        atr = np.matmul(At, rhs[:, :, None])
        return np.matmul(V, inv[:, :, None] * np.matmul(Vt, atr))[:, :, 0]

    coef = solve(z)
    residual = z - np.matmul(A, coef[:, :, None])[:, :, 0]
    return coef + solve(residual), S


def _graph_curvature(a, b, c, d, e):
    """Exact geometry of ``z = a x^2 + b x y + c y^2 + d x + e y + f`` at ``(0, 0)``.

    All inputs shape (m,).  Returns the unit normal (upward, shape (m, 3)),
    ``k1 >= k2`` (m,) and unit principal directions ``d1``, ``d2`` (m, 3)
    with ``d1 x d2 = normal``, all in the local frame.
    """
    m = a.shape[0]
    w = np.sqrt(1.0 + d * d + e * e)
    tx = np.stack([np.ones(m), np.zeros(m), d], axis=1)  # X_x
    ty = np.stack([np.zeros(m), np.ones(m), e], axis=1)  # X_y
    nrm = np.stack([-d, -e, np.ones(m)], axis=1) / w[:, None]
    E, F, G = 1.0 + d * d, d * e, 1.0 + e * e
    L, M, N = 2.0 * a / w, b / w, 2.0 * c / w  # II = X_ab . n
    det = E * G - F * F
    t1 = tx / np.sqrt(E)[:, None]
    t2 = np.cross(nrm, t1)

    def coords(t):  # (p, q) with p X_x + q X_y = t
        u, v = np.einsum("ij,ij->i", tx, t), np.einsum("ij,ij->i", ty, t)
        return (G * u - F * v) / det, (E * v - F * u) / det

    def second(p, q):
        return L * p[0] * q[0] + M * (p[0] * q[1] + p[1] * q[0]) + N * p[1] * q[1]

    c1, c2 = coords(t1), coords(t2)
    # shape operator S = -I^{-1} II in the orthonormal frame (t1, t2)
    s11, s12, s22 = -second(c1, c1), -second(c1, c2), -second(c2, c2)
    half = 0.5 * (s11 - s22)
    mean = 0.5 * (s11 + s22)
    rad = np.hypot(half, s12)
    theta = 0.5 * np.arctan2(s12, half)
    cos, sin = np.cos(theta)[:, None], np.sin(theta)[:, None]
    return nrm, mean + rad, mean - rad, cos * t1 + sin * t2, cos * t2 - sin * t1


def quadric_curvature(
    points,
    k: int = 40,
    normals=None,
    *,
    centres=None,
    workers: int = -1,
    block: int = 4096,
) -> QuadricResult:
    """Curvature by least-squares quadric fits over k nearest neighbours.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Point coordinates (any unit and position; centred internally).
    k : int, optional
        Neighbours per fit, the point itself included (default 40; at least 7).
    normals : array_like, shape (n, 3), optional
        Normals to use for the local frames instead of the oriented PCA
        normals; they are also the reported normals (normalised), the
        principal directions being projected onto their tangent planes.
        Curvature signs follow them.
    centres : array_like of int, shape (m,), optional
        Evaluate only at these points (indices into ``points``; repeats
        allowed), each with its ``k`` nearest neighbours in the whole cloud;
        the result has one row per centre, in this order.  The values are
        those of the full evaluation at these points (same neighbours, same
        fit) except for the side of the normal: the PCA normals of the
        centres are oriented by the same rule over a graph of the centres
        themselves (:data:`CENTRE_GRAPH_NEIGHBOURS` nearest other centres),
        which agrees with the full evaluation where the centres sample the
        surface densely enough for the propagation (spacing well below the
        curvature radii) and every component of it.  Given ``normals`` set
        the side as usual.
    workers : int, optional
        Threads for the k-d tree query (-1: all cores).
    block : int, optional
        Points processed at once, at most ``BLOCK_ROWS // k`` (memory
        ``~ block * k * 100`` bytes, at most ~100 MB).

    Returns
    -------
    QuadricResult

    Raises
    ------
    HeatcurvError
        On bad input (shape, NaN/inf, fewer than ``k`` points, ``k < 7``,
        bad normals, centres that are not indices of the points).

    Examples
    --------
    >>> import numpy as np
    >>> from heatcurv import surfaces
    >>> from support.baseline import quadric_curvature
    >>> sphere = surfaces.Sphere(radius=2.0).sample(4000, "fibonacci")
    >>> res = quadric_curvature(sphere.points)
    >>> round(float(np.median(res.mean)), 3)  # 1/R = 0.5; the quadric misses the quartic term
    0.505
    >>> at = quadric_curvature(sphere.points, centres=[7, 100, 7])
    >>> len(at), bool(np.allclose(at.mean, res.mean[[7, 100, 7]], rtol=1e-12))
    (3, True)
    """
    timings = {}
    tic = time.perf_counter()
    k = _validate_k(k)
    prepared = prepare_points(points, min_points=k)
    given = None if normals is None else prepare_normals(normals, prepared)
    block = max(1, min(int(block), BLOCK_ROWS // k))
    X, offset = prepared.points, prepared.offset
    if centres is None:
        at, back_rows = None, None
    else:
        chosen = _validate_centres(centres, prepared.n_input)
        at, back_rows = np.unique(prepared.inverse[chosen], return_inverse=True)
        back_rows = back_rows.reshape(-1)
    Y = X if at is None else X[at]  # the fitted points (distinct)
    n = Y.shape[0]
    dist, idx = cKDTree(X).query(Y, k=k, workers=workers)
    radius = dist[:, -1]
    area = math.pi * radius**2 / (k - 1)
    timings["neighbours"] = time.perf_counter() - tic

    tic = time.perf_counter()
    if given is not None:
        nrm = given if at is None else given[at]
    else:
        nrm = _pca_normals(X, idx, block)
        if at is None:
            graph = _knn_neighbourhood(idx, dist)
        else:  # orient over the centres' own k-NN graph
            gk = min(n, CENTRE_GRAPH_NEIGHBOURS + 1)
            gdist, gidx = cKDTree(Y).query(Y, k=gk, workers=workers)
            graph = _knn_neighbourhood(gidx.reshape(n, gk), gdist.reshape(n, gk))
        nrm = orient_normals(Y, nrm, graph, area)
    timings["normals"] = time.perf_counter() - tic

    tic = time.perf_counter()
    out_n = np.empty((n, 3))
    out_k1, out_k2 = np.empty(n), np.empty(n)
    out_d1, out_d2 = np.empty((n, 3)), np.empty((n, 3))
    well_posed = np.empty(n, dtype=bool)
    for s in range(0, n, block):
        sl = slice(s, min(s + block, n))
        nb = idx[sl]
        e1, e2 = tangent_frames(nrm[sl])
        frame = np.stack([e1, e2, nrm[sl]], axis=1)  # (b, 3, 3), rows e1, e2, n
        rel = X[nb] - Y[sl][:, None, :]
        loc = np.matmul(rel, frame.transpose(0, 2, 1))  # local coordinates (b, k, 3)
        scale = np.where(radius[sl] > 0, radius[sl], 1.0)
        x, y, z = (loc / scale[:, None, None]).transpose(2, 0, 1)
        A = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=2)  # (b, k, 6)
        coef, S = _least_squares(A, z)
        well_posed[sl] = (S[:, 0] > RCOND_MIN * S[:, -1]) & (radius[sl] > 0)
        sc = scale
        nrm_loc, k1, k2, d1_loc, d2_loc = _graph_curvature(
            coef[:, 0] / sc, coef[:, 1] / sc, coef[:, 2] / sc, coef[:, 3], coef[:, 4]
        )
        # local (e1, e2, n) coordinates -> 3-D: v @ frame
        out_n[sl] = np.einsum("bi,bij->bj", nrm_loc, frame)
        out_d1[sl] = np.einsum("bi,bij->bj", d1_loc, frame)
        out_d2[sl] = np.einsum("bi,bij->bj", d2_loc, frame)
        out_k1[sl], out_k2[sl] = k1, k2
    if given is not None:
        out_n = nrm.copy()
        d1 = out_d1 - np.einsum("ij,ij->i", out_d1, out_n)[:, None] * out_n
        out_d1 = d1 / np.linalg.norm(d1, axis=1)[:, None]
        out_d2 = np.cross(out_n, out_d1)
    timings["fit"] = time.perf_counter() - tic

    if at is None:
        back = prepared.to_input_order
        area_out = prepared.share_among_duplicates(area)
        rows = prepared.n_input
    else:

        def back(values):
            return values[back_rows]

        multiplicity = np.bincount(prepared.inverse, minlength=X.shape[0])[at]
        area_out = back(area / multiplicity)
        rows = chosen.size
    return QuadricResult(
        normals=back(out_n),
        mean=back(0.5 * (out_k1 + out_k2)),
        gaussian=back(out_k1 * out_k2),
        k1=back(out_k1),
        k2=back(out_k2),
        d1=back(out_d1),
        d2=back(out_d2),
        area=area_out,
        reliable=back(well_posed & np.all(np.isfinite(out_n), axis=1)),
        spacing=back(radius),
        neighbours=np.full(rows, k - 1, dtype=np.int64),
        options=QuadricOptions(k=k),
        info={"timings": timings, "offset": offset, "centres": None if at is None else chosen.copy()},
    )
