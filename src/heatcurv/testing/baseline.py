"""The classical k-nearest-neighbour quadric fit, as a baseline for heatcurv.

(Formerly ``heatcurv.baseline``.)

This is the estimator most users know from PCL / CGAL-style pipelines
(osculating jets of degree 2, "quadric fitting"):

1. the ``k`` nearest neighbours of every point (the point itself included);
2. a PCA normal of that neighbourhood, given one consistent orientation with
   :func:`heatcurv.normals.orient_normals` (the same rule heatcurv uses:
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
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from numbers import Integral

import numpy as np
from scipy.spatial import cKDTree

from ..errors import HeatcurvError
from ..neighbourhood import Neighbourhood
from ..normals import orient_normals, tangent_frames
from ..validation import prepare_normals, prepare_points

__all__ = ["QuadricOptions", "QuadricResult", "quadric_curvature"]

#: A fit whose design matrix has ``s_min / s_max`` below this (in scaled
#: coordinates) is marked unreliable: the neighbours (nearly) lie on a conic
#: or a line and the quadric is not determined.
RCOND_MIN = 1e-6


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

    The fields mirror :class:`heatcurv.CurvatureResult` so that the same
    evaluation code (:func:`heatcurv.testing.compare`) applies.

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
        :func:`heatcurv.testing.compare` uses by default
        (:func:`heatcurv.testing.default_margin`).
    neighbours : ndarray of int, shape (n,)
        Neighbours per fit excluding the point itself (``k - 1``).
    options : QuadricOptions
    info : dict
        ``timings`` (seconds per stage), ``offset`` (the centring shift).
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


def _knn_neighbourhood(idx: np.ndarray, dist: np.ndarray) -> Neighbourhood:
    """CSR :class:`~heatcurv.neighbourhood.Neighbourhood` from k-NN arrays (shape (n, k)).

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
    """Smallest-eigenvalue eigenvector of each k-NN covariance, shape (n, 3)."""
    out = np.empty_like(X)
    for s in range(0, X.shape[0], block):
        nb = X[idx[s : s + block]]  # (b, k, 3)
        rel = nb - nb.mean(axis=1, keepdims=True)
        cov = np.einsum("bki,bkj->bij", rel, rel)
        out[s : s + block] = np.linalg.eigh(cov)[1][:, :, 0]
    return out


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
    workers : int, optional
        Threads for the k-d tree query (-1: all cores).
    block : int, optional
        Points processed at once (memory ``~ block * k * 100`` bytes).

    Returns
    -------
    QuadricResult

    Raises
    ------
    HeatcurvError
        On bad input (shape, NaN/inf, fewer than ``k`` points, ``k < 7``,
        bad normals).

    Examples
    --------
    >>> import numpy as np
    >>> from heatcurv import surfaces
    >>> from heatcurv.testing import quadric_curvature
    >>> sphere = surfaces.Sphere(radius=2.0).sample(4000, "fibonacci")
    >>> res = quadric_curvature(sphere.points)
    >>> round(float(np.median(res.mean)), 3)  # 1/R = 0.5; the quadric misses the quartic term
    0.505
    """
    timings = {}
    tic = time.perf_counter()
    k = _validate_k(k)
    prepared = prepare_points(points, min_points=k)
    given = None if normals is None else prepare_normals(normals, prepared)
    block = max(1, int(block))
    X, offset = prepared.points, prepared.offset
    n = X.shape[0]
    dist, idx = cKDTree(X).query(X, k=k, workers=workers)
    radius = dist[:, -1]
    area = math.pi * radius**2 / (k - 1)
    timings["neighbours"] = time.perf_counter() - tic

    tic = time.perf_counter()
    if given is None:
        nrm = _pca_normals(X, idx, block)
        nrm = orient_normals(X, nrm, _knn_neighbourhood(idx, dist), area)
    else:
        nrm = given
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
        rel = X[nb] - X[sl][:, None, :]
        loc = np.einsum("bij,bkj->bki", frame, rel)  # local coordinates (b, k, 3)
        scale = np.where(radius[sl] > 0, radius[sl], 1.0)
        x, y, z = (loc / scale[:, None, None]).transpose(2, 0, 1)
        A = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=2)  # (b, k, 6)
        U, S, Vt = np.linalg.svd(A, full_matrices=False)
        smax = S[:, :1]
        inv = np.where(S > RCOND_MIN * smax, 1.0 / np.where(S > 0, S, 1.0), 0.0)
        coef = np.einsum("bji,bj,bkj,bk->bi", Vt, inv, U, z)  # V diag(1/S) U^T z
        well_posed[sl] = (S[:, -1] > RCOND_MIN * smax[:, 0]) & (radius[sl] > 0)
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
        out_n = given.copy()
        d1 = out_d1 - np.einsum("ij,ij->i", out_d1, out_n)[:, None] * out_n
        out_d1 = d1 / np.linalg.norm(d1, axis=1)[:, None]
        out_d2 = np.cross(out_n, out_d1)
    timings["fit"] = time.perf_counter() - tic

    back = prepared.to_input_order
    return QuadricResult(
        normals=back(out_n),
        mean=back(0.5 * (out_k1 + out_k2)),
        gaussian=back(out_k1 * out_k2),
        k1=back(out_k1),
        k2=back(out_k2),
        d1=back(out_d1),
        d2=back(out_d2),
        area=prepared.share_among_duplicates(area),
        reliable=back(well_posed & np.all(np.isfinite(out_n), axis=1)),
        spacing=back(radius),
        neighbours=np.full(prepared.n_input, k - 1, dtype=np.int64),
        options=QuadricOptions(k=k),
        info={"timings": timings, "offset": offset},
    )
