"""How the points of a picture are lit, and which of them are hidden behind the near side.

:func:`heatcurv.render.render_field` colours each point by its field value;
these functions then decide how bright each point is drawn and whether it is
drawn at all:

* :func:`shade_colours` lights the colours by a headlight slightly above and
  left of the camera (:data:`LIGHT`): :data:`AMBIENT` light plus Lambert's
  diffuse light, two-sided, so normals of either sign light alike;
* :func:`estimated_normals` gives the normals to light by when none are
  given: the direction of least spread of each point's nearest neighbours;
* :func:`hidden_back_faces` picks, in one view, the points facing away from
  the camera that lie behind a surface facing it (the far side of a closed
  object); they are not drawn, so they cannot show through the gaps between
  the near side's discs.

They take and return arrays (numpy and scipy only) and draw nothing.
"""

from __future__ import annotations

import numpy as np

__all__ = ["AMBIENT", "HIDDEN_DEPTH", "LIGHT", "estimated_normals", "hidden_back_faces", "shade_colours"]

#: Share of a point's colour kept where the light grazes its surface or misses it (ambient light);
#: the rest is diffuse (Lambert) light.
AMBIENT = 0.4
#: Direction the light comes from, in screen coordinates (right, up, towards the camera): a
#: headlight slightly above and left of the camera, so surfaces facing the viewer are bright,
#: the outline darkens and bumps read as lit from the upper left.
LIGHT = np.array([-0.3, 0.4, 1.0]) / np.linalg.norm([-0.3, 0.4, 1.0])
#: A point facing away from the camera is hidden when a point facing it, next to it on the
#: picture, is nearer to the camera by more than this many disc diameters
#: (:func:`hidden_back_faces`).
HIDDEN_DEPTH = 2.0


def estimated_normals(xyz: np.ndarray, k: int = 10) -> np.ndarray | None:
    """Unoriented normals for shading: the direction of least spread of each point's nearest neighbours.

    Parameters
    ----------
    xyz : ndarray, shape (n, 3)
        Finite coordinates.
    k : int, optional
        Neighbours per point, the point itself included (at most ``n``).

    Returns
    -------
    ndarray, shape (n, 3), or None
        Unit normals, of arbitrary sign (which two-sided lighting,
        :func:`shade_colours`, does not see); None with fewer than 4 points.
    """
    from scipy.spatial import cKDTree

    if xyz.shape[0] < 4:
        return None
    k = min(k, xyz.shape[0])
    tree = cKDTree(xyz)
    normals = np.empty_like(xyz)
    for start in range(0, xyz.shape[0], 100_000):  # blocks: a few tens of MB at a time
        _, neighbours = tree.query(xyz[start : start + 100_000], k=k, workers=-1)
        around = xyz[neighbours]
        around -= around.mean(axis=1, keepdims=True)
        _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", around, around))
        normals[start : start + 100_000] = vectors[:, :, 0]
    return normals


def shade_colours(rgba: np.ndarray, normals_on_screen: np.ndarray) -> np.ndarray:
    """Colours lit by :data:`LIGHT`: each colour times ``AMBIENT + (1 - AMBIENT) max(0, n . light)``.

    Parameters
    ----------
    rgba : ndarray, shape (n, 4)
        Colours, red, green, blue and alpha in [0, 1].
    normals_on_screen : ndarray, shape (n, 3)
        Unit normals in screen coordinates (right, up, towards the camera).

    Returns
    -------
    ndarray, shape (n, 4)
        The lit colours (a new array); alpha is kept.

    Notes
    -----
    Lighting is two-sided: a normal facing away is turned to face the camera
    first, so open scans seen from behind and normals of either sign are lit
    alike. Points without a finite normal get the brightness of a surface
    facing the camera.

    Examples
    --------
    A point whose surface the light grazes keeps the :data:`AMBIENT` share of
    its colour:

    >>> import numpy as np
    >>> from heatcurv.shading import shade_colours
    >>> shade_colours(np.array([[1.0, 0.5, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    array([[0.4, 0.2, 0. , 1. ]])
    """
    n = normals_on_screen
    toward = np.where(n[:, 2:3] < 0, -n, n)
    diffuse = np.clip(toward @ LIGHT, 0.0, 1.0)
    diffuse = np.where(np.isfinite(diffuse), diffuse, LIGHT[2])
    shaded = np.array(rgba, dtype=np.float64, copy=True)
    shaded[:, :3] *= (AMBIENT + (1.0 - AMBIENT) * diffuse)[:, None]
    return shaded


def hidden_back_faces(screen: np.ndarray, facing: np.ndarray, diameter: float) -> np.ndarray:
    """Mask of the points that face away from the camera and lie behind a surface that faces it.

    Parameters
    ----------
    screen : ndarray, shape (n, 3)
        Right, up and depth towards the camera of each point.
    facing : ndarray, shape (n,)
        Normal component towards the camera (NaN: unknown, never hidden).
    diameter : float
        Disc diameter in length units.

    Returns
    -------
    ndarray of bool, shape (n,)

    Notes
    -----
    The picture is cut into square cells one disc diameter wide. A point
    facing away is hidden when a point facing the camera lies in its cell or
    one of the 8 around it (1 to 2 diameters away on the picture) and is
    nearer by more than :data:`HIDDEN_DEPTH` diameters: it is on the far side
    of a closed surface, and drawn it would show through the gaps between the
    near side's discs. Points facing away with nothing in front of them (the
    back of an open scan, the outline of a closed one) stay. Normals may be
    oriented either way: both signs are tried and the one that hides more is
    kept (inward normals hide nothing with the outward sign).
    """
    from scipy.ndimage import maximum_filter

    hidden = np.zeros(screen.shape[0], dtype=bool)
    known = np.isfinite(facing)
    if not known.any():
        return hidden
    cell = max(diameter, float(np.ptp(screen[:, :2], axis=0).max()) / 2048.0, 1e-300)  # at most 2048^2 cells
    cells = np.floor((screen[:, :2] - screen[:, :2].min(axis=0)) / cell).astype(np.int64)
    shape = tuple(cells.max(axis=0) + 1)
    margin = HIDDEN_DEPTH * diameter
    for sign in (1.0, -1.0):
        front = known & (sign * facing > 0)
        back = known & (sign * facing < 0)
        if not front.any() or not back.any():
            continue
        nearest = np.full(shape, -np.inf)  # per cell, the depth of the nearest point facing the camera
        np.maximum.at(nearest, (cells[front, 0], cells[front, 1]), screen[front, 2])
        nearest = maximum_filter(nearest, size=3, mode="constant", cval=-np.inf)  # and the 8 cells around
        behind = back.copy()
        behind[back] = nearest[cells[back, 0], cells[back, 1]] > screen[back, 2] + margin
        if behind.sum() > hidden.sum():
            hidden = behind
    return hidden
