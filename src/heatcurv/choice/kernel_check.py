"""Stage ``kernel_check``: refuse a kernel that cannot give an answer, warn about a doubtful one.

Every fit of the estimator is a weighted least-squares problem over a point's
ball, with the heat kernel as weights. Its options (``alpha``, ``m``,
``neighbours``, ``scale``) set the kernel's width against the ball, and some
combinations leave nothing to fit: ``alpha = 20`` with the density spacing
makes the default kernel ``R / 20`` wide, so a median point's fit rests on about
one neighbour (a unit sphere then gave a median mean curvature of 0.56, every
point flagged unreliable, exit status 0); ``m = 0.05`` does the same to the
paper's kernel (mean curvature off by 87 %, every point "reliable"). Before any
curvature is computed, this stage measures the kernel on a random subsample of
the operator's balls:

* the **effective neighbours** of the fit's weights, ``(sum w)^2 / sum w^2``
  (:func:`heatcurv.operators.kernel.effective_neighbours`): a median below the fit's
  floor (``TUNING.chord_support``, ``TUNING.tensor_support``) is an error that names the values that work
  for this cloud; a median just above it, a warning. The floors differ by
  fit: the chord fit interpolates (exact on clean data with any positive
  weights) and needs little (a few effective neighbours), the paper's tensor
  fit and its quadratures average and need more (below about 5 its mean
  curvature is off by tens of per cent with every point "reliable"); the
  runs behind each floor are in docs/how_it_works.md (thresholds);
* the **kernel at the ball's edge**, relative to its centre: the paper's
  quadratures assume the ball holds the whole kernel, so a kernel cut above
  1e-3 of its peak warns (``alpha = 2`` at ``m = 1/4`` cuts it at 1.8 %; a
  regular sphere's mean curvature is then 10 % off); the default's fit is
  tapered to 0 at the edge by design and warns only when the kernel is
  wider than the ball (edge above ``exp(-1)``), where the ball, not the heat
  kernel, sets the weights;
* the **points in each ball** (:func:`check_ball_counts`), where the ball has
  a fixed radius (``radius=``, or ``alpha`` times the paper's spacings)
  rather than a neighbour count: a ball that holds fewer points than the
  fit has unknowns leaves it under-determined, and a point whose ball holds
  fewer than ``min_neighbours`` gets its nearest ones and is unreliable. When
  a median point's ball holds fewer than :func:`neighbours_needed`, a warning
  names the cloud's median spacing and a radius (or ``alpha``) that gives
  nine points in ten enough neighbours (``radius = 1e-4`` on the bunny scan,
  whose spacing is 0.28, leaves every point unreliable).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import HeatcurvError, HeatcurvWarning
from ..geometry.neighbourhood import Neighbourhood
from ..geometry.sampling import draw_subset
from ..operators.kernel import effective_neighbours, heat_kernel_weights, tapered_heat_weights
from ..options import METHODS, RANGES, Options
from ..tuning import TUNING

__all__ = [
    "KernelSupport", "measure_support", "check_kernel", "FIT_UNKNOWNS", "neighbours_needed",
    "check_ball_counts",
]

#: Balls the measurement runs on.
SAMPLE = 2000
#: Unknowns of each fit: the chord fit's curvature tensor (3), normal tilt (2) and cubic terms (4);
#: the paper's tensor fit, ``H``, ``p``, ``b`` (:mod:`heatcurv.fits.principal`).
FIT_UNKNOWNS = {"chord": 9, "tensor": 3}


@dataclass(frozen=True)
class KernelSupport:
    """What :func:`measure_support` measured.

    Attributes
    ----------
    effective_neighbours : float
        Median effective neighbours of the fit's weights over the subsample.
    fit : {"chord", "tensor"}
        The fit the kernel weights: the default's chord fit or the paper's tensor fit.
    edge_weight : float
        The heat kernel at the ball's edge relative to its centre,
        ``exp(-alpha^2 / (4 m))`` (the chord fit: ``m = 1/4``).
    tapered : bool
        Whether the fit's weights are tapered to 0 at the ball's edge.
    """

    effective_neighbours: float
    fit: str
    edge_weight: float
    tapered: bool


def _fit_weights(sub: Neighbourhood, h: np.ndarray, options: Options, n_points: int) -> np.ndarray:
    """The fit's pair weights on the sampled balls (areas left out: they only reweight mildly)."""
    if options.fit == "chord":
        # the chord fit: t = h^2 / 4 with h = R / alpha, tapered at the edge (heatcurv.operators.kernel)
        return tapered_heat_weights(sub, sub.radius / options.alpha, np.ones(n_points))
    return heat_kernel_weights(sub, h, options.m)


def _sample(nbhd: Neighbourhood, h: np.ndarray, options: Options, seed: int = 0, keys: np.ndarray | None = None):
    """A subsample of the balls the fit will use (the narrowest, for the chord fit), drawn by ``keys``.

    ``keys`` (:func:`heatcurv.geometry.sampling.geometric_keys`) make the sample independent of the row order;
    without them a seeded random sample of the rows is drawn.
    """
    n = nbhd.n_points
    rows = draw_subset(n, SAMPLE, seed, keys)
    sub = nbhd.take_rows(rows)
    fixed = options.radius is None and options.scale != "auto"
    if options.fit == "chord" and fixed and int(options.scale) < int(options.neighbours):
        sub = sub.nearest(int(options.scale))  # a fixed kernel narrower than the operator's ball
    return sub, h[rows]


def measure_support(nbhd: Neighbourhood, h: np.ndarray, options: Options, seed: int = 0) -> KernelSupport:
    """Effective neighbours and edge weight of the fit's kernel on a random subsample of balls.

    Parameters
    ----------
    nbhd : Neighbourhood
        The operator's neighbourhood (for the chord fit, its narrowest kernel).
    h : ndarray, shape (n,)
        The operator's spacing.
    options : Options
    seed : int, optional
        Seed of the subsample.

    Returns
    -------
    KernelSupport
    """
    return _measure(*_sample(nbhd, h, options, seed), options, nbhd.n_points)


def _measure(sub: Neighbourhood, h_sub: np.ndarray, options: Options, n_points: int) -> KernelSupport:
    """:func:`measure_support` on balls already sampled."""
    weights = _fit_weights(sub, h_sub, options, n_points)
    tapered = options.fit == "chord"
    m = 0.25 if tapered else options.m
    return KernelSupport(
        effective_neighbours=float(np.median(effective_neighbours(sub, weights))),
        fit="chord" if tapered else "tensor",
        edge_weight=math.exp(-(options.alpha**2) / (4.0 * m)),
        tapered=tapered,
    )


def _widest_alpha(sub: Neighbourhood, target: float, n_points: int, alpha: float) -> float | None:
    """The largest ``alpha`` below ``alpha`` whose chord-fit kernel reaches ``target`` effective neighbours."""

    def support(a):
        w = tapered_heat_weights(sub, sub.radius / a, np.ones(n_points))
        return np.median(effective_neighbours(sub, w))

    lo, hi = 0.25, alpha
    if support(lo) < target:
        return None
    for _ in range(30):  # bisection: the support falls as alpha grows
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if support(mid) >= target else (lo, mid)
    return lo


def _smallest_m(sub: Neighbourhood, h: np.ndarray, target: float, m: float) -> float | None:
    """The smallest ``m`` above ``m`` whose heat kernel reaches ``target`` effective neighbours."""

    def support(value):
        return np.median(effective_neighbours(sub, heat_kernel_weights(sub, h, value)))

    lo, hi = m, 1e3
    if support(hi) < target:
        return None
    for _ in range(40):  # bisection in log m: the support grows with m
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if support(mid) >= target else (mid, hi)
    return hi


def _advice(sub: Neighbourhood, h_sub: np.ndarray, options: Options, n_points: int, target: float) -> str:
    """What would give the fit ``target`` effective neighbours on the sampled balls."""
    if options.fit == "chord":
        best = _widest_alpha(sub, target, n_points, options.alpha)
        more = "more neighbours (neighbours=, or a wider scale=)"
        return f"use alpha <= {best:.3g} or {more}" if best is not None else f"use {more}"
    best = _smallest_m(sub, h_sub, target, options.m)
    if best is None:
        return "use a larger alpha (a wider ball)"
    return f"use m >= {best:.3g} (and alpha >= {math.sqrt(4 * best * math.log(1e3)):.3g} so the ball holds its kernel)"


#: The options that shape the fit's kernel.
KERNEL_OPTIONS = ("alpha", "m", "spacing", "gamma", "k_local", "neighbours", "radius", "scale", "fit")


def _options_chosen(options: Options) -> bool:
    """Whether the caller changed the kernel from the method's preset (then a useless kernel is an error)."""
    preset = METHODS[options.method]
    return any(getattr(options, name) != getattr(preset, name) for name in KERNEL_OPTIONS if name != "scale") or (
        options.fit == "chord" and options.scale != "auto"
    )


def check_kernel(nbhd: Neighbourhood, h: np.ndarray, options: Options, keys: np.ndarray | None = None) -> KernelSupport:
    """Raise on a kernel that cannot give an answer, warn on a doubtful one (see the module docstring).

    Parameters
    ----------
    nbhd : Neighbourhood
        The operator's neighbourhood.
    h : ndarray, shape (n,)
        The operator's spacing.
    options : Options
    keys : ndarray, shape (n,), optional
        Sampling keys (:func:`heatcurv.geometry.sampling.geometric_keys`); default a
        seeded random sample of the rows.

    Returns
    -------
    KernelSupport

    Raises
    ------
    HeatcurvError
        When the median point's fit has fewer effective neighbours than the
        fit's floor (``TUNING.chord_support``, ``TUNING.tensor_support``) with options the caller chose;
        with the method's own preset (the paper's on a random cloud) this is
        a warning: the literal method stays reproducible.

    Warns
    -----
    HeatcurvWarning
        When it has barely more, or the ball cuts the kernel (``TUNING.tapered_edge_weight``,
        ``TUNING.untapered_edge_weight``).
    """
    sub, h_sub = _sample(nbhd, h, options, keys=keys)
    support = _measure(sub, h_sub, options, nbhd.n_points)
    n_eff = support.effective_neighbours
    low, few = TUNING.chord_support if support.fit == "chord" else TUNING.tensor_support
    what = f"alpha = {options.alpha:g}" + ("" if options.fit == "chord" else f", m = {options.m:g}")
    fit = "chord fit" if options.fit == "chord" else "paper's tensor fit"
    if n_eff < low:
        message = (
            f"{what}: the heat kernel is so narrow that a median point's fit rests on {n_eff:.2g} effective "
            f"neighbours; the {fit} needs at least {low:g}: {_advice(sub, h_sub, options, nbhd.n_points, few)}"
        )
        if _options_chosen(options):
            raise HeatcurvError(message)
        # the method's own preset: the cloud, not the options, is the problem (the paper's eq 2.6
        # spacing measures about half the spacing of a random cloud); reproduce it, loudly
        warnings.warn(
            f"method {options.method!r} does not suit this cloud ({message}); method='default' is built for "
            "irregular clouds",
            HeatcurvWarning,
            stacklevel=3,
        )
    elif n_eff < few:
        warnings.warn(
            f"{what}: a median point's fit rests on only {n_eff:.3g} effective neighbours; expect noisy "
            f"curvatures ({_advice(sub, h_sub, options, nbhd.n_points, few)})",
            HeatcurvWarning,
            stacklevel=3,
        )
    limit = TUNING.tapered_edge_weight if support.tapered else TUNING.untapered_edge_weight
    if support.edge_weight > limit:
        if support.tapered:
            message = (
                f"alpha = {options.alpha:g} makes the heat kernel wider than its ball (it is still "
                f"{support.edge_weight:.2g} of its peak at the edge): the ball, not the kernel, sets the fit's "
                "weights; alpha >= 1 keeps the kernel inside"
            )
        else:
            need = math.sqrt(4 * options.m * math.log(1.0 / limit))
            message = (
                f"{what}: the ball cuts the heat kernel at {support.edge_weight:.2g} of its peak, which biases "
                f"the paper's quadratures (areas, mean curvature); use alpha >= {need:.3g} at this m"
            )
        warnings.warn(message, HeatcurvWarning, stacklevel=3)
    return support


def neighbours_needed(options: Options) -> int:
    """Fewest neighbours a point's ball must hold for its fit to be reliable.

    More than the fit's unknowns (:data:`FIT_UNKNOWNS`: a least-squares fit
    needs more equations than unknowns), and at least ``min_neighbours`` (a
    point with fewer gets its nearest ones and is unreliable).

    Parameters
    ----------
    options : Options

    Returns
    -------
    int
    """
    return max(FIT_UNKNOWNS[_fit_name(options)] + 1, int(options.min_neighbours))


def _fit_name(options: Options) -> str:
    return "chord" if options.fit == "chord" else "tensor"


def _ball_counts(nbhd: Neighbourhood, reach: np.ndarray) -> np.ndarray:
    """Neighbours within each point's own ball, shape (n,), also where the ball was augmented.

    An augmented row (:func:`heatcurv.geometry.neighbourhood.ball_neighbourhood`) holds
    its nearest neighbours, which include every point of its ball: its count
    is that of its distances within ``reach``.
    """
    counts = nbhd.counts.copy()
    rows = np.flatnonzero(nbhd.augmented)
    if rows.size:
        sub = nbhd.take_rows(rows)
        inside = sub.distances <= np.repeat(reach[rows], sub.counts)
        counts[rows] = np.bincount(np.repeat(np.arange(rows.size), sub.counts), weights=inside,
                                   minlength=rows.size).astype(np.int64)
    return counts


def _round_up(value: float) -> float:
    """``value`` rounded up to two significant digits (a suggestion that still clears the bar)."""
    step = 10.0 ** (math.floor(math.log10(value)) - 1)
    return math.ceil(value / step * (1 - 1e-12)) * step


def check_ball_counts(points: np.ndarray, tree, nbhd: Neighbourhood, h: np.ndarray, options: Options,
                      keys: np.ndarray | None = None, unit: float = 1.0) -> None:
    """Warn when a median point's ball holds fewer neighbours than the fit needs (see the module docstring).

    Only balls of a fixed radius are checked (``radius=``, or the spacings
    ``global`` and ``local``): a ball of ``neighbours`` nearest points
    holds at least 20, more than any fit needs.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        The operator's distinct points.
    tree : scipy.spatial.cKDTree
        The k-d tree on ``points``.
    nbhd : Neighbourhood
        The operator's neighbourhood.
    h : ndarray, shape (n,)
        The operator's spacing: each ball's radius is ``alpha h``.
    options : Options
    keys : ndarray, shape (n,), optional
        Sampling keys (:func:`heatcurv.geometry.sampling.geometric_keys`) of the
        points the suggestion is measured on; default a seeded random sample.
    unit : float, optional
        The input's length per unit of ``points`` (lengths in the message are in input units).

    Warns
    -----
    HeatcurvWarning
        When a median point's ball holds fewer than :func:`neighbours_needed`
        neighbours; the message names the median spacing (nearest-neighbour
        distance) and the radius, or ``alpha``, within which
        ``TUNING.filled_share`` of the points have enough.
    """
    if options.radius is None and options.spacing == "density":
        return
    need = neighbours_needed(options)
    reach = options.alpha * np.asarray(h, dtype=np.float64)
    held = float(np.median(_ball_counts(nbhd, reach)))
    if held >= need:
        return
    rows = draw_subset(nbhd.n_points, SAMPLE, 0, keys)
    distances, _ = tree.query(points[rows], k=need + 1)  # the points are distinct: the first is the point itself
    spacing = float(np.median(distances[:, 1])) * unit
    unknowns = FIT_UNKNOWNS[_fit_name(options)]
    fit = "chord fit" if options.fit == "chord" else "paper's tensor fit"
    if need == unknowns + 1:
        why = f"the {fit} has {unknowns} unknowns and needs at least {need}"
    else:
        why = f"min_neighbours = {need} asks for at least {need} (a point with fewer gets its nearest ones)"
    advice = f"radius = {_round_up(float(np.quantile(distances[:, need], TUNING.filled_share)) * unit):.2g}"
    if options.radius is not None:
        what = f"radius = {options.radius:g}"
    else:
        what = f"alpha = {options.alpha:g} ({options.spacing} spacing)"
        alpha = _round_up(float(np.quantile(distances[:, need] / h[rows], TUNING.filled_share)))
        if alpha <= RANGES["alpha"].high:
            advice = f"alpha = {alpha:.2g}"
    neighbours = "neighbour" if held == 1 else "neighbours"
    warnings.warn(
        f"{what} leaves a median point's ball with {held:g} {neighbours}; {why}, so many points will be "
        f"unreliable. The points' median spacing is {spacing:.2g}: {advice} gives "
        f"{round(100 * TUNING.filled_share)} % of them at least {need} neighbours",
        HeatcurvWarning,
        stacklevel=3,
    )
