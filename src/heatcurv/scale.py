"""Kernel width of the default estimator: noise level and a bias-variance choice.

The default fit (:mod:`heatcurv.chordfit`) runs at a kernel that holds a
given number ``k`` of neighbours: the ball radius is ``R_i = d_k(i)``, the
distance to the ``k``-th nearest neighbour, and the heat kernel of the paper
(``t = h^2/4``, eq 2.8) has ``h_i = R_i / alpha``. On clean clouds the
smallest kernel (``k = 60``) with the chord curvatures is best; with noise,
wider kernels average it out but bend the fit away from the surface (bias
grows with ``R^2``). :func:`select_scale` picks the width per cloud:

1. fit, on a random subsample of the points, the chord fit and the
   denoised fit at ``k = 60``; the denoised fit's residual estimates the
   noise ``sigma``. If the chord fit's residual is not clearly larger
   (``clean_ratio``) the cloud is clean: use the chord fit at ``k = 60``
   (exact on circles, no averaging needed). Under even slight noise its
   near-neighbour chords ``2 z / |x_i - x_j|^2`` amplify the noise and it
   loses to the denoised fit;
2. otherwise fit the ladder ``k = 60, 120, 240, ...`` of denoised fits and
   compute each one's standard deviation of the mean curvature from
   ``sigma`` (least-squares sandwich formula);
3. Lepski's rule: take the widest candidate whose estimates agree with those
   of every narrower one: the median over the subsample of the change,
   in units of the narrower candidate's standard deviation at that point,
   at most ``tau`` (pure noise gives about 0.67). Wider kernels are accepted
   while their change is explainable by noise, and refused as soon as the
   change reveals bias.

Kernels wider than ``k_fit`` (240) neighbours are fitted against a random
subset of the cloud holding about ``k_fit`` points per ball (a coarser level):
the cost per point stays that of 240 neighbours however wide the kernel.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from .chordfit import ChordFit, chord_fit
from .kernel import tapered_heat_weights
from .neighbourhood import Neighbourhood, block_ranges, knn_neighbourhood, rows_per_block
from .sampling import draw_subset

__all__ = [
    "Scale", "ScaleChoice", "ScaleReport", "FitLevel", "fit_blocks", "fit_at_scale", "select_scale", "select_form",
]


@dataclass(frozen=True)
class Scale:
    """One candidate kernel: ``k`` neighbours, chord or denoised fit."""

    k: int
    denoise: bool

    @property
    def label(self) -> str:
        return f"{'denoised' if self.denoise else 'chord'}-{self.k}"


@dataclass(frozen=True)
class ScaleChoice:
    """What :func:`select_scale` measured and chose.

    Attributes
    ----------
    scale : Scale
        The chosen candidate.
    sigma : float
        Estimated noise (root-mean-square height residual), length units.
    relative_noise : float
        ``sigma`` over the median spacing ``h`` at ``k = 60``.
    candidates : list of Scale
        The ladder, narrowest first.
    sd : list of float
        Root-mean-square standard deviation of each candidate's mean curvature.
    mean_abs : float
        Mean ``|kappa_M|`` of the narrowest candidate (for scale).
    """

    scale: Scale
    sigma: float
    relative_noise: float
    candidates: list = field(default_factory=list)
    sd: list = field(default_factory=list)
    mean_abs: float = float("nan")


@dataclass(frozen=True)
class ScaleReport:
    """The chord fit's kernel as a result reports it (``result.info["scale"]``).

    Read it by attribute (``report.k``) or, as before it had a type, by key
    (``report["k"]``, ``report.get("fit")``).

    Attributes
    ----------
    k : int
        Neighbours in the fit's kernel.
    fit : str
        ``"chord-<k>"`` (clean cloud) or ``"denoised-<k>"``.
    radius : float
        99th percentile of the fit's ball radii, length units.
    median_h : float
        Median kernel spacing ``h = R / alpha`` of the fit.
    median_radius : float
        Median ball radius ``R`` of the fit, length units (with ``radius=``: that radius).
    sigma : float
        Estimated noise, length units.
    relative_noise : float
        ``sigma`` over the median spacing of the narrowest kernel.
    candidates : list of str
        Labels of the kernels compared, narrowest first.
    sd : list of float
        Root-mean-square standard deviation of each candidate's mean curvature.
    """

    k: int
    fit: str
    radius: float
    median_h: float
    sigma: float
    relative_noise: float
    candidates: list = field(default_factory=list)
    sd: list = field(default_factory=list)
    median_radius: float = float("nan")

    def in_unit(self, unit: float) -> ScaleReport:
        """The report with its lengths multiplied by ``unit`` (the stages' unit back to the input's)."""
        if unit == 1.0:
            return self
        return replace(
            self, radius=self.radius * unit, median_h=self.median_h * unit, sigma=self.sigma * unit,
            median_radius=self.median_radius * unit,
        )

    @classmethod
    def from_choice(
        cls, choice: ScaleChoice, radius: np.ndarray, alpha: float, fixed_radius: float | None = None
    ) -> ScaleReport:
        """The report of ``choice`` fitted with ball radii ``radius`` (shape (n,)).

        With ``fixed_radius`` (``radius=``) the label is ``"<form>-r<radius>"``.
        """
        label = choice.scale.label
        if fixed_radius is not None:
            label = f"{'denoised' if choice.scale.denoise else 'chord'}-r{fixed_radius:g}"
        return cls(
            k=choice.scale.k,
            fit=label,
            radius=float(np.percentile(radius, 99)),
            median_h=float(np.median(radius / alpha)),
            sigma=choice.sigma,
            relative_noise=choice.relative_noise,
            candidates=[label] if fixed_radius is not None else [c.label for c in choice.candidates],
            sd=choice.sd,
            median_radius=float(np.median(radius)),
        )

    def __getitem__(self, key: str):
        if key not in self.__dataclass_fields__:
            raise KeyError(key)
        return getattr(self, key)

    def get(self, key: str, default=None):
        """Dict-style access, as ``info["scale"]`` had before it had a type."""
        return getattr(self, key, default) if key in self.__dataclass_fields__ else default

    def keys(self):
        return self.__dataclass_fields__.keys()

    def as_dict(self) -> dict:
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


@dataclass(frozen=True)
class FitLevel:
    """Where a kernel of ``k`` neighbours draws its neighbours from: the cloud, or a coarser level.

    Kernels wider than ``k_fit`` neighbours are fitted against a random subset
    holding about ``k_fit / k`` of the points (sorted indices ``source``), on
    which the ``k``-th neighbour of the cloud is about the
    ``k * fraction``-th: the cost per point stays that of ``k_fit`` neighbours.

    Attributes
    ----------
    points : ndarray, shape (n_level, 3)
        The level's points.
    tree : scipy.spatial.cKDTree
        Tree on ``points``.
    source : ndarray of int, shape (n_level,), or None
        Index of each level point in the cloud (None: the level is the cloud).
    fraction : float
        ``n_level / n``.
    k : int
        Neighbours to query on the level.
    """

    points: np.ndarray
    tree: cKDTree
    source: np.ndarray | None
    fraction: float
    k: int

    @classmethod
    def for_kernel(
        cls, points: np.ndarray, tree: cKDTree, k: int, k_fit: int = 240, seed: int = 0, keys: np.ndarray | None = None
    ) -> FitLevel:
        """The level of a kernel of ``k`` neighbours on the cloud ``points`` (tree ``tree``).

        The coarse level is drawn by ``keys`` (:func:`heatcurv.sampling.geometric_keys`: the same
        level whatever the row order), else at random from the rows (seeded).
        """
        n = points.shape[0]
        if k <= k_fit:
            return cls(points, tree, None, 1.0, min(k, n - 1))
        size = min(max(int(round(n * k_fit / k)), k_fit + 1), n)
        coarse = draw_subset(n, size, seed + k, keys)
        fraction = coarse.size / n
        level_points = points[coarse]
        # the k-th neighbour in the cloud is about the (k * fraction)-th of the coarse level
        k_level = min(int(round(k * fraction)), coarse.size - 1)
        return cls(level_points, cKDTree(level_points), coarse, fraction, k_level)

    def rows_per_block(self, block_pairs: int | None = None) -> int:
        """Centres per block so that a block holds at most ``block_pairs`` pairs (default the policy's)."""
        return rows_per_block(self.k, block_pairs)

    def neighbourhood(self, queries: np.ndarray, workers: int = -1) -> Neighbourhood:
        """The ``k`` nearest level points of each query, indices into the cloud."""
        return knn_neighbourhood(
            self.points, self.k, tree=self.tree, queries=queries, source_index=self.source, workers=workers
        )


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
    k_fit: int = 240,
    passes: int = 2,
    seed: int = 0,
    workers: int = -1,
    block_pairs: int | None = None,
    keys: np.ndarray | None = None,
):
    """Run the chord fit at one kernel width, one block of centres at a time.

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
    k_fit : int, optional
        Widest kernel fitted against every point; wider ones use a coarser level.
    passes : int, optional
        Fits, each refining the normal (see :func:`heatcurv.chordfit.chord_fit`).
    seed : int, optional
        Seed of the coarse level.
    workers : int, optional
        Threads for the k-d tree queries.
    block_pairs : int, optional
        Neighbour pairs per block (default :data:`heatcurv.neighbourhood.BLOCK_PAIRS`).
    keys : ndarray, shape (n,), optional
        Sampling keys of the coarse level (:func:`heatcurv.sampling.geometric_keys`).

    Yields
    ------
    lo, hi : int
        The block's centres are ``centres[lo:hi]``.
    nbhd : Neighbourhood
        The block's pairs (indices into ``points``), ``hi - lo`` rows.
    fit : ChordFit
        The block's fit.
    fraction : float
        Share of the cloud the neighbours were drawn from (1, or the coarse level's).
    """
    cidx = np.arange(points.shape[0]) if centres is None else np.asarray(centres)
    level = FitLevel.for_kernel(points, tree, scale.k, k_fit, seed, keys)
    if base is not None and (centres is not None or level.source is not None):
        raise ValueError("base neighbourhoods serve full-level fits at every point only")
    for lo, hi in block_ranges(cidx.shape[0], level.rows_per_block(block_pairs)):
        queries = points[cidx[lo:hi]]
        nbhd = base.rows_slice(lo, hi) if base is not None else level.neighbourhood(queries, workers)
        # heat kernel, t = h^2 / 4 (eq 2.8), tapered to 0 at the ball's edge
        weights = tapered_heat_weights(nbhd, nbhd.radius / alpha, areas)
        fit = chord_fit(
            points, nbhd, normals[lo:hi], weights, denoise=scale.denoise, centres=queries, passes=passes
        )
        yield lo, hi, nbhd, fit, level.fraction


def fit_at_scale(
    points: np.ndarray,
    tree: cKDTree,
    normals: np.ndarray,
    areas: np.ndarray,
    scale: Scale,
    *,
    centres: np.ndarray | None = None,
    alpha: float = 2.0,
    k_fit: int = 240,
    passes: int = 2,
    seed: int = 0,
    workers: int = -1,
    keys: np.ndarray | None = None,
) -> tuple[ChordFit, np.ndarray, Neighbourhood, float]:
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
    fraction : float
        Share of the cloud the neighbours were drawn from (1, or the coarse level's).
    """
    fits, nbhds, fractions = [], [], [1.0]
    for _, _, nbhd, fit, fraction in fit_blocks(
        points, tree, normals, areas, scale, centres=centres, alpha=alpha, k_fit=k_fit, passes=passes, seed=seed,
        workers=workers, keys=keys,
    ):
        fits.append(fit)
        nbhds.append(nbhd)
        fractions.append(fraction)
    nbhd = Neighbourhood.concatenate(nbhds)
    return ChordFit.concatenate(fits), nbhd.radius / alpha, nbhd, fractions[-1]


def _is_clean(sigma_chord: float, sigma: float, h0: float, clean_ratio: float) -> bool:
    """The noise gate: the chord fit's residual is not clearly above the denoised fit's."""
    # large noise saturates the chord residual (|kN| <= 1/|z|), so the ratio alone
    # cannot tell; past sigma/h = 1 % no clean cloud gets (measured <= 3.5e-4)
    return sigma_chord <= clean_ratio * sigma and sigma < 0.01 * h0


def select_form(
    points: np.ndarray,
    nbhd: Neighbourhood,
    normals: np.ndarray,
    areas: np.ndarray,
    *,
    alpha: float = 2.0,
    n_sub: int = 2000,
    clean_ratio: float = 1.6,
    seed: int = 0,
    keys: np.ndarray | None = None,
) -> ScaleChoice:
    """The noise gate alone, on a neighbourhood the caller fixed (``radius=``): chord or denoised fit.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct centred points.
    nbhd : Neighbourhood
        The fixed balls of every point (e.g. one physical radius).
    normals : ndarray, shape (n, 3)
        Oriented starting normals.
    areas : ndarray, shape (n,)
        Per-point areas.
    alpha, n_sub, clean_ratio, seed, keys
        As :func:`select_scale` (its other tuning constants do not apply).

    Returns
    -------
    ScaleChoice
        ``scale.k`` is the median neighbour count of the balls.
    """
    sub = draw_subset(points.shape[0], n_sub, seed, keys)
    balls = nbhd.take_rows(sub)
    h = balls.radius / alpha
    weights = tapered_heat_weights(balls, h, areas)
    chord = chord_fit(points, balls, normals[sub], weights, centres=points[sub])
    denoised = chord_fit(points, balls, normals[sub], weights, centres=points[sub], denoise=True)
    sigma, h0 = float(np.median(denoised.sigma)), float(np.median(h))
    clean = _is_clean(float(np.median(chord.sigma)), sigma, h0, clean_ratio)
    k = int(np.median(nbhd.counts))
    return ScaleChoice(
        scale=Scale(k, not clean), sigma=sigma, relative_noise=sigma / h0, candidates=[Scale(k, not clean)], sd=[0.0],
        mean_abs=float(np.mean(np.abs((chord if clean else denoised).principal.mean))),
    )


def select_scale(
    points: np.ndarray,
    tree: cKDTree,
    normals: np.ndarray,
    areas: np.ndarray,
    *,
    base_k: int = 60,
    max_k: int | None = None,
    alpha: float = 2.0,
    k_fit: int = 240,
    n_sub: int = 2000,
    tau: float = 1.0,
    clean_ratio: float = 1.6,
    fixed_k: int | None = None,
    seed: int = 0,
    workers: int = -1,
    keys: np.ndarray | None = None,
) -> ScaleChoice:
    """Choose the kernel width for the whole cloud (see the module docstring).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct centred points.
    tree : scipy.spatial.cKDTree
        Tree on ``points``.
    normals : ndarray, shape (n, 3)
        Oriented starting normals.
    areas : ndarray, shape (n,)
        Per-point areas.
    base_k : int, optional
        Narrowest kernel (neighbours).
    max_k : int, optional
        Widest kernel tried; the ladder doubles from ``base_k`` and stops at
        ``max_k``, by default a tenth of the cloud (at least 1920). A fixed
        neighbour count would not do: the same relative noise on a denser
        sample of the same surface needs a kernel of the same *size*, which
        holds proportionally more points (a million-point torus with noise
        of 0.12 % of its diagonal chose 960 neighbours under a fixed cap of
        1920 and its mean curvature was off by 68 %). Wide kernels cost no
        more per point: they are fitted against a coarser level.
    alpha : float, optional
        Ball radius in units of ``h``.
    k_fit : int, optional
        Widest kernel fitted against every point.
    n_sub : int, optional
        Points the ladder is evaluated on.
    tau : float, optional
        Lepski's tolerance: the largest median change, in standard deviations
        of the narrower candidate (pure noise gives about 0.67).
    clean_ratio : float, optional
        The cloud counts as clean, and the chord fit at ``base_k`` is used,
        when the chord fit's residual is at most this multiple of the
        denoised fit's. Without noise both residuals are the model's error
        and alike (measured ratios 0.2-1.3 on clean random, Fibonacci and grid
        clouds of 3000-20 000 points); noise enters the chord residual through
        ``2 z / |x_i - x_j|^2`` amplified, and the ratio jumps to about 4
        (measured 2.2-4.4 for noise from 1e-6 to 1.2e-3 of the bounding-box
        diagonal). Strong noise saturates the chord residual (``|kN| <=
        1/|z|``) and the ratio falls back (1.4 at ``sigma / h = 0.37``), so
        a cloud with ``sigma / h`` above 1 % never counts as clean (clean
        clouds measured at most 3.5e-4).
    fixed_k : int, optional
        Use this kernel width instead of choosing one: only the noise is
        measured, to pick the chord fit (clean) or the denoised one.
    seed : int, optional
        Seed of the subsample and coarse levels (results are reproducible).
    workers : int, optional
        Threads for the k-d tree queries.
    keys : ndarray, shape (n,), optional
        Sampling keys of the subsample and the coarse levels
        (:func:`heatcurv.sampling.geometric_keys`: the choice does not depend
        on the row order); default seeded random samples of the rows.

    Returns
    -------
    ScaleChoice
    """
    n = points.shape[0]
    sub = draw_subset(n, n_sub, seed, keys)
    ladder = []
    k = base_k
    if max_k is None:
        max_k = max(1920, n // 10)
    # at least base_k itself (a base_k above the default cap, e.g. neighbours close to n)
    while k <= max(base_k, min(max_k, max(n // 4, base_k))):
        ladder.append(Scale(k, True))
        k *= 2

    # the noise gate: residuals of the chord and of the denoised fit at base_k
    chord, h, _, _ = fit_at_scale(
        points, tree, normals[sub], areas, Scale(base_k, False), centres=sub, alpha=alpha, k_fit=k_fit, seed=seed,
        workers=workers, keys=keys,
    )
    means, factors = [], []
    for j, sc in enumerate(ladder):
        fit, h, _, _ = fit_at_scale(
            points, tree, normals[sub], areas, sc, centres=sub, alpha=alpha, k_fit=k_fit, seed=seed, workers=workers,
            keys=keys,
        )
        means.append(fit.principal.mean)
        factors.append(fit.mean_variance_factor)
        if j == 0:
            sigma = float(np.median(fit.sigma))
            h0 = float(np.median(h))
            sigma_chord = float(np.median(chord.sigma))
            clean = _is_clean(sigma_chord, sigma, h0, clean_ratio)
            if clean or fixed_k is not None:
                k_use = base_k if fixed_k is None else int(fixed_k)
                return ScaleChoice(
                    scale=Scale(k_use, not clean), sigma=sigma, relative_noise=sigma / h0, candidates=ladder[:1],
                    sd=[0.0], mean_abs=float(np.mean(np.abs(means[0]))),
                )
    sd_point = [sigma * np.sqrt(np.maximum(f, 0.0)) for f in factors]
    sd = [float(np.sqrt(np.mean(x**2))) for x in sd_point]
    tiny = np.finfo(float).tiny
    chosen = 0
    for j in range(1, len(ladder)):
        # per point, the change from a narrower candidate in units of that one's standard
        # deviation; the median is robust to the few points where a fit is poor
        agree = all(
            np.median(np.abs(means[j] - means[i]) / np.maximum(sd_point[i], tiny)) <= tau for i in range(j)
        )
        if not agree:
            break
        chosen = j
    return ScaleChoice(
        scale=ladder[chosen],
        sigma=sigma,
        relative_noise=sigma / h0,
        candidates=ladder,
        sd=sd,
        mean_abs=float(np.mean(np.abs(means[0]))),
    )

