"""The survey in two rounds (keys, then fits at the cloud's centres only) equals the one-round survey bit for bit.

heatcurv.choice.survey's rounds fit each candidate only at the cloud's sample centres, each over the points
within its reach; :func:`heatcurv.choice.survey.survey_part` fits every tile's own candidates over the
tile and a wide halo. The fits the decision reads, and so the choice, must be the same numbers.
"""

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv.choice.choices import FrameStats
from heatcurv.choice.survey import (
    GATE_LEVELS,
    FitsNotSurveyed,
    JoinedFits,
    SurveyedFits,
    fit_centres,
    join_keys,
    key_part,
    merge_fits,
    merge_surveys,
    survey_part,
)


def _cloud(n, noise, seed=3):
    sample = heatcurv.surfaces.Torus(0.6, 1.4).sample(n, "random", seed=seed)
    rng = np.random.default_rng(seed)
    diagonal = np.linalg.norm(np.ptp(sample.points, axis=0))
    return sample.points + rng.normal(scale=noise * diagonal, size=sample.points.shape) + [5e5, 4e6, 100.0]


def _tiles(points, halo, parts=3):
    """Slabs across x of equal counts, each with every point within ``halo`` of its box."""
    cuts = np.quantile(points[:, 0], np.linspace(0, 1, parts + 1)[1:-1])
    label = np.searchsorted(cuts, points[:, 0], side="right")
    out = []
    for t in range(parts):
        core = label == t
        low, high = points[core].min(axis=0) - halo, points[core].max(axis=0) + halo
        rows = np.flatnonzero(np.all((points >= low) & (points <= high), axis=1))
        out.append((rows, core[rows]))
    return out


def _frame(points):
    stats = FrameStats()
    stats.add(points)
    return stats.frame()


def _keyed(noise):
    """The 6000-point torus in three slabs, its frame, round 1's plan of the cloud's centres, and each
    slab's core reach from round 1."""
    points = _cloud(6000, noise)
    frame = _frame(points)
    tiles = _tiles(points, 2.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        keys = [key_part(points[rows], core, frame) for rows, core in tiles]
    return points, frame, tiles, join_keys([survey for survey, _, _ in keys], frame), [reach for _, reach, _ in keys]


@pytest.mark.parametrize("noise", [0.0012, 0.0])
def test_two_rounds_fit_the_same_numbers_and_choose_the_same_widths(noise):
    points, frame, tiles, plan, reaches = _keyed(noise)
    for (_, core), reach in zip(tiles, reaches):
        assert reach.shape == (int(core.sum()),) and np.all(reach > 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        one = [survey_part(points[rows], core, frame) for rows, core in tiles]
        old = merge_surveys(one, frame)
        parts, kept = [], []
        for t, (rows, _) in enumerate(tiles):
            places = plan.of_tile(t)
            whole = fit_centres(points[rows], frame, plan, places)
            # only the points within each centre's reach: the same fits to the last bit
            centres = plan.positions[places] * frame.unit + frame.offset
            near = cKDTree(points[rows]).query_ball_point(centres, whole.reach * frame.unit)
            keep = np.unique(np.concatenate([np.asarray(i, dtype=np.int64) for i in near]))
            kept.append(keep.size / rows.size)
            part = fit_centres(points[rows][keep], frame, plan, places)
            for label, fits in whole.fits.items():
                for f in ("mean", "factor", "sigma", "h"):
                    np.testing.assert_array_equal(getattr(part.fits[label], f), getattr(fits, f), err_msg=label)
            parts.append(part)
        new = merge_fits(parts, plan, frame)
    print("kept", kept)
    assert min(kept) < 0.9  # a real restriction somewhere
    # the centres are the one-round survey's, in the same order, and every fit the decision reads is equal
    joined, surveyed = JoinedFits(parts, plan), SurveyedFits(one, plan.positions.shape[0])
    np.testing.assert_array_equal(joined.positions, surveyed.positions)
    levels = [(heatcurv.fits.balls.Scale(60, False), plan.positions.shape[0])] + list(zip(plan.ladder, plan.sizes))
    for scale, size in levels:
        a, b = joined(scale, size), surveyed(scale, size)
        for f in ("mean", "factor", "sigma", "h"):
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f"{scale.label} {f}")
    assert new.scale.scale == old.scale.scale and new.scale.sigma == old.scale.sigma
    if old.scale.k_centre is None:
        assert new.scale.k_centre is None and noise == 0.0  # a clean cloud: one width
    else:
        np.testing.assert_array_equal(new.scale.k_centre, old.scale.k_centre)
        assert old.scale.k_centre.max() > 60  # the noisy cloud chose wide kernels somewhere


@pytest.mark.parametrize("noise", [0.0, 0.0012])
def test_the_noise_gates_round_decides_a_clean_cloud_and_defers_a_noisy_one(noise, records):
    # round 2 fits the gate's candidates first (the chord and the ladder's first); a clean cloud's
    # choice needs nothing wider, so its wide fits (most of a survey's work) are never made
    points, frame, tiles, plan, _ = _keyed(noise)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gate = [fit_centres(points[rows], frame, plan, plan.of_tile(t), GATE_LEVELS)
                for t, (rows, _) in enumerate(tiles)]
        every = [fit_centres(points[rows], frame, plan, plan.of_tile(t)) for t, (rows, _) in enumerate(tiles)]
        full = merge_fits(every, plan, frame)
        assert all(set(part.fits) == {"chord-60", plan.ladder[0].label} for part in gate)
        # the gate's fits are the full round's, bit for bit, and read less far
        for g, e in zip(gate, every):
            for label, fits in g.fits.items():
                np.testing.assert_array_equal(fits.sigma, e.fits[label].sigma)
            assert np.all(g.reach <= e.reach)
        if noise:
            assert full.scale.k_centre is not None and full.scale.k_centre.max() > 60
            with pytest.raises(FitsNotSurveyed, match="denoised-120"):
                merge_fits(gate, plan, frame)
        else:
            decided = merge_fits(gate, plan, frame)
            assert decided.scale.scale == full.scale.scale == heatcurv.fits.balls.Scale(60, False)
            assert decided.scale.sigma == full.scale.sigma
            # the widest candidate here holds 1500 neighbours, a ball 5x the gate's; with the two operator
            # balls every reach adds, the gate's farthest read is this share (%) of the full round's
            share = max(g.reach.max() / e.reach.max() for g, e in zip(gate, every))
            records.check("survey_rounds/torus-random-6000-noise0-gate", reach=100 * share)


def test_a_tile_whose_centres_are_all_past_the_wide_candidates_prefix_fits_only_its_own():
    # 100M points in 512 tiles left most tiles with a few centres, none among the wide candidates'
    # first: the fit of zero centres raised IndexError (survey of tile 1 of 512 failed)
    points, frame, _, plan, _ = _keyed(0.0012)
    late = np.arange(min(plan.sizes), plan.positions.shape[0])[-50:]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = fit_centres(points, frame, plan, late)
    assert late.size == 50 and len(part.fits) == len(plan.ladder) + 1
    assert min(plan.sizes) <= late[0]  # some candidate is fitted at none of these centres
    for scale, size in zip(plan.ladder, plan.sizes):
        assert part.fits[scale.label].mean.shape == ((50,) if size > late[0] else (0,))
    assert part.fits[plan.ladder[0].label].mean.shape == (50,) and np.all(np.isfinite(part.reach))
