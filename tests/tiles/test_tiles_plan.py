"""The plan: statistics, the k-d tiling, the counting sort into scratch, sizes and budgets."""

import numpy as np
import pytest

from heatcurv.errors import HeatcurvError
from heatcurv.tiles.plan import make_tiling, parse_size, read_rows, scan_stats, scatter
from heatcurv.tiles.sources import open_source


@pytest.fixture(scope="module")
def cloud(tmp_path_factory):
    """Uneven density: a dense square beside a sparse one, 30000 points."""
    rng = np.random.default_rng(4)
    dense = rng.uniform([0, 0, 0], [10, 10, 1], (24000, 3))
    sparse = rng.uniform([10, 0, 0], [40, 10, 1], (6000, 3))
    points = rng.permutation(np.concatenate([dense, sparse]))
    path = tmp_path_factory.mktemp("plan") / "cloud.npy"
    np.save(path, points)
    return path, points


def test_stats(cloud):
    stats = scan_stats(open_source(cloud[0]))
    points = cloud[1]
    assert stats.count == stats.finite == 30000
    assert stats.low == tuple(points.min(axis=0)) and stats.high == tuple(points.max(axis=0))
    assert np.allclose(stats.centroid, points.mean(axis=0), rtol=1e-14)
    rms = np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1)))
    assert stats.rms_radius == pytest.approx(rms, rel=1e-12)


def test_tiles_balance_counts_and_the_scatter_is_a_counting_sort(cloud, tmp_path):
    source = open_source(cloud[0])
    stats = scan_stats(source)
    tiling = make_tiling(source, stats, 5000)
    counts = np.array(tiling.counts)
    assert counts.sum() == 30000 and counts.max() <= 5000 and len(counts) <= 12  # halved boxes: >= 2500 each
    scatter(source, tiling, tmp_path)
    seen = []
    for t in range(len(counts)):
        points, rows = read_rows(tmp_path, int(tiling.offsets[t]), int(tiling.offsets[t + 1]))
        assert np.array_equal(points, cloud[1][rows])  # each point with its own row number
        assert np.all(np.diff(rows) > 0)  # input order inside a tile
        low, high = tiling.box(t)
        assert np.all((points >= low) & (points <= high))
        seen.append(rows)
    assert np.array_equal(np.sort(np.concatenate(seen)), np.arange(30000))


@pytest.mark.parametrize("text, size", [("3G", 3 * 2**30), ("500M", 500 * 2**20), ("1.5 GB", int(1.5 * 2**30)),
                                        ("2GiB", 2 * 2**30), ("123", 123), (4096, 4096)])
def test_parse_size(text, size):
    assert parse_size(text) == size


@pytest.mark.parametrize("text", ["3X", "", "-1G", "0"])
def test_parse_size_refuses(text):
    with pytest.raises(HeatcurvError, match="memory size"):
        parse_size(text)
