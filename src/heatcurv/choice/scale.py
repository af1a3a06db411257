"""Kernel width of the default estimator: noise level and a bias-variance choice.

The default fit (:mod:`heatcurv.fits.chordfit`) runs at a kernel that holds a
given number ``k`` of neighbours: the ball radius is ``R_i = d_k(i)``, the
distance to the ``k``-th nearest neighbour, and the heat kernel of the paper
(``t = h^2/4``, eq 2.8) has ``h_i = R_i / alpha``. On clean clouds the
smallest kernel (``k = 60``) with the chord curvatures is best; with noise,
wider kernels average it out but bend the fit away from the surface (bias
grows with ``R^2``). :func:`select_scale` picks the width per cloud:

1. fit, on a subsample of the points (2000, drawn by geometric keys), the
   chord fit and the denoised fit at ``k = 60``; the denoised fit's residual
   estimates the noise ``sigma``. If the chord fit's residual is not clearly
   larger (``clean_ratio``) the cloud is clean: use the chord fit at ``k = 60``
   (exact on circles, no averaging needed). Under even slight noise its
   near-neighbour chords ``2 z / |x_i - x_j|^2`` amplify the noise and it
   loses to the denoised fit;
2. otherwise fit the ladder ``k = 60, 120, 240, ...`` (up to a quarter of
   the cloud) of denoised fits, each with every point of its ball (the widest at
   fewer centres: :data:`PAIRS_PER_LEVEL`), and compute each one's standard
   deviation of the mean curvature from the local noise (least-squares
   sandwich formula; the noise is the larger of the 60-neighbour residual and
   the candidate's own, both as medians over a window of :data:`WINDOW`
   centres: a narrow fit absorbs part of strong noise);
3. bin the centres by their local noise, one bin per factor of about 2.4
   (the optimal width balances a bias growing as ``R^2`` against a standard
   deviation falling as ``sigma / R^3``, so ``k ~ sigma^(2/5)``: one bin is
   one doubling of ``k``), and in each bin apply Lepski's rule: take the
   widest candidate whose estimates agree with those of every narrower one:
   the median over the bin's centres of the change, in units of the narrower
   candidate's standard deviation at that point, at most ``tau`` (pure noise
   gives about 0.67). Wider kernels are accepted while their change is
   explainable by noise, and refused as soon as the change reveals bias;
4. a local guard narrows a region's kernel where the median change over its
   window exceeds ``TUNING.tau_local`` standard deviations (clear local bias);
   each point takes the choice of its nearest centre;
5. a cloud in the very-low-noise band (``relative_noise`` from ``TUNING.no_noise``
   to below ``TUNING.low_noise``, e.g. a LAZ file's millimetres) is fitted with the
   denoised form's low-noise refit (:mod:`heatcurv.fits.anchors`), whose bias is far
   below that of the plain fit the rule compares. Where the rule widened the
   kernel of the median centre, every widened centre's kernel is ``TUNING.low_noise_levels`` doubling wider.

The bias decision pools every centre of a noise bin, and only the guard of
step 4 looks at small regions: a per-region test is noisy, and a too-narrow
kernel costs more than a slightly biased one. A cloud whose noise changes from
region to region still gets each region about the width its own noise calls
for (docs/accuracy.md, mixed noise; the per-region variant is in
docs/how_it_works.md, thresholds).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from ..fits.balls import Scale, fit_at_scale
from ..fits.chordfit import ChordFit, chord_fit
from ..geometry.neighbourhood import Neighbourhood
from ..geometry.sampling import draw_subset, shifted_keys
from ..operators.kernel import tapered_heat_weights
from ..tuning import TUNING

__all__ = [
    "CentreFits", "CentreFitter", "RISE_LEVELS", "ScaleChoice", "ScaleReport", "decide_scale", "in_low_noise_band",
    "level_sizes", "residual_rise", "select_scale", "select_form",
]


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
    k_per_point : ndarray of int, shape (n,), or None
        The kernel width chosen at each point (None: ``scale.k`` everywhere).
    centres : ndarray, shape (q, 3), or None
        The sample centres the widths were chosen at (stages' frame); None
        when one width serves the whole cloud.
    k_centre : ndarray of int, shape (q,), or None
        The width chosen at each centre; a point takes its nearest centre's.
    low_noise : bool
        The very-low-noise path (:func:`decide_scale`, step 5 of the module): the kernel was
        widened for the denoised form's low-noise refit, which the anchors then fit
        (:mod:`heatcurv.fits.anchors`).
    residual_rise : float
        The denoised fit's median residual at four times the narrowest kernel over its residual
        at the narrowest (:func:`residual_rise`): about 1 where the residual is noise, growing
        where it is the model's misfit; NaN on a clean cloud, with a fixed kernel, or where the
        ladder stops short of it.
    quiet_rise : float
        The same rise of the quietest centres' residual (:func:`residual_rise`): about 1 where the
        residual of the smooth parts is noise, even where most wide balls reach a sharp edge.
    """

    scale: Scale
    sigma: float
    relative_noise: float
    candidates: list = field(default_factory=list)
    sd: list = field(default_factory=list)
    mean_abs: float = float("nan")
    k_per_point: np.ndarray | None = None
    centres: np.ndarray | None = None
    k_centre: np.ndarray | None = None
    low_noise: bool = False
    residual_rise: float = float("nan")
    quiet_rise: float = float("nan")

    def at_points(self, points: np.ndarray, workers: int = -1) -> ScaleChoice:
        """The choice with ``k_per_point`` for ``points`` (shape (n, 3)): each takes its nearest centre's width.

        ``scale.k`` becomes the median point's width. Without centres (one
        width for all) the choice is returned as it is.
        """
        if self.centres is None:
            return self
        _, nearest = cKDTree(self.centres).query(points, 1, workers=workers)
        k_point = self.k_centre[nearest]
        return replace(self, scale=Scale(int(np.median(k_point)), True), k_per_point=k_point)


@dataclass(frozen=True)
class ScaleReport:
    """The chord fit's kernel as a result reports it (``result.info["scale"]``).

    Attributes
    ----------
    k : int
        Neighbours in the fit's kernel.
    fit : str
        The fit plan's label (:attr:`heatcurv.choice.plan.FitPlan.label`): ``"chord-<k>"`` (clean
        cloud), ``"denoised-<k>"``, or ``"<form>-r<radius>"`` with ``radius=``.
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
    support_radius : float
        The largest support radius of any point, length units: with the cloud-wide
        choices fixed (:mod:`heatcurv.choice.choices`), no point farther than this changes a
        point's values (a tiled run's halo). The per-point fit's is its ball radius.
    anchors : int
        Points the wide kernel was fitted at (0: every point has its own fit).
    k_min, k_max : int
        Narrowest and widest kernel chosen at any point (``k`` is the median point's).
    low_noise : bool
        The very-low-noise path ran (:attr:`ScaleChoice.low_noise`, module docstring step 5).
    residual_rise, quiet_rise : float
        :attr:`ScaleChoice.residual_rise`, :attr:`ScaleChoice.quiet_rise`.
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
    support_radius: float = float("nan")
    anchors: int = 0
    k_min: int = 0
    k_max: int = 0
    low_noise: bool = False
    residual_rise: float = float("nan")
    quiet_rise: float = float("nan")

    def in_unit(self, unit: float) -> ScaleReport:
        """The report with its lengths multiplied by ``unit`` (the stages' unit back to the input's)."""
        if unit == 1.0:
            return self
        return replace(
            self, radius=self.radius * unit, median_h=self.median_h * unit, sigma=self.sigma * unit,
            median_radius=self.median_radius * unit, support_radius=self.support_radius * unit,
        )

    @classmethod
    def from_choice(
        cls, choice: ScaleChoice, label: str, radius: np.ndarray, alpha: float, *, fixed_radius: bool = False,
        support: np.ndarray | None = None, anchors: int = 0, k: np.ndarray | None = None,
    ) -> ScaleReport:
        """The report of ``choice`` fitted as the plan ``label`` says (:attr:`heatcurv.choice.plan.FitPlan.label`).

        ``radius`` (shape (n,)) are the fit's ball radii, ``fixed_radius`` says they are the one
        radius of ``radius=`` (the only candidate), ``support`` (shape (n,)) each point's support
        radius (default ``radius``), ``anchors`` the anchors' count and ``k`` (shape (n,)) each
        point's kernel width.
        """
        support = radius if support is None else support
        finite = support[np.isfinite(support)]
        return cls(
            support_radius=float(finite.max()) if finite.size else float("nan"), anchors=int(anchors),
            k_min=choice.scale.k if k is None else int(k.min()), k_max=choice.scale.k if k is None else int(k.max()),
            low_noise=bool(choice.low_noise), residual_rise=choice.residual_rise, quiet_rise=choice.quiet_rise,
            k=choice.scale.k if k is None else int(np.median(k)),
            fit=label,
            radius=float(np.percentile(radius, 99)),
            median_h=float(np.median(radius / alpha)),
            sigma=choice.sigma,
            relative_noise=choice.relative_noise,
            candidates=[label] if fixed_radius else [c.label for c in choice.candidates],
            sd=choice.sd,
            median_radius=float(np.median(radius)),
        )

    def as_dict(self) -> dict:
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


def in_low_noise_band(relative_noise: float) -> bool:
    """Whether ``relative_noise`` is in the very-low-noise band: ``TUNING.no_noise`` to below ``TUNING.low_noise``."""
    return TUNING.no_noise <= relative_noise < TUNING.low_noise


#: Centres each centre's Lepski test takes the median over (of ``n_sub``): the region a kernel is
#: chosen for, about a tenth of the cloud with the default subsample.
WINDOW = 200
#: Neighbour pairs each candidate kernel is evaluated with: the widest ones at fewer centres.
PAIRS_PER_LEVEL = 500_000
#: Fewest centres a candidate is evaluated at.
MIN_CENTRES = 100
#: Fewest centres a median over a window takes.
MIN_WINDOW = 50


def _is_clean(sigma_chord: float, sigma: float, h0: float, clean_ratio: float) -> bool:
    """The noise gate: the chord fit's residual is not clearly above the denoised fit's."""
    if sigma_chord <= TUNING.exact_residual * h0:
        return True  # both residuals are rounding (planar faces): their ratio is chance
    # large noise saturates the chord residual (|kN| <= 1/|z|), so the ratio alone
    # cannot tell; no clean cloud has sigma / h past TUNING.clean_noise_limit (measured <= 3.5e-4)
    return sigma_chord <= clean_ratio * sigma and sigma < TUNING.clean_noise_limit * h0


def select_form(
    points: np.ndarray,
    nbhd: Neighbourhood,
    normals: np.ndarray,
    areas: np.ndarray,
    *,
    alpha: float = 2.0,
    n_sub: int = 2000,
    clean_ratio: float = 2.2,
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


def _nested_centres(sub: np.ndarray, keys: np.ndarray | None, seed: int) -> np.ndarray:
    """The subsample ``sub`` in the order its prefixes are taken (smallest keys first, else seeded)."""
    if keys is not None:  # by the shifted keys the subsample was drawn by: a tile's prefixes hold the cloud's
        return sub[np.argsort(shifted_keys(keys[sub], seed), kind="stable")]
    return sub[np.random.default_rng(seed + 1).permutation(sub.shape[0])]


def _ladder(base_k: int, max_k: int | None, n: int) -> list:
    """The candidates ``base_k, 2 base_k, ...`` up to ``max_k`` (default ``TUNING.widest_kernel``) and ``n / 4``."""
    top = min(TUNING.widest_kernel if max_k is None else max_k, n // 4)
    ladder, k = [], base_k
    while k <= max(base_k, top):  # at least base_k itself (a base_k close to n)
        ladder.append(Scale(k, True))
        k *= 2
    return ladder


def _windows(positions: np.ndarray, at: np.ndarray, window: int, workers: int) -> np.ndarray | None:
    """The ``window`` nearest of ``positions`` to each of ``at``, shape (q, window); None: all of them."""
    if window >= positions.shape[0]:
        return None
    _, idx = cKDTree(positions).query(at, window, workers=workers)
    return idx.reshape(at.shape[0], window)


def _window_medians(values: np.ndarray, windows: np.ndarray | None, q: int) -> np.ndarray:
    """Median of ``values`` (shape (m,)) over each row of ``windows`` (:func:`_windows`), shape (q,)."""
    if windows is None:
        return np.full(q, np.median(values))
    return np.median(values[windows], axis=1)


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
    clean_ratio: float = 2.2,
    fixed_k: int | None = None,
    seed: int = 0,
    workers: int = -1,
    keys: np.ndarray | None = None,
    window: int = WINDOW,
    pairs_per_level: int = PAIRS_PER_LEVEL,
    n_cloud: int | None = None,
) -> ScaleChoice:
    """Choose the kernel width at every point (see the module docstring).

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
        ``max_k``, by default a quarter of the cloud. A fixed neighbour count
        would not do: the same relative noise on a denser sample of the same
        surface needs a kernel of the same *size*, which holds proportionally
        more points (a million-point torus with noise of 0.12 % of its
        diagonal chose 960 neighbours under a fixed cap of 1920 and its mean
        curvature was off by 68 %; a 30 000-point patch with 0.6 % noise was
        best at 3840 neighbours, 10.1 % against 14.7 % at 1920, a 20 000-point
        sphere at 3840, 1.0 % against 2.4 %). Wide kernels cost no more per
        point: they are fitted at anchors (:mod:`heatcurv.fits.anchors`).
    alpha : float, optional
        Ball radius in units of ``h``.
    k_fit : int, optional
        Unused by the choice (every candidate is fitted with all the points of
        its ball); kept for the signature of :class:`heatcurv.ScaleTuning`.
    n_sub : int, optional
        Centres the ladder is evaluated on (fewer for the widest candidates:
        ``pairs_per_level``).
    tau : float, optional
        Lepski's tolerance: the largest median change, in standard deviations
        of the narrower candidate (pure noise gives about 0.67).
    clean_ratio : float, optional
        The cloud counts as clean, and the chord fit at ``base_k`` is used, when the chord fit's residual is at most
        this multiple of the denoised fit's. Without noise both residuals are the model's error and the ratio stays
        at most 2.0; noise enters the chord residual through ``2 z / |x_i - x_j|^2`` amplified, and the ratio jumps
        to about 4 (docs/accuracy.md, the noise gate's ratio). Strong noise saturates the chord residual
        (``|kN| <= 1/|z|``) and the ratio falls back, so a cloud with ``sigma / h`` above 1 % never counts as clean
        (clean clouds stay far below it).
    fixed_k : int, optional
        Use this kernel width instead of choosing one: only the noise is
        measured, to pick the chord fit (clean) or the denoised one.
    seed : int, optional
        Seed of the subsample (results are reproducible).
    workers : int, optional
        Threads for the k-d tree queries.
    keys : ndarray, shape (n,), optional
        Sampling keys of the subsample (:func:`heatcurv.geometry.sampling.geometric_keys`:
        the choice does not depend on the row order); default seeded random
        samples of the rows.
    window : int, optional
        Centres each point's choice looks at (:data:`WINDOW`).
    pairs_per_level : int, optional
        Neighbour pairs one candidate is evaluated with (:data:`PAIRS_PER_LEVEL`).
    n_cloud : int, optional
        Rows of the whole cloud (:class:`heatcurv.choice.choices.CloudFrame`), which
        set the widest candidate; default ``len(points)``.

    Returns
    -------
    ScaleChoice
        With ``k_per_point``, the width chosen at each point.
    """
    n = points.shape[0]
    centres = _nested_centres(draw_subset(n, n_sub, seed, keys), keys, seed)
    fitter = CentreFitter(points, tree, normals[centres], areas, centres, alpha=alpha, workers=workers)
    choice = decide_scale(
        fitter, points[centres], n if n_cloud is None else n_cloud, base_k=base_k, max_k=max_k, tau=tau,
        clean_ratio=clean_ratio, fixed_k=fixed_k, window=window, pairs_per_level=pairs_per_level, workers=workers,
    )
    return choice.at_points(points, workers)


def centre_noise(points, tree, normals, areas, *, base_k: int = 60, alpha: float = 2.0, n_sub: int = 2000,
                 seed: int = 0, keys: np.ndarray | None = None, workers: int = -1) -> float:
    """The cloud's noise as the kernel choice measures it (``ScaleChoice.sigma``), without the choice.

    The median residual of the denoised fit at ``base_k`` over the same sample
    centres :func:`select_scale` uses (:func:`heatcurv.orient.auto.auto_policy`
    needs it before the choice is made).

    Parameters
    ----------
    points, tree, areas, base_k, alpha, n_sub, seed, keys, workers
        As :func:`select_scale`.
    normals : ndarray, shape (n, 3)
        Unit normals, either sign.

    Returns
    -------
    float
        Length units.
    """
    centres = draw_subset(points.shape[0], n_sub, seed, keys)
    fitter = CentreFitter(points, tree, normals[centres], areas, centres, alpha=alpha, workers=workers)
    return float(np.median(fitter(Scale(base_k, True), centres.shape[0]).sigma))


@dataclass(frozen=True)
class CentreFits:
    """One candidate kernel's fit at the first sample centres (what Lepski's rule compares).

    Attributes
    ----------
    mean : ndarray, shape (s,)
        Fitted mean curvature (its sign follows the centre's normal; only
        differences at one centre and magnitudes are used).
    factor : ndarray, shape (s,)
        Standard deviation of ``mean`` per unit height noise
        (``sqrt(ChordFit.mean_variance_factor)``).
    sigma : ndarray, shape (s,)
        The fit's residual, length units.
    h : ndarray, shape (s,)
        Kernel spacing ``h = R / alpha`` at each centre.
    """

    mean: np.ndarray
    factor: np.ndarray
    sigma: np.ndarray
    h: np.ndarray

    @classmethod
    def of(cls, fit: ChordFit, h: np.ndarray) -> CentreFits:
        """From a :class:`ChordFit` and its spacings."""
        return cls(fit.principal.mean, np.sqrt(np.maximum(fit.mean_variance_factor, 0.0)), fit.sigma, h)


class CentreFitter:
    """Fits candidate kernels at the nested sample centres of a cloud held in memory.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    tree : scipy.spatial.cKDTree
    normals : ndarray, shape (q, 3)
        Starting normals of the centres.
    areas : ndarray, shape (n,)
    centres : ndarray of int, shape (q,)
        The centres, in the order their prefixes are taken.
    alpha, workers : optional
        As :func:`heatcurv.fits.balls.fit_at_scale`.

    Calling it with ``(scale, size)`` fits ``scale`` at the first ``size``
    centres (a :class:`CentreFits`); :mod:`heatcurv.choice.survey` has the same
    interface for centres measured tile by tile.
    """

    def __init__(self, points, tree, normals, areas, centres, *, alpha: float = 2.0, workers: int = -1):
        self.points, self.tree, self.normals, self.areas = points, tree, normals, areas
        self.centres, self.alpha, self.workers = centres, alpha, workers

    def __call__(self, scale: Scale, size: int) -> CentreFits:
        if size == 0:  # a tile none of whose centres is among this candidate's first (heatcurv.choice.survey)
            return CentreFits(*(np.zeros(0) for _ in range(4)))
        fit, h, _ = fit_at_scale(
            self.points, self.tree, self.normals[:size], self.areas, scale, centres=self.centres[:size],
            alpha=self.alpha, workers=self.workers,
        )
        return CentreFits.of(fit, h)


def level_sizes(ladder: list, q: int, pairs_per_level: int = PAIRS_PER_LEVEL) -> list:
    """Centres each candidate of ``ladder`` is fitted at (of ``q``): the widest at fewer, >= :data:`MIN_CENTRES`."""
    return [q] + [min(q, max(MIN_CENTRES, pairs_per_level // c.k)) for c in ladder[1:]]


def decide_scale(
    fits,
    at: np.ndarray,
    n_cloud: int,
    *,
    base_k: int = 60,
    max_k: int | None = None,
    tau: float = 1.0,
    clean_ratio: float = 2.2,
    fixed_k: int | None = None,
    window: int = WINDOW,
    pairs_per_level: int = PAIRS_PER_LEVEL,
    workers: int = -1,
) -> ScaleChoice:
    """The noise gate, the noise regions and Lepski's rule on fits at sample centres (steps 1-4 of the module).

    Parameters
    ----------
    fits : callable
        ``fits(scale, size)`` -> :class:`CentreFits` at the first ``size``
        centres (:class:`CentreFitter`, or a tiled run's survey).
    at : ndarray, shape (q, 3)
        The centres' positions, in the order their prefixes are taken.
    n_cloud : int
        Points of the whole cloud (the ladder stops at a quarter of it).
    base_k, max_k, tau, clean_ratio, fixed_k, window, pairs_per_level, workers
        As :func:`select_scale`.

    Returns
    -------
    ScaleChoice
        With ``centres`` and ``k_centre`` (each point then takes its nearest
        centre's width: :meth:`ScaleChoice.at_points`).
    """
    q = at.shape[0]
    ladder = _ladder(base_k, max_k, n_cloud)

    # the noise gate: residuals of the chord and of the denoised fit at base_k
    chord = fits(Scale(base_k, False), q)
    base = fits(ladder[0], q)
    sigma, h0 = float(np.median(base.sigma)), float(np.median(base.h))
    clean = _is_clean(float(np.median(chord.sigma)), sigma, h0, clean_ratio)
    mean_abs = float(np.mean(np.abs(base.mean)))
    if clean or fixed_k is not None:
        k_use = base_k if fixed_k is None else int(fixed_k)
        return ScaleChoice(
            scale=Scale(k_use, not clean), sigma=sigma, relative_noise=sigma / h0, candidates=ladder[:1], sd=[0.0],
            mean_abs=mean_abs,
        )
    ladder_fits = _LadderFits(fits, ladder, level_sizes(ladder, q, pairs_per_level), at, base, window, workers)
    if len(ladder) > 1:
        ladder_fits.evaluate(1)
    ladder_fits.complete_sds()
    noise_bin = _noise_regions(ladder_fits.noise)
    chosen = np.minimum(_lepski(ladder_fits, noise_bin, tau), _local_guard(ladder_fits, window, workers))
    # very low noise, where the rule widened the median centre's kernel: the low-noise refit's kernel is wider
    # (TUNING.low_noise_levels). Where the rule kept the narrowest (scans: the bunny, the face, relative_noise
    # 0.019, chose 60; widened to 240 the bunny's area moved 2 %, the face's 28 %) the bias is at the
    # narrowest scale already, and the cloud keeps the plain fit.
    low_noise = in_low_noise_band(sigma / h0) and np.median(chosen) > 0
    if low_noise:
        chosen = np.where(chosen > 0, np.minimum(chosen + TUNING.low_noise_levels, len(ladder) - 1), chosen)
        # the wider candidates are fitted too, so that a tiled run's survey measures their balls (its
        # halo) as it does the chosen ones'
        for j in range(len(ladder_fits.means), int(chosen.max()) + 1):
            ladder_fits.evaluate(j)
    means, sds = ladder_fits.means, ladder_fits.sds
    k_all = np.array([c.k for c in ladder])
    evaluated = ladder[: len(means)]
    sd = [float(np.sqrt(np.mean(x**2))) for x in sds]
    k_centre = k_all[chosen]
    rise, quiet_rise = residual_rise(ladder_fits)
    return ScaleChoice(
        scale=Scale(int(np.median(k_centre)), True),
        sigma=sigma,
        relative_noise=sigma / h0,
        candidates=evaluated,
        sd=sd,
        mean_abs=mean_abs,
        centres=at,
        k_centre=k_centre,
        low_noise=bool(low_noise),
        residual_rise=rise,
        quiet_rise=quiet_rise,
    )


class _LadderFits:
    """The candidates' fits at their centres, the local noise they measure and their standard deviations.

    ``noise`` is the denoised residual's median over each centre's window; a narrow fit absorbs part of
    strong noise (at ``sigma`` about 2 spacings the 60-neighbour residual was half the true ``sigma``), so
    the noise is the largest of the narrow candidates' (up to ``TUNING.noise_levels`` doublings: wider
    ones' residuals hold their bias, which on thin parts would widen the kernel further).
    """

    def __init__(self, fits, ladder: list, sizes: list, at: np.ndarray, base, window: int, workers: int):
        self.fits, self.ladder, self.level_sizes, self.at = fits, ladder, sizes, at
        self.window, self.workers = window, workers
        q = at.shape[0]
        self.noise = _window_medians(base.sigma, _windows(at, at, window, workers), q)
        self.means, self.factors, self.sizes = [base.mean], [base.factor], [q]
        self.sds: list = []
        self.sigmas = [np.asarray(base.sigma)]  # each evaluated candidate's residual at its centres
        self.residuals = [float(np.median(base.sigma))]
        self.growing = True  # the residual still grows like noise being uncovered, not like bias

    def evaluate(self, j: int) -> None:
        """Fit candidate ``j`` at its centres; while its residual grows like noise, raise ``noise`` to it."""
        size = self.level_sizes[j]
        fit = self.fits(self.ladder[j], size)
        self.means.append(fit.mean)
        self.factors.append(fit.factor)
        self.sizes.append(size)
        self.sigmas.append(np.asarray(fit.sigma))
        residual = float(np.median(fit.sigma))
        if j <= TUNING.noise_levels and self.growing and residual < TUNING.noise_growth * self.residuals[-1]:
            mine = self.at[:size]
            q = self.at.shape[0]
            own_windows = _windows(mine, mine, max(MIN_WINDOW, self.window * size // q), self.workers)
            own = _window_medians(fit.sigma, own_windows, size)
            self.noise[:size] = np.maximum(self.noise[:size], own)
            self.sds.clear()  # the standard deviations follow the noise
        else:
            self.growing = False
        self.residuals.append(residual)
        self.complete_sds()

    def complete_sds(self) -> None:
        """Each evaluated candidate's standard deviation at its centres: the noise times its factor."""
        while len(self.sds) < len(self.means):
            i = len(self.sds)
            self.sds.append(self.noise[: self.sizes[i]] * self.factors[i])

    def changes(self, j: int) -> list:
        """Per centre of candidate ``j``, the change from each narrower one in that one's standard deviations."""
        size, tiny = self.sizes[j], np.finfo(float).tiny
        return [np.abs(self.means[j] - self.means[i][:size]) / np.maximum(self.sds[i][:size], tiny)
                for i in range(j)]


#: Doublings of the narrowest kernel :func:`residual_rise` compares it with.
RISE_LEVELS = 2


def residual_rise(ladder_fits: _LadderFits) -> tuple[float, float]:
    """How the denoised residual grows from the narrowest candidate to candidate :data:`RISE_LEVELS`.

    Noise leaves about the same residual at every width; a model's misfit (a
    coarse mesh's facets, a surface curving within the ball) grows as ``R^2``,
    about 4 over two doublings of the neighbours. The candidate is fitted here
    when Lepski's rule stopped short of it (at the same centres as the rule's
    fits: a tiled run's survey holds it).

    Returns
    -------
    rise : float
        The wider candidate's median residual over the narrowest's (NaN without it).
    quiet_rise : float
        The same of the residuals' 10th percentiles over the wider candidate's centres: the quietest
        centres, away from edges and detail. Where a wide ball reaches a sharp edge at most centres
        (a CAD part), the median rises with the edges' misfit while the quietest centres' residual
        is still the noise; where it is the surface's own misfit (a coarse mesh), it rises there too.
    """
    if len(ladder_fits.ladder) <= RISE_LEVELS:
        return float("nan"), float("nan")
    if len(ladder_fits.sigmas) > RISE_LEVELS:
        wide = ladder_fits.sigmas[RISE_LEVELS]
    else:
        size = ladder_fits.level_sizes[RISE_LEVELS]
        wide = np.asarray(ladder_fits.fits(ladder_fits.ladder[RISE_LEVELS], size).sigma)
    tiny = np.finfo(float).tiny
    narrow = ladder_fits.sigmas[0]
    rise = float(np.median(wide)) / max(ladder_fits.residuals[0], tiny)
    quiet = float(np.percentile(wide, 10)) / max(float(np.percentile(narrow[: wide.shape[0]], 10)), tiny)
    return rise, quiet


def _noise_regions(noise: np.ndarray) -> np.ndarray:
    """Step 1: the centres binned by their local ``noise``, one bin per doubling of the best ``k``, shape (q,).

    Optimal widths balance a bias growing as ``R^2`` against a standard deviation falling as ``sigma / R^3``,
    so ``k ~ R^2 ~ sigma^(2/5)``: a bin is a factor of about 2.4 in noise. A region of its own noise must be a
    sizeable part of the cloud (``TUNING.min_region``): a few per cent of "noisier" centres are vegetation,
    edges or stray parts, which the fit must not widen for (their residual is what flags them), so small
    bins join the largest.
    """
    tiny = np.finfo(float).tiny
    reference = float(np.median(noise))
    noise_bin = np.round(0.4 * np.log2(np.maximum(noise, tiny) / max(reference, tiny))).astype(np.int64)
    labels, counts = np.unique(noise_bin, return_counts=True)
    small = labels[counts < TUNING.min_region * noise.shape[0]]
    noise_bin[np.isin(noise_bin, small)] = labels[np.argmax(counts)]
    return noise_bin


def _lepski(ladder_fits: _LadderFits, noise_bin: np.ndarray, tau: float) -> np.ndarray:
    """Step 2, Lepski's rule in each noise region: per centre, the index of the widest candidate whose median
    change (over the region's centres) from every narrower one is within ``tau`` of that one's standard
    deviation; shape (q,)."""
    chosen = np.zeros(noise_bin.shape[0], dtype=np.int64)
    open_bins = set(np.unique(noise_bin).tolist())
    for j in range(1, len(ladder_fits.ladder)):
        if j >= len(ladder_fits.means):
            ladder_fits.evaluate(j)
        size = ladder_fits.sizes[j]
        changes = ladder_fits.changes(j)  # (once per candidate: the same for every region)
        for b in sorted(open_bins):
            members = noise_bin[:size] == b
            if members.sum() < MIN_WINDOW:  # too few centres left at this width: stop widening
                open_bins.discard(b)
                continue
            if all(np.median(c[members]) <= tau for c in changes):
                chosen[noise_bin == b] = j
            else:
                open_bins.discard(b)
        if not open_bins:
            break
    return chosen


def _local_guard(ladder_fits: _LadderFits, window: int, workers: int) -> np.ndarray:
    """Step 3: per centre, the index of the widest evaluated candidate whose change from no narrower one is
    clearly bias there (its median over the centre's window above ``TUNING.tau_local`` standard deviations);
    shape (q,)."""
    at = ladder_fits.at
    q = at.shape[0]
    guarded = np.full(q, len(ladder_fits.means) - 1)
    for j in range(1, len(ladder_fits.means)):
        size = ladder_fits.sizes[j]
        windows = _windows(at[:size], at, max(MIN_WINDOW, window * size // q), workers)
        biased = np.zeros(q, dtype=bool)
        for change in ladder_fits.changes(j):
            biased |= _window_medians(change, windows, q) > TUNING.tau_local
        guarded = np.where(biased & (guarded >= j), j - 1, guarded)
    return guarded
