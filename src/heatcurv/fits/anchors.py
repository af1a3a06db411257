"""Wide kernels at flat cost: fit at anchors with every point of the ball, carry the fits to all points.

Under noise the default fit (:mod:`heatcurv.fits.chordfit`) needs kernels of hundreds
to tens of thousands of neighbours (:mod:`heatcurv.choice.scale`). Fitting every point
with all of them costs ``k`` pairs per point; fitting against a thinned level of
the cloud keeps the cost but throws away the averaging the wide kernel is for.

A wide kernel only resolves the curvature field at its own scale, so it need not
be fitted at every point. Here it is fitted, with *all* ``k`` neighbours of the
ball, at **anchors**: a subset of the points with about ``TUNING.anchors_per_ball``
anchors in each ball (a point is an anchor when its sampling key is below
``TUNING.anchors_per_ball / k``, so the anchors of a wider kernel are sparser and the
pair work stays about ``TUNING.anchors_per_ball`` pairs per point whatever ``k``).
Every point then takes its :data:`CARRIED_ANCHORS` nearest anchors and carries
their fitted models to itself (:mod:`heatcurv._kernels.anchors`): each anchor's
model (tensor, tilt, cubic and, under very low noise, quartic terms) describes a
surface, and the carry gives that surface's normal and curvature tensor *at the
point's offset*, exactly (so exact on circles and spheres, and to every order
the model has; a noisy model, ``sigma`` at least ``TUNING.exact_carry_sigma`` ball
radii, to first order in the offset); the point's values are their smooth
weighted mean. The anchor
spacing is about ``R / 2``, well inside the ball where an anchor's model is
fitted.

A model fitted over a wide ball is less accurate away from its centre than at
it. Under ordinary noise the fit's own variance hides that; under very low noise
(``relative_noise`` from ``TUNING.no_noise`` to below
``TUNING.low_noise``, e.g. a LAZ file's millimetres, where the kernel
choice widened the kernel: :attr:`heatcurv.choice.scale.ScaleChoice.low_noise`) it
would dominate (a torus at 1e-5 of its diagonal, 480
neighbours: the nearest anchor's model is 0.12 % off in the mean curvature within
0.1 R of it, 0.5 % at 0.3-0.4 R), so there the anchors are 1.5x denser
(:func:`anchors_per_ball`) and each point's tensor is a weighted cubic regression
of its :data:`REGRESSED_ANCHORS` nearest anchors' *own* tensors, at their centres
(:func:`carry_degree`): it reproduces any cubic variation of the curvature field.
Its accuracy, on and off, is in docs/accuracy.md (very low noise).

Every value of a point depends only on the points within its **support
radius** ``max_a (|p - a| + R_a)`` over the anchors it uses, the regression's
included (a few ball radii with the regression, about one without it; docs/how_it_works.md,
thresholds): the halo a tiled run needs, per point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .._kernels import anchors as kernels
from ..backend import map_blocks
from ..fits.balls import Scale, fit_balls
from ..flags.border import centroid_offset
from ..geometry.neighbourhood import Neighbourhood, block_ranges, knn_neighbourhood, rows_per_block
from ..geometry.sampling import key_sample, key_thinning
from ..operators.areas import density_areas
from ..operators.kernel import tapered_heat_weights
from ..orient.normals import pca_normals, tangent_frames
from ..orient.orientation import Orientation, orient
from ..tuning import TUNING
from .chordfit import ChordFit
from .principal import PrincipalCurvatures, tensor_to_principal

__all__ = [
    "CARRIED_ANCHORS", "PCA_NEIGHBOURS", "REGRESSED_ANCHORS", "AnchorFits", "CarriedFit", "anchor_normals",
    "anchor_rows", "anchors_per_ball", "ball_roundness", "carry_degree", "carry_fits", "fit_anchors",
]

#: Anchors each point's values are carried from (the farthest gets weight 0).
CARRIED_ANCHORS = 8
#: Points carried at a time (:func:`carry_fits`): their anchor lists are held at once.
CARRY_BLOCK = 262_144
#: Anchors whose own tensors are regressed at each point under very low noise (:func:`carry_degree`).
REGRESSED_ANCHORS = 24
#: Most neighbours of an anchor's PCA normal (:func:`anchor_normals`): enough to average noise
#: of several spacings (a 480-point ball is 12 spacings wide), cheap beside the fit.
PCA_NEIGHBOURS = 480
#: Anchors per anchor in the orientation's graph over the anchors.
ANCHOR_GRAPH = 12


@dataclass(frozen=True)
class AnchorFits:
    """The chord fits at the anchors.

    Attributes
    ----------
    index : ndarray of int, shape (m,)
        The anchors' rows in the cloud, increasing.
    k : ndarray of int, shape (m,)
        Neighbours in each anchor's ball.
    fit : ChordFit
        The fits (with ``coefficients``), one row per anchor.
    radius : ndarray, shape (m,)
        Ball radii ``R_a``.
    offset : ndarray, shape (m,)
        Tangential centroid offset of each ball in ball radii (:func:`heatcurv.flags.border.centroid_offset`).
    density_area : ndarray, shape (m,)
        Area per point at the anchor, from its ball's count (:func:`heatcurv.operators.areas.density_areas`).
    roundness : ndarray, shape (m,)
        ``lambda_0 / lambda_1`` of each ball's plain covariance (:func:`ball_roundness`).
    """

    index: np.ndarray
    k: np.ndarray
    fit: ChordFit
    radius: np.ndarray
    offset: np.ndarray
    density_area: np.ndarray
    roundness: np.ndarray


@dataclass(frozen=True)
class CarriedFit:
    """The anchors' fits carried to every point.

    Attributes
    ----------
    normals : ndarray, shape (n, 3)
        Unit normals.
    principal : PrincipalCurvatures
        ``well_posed`` is False where no usable anchor reached the point.
    sigma, offset, radius, density_area, roundness : ndarray, shape (n,)
        The anchors' residual (the most-weighted anchor's: averaged, a tree
        crown's residuals were diluted by the ground's around it), centroid
        offset, ball radius, area per point and ball roundness (weighted as the curvatures).
    noise : ndarray, shape (n,)
        The anchors' noise estimate (:attr:`heatcurv.fits.chordfit.ChordFit.noise`), weighted as the curvatures.
    noise_factors : ndarray, shape (n, 5)
        The anchors' :attr:`heatcurv.fits.chordfit.ChordFit.noise_factors`, weighted as the curvatures.
    support : ndarray, shape (n,)
        Support radius: no point farther than this from a point changes its values.
    nearest : ndarray of int, shape (n,)
        Each point's nearest anchor (position in ``AnchorFits.index``).
    """

    normals: np.ndarray
    principal: PrincipalCurvatures
    sigma: np.ndarray
    offset: np.ndarray
    radius: np.ndarray
    density_area: np.ndarray
    roundness: np.ndarray
    noise: np.ndarray
    noise_factors: np.ndarray
    support: np.ndarray
    nearest: np.ndarray

    @property
    def mean_variance_factor(self) -> np.ndarray:
        """``Var(kappa_M) / sigma^2``, shape (n,): the first column of :attr:`noise_factors`."""
        return self.noise_factors[:, 0]


def anchors_per_ball(low_noise: bool) -> int:
    """Anchors per ball for a cloud's noise: denser where the noise no longer hides the carry's error.

    The carried values are exact on the anchors' model surfaces (:mod:`heatcurv._kernels.anchors`), but
    a model fitted over a wide ball is less accurate away from its centre: on a torus with noise 1e-5
    of the diagonal (480 neighbours, 20 000 points) the nearest anchor's model is off by 0.12 % in the
    mean curvature within 0.1 R of it and 0.5 % at 0.3-0.4 R. Under ordinary noise the fit's own
    variance hides that; under very low noise (a LAZ file's millimetres) it would dominate, so the anchors
    are denser there (``TUNING.low_noise_anchors_per_ball``).

    Parameters
    ----------
    low_noise : bool
        The kernel choice's ``low_noise`` (:class:`heatcurv.choice.scale.ScaleChoice`: the cloud is in the
        very-low-noise band and its kernel wider than the narrowest).

    Returns
    -------
    int
        ``TUNING.low_noise_anchors_per_ball`` under very low noise, else ``TUNING.anchors_per_ball``.
    """
    return TUNING.low_noise_anchors_per_ball if low_noise else TUNING.anchors_per_ball


def carry_degree(low_noise: bool) -> int:
    """Degree of the regression of the anchors' own tensors (:func:`carry_fits`) for a cloud's noise.

    Even exact on its model surface, an anchor's model is less accurate away from its centre than
    at it (:func:`anchors_per_ball`). Under very low noise the anchors' own tensors, at their
    centres, are the better data: a weighted cubic regression of them over the
    :data:`REGRESSED_ANCHORS` nearest anchors reproduces any cubic variation of the curvature
    field, where a mean of carried models keeps the models' error. Under ordinary noise the
    mean's smoothing is worth more (and the anchors stay ``TUNING.anchors_per_ball`` per ball,
    too sparse to regress).

    Parameters
    ----------
    low_noise : bool
        The kernel choice's ``low_noise`` (:func:`anchors_per_ball`).

    Returns
    -------
    int
        ``TUNING.regression_degree`` under very low noise, else 0 (the weighted mean).
    """
    return TUNING.regression_degree if low_noise else 0


def anchor_rows(keys: np.ndarray, k: np.ndarray, seed: int = 0, per_ball: int = TUNING.anchors_per_ball) -> np.ndarray:
    """The anchors of kernels of ``k`` neighbours: about ``per_ball`` in each ball.

    Parameters
    ----------
    keys : ndarray, shape (n,)
        Sampling keys (:func:`heatcurv.geometry.sampling.geometric_keys`).
    k : ndarray of int, shape (n,)
        Each point's kernel width, in neighbours.
    seed : int, optional
        Shifts the keys (:func:`heatcurv.geometry.sampling.key_thinning`).
    per_ball : int, optional

    Returns
    -------
    ndarray of int, shape (m,)
        Increasing rows; every point is an anchor where ``k <= TUNING.every_point * per_ball``, and
        at least ``min(n, per_ball)`` when the draw finds fewer than two (keys crowded into a narrow
        band, as on a few tight clusters far apart: the points with the smallest keys).
    """
    k = np.asarray(k, dtype=np.float64)
    fraction = np.where(k <= TUNING.every_point * per_ball, 1.0, per_ball / k)
    rows = key_thinning(keys, fraction, seed)
    return rows if rows.size >= 2 else key_sample(keys, min(keys.shape[0], per_ball), seed)


def anchor_normals(
    points: np.ndarray,
    tree: cKDTree,
    index: np.ndarray,
    k: np.ndarray,
    areas: np.ndarray,
    *,
    mode: str,
    towards=None,
    excluded: np.ndarray | None = None,
    alpha: float = 2.0,
    workers: int = -1,
    open_up: bool = False,
) -> Orientation:
    """The anchors' own normals, oriented over a graph of the anchors: for noise that swamps the small balls.

    When the noise is a sizeable fraction of the operator's ball (``sigma > R / 4``),
    PCA normals of those balls are tilted by tens of degrees and their
    orientation, propagated point to point, breaks apart (a million-point torus
    with noise 6 spacings thick: 44 % of the normals inward). Each anchor's
    normal is then the heat-weighted PCA normal of its own ball (at most
    :data:`PCA_NEIGHBOURS` neighbours), and the orientation
    (:func:`heatcurv.orient.orientation.orient`) runs over the anchors.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    tree : scipy.spatial.cKDTree
        Tree on ``points``.
    index : ndarray of int, shape (m,)
        The anchors.
    k : ndarray of int, shape (m,)
        Each anchor's kernel width.
    areas : ndarray, shape (n,)
        Weights of the points in the covariances (0 for outliers).
    mode, towards : optional
        The orientation policy, as :func:`heatcurv.orient.orientation.orient`
        (``towards``: shape (3,), or one position per point, shape (n, 3)).
    excluded : ndarray of bool, shape (n,), optional
        Points no anchor stands for (outliers).
    alpha : float, optional
        Ball radius in heat-kernel spacings.
    workers : int, optional
    open_up : bool, optional
        ``"outward"`` chosen by ``orient="auto"``: as :func:`heatcurv.orient.orientation.orient`.

    Returns
    -------
    Orientation
        Of the anchors (shape (m, ...)).
    """
    index, k = np.asarray(index), np.asarray(k)
    m = index.shape[0]
    normals = np.empty((m, 3))
    width = np.minimum(k, min(PCA_NEIGHBOURS, points.shape[0] - 1))
    for value in np.unique(width):
        group = np.flatnonzero(width == value)
        for lo, hi in block_ranges(group.shape[0], rows_per_block(int(value))):
            rows = group[lo:hi]
            nbhd = knn_neighbourhood(points, int(value), tree=tree, queries=points[index[rows]], workers=workers)
            weights = tapered_heat_weights(nbhd, nbhd.radius / alpha, areas)
            normals[rows] = _weighted_pca_normals(points, nbhd, weights)
    anchors = points[index]
    graph = knn_neighbourhood(anchors, min(ANCHOR_GRAPH, m - 1))
    if towards is not None and np.ndim(towards) == 2:
        towards = np.asarray(towards)[index]
    return orient(
        anchors, normals, graph, mode=mode, towards=towards, graph_neighbours=None,
        excluded=None if excluded is None else np.asarray(excluded)[index], open_up=open_up,
    )


def _weighted_pca_normals(points: np.ndarray, nbhd, weights: np.ndarray) -> np.ndarray:
    """Unit eigenvectors of the smallest eigenvalue of each row's weighted covariance, shape (rows, 3)."""
    rows = nbhd.rows
    total = np.maximum(np.bincount(rows, weights, minlength=nbhd.n_points), np.finfo(float).tiny)
    x = points[nbhd.indices]
    mean = np.stack([np.bincount(rows, weights * x[:, a], minlength=nbhd.n_points) for a in range(3)], 1)
    mean /= total[:, None]
    d = x - mean[rows]
    cov = np.empty((nbhd.n_points, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            cov[:, a, b] = cov[:, b, a] = np.bincount(rows, weights * d[:, a] * d[:, b], minlength=nbhd.n_points)
    return np.linalg.eigh(cov)[1][:, :, 0]


def fit_anchors(
    points: np.ndarray,
    tree: cKDTree,
    normals: np.ndarray,
    areas: np.ndarray,
    index: np.ndarray,
    k: np.ndarray,
    *,
    denoise: bool,
    low_noise: bool = False,
    alpha: float = 2.0,
    taper: bool = True,
    refine: bool = True,
    workers: int = -1,
    block_pairs: int | None = None,
    progress=None,
) -> AnchorFits:
    """The chord fit (two passes: normal refinement, then curvatures) at every anchor, with its whole ball.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct centred points; ``tree`` is built on them.
    tree : scipy.spatial.cKDTree
    normals : ndarray, shape (m, 3)
        Oriented starting normals of the anchors.
    areas : ndarray, shape (n,)
        Fit weights' areas (0 for outliers).
    index : ndarray of int, shape (m,)
        The anchors (:func:`anchor_rows`).
    k : ndarray of int, shape (m,)
        Neighbours in each anchor's ball.
    denoise : bool
        The denoised height form of the fit.
    low_noise : bool, optional
        With ``denoise``, its low-noise refit (:func:`carry_degree`, :func:`heatcurv.fits.chordfit.chord_fit`)
        at the anchors whose kernel holds at least ``TUNING.low_noise_min_neighbours`` neighbours.
    alpha : float, optional
        Ball radius in heat-kernel spacings (``h = R / alpha``, ``t = h^2 / 4``, eq 2.8).
    taper : bool, optional
        Taper the centroid offsets (border flags) as the operator's balls.
    refine : bool, optional
        Correct the starting normals by a first fit's tilt (False: the caller's normals are kept).
    workers : int, optional
        Threads of the k-d tree queries.
    block_pairs : int, optional
        Pairs per block (default the policy's, :data:`heatcurv.geometry.neighbourhood.BLOCK_PAIRS`).
    progress : callable, optional
        ``progress(fraction)`` after each block.

    Returns
    -------
    AnchorFits
    """
    index, k = np.asarray(index), np.asarray(k)
    m = index.shape[0]
    radius, offset, density, roundness = np.empty(m), np.empty(m), np.empty(m), np.empty(m)

    def fit_block(rows: np.ndarray, width: int) -> tuple:
        # two passes (a tilt-refined normal, then the curvatures) unless the normals are the caller's
        nbhd, fit = fit_balls(
            points, tree, index[rows], normals[rows], areas, Scale(width, denoise), alpha=alpha,
            passes=2 if refine else 1, workers=workers,
            low_noise=low_noise and width >= TUNING.low_noise_min_neighbours,
        )
        offset[rows] = centroid_offset(points, nbhd, fit.normals, taper=taper, centres=points[index[rows]])
        density[rows] = density_areas(nbhd)
        roundness[rows] = ball_roundness(points, nbhd, index[rows])
        radius[rows] = nbhd.radius
        return rows, fit

    order = np.argsort(k, kind="stable")  # one k-d tree query width per group
    jobs = []
    for width in np.unique(k):
        group = order[k[order] == width]
        blocks = block_ranges(group.shape[0], rows_per_block(int(width), block_pairs))
        jobs += [(group[lo:hi], int(width)) for lo, hi in blocks]
    pairs_total = max(int(k.sum()), 1)
    pairs_done = 0
    parts, slots = [], []
    # a wide kernel's block holds too few anchors for the kernels' row threads: blocks run side by side
    largest = max((rows.shape[0] for rows, _ in jobs), default=0)
    for rows, fit in map_blocks(lambda job: fit_block(*job), jobs, largest):
        parts.append(fit)
        slots.append(rows)
        pairs_done += int(k[rows].sum())
        if progress is not None:
            progress(pairs_done / pairs_total)
    # the blocks ran grouped by width: back to the anchors' order
    back = np.empty(m, dtype=np.int64)
    back[np.concatenate(slots)] = np.arange(m)
    fit = ChordFit.concatenate(parts).take(back)
    return AnchorFits(index=index, k=k, fit=fit, radius=radius, offset=offset, density_area=density,
                      roundness=roundness)


def ball_roundness(points: np.ndarray, nbhd: Neighbourhood, centres: np.ndarray) -> np.ndarray:
    """``lambda_0 / lambda_1`` of the plain covariance of each ball of ``nbhd`` (rows centred at ``points[centres]``).

    Near 0 for a disc of surface; towards 1 where the surface turns within the ball by about as
    much as the ball is wide (the bottom of a cup narrower than the ball, a tube across it): such
    a ball has no tangent plane for a height fit to be taken over.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    nbhd : Neighbourhood
        One row per centre, indices into ``points``.
    centres : ndarray of int, shape (r,)

    Returns
    -------
    ndarray, shape (r,)
        NaN where ``lambda_1`` vanishes.
    """
    return pca_normals(points, nbhd, roundness=True, centres=centres)[2]


def carry_fits(points: np.ndarray, anchors: AnchorFits, *, normals: np.ndarray | None = None,
               reference: np.ndarray | None = None, carried: int = CARRIED_ANCHORS, degree: int = 0,
               workers: int = -1) -> CarriedFit:
    """Every point's normal, curvatures and fit diagnostics from its nearest anchors (module docstring).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        The points to evaluate at (the cloud).
    anchors : AnchorFits
    normals : ndarray, shape (n, 3), optional
        Unit normals to keep (the caller's): the carried tensor is projected onto
        their tangent planes. Default: the carried normals.
    reference : ndarray, shape (n, 3), optional
        Each point's own oriented normal (the operator's): anchors more than 60
        degrees from it are not carried to the point. Without it, a part
        thinner than the ball got its other side's normals (an airplane mesh:
        981 of 5400 normals inward at a 960-neighbour kernel). Default: the
        caller's ``normals``, if given.
    carried : int, optional
        Nearest anchors per point whose models are carried and averaged.
    degree : int, optional
        0: the tensor is that weighted mean. 1-3: it is the regression of that degree of the
        :data:`REGRESSED_ANCHORS` nearest anchors' own tensors (:func:`carry_degree`; the
        normal is still the mean's). The support radius counts every anchor used.
    workers : int, optional
        Threads of the k-d tree query.

    Returns
    -------
    CarriedFit
    """
    fit = anchors.fit
    if anchors.index.shape[0] == points.shape[0]:  # every point is an anchor: its own fit
        return CarriedFit(
            normals=fit.normals if normals is None else normals, principal=fit.principal, sigma=fit.sigma,
            offset=anchors.offset, radius=anchors.radius, density_area=anchors.density_area,
            roundness=anchors.roundness, noise=fit.noise, noise_factors=fit.noise_factors, support=anchors.radius,
            nearest=np.argsort(anchors.index),
        )
    if reference is None:
        reference = normals
    summed, tensor, values, support, total, nearest = _carried_sums(points, anchors, reference, carried, degree,
                                                                     workers)
    length = np.linalg.norm(summed, axis=1)
    reached = (total > 0) & (length > 0) & np.all(np.isfinite(tensor), axis=1)
    # no usable anchor near the point at all (every nearby fit ill-posed): the nearest anchor's normal,
    # zero curvature, and not well posed (so never reliable); never a NaN
    lost = ~(length > 0) | ~np.all(np.isfinite(summed), axis=1) | ~np.all(np.isfinite(tensor), axis=1)
    if reference is not None:  # no anchor on the point's side: its own normal, not the other side's
        lost |= total == 0
    if lost.any():
        summed[lost] = fit.normals[nearest[lost]] if reference is None else reference[lost]
        tensor[lost] = 0.0
        length[lost] = 1.0
    keep = normals is not None
    if not keep:
        normals = summed / np.where(length > 0, length, 1.0)[:, None]
    pc = _principal_in_tangent_plane(tensor, normals, reached)
    # an anchor keeps its own fit (where every point is an anchor, nothing is carried)
    own = anchors.index
    if not keep:
        normals[own] = fit.normals
    for name in PrincipalCurvatures.__dataclass_fields__:
        getattr(pc, name)[own] = getattr(fit.principal, name)
    values[own] = _anchor_scalars(anchors)
    support[own] = anchors.radius
    return CarriedFit(
        normals=normals, principal=pc, sigma=values[:, 0], offset=values[:, 1], radius=values[:, 2],
        density_area=values[:, 3], roundness=values[:, 10], noise=values[:, 4], noise_factors=values[:, 5:10],
        support=support, nearest=nearest,
    )


def _anchor_scalars(anchors: AnchorFits) -> np.ndarray:
    """The per-anchor values carried beside the fits, shape (m, 11): the residual ``sigma`` (carried as the
    most-weighted anchor's), centroid offset, ball radius, density area, noise, the five noise factors and the
    ball's roundness."""
    fit = anchors.fit
    return np.column_stack([fit.sigma, anchors.offset, anchors.radius, anchors.density_area, fit.noise,
                            fit.noise_factors, anchors.roundness])


def _carried_sums(points: np.ndarray, anchors: AnchorFits, reference: np.ndarray | None, carried: int,
                  degree: int, workers: int) -> tuple:
    """The compiled carry (:func:`heatcurv._kernels.anchors.carry_anchor_fits`) over the points, a block at a time.

    Returns
    -------
    summed : ndarray, shape (n, 3)
        The weighted sum of the carried normals (not normalised).
    tensor : ndarray, shape (n, 6)
        The carried curvature tensor (``xx, xy, xz, yy, yz, zz``).
    values : ndarray, shape (n, 11)
        The carried :func:`_anchor_scalars`; where no anchor's weight reached the point, the nearest anchor's.
    support : ndarray, shape (n,)
        Distance to the farthest anchor used plus its ball radius.
    total : ndarray, shape (n,)
        The weights' sum (0: no anchor reached the point).
    nearest : ndarray, shape (n,), int64
        The nearest anchor.
    """
    fit = anchors.fit
    at = points[anchors.index]
    m, n = at.shape[0], points.shape[0]
    carried = min(carried, m)
    queried = min(max(carried, REGRESSED_ANCHORS if degree > 0 else 0), m)
    e1, e2 = tangent_frames(fit.normals)
    usable = (fit.principal.well_posed & np.all(np.isfinite(fit.coefficients), axis=1)).astype(np.float64)
    scalars = _anchor_scalars(anchors)
    exact = (fit.sigma < TUNING.exact_carry_sigma * anchors.radius).astype(np.float64)
    tree = cKDTree(at)
    summed, tensor, values = np.empty((n, 3)), np.empty((n, 6)), np.empty((n, scalars.shape[1]))
    support, total, nearest_dist = np.empty(n), np.empty(n), np.empty(n)
    nearest = np.empty(n, dtype=np.int64)
    # the points a block at a time: the anchor lists of a million points (24 under very low noise) would
    # otherwise add 0.4 GB to the peak; each point's values are its own, so the blocks change none
    for lo in range(0, n, CARRY_BLOCK):
        hi = min(n, lo + CARRY_BLOCK)
        dist, idx = tree.query(points[lo:hi], queried, workers=workers)
        dist, idx = dist.reshape(hi - lo, queried), idx.reshape(hi - lo, queried)
        indptr = np.arange(0, idx.size + 1, queried, dtype=np.int64)
        parts = kernels.carry_anchor_fits(
            points[lo:hi], indptr, idx.reshape(-1), dist.reshape(-1), at, fit.normals, e1, e2, fit.coefficients,
            anchors.radius, usable, scalars, reference=None if reference is None else reference[lo:hi],
            n_mean=carried, degree=degree, exact=exact,
        )
        for out, part in zip((summed, tensor, values, support, total), parts):
            out[lo:hi] = part
        nearest[lo:hi], nearest_dist[lo:hi] = idx[:, 0], dist[:, 0]
    unset = ~np.all(np.isfinite(values), axis=1)
    if unset.any():
        values[unset] = scalars[nearest[unset]]
        support[unset] = nearest_dist[unset] + anchors.radius[nearest[unset]]
    return summed, tensor, values, support, total, nearest


def _principal_in_tangent_plane(tensor: np.ndarray, normals: np.ndarray, reached: np.ndarray) -> PrincipalCurvatures:
    """Principal curvatures of the carried ``tensor`` projected onto the tangent plane of ``normals``.

    ``reached`` (shape (n,), bool) is ``well_posed``; rows not reached are projected onto ``z = 0``.
    """
    u, v = tangent_frames(np.where(reached[:, None], normals, [[0.0, 0.0, 1.0]]))
    b11 = _quadratic_form(tensor, u, u)
    b12 = _quadratic_form(tensor, u, v)
    b22 = _quadratic_form(tensor, v, v)
    pc = tensor_to_principal(0.5 * (b11 + b22), 0.5 * (b11 - b22), b12, u, v, normals)
    return PrincipalCurvatures(
        k1=pc.k1, k2=pc.k2, d1=pc.d1, d2=pc.d2, mean=pc.mean, gaussian=pc.gaussian, well_posed=reached
    )


def _quadratic_form(tensor: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u^T T v`` per row for symmetric ``T`` stored as ``xx, xy, xz, yy, yz, zz``, shape (n,)."""
    xx, xy, xz, yy, yz, zz = tensor.T
    return (u[:, 0] * (xx * v[:, 0] + xy * v[:, 1] + xz * v[:, 2])
            + u[:, 1] * (xy * v[:, 0] + yy * v[:, 1] + yz * v[:, 2])
            + u[:, 2] * (xz * v[:, 0] + yz * v[:, 1] + zz * v[:, 2]))
