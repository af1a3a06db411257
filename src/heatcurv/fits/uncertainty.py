"""Standard errors of the default estimator's curvatures and normals: noise, bias and carry.

Each standard error is the root of the value's estimated mean square error, the sum of:

* **noise**: the fit is a weighted least-squares fit (:mod:`heatcurv.fits.chordfit`), so
  independent height noise of standard deviation ``sigma`` reaches each fitted
  coefficient through the sandwich covariance ``sigma^2 G^-1 G2 G^-1``;
  :attr:`heatcurv.fits.chordfit.ChordFit.noise_factors` carries it to the mean, principal
  and Gaussian curvatures and the normal, and ``sigma`` is the fit's own estimate of the
  noise (:attr:`heatcurv.fits.chordfit.ChordFit.noise`). Beyond first order, a noisy
  umbilic point's curvatures split (:func:`_eigenvalue_spread`), and the noise moves the
  point along the surface, which turns the true normal at it by ``sigma k``. The kernel's
  weights, on the noisy distance, flatten the fitted curvatures by about
  ``TUNING.flattening_bias (sigma / R)^2`` of their value (``R`` the fit's ball radius;
  :func:`heatcurv.flags.reliability.flattened`); its sign depends on the shape (negative on a
  sphere, positive on a cylinder), so it is counted as an error of that size. On a cloud
  the kernel choice calls clean (the chord fit) the residual is the model's misfit, not
  noise, and this part is left out: the two below measure that error instead.
* **bias**: a kernel of ``k`` neighbours bends the fit away from the surface by an
  amount growing as the ball's area, ``R^2 ~ k`` (:mod:`heatcurv.choice.scale`). At
  sample centres (:func:`bias_centres`) the same fit is run at ``k`` and at ``2 k``
  neighbours; the change ``f_2k - f_k`` is then about the bias of ``f_k`` itself, plus
  noise of variance ``Var(f_k) - Var(f_2k)`` (nested fits). Its square, averaged over
  the :data:`WINDOW` centres nearest a centre and less that noise variance, is the
  squared bias of the points nearest that centre: a regional estimate, as the bias
  field is smooth on the scale of the ball. A region ends where the fit's residual
  changes: the average weighs each centre by how close its residual is to the centre's
  own (:data:`RESIDUAL_WIDTH`), and so does the blend to the points, so that the
  changes of the balls that reach a sharp edge, a tree or noisier ground are not
  spread onto the smooth surface beside them, whose residual is the noise alone.
* **carry**: the values a point was given against the fit at ``k`` centred at the
  centre itself, averaged the same way: the error of carrying the anchors' fits to the
  points (:mod:`heatcurv.fits.anchors`), and on clean clouds the last tilt correction the
  reported normal leaves out.

The rounding of the input coordinates (float32, a LAS file's grid) is noise of known size: a
noisy fit's residual holds it, a clean one's is given it through the noise factors.

Everything is local, so a part of a cloud computes the whole cloud's standard errors where it
holds a point's surroundings (:mod:`heatcurv.tiles`): each point draws itself as a centre by its
own key, and :attr:`StandardErrors.reach` says how far its errors depend on other points.

The standard errors are regional where the bias dominates: a value whose error is a
smooth field (clean clouds, wide kernels) is within two standard errors more often than
the 95 % of independent Gaussian errors (docs/accuracy.md, error bars).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.sampling import key_thinning
from ..tuning import TUNING
from .balls import Scale, fit_blocks
from .chordfit import NOISE_FIELDS, ChordFit

__all__ = ["RESIDUAL_WIDTH", "StandardErrors", "WINDOW", "standard_errors", "bias_centres"]

#: Sample centres whose squared changes are averaged into each point's bias.
WINDOW = 16
#: Pairs the refits at ``k`` and ``2 k`` may take, per point of the cloud: a share ``PAIRS_PER_POINT / (3 k)``
#: of the points are centres ...
PAIRS_PER_POINT = 8
#: ... at least this many over the whole cloud, and at most one point in :data:`MAX_CENTRE_SHARE`.
MIN_CENTRES = 200
MAX_CENTRE_SHARE = 16
#: Nearest centres whose estimates each point blends.
BLENDED = 4
#: Width of the residual similarity, in natural log units: a centre whose fit residual is ``e^0.2``
#: (1.22) times another's weighs ``e^-0.5`` in its window and blend. About twice the sampling
#: spread of a residual over 60 neighbours (``1 / sqrt(120)``); measured on the error-bar benchmark
#: (docs/accuracy.md), widths 0.1-0.35 against none.
RESIDUAL_WIDTH = 0.2
#: Floating-point floor of a curvature's standard error, relative to the point's largest ``|k1|, |k2|``:
#: the chord fit solves normal equations whose condition number reaches 1e6-1e7, so even exact data
#: (a sphere, where the fit is exact) leaves errors of 2e-10 - 6e-10 (median) of the curvature in float64 ...
ROUNDING = 1e-9
#: ... plus this much of the ball's ``1 / R``, so that an exact plane's bars (its errors are exactly 0)
#: are not 0 either: 6x below the sphere's rounding on that scale (6e-11 / R).
ROUNDING_FLAT = 1e-11


@dataclass(frozen=True)
class StandardErrors:
    """One standard error per point and field, in the cloud's units (the stage's order of points).

    Attributes
    ----------
    mean, k1, k2, gaussian : ndarray, shape (m,)
        1 / length (``gaussian``: 1 / length^2).
    normal : ndarray, shape (m,)
        Radians.
    reach : ndarray, shape (m,)
        How far each point's standard errors reach: no point farther changes them (its values'
        reach, then the centres its estimate is blended from, their windows and their refits'
        balls), length units; infinite where no centre was drawn.
    """

    mean: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    gaussian: np.ndarray
    normal: np.ndarray
    reach: np.ndarray


def bias_centres(k: np.ndarray, keys: np.ndarray, cloud_points: int, seed: int = 0) -> np.ndarray:
    """The sample centres of the bias estimate: the points whose key is below their share of centres.

    A point of kernel ``k`` is a centre with probability ``PAIRS_PER_POINT / (3 k)`` (the refits at
    ``k`` and ``2 k`` then take about :data:`PAIRS_PER_POINT` pairs per point), at least
    ``MIN_CENTRES / cloud_points`` and at most ``1 / MAX_CENTRE_SHARE``. The draw is local
    (:func:`heatcurv.geometry.sampling.key_thinning`): a part of the cloud holding a point and its
    surroundings draws the same centres there as the whole cloud.

    Parameters
    ----------
    k : ndarray, shape (n,)
        Each point's kernel (neighbours).
    keys : ndarray, shape (n,)
        Sampling keys (:func:`heatcurv.geometry.sampling.geometric_keys`).
    cloud_points : int
        Points of the whole cloud (:attr:`heatcurv.choice.choices.CloudFrame.n_points`).
    seed : int, optional
        Shifts the keys (:func:`heatcurv.geometry.sampling.key_thinning`).

    Returns
    -------
    ndarray of int
        Sorted point indices.
    """
    k = np.maximum(np.asarray(k, dtype=np.float64), 1.0)
    share = np.maximum(MIN_CENTRES / max(cloud_points, 1), np.minimum(PAIRS_PER_POINT / (3.0 * k),
                                                                      1.0 / MAX_CENTRE_SHARE))
    return key_thinning(keys, share, seed)


def _scale_changes(points, tree, normals, areas, centres, k, denoise: bool, low_noise: bool, alpha: float,
                   workers: int):
    """At ``centres`` of kernel ``k``: the change of each field from ``k`` to ``2 k`` neighbours, and its noise.

    Returns ``change`` and ``noise``, shape (c, 5) each, columns :data:`NOISE_FIELDS`: ``f_2k - f_k``
    (the normal's angle between the two fits) scaled to the bias of ``f_k`` (bias ~ k), and the
    variance its noise adds, ``Var(f_k) - Var(f_2k)`` scaled alike; the fit at ``k`` (a :class:`ChordFit`);
    and the radius of the ball at ``2 k``, shape (c,).
    """
    wide = int(min(2 * k, points.shape[0] - 1))
    fits, radius = [], np.zeros(len(centres))
    for size in (k, wide):
        blocks = []
        for lo, hi, nbhd, fit in fit_blocks(points, tree, normals, areas, Scale(int(size), denoise), centres=centres,
                                            alpha=alpha, workers=workers, low_noise=low_noise):
            blocks.append(fit)
            radius[lo:hi] = np.maximum(radius[lo:hi], nbhd.radius)
        fits.append(ChordFit.concatenate(blocks))
    gain = k / max(wide - k, 1)
    narrow, broad = fits
    pc = broad.principal
    change = _differences(np.column_stack([pc.mean, pc.k1, pc.k2, pc.gaussian]), broad.normals, narrow)
    noise = _noise_variance(narrow) - _noise_variance(broad)
    return gain * change, gain**2 * np.maximum(noise, 0.0), narrow, radius


def _eigenvalue_spread(variance: np.ndarray, split: np.ndarray) -> np.ndarray:
    """The principal curvatures' mean square error beyond the first order, shape (m,).

    ``k1, k2 = H +- rho`` with ``rho = |(B - H I)|``: noise of variance ``s^2`` in each of the two
    components of ``B - H I`` makes ``E[rho_hat^2] = rho^2 + 2 s^2`` (a noisy umbilic point splits
    its curvatures), so the error of ``rho_hat`` has mean square ``s^2`` far from an umbilic (the
    first-order variance) and ``2 s^2`` at one. The extra ``s^2 * s^2 / (s^2 + rho^2)``, with
    ``rho^2`` estimated as ``max(rho_hat^2 - 2 s^2, 0)`` and ``s^2`` as the principal curvatures'
    mean first-order variance less the mean curvature's, bridges the two.
    """
    s2 = np.maximum(0.5 * (variance[:, 1] + variance[:, 2]) - variance[:, 0], 0.0)
    rho2 = np.maximum((0.5 * split) ** 2 - 2.0 * s2, 0.0)
    return np.divide(s2 * s2, s2 + rho2, out=np.zeros_like(s2), where=s2 + rho2 > 0)


def _noise_variance(fit: ChordFit) -> np.ndarray:
    """Each field's noise variance of a fit, ``noise^2 * noise_factors``, shape (c, 5)."""
    return fit.noise[:, None] ** 2 * np.maximum(fit.noise_factors, 0.0)


def standard_errors(points: np.ndarray, tree: cKDTree, areas: np.ndarray, normals: np.ndarray, values: np.ndarray,
                    k: np.ndarray, radius: np.ndarray, keys: np.ndarray, reach: np.ndarray, *, cloud_points: int,
                    denoise: bool, noise: np.ndarray,
                    noise_factors: np.ndarray, residual: np.ndarray, rounding: np.ndarray | None = None,
                    low_noise: bool = False, alpha: float = 2.0, seed: int = 0,
                    workers: int = -1) -> StandardErrors:
    """Stage ``standard_errors``: each point's standard errors (module docstring).

    Parameters
    ----------
    points : ndarray, shape (m, 3)
        Distinct, centred points (operator order).
    tree : scipy.spatial.cKDTree
        Over ``points``.
    areas : ndarray, shape (m,)
        The areas of the fit weights (0: no weight).
    normals : ndarray, shape (m, 3)
        The fitted, oriented normals.
    values : ndarray, shape (m, 4)
        The fitted ``mean``, ``k1``, ``k2`` and ``gaussian``.
    k : ndarray of int, shape (m,)
        Each point's kernel (neighbours).
    radius : ndarray, shape (m,)
        Each point's fit ball radius (the float64 floor's scale on flat parts).
    keys : ndarray, shape (m,)
        Sampling keys of the centres.
    reach : ndarray, shape (m,)
        How far each point's values, normal and residual reach (no point farther changes them).
    cloud_points : int
        Points of the whole cloud, of which ``points`` may be a part (:func:`bias_centres`).
    denoise : bool
        The fit's form: denoised heights (noisy clouds) or chord curvatures (clean).
    noise : ndarray, shape (m,)
        The fit's noise estimate at each point (:attr:`heatcurv.fits.chordfit.ChordFit.noise`), length units.
    noise_factors : ndarray, shape (m, 5)
        :attr:`heatcurv.fits.chordfit.ChordFit.noise_factors` of each point's fit.
    residual : ndarray, shape (m,)
        The fit's residual at each point (root mean square height misfit, length units): where
        it changes, a region of the bias estimate ends.
    rounding : ndarray, shape (m,), optional
        Variance of each point's height under the rounding of the input coordinates
        (:func:`heatcurv.flags.reliability.rounding_height_variance`), length^2; None: exact coordinates.
        It is noise the clean fit's residual does not measure; a denoised fit's noise estimate holds it.
    low_noise : bool, optional
        With ``denoise``: the fit's low-noise refit (very low noise; :func:`heatcurv.fits.chordfit.chord_fit`),
        whose bias the changes then measure.
    alpha, seed, workers : optional
        The fit's ball-to-kernel ratio, the centres' draw, threads.

    Returns
    -------
    StandardErrors
    """
    n = points.shape[0]
    # a point without a fit (an outlier's island: no weighted neighbour) has no error to estimate and
    # is no centre: its standard errors are infinite
    fitted = np.isfinite(noise) & np.all(np.isfinite(noise_factors), axis=1) & (areas > 0)
    centres = bias_centres(k, keys, cloud_points, seed)
    centres = centres[fitted[centres]]
    if centres.size == 0:  # no estimate (and no bound on what one would need)
        return StandardErrors(*(np.full(n, np.inf) for _ in range(5)), reach=np.full(n, np.inf))
    change, change_noise, own = (np.zeros((centres.shape[0], 5)) for _ in range(3))
    centre_reach = np.asarray(reach, dtype=np.float64)[centres]
    for size in np.unique(k[centres]):
        rows = np.flatnonzero(k[centres] == size)
        at = centres[rows]
        change[rows], change_noise[rows], narrow, wide = _scale_changes(points, tree, normals[at], areas, at,
                                                                        int(size), denoise, low_noise, alpha, workers)
        # the values given against the fit at k centred at the centre itself: the carry's own error
        # (fits at anchors), or the last tilt the fit's normal leaves out (fits at every point)
        own[rows] = _differences(values[at], normals[at], narrow)
        centre_reach[rows] = np.maximum(centre_reach[rows], wide)
    # each centre's window of its nearest centres; each point blends those of its nearest centres
    tree_c = cKDTree(points[centres])
    window = min(WINDOW, centres.shape[0])
    distance, near = (a.reshape(-1, window) for a in tree_c.query(points[centres], window, workers=workers))
    # what a centre's window estimate depends on: its centres' refits, values and residuals
    window_reach = np.max(distance + centre_reach[near], axis=1)
    # (a residual that is not finite, or 0, matches no other)
    level = np.log(np.maximum(np.where(np.isfinite(residual), residual, 0.0), np.finfo(float).tiny))
    # each window's centres weighed by how near their residual is to its own
    alike = _similarity(level[centres][near], level[centres][:, None])
    carry = _window_mean(own**2, near, alike)
    squared = _window_mean(change**2, near, alike)
    if not denoise:  # a clean cloud's residual is misfit, not noise: the changes measure the whole error
        total, blend_reach = _blend(tree_c, points, squared + carry, level, level[centres], window_reach, workers)
        if rounding is not None:  # ... but for the rounding of the coordinates, which is noise of known size
            total += rounding[:, None] * np.maximum(noise_factors, 0.0)
        return _with_rounding(total, values, radius, fitted, np.maximum(reach, blend_reach))
    variance = noise[:, None] ** 2 * np.maximum(noise_factors, 0.0)
    variance[:, 1:3] += _eigenvalue_spread(variance, values[:, 1] - values[:, 2])[:, None]
    # the noise moves the point itself along the surface too (isotropic noise): the true normal at
    # its measured position turns by sigma k along each principal direction
    variance[:, 4] += noise**2 * (values[:, 1] ** 2 + values[:, 2] ** 2)
    # the noise's flattening, a share of each curvature (twice it of K = k1 k2)
    flattening = TUNING.flattening_bias * (noise / radius) ** 2
    variance[:, :3] += (flattening[:, None] * values[:, :3]) ** 2
    variance[:, 3] += (2.0 * flattening * values[:, 3]) ** 2
    bias2 = np.maximum(squared - _window_mean(change_noise, near, alike), 0.0)
    blended, blend_reach = _blend(tree_c, points, bias2 + carry, level, level[centres], window_reach, workers)
    return _with_rounding(variance + blended, values, radius, fitted, np.maximum(reach, blend_reach))


def _similarity(level: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Weight of residuals of log ``level`` beside log ``reference`` (broadcast): a Gaussian of width
    :data:`RESIDUAL_WIDTH`, at least 1e-12 so that a lone centre still counts."""
    return np.exp(-0.5 * ((level - reference) / RESIDUAL_WIDTH) ** 2) + 1e-12


def _blend(tree: cKDTree, points: np.ndarray, values: np.ndarray, level: np.ndarray, level_centres: np.ndarray,
           centre_reach: np.ndarray, workers: int) -> tuple[np.ndarray, np.ndarray]:
    """``values`` at the centres (shape (c, 5)) at every point (shape (m, 5)): its :data:`BLENDED` nearest centres'
    with inverse-square-distance weights (the nearest centre's alone draws the centres' cells on a smooth field),
    times the similarity of the centre's log residual ``level_centres`` (shape (c,)) to the point's ``level``
    (shape (m,)). Also how far each point's blend reaches, given each centre's ``centre_reach`` (shape (m,))."""
    count = min(BLENDED, tree.n)
    distance, index = tree.query(points, count, workers=workers)
    distance, index = distance.reshape(len(points), count), index.reshape(len(points), count)
    weight = 1.0 / np.maximum(distance, 1e-12 * max(float(distance.max()), 1e-300)) ** 2
    weight *= _similarity(level_centres[index], level[:, None])
    weight /= weight.sum(axis=1, keepdims=True)
    out = np.zeros((len(points), values.shape[1]))
    for column in range(count):  # one (m, 5) gather at a time
        out += weight[:, column, None] * values[index[:, column]]
    return out, np.max(distance + centre_reach[index], axis=1)


def _window_mean(values: np.ndarray, near: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Each window's weighted mean of ``values`` (shape (c, 5)) over its centres ``near`` (shape (c, w)) with
    ``weights`` (shape (c, w)), NaNs left out.

    A refit that failed at a centre (no weighted pairs in its ball) gives NaN; a window of
    nothing else gives infinity: no estimate.
    """
    gathered = values[near]
    finite = np.isfinite(gathered)
    weight = weights[:, :, None] * finite
    count = weight.sum(axis=1)
    total = (np.where(finite, gathered, 0.0) * weight).sum(axis=1)
    return np.divide(total, count, out=np.full(total.shape, np.inf), where=count > 0)


def _with_rounding(total: np.ndarray, values: np.ndarray, radius: np.ndarray,
                   fitted: np.ndarray, reach: np.ndarray) -> StandardErrors:
    """The standard errors from the mean square errors ``total`` (shape (m, 5)), at least the float64 floor,
    reaching ``reach`` (shape (m,)).

    Points without a fit (``fitted`` False) get infinity.
    """
    largest = np.maximum(np.abs(values[:, 1]), np.abs(values[:, 2]))
    curvature = ROUNDING * largest + ROUNDING_FLAT / radius
    floor = np.stack([curvature, curvature, curvature, 2.0 * largest * curvature], axis=1)  # K = k1 k2
    with np.errstate(invalid="ignore"):
        root = np.sqrt(total)
    root[:, :4] = np.maximum(root[:, :4], floor)
    root[~fitted] = np.inf
    root[np.isnan(root)] = np.inf
    return StandardErrors(*(root[:, column] for column in range(5)), reach=reach)


def _differences(values: np.ndarray, normals: np.ndarray, fit: ChordFit) -> np.ndarray:
    """``values`` (shape (c, 4)) less the fit's mean, k1, k2 and K, and the angle between the normals, shape (c, 5)."""
    out = np.empty((values.shape[0], 5))
    for column, name in enumerate(NOISE_FIELDS[:4]):
        out[:, column] = values[:, column] - getattr(fit.principal, name)
    out[:, 4] = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", normals, fit.normals)), 0.0, 1.0))
    return out
