"""Points whose ball holds the other side of a thin part: two sheets, not one.

A point's curvature and area come from its ball, read as one sheet of surface
with the point on it. Where a part is only a few spacings thick (a leg, an ear,
a wing, a thin plate) the ball also holds the part's other side: the fit mixes
two surfaces and the density counts both sides' points, so neither the
curvature nor the area is the sheet's. :func:`second_sheet` finds those points
from the oriented normals; they get no area and are not ``reliable``.

A neighbour ``q`` among the nearest of a point ``p`` (normals ``n_p``, ``n_q``)
lies on the other side when it is

* straight over or under ``p``: its height ``h = (q - p) . n_p`` is larger
  than its distance from ``p``'s normal line, and larger than half ``p``'s
  spacing (a neighbour on the same sheet lies in or near the tangent plane:
  more than 45 degrees out of it takes a quarter turn of the surface between
  them, which a resolved surface does not make within a few spacings), and
* facing the other way: ``n_p . n_q < -`` ``TUNING.sheet_aligned`` (the two sides
  of a thin part face away from each other, and both turn together when the
  part is inside out, so the test holds whichever side they were given).

A tile of a run oriented ``outward`` does not know its normals' final signs,
so it keeps the pairs whose facing decides the test (:func:`facing_pairs`)
for the driver (:mod:`heatcurv.tiles.sheets`).

Noise scatters one sheet's points over and under each other, but leaves their
normals alike, so it does not trip the test; nor does a sheet right over a
point facing the same way (a part whose one side alone is inside out), which
under noise the height alone cannot tell from the scatter.

A part thinner still (under about two spacings) gives its two sides one normal:
the ball reads as one sheet with noise as wide as the part, and both sides come
out facing the same way. What tells the two apart is the *shape* of the
scatter. Over a least-squares quadric through the ball, noise leaves residuals
that are about normal (kurtosis ``mean(r^4) / mean(r^2)^2`` near 3), two layers
residuals split in two groups (kurtosis near 1 for two equal layers, at most
``TUNING.layer_kurtosis``), whichever way they face. A point is **layered** when its ball's residual is
wider than ``TUNING.layer_residual`` of its spacing with such a kurtosis
(:func:`layered_balls`); a single ball's kurtosis scatters, so a point counts as
a second sheet when more than ``TUNING.layer_vote`` of its
``TUNING.sheet_neighbours`` nearest are layered (:func:`second_sheet`).
"""

from __future__ import annotations

import numpy as np

from .._kernels import segment as kernels
from ..geometry.neighbourhood import Neighbourhood
from ..tuning import TUNING

__all__ = [
    "layered_balls", "second_sheet", "layered_sheet", "facing_pairs",
]



def second_sheet(points: np.ndarray, normals: np.ndarray, nbhd: Neighbourhood, spacing: np.ndarray) -> np.ndarray:
    """Points whose ball holds two sheets (module docstring), shape (n,), bool.

    A neighbour on the other side of the point's part facing the other way,
    or most of its nearest neighbours' balls layered (:func:`layered_balls`).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    normals : ndarray, shape (n, 3)
        Oriented unit normals (NaN rows: never flagged, never counted).
    nbhd : Neighbourhood
        The operator's neighbourhood; its ``TUNING.sheet_neighbours`` nearest of each row are used.
    spacing : ndarray, shape (n,)
        Each point's sampling spacing ``h`` (eq 2.6 / 2.7).

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    reach = nbhd.kth_distance(TUNING.sheet_neighbours)
    found = kernels.opposite_sheet_counts(points, normals, nbhd.indptr, nbhd.indices, nbhd.distances, reach,
                                          TUNING.sheet_height * spacing, TUNING.sheet_aligned)
    return (found > 0) | layered_sheet(points, normals, nbhd, spacing)


def layered_sheet(points: np.ndarray, normals: np.ndarray, nbhd: Neighbourhood, spacing: np.ndarray) -> np.ndarray:
    """Points more than ``TUNING.layer_vote`` of whose ``TUNING.sheet_neighbours`` nearest have layered balls,
    shape (n,), bool: the part of :func:`second_sheet` that no normal's sign changes.

    Parameters are those of :func:`second_sheet`.
    """
    reach = nbhd.kth_distance(TUNING.sheet_neighbours)
    layered = layered_balls(points, normals, nbhd, np.asarray(spacing, dtype=np.float64))
    counts = kernels.flagged_within(layered, nbhd.indptr, nbhd.indices, nbhd.distances, reach)
    return counts[:, 1] > TUNING.layer_vote * counts[:, 0]


def facing_pairs(points: np.ndarray, normals: np.ndarray, nbhd: Neighbourhood,
                 spacing: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The neighbours :func:`second_sheet` reads whose facing decides it: over or under the point, with normals
    within ``TUNING.sheet_aligned`` of parallel or of opposite (``|n_p . n_q| >`` it).

    Where the normals' signs are settled only later (a tile of a run oriented outward, whose pieces the
    driver turns), the point is a second sheet when one of its pairs ends up facing away
    (``n_p . n_q < -TUNING.sheet_aligned`` with the final signs).

    Returns
    -------
    rows, columns : ndarray, shape (k,), int64
        The pairs ``(p, q)``.
    dots : ndarray, shape (k,)
        ``n_p . n_q`` with the given normals.
    """
    reach = nbhd.kth_distance(TUNING.sheet_neighbours)
    return kernels.over_under_pairs(points, normals, nbhd.indptr, nbhd.indices, nbhd.distances, reach,
                                    TUNING.sheet_height * np.asarray(spacing, dtype=np.float64), TUNING.sheet_aligned)


def layered_balls(points: np.ndarray, normals: np.ndarray, nbhd: Neighbourhood, spacing: np.ndarray) -> np.ndarray:
    """Balls whose quadric residuals split in two layers (module docstring), shape (n,), bool.

    Parameters
    ----------
    points, normals, nbhd, spacing
        As :func:`second_sheet`; every neighbour of a row is in its ball.

    Returns
    -------
    ndarray of bool, shape (n,)
        ``rms > TUNING.layer_residual * h`` and ``kurtosis < TUNING.layer_kurtosis`` (False where either is NaN).
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    moments = kernels.quadric_residual_moments(points, normals, nbhd.indptr, nbhd.indices, spacing)
    return (moments[:, 0] > TUNING.layer_residual * spacing) & (moments[:, 1] < TUNING.layer_kurtosis)
