"""Ray casting against the surfaces: argument checks, box slabs, quadric roots, safe marching.

:meth:`Surface.ray_intersect <heatcurv.surfaces.Surface.ray_intersect>`
checks its arguments with :func:`_as_rays`; the closed forms of the sphere,
ellipsoid and cylinder solve a quadratic with :func:`_first_quadric_root`;
every other surface marches along the rays on its implicit function
(:meth:`RayCasting._intersect`).
"""

from __future__ import annotations

import numpy as np

from heatcurv.errors import HeatcurvError

from ._util import _as_points


def _as_rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    """Broadcast ray origins and directions to (m, 3); directions made unit."""
    o = _as_points(origins, "origins")
    d = _as_points(directions, "directions")
    try:
        o, d = np.broadcast_arrays(o, d)
    except ValueError:
        raise HeatcurvError(
            f"origins and directions must broadcast, got shapes {o.shape} and {d.shape}"
        ) from None
    length = np.linalg.norm(d, axis=1)
    if np.any(length == 0.0):
        raise HeatcurvError("ray directions must be non-zero")
    return np.ascontiguousarray(o), d / length[:, None]


def _slab(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Entry and exit ray parameters of the box ``[lo, hi]`` (entry clipped at 0).

    Shapes: ``o``, ``d`` (m, 3); returns two arrays of shape (m,); the ray
    misses the box where ``entry >= exit``.
    """
    safe = np.where(d == 0.0, 1e-300, d)
    ta = (lo - o) / safe
    tb = (hi - o) / safe
    enter = np.max(np.minimum(ta, tb), axis=1)
    leave = np.min(np.maximum(ta, tb), axis=1)
    return np.maximum(enter, 0.0), leave


def _first_quadric_root(qa, qb, qc, valid=None, tmin=0.0):
    """Smallest root ``t > tmin`` of ``qa t^2 + 2 qb t + qc = 0`` (``inf`` if none).

    Vectorised over arrays of shape (m,), cancellation-free.  ``valid`` is an
    optional callable ``valid(t) -> bool array`` a root must also satisfy
    (e.g. lying within the cylinder's height).
    """
    disc = qb * qb - qa * qc
    ok = (disc >= 0.0) & (qa > 0.0)
    root = np.sqrt(np.where(ok, disc, 0.0))
    q = -(qb + np.copysign(root, qb))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(ok, q / qa, np.inf)
        r2 = np.where(ok & (q != 0.0), qc / q, np.inf)
    near = np.minimum(r1, r2)
    far = np.maximum(r1, r2)
    out = np.full(qa.shape, np.inf)
    for t in (far, near):  # the nearer valid root wins, so assign it last
        good = ok & np.isfinite(t) & (t > tmin)
        if valid is not None:
            good &= valid(np.where(good, t, 0.0))
        out = np.where(good, t, out)
    return out


class RayCasting:
    """First hits of rays; a base class of :class:`~heatcurv.surfaces.Surface`.

    A surface provides :meth:`implicit` and :meth:`bounding_box` (and, for a
    tighter search, :meth:`_implicit_lipschitz` and :meth:`_march_box`); the
    generic :meth:`_intersect` marches safely along the rays, closed forms
    override it.
    """

    def implicit(self, points) -> np.ndarray:
        """An implicit function of the surface (ignoring the border of open ones).

        Zero on the surface, positive on the side the normal points to
        (outside for closed surfaces, above for graphs).  It is
        Lipschitz-continuous along any unit direction with the constant
        :meth:`_implicit_lipschitz`, which lets :meth:`ray_intersect` march
        safely.

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        ndarray, shape (n,)
        """
        raise NotImplementedError

    def _implicit_lipschitz(self) -> float:
        """Upper bound of ``|grad implicit|`` (a distance function has 1)."""
        return 1.0

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """An axis-aligned box containing the surface (tight for the closed forms).

        Returns
        -------
        lo, hi : ndarray, shape (3,)
        """
        raise NotImplementedError

    def _march_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Box the ray marcher searches: the bounding box, slightly padded.

        Open surfaces whose border is given by the box (graphs) override this
        so that the box does not extend past the border.
        """
        lo, hi = self.bounding_box()
        pad = 1e-6 * float(np.linalg.norm(hi - lo)) + 1e-300
        return lo - pad, hi + pad

    def ray_intersect(self, origins, directions) -> np.ndarray:
        """Distance along each ray to its first intersection with the surface.

        Parameters
        ----------
        origins : array_like, shape (m, 3) or (3,)
            Ray origins (broadcast against ``directions``).
        directions : array_like, shape (m, 3) or (3,)
            Ray directions, need not be unit length.

        Returns
        -------
        ndarray, shape (m,)
            ``t > 0`` such that ``origin + t * direction / |direction|`` is the
            first surface point hit (the border of open surfaces respected),
            ``inf`` where the ray misses.  Closed forms for the
            :class:`Sphere`, :class:`Ellipsoid` and :class:`Cylinder`; the
            other surfaces march along the ray with steps
            ``max(|implicit| / Lipschitz, 2e-4 * box diagonal)`` (a step
            that cannot jump over the surface unless the ray stays within
            ~``2e-4`` box diagonals of it, i.e. is grazing), then bisect the
            first sign change to full precision.
        """
        o, d = _as_rays(origins, directions)
        return self._intersect(o, d)

    def _intersect(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Generic first hit: safe marching plus bisection (unit ``d``).

        What :meth:`ray_intersect` does for surfaces without a closed form
        (the sphere, ellipsoid and cylinder override this method).  Within
        :meth:`_march_box` each ray steps by ``max(|implicit| / Lipschitz,
        2e-4 * box diagonal)``, then the first sign change of
        :meth:`implicit` is bisected to adjacent floats.

        Parameters
        ----------
        o, d : ndarray, shape (m, 3)
            Ray origins and *unit* directions.

        Returns
        -------
        ndarray, shape (m,)
            Distance to the first hit, ``inf`` where the ray misses.
        """
        m = o.shape[0]
        out = np.full(m, np.inf)
        lo, hi = self._march_box()
        enter, leave = _slab(o, d, lo, hi)
        idx = np.flatnonzero(enter < leave)
        if idx.size == 0:
            return out
        lip = float(self._implicit_lipschitz())
        hmin = 2e-4 * float(np.linalg.norm(hi - lo))
        oo, dd, t, t_end = o[idx], d[idx], enter[idx], leave[idx]
        g = self.implicit(oo + t[:, None] * dd)
        at_zero = g == 0.0
        out[idx[at_zero]] = t[at_zero]
        keep = ~at_zero
        idx, oo, dd, t, t_end, g = idx[keep], oo[keep], dd[keep], t[keep], t_end[keep], g[keep]
        b_ids, b_lo, b_hi, b_neg = [], [], [], []
        while idx.size:
            step = np.maximum(np.abs(g) / lip, hmin)
            tn = np.minimum(t + step, t_end)
            gn = self.implicit(oo + tn[:, None] * dd)
            cross = (gn == 0.0) | (np.signbit(gn) != np.signbit(g))
            if np.any(cross):
                b_ids.append(idx[cross])
                b_lo.append(t[cross])
                b_hi.append(tn[cross])
                b_neg.append(np.signbit(g[cross]))
            keep = ~(cross | (tn >= t_end))
            idx, oo, dd, t, t_end, g = idx[keep], oo[keep], dd[keep], tn[keep], t_end[keep], gn[keep]
        if not b_ids:
            return out
        ids = np.concatenate(b_ids)
        a, b = np.concatenate(b_lo), np.concatenate(b_hi)
        neg_a = np.concatenate(b_neg)
        oo, dd = o[ids], d[ids]
        for _ in range(200):  # bisection to adjacent floats (~60 halvings)
            mid = 0.5 * (a + b)
            if np.all((mid == a) | (mid == b)):
                break
            gm = self.implicit(oo + mid[:, None] * dd)
            zero = gm == 0.0
            same = (np.signbit(gm) == neg_a) & ~zero
            a = np.where(same | zero, mid, a)
            b = np.where(same, b, mid)
        out[ids] = 0.5 * (a + b)
        return out
