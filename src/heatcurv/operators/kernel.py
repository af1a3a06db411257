"""Heat-kernel weights on the neighbour pairs (paper eqs 2.2, 2.4, 2.8, 2.9).

With diffusion time ``t = m h^2`` (eq 2.8) the Gaussian heat kernel of eq 2.2 is

    H^t(x, y) = (4 pi t)^-1 exp(-|x - y|^2 / (4 t)),

and at the paper's ``m = 1/4`` this is ``exp(-|x - y|^2 / h^2) / (pi h^2)``.
We store the unnormalised factor ``W_ij = exp(-|xi - xj|^2 / (4 m h_i^2))`` per
pair; the normalisations ``1/(4 pi t)`` (area system) and ``1/(4 pi t^2)``
(Laplace-Beltrami, eq 2.4 / 2.9) are returned by the helpers below so every
stage uses the same constants.
"""

from __future__ import annotations

import numpy as np

from .._kernels import segment as kernels
from ..errors import HeatcurvError
from ..geometry.neighbourhood import Neighbourhood

__all__ = [
    "heat_kernel_weights",
    "diffusion_time",
    "area_normalisation",
    "laplacian_normalisation",
    "flat_top",
    "ball_taper",
    "tapered_heat_weights",
    "effective_neighbours",
    "TAPER_START",
]


def diffusion_time(h: np.ndarray, m: float) -> np.ndarray:
    """Heat-diffusion time ``t = m h^2`` (eq 2.8), shape like ``h``."""
    if not m > 0:
        raise HeatcurvError(f"m must be positive (t = m h^2), got {m}")
    return m * np.asarray(h, dtype=np.float64) ** 2


def area_normalisation(h: np.ndarray, m: float) -> np.ndarray:
    """``1 / (4 pi t)``, the factor of the heat kernel in ``H A = 1`` (section 2.2)."""
    return 1.0 / (4.0 * np.pi * diffusion_time(h, m))


def laplacian_normalisation(h: np.ndarray, m: float) -> np.ndarray:
    """``1 / (4 pi t^2)``, the factor of eq 2.4; ``4 / (pi h^4)`` at ``m = 1/4`` (eq 2.9)."""
    t = diffusion_time(h, m)
    return 1.0 / (4.0 * np.pi * t * t)


def heat_kernel_weights(nbhd: Neighbourhood, h: np.ndarray, m: float = 0.25) -> np.ndarray:
    """Gaussian weights ``W_ij = exp(-|xi - xj|^2 / (4 m h_i^2))`` of every pair.

    Parameters
    ----------
    nbhd : Neighbourhood
        Neighbour pairs with their distances.
    h : ndarray, shape (n,)
        Spacing of each centre point ``i`` (eq 2.6 or 2.7).
    m : float, optional
        Diffusion-time constant, ``t = m h^2``; the paper's choice is 1/4.

    Returns
    -------
    ndarray, shape (nnz,)
        ``W_ij`` in the order of ``nbhd.indices``; the diagonal ``W_ii = 1`` is
        implicit.
    """
    t = diffusion_time(h, m)
    t_pair = np.repeat(t, nbhd.counts)
    return np.exp(-(nbhd.distances**2) / (4.0 * t_pair))


#: Where the flat-top profile starts to fall, as a fraction of the ball radius.
TAPER_START = 0.7


def flat_top(u: np.ndarray, start: float = TAPER_START) -> np.ndarray:
    """Flat-top profile: 1 up to ``start``, a raised cosine down to 0 at ``u = 1``.

    Parameters
    ----------
    u : ndarray
        Distance in units of the ball radius.
    start : float, optional
        Where the fall begins.

    Returns
    -------
    ndarray
        Same shape as ``u``; 0 for ``u >= 1``.
    """
    out = np.where(u <= start, 1.0, 0.5 * (1.0 + np.cos(np.pi * (u - start) / (1.0 - start))))
    return np.where(u >= 1.0, 0.0, out)


def ball_taper(nbhd: Neighbourhood) -> np.ndarray:
    """``flat_top(|xi - xj| / r_i)`` for every pair, shape ``(nnz,)``.

    Multiplying a kernel by it makes every sum over the ball continuous in the
    points: a neighbour entering or leaving the ball at its radius has weight
    0, so rounding (a rigid motion, a change of units) cannot change a result
    by a jump.
    """
    return flat_top(nbhd.distances / np.repeat(nbhd.radius, nbhd.counts))


def tapered_heat_weights(nbhd: Neighbourhood, h: np.ndarray, areas: np.ndarray) -> np.ndarray:
    """Fit weights ``exp(-|xi - xj|^2 / h_i^2) flat_top(|xi - xj| / R_i) A_j`` of every pair.

    The heat kernel at ``t = h^2 / 4`` (eq 2.8 with the paper's ``m = 1/4``),
    tapered to 0 at the ball's edge (:func:`ball_taper`), times the
    neighbour's area: the weights of the default estimator's chord fit.

    Parameters
    ----------
    nbhd : Neighbourhood
        Neighbour pairs; ``nbhd.radius`` is ``R_i``.
    h : ndarray, shape (n,)
        Spacing of each centre.
    areas : ndarray, shape (N,)
        Areas of the points ``nbhd.indices`` refer to.

    Returns
    -------
    ndarray, shape (nnz,)
    """
    inv_h2 = 1.0 / np.asarray(h, dtype=np.float64) ** 2
    return kernels.tapered_heat_weights(
        nbhd.indptr, nbhd.indices, nbhd.distances, nbhd.radius, inv_h2, areas, TAPER_START
    )


def effective_neighbours(nbhd: Neighbourhood, weights: np.ndarray) -> np.ndarray:
    """Kish's effective number of neighbours of each row's weights, ``(sum_j w_ij)^2 / sum_j w_ij^2``.

    As many as the row's neighbours when the weights are equal; about 1 when
    one neighbour carries all the weight (a kernel much narrower than the
    spacing). A least-squares fit with ``p`` unknowns needs more than ``p``.

    Parameters
    ----------
    nbhd : Neighbourhood
    weights : ndarray, shape (nnz,)
        Non-negative pair weights.

    Returns
    -------
    ndarray, shape (n,)
        0 for rows without weight.
    """
    total = nbhd.segment_sum(weights)
    squares = nbhd.segment_sum(weights * weights)
    return np.where(squares > 0, total * total / np.where(squares > 0, squares, 1.0), 0.0)
