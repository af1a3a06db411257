"""A tiled run's kernel choice, measured tile by tile: the cloud-wide part of :func:`heatcurv.scale.select_scale`.

In memory, :func:`heatcurv.scale.select_scale` fits the candidate kernels at
sample centres (the points with the smallest sampling keys, in key order,
the wider candidates at a prefix of them) and then decides from those fits
alone (:func:`heatcurv.scale.decide_scale`). A centre's fit depends only on the
points within its ball, so a tiled run can fit the centres where they lie:

1. each tile fits every candidate at *its* core points of smallest keys
   (:func:`survey_part`): the cloud's first ``s`` centres that fall in a tile
   are among the tile's first ``s``, so every fit the decision reads is made
   by some tile;
2. the driver joins the tiles' fits in key order and runs the same decision
   (:func:`merge_surveys`), which gives :class:`heatcurv.choices.CloudChoices`
   for every tile.

The fits use unoriented normals: a centre's fits at all widths share its
normal, and the decision reads only magnitudes and differences at one centre,
which a flipped normal leaves unchanged (to rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .choices import CloudChoices, CloudFrame
from .errors import HeatcurvError
from .neighbourhood import Neighbourhood
from .normals import pca_normals
from .operator import HeatKernelOperator
from .options import Options, rename_aliases, resolve_options
from .outliers import find_outliers
from .sampling import geometric_keys, shifted_keys
from .scale import CentreFits, CentreFitter, Scale, _ladder, decide_scale, level_sizes

__all__ = ["CentreSurvey", "check_tileable", "merge_surveys", "survey_part", "tile_options"]


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
    opts = resolve_options(options.pop("method", "default"), **rename_aliases(options, "estimate"))
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
        (:func:`heatcurv.scale.level_sizes`).
    reach : ndarray, shape (c,)
        How far from each candidate its fits read points (the widest ball plus
        one operator ball for its neighbours' areas and normal), stages' units:
        the tile's halo must hold that much.
    """

    keys: np.ndarray
    positions: np.ndarray
    fits: dict
    reach: np.ndarray


def _candidate_rows(keys: np.ndarray, core: np.ndarray, size: int, seed: int) -> np.ndarray:
    """The ``size`` core rows of smallest shifted keys, in key order."""
    rows = np.flatnonzero(core)
    shifted = shifted_keys(keys[rows], seed)
    order = np.argsort(shifted, kind="stable")[:size]
    return rows[order]


def survey_part(points, core, frame: CloudFrame, **options) -> CentreSurvey:
    """Fit the candidate kernels at a tile's candidate centres (step 1 of the module).

    Parameters
    ----------
    points : array_like, shape (m, 3)
        The tile's points with their halo, input coordinates.
    core : array_like of bool, shape (m,)
        The tile's own points (the candidates are drawn from them).
    frame : CloudFrame
        The whole cloud's frame.
    **options
        As :func:`heatcurv.estimate` (:func:`tile_options`).

    Returns
    -------
    CentreSurvey
    """
    opts = tile_options(options)
    tuning = opts.scale_tuning
    core = np.asarray(core, dtype=bool)
    op = HeatKernelOperator.from_points(points, opts, frame=frame)
    X, base = op.points, op.neighbourhood
    prepared = op.prepared
    core_rows = np.zeros(X.shape[0], dtype=bool)
    core_rows[prepared.inverse[core]] = True
    keys = geometric_keys(X, base, frame)
    outliers = find_outliers(X, base)
    normals, _ = pca_normals(X, base, taper=opts.taper)
    fit_areas = np.where(outliers.mask, 0.0, np.maximum(op.areas, 0.0))
    ladder = _ladder(int(opts.neighbours), tuning.max_k, frame.n_points)
    q = min(tuning.n_sub, frame.n_points)
    sizes = level_sizes(ladder, q)
    rows = _candidate_rows(keys, core_rows, q, tuning.seed)
    fitter = CentreFitter(X, op.tree, normals[rows], fit_areas, rows, alpha=opts.alpha, workers=opts.workers)
    base_k = int(opts.neighbours)
    fits = {Scale(base_k, False).label: fitter(Scale(base_k, False), min(q, rows.shape[0]))}
    widest = np.zeros(rows.shape[0])
    for scale, size in zip(ladder, sizes):
        size = min(size, rows.shape[0])
        fits[scale.label] = fitter(scale, size)
        widest[:size] = np.maximum(widest[:size], fits[scale.label].h[:size] * opts.alpha)
    reach = widest + _largest_ball(base)
    return CentreSurvey(shifted_keys(keys[rows], tuning.seed), X[rows], fits, reach)


def _largest_ball(base: Neighbourhood) -> float:
    """The largest operator ball radius of the tile (a neighbour's area and normal reach that far)."""
    return float(base.radius.max()) if base.n_points else 0.0


class SurveyedFits:
    """The joined fits of every tile, with the interface of :class:`heatcurv.scale.CentreFitter`."""

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
                raise HeatcurvError(f"tile {i} did not fit {scale.label} at the centres the choice needs")
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
    """
    opts = tile_options(options)
    tuning = opts.scale_tuning
    q = min(tuning.n_sub, frame.n_points, sum(s.keys.shape[0] for s in surveys))
    fits = SurveyedFits(surveys, q)
    choice = decide_scale(
        fits, fits.positions, frame.n_points, base_k=int(opts.neighbours), max_k=tuning.max_k, tau=tuning.tau,
        clean_ratio=tuning.clean_ratio, fixed_k=None if opts.scale == "auto" else int(opts.scale),
        workers=opts.workers,
    )
    return CloudChoices(frame, choice)
