"""Clouds of several objects apart: terrain beside a closed object, terrain beside an open one."""

import numpy as np

from heatcurv import surfaces

__all__ = ["valley_and_boulder", "valley_and_dish"]


def valley_and_boulder(seed: int = 0):
    """A valley ``z = 0.1 (x^2 + y^2)`` over ``[-2, 2]^2`` (20 000 random points) and a sphere of radius 0.3
    (4000 points) 1.5 over its bottom: terrain and a closed object apart from it.

    Returns
    -------
    ground : ndarray, shape (20000, 3)
    boulder : ndarray, shape (4000, 3)
    outward : ndarray, shape (4000, 3)
        The sphere's outward normals.
    """
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-2.0, 2.0, (20000, 2))
    ground = np.column_stack([xy, 0.1 * (xy**2).sum(axis=1)])
    sphere = surfaces.Sphere(radius=0.3).sample(4000, "random", seed=seed)
    return ground, sphere.points + [0.0, 0.0, 1.5], sphere.normals


def valley_and_dish(seed: int = 0):
    """The valley of :func:`valley_and_boulder` and, 4 beyond its rim, a dish ``x = 6 + 0.4 (y^2 + (z - 1)^2)``
    standing on its side, open towards ``+x`` (8000 points): an open cloud over no plane (the dish faces down
    as much as up).

    Returns
    -------
    ground : ndarray, shape (20000, 3)
    dish : ndarray, shape (8000, 3)
    """
    ground = valley_and_boulder(seed)[0]
    yz = np.random.default_rng(seed + 1).uniform(-1.0, 1.0, (8000, 2))
    return ground, np.column_stack([6.0 + 0.4 * (yz**2).sum(axis=1), yz[:, 0], yz[:, 1] + 1.0])
