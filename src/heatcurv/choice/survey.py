"""A tiled run's kernel choice, measured tile by tile.

The cloud-wide part of :func:`heatcurv.choice.scale.select_scale`.

In memory, :func:`heatcurv.choice.scale.select_scale` fits the candidate kernels at
sample centres (the points with the smallest sampling keys, in key order,
the wider candidates at a prefix of them) and then decides from those fits
alone (:func:`heatcurv.choice.scale.decide_scale`). A centre's fit depends only on the
points within its ball, so a tiled run can fit the centres where they lie:

1. each tile fits every candidate at *its* core points of smallest keys
   (:func:`survey_part`): the cloud's first ``s`` centres that fall in a tile
   are among the tile's first ``s``, so every fit the decision reads is made
   by some tile;
2. the driver joins the tiles' fits in key order and runs the same decision
   (:func:`merge_surveys`), which gives :class:`heatcurv.choice.choices.CloudChoices`
   for every tile.

The keys are uniform on [0, 1), so the cloud's first ``s`` lie below
``(s + 8 sqrt(s)) / n`` but with a negligible chance (:func:`key_bound`): a
tile fits each candidate kernel only at its centres below that bound (about
``s / tiles`` of them, not ``s``), and the merge checks that the tiles' fits
hold the cloud's first ``s`` (:class:`CandidatesShort` otherwise: the survey
runs again without the bound).

A tiled run surveys in two rounds that make the same fits at exactly the
centres the decision reads and nowhere else (:func:`key_part`,
:func:`join_keys`, :func:`fit_centres`, :func:`merge_fits`: the sampling keys
of every tile over a thin halo first, then each candidate's fits at the
cloud's centres only, each over the points within its reach), instead of every
candidate at every tile's own ``n_sub`` centres over a halo as wide as the
widest candidate's ball (:func:`survey_part`, :func:`merge_surveys`: the same
choice, bit for bit, at several times the cost).

The fits use unoriented normals: a centre's fits at all widths share its
normal, and the decision reads only magnitudes and differences at one centre,
which a flipped normal leaves unchanged (to rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import HeatcurvError
from ..fits.balls import Scale
from ..flags.outliers import find_outliers
from ..geometry.neighbourhood import Neighbourhood
from ..geometry.sampling import geometric_keys, shifted_keys
from ..operators.areas import fit_areas
from ..operators.operator import HeatKernelOperator
from ..options import Options, resolve_options
from ..orient.auto import auto_policy
from ..orient.normals import pca_normals
from .choices import CloudChoices, CloudFrame
from .scale import CentreFits, CentreFitter, _ladder, decide_scale, level_sizes

__all__ = [
    "CentreSurvey", "check_tileable", "merge_surveys", "survey_part", "tile_options", "KeySurvey", "CentrePlan",
    "CentreFitsPart", "key_part", "join_keys", "fit_centres", "merge_fits", "GATE_LEVELS", "FitsNotSurveyed",
    "key_bound", "CandidatesShort",
]


def tile_options(options: dict) -> Options:
    """The resolved options of a tiled run, or an error naming the one a tiled run cannot honour.

    Parameters
    ----------
    options : dict
        ``method`` and any :class:`heatcurv.Options` field, as for :func:`heatcurv.estimate`.

    Returns
    -------
    Options
    """
    options = dict(options)
    opts = resolve_options(options.pop("method", "default"), **options)
    check_tileable(opts)
    return opts


def check_tileable(opts: Options) -> None:
    """Raise :class:`HeatcurvError` unless a tile with its halo computes as the whole cloud would under ``opts``.

    The paper's method and the ``H A = 1`` areas solve one linear system over
    the whole cloud; a fixed ``radius=`` draws its noise check from a sample
    this module does not survey.
    """
    if opts.fit != "chord" or opts.area_method != "density" or opts.spacing != "density":
        raise HeatcurvError(
            f"a tiled run computes the default method only (got method={opts.method!r}, fit={opts.fit!r}, "
            f"area_method={opts.area_method!r}, spacing={opts.spacing!r}): the paper's areas solve one system over "
            "the whole cloud; run it in memory"
        )
    if opts.radius is not None:
        raise HeatcurvError(
            "a tiled run chooses the kernel by neighbour counts: leave radius= unset, or run in memory"
        )


@dataclass(frozen=True)
class CentreSurvey:
    """One tile's fits at its candidate centres (its core points of smallest keys, in key order).

    Attributes
    ----------
    keys : ndarray, shape (c,)
        The candidates' shifted sampling keys, increasing.
    positions : ndarray, shape (c, 3)
        Their coordinates in the cloud's frame (stages' units).
    fits : dict
        ``{scale label: CentreFits}``, each at the first candidates
        (:func:`heatcurv.choice.scale.level_sizes`).
    reach : ndarray, shape (c,)
        How far from each candidate its fits read points (the widest ball plus
        one operator ball for its neighbours' areas and normal), stages' units:
        the tile's halo must hold that much.
    bound : float
        The candidates are the tile's core points of shifted key below it, at
        most ``n_sub`` (:func:`key_bound`; 1: every key).
    largest_ball : float
        The largest operator ball radius of the tile's core points, stages' units.
    """

    keys: np.ndarray
    positions: np.ndarray
    fits: dict
    reach: np.ndarray
    bound: float = 1.0
    largest_ball: float = 0.0


#: Standard deviations of the count of keys below :func:`key_bound` above the centres the choice needs.
KEY_BOUND_SIGMAS = 8.0


def key_bound(size: int, n_points: int) -> float:
    """A shifted key below which a cloud of ``n_points`` holds its ``size`` smallest but with a negligible chance.

    The shifted keys are uniform on [0, 1) (:func:`heatcurv.geometry.sampling.geometric_keys`), so the
    count below ``b`` is binomial with mean ``n b``: at ``b = (size + 8 sqrt(size)) / n`` it falls short of
    ``size`` with a chance of 3e-11 at ``size = 100`` (the fewest centres a kernel is fitted at) and 2e-14
    at 2000, whatever ``n`` (binomial tails; a lattice's repeated keys may do worse: :class:`CandidatesShort`).
    """
    return min(1.0, (size + KEY_BOUND_SIGMAS * np.sqrt(size)) / max(n_points, 1))


class CandidatesShort(HeatcurvError):
    """:func:`merge_surveys`: the tiles' candidates below :func:`key_bound` are fewer than the choice needs."""


def _candidate_rows(keys: np.ndarray, core: np.ndarray, size: int, seed: int, bound: float = 1.0) -> np.ndarray:
    """The ``size`` core rows of smallest shifted keys, those below ``bound`` only, in key order."""
    rows = np.flatnonzero(core)
    shifted = shifted_keys(keys[rows], seed)
    order = np.argsort(shifted, kind="stable")[:size]
    return rows[order[shifted[order] < bound]]


def survey_part(points, core, frame: CloudFrame, operator=None, outliers=None, bounded: bool = True,
                **options) -> CentreSurvey:
    """Fit the candidate kernels at a tile's candidate centres (step 1 of the module).

    Parameters
    ----------
    points : array_like, shape (m, 3)
        The tile's points with their halo, input coordinates.
    core : array_like of bool, shape (m,)
        The tile's own points (the candidates are drawn from them).
    frame : CloudFrame
        The whole cloud's frame.
    operator : HeatKernelOperator, optional
        The operator over ``points`` with these options, if built already.
    outliers : Outliers, optional
        Its outliers (:func:`heatcurv.flags.outliers.find_outliers`), if found already.
    bounded : bool, optional
        Fit only the candidates below :func:`key_bound` (default), else the
        tile's ``n_sub`` smallest keys.
    **options
        As :func:`heatcurv.estimate` (:func:`tile_options`).

    Returns
    -------
    CentreSurvey
    """
    opts = tile_options(options)
    tuning = opts.scale_tuning
    core = np.asarray(core, dtype=bool)
    op = HeatKernelOperator.from_points(points, opts, frame=frame) if operator is None else operator
    X, base = op.points, op.neighbourhood
    prepared = op.prepared
    core_rows = np.zeros(X.shape[0], dtype=bool)
    core_rows[prepared.inverse[core]] = True
    keys = geometric_keys(X, base, frame)
    outliers = find_outliers(X, base) if outliers is None else outliers
    ladder = _ladder(int(opts.neighbours), tuning.max_k, frame.n_points)
    q = min(tuning.n_sub, frame.n_points)
    sizes = level_sizes(ladder, q)
    bound = key_bound(q, frame.n_points) if bounded else 1.0
    rows = _candidate_rows(keys, core_rows, q, tuning.seed, bound)
    candidate_keys = shifted_keys(keys[rows], tuning.seed)

    def fitted(size: int) -> int:
        """How many of the tile's candidates a kernel fitted at the cloud's first ``size`` centres needs."""
        below = key_bound(size, frame.n_points) if bounded else 1.0
        return min(size, int(np.searchsorted(candidate_keys, below)))

    normals, _ = pca_normals(X, base, taper=opts.taper, rows=rows)
    fitter = CentreFitter(X, op.tree, normals, fit_areas(op.areas, outliers.mask), rows, alpha=opts.alpha,
                          workers=opts.workers)
    base_k = int(opts.neighbours)
    fits = {Scale(base_k, False).label: fitter(Scale(base_k, False), fitted(q))}
    widest = np.zeros(rows.shape[0])
    for scale, size in zip(ladder, sizes):
        size = fitted(size)
        fits[scale.label] = fitter(scale, size)
        widest[:size] = np.maximum(widest[:size], fits[scale.label].h[:size] * opts.alpha)
    reach = widest + _largest_ball(base)
    largest = float(base.radius[core_rows].max()) if core_rows.any() else 0.0
    return CentreSurvey(candidate_keys, X[rows], fits, reach, bound, largest)


def _largest_ball(base: Neighbourhood) -> float:
    """The largest operator ball radius of the tile (a neighbour's area and normal reach that far)."""
    return float(base.radius.max()) if base.n_points else 0.0


class SurveyedFits:
    """The joined fits of every tile, with the interface of :class:`heatcurv.choice.scale.CentreFitter`."""

    def __init__(self, surveys: list, q: int):
        keys = np.concatenate([s.keys for s in surveys])
        tile = np.concatenate([np.full(s.keys.shape[0], i) for i, s in enumerate(surveys)])
        rank = np.concatenate([np.arange(s.keys.shape[0]) for s in surveys])
        order = np.argsort(keys, kind="stable")[:q]
        self.surveys, self.tile, self.rank = surveys, tile[order], rank[order]
        self.positions = np.concatenate([s.positions for s in surveys])[order]

    def __call__(self, scale: Scale, size: int) -> CentreFits:
        tile, rank = self.tile[:size], self.rank[:size]
        parts = {f: np.empty(size) for f in ("mean", "factor", "sigma", "h")}
        for i, survey in enumerate(self.surveys):
            mine = tile == i
            if not mine.any():
                continue
            fits = survey.fits[scale.label]
            if rank[mine].max() >= fits.mean.shape[0]:
                short = CandidatesShort if survey.bound < 1.0 else HeatcurvError
                raise short(f"tile {i} did not fit {scale.label} at the centres the choice needs")
            for f in parts:
                parts[f][mine] = getattr(fits, f)[rank[mine]]
        return CentreFits(**parts)


def merge_surveys(surveys: list, frame: CloudFrame, **options) -> CloudChoices:
    """The whole cloud's choices from its tiles' surveys (step 2 of the module).

    Parameters
    ----------
    surveys : list of CentreSurvey
        One per tile (any order).
    frame : CloudFrame
    **options
        As :func:`heatcurv.estimate`.

    Returns
    -------
    CloudChoices

    Raises
    ------
    CandidatesShort
        When the tiles fitted their candidates below :func:`key_bound` only
        and those are fewer than the choice needs: survey again unbounded.
    """
    opts = tile_options(options)
    tuning = opts.scale_tuning
    candidates = sum(s.keys.shape[0] for s in surveys)
    if any(s.bound < 1.0 for s in surveys) and candidates < min(tuning.n_sub, frame.n_points):
        raise CandidatesShort(f"the tiles hold {candidates} candidate centres below their key bound, fewer than "
                              f"the {min(tuning.n_sub, frame.n_points)} the choice needs")
    q = min(tuning.n_sub, frame.n_points, candidates)
    fits = SurveyedFits(surveys, q)
    return _decide(fits, fits.positions, frame, opts)


def _decide(fits, positions: np.ndarray, frame: CloudFrame, opts) -> CloudChoices:
    """:func:`heatcurv.choice.scale.decide_scale` and :func:`heatcurv.orient.auto.auto_policy` once for the
    cloud, at its sample centres (``positions``)."""
    tuning = opts.scale_tuning
    choice = decide_scale(
        fits, positions, frame.n_points, base_k=int(opts.neighbours), max_k=tuning.max_k, tau=tuning.tau,
        clean_ratio=tuning.clean_ratio, fixed_k=None if opts.scale == "auto" else int(opts.scale),
        workers=opts.workers,
    )
    return CloudChoices(frame, choice, auto_policy(positions, choice.sigma))


# ----------------------------------------------------------------------------------------------------
# The survey in two rounds: the cloud's sample centres first (keys only), then fits at those centres only
# ----------------------------------------------------------------------------------------------------
#
# :func:`survey_part` fits every candidate at a tile's own ``n_sub`` centres of smallest keys, over the
# tile and a halo as wide as the widest candidate's ball; the decision reads ``n_sub`` of those
# ``n_sub x tiles`` centres. The two rounds below make the same fits at exactly the centres read:
#
# 1. :func:`key_part`: the sampling key of each of a tile's core points (its ``neighbours`` nearest,
#    over the core and a halo of one operator ball) and the tile's ``n_sub`` smallest;
# 2. :func:`join_keys`: the cloud's first ``n_sub`` in key order (as :class:`SurveyedFits` joins them),
#    and how many of them each candidate is fitted at (:func:`heatcurv.choice.scale.level_sizes`);
# 3. :func:`fit_centres`: a tile's fits at its centres of the cloud's first ``n_sub``, each over the
#    points within its widest ball plus two operator balls (the areas of the ball's points and the
#    outlier test's neighbour medians), never the whole tile;
# 4. :func:`merge_fits`: the decision (:func:`heatcurv.choice.scale.decide_scale`) on the joined fits.
#
# Steps 3-4 run first with the noise gate's candidates only (:data:`GATE_LEVELS`): the decision reads
# the wider ones only under noise, and asks for them by raising :class:`FitsNotSurveyed`.
#
# A fit depends on its centre's ball and what the ball's points' own neighbourhoods hold, so it is
# the same number whichever points lie farther: the fits, and the choice, are those of
# :func:`survey_part` and :func:`merge_surveys` to the last bit (tests/test_survey_rounds.py).


@dataclass(frozen=True)
class KeySurvey:
    """A tile's candidate centres from its keys alone (round 1).

    Attributes
    ----------
    keys : ndarray, shape (c,)
        The tile's ``c <= n_sub`` smallest shifted sampling keys of its core points, increasing.
    positions : ndarray, shape (c, 3)
        Their coordinates in the cloud's frame (stages' units).
    balls : ndarray, shape (c,)
        Their operator ball radii (``neighbours`` nearest), stages' units.
    largest_ball : float
        The largest operator ball radius of the tile's core points, stages' units.
    """

    keys: np.ndarray
    positions: np.ndarray
    balls: np.ndarray
    largest_ball: float


def key_part(points, core, frame: CloudFrame, **options) -> tuple[KeySurvey, np.ndarray, tuple]:
    """Round 1 on a tile: the sampling keys of its core points and its candidate centres.

    Parameters
    ----------
    points : array_like, shape (m, 3)
        The tile's core and halo points, input coordinates (the halo must hold
        each core point's ``neighbours`` nearest: the returned reach).
    core : array_like of bool, shape (m,)
    frame : CloudFrame
        The whole cloud's frame.
    **options
        As :func:`heatcurv.estimate` (:func:`tile_options`).

    Returns
    -------
    survey : KeySurvey
    reach : ndarray, shape (k,)
        The operator ball radius of each core row (``points[core]``, in order),
        stages' units: the key reads no point farther.
    queried : tuple
        ``(prepared, neighbourhood)``: the distinct points and their
        ``neighbours`` nearest, as the operator's (a tiled run keeps the core's,
        :mod:`heatcurv.tiles.neighbours`).
    """
    from scipy.spatial import cKDTree

    from ..geometry.neighbourhood import knn_neighbourhood
    from ..operators.operator import _prepare

    opts = tile_options(options)
    core = np.asarray(core, dtype=bool)
    # the operator's own steps (HeatKernelOperator.from_points): the same distinct points, the same balls
    prepared = _prepare(points, opts, frame)
    X = prepared.points
    base = knn_neighbourhood(X, int(opts.neighbours), tree=cKDTree(X), workers=opts.workers)
    core_rows = np.zeros(X.shape[0], dtype=bool)
    core_rows[prepared.inverse[core]] = True
    keys = geometric_keys(X, base, frame)
    q = min(opts.scale_tuning.n_sub, frame.n_points)
    rows = _candidate_rows(keys, core_rows, q, opts.scale_tuning.seed)
    radius = base.radius
    survey = KeySurvey(shifted_keys(keys[rows], opts.scale_tuning.seed), X[rows], radius[rows],
                       float(radius[core_rows].max()) if core_rows.any() else 0.0)
    return survey, radius[prepared.inverse[core]], (prepared, base)


@dataclass(frozen=True)
class CentrePlan:
    """The cloud's sample centres from every tile's :class:`KeySurvey` (round 2's work list).

    Attributes
    ----------
    tile, rank : ndarray of int, shape (q,)
        The tile of each of the cloud's ``q`` centres, in key order, and its
        place in that tile's :class:`KeySurvey`.
    positions : ndarray, shape (q, 3)
        The centres, stages' units.
    balls : ndarray, shape (q,)
        Their operator ball radii, stages' units.
    sizes : list of int
        Centres each candidate of the ladder is fitted at (the first ones):
        :func:`heatcurv.choice.scale.level_sizes`.
    ladder : list of Scale
    largest_ball : float
        The largest operator ball of any point of the cloud, stages' units.
    """

    tile: np.ndarray
    rank: np.ndarray
    positions: np.ndarray
    balls: np.ndarray
    sizes: list
    ladder: list
    largest_ball: float

    def of_tile(self, tile: int) -> np.ndarray:
        """Places (in the cloud's key order, increasing) of the centres that lie in ``tile``."""
        return np.flatnonzero(self.tile == tile)

    def widths(self, places: np.ndarray, levels: int | None = None) -> np.ndarray:
        """The widest candidate (neighbours) each centre at ``places`` is fitted with, shape (len(places),).

        ``levels``: only the ladder's first ``levels`` candidates are fitted (None: all).
        """
        k = np.array([c.k for c in self.ladder[:levels]])
        sizes = np.asarray(self.sizes[:levels])
        return np.array([k[sizes > p].max() for p in np.asarray(places).tolist()], dtype=np.int64)


def join_keys(surveys: list, frame: CloudFrame, **options) -> CentrePlan:
    """Round 2's work list: the cloud's first ``n_sub`` centres in key order (as :class:`SurveyedFits`)."""
    opts = tile_options(options)
    tuning = opts.scale_tuning
    keys = np.concatenate([s.keys for s in surveys])
    tile = np.concatenate([np.full(s.keys.shape[0], i) for i, s in enumerate(surveys)])
    rank = np.concatenate([np.arange(s.keys.shape[0]) for s in surveys])
    q = min(tuning.n_sub, frame.n_points, keys.shape[0])
    order = np.argsort(keys, kind="stable")[:q]
    ladder = _ladder(int(opts.neighbours), tuning.max_k, frame.n_points)
    return CentrePlan(
        tile[order], rank[order], np.concatenate([s.positions for s in surveys])[order],
        np.concatenate([s.balls for s in surveys])[order], level_sizes(ladder, q), ladder,
        max((s.largest_ball for s in surveys), default=0.0),
    )


#: Round 2 first fits the noise gate's candidates only (the chord and the ladder's first, at every
#: centre): on a clean cloud they decide (:func:`heatcurv.choice.scale.decide_scale` stops there, and
#: :func:`merge_fits` returns), so the wide candidates, most of a survey's work, are fitted only under
#: noise (:class:`FitsNotSurveyed`, then a round of every candidate).
GATE_LEVELS = 1


class FitsNotSurveyed(HeatcurvError):
    """:func:`merge_fits` on a round of the gate's candidates needs a wider candidate: fit every one."""


@dataclass(frozen=True)
class CentreFitsPart:
    """A tile's fits at its centres of the cloud's first ``q`` (round 2).

    Attributes
    ----------
    places : ndarray of int, shape (c,)
        The centres' places in the cloud's key order, increasing.
    fits : dict
        ``{scale label: CentreFits}`` at the first of ``places`` that the
        candidate is fitted at (those below its level size).
    reach : ndarray, shape (c,)
        Each centre's widest fitted ball plus two largest operator balls, stages' units.
    """

    places: np.ndarray
    fits: dict
    reach: np.ndarray

    def take(self, keep) -> CentreFitsPart:
        """The part of these centres where ``keep`` (bool, shape (c,)): the same fits, fewer centres."""
        keep = np.asarray(keep, dtype=bool)
        fits = {label: CentreFits(*(getattr(f, a)[keep[: f.mean.shape[0]]] for a in ("mean", "factor", "sigma", "h")))
                for label, f in self.fits.items()}
        return CentreFitsPart(self.places[keep], fits, self.reach[keep])


def fit_centres(points, frame: CloudFrame, plan: CentrePlan, places, levels: int | None = None, knn=None,
                **options) -> CentreFitsPart:
    """Round 2 on a tile: every candidate at the tile's centres that need it (step 3 of the rounds).

    Parameters
    ----------
    points : array_like, shape (m, 3)
        Every point within each centre's reach (its widest ball plus two
        operator balls), input coordinates; farther points change nothing.
    frame : CloudFrame
    plan : CentrePlan
    places : array_like of int, shape (c,)
        The tile's centres, places in ``plan`` (increasing).
    levels : int, optional
        Fit only the ladder's first ``levels`` candidates (and the chord at
        ``neighbours``): :data:`GATE_LEVELS` for the noise gate's round.
        Default: every candidate.
    knn : callable, optional
        The points' nearest neighbours where they are known already
        (:meth:`heatcurv.operators.operator.HeatKernelOperator.from_points`).
    **options
        As :func:`heatcurv.estimate`.

    Returns
    -------
    CentreFitsPart
    """
    from scipy.spatial import cKDTree

    opts = tile_options(options)
    places = np.asarray(places, dtype=np.int64)
    op = HeatKernelOperator.from_points(points, opts, frame=frame, knn=knn)
    X, base = op.points, op.neighbourhood
    dist, rows = cKDTree(X).query(plan.positions[places])
    if places.size and dist.max() != 0.0:
        raise HeatcurvError("a survey centre is missing from its tile's points (the scratch files changed?)")
    outliers = find_outliers(X, base)
    normals, _ = pca_normals(X, base, taper=opts.taper, rows=rows)
    fitter = CentreFitter(X, op.tree, normals, fit_areas(op.areas, outliers.mask), rows, alpha=opts.alpha,
                          workers=opts.workers)
    base_k = int(opts.neighbours)
    fits = {Scale(base_k, False).label: fitter(Scale(base_k, False), places.shape[0])}
    widest = np.zeros(places.shape[0])
    for scale, size in zip(plan.ladder[:levels], plan.sizes[:levels]):
        count = int(np.searchsorted(places, size))  # this tile's centres among the cloud's first `size`
        fits[scale.label] = fitter(scale, count)
        widest[:count] = np.maximum(widest[:count], fits[scale.label].h[:count] * opts.alpha)
    return CentreFitsPart(places, fits, widest + 2.0 * plan.largest_ball)


class JoinedFits:
    """The fits of every tile's :class:`CentreFitsPart`, in the cloud's key order (``fits(scale, size)``)."""

    def __init__(self, parts: list, plan: CentrePlan):
        self.parts, self.plan = parts, plan
        self.positions = plan.positions

    def __call__(self, scale: Scale, size: int) -> CentreFits:
        out = {f: np.empty(size) for f in ("mean", "factor", "sigma", "h")}
        filled = np.zeros(size, dtype=bool)
        for part in self.parts:
            fits = part.fits.get(scale.label)
            if fits is None:
                continue
            places = part.places[: fits.mean.shape[0]]
            mine = places < size
            for f in out:
                out[f][places[mine]] = getattr(fits, f)[mine]
            filled[places[mine]] = True
        if not any(scale.label in part.fits for part in self.parts):
            # a round of the noise gate's candidates only (GATE_LEVELS), and the choice needs a wider one
            raise FitsNotSurveyed(f"the decision needs {scale.label}, which this round did not fit")
        if not filled.all():
            missing = int((~filled).sum())
            raise HeatcurvError(f"no tile fitted {scale.label} at {missing} of the centres the choice needs")
        return CentreFits(**out)


def merge_fits(parts: list, plan: CentrePlan, frame: CloudFrame, **options) -> CloudChoices:
    """The whole cloud's choices from round 2's fits (what :func:`merge_surveys` gives from one-round surveys)."""
    return _decide(JoinedFits(parts, plan), plan.positions, frame, tile_options(options))
