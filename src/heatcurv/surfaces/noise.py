"""Gaussian noise of the samples.

``noise > 0`` adds isotropic Gaussian noise of standard deviation
``noise * diag`` (``diag`` = bounding-box diagonal of the clean points); the
exact quantities are always those of the clean points.
"""

from __future__ import annotations

import numpy as np

from heatcurv.errors import HeatcurvError

from ._util import _finite


def _check_noise(noise) -> float:
    """Validate a relative noise level (finite, >= 0)."""
    noise = _finite("noise", noise)
    if noise < 0.0:
        raise HeatcurvError(f"noise must be >= 0, got {noise}")
    return noise


def _add_noise(clean: np.ndarray, noise: float, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """Noisy copy of the clean points and the absolute standard deviation applied.

    Parameters
    ----------
    clean : ndarray, shape (n, 3)
        Points on the surface.
    noise : float
        Relative level, already checked by :func:`_check_noise`.
    rng : numpy.random.Generator
        Draws the ``(n, 3)`` normal deviates (nothing is drawn for ``noise == 0``).

    Returns
    -------
    points : ndarray, shape (n, 3)
        ``clean`` plus noise of standard deviation ``sigma`` (a copy when ``noise == 0``).
    sigma : float
        ``noise * diag``, ``diag`` the bounding-box diagonal of ``clean``.
    """
    sigma = 0.0
    if noise > 0.0:
        diag = float(np.linalg.norm(clean.max(axis=0) - clean.min(axis=0)))
        sigma = noise * diag
        points = clean + rng.normal(0.0, sigma, clean.shape)
    else:
        points = clean.copy()
    return points, sigma
