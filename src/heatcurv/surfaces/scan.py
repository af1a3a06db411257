"""The simulated terrestrial / structured-light scanner behind ``sampler="scan"``.

:meth:`Surface.scan <heatcurv.surfaces.Surface.scan>` documents what a scan
sample is; this module does the work:

* :func:`_view_positions` and the default station layouts ``_AROUND`` (around
  an object) and ``_ABOVE`` (above a patch), used by the surfaces'
  ``default_viewpoints``;
* :class:`Scanner`, the scanner set up at its viewpoints: the angular ray grid
  (:meth:`Scanner.rays`), the kept first hits (:meth:`Scanner.hits`), which
  surface points it sees (:meth:`Scanner.sees`) and the distance to the unseen
  region (:meth:`Scanner.border_distance`);
* :func:`simulate_scan`, which checks the arguments, chooses the angular step
  from a pilot scan and returns the :class:`~heatcurv.surfaces.SurfaceSample`.

The scanner only uses the public geometry of the surface and a few of its
private hooks (``_intersect``, ``_clip_uv``, ``_grid_uv``, ``_make_sample``);
it imports no surface class.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from heatcurv.errors import HeatcurvError

from ._util import _as_points, _check_n, _dot, _finite
from .noise import _check_noise


def _view_positions(views, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Viewpoints from ``(azimuth, elevation, distance)`` triples, shape (k, 3).

    Angles in degrees about the centre of the box ``[lo, hi]``, distances in
    bounding radii (half the box diagonal).
    """
    az = np.radians([a for a, _, _ in views])
    el = np.radians([e for _, e, _ in views])
    dist = np.array([r for _, _, r in views]) * 0.5 * float(np.linalg.norm(hi - lo))
    unit = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return 0.5 * (lo + hi) + dist[:, None] * unit


#: (azimuth, elevation, distance) of the default scan viewpoints around an
#: object and above a graph patch: degrees, and bounding radii (half the
#: bounding-box diagonal) from the box centre; see
#: :meth:`Surface.default_viewpoints`.  Different distances give the scans
#: different densities (one angular step for all), as with a real scanner
#: set up at several stations.
_AROUND = ((30.0, 35.0, 2.5), (150.0, -25.0, 3.0), (270.0, 10.0, 3.5))
_ABOVE = ((0.0, 65.0, 2.0), (120.0, 55.0, 2.75), (240.0, 72.0, 3.5))


def _bounding_sphere(surface) -> tuple[np.ndarray, float]:
    """Centre and radius (half the diagonal) of the sphere of ``surface.bounding_box()``."""
    lo, hi = surface.bounding_box()
    return 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))


class Scanner:
    """A scanner set up at some viewpoints around one surface.

    Parameters
    ----------
    surface : Surface
    viewpoints : ndarray, shape (m, 3)
        Scanner positions, checked by :func:`simulate_scan` (outside the
        bounding sphere).
    min_cos : float
        Cosine of the largest kept incidence angle (ray against normal).
    """

    def __init__(self, surface, viewpoints: np.ndarray, min_cos: float):
        self.surface = surface
        self.viewpoints = viewpoints
        self.min_cos = min_cos

    def rays(self, delta: float):
        """Rays of the angular scan grids: origins, unit directions, viewpoint index.

        Each viewpoint looks at the bounding-box centre; its rays are spaced
        ``delta`` radians in azimuth (about the viewpoint's vertical axis) and
        elevation, ordered in scan lines of constant azimuth, and limited to the
        cone around the bounding sphere.
        """
        centre, rb = _bounding_sphere(self.surface)
        origins, dirs, index = [], [], []
        for i, c in enumerate(self.viewpoints):
            fwd = centre - c
            dist = float(np.linalg.norm(fwd))
            f = fwd / dist
            half = min(math.asin(min(rb / dist, 1.0)) * 1.02, 0.5 * math.pi)
            up0 = np.array([0.0, 0.0, 1.0]) if abs(f[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
            right = np.cross(f, up0)
            right /= np.linalg.norm(right)
            up = np.cross(right, f)
            k = int(math.ceil(half / delta))
            ang = delta * np.arange(-k, k + 1, dtype=np.float64)
            phi, theta = np.meshgrid(ang, ang, indexing="ij")  # scan lines: constant azimuth
            phi, theta = phi.ravel(), theta.ravel()
            inside = np.cos(theta) * np.cos(phi) >= math.cos(half)
            phi, theta = phi[inside], theta[inside]
            ct = np.cos(theta)[:, None]
            d = ct * (np.cos(phi)[:, None] * f + np.sin(phi)[:, None] * right) + np.sin(theta)[:, None] * up
            dirs.append(d / np.linalg.norm(d, axis=1)[:, None])
            origins.append(np.broadcast_to(c, d.shape))
            index.append(np.full(d.shape[0], i, dtype=np.int64))
        return np.concatenate(origins), np.concatenate(dirs), np.concatenate(index)

    def hits(self, delta: float):
        """Cast the scan grid; the kept first hits' parameters and viewpoint index."""
        surface = self.surface
        o, d, index = self.rays(delta)
        t = surface._intersect(o, d)
        hit = np.isfinite(t)
        o, d, t, index = o[hit], d[hit], t[hit], index[hit]
        u, v = surface._clip_uv(*surface.parameters_of(o + t[:, None] * d))
        facing = np.abs(_dot(surface.normal(u, v), d)) >= self.min_cos
        return u[facing], v[facing], index[facing]

    def sees(self, q: np.ndarray, nq: np.ndarray) -> np.ndarray:
        """Which points ``q`` (normals ``nq``) some viewpoint sees unoccluded, not grazing."""
        lo, hi = self.surface.bounding_box()
        tol = 1e-7 * float(np.linalg.norm(hi - lo))
        covered = np.zeros(q.shape[0], dtype=bool)
        for c in self.viewpoints:
            vec = q - c
            dist = np.linalg.norm(vec, axis=1)
            d = vec / dist[:, None]
            sel = np.flatnonzero(~covered & (np.abs(_dot(nq, d)) >= self.min_cos))
            if sel.size == 0:
                continue
            t = self.surface._intersect(np.broadcast_to(c, (sel.size, 3)), d[sel])
            covered[sel[t >= dist[sel] - tol]] = True
        return covered

    def border_distance(self, u, v, n: int) -> np.ndarray:
        """``border_distance`` of scan points: min of the surface's and the hole's.

        The unseen region is found on a dense reference sample (the
        ``"grid"`` layout with ``clip(2 n, 4000, 100000)`` points): a reference
        point is seen if some viewpoint sees it unoccluded and within the
        incidence limit.  The distance to the unseen region is approximated
        by the 3-D distance to the nearest unseen reference point minus the
        largest reference nearest-neighbour distance (clipped at 0): close to
        a lower bound of the distance along the surface, to about one
        reference spacing.
        """
        surface = self.surface
        own = surface.border_distance(u, v)
        ur, vr = surface._grid_uv(int(min(max(2 * n, 4000), 100000)))
        q = surface.position(ur, vr)
        seen = self.sees(q, surface.normal(ur, vr))
        if np.all(seen):
            return own
        spacing = float(np.max(cKDTree(q).query(q, 2)[0][:, 1]))
        hole = cKDTree(q[~seen]).query(surface.position(u, v))[0]
        return np.minimum(own, np.maximum(hole - spacing, 0.0))


def simulate_scan(surface, n, viewpoints=None, noise: float = 0.0, seed=None, max_incidence: float = 80.0):
    """The work of :meth:`Surface.scan <heatcurv.surfaces.Surface.scan>` (see there).

    Parameters
    ----------
    surface : Surface
    n, viewpoints, noise, seed, max_incidence
        As in :meth:`Surface.scan <heatcurv.surfaces.Surface.scan>`.

    Returns
    -------
    SurfaceSample
    """
    n = _check_n(n)
    noise = _check_noise(noise)
    inc = _finite("max_incidence", max_incidence)
    if not 0.0 < inc < 90.0:
        raise HeatcurvError(f"max_incidence must be in (0, 90) degrees, got {max_incidence!r}")
    min_cos = math.cos(math.radians(inc))
    centre, rb = _bounding_sphere(surface)
    if viewpoints is None:
        vps = surface.default_viewpoints()
    else:
        vps = _as_points(viewpoints, "viewpoints")
    far = np.linalg.norm(vps - centre, axis=1)
    if np.any(far <= rb * (1.0 + 1e-9)):
        raise HeatcurvError(
            f"scan viewpoints must lie outside the bounding sphere (centre {centre.tolist()}, "
            f"radius {rb:.6g}); distances {far.tolist()}"
        )
    scanner = Scanner(surface, vps, min_cos)
    rng = np.random.default_rng(seed)
    # pilot: ~3000 rays per viewpoint over the widest cone
    half = max(math.asin(min(rb / float(f), 1.0)) for f in far)
    delta0 = 1.02 * half * math.sqrt(math.pi / 3000.0)
    u, _, _ = scanner.hits(delta0)
    if u.size == 0:
        raise HeatcurvError("no scan ray hit the surface from these viewpoints")
    target = 1.03 * n + 8
    delta = delta0 * math.sqrt(u.size / target)
    for _ in range(4):
        u, v, index = scanner.hits(delta)
        if u.size >= n:
            break
        delta *= 0.99 * math.sqrt(max(u.size, 1) / target)
    if u.size > n:
        keep = np.sort(rng.choice(u.size, size=n, replace=False))
        u, v, index = u[keep], v[keep], index[keep]
    border = scanner.border_distance(u, v, n)
    return surface._make_sample(
        u, v, "scan", noise, rng, border_distance=border, viewpoints=vps, viewpoint_index=index
    )
