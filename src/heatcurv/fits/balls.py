"""The chord fit at one kernel width: every centre fitted with the whole ball of its ``k`` nearest neighbours.

A :class:`Scale` is one candidate kernel (``k`` neighbours, chord or denoised
fit). :func:`fit_balls` fits a set of centres at it, :func:`fit_blocks` every
point one block of centres at a time (so that memory stays bounded however
wide the kernel), :func:`fit_at_scale` the same from an operator's arrays. The
choice among scales is :mod:`heatcurv.choice.scale`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..backend import SPLIT_ROWS, map_blocks
from ..geometry.neighbourhood import Neighbourhood, block_ranges, knn_neighbourhood, rows_per_block
from ..operators.kernel import tapered_heat_weights
from .chordfit import ChordFit, chord_fit

__all__ = ["Scale", "fit_at_scale", "fit_balls", "fit_blocks"]


@dataclass(frozen=True)
class Scale:
    """One candidate kernel: ``k`` neighbours, chord or denoised fit."""

    k: int
    denoise: bool

    @property
    def label(self) -> str:
        return f"{'denoised' if self.denoise else 'chord'}-{self.k}"


def fit_balls(
    points: np.ndarray,
    tree: cKDTree,
    centres: np.ndarray,
    normals: np.ndarray,
    areas: np.ndarray,
    scale: Scale,
    *,
    alpha: float = 2.0,
    passes: int = 2,
    workers: int = -1,
    nbhd: Neighbourhood | None = None,
    low_noise: bool = False,
) -> tuple[Neighbourhood, ChordFit]:
    """The chord fit at ``centres``, each with the whole ball of its ``scale.k`` nearest neighbours.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct centred points; ``tree`` is built on them.
    tree : scipy.spatial.cKDTree
    centres : ndarray of int, shape (m,)
        The points fitted at.
    normals : ndarray, shape (m, 3)
        Their oriented starting normals.
    areas : ndarray, shape (n,)
        Per-point areas (fit weights ``W_ij A_j``).
    scale : Scale
        Neighbour count and fit form.
    alpha, passes, workers : optional
        As :func:`fit_blocks`.
    nbhd : Neighbourhood, optional
        The centres' balls, already computed (else queried).
    low_noise : bool, optional
        The denoised form's low-noise refit (:func:`heatcurv.fits.chordfit.chord_fit`).

    Returns
    -------
    nbhd : Neighbourhood
        The balls (indices into ``points``), one row per centre.
    fit : ChordFit
    """
    queries = points[centres]
    if nbhd is None:
        nbhd = knn_neighbourhood(points, min(scale.k, points.shape[0] - 1), tree=tree, queries=queries,
                                 workers=workers)
    # heat kernel, t = h^2 / 4 (eq 2.8) with h = R / alpha, tapered to 0 at the ball's edge
    weights = tapered_heat_weights(nbhd, nbhd.radius / alpha, areas)
    fit = chord_fit(points, nbhd, normals, weights, denoise=scale.denoise, centres=queries, passes=passes,
                    low_noise=low_noise)
    return nbhd, fit


def fit_blocks(
    points: np.ndarray,
    tree: cKDTree,
    normals: np.ndarray,
    areas: np.ndarray,
    scale: Scale,
    *,
    centres: np.ndarray | None = None,
    base: Neighbourhood | None = None,
    alpha: float = 2.0,
    passes: int = 2,
    workers: int = -1,
    block_pairs: int | None = None,
    low_noise: bool = False,
):
    """Run the chord fit at one kernel width, one block of centres at a time, each with its whole ball.

    The neighbourhood of a block exists only while the block is fitted, so
    memory stays bounded by ``block_pairs`` pairs however many points and
    however wide the kernel. (:func:`heatcurv.estimate` runs the same steps
    as named stages of its own.)

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct centred points; ``tree`` is built on them.
    tree : scipy.spatial.cKDTree
    normals : ndarray, shape (m, 3)
        Oriented starting normals of the centres.
    areas : ndarray, shape (n,)
        Per-point areas (fit weights ``W_ij A_j``).
    scale : Scale
        Neighbour count and fit form.
    centres : ndarray of int, shape (m,), optional
        Indices of the points to fit at (default all).
    base : Neighbourhood, optional
        The ``scale.k`` nearest neighbours of every point, already computed
        (the operator's): used instead of new queries. Only with ``centres=None``.
    alpha : float, optional
        Ball radius in units of ``h`` (``R = d_k = alpha h``).
    passes : int, optional
        Fits, each refining the normal (see :func:`heatcurv.fits.chordfit.chord_fit`).
    workers : int, optional
        Threads for the k-d tree queries.
    block_pairs : int, optional
        Neighbour pairs per block (default :data:`heatcurv.geometry.neighbourhood.BLOCK_PAIRS`).
    low_noise : bool, optional
        As :func:`fit_balls`.

    Yields
    ------
    lo, hi : int
        The block's centres are ``centres[lo:hi]``.
    nbhd : Neighbourhood
        The block's pairs (indices into ``points``), ``hi - lo`` rows.
    fit : ChordFit
        The block's fit.
    """
    cidx = np.arange(points.shape[0]) if centres is None else np.asarray(centres)
    if base is not None and centres is not None:
        raise ValueError("base neighbourhoods serve fits at every point only")
    k = min(scale.k, points.shape[0] - 1)

    def fit_block(bounds):
        lo, hi = bounds
        nbhd, fit = fit_balls(
            points, tree, cidx[lo:hi], normals[lo:hi], areas, scale, alpha=alpha, passes=passes, workers=workers,
            nbhd=None if base is None else base.rows_slice(lo, hi), low_noise=low_noise,
        )
        return lo, hi, nbhd, fit

    rows = rows_per_block(k, block_pairs)
    if cidx.shape[0] <= rows and cidx.shape[0] < SPLIT_ROWS:
        # one small block (a wide kernel at a few centres): halves side by side on the kernels' threads
        rows = max(1, -(-cidx.shape[0] // 2))
    yield from map_blocks(fit_block, list(block_ranges(cidx.shape[0], rows)), rows)


def fit_at_scale(
    points: np.ndarray,
    tree: cKDTree,
    normals: np.ndarray,
    areas: np.ndarray,
    scale: Scale,
    *,
    centres: np.ndarray | None = None,
    alpha: float = 2.0,
    passes: int = 2,
    workers: int = -1,
) -> tuple[ChordFit, np.ndarray, Neighbourhood]:
    """Run the chord fit at one kernel width (all blocks of :func:`fit_blocks` joined).

    Parameters are those of :func:`fit_blocks`.

    Returns
    -------
    fit : ChordFit
    h : ndarray, shape (m,)
        Kernel spacing ``h_i = R_i / alpha`` of each centre.
    nbhd : Neighbourhood
        The pairs fitted (indices into ``points``); for many centres use
        :func:`fit_blocks`, which does not keep them.
    """
    fits, nbhds = [], []
    for _, _, nbhd, fit in fit_blocks(
        points, tree, normals, areas, scale, centres=centres, alpha=alpha, passes=passes, workers=workers,
    ):
        fits.append(fit)
        nbhds.append(nbhd)
    nbhd = Neighbourhood.concatenate(nbhds)
    return ChordFit.concatenate(fits), nbhd.radius / alpha, nbhd

