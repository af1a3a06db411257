"""The base class of the analytic surfaces and the sample record they produce.

:class:`Surface` holds what every surface shares: the generic differential
geometry from the derivatives of the parametrisation, the interface of the
inverse parametrisation, implicit form and rays, and the public sampling
methods.  The parameter layouts come from
:class:`~heatcurv.surfaces.samplers.ParameterSamplers`, the ray casting
from :class:`~heatcurv.surfaces.rays.RayCasting`, the simulated scanner from
:mod:`heatcurv.surfaces.scan`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from heatcurv.errors import HeatcurvError

from ._util import _as_uv, _check_n, _dot, _positive, _unit
from .curvature import Curvature, _curvature_in_frame
from .noise import _add_noise, _check_noise
from .rays import RayCasting
from .samplers import SAMPLERS, ParameterSamplers
from .scan import _AROUND, _view_positions, simulate_scan


@dataclass(frozen=True, eq=False)
class SurfaceSample:
    """A point cloud drawn from a :class:`Surface`, with exact ground truth.

    Attributes
    ----------
    surface : Surface
        The surface the points were drawn from.
    sampler : str
        Name of the sampler (one of :data:`SAMPLERS`, or ``"custom"`` for
        :meth:`Surface.sample_at`).
    noise : float
        Noise standard deviation as a fraction of the bounding-box diagonal of
        ``clean_points``.
    sigma : float
        The absolute noise standard deviation that was applied.
    points : ndarray, shape (n, 3)
        What an estimator sees: ``clean_points`` plus noise.
    clean_points : ndarray, shape (n, 3)
        Points exactly on the surface.
    u, v : ndarray, shape (n,)
        Parameters of the clean points.
    normals : ndarray, shape (n, 3)
        Exact unit normals at the clean points.
    mean, gaussian, k1, k2 : ndarray, shape (n,)
        Exact curvatures at the clean points (see :class:`Curvature`).
    d1, d2 : ndarray, shape (n, 3)
        Exact principal directions.
    umbilic : ndarray of bool, shape (n,)
        Where the principal directions are undefined.
    total_area : float
        Exact area of the whole surface.
    border_distance : ndarray, shape (n,)
        Lower bound on the distance along the surface to the border
        (``inf`` on closed surfaces).
    feature_distance : ndarray, shape (n,)
        Distance along the surface to the nearest sharp feature (the fold of a
        :class:`FoldedSquare`); ``inf`` on smooth surfaces.
    viewpoints : ndarray, shape (m, 3), or None
        ``"scan"`` samples: the scanner positions; None for the other samplers.
    viewpoint_index : ndarray of int, shape (n,), or None
        ``"scan"`` samples: the viewpoint (row of ``viewpoints``) whose ray
        produced each point; None for the other samplers.
    """

    surface: Surface
    sampler: str
    noise: float
    sigma: float
    points: np.ndarray
    clean_points: np.ndarray
    u: np.ndarray
    v: np.ndarray
    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    umbilic: np.ndarray
    total_area: float
    border_distance: np.ndarray
    feature_distance: np.ndarray = field(repr=False)
    viewpoints: np.ndarray | None = field(default=None, repr=False)
    viewpoint_index: np.ndarray | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def transformed(self, scale: float = 1.0, rotation=None, translation=None) -> SurfaceSample:
        """The same sample after ``x -> scale * rotation @ x + translation``.

        Every exact quantity is mapped accordingly: normals and principal
        directions are rotated, curvatures divided by ``scale`` (Gaussian by
        ``scale**2``), ``total_area`` multiplied by ``scale**2``, distances
        (``border_distance``, ``feature_distance``, ``sigma``) by ``scale``;
        ``points`` (noise included) and ``viewpoints`` are moved like the clean
        points.  ``surface``, ``u`` and ``v`` still refer to the untransformed
        surface.

        Parameters
        ----------
        scale : float
            ``> 0``.
        rotation : array_like, shape (3, 3), optional
            A proper rotation (orthonormal, determinant +1, to 1e-9); a
            reflection would break ``d1 x d2 = n``.  Default identity.
        translation : array_like, shape (3,), optional
            Default zero.

        Returns
        -------
        SurfaceSample
        """
        s = _positive("scale", scale)
        rot = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        if rot.shape != (3, 3) or not np.all(np.isfinite(rot)):
            raise HeatcurvError(f"rotation must be a finite 3 x 3 matrix, got shape {rot.shape}")
        if not (np.allclose(rot @ rot.T, np.eye(3), atol=1e-9) and np.linalg.det(rot) > 0):
            raise HeatcurvError("rotation must be a proper rotation matrix (orthonormal, det = +1)")
        shift = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
        if shift.shape != (3,) or not np.all(np.isfinite(shift)):
            raise HeatcurvError(f"translation must be 3 finite numbers, got {translation!r}")

        def move(p):
            return s * (p @ rot.T) + shift

        return replace(
            self,
            points=move(self.points),
            clean_points=move(self.clean_points),
            normals=self.normals @ rot.T,
            d1=self.d1 @ rot.T,
            d2=self.d2 @ rot.T,
            mean=self.mean / s,
            k1=self.k1 / s,
            k2=self.k2 / s,
            gaussian=self.gaussian / (s * s),
            sigma=self.sigma * s,
            total_area=self.total_area * s * s,
            border_distance=self.border_distance * s,
            feature_distance=self.feature_distance * s,
            viewpoints=None if self.viewpoints is None else move(self.viewpoints),
        )

    @property
    def n(self) -> int:
        """Number of points."""
        return len(self)

    @property
    def fold_distance(self) -> np.ndarray:
        """Alias of :attr:`feature_distance` (distance to the fold), shape (n,)."""
        return self.feature_distance

    def interior(self, margin: float) -> np.ndarray:
        """Mask of the points farther than ``margin`` from the border.

        Parameters
        ----------
        margin : float
            Distance along the surface.

        Returns
        -------
        ndarray of bool, shape (n,)
            ``border_distance > margin``; all True on closed surfaces.
        """
        return self.border_distance > float(margin)

    def near_feature(self, margin: float) -> np.ndarray:
        """Mask of the points within ``margin`` of a sharp feature.

        Parameters
        ----------
        margin : float
            Distance along the surface.

        Returns
        -------
        ndarray of bool, shape (n,)
            ``feature_distance <= margin``; all False on smooth surfaces.
        """
        return self.feature_distance <= float(margin)


class Surface(ParameterSamplers, RayCasting):
    """Base class of the analytic surfaces.

    Subclasses define :meth:`position`, :meth:`tangents`,
    :meth:`second_derivatives` and :meth:`area`, and may override
    :meth:`normal` and :meth:`curvature` with closed forms.  The generic
    implementations work from the derivatives of the parametrisation.

    Attributes
    ----------
    name : str
        Short name, as in :data:`SURFACES`.
    closed : bool
        True for surfaces without border.
    domain : tuple of two (float, float)
        Parameter rectangle ``((u0, u1), (v0, v1))``.
    periodic : tuple of two bool
        Whether ``u`` and ``v`` are periodic (then the upper end is excluded).
    """

    name: str = "surface"
    closed: bool = False
    periodic: tuple[bool, bool] = (False, False)
    domain: tuple[tuple[float, float], tuple[float, float]] = ((0.0, 1.0), (0.0, 1.0))

    # -- geometry to be provided by subclasses -----------------------------

    def position(self, u, v) -> np.ndarray:
        """Points ``X(u, v)``.

        Parameters
        ----------
        u, v : array_like, shape (n,)
            Parameters (scalars are treated as length-1 arrays).

        Returns
        -------
        ndarray, shape (n, 3)
        """
        raise NotImplementedError

    def tangents(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Analytic first derivatives ``X_u`` and ``X_v``.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        X_u, X_v : ndarray, shape (n, 3)
        """
        raise NotImplementedError

    def second_derivatives(self, u, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Analytic second derivatives ``X_uu``, ``X_uv``, ``X_vv``.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        X_uu, X_uv, X_vv : ndarray, shape (n, 3)
        """
        raise NotImplementedError

    def area(self) -> float:
        """Exact total area of the surface.

        Returns
        -------
        float
        """
        raise NotImplementedError

    # -- generic differential geometry -------------------------------------

    def normal(self, u, v) -> np.ndarray:
        """Unit normal, oriented as documented for each surface.

        The generic version is ``X_u x X_v / |X_u x X_v|``; every
        parametrisation in this package is chosen so that this has the
        documented orientation.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n, 3)
        """
        xu, xv = self.tangents(u, v)
        return _unit(np.cross(xu, xv))

    def area_element(self, u, v) -> np.ndarray:
        """Area element ``|X_u x X_v|``.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n,)
        """
        xu, xv = self.tangents(u, v)
        return np.linalg.norm(np.cross(xu, xv), axis=1)

    def curvature_from_derivatives(self, u, v) -> Curvature:
        """Curvatures from the analytic derivatives, by the general formulas.

        Builds ``I`` and ``II_ab = X_ab . n`` from :meth:`tangents`,
        :meth:`second_derivatives` and :meth:`normal`, expresses the shape
        operator ``S = -I^{-1} II`` in the orthonormal tangent frame
        ``e1 = X_u / |X_u|``, ``e2 = n x e1`` and diagonalises it in closed
        form.  Needs a regular parametrisation (``X_u != 0``).

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        Curvature
        """
        u, v = _as_uv(u, v)
        xu, xv = self.tangents(u, v)
        xuu, xuv, xvv = self.second_derivatives(u, v)
        nrm = self.normal(u, v)
        e_ = _dot(xu, xu)
        f_ = _dot(xu, xv)
        g_ = _dot(xv, xv)
        det = e_ * g_ - f_ * f_
        l_ = _dot(xuu, nrm)
        m_ = _dot(xuv, nrm)
        n_ = _dot(xvv, nrm)
        e1 = _unit(xu)
        e2 = np.cross(nrm, e1)

        def coords(e):  # parameter coordinates (a, b) with a X_u + b X_v = e
            p = _dot(xu, e)
            q = _dot(xv, e)
            return (g_ * p - f_ * q) / det, (e_ * q - f_ * p) / det

        def second_form(p, q):
            return l_ * p[0] * q[0] + m_ * (p[0] * q[1] + p[1] * q[0]) + n_ * p[1] * q[1]

        p1 = coords(e1)
        p2 = coords(e2)
        return _curvature_in_frame(
            e1, e2, -second_form(p1, p1), -second_form(p1, p2), -second_form(p2, p2)
        )

    def curvature(self, u, v) -> Curvature:
        """Exact curvatures and principal directions.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        Curvature
        """
        return self.curvature_from_derivatives(u, v)

    def border_distance(self, u, v) -> np.ndarray:
        """Lower bound on the distance along the surface to the border.

        The generic version is the parameter distance to the edges of the
        non-periodic parameter directions, a lower bound whenever the metric
        dominates the Euclidean metric of the parameters in those directions
        (true for every open surface here).

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n,)
            ``inf`` everywhere on closed surfaces.
        """
        u, v = _as_uv(u, v)
        out = np.full(u.shape, np.inf)
        if self.closed:
            return out
        for t, (t0, t1), per in zip((u, v), self.domain, self.periodic):
            if not per:
                out = np.minimum(out, np.minimum(t - t0, t1 - t))
        return out

    def feature_distance(self, u, v) -> np.ndarray:
        """Distance along the surface to the nearest sharp feature.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n,)
            ``inf`` for smooth surfaces.
        """
        u, _ = _as_uv(u, v)
        return np.full(u.shape, np.inf)

    # -- inverse parametrisation -------------------------------------------

    def parameters_of(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Parameters ``(u, v)`` of points on the surface, the inverse of :meth:`position`.

        For points on the surface ``position(*parameters_of(p))`` reproduces
        ``p`` up to rounding.  Points off the surface are mapped to the
        parameters of a nearby surface point (a radial or vertical projection,
        documented per surface), not necessarily the nearest one.  Periodic
        parameters are wrapped into the domain, the others are *not* clipped.

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        u, v : ndarray, shape (n,)
        """
        raise NotImplementedError

    def default_viewpoints(self) -> np.ndarray:
        """Default scanner positions of :meth:`scan`.

        Three positions looking at the bounding-box centre from 2.5, 3 and 3.5
        bounding radii (half the bounding-box diagonal): for closed surfaces
        around the object at azimuths 30, 150, 270 degrees and elevations
        +35, -25, +10 degrees; graphs (and the folded square) are looked at
        from above, from 2, 2.75 and 3.5 bounding radii at azimuths 0, 120,
        240 and elevations 65, 55, 72 degrees (steeper than the surfaces'
        slopes, so only the upper side is seen); the cylinder from the side
        (azimuths as above) at heights +0.6, -0.6 and 0 half-heights, so the
        inside of the tube stays unseen.

        Returns
        -------
        ndarray, shape (3, 3)
        """
        return _view_positions(_AROUND, *self.bounding_box())

    # -- the simulated scanner ---------------------------------------------

    def scan(
        self,
        n,
        viewpoints=None,
        noise: float = 0.0,
        seed=None,
        max_incidence: float = 80.0,
    ) -> SurfaceSample:
        """A simulated terrestrial / structured-light scan with exact ground truth.

        From each viewpoint, rays are cast on a regular angular grid (scan
        lines of constant azimuth about the viewpoint's vertical axis, the same
        angular step in azimuth and elevation, covering the cone of the
        bounding sphere) and the *first* hit of each ray is kept, unless it
        is grazing (angle between ray and normal > ``max_incidence``).  Hits
        of all viewpoints are pooled, so the density varies: overlaps, scan
        lines, fall-off with distance and with incidence (``~ cos(incidence) /
        distance^2``); regions no viewpoint sees stay empty (holes, also on
        closed surfaces).  Open surfaces can be hit on either side (e.g. the
        inside of the :class:`Cylinder` through its ends, with viewpoints not
        of the default); ``normals`` keep the surface's orientation.

        The angular step is chosen from a coarse pilot scan so that the hit
        count is about ``1.03 n``; the excess hits are then dropped at random
        (seeded, order preserved), which gives exactly ``n`` points.  If a scan
        still comes out short after three refinements of the step (it should
        not), fewer points are returned.  The exact values at each hit come
        from its parameters, :meth:`parameters_of` of the hit point, so
        ``clean_points == position(u, v)`` exactly.  ``border_distance`` is
        the minimum of the surface's own and an approximate distance to the
        unseen region (see :meth:`heatcurv.surfaces.scan.Scanner.border_distance`), so
        :meth:`SurfaceSample.interior` excludes the borders of holes as well.

        Parameters
        ----------
        n : int
            Requested number of points (>= 4).
        viewpoints : array_like, shape (m, 3), optional
            Scanner positions, each outside the bounding sphere (centre and
            half-diagonal of :meth:`bounding_box`); default
            :meth:`default_viewpoints`.
        noise : float
            As in :meth:`sample` (``noise * diag`` standard deviation).
        seed : None, int, or numpy.random.Generator
            Seeds the dropping of excess hits and the noise; same seed, same
            sample.
        max_incidence : float
            Largest kept angle between ray and surface normal, degrees in
            ``(0, 90)``.

        Returns
        -------
        SurfaceSample
            ``sampler == "scan"``, with ``viewpoints`` (m, 3) and
            ``viewpoint_index`` (n,) set.

        Raises
        ------
        HeatcurvError
            For ``n < 4``, bad viewpoints (shape, non-finite, inside the
            bounding sphere), a bad ``max_incidence`` or noise, or when no
            ray hits the surface.
        """
        return simulate_scan(
            self, n, viewpoints=viewpoints, noise=noise, seed=seed, max_incidence=max_incidence
        )

    # -- public sampling ---------------------------------------------------

    def sample(self, n, sampler: str = "grid", noise: float = 0.0, seed=None) -> SurfaceSample:
        """Draw a point cloud with exact ground truth.

        Parameters
        ----------
        n : int
            Requested number of points (>= 4).  ``"fibonacci"`` and
            ``"random"`` return exactly ``n``; ``"grid"`` and ``"jittered"``
            return the nearest grid size; ``"scan"`` about ``n`` (see
            :meth:`scan`).
        sampler : {"grid", "fibonacci", "random", "jittered", "scan"}
            See :mod:`heatcurv.surfaces`; ``"scan"`` is :meth:`scan` with the
            default viewpoints.
        noise : float
            Standard deviation of isotropic Gaussian noise added to
            ``points``, as a fraction of the bounding-box diagonal of the clean
            points.
        seed : None, int, or numpy.random.Generator
            Passed to :func:`numpy.random.default_rng`; the same seed gives the
            same sample.

        Returns
        -------
        SurfaceSample

        Raises
        ------
        HeatcurvError
            For an unknown sampler, ``n < 4`` or a negative/non-finite noise.
        """
        n = _check_n(n)
        if sampler not in SAMPLERS:
            raise HeatcurvError(
                f"unknown sampler {sampler!r}; supported samplers: {', '.join(SAMPLERS)}"
            )
        if sampler == "scan":
            return self.scan(n, noise=noise, seed=seed)
        rng = np.random.default_rng(seed)
        if sampler == "grid":
            u, v = self._grid_uv(n)
        elif sampler == "fibonacci":
            u, v = self._fibonacci_uv(n)
        elif sampler == "random":
            u, v = self._random_uv(n, rng)
        else:
            u, v = self._jittered_uv(n, rng)
        return self._make_sample(u, v, sampler, noise, rng)

    def sample_at(self, u, v, noise: float = 0.0, seed=None) -> SurfaceSample:
        """Build a :class:`SurfaceSample` at given parameters.

        Parameters
        ----------
        u, v : array_like, shape (n,)
            Parameters of the points.
        noise : float
            As in :meth:`sample`.
        seed : None, int, or numpy.random.Generator
            Seed of the noise.

        Returns
        -------
        SurfaceSample
            With ``sampler == "custom"``.
        """
        u, v = _as_uv(u, v)
        u, v = u.copy(), v.copy()  # never alias the caller's arrays
        return self._make_sample(u, v, "custom", noise, np.random.default_rng(seed))

    def _make_sample(
        self, u, v, sampler, noise, rng, border_distance=None, viewpoints=None, viewpoint_index=None
    ) -> SurfaceSample:
        noise = _check_noise(noise)
        u, v = _as_uv(u, v)
        clean = self.position(u, v)
        curv = self.curvature(u, v)
        points, sigma = _add_noise(clean, noise, rng)
        return SurfaceSample(
            surface=self,
            sampler=sampler,
            noise=noise,
            sigma=sigma,
            points=points,
            clean_points=clean,
            u=u,
            v=v,
            normals=self.normal(u, v),
            mean=curv.mean,
            gaussian=curv.gaussian,
            k1=curv.k1,
            k2=curv.k2,
            d1=curv.d1,
            d2=curv.d2,
            umbilic=curv.umbilic,
            total_area=float(self.area()),
            border_distance=(
                self.border_distance(u, v) if border_distance is None else border_distance
            ),
            feature_distance=self.feature_distance(u, v),
            viewpoints=viewpoints,
            viewpoint_index=viewpoint_index,
        )

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self._params().items())
        return f"{type(self).__name__}({params})"

    def _params(self) -> dict:
        return {}
