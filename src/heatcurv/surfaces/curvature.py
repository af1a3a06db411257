"""The exact curvature record of a surface and the closed forms that build it.

See the sign convention in :mod:`heatcurv.surfaces`: a curvature is positive
where the surface bends away from its normal, ``k1 >= k2``, ``d1 x d2 = n``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_UMBILIC_RTOL = 1e-9


@dataclass(frozen=True, eq=False)
class Curvature:
    """Exact curvature quantities at ``n`` surface points.

    Attributes
    ----------
    mean : ndarray, shape (n,)
        Mean curvature ``(k1 + k2) / 2``.
    gaussian : ndarray, shape (n,)
        Gaussian curvature ``k1 * k2``.
    k1, k2 : ndarray, shape (n,)
        Principal curvatures, ``k1 >= k2``; positive where the surface bends
        away from its normal.
    d1, d2 : ndarray, shape (n, 3)
        Unit principal directions for ``k1`` and ``k2``, tangent to the
        surface, with ``d1 x d2 = n``.  Arbitrary (but still such a frame)
        where ``umbilic`` is True.
    umbilic : ndarray of bool, shape (n,)
        ``|k1 - k2| <= 1e-9 * max(1, |k1|, |k2|)``.
    """

    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    umbilic: np.ndarray


def _umbilic_mask(k1: np.ndarray, k2: np.ndarray) -> np.ndarray:
    scale = np.maximum(1.0, np.maximum(np.abs(k1), np.abs(k2)))
    return np.abs(k1 - k2) <= _UMBILIC_RTOL * scale


def _principal_curvature(k1, k2, d1, d2, mean=None, umbilic=None) -> Curvature:
    """A :class:`Curvature` from principal curvatures and directions.

    ``mean`` defaults to ``(k1 + k2) / 2`` and ``umbilic`` to the tolerance
    test documented in :class:`Curvature`; ``gaussian`` is ``k1 * k2``.
    """
    return Curvature(
        mean=0.5 * (k1 + k2) if mean is None else mean,
        gaussian=k1 * k2,
        k1=k1,
        k2=k2,
        d1=d1,
        d2=d2,
        umbilic=_umbilic_mask(k1, k2) if umbilic is None else umbilic,
    )


def _curvature_in_frame(e1, e2, b11, b12, b22) -> Curvature:
    """Diagonalise the symmetric shape operator ``[[b11, b12], [b12, b22]]``.

    ``e1``, ``e2`` (shape (n, 3)) are an orthonormal tangent frame with
    ``e1 x e2 = n`` in which the shape operator has the given entries.
    """
    # "+ 0.0" turns the -0.0 of -II on flat surfaces into +0.0.
    b11, b12, b22 = b11 + 0.0, b12 + 0.0, b22 + 0.0
    half_diff = 0.5 * (b11 - b22)
    mean = 0.5 * (b11 + b22)
    radius = np.hypot(half_diff, b12)
    k1 = mean + radius
    k2 = mean - radius
    # The quadratic form is mean + radius * cos(2 theta - psi) with
    # psi = atan2(b12, half_diff); its maximum (k1) is at theta = psi / 2.
    theta = 0.5 * np.arctan2(b12, half_diff)
    c = np.cos(theta)[:, None]
    s = np.sin(theta)[:, None]
    d1 = c * e1 + s * e2
    d2 = c * e2 - s * e1  # = n x d1
    return _principal_curvature(k1, k2, d1, d2, mean=mean)
