"""Simulated scenes with known answers: an aerial LiDAR tile and a CAD part with sharp edges.

The analytic surfaces of :mod:`heatcurv.surfaces` are smooth and alone; real
clouds are neither.  A :class:`Scene` puts several surfaces together as a
scanner or a CAD model produces them, sampled as that source samples them,
and keeps the exact answers where they exist:

:func:`lidar_tile`
    60 m x 60 m of aerial LiDAR in metres at UTM-like coordinates: rolling
    terrain (a hill and a valley), three buildings (flat and gable roofs,
    vertical walls seen five times more sparsely than the roofs), trees
    (volumetric scatter in ellipsoidal crowns), scan noise and the 1 cm
    quantisation of LAS files.
:func:`cad_part`
    A closed 40 x 30 x 10 mm block with a cylindrical boss on top and a
    cylindrical through-hole, uniform by area on every face.

Sign convention as everywhere in :mod:`heatcurv.surfaces`: a curvature is
positive where the surface bends away from its normal (a sphere with outward
normals has ``mean = +1/R``).  The normals are the exact ones of the clean
points, oriented to the sky side on ground and roofs, out of the building on
walls, out of the solid on the CAD part.  Curvature is exact where it is
defined and NaN where it is not: in the vegetation, and within ``margin`` of
a sharp edge (:attr:`Scene.sharp`), where every neighbourhood straddles the
edge.  Unlike :meth:`Surface.sample <heatcurv.surfaces.Surface.sample>`,
``noise`` is an absolute standard deviation in the scene's unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from heatcurv.errors import HeatcurvError

from ._util import _check_n, _finite
from .graphs import Graph

__all__ = [
    "BOSS_SIDE",
    "BUILDING_ROOF",
    "BUILDING_WALL",
    "GROUND",
    "HOLE_WALL",
    "PLANAR_FACE",
    "VEGETATION",
    "Scene",
    "cad_part",
    "cad_part_area",
    "lidar_terrain",
    "lidar_tile",
]

#: ASPRS LAS classification codes of :func:`lidar_tile`: ground 2, high
#: vegetation 5, building 6 (the roofs).  ASPRS has no class for walls;
#: they get 66, from the user-definable range 64-255 (a building is
#: ``labels == 6`` or ``labels == 66``).
GROUND, VEGETATION, BUILDING_ROOF, BUILDING_WALL = 2, 5, 6, 66
#: Face kinds of :func:`cad_part`: planes, the boss's convex cylinder, the hole's concave one.
PLANAR_FACE, BOSS_SIDE, HOLE_WALL = 1, 2, 3
#: Edge distances, as fractions of the scene's size: the fine and coarse sampling steps of the
#: edges, and the distance within which the fine samples are used.  Curved edges are polylines
#: with vertices every coarse step (their sagitta, under a tenth of the fine step, adds to the
#: half step of error).
_FINE, _COARSE, _NEAR = 2e-4, 4e-3, 0.05


@dataclass(frozen=True, eq=False)
class Scene:
    """A simulated point cloud of several surfaces, with the exact answers where they exist.

    Attributes
    ----------
    name : str
        ``"lidar_tile"`` or ``"cad_part"``.
    points : ndarray, shape (n, 3)
        What an estimator sees: ``clean_points`` plus noise (and, for the
        LiDAR tile, rounded to ``quantum``).
    clean_points : ndarray, shape (n, 3)
        Points exactly on the surfaces (in the crowns, for vegetation).
    labels : ndarray of int64, shape (n,)
        Class of every point, a key of ``classes``.
    classes : dict of int to str
        Names of the labels.
    normals : ndarray, shape (n, 3)
        Exact unit normals: to the sky side on ground and roofs (``n_z > 0``),
        horizontal and out of the building on walls, out of the solid on the
        CAD part; NaN rows in the vegetation.  Also :attr:`up_normals`.
    mean, gaussian : ndarray, shape (n,)
        Exact mean and Gaussian curvature for ``normals``; NaN in the
        vegetation and where ``sharp``.
    edge_distance : ndarray, shape (n,)
        Lower bound on the Euclidean distance from the clean point to the
        nearest sharp edge: below it by at most ``1.5e-4`` of the scene's
        size (9 mm on the tile, 6 um on the part) within 5 % of the size
        (3 m, 2 mm) of an edge, by at most ``2.5e-3`` of the size farther;
        ``inf`` in the vegetation.
    border_distance : ndarray, shape (n,)
        Horizontal distance to the tile's edge on the LiDAR ground; ``inf``
        elsewhere and on the closed CAD part.
    margin : float
        The distance that defines ``sharp``.
    sharp : ndarray of bool, shape (n,)
        ``edge_distance <= margin``.
    convex, concave : ndarray of bool, shape (n,)
        Smooth regions away from edges where the mean curvature is known to
        be positive (hill top, boss) or negative (valley floor, hole wall).
    area : float
        Exact total area of the surfaces (the CAD part); NaN for the LiDAR
        tile, whose ground is cut by footprints.
    noise : float
        Standard deviation of the Gaussian noise, in the scene's unit.
    quantum : float
        Coordinate resolution of ``points`` (0: not rounded).
    extra : dict
        Parameters of the scene worth keeping (the LiDAR tile's ``origin``).
    """

    name: str
    points: np.ndarray
    clean_points: np.ndarray
    labels: np.ndarray
    classes: dict
    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    edge_distance: np.ndarray
    border_distance: np.ndarray
    margin: float
    sharp: np.ndarray
    convex: np.ndarray
    concave: np.ndarray
    area: float
    noise: float
    quantum: float = 0.0
    extra: dict = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def n(self) -> int:
        """Number of points."""
        return len(self)

    @property
    def up_normals(self) -> np.ndarray:
        """:attr:`normals`, shape (n, 3): up on ground and roofs, outward on walls."""
        return self.normals

    def near_edge(self, margin: float) -> np.ndarray:
        """Mask of the points within ``margin`` of a sharp edge, shape (n,), bool."""
        return self.edge_distance <= float(margin)


# --------------------------------------------------------------------------- shared helpers


def _allocate(n: int, weights) -> np.ndarray:
    """``n`` split in proportion to ``weights`` by largest remainders: int64 counts summing to ``n``."""
    w = np.asarray(weights, dtype=np.float64)
    share = n * w / w.sum()
    counts = np.floor(share).astype(np.int64)
    rest = n - int(counts.sum())
    counts[np.argsort(counts - share, kind="stable")[:rest]] += 1
    return counts


def _draw(rng, count: int, propose, accept, batch: int) -> np.ndarray:
    """``count`` rows of ``propose(rng, m)`` (shape (m, d)) that pass ``accept(rows)``, by rejection."""
    kept, have = [propose(rng, 0)], 0  # (0, d): the shape when nothing is asked
    for _ in range(1000):
        if have >= count:
            break
        rows = propose(rng, max(batch, 2 * (count - have) + 16))
        rows = rows[accept(rows)]
        kept.append(rows)
        have += rows.shape[0]
    else:  # pragma: no cover - the acceptance rates here are all above 20 %
        raise HeatcurvError("rejection sampling did not converge")
    return np.concatenate(kept)[:count]


def _densify(polyline: np.ndarray, step: float) -> np.ndarray:
    """Points every ``step`` (or closer) along the segments of ``polyline`` (shape (k, 3)), ends included."""
    a, b = polyline[:-1], polyline[1:]
    m = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / step)).astype(np.int64)
    seg = np.repeat(np.arange(a.shape[0]), m)
    j = np.arange(int(m.sum())) - np.repeat(np.cumsum(m) - m, m) + 1  # 1 .. m within each segment
    t = (j / m[seg])[:, None]
    return np.concatenate([polyline[:1], a[seg] + t * (b[seg] - a[seg])])


def _edge_distance(clean: np.ndarray, edges: list, size: float) -> np.ndarray:
    """Lower bound on the distance from the points ``clean`` to the polylines ``edges``, shape (n,).

    Edge samples every ``_COARSE * size`` bound every distance to within half
    that step; the points that may lie within ``_NEAR * size`` of an edge are
    measured again against samples every ``_FINE * size`` (a search with an
    upper bound is fast, an unbounded one far from thin sets of samples is not).
    """
    fine, coarse = _FINE * size, _COARSE * size
    upper = cKDTree(np.concatenate([_densify(e, coarse) for e in edges])).query(clean)[0]
    out = np.maximum(upper - 0.5 * coarse, 0.0)
    near = np.flatnonzero(out <= _NEAR * size)
    if near.size:
        tree = cKDTree(np.concatenate([_densify(e, fine) for e in edges]))
        d = tree.query(clean[near], distance_upper_bound=float(upper[near].max()) + fine)[0]
        out[near] = np.maximum(d - 0.5 * fine, 0.0)
    return out


def _check_margin(margin) -> float:
    m = _finite("margin", margin)
    if m < 0.0:
        raise HeatcurvError(f"margin must be >= 0, got {margin}")
    return m


def _check_noise(noise) -> float:
    s = _finite("noise", noise)
    if s < 0.0:
        raise HeatcurvError(f"noise must be >= 0 (an absolute standard deviation), got {noise}")
    return s


def _scene(name, rng, parts, edges, size, noise, margin, classes, area, quantum=0.0, offset=None, extra=None):
    """Assemble a :class:`Scene` from per-part arrays: noise, quantisation, edge distances, sharp mask.

    ``parts`` is a list of dicts with ``points`` (k, 3), ``normals`` (k, 3),
    ``mean``, ``gaussian`` (k,), ``label`` (int), and optional ``border``
    (k,), ``convex``, ``concave``, ``on_surface`` (k,) bool (False: no edge
    distance, the vegetation).  ``size`` scales the edge-distance sampling,
    ``edges`` are polylines of shape (k, 3) in the parts' coordinates, and
    ``offset`` moves the finished points (after the noise, before rounding
    to ``quantum``).
    """

    def cat(key, default):
        return np.concatenate([p.get(key, np.full(p["points"].shape[0], default)) for p in parts])

    clean = np.concatenate([p["points"] for p in parts])
    normals = np.concatenate([p["normals"] for p in parts])
    labels = np.concatenate([np.full(p["points"].shape[0], p["label"], dtype=np.int64) for p in parts])
    surface = cat("on_surface", True).astype(bool)
    edge = np.full(clean.shape[0], np.inf)
    edge[surface] = _edge_distance(clean[surface], edges, size)
    sharp = edge <= margin
    mean, gaussian = cat("mean", np.nan), cat("gaussian", np.nan)
    mean[sharp] = np.nan
    gaussian[sharp] = np.nan
    points = clean + rng.normal(0.0, noise, clean.shape) if noise > 0.0 else clean.copy()
    if offset is not None:
        clean = clean + offset
        points = points + offset
    if quantum > 0.0:
        points = np.round(points / quantum) * quantum
    return Scene(
        name=name,
        points=points,
        clean_points=clean,
        labels=labels,
        classes=dict(classes),
        normals=normals,
        mean=mean,
        gaussian=gaussian,
        edge_distance=edge,
        border_distance=cat("border", np.inf),
        margin=margin,
        sharp=sharp,
        convex=cat("convex", False).astype(bool) & ~sharp,
        concave=cat("concave", False).astype(bool) & ~sharp,
        area=float(area),
        noise=noise,
        quantum=quantum,
        extra=dict(extra or {}),
    )


# --------------------------------------------------------------------------- the LiDAR tile

_HALF = 30.0  # the tile is [-30, 30]^2 m about its centre
_SLOPE = (0.03, 0.02)  # m/m, a gentle regional tilt
_HILL = (-14.0, 12.0, 3.0, 6.0)  # centre x, y, height, width (Gaussian sigma), m
_VALLEY = (14.0, -14.0, 2.0, 5.0)  # centre x, y, depth, width
#: centre x, y, half-length a, half-width b (m), rotation (degrees), eave height above the
#: highest ground under the footprint, ridge height above the eaves (0: flat roof)
_BUILDINGS = (
    (12.0, 12.0, 7.0, 5.0, 0.0, 8.0, 0.0),
    (-11.0, -14.0, 8.0, 5.0, 25.0, 6.0, 3.0),
    (22.0, -2.0, 4.0, 4.0, -15.0, 5.0, 0.0),
)
#: crown centre x, y (m), horizontal and vertical semi-axes (m), trunk height below the crown (m)
_TREES = (
    (0.0, 4.0, 3.0, 3.5, 3.0),
    (4.0, -4.0, 2.5, 3.0, 2.5),
    (-23.0, 0.0, 3.5, 4.0, 3.0),
    (-3.0, 21.0, 3.0, 3.5, 2.5),
    (23.0, 23.0, 2.5, 3.0, 2.0),
)
_WALL_DENSITY = 0.2  # points per m^2 of wall / points per m^2 of ground (seen from above)
_CANOPY_DENSITY = 1.2  # vegetation points per m^2 of crown footprint / ground density
_UNDER_CANOPY = 0.4  # the fraction of the ground under a crown that the pulses still reach


def _bump(x, y, cx, cy, height, width):
    """``height * exp(-r^2 / (2 width^2))`` about ``(cx, cy)`` and its first and second derivatives."""
    dx, dy, s2 = x - cx, y - cy, width * width
    g = height * np.exp(-(dx * dx + dy * dy) / (2.0 * s2))
    fxx = (dx * dx / s2 - 1.0) / s2 * g
    fyy = (dy * dy / s2 - 1.0) / s2 * g
    return g, -dx / s2 * g, -dy / s2 * g, fxx, dx * dy / (s2 * s2) * g, fyy


def _terrain_terms(x, y):
    """``f, fx, fy, fxx, fxy, fyy`` of the terrain height (m) over the tile's local ``(x, y)``."""
    hill = _bump(x, y, *_HILL)
    cx, cy, depth, width = _VALLEY
    valley = _bump(x, y, cx, cy, -depth, width)
    sx, sy = _SLOPE
    base = (sx * x + sy * y, sx + 0.0 * x, sy + 0.0 * x, 0.0 * x, 0.0 * x, 0.0 * x)
    return tuple(b + h + v for b, h, v in zip(base, hill, valley))


def _terrain_graph() -> Graph:
    def term(k):
        return lambda x, y: _terrain_terms(x, y)[k]

    return Graph(*(term(k) for k in range(6)), size=_HALF, name="lidar_terrain")


def lidar_terrain(x, y, origin=(500000.0, 5000000.0, 200.0)) -> np.ndarray:
    """The ground height of :func:`lidar_tile` at ``(x, y)`` in the tile's coordinates.

    Parameters
    ----------
    x, y : array_like, shape (n,)
        Easting and northing (m), as in the tile's points.
    origin : sequence of 3 floats
        The tile's ``origin`` (its centre at height 0 of the local terrain).

    Returns
    -------
    ndarray, shape (n,)
        ``z``: ``origin[2] + f(x - origin[0], y - origin[1])``, ``f`` a tilt plus a
        Gaussian hill (3 m high, sigma 6 m, at local ``(-14, 12)``) and valley
        (2 m deep, sigma 5 m, at ``(14, -14)``).
    """
    ox, oy, oz = (float(c) for c in origin)
    x = np.asarray(x, dtype=np.float64) - ox
    y = np.asarray(y, dtype=np.float64) - oy
    return oz + _terrain_terms(x, y)[0]


def _rotation(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s], [s, c]])


class _Building:
    """A box building: rectangle footprint rotated about its centre, flat or gable roof (ridge along ``u``)."""

    def __init__(self, cx, cy, a, b, angle, storey, ridge):
        self.centre = np.array([cx, cy])
        self.a, self.b, self.ridge = a, b, ridge
        self.rot = _rotation(angle)
        u, v = np.meshgrid(np.linspace(-a, a, 41), np.linspace(-b, b, 41))
        ground = _terrain_terms(*self.to_world(u.ravel(), v.ravel()).T)[0]
        self.eave = float(ground.max()) + storey
        self.base = float(ground.min())

    def to_world(self, u, v) -> np.ndarray:
        """Horizontal world coordinates of local ``(u, v)``, shape (k, 2)."""
        return self.centre + np.column_stack([u, v]) @ self.rot.T

    def to_local(self, xy: np.ndarray) -> np.ndarray:
        return (xy - self.centre) @ self.rot

    def inside(self, xy: np.ndarray, pad: float = 0.0) -> np.ndarray:
        uv = self.to_local(xy)
        return (np.abs(uv[:, 0]) <= self.a + pad) & (np.abs(uv[:, 1]) <= self.b + pad)

    def roof_height(self, v):
        return self.eave + self.ridge * (1.0 - np.abs(v) / self.b)

    def roof(self, rng, count):
        u = rng.uniform(-self.a, self.a, count)
        v = rng.uniform(-self.b, self.b, count)  # uniform in plan, as an aerial scanner sees it
        xy = self.to_world(u, v)
        nl = np.column_stack([np.zeros(count), np.sign(v) * self.ridge / self.b, np.ones(count)])
        nl /= np.linalg.norm(nl, axis=1)[:, None]
        normals = np.column_stack([nl[:, :2] @ self.rot.T, nl[:, 2]])
        zero = np.zeros(count)
        pts = np.column_stack([xy, self.roof_height(v)])
        return {"points": pts, "normals": normals, "mean": zero, "gaussian": zero.copy(), "label": BUILDING_ROOF}

    def _walls(self):
        """Per wall: start corner (u, v), direction, length, outward local normal."""
        a, b = self.a, self.b
        return [
            ((-a, -b), (1.0, 0.0), 2 * a, (0.0, -1.0)),
            ((a, -b), (0.0, 1.0), 2 * b, (1.0, 0.0)),
            ((a, b), (-1.0, 0.0), 2 * a, (0.0, 1.0)),
            ((-a, b), (0.0, -1.0), 2 * b, (-1.0, 0.0)),
        ]

    def _wall_profile(self, wall, t):
        """Local ``(u, v)``, ground and top height along ``wall`` at arc length ``t``."""
        (u0, v0), (du, dv), _, _ = wall
        u, v = u0 + t * du, v0 + t * dv
        ground = _terrain_terms(*self.to_world(u, v).T)[0]
        return u, v, ground, self.roof_height(v)

    def wall_areas(self) -> np.ndarray:
        """Areas of the four walls (m^2), trapezoidal rule on 400 intervals, shape (4,)."""
        out = []
        for wall in self._walls():
            t = np.linspace(0.0, wall[2], 401)
            _, _, ground, top = self._wall_profile(wall, t)
            height = top - ground
            out.append(float(np.sum(0.5 * (height[1:] + height[:-1]) * np.diff(t))))
        return np.array(out)

    def walls(self, rng, count):
        per_wall = _allocate(count, self.wall_areas())
        zmax = self.eave + self.ridge
        parts = []
        for wall, k in zip(self._walls(), per_wall):

            def propose(rng, m, wall=wall):
                return np.column_stack([rng.uniform(0.0, wall[2], m), rng.uniform(self.base, zmax, m)])

            def accept(rows, wall=wall):
                _, _, ground, top = self._wall_profile(wall, rows[:, 0])
                return (rows[:, 1] >= ground) & (rows[:, 1] <= top)

            tz = _draw(rng, int(k), propose, accept, 64)
            u, v, _, _ = self._wall_profile(wall, tz[:, 0])
            out = np.array(wall[3]) @ self.rot.T
            parts.append(np.column_stack([self.to_world(u, v), tz[:, 1], np.broadcast_to([*out, 0.0], (u.size, 3))]))
        table = np.concatenate(parts)
        zero = np.zeros(count)
        return {
            "points": table[:, :3],
            "normals": table[:, 3:],
            "mean": zero,
            "gaussian": zero.copy(),
            "label": BUILDING_WALL,
        }

    def edges(self, step) -> list:
        """The building's sharp edges as 3-D polylines: eaves, gables, ridge, corners, foot."""
        a, b = self.a, self.b
        out = []
        for wall in self._walls():  # the foot: the wall meets the (curved) ground
            t = np.linspace(0.0, wall[2], max(2, math.ceil(wall[2] / step) + 1))
            u, v, ground, _ = self._wall_profile(wall, t)
            out.append(np.column_stack([self.to_world(u, v), ground]))
        corners = [(-a, -b), (a, -b), (a, b), (-a, b)]
        for u, v in corners:  # vertical corners
            ground = float(_terrain_terms(*self.to_world(np.array([u]), np.array([v])).T)[0][0])
            out.append(np.array([[*self.to_world(np.array([u]), np.array([v]))[0], z] for z in (ground, self.eave)]))
        for u in (-a, a):  # the eaves (long sides), the gable ends' roof edges, the ridge
            uv = np.array([[u, -b], [u, 0.0], [u, b]])
            out.append(np.column_stack([self.to_world(uv[:, 0], uv[:, 1]), self.roof_height(uv[:, 1])]))
        for v in (-b, 0.0, b):
            if v == 0.0 and self.ridge == 0.0:
                continue
            uv = np.array([[-a, v], [a, v]])
            out.append(np.column_stack([self.to_world(uv[:, 0], uv[:, 1]), self.roof_height(uv[:, 1])]))
        return out


def lidar_tile(
    n: int = 20000,
    *,
    noise: float = 0.03,
    seed=0,
    quantum: float = 0.01,
    margin: float = 0.5,
    origin=(500000.0, 5000000.0, 200.0),
) -> Scene:
    """A synthetic aerial LiDAR tile: terrain, buildings and trees, in metres.

    60 m x 60 m centred at ``origin`` (UTM-like easting, northing, height):

    * ground (label :data:`GROUND` = 2): the graph of :func:`lidar_terrain`, a
      gentle tilt with a Gaussian hill (top: ``mean ~ +0.083 / m`` for the
      up normal, a dome bending away from it) and a Gaussian valley
      (``mean ~ -0.08 / m``); sampled uniformly in plan, none under the
      roofs, 40 % under the crowns;
    * three buildings: two flat roofs and one gable roof (pitch 31 degrees),
      footprints rotated 0, 25 and -15 degrees (:data:`BUILDING_ROOF` = 6,
      uniform in plan like the ground) and vertical walls standing on the
      terrain (:data:`BUILDING_WALL` = 66, uniform by area at a fifth of the
      ground's density per m^2, as an aerial scanner grazes them);
      curvature 0;
    * five trees (:data:`VEGETATION` = 5): volumetric scatter uniform in
      ellipsoidal crowns, no trunks, 1.2 times the ground's density per m^2
      of crown footprint; no normals or curvature.

    About 5 points per m^2 of ground at the default ``n``.  Noise is
    isotropic Gaussian, then the coordinates are rounded to ``quantum`` (LAS
    stores integers with a 0.01 m scale).  The sharp edges are the roofs'
    eaves, gable edges and ridge, the walls' corners and their foot on the
    ground.  ``convex`` is the ground within 4.8 m (0.8 sigma) of the hill
    top, ``concave`` the ground within 4 m of the valley floor.

    Parameters
    ----------
    n : int
        Number of points (exactly).
    noise : float
        Standard deviation of the noise, m.
    seed : int or numpy.random.Generator, optional
        The same seed gives the same tile.
    quantum : float
        Coordinate resolution, m; 0 keeps full precision.
    margin : float
        Distance to an edge within which a point is ``sharp``, m.
    origin : sequence of 3 floats
        Coordinates of the tile's centre at local height 0.

    Returns
    -------
    Scene
        ``area`` is NaN; ``border_distance`` is the ground's horizontal
        distance to the tile's edge.  ``extra`` holds ``origin``.
    """
    n = _check_n(n)
    noise, margin = _check_noise(noise), _check_margin(margin)
    quantum = _finite("quantum", quantum)
    if quantum < 0.0:
        raise HeatcurvError(f"quantum must be >= 0, got {quantum}")
    offset = np.asarray(origin, dtype=np.float64).reshape(-1)
    if offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise HeatcurvError(f"origin must be 3 finite numbers, got {origin!r}")
    rng = np.random.default_rng(seed)
    buildings = [_Building(*spec) for spec in _BUILDINGS]
    trees = np.array(_TREES)
    footprint = sum(4.0 * bld.a * bld.b for bld in buildings)
    crown_plan = float(np.sum(math.pi * trees[:, 2] ** 2))
    ground_plan = (2 * _HALF) ** 2 - footprint - (1.0 - _UNDER_CANOPY) * crown_plan
    weights = [ground_plan]
    weights += [4.0 * bld.a * bld.b for bld in buildings]
    weights += [_WALL_DENSITY * float(bld.wall_areas().sum()) for bld in buildings]
    weights += list(_CANOPY_DENSITY * math.pi * trees[:, 2] ** 2)
    counts = _allocate(n, weights)
    nb = len(buildings)
    parts = [_ground(rng, int(counts[0]), buildings, trees)]
    parts += [bld.roof(rng, int(k)) for bld, k in zip(buildings, counts[1 : 1 + nb])]
    parts += [bld.walls(rng, int(k)) for bld, k in zip(buildings, counts[1 + nb : 1 + 2 * nb])]
    parts += [_crown(rng, int(k), tree) for tree, k in zip(trees, counts[1 + 2 * nb :])]
    edges = [e for bld in buildings for e in bld.edges(_COARSE * 2 * _HALF)]
    classes = {GROUND: "ground", VEGETATION: "high vegetation", BUILDING_ROOF: "building roof"}
    classes[BUILDING_WALL] = "building wall"
    extra = {"origin": tuple(offset.tolist())}
    return _scene(
        "lidar_tile", rng, parts, edges, 2 * _HALF, noise, margin, classes, math.nan, quantum=quantum, offset=offset,
        extra=extra,
    )


def _ground(rng, count, buildings, trees):
    """Ground points uniform in plan outside the footprints, thinned under the crowns."""

    def propose(rng, m):
        return np.column_stack([rng.uniform(-_HALF, _HALF, (m, 2)), rng.uniform(0.0, 1.0, m)])

    def accept(rows):
        xy = rows[:, :2]
        ok = np.ones(rows.shape[0], dtype=bool)
        for bld in buildings:
            ok &= ~bld.inside(xy)
        for cx, cy, r, _, _ in trees:
            under = (xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2 <= r * r
            ok &= ~under | (rows[:, 2] < _UNDER_CANOPY)
        return ok

    xy = _draw(rng, count, propose, accept, 1024)[:, :2]
    graph = _terrain_graph()
    curv = graph.curvature(xy[:, 0], xy[:, 1])
    hx, hy, _, hw = _HILL
    vx, vy, _, vw = _VALLEY
    return {
        "points": graph.position(xy[:, 0], xy[:, 1]),
        "normals": graph.normal(xy[:, 0], xy[:, 1]),
        "mean": curv.mean,
        "gaussian": curv.gaussian,
        "label": GROUND,
        "border": _HALF - np.max(np.abs(xy), axis=1),
        "convex": np.hypot(xy[:, 0] - hx, xy[:, 1] - hy) <= 0.8 * hw,
        "concave": np.hypot(xy[:, 0] - vx, xy[:, 1] - vy) <= 0.8 * vw,
    }


def _crown(rng, count, tree):
    """Points uniform in the volume of an ellipsoidal crown above the ground."""
    cx, cy, r, h, trunk = tree
    ground = float(_terrain_terms(np.array([cx]), np.array([cy]))[0][0])
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    d *= rng.uniform(0.0, 1.0, count)[:, None] ** (1.0 / 3.0)
    pts = np.array([cx, cy, ground + trunk + h]) + d * np.array([r, r, h])
    nan = np.full(count, np.nan)
    return {
        "points": pts,
        "normals": np.full((count, 3), np.nan),
        "mean": nan,
        "gaussian": nan.copy(),
        "label": VEGETATION,
        "on_surface": np.zeros(count, dtype=bool),
    }


# --------------------------------------------------------------------------- the CAD part

_BLOCK = (20.0, 15.0, 10.0)  # half-length, half-width, height (mm): [-20, 20] x [-15, 15] x [0, 10]
_BOSS = (-8.0, 0.0, 6.0, 8.0)  # centre x, y, radius, height above the block (mm)
_HOLE = (9.0, 0.0, 4.0)  # centre x, y, radius (mm); through the block


def cad_part_area() -> float:
    """Exact surface area of :func:`cad_part`, mm^2.

    Returns
    -------
    float
        ``2 * 40 * 30 - pi r_b^2 - 2 pi r_h^2 + 2 (40 + 30) 10`` (block without
        the discs) ``+ pi r_b^2 + 2 pi r_b h_b`` (boss) ``+ 2 pi r_h 10`` (hole).
    """
    a, b, h = _BLOCK
    _, _, rb, hb = _BOSS
    _, _, rh = _HOLE
    planes = 2 * (4 * a * b) - 2 * math.pi * rh * rh + 2 * (2 * a + 2 * b) * h
    return planes + 2 * math.pi * rb * hb + 2 * math.pi * rh * h


def cad_part(n: int = 20000, *, noise: float = 0.0, seed=0, margin: float = 0.5) -> Scene:
    """A machined part: a block with a cylindrical boss and a through-hole, closed, in millimetres.

    The block is ``[-20, 20] x [-15, 15] x [0, 10]``; the boss, radius 6 and
    8 high, stands on the top face at ``(-8, 0)``; the hole, radius 4, goes
    through the block at ``(9, 0)``.  Points are uniform by area on every
    face, with exact outward normals (out of the solid: into the hole's air
    on its wall).  Labels: :data:`PLANAR_FACE` (1: the block's faces and the
    boss's top, curvature 0), :data:`BOSS_SIDE` (2: ``mean = +1/12``,
    convex), :data:`HOLE_WALL` (3: ``mean = -1/8``, concave); Gaussian
    curvature 0 everywhere.  The sharp edges are the block's twelve edges
    and the four circles where the boss and the hole meet the planes.

    Parameters
    ----------
    n : int
        Number of points (exactly).
    noise : float
        Standard deviation of isotropic Gaussian noise, mm.
    seed : int or numpy.random.Generator, optional
    margin : float
        Distance to an edge within which a point is ``sharp``, mm.

    Returns
    -------
    Scene
        ``area`` is :func:`cad_part_area`; ``convex`` is the boss's side and
        ``concave`` the hole's wall, away from the edges.
    """
    n = _check_n(n)
    noise, margin = _check_noise(noise), _check_margin(margin)
    rng = np.random.default_rng(seed)
    a, b, h = _BLOCK
    bx, by, rb, hb = _BOSS
    hx, hy, rh = _HOLE
    faces = [  # (area, sampler(rng, k) -> points, normals, label)
        (4 * a * b - math.pi * rh * rh, lambda r, k: _plane_with_holes(r, k, 0.0, -1.0, [(hx, hy, rh)])),
        (
            4 * a * b - math.pi * (rb * rb + rh * rh),
            lambda r, k: _plane_with_holes(r, k, h, 1.0, [(hx, hy, rh), (bx, by, rb)]),
        ),
        (2 * b * h, lambda r, k: _box_side(r, k, 0, a)),
        (2 * b * h, lambda r, k: _box_side(r, k, 0, -a)),
        (2 * a * h, lambda r, k: _box_side(r, k, 1, b)),
        (2 * a * h, lambda r, k: _box_side(r, k, 1, -b)),
        (math.pi * rb * rb, lambda r, k: _disc(r, k, bx, by, rb, h + hb)),
        (2 * math.pi * rb * hb, lambda r, k: _cylinder(r, k, bx, by, rb, h, h + hb, 1.0)),
        (2 * math.pi * rh * h, lambda r, k: _cylinder(r, k, hx, hy, rh, 0.0, h, -1.0)),
    ]
    counts = _allocate(n, [area for area, _ in faces])
    parts = []
    for (_, sampler), k in zip(faces, counts):
        pts, nrm, label = sampler(rng, int(k))
        mean = {PLANAR_FACE: 0.0, BOSS_SIDE: 0.5 / rb, HOLE_WALL: -0.5 / rh}[label]
        parts.append(
            {
                "points": pts,
                "normals": nrm,
                "label": label,
                "mean": np.full(int(k), mean),
                "gaussian": np.zeros(int(k)),
                "convex": np.full(int(k), label == BOSS_SIDE),
                "concave": np.full(int(k), label == HOLE_WALL),
            }
        )
    step = _COARSE * 2 * a
    edges = []
    for z in (0.0, h):
        edges.append(np.array([[-a, -b, z], [a, -b, z], [a, b, z], [-a, b, z], [-a, -b, z]]))
    for x, y in ((-a, -b), (a, -b), (a, b), (-a, b)):
        edges.append(np.array([[x, y, 0.0], [x, y, h]]))
    for cx, cy, r, z in ((hx, hy, rh, 0.0), (hx, hy, rh, h), (bx, by, rb, h), (bx, by, rb, h + hb)):
        t = np.linspace(0.0, 2 * math.pi, math.ceil(4 * math.pi * r / step) + 1)  # vertices every step / 2
        edges.append(np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t), np.full(t.size, z)]))
    classes = {PLANAR_FACE: "planar face", BOSS_SIDE: "boss side", HOLE_WALL: "hole wall"}
    return _scene("cad_part", rng, parts, edges, 2 * a, noise, margin, classes, cad_part_area())


def _plane_with_holes(rng, count, z, up, discs):
    """Uniform points of the block's bottom (``up = -1``) or top (``+1``) face outside ``discs``."""
    a, b, _ = _BLOCK

    def propose(rng, m):
        return np.column_stack([rng.uniform(-a, a, m), rng.uniform(-b, b, m)])

    def accept(xy):
        ok = np.ones(xy.shape[0], dtype=bool)
        for cx, cy, r in discs:
            ok &= (xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2 > r * r
        return ok

    xy = _draw(rng, count, propose, accept, 256)
    normals = np.zeros((count, 3))
    normals[:, 2] = up
    return np.column_stack([xy, np.full(count, z)]), normals, PLANAR_FACE


def _box_side(rng, count, axis, at):
    """Uniform points of the block's side face ``x = at`` (``axis = 0``) or ``y = at`` (``axis = 1``)."""
    a, b, h = _BLOCK
    span = b if axis == 0 else a
    pts = np.empty((count, 3))
    pts[:, axis] = at
    pts[:, 1 - axis] = rng.uniform(-span, span, count)
    pts[:, 2] = rng.uniform(0.0, h, count)
    normals = np.zeros((count, 3))
    normals[:, axis] = math.copysign(1.0, at)
    return pts, normals, PLANAR_FACE


def _disc(rng, count, cx, cy, r, z):
    """Uniform points of the horizontal disc of radius ``r`` at height ``z``, normal up."""
    rho = r * np.sqrt(rng.uniform(0.0, 1.0, count))
    t = rng.uniform(0.0, 2 * math.pi, count)
    pts = np.column_stack([cx + rho * np.cos(t), cy + rho * np.sin(t), np.full(count, z)])
    return pts, np.tile([0.0, 0.0, 1.0], (count, 1)), PLANAR_FACE


def _cylinder(rng, count, cx, cy, r, z0, z1, out):
    """Uniform points of a vertical cylinder's side; normals away from (``out = 1``) or to the axis."""
    t = rng.uniform(0.0, 2 * math.pi, count)
    radial = np.column_stack([np.cos(t), np.sin(t), np.zeros(count)])
    pts = np.column_stack([cx + r * radial[:, 0], cy + r * radial[:, 1], rng.uniform(z0, z1, count)])
    return pts, out * radial, BOSS_SIDE if out > 0 else HOLE_WALL
