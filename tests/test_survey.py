"""heatcurv.survey and estimate(choices=): a part of a cloud computes as the whole cloud would.

A tiled run (heatcurv.tiles) surveys its tiles' sample centres, joins them into the cloud's
kernel choice, and computes each tile with its halo under that choice. Here the tiles are cut
by hand: wherever a point's reach (``info["reach"]``) lies inside the points its tile holds,
its values must equal the in-memory run's to the last bit.
"""

import warnings

import numpy as np
import pytest

import heatcurv
from heatcurv.choices import FrameStats
from heatcurv.errors import HeatcurvError
from heatcurv.reliability import ReliabilityInputs, cloud_flags
from heatcurv.survey import merge_surveys, survey_part, tile_options

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


def test_reach_certifies_exactly_the_points_a_narrow_halo_computes_right(noisy):
    points, whole = noisy
    out, certified, _ = _tiled(points, 0.6, orient="up")
    # measured: 63 % of the points certified with this halo (kernel of 240 neighbours), and 69 % of
    # the others differ
    assert 0.1 < certified.mean() < 0.9
    for f in ("normals", "mean", "k1", "k2", "area"):
        np.testing.assert_array_equal(out[f][certified], getattr(whole, f)[certified], err_msg=f)
    # and the halo is too narrow for the others: the certificate is not vacuous
    differs = np.abs(out["mean"] - whole.mean) > 1e-9 * np.abs(whole.mean)
    assert differs[~certified].mean() > 0.5


def test_a_clean_cloud_gets_one_width_from_the_survey():
    points = _cloud(3000, 0.0)
    stats = FrameStats()
    stats.add(points)
    frame = stats.frame()
    tiles = _halves(points, 10.0)
    choices = merge_surveys([survey_part(points[r], c, frame) for r, c, _, _ in tiles], frame)
    assert choices.scale.scale == heatcurv.scale.Scale(60, False)
    assert choices.scale.centres is None


@pytest.mark.parametrize("options, word", [
    ({"method": "paper"}, "default method only"),
    ({"area_method": "system"}, "default method only"),
    ({"radius": 0.3}, "radius"),
])
def test_options_a_tile_cannot_honour_are_refused(options, word):
    with pytest.raises(HeatcurvError, match=word):
        tile_options(options)
