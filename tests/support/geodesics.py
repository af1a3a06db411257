"""Exact geodesic distances on a torus, for the tests of the heat method.

The cloud's points, with a fine grid in the torus's ``(u, v)`` parameters
around them, are triangulated in the parameter plane (periodic: the plane
tiled three by three, each triangle kept once, by its centroid) and the
polyhedral geodesic distance from the source is computed exactly (the
Mitchell-Mount-Papadimitriou algorithm of ``pygeodesic``). A fine grid of
300 x 120 makes the polyhedral distance within 3e-5 of the smooth one (the
farthest point: 8.57423 on the grid against 8.57445 on a 600 x 240 grid).

``python tests/support/geodesics.py`` writes ``tests/data/torus_geodesic.npz``,
which the tests read (pygeodesic is not a test dependency).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import Delaunay

#: The fixture: cloud size, seed, the source's index and the fine grid.
N_POINTS, SEED, SOURCE, GRID = 10000, 0, 0, (300, 120)
FIXTURE = Path(__file__).resolve().parents[1] / "data" / "torus_geodesic.npz"


def torus_cloud():
    """The fixture's cloud: random points of the default torus, shape (n, 3), with their ``u, v``."""
    from heatcurv import surfaces

    return surfaces.Torus().sample(N_POINTS, "random", seed=SEED)


def exact_distances(sample, source: int, grid=GRID) -> np.ndarray:
    """Polyhedral geodesic distance from ``sample.points[source]`` to every point of ``sample``, shape (n,)."""
    import pygeodesic.geodesic as geodesic

    torus = sample.surface
    two_pi = 2.0 * np.pi
    gu, gv = np.meshgrid(np.arange(grid[0]) * two_pi / grid[0], np.arange(grid[1]) * two_pi / grid[1], indexing="ij")
    u = np.concatenate([np.mod(sample.u, two_pi), gu.ravel()])
    v = np.concatenate([np.mod(sample.v, two_pi), gv.ravel()])
    m = u.size
    scale = np.array([torus.r2, torus.r1])  # about isotropic triangles
    shifts = [(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1)]
    plane = np.concatenate([np.column_stack([u + a * two_pi, v + b * two_pi]) for a, b in shifts]) * scale
    triangles = Delaunay(plane).simplices
    centroid = plane[triangles].mean(axis=1) / scale
    inside = np.all((centroid >= 0.0) & (centroid < two_pi), axis=1)
    faces = (triangles[inside] % m).astype(np.int32)
    vertices = torus.position(u, v)
    solver = geodesic.PyGeodesicAlgorithmExact(vertices, faces)
    distance, _ = solver.geodesicDistances(np.array([source]), None)
    return np.asarray(distance[: sample.u.size], dtype=np.float64)


def write_fixture() -> None:
    sample = torus_cloud()
    distance = exact_distances(sample, SOURCE)
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(FIXTURE, distance=distance, points=sample.points.astype(np.float32))


if __name__ == "__main__":
    write_fixture()
