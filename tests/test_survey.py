"""heatcurv.choice.survey and estimate(choices=): a part of a cloud computes as the whole cloud would.

A tiled run (heatcurv.tiles) surveys its tiles' sample centres, joins them into the cloud's
kernel choice, and computes each tile with its halo under that choice. Here the tiles are cut
by hand: wherever a point's reach (``info["reach"]``) lies inside the points its tile holds,
its values must equal the in-memory run's to the last bit.
"""

import warnings

import numpy as np
import pytest

import heatcurv
from heatcurv.choice.choices import FrameStats
from heatcurv.choice.survey import merge_surveys, survey_part, tile_options
from heatcurv.errors import HeatcurvError
from heatcurv.flags.reliability import ReliabilityInputs, cloud_flags

FIELDS = ("normals", "mean", "gaussian", "k1", "k2", "area", "fit_radius", "border", "outlier")


def _cloud(n, noise, seed=3):
    sample = heatcurv.surfaces.Torus(0.6, 1.4).sample(n, "random", seed=seed)
    rng = np.random.default_rng(seed)
    diagonal = np.linalg.norm(np.ptp(sample.points, axis=0))
    # UTM-like coordinates: the tiles must centre exactly as the whole cloud does
    return sample.points + rng.normal(scale=noise * diagonal, size=sample.points.shape) + [5e5, 4e6, 100.0]


def _halves(points, halo):
    """Two tiles split at x's median, each with every point within ``halo`` of its box."""
    split = np.median(points[:, 0])
    tiles = []
    for side in (False, True):
        core = (points[:, 0] >= split) == side
        low, high = points[core].min(axis=0) - halo, points[core].max(axis=0) + halo
        rows = np.flatnonzero(np.all((points >= low) & (points <= high), axis=1))
        tiles.append((rows, core[rows], low, high))
    return tiles


def _tiled(points, halo, **options):
    stats = FrameStats()
    for chunk in np.array_split(points, 3):
        stats.add(chunk)
    frame = stats.frame()
    tiles = _halves(points, halo)
    choices = merge_surveys([survey_part(points[rows], core, frame, **options) for rows, core, _, _ in tiles],
                            frame, **options)
    out = {f: None for f in FIELDS}
    certified = np.zeros(len(points), dtype=bool)
    parts = []
    for rows, core, low, high in tiles:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = heatcurv.estimate(points[rows], choices=choices, **options)
        mine = rows[core]
        for f in FIELDS:
            value = getattr(res, f)
            if out[f] is None:
                out[f] = np.zeros((len(points),) + value.shape[1:], dtype=value.dtype)
            out[f][mine] = value[core]
        # the certificate: the point's reach inside the box its tile read (no point lies beyond the
        # cloud's own box: there the tile misses nothing)
        p = points[mine]
        low = np.where(low <= points.min(axis=0), -np.inf, low)
        high = np.where(high >= points.max(axis=0), np.inf, high)
        room = np.minimum(p - low, high - p).min(axis=1)
        certified[mine] = res.info["reach"][core] <= room
        parts.append((mine, res.info["reliability"].take(np.flatnonzero(core))))
    joined = ReliabilityInputs(*[np.concatenate([getattr(b, f) for _, b in parts])
                                 for f in ("local", "residual", "width", "rho", "counted")])
    reliable = np.empty(len(points), dtype=bool)
    reliable[np.concatenate([a for a, _ in parts])] = cloud_flags(joined)[0]
    out["reliable"] = reliable
    return out, certified, choices


@pytest.fixture(scope="module")
def noisy():
    points = _cloud(6000, 0.0012)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return points, heatcurv.estimate(points, orient="up")


def test_tiles_with_halos_equal_the_whole_cloud_bit_for_bit(noisy):
    points, whole = noisy
    out, certified, choices = _tiled(points, 2.5, orient="up")
    assert certified.all()
    # the survey's choice is the in-memory one
    assert choices.scale.sigma == whole.info["scale"].sigma
    assert whole.info["scale"].k_max > 60  # a noisy cloud: wide kernels fitted at anchors
    for f in FIELDS + ("reliable",):
        np.testing.assert_array_equal(out[f], getattr(whole, f), err_msg=f)


def test_reach_certifies_exactly_the_points_a_narrow_halo_computes_right(noisy, records):
    points, whole = noisy
    # the values' reach (the standard errors reach several balls further: tests/tiles/test_tiles_lidar_identity.py)
    out, certified, _ = _tiled(points, 0.6, orient="up", se=False)
    assert 0.1 < certified.mean() < 0.9  # this halo (kernel of 240 neighbours) is too narrow for some
    for f in ("normals", "mean", "k1", "k2", "area"):
        np.testing.assert_array_equal(out[f][certified], getattr(whole, f)[certified], err_msg=f)
    # and the halo is too narrow for the others: the certificate is not vacuous
    differs = np.abs(out["mean"] - whole.mean) > 1e-9 * np.abs(whole.mean)
    assert differs[~certified].mean() > 0.5
    # how conservative the certificate is: the points it leaves out (of all), and those of them whose values
    # are right all the same
    records.check(
        "survey/torus-random-6000-noise0.0012-halo0.6", uncertified=100 * (1 - certified.mean()),
        uncertified_but_equal=100 * (1 - differs[~certified].mean()),
    )


def test_a_clean_cloud_gets_one_width_from_the_survey():
    points = _cloud(3000, 0.0)
    stats = FrameStats()
    stats.add(points)
    frame = stats.frame()
    tiles = _halves(points, 10.0)
    choices = merge_surveys([survey_part(points[r], c, frame) for r, c, _, _ in tiles], frame)
    assert choices.scale.scale == heatcurv.fits.balls.Scale(60, False)
    assert choices.scale.centres is None


@pytest.mark.parametrize("options, word", [
    ({"method": "paper"}, "default method only"),
    ({"area_method": "system"}, "default method only"),
    ({"radius": 0.3}, "radius"),
])
def test_options_a_tile_cannot_honour_are_refused(options, word):
    with pytest.raises(HeatcurvError, match=word):
        tile_options(options)


def _tower(n, sigma, height, seed=0, side=100.0, foot=24.0):
    """Ground around a square tower ``foot`` wide and ``height`` tall (walls and roof), Gaussian noise."""
    rng = np.random.default_rng(seed)
    areas = np.array([side**2 - foot**2, 4 * foot * height, foot**2])
    ng, nw = (n * areas[:2] / areas.sum()).astype(int)
    ground = rng.uniform(-side / 2, side / 2, (2 * ng, 2))
    ground = ground[(np.abs(ground) > foot / 2).any(axis=1)][:ng]
    along, z, face = rng.uniform(-foot / 2, foot / 2, nw), rng.uniform(0, height, nw), rng.integers(0, 4, nw)
    across = np.where(face % 2 == 0, foot / 2, -foot / 2)
    walls = np.where((face < 2)[:, None], np.column_stack([along, across, z]), np.column_stack([across, along, z]))
    roof = np.column_stack([rng.uniform(-foot / 2, foot / 2, (n - ng - nw, 2)), np.full(n - ng - nw, height)])
    points = np.concatenate([np.column_stack([ground, np.zeros(ng)]), walls, roof])
    return points + rng.normal(scale=sigma, size=points.shape) + [5e5, 5e6, 100.0]


def test_under_strong_noise_a_walls_reach_covers_the_anchors_its_side_was_voted_from():
    # noise half a kernel width: the anchors' own normals are oriented over the anchors' graph; a
    # wall anchor takes its side from the roof's or the ground's anchors by local votes, so a
    # mid-wall point's values read that far. Measured: reach 195-220 m, distances 80-100 m (before,
    # the anchors' votes were not counted: 29-48 m, and a tile could certify a side it never saw)
    height = 200.0
    points = _tower(12000, 1.8, height)
    stats = FrameStats()
    stats.add(points)
    frame = stats.frame()
    choices = merge_surveys([survey_part(points, np.ones(len(points), dtype=bool), frame, orient="up")], frame,
                            orient="up")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = heatcurv.estimate(points, choices=choices, orient="up")
    assert res.info["orientation"].on_anchors > 0  # the strong-noise path
    local = points - [5e5, 5e6, 100.0]
    to_edge = np.minimum(local[:, 2], height - local[:, 2])
    mid_wall = (np.abs(np.abs(local[:, :2]).max(axis=1) - 12.0) < 3.0) & (to_edge > 0.4 * height)
    assert mid_wall.sum() > 1000
    assert np.all(res.info["reach"][mid_wall] >= to_edge[mid_wall])


def test_each_tile_fits_only_its_candidates_below_the_key_bound(noisy):
    from heatcurv.choice import survey as survey_module
    from heatcurv.choice.scale import level_sizes

    points, whole = noisy
    stats = FrameStats()
    stats.add(points)
    frame = stats.frame()
    tiles = _halves(points, 2.5)
    bounded = [survey_part(points[r], c, frame, orient="up") for r, c, _, _ in tiles]
    full = [survey_part(points[r], c, frame, orient="up", bounded=False) for r, c, _, _ in tiles]
    q = 2000
    bound = survey_module.key_bound(q, len(points))
    assert bound == pytest.approx((2000 + 8 * np.sqrt(2000)) / 6000)
    for b, f in zip(bounded, full):
        assert b.bound == bound and f.bound == 1.0
        assert np.all(b.keys < bound) and f.keys.shape[0] == q  # each half holds 3000 points
        # the bounded candidates are the full list's first ones: the same fits there
        c = b.keys.shape[0]
        np.testing.assert_array_equal(b.keys, f.keys[:c])
        for label, fits in b.fits.items():
            size = fits.mean.shape[0]
            np.testing.assert_array_equal(fits.mean, f.fits[label].mean[:size], err_msg=label)
    # two halves of 3000 points fit 2 x (2000 + 8 sqrt(2000)) / 3 centres at the base width, not 2 x 2000
    assert sum(b.keys.shape[0] for b in bounded) < 0.62 * sum(f.keys.shape[0] for f in full)
    # a wide candidate is fitted at the halves' keys below its own bound: about half its centres each
    ladder = survey_module._ladder(60, None, len(points))
    sizes = dict(zip((s.label for s in ladder), level_sizes(ladder, q)))
    widest = ladder[-1].label
    fitted = [b.fits[widest].mean.shape[0] for b in bounded]
    below = survey_module.key_bound(sizes[widest], len(points))
    assert fitted == [min(sizes[widest], int((f.keys < below).sum())) for f in full]
    assert sizes[widest] <= sum(fitted) < 0.75 * sum(f.fits[widest].mean.shape[0] for f in full)
    # and the choice is the one every candidate gives, which is the in-memory one
    a, b = merge_surveys(bounded, frame, orient="up"), merge_surveys(full, frame, orient="up")
    assert a.scale.sigma == b.scale.sigma == whole.info["scale"].sigma
    assert a.scale.scale == b.scale.scale
    np.testing.assert_array_equal(a.scale.k_centre, b.scale.k_centre)


def test_candidates_short_of_the_choice_are_an_error_the_driver_catches(noisy, monkeypatch):
    from heatcurv.choice import survey as survey_module

    points, _ = noisy
    stats = FrameStats()
    stats.add(points)
    frame = stats.frame()
    # a bound below the cloud's 2000th key: the halves hold fewer candidates than the choice reads
    monkeypatch.setattr(survey_module, "KEY_BOUND_SIGMAS", -10.0)
    parts = [survey_part(points[r], c, frame, orient="up") for r, c, _, _ in _halves(points, 2.5)]
    assert sum(p.keys.shape[0] for p in parts) < 2000
    with pytest.raises(survey_module.CandidatesShort, match="fewer than the 2000"):
        merge_surveys(parts, frame, orient="up")


def test_a_wide_kernel_fitted_short_of_its_centres_is_candidates_short_too(noisy, monkeypatch):
    from heatcurv.choice import survey as survey_module

    points, _ = noisy
    stats = FrameStats()
    stats.add(points)
    frame = stats.frame()
    real = survey_module.key_bound
    # the base width's bound holds, the wider ones' fall below their centres: each half fits too few
    monkeypatch.setattr(survey_module, "key_bound", lambda size, n: real(size, n) if size == 2000 else 0.5 * size / n)
    parts = [survey_part(points[r], c, frame, orient="up") for r, c, _, _ in _halves(points, 2.5)]
    assert sum(p.keys.shape[0] for p in parts) >= 2000
    with pytest.raises(survey_module.CandidatesShort, match="did not fit"):
        merge_surveys(parts, frame, orient="up")
