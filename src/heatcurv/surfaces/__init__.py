"""Analytic test surfaces with exact differential geometry, and point samplers.

Every surface here is given by a parametrisation ``X(u, v)`` with analytic first
and second derivatives, so its unit normal, principal curvatures ``k1 >= k2``,
mean and Gaussian curvature and principal directions are known exactly.  The
samplers turn a surface into a point cloud (:class:`SurfaceSample`) that
carries these exact values as ground truth for estimators, tests and benchmarks.

Sign convention
---------------
A curvature is **positive where the surface bends away from its normal**: the
normal curvature of a chord is ``2 (x_i - x_j) . n_i / |x_i - x_j|^2``.  With
``II_ab = X_ab . n`` and the first fundamental form ``I``, the shape operator is
``S = -I^{-1} II``; ``k1 >= k2`` are its eigenvalues, ``mean = (k1 + k2) / 2``
and ``gaussian = k1 * k2``.  A sphere of radius ``R`` with outward normals has
``mean = k1 = k2 = +1/R``.  The principal directions ``d1`` (for ``k1``) and
``d2`` (for ``k2``) are unit 3-D tangent vectors with ``d1 x d2 = n``
(``d2 = n x d1``).  At umbilics (``|k1 - k2| <= 1e-9 max(1, |k1|, |k2|)``) they
are some orthonormal tangent frame with the same handedness.

Normal orientation
------------------
Closed surfaces (:class:`Sphere`, :class:`Ellipsoid`, :class:`Torus`): outward.  Graphs
(:class:`Graph`, :class:`Paraboloid`, :class:`Saddle`, :class:`Arch`,
:class:`Plane`) and :class:`FoldedSquare`: positive z-component.
:class:`Cylinder`: away from the axis.  Consequently an upward-opening
:class:`Paraboloid` (``a > 0``) has *negative* curvature and the
:class:`Arch` ridge has *positive* curvature.

Samplers
--------
``"grid"``
    Regular grid in parameter space, border included; periodic directions do
    not repeat the seam, and the numbers of rows and columns are chosen so
    that cells are nearly square in 3-D (``m x m`` with ``m = round(sqrt(n))``
    for the square graph domains).  On the sphere a latitude-longitude grid
    degenerates at the poles, so ``"grid"`` gives the Fibonacci sphere there
    (and on the :class:`Ellipsoid`, the Fibonacci sphere mapped, see below).
``"fibonacci"``
    The 2-D Fibonacci lattice ``((i + 0.5) / n, frac(i * golden))`` in the
    unit square, mapped by the surface's area-preserving map where it has one
    (sphere: the classic Fibonacci sphere, torus: inverse CDF of the area
    element in the tube angle, cylinder: linear) and by the plain linear
    parameter map otherwise (graphs, plane, folded square: *not*
    area-uniform on curved graphs).  The :class:`Ellipsoid` takes the
    sphere's lattice in its (longitude, latitude) parameters, i.e. the
    Fibonacci sphere stretched by ``diag(a, b, c)``: nearly uniform in
    parameter space but *not* area-uniform (denser where the stretch is
    smaller).  Exactly ``n`` points.
``"random"``
    Area-uniform random points, exactly ``n``, by rejection sampling in the
    parameter domain with acceptance ``|X_u x X_v| / max``.
``"jittered"``
    The grid with every point moved uniformly within +-0.25 cell in parameter
    space (reflected back at a domain border, wrapped in periodic
    directions).  On the sphere the jitter moves the
    Fibonacci points, along the east and north directions by up to
    +-0.25 cell (cell side ``sqrt(4 pi / n) R``), then projected back; the
    :class:`Ellipsoid` maps the jittered unit-sphere points the same way as
    its ``"fibonacci"`` lattice.
``"scan"``
    A simulated terrestrial / structured-light scan, see :meth:`Surface.scan`:
    rays on a regular azimuth x elevation grid from a few viewpoints, first
    hits kept, grazing hits (incidence > 80 degrees) dropped.  The density
    varies (overlapping scans, scan lines, fall-off with distance and
    incidence), parts of the surface may stay unseen (holes), and the count
    is about ``n`` (exactly ``n`` unless the scan came out short, see
    :meth:`Surface.scan`).  ``border_distance`` then also bounds the distance
    to the unseen region, approximately.

Inverse parametrisation and rays
--------------------------------
Every surface also has an inverse parametrisation :meth:`Surface.parameters_of`
(``position(parameters_of(p)) == p`` up to rounding for points on the
surface), an implicit function :meth:`Surface.implicit` (zero on the surface,
positive on the side the normal points to) and a vectorised first-hit ray
caster :meth:`Surface.ray_intersect` (closed form for the sphere, ellipsoid
and cylinder, safe marching plus bisection on the implicit function for the
others).

``noise > 0`` adds isotropic Gaussian noise of standard deviation
``noise * diag`` (``diag`` = bounding-box diagonal of the clean points); the
exact quantities are always those of the clean points.

Modules
-------
=====================  ======================================================
``base``               :class:`Surface` (generic geometry, sampling API) and
                       :class:`SurfaceSample`
``curvature``          :class:`Curvature`, the exact-curvature record
``closed``             :class:`Sphere`, :class:`Ellipsoid`, :class:`Torus`
``patches``            :class:`Cylinder`, :class:`FoldedSquare` (open surfaces)
``graphs``             :class:`Graph` and :class:`Paraboloid`, :class:`Saddle`,
                       :class:`Arch`, :class:`Plane`
``samplers``           parameter layouts of the samplers, :data:`SAMPLERS`
``scan``               the simulated scanner of ``sampler="scan"``
``rays``               ray casting: closed-form roots, safe marching,
                       the implicit-function interface
``noise``              the Gaussian noise of the samples
``registry``           :data:`SURFACES` and :func:`get`
``scenes``             simulated scenes of several surfaces with known
                       answers: :func:`lidar_tile` (terrain, buildings,
                       trees), :func:`cad_part` (sharp edges), :class:`Scene`
``accuracy``           error measures of an estimate against a sample's
                       exact values (eqs 4.1, 5.1, relative L1):
                       :func:`~heatcurv.surfaces.accuracy.compare`
=====================  ======================================================

Everything public is importable from :mod:`heatcurv.surfaces` itself, except
the error measures, imported from :mod:`heatcurv.surfaces.accuracy`.
"""

from __future__ import annotations

from .base import Surface, SurfaceSample
from .closed import Ellipsoid, Sphere, Torus
from .curvature import Curvature
from .graphs import Arch, Graph, Paraboloid, Plane, Saddle
from .patches import Cylinder, FoldedSquare
from .registry import SURFACES, get
from .samplers import SAMPLERS
from .scenes import (
    BOSS_SIDE,
    BUILDING_ROOF,
    BUILDING_WALL,
    GROUND,
    HOLE_WALL,
    PLANAR_FACE,
    VEGETATION,
    Scene,
    cad_part,
    cad_part_area,
    lidar_terrain,
    lidar_tile,
)

__all__ = [
    "BOSS_SIDE",
    "BUILDING_ROOF",
    "BUILDING_WALL",
    "GROUND",
    "HOLE_WALL",
    "PLANAR_FACE",
    "VEGETATION",
    "Arch",
    "Curvature",
    "Cylinder",
    "Ellipsoid",
    "FoldedSquare",
    "Graph",
    "Paraboloid",
    "Plane",
    "SAMPLERS",
    "SURFACES",
    "Saddle",
    "Scene",
    "Sphere",
    "Surface",
    "SurfaceSample",
    "Torus",
    "cad_part",
    "cad_part_area",
    "get",
    "lidar_terrain",
    "lidar_tile",
]
