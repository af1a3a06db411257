"""Sharp features from the heat-kernel mean curvature, on the paper's folded square (Fig 10)."""

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.features import feature_score, otsu_threshold


def fold(angle):
    sample = surfaces.FoldedSquare(interior_angle=angle).sample(961, "grid")  # the paper's n = 961
    return sample, heatcurv.estimate(sample.points)


def test_feature_score_closed_form():
    # at a crease of turning angle phi: kappa_M h = 2 sin(phi/2) / sqrt(pi)
    h = 0.02
    for phi in (1.0, 30.0, 90.0, 150.0):
        kappa = 2 * np.sin(np.radians(phi) / 2) / (np.sqrt(np.pi) * h)
        assert feature_score(np.array([kappa, -kappa]), np.full(2, h)) == pytest.approx([phi, phi], rel=1e-12)
    assert feature_score(np.array([1e9]), np.array([1.0]))[0] == 180.0


def fold_errors(sample, res, feat, turn) -> dict:
    """How far the mask reaches from the crease (% of h), and the crease's worst score against the turning angle (%)."""
    on_fold = sample.fold_distance < 1e-9
    h = np.median(res.spacing)  # default: h = d_60 / 2, about 2.1 grid steps here
    return {
        "reach": 100 * sample.fold_distance[feat.mask].max() / h,
        "score": 100 * np.abs(feat.score[on_fold] / turn - 1).max(),
    }


@pytest.mark.parametrize("angle", [60, 90, 120, 150])
def test_auto_threshold_finds_the_fold(angle, records):
    sample, res = fold(angle)
    feat = heatcurv.sharp_features(res)
    assert feat.mask[sample.fold_distance < 1e-9].all()
    # the score estimates the turning angle, below it at the sharpest folds (the 60 degree fold has its
    # sheets 1.7 h apart 1 h from the crease)
    records.check(f"features/fold-{angle}-grid-961", **fold_errors(sample, res, feat, 180.0 - angle))
    assert feat.threshold >= 10.0


@pytest.mark.parametrize("angle, threshold", [(170, 3.0), (179, 0.3)])
def test_user_threshold_finds_shallow_folds(angle, threshold, records):
    # turning 10 and 1 degrees: below the automatic floor of 10 degrees, found with a user threshold
    sample, res = fold(angle)
    feat = heatcurv.sharp_features(res, threshold=threshold)
    assert feat.mask[sample.fold_distance < 1e-9].all()
    records.check(f"features/fold-{angle}-grid-961-threshold", **fold_errors(sample, res, feat, 180.0 - angle))
    assert feat.threshold == threshold
    if angle == 179:
        assert not heatcurv.sharp_features(res).mask.any()  # the automatic floor ignores 1 degree


@pytest.mark.parametrize(
    "sample",
    [
        surfaces.Sphere().sample(4000, "fibonacci"),
        surfaces.Torus().sample(8000, "fibonacci"),
        surfaces.Plane().sample(900, "jittered", seed=1),
    ],
    ids=["sphere", "torus", "plane"],
)
def test_smooth_surfaces_have_no_features(sample, request, records):
    # the largest score (a smooth surface turns by 0 degrees) stays under the automatic threshold of 3x
    # the median score and the 10 degree floor
    feat = heatcurv.sharp_features(sample.points)
    assert not feat.mask.any()
    records.check(f"features/smooth-{request.node.callspec.id}", score_max_deg=feat.score.max())


def test_otsu_splits_two_populations():
    rng = np.random.default_rng(0)
    values = np.concatenate([rng.normal(1.0, 0.2, 5000), rng.normal(6.0, 0.5, 300)])
    thr = otsu_threshold(values)
    assert 2.0 < thr < 5.0
    assert otsu_threshold(np.full(10, 3.0)) == 3.0


def test_feature_errors():
    sample, res = fold(120)
    with pytest.raises(HeatcurvError, match=r"threshold = -1 is outside its range \[0, 180\]: a turning angle"):
        heatcurv.sharp_features(res, threshold=-1)
    with pytest.raises(HeatcurvError, match="cannot change a result"):
        heatcurv.sharp_features(res, alpha=3.0)
    direct = heatcurv.sharp_features(sample.points)
    np.testing.assert_allclose(direct.score, heatcurv.sharp_features(res).score)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"threshold": float("nan")}, r"^threshold must be a number in \[0, 180\], got nan$"),
        ({"threshold": 200.0}, r"^threshold = 200 is outside its range \[0, 180\]"),
        ({"min_angle": -1.0}, r"^min_angle = -1 is outside its range"),
        ({"background": float("nan")}, r"^background must be a number in \[0, 1000\], got nan$"),
    ],
)
def test_feature_numbers_are_range_checked(options, message):
    pts = heatcurv.surfaces.Sphere().sample(200, "random", seed=1).points
    with pytest.raises(heatcurv.HeatcurvError, match=message):
        heatcurv.sharp_features(pts, **options)
