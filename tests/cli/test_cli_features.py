"""heatcurv.cli.features: ``heatcurv features`` finds a crease."""

import numpy as np
from cli_helpers import run

from heatcurv import io, surfaces


def test_features_command_finds_the_crease(tmp_path, records):
    fold = surfaces.FoldedSquare(interior_angle=90).sample(2500, "random", seed=0)
    path = tmp_path / "fold.xyz"
    io.write_points(path, fold.points)
    out = run("features", path, "-o", tmp_path / "fold.csv")
    assert out.returncode == 0, out.stderr
    assert "sharp features:" in out.stdout
    back = io.read_points(tmp_path / "fold.csv")
    assert list(back.fields) == ["feature", "feature_score"]
    mask = back.fields["feature"].astype(bool)
    distance = fold.fold_distance
    assert mask.sum() > 20
    # the features' distances to the fold, in % of the square's width (2)
    records.check(
        "cli_features/fold-90-random-2500", median_distance=100 * np.median(distance[mask]) / 2,
        max_distance=100 * distance[mask].max() / 2,
    )


def test_features_writes_float32_scores_unless_float64(tmp_path):
    fold = surfaces.FoldedSquare(interior_angle=90).sample(1500, "random", seed=1)
    path = tmp_path / "fold.ply"
    io.write_points(path, fold.points)
    for flag, kind in (((), np.float32), (("--float64",), np.float64)):
        out = run("features", path, "-o", tmp_path / "out.npz", "-q", *flag)
        assert out.returncode == 0, out.stderr
        with np.load(tmp_path / "out.npz") as archive:
            assert archive.files == ["points", "feature", "feature_score"]
            assert archive["feature_score"].dtype == kind and archive["feature"].dtype == np.bool_
            assert archive["points"].dtype == np.float64  # coordinates never narrowed
