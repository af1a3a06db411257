"""Closed clouds the analytic surfaces do not give: exact planes meeting at edges, and a symmetric vertex set."""

import numpy as np

__all__ = ["cube_faces", "uv_sphere"]


def cube_faces(n: int, seed: int = 4):
    """``n`` random points on the faces of the cube ``[-1, 1]^3``, each face's coordinate exactly +-1.

    Returns
    -------
    points, normals : ndarray, shape (n, 3)
        The points and the faces' outward normals.
    """
    rng = np.random.default_rng(seed)
    face, uv = rng.integers(0, 6, n), rng.uniform(-1.0, 1.0, (n, 2))
    axis, side = face // 2, np.where(face % 2 == 0, 1.0, -1.0)
    points, normals = np.zeros((n, 3)), np.zeros((n, 3))
    for a in range(3):
        on, (b, c) = axis == a, [d for d in range(3) if d != a]
        points[on, a], points[on, b], points[on, c] = side[on], uv[on, 0], uv[on, 1]
        normals[on, a] = side[on]
    return points, normals


def uv_sphere(rings: int, per_ring: int) -> np.ndarray:
    """The vertices of a unit UV sphere: ``rings`` circles of latitude of ``per_ring`` vertices each, then the poles.

    Returns
    -------
    ndarray, shape (rings * per_ring + 2, 3)
        The vertices (their own outward normals).
    """
    polar = np.linspace(0.0, np.pi, rings + 2)[1:-1]
    turn = np.linspace(0.0, 2.0 * np.pi, per_ring, endpoint=False)
    ring = np.stack(np.broadcast_arrays(np.sin(polar)[:, None] * np.cos(turn), np.sin(polar)[:, None] * np.sin(turn),
                                        np.cos(polar)[:, None]), axis=-1).reshape(-1, 3)
    return np.vstack([ring, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
