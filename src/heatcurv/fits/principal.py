"""Principal curvatures and directions by fitting the curvature tensor (paper section 3).

At each point the edge normal curvatures ``kN_ij = 2 (xi-xj).n / |xi-xj|^2``
(eq 2.12) are fitted by a symmetric 2x2 tensor ``B`` in a tangent frame
``(e1, e2)`` (Euler's formula, ``chi^T B chi = kN`` with ``chi`` the unit
tangent direction of the edge), minimising

    E(B) = sum_j w_ij (chi_ij^T B chi_ij - kN_ij)^2,   w_ij = W_ij |xi-xj|^2 A_j.

Writing ``B = H I + [[p, b], [b, -p]]`` and the edge angle ``theta`` gives
``chi^T B chi = H + p cos 2theta + b sin 2theta``; the eigenvalues are
``k_{1,2} = H +- sqrt(p^2 + b^2)`` with ``d1`` at angle ``atan2(b, p) / 2``.

* ``constrained`` (eq 3.1): ``a + c = 2 kappa_M`` fixes ``H`` to the mean
  curvature of eq 2.11/2.12; ``ac - b^2 <= kappa_M^2`` then always holds, and
  the lower bound ``ac - b^2 >= kappa_M^2 - ((min_j kN_ij - eps) - kappa_M)^2``
  is the disc ``p^2 + b^2 <= (kappa_M - min_j kN_ij + eps)^2``, i.e.
  ``k2 >= min_j kN_ij - eps``. The least-squares problem on a disc is solved
  exactly (a trust-region subproblem in two unknowns).
* ``unconstrained``: ``H``, ``p``, ``b`` fitted together (the classical
  fitting ellipse of the paper's refs [12, 31, 32]).

Gaussian curvature is ``k1 * k2`` (section 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import HeatcurvError
from ..geometry.neighbourhood import Neighbourhood
from ..orient.normals import tangent_frames

__all__ = ["PrincipalCurvatures", "principal_fit", "tensor_to_principal"]


@dataclass(frozen=True)
class PrincipalCurvatures:
    """Result of the tensor fit.

    Attributes
    ----------
    k1, k2 : ndarray, shape (n,)
        Principal curvatures, ``k1 >= k2``.
    d1, d2 : ndarray, shape (n, 3)
        Unit principal directions, tangent, ``d1 x d2 = n``.
    mean : ndarray, shape (n,)
        ``(k1 + k2) / 2`` (equal to the given mean for the constrained fit).
    gaussian : ndarray, shape (n,)
        ``k1 * k2``.
    well_posed : ndarray, shape (n,), bool
        False where the edge directions did not span the fit (fewer than
        three distinct directions with weight): the tensor is then a guess.
    """

    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    well_posed: np.ndarray

    def flipped(self, mask: np.ndarray) -> PrincipalCurvatures:
        """The curvatures seen from the other side where ``mask`` (shape (n,), bool) is set.

        Reversing the normal negates every curvature, so ``k1' = -k2`` along
        ``d2`` and ``k2' = -k1`` along ``d1``; ``d2 x d1 = -n`` keeps the
        frame right-handed about the reversed normal; the Gaussian curvature
        is unchanged.
        """
        m = np.asarray(mask, dtype=bool)
        col = m[:, None]
        return PrincipalCurvatures(
            k1=np.where(m, -self.k2, self.k1), k2=np.where(m, -self.k1, self.k2),
            d1=np.where(col, self.d2, self.d1), d2=np.where(col, self.d1, self.d2),
            mean=np.where(m, -self.mean, self.mean), gaussian=self.gaussian, well_posed=self.well_posed,
        )


def tensor_to_principal(H, p, b, e1, e2, normals) -> PrincipalCurvatures:
    """Eigen-decompose ``B = H I + [[p, b], [b, -p]]`` given in the frame ``(e1, e2)``.

    Parameters
    ----------
    H, p, b : ndarray, shape (n,)
        Tensor coefficients.
    e1, e2 : ndarray, shape (n, 3)
        Tangent frame the tensor is written in.
    normals : ndarray, shape (n, 3)
        Unit normals, ``e1 x e2 = n``.

    Returns
    -------
    PrincipalCurvatures
        ``well_posed`` all True (the caller refines it).
    """
    rho = np.hypot(p, b)
    phi = 0.5 * np.arctan2(b, p)
    d1 = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    d2 = np.cross(normals, d1)
    k1, k2 = H + rho, H - rho
    return PrincipalCurvatures(
        k1=k1, k2=k2, d1=d1, d2=d2, mean=H, gaussian=k1 * k2, well_posed=np.ones(H.shape, bool)
    )


def _disc_constrained_lsq(G, r, radius, iterations: int = 40):
    """Minimise ``z^T G z - 2 r^T z`` over ``|z| <= radius`` for many 2x2 problems.

    Parameters
    ----------
    G : ndarray, shape (n, 2, 2)
        Symmetric positive semi-definite normal matrices.
    r : ndarray, shape (n, 2)
        Right-hand sides.
    radius : ndarray, shape (n,)
        Disc radii (>= 0).

    Returns
    -------
    ndarray, shape (n, 2)
        The exact minimiser: the unconstrained one where it lies in the disc,
        else ``(G + lam I)^-1 r`` with ``lam > 0`` found by Newton's method on
        the secular equation ``1/|z(lam)| = 1/radius`` (More & Sorensen 1983).
    """
    g, Q = np.linalg.eigh(G)  # ascending eigenvalues
    q = np.einsum("nki,nk->ni", Q, r)  # r in the eigenbasis
    tiny = 1e-300
    with np.errstate(divide="ignore", invalid="ignore"):
        z_free = np.where(g > 1e-14 * np.maximum(g[:, 1:], tiny), q / np.maximum(g, tiny), 0.0)
    inside = np.linalg.norm(z_free, axis=1) <= radius
    lam = np.zeros(g.shape[0])
    np_err = np.errstate(over="ignore", divide="ignore", invalid="ignore")
    np_err.__enter__()
    active = ~inside & (radius > 0)
    if active.any():
        ga, qa, Ra = g[active], q[active], radius[active]
        # phi(lam) = 1/R - 1/|z(lam)| is convex and decreasing on lam >= 0 and
        # positive at 0 (the free minimiser is outside): Newton from lam = 0
        # increases monotonically to the root without overshooting.
        lam_a = np.zeros(ga.shape[0])
        for _ in range(iterations):
            den = np.maximum(ga + lam_a[:, None], tiny)
            zn = np.sqrt(np.sum((qa / den) ** 2, axis=1))
            dzn = -np.sum(qa**2 / den**3, axis=1) / np.maximum(zn, tiny)  # d|z|/dlam < 0
            phi = 1.0 / Ra - 1.0 / np.maximum(zn, tiny)
            lam_a = lam_a + np.where(dzn < 0, phi * zn**2 / np.maximum(-dzn, tiny), 0.0)
        lam[active] = lam_a
    z_eig = np.where(inside[:, None], z_free, q / np.maximum(g + lam[:, None], tiny))
    z_eig[(radius <= 0) & ~inside] = 0.0
    np_err.__exit__(None, None, None)
    return np.einsum("nik,nk->ni", Q, z_eig)


def principal_fit(
    points: np.ndarray,
    nbhd: Neighbourhood,
    normals: np.ndarray,
    pair_weights: np.ndarray,
    mean: np.ndarray | None = None,
    constrained: bool = True,
    eps: float | None = None,
) -> PrincipalCurvatures:
    """Fit the curvature tensor to the edge normal curvatures (section 3, eq 3.1).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    nbhd : Neighbourhood
        Neighbour pairs.
    normals : ndarray, shape (n, 3)
        Unit, consistently oriented normals (they fix the curvature signs).
    pair_weights : ndarray, shape (nnz,)
        ``w_ij``; the paper's are ``W_ij |xi-xj|^2 A_j``.
    mean : ndarray, shape (n,), optional
        Mean curvature ``kappa_M``; required for the constrained fit.
    constrained : bool, optional
        Eq 3.1 (``a + c = 2 kappa_M`` and the bounds on ``ac - b^2``) when
        True, the free three-parameter fit when False.
    eps : float, optional
        The paper's small constant in the lower bound of eq 3.1; default
        ``1e-9`` times the largest ``|kN|`` of the cloud.

    Returns
    -------
    PrincipalCurvatures
    """
    n = points.shape[0]
    rows = nbhd.rows
    diff = points[nbhd.indices] - points[rows]  # x_j - x_i
    nrm = normals[rows]
    along_n = np.einsum("ij,ij->i", diff, nrm)
    kN = -2.0 * along_n / nbhd.distances**2  # 2 (xi - xj).n / |xi - xj|^2
    e1, e2 = tangent_frames(normals)
    tx = np.einsum("ij,ij->i", diff, e1[rows])
    ty = np.einsum("ij,ij->i", diff, e2[rows])
    t2 = tx * tx + ty * ty
    with np.errstate(invalid="ignore", divide="ignore"):
        cos2 = np.where(t2 > 0, (tx * tx - ty * ty) / t2, 0.0)
        sin2 = np.where(t2 > 0, 2.0 * tx * ty / t2, 0.0)
    w = np.where(t2 > 0, pair_weights, 0.0)

    if constrained:
        if mean is None:
            raise HeatcurvError("the constrained fit (eq 3.1) needs the mean curvature")
        y = kN - mean[rows]
        acc = nbhd.segment_sum(
            np.stack([w * cos2 * cos2, w * cos2 * sin2, w * sin2 * sin2, w * cos2 * y, w * sin2 * y], 1)
        )
        G = np.stack([acc[:, 0], acc[:, 1], acc[:, 1], acc[:, 2]], 1).reshape(n, 2, 2)
        r = acc[:, 3:5]
        kmin = np.full(n, np.inf)
        np.minimum.at(kmin, rows, kN)
        kmin[~np.isfinite(kmin)] = mean[~np.isfinite(kmin)]
        if eps is None:
            eps = 1e-9 * (np.abs(kN).max() if kN.size else 1.0)
        radius = np.maximum(mean - kmin + eps, 0.0)
        pb = _disc_constrained_lsq(G, r, radius)
        H = mean
        det = G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] ** 2
        scale = np.maximum(G[:, 0, 0] + G[:, 1, 1], 1e-300)
        well_posed = det > 1e-8 * scale**2
    else:
        one = np.ones_like(w)
        cols = [one, cos2, sin2]
        acc = nbhd.segment_sum(
            np.stack([w * a * c for i, a in enumerate(cols) for c in cols[i:]] + [w * a * kN for a in cols], 1)
        )
        # unpack the 6 upper-triangle entries into symmetric 3x3 matrices
        iu = np.triu_indices(3)
        G = np.zeros((n, 3, 3))
        G[:, iu[0], iu[1]] = acc[:, :6]
        G[:, iu[1], iu[0]] = acc[:, :6]
        r = acc[:, 6:9]
        scale = np.maximum(np.trace(G, axis1=1, axis2=2), 1e-300)
        ridge = 1e-12 * scale
        sol = np.linalg.solve(G + ridge[:, None, None] * np.eye(3), r[:, :, None])[:, :, 0]
        H = sol[:, 0]
        pb = sol[:, 1:3]
        well_posed = np.linalg.det(G) > 1e-9 * scale**3
    res = tensor_to_principal(H, pb[:, 0], pb[:, 1], e1, e2, normals)
    return PrincipalCurvatures(
        k1=res.k1, k2=res.k2, d1=res.d1, d2=res.d2, mean=res.mean, gaussian=res.gaussian, well_posed=well_posed
    )
