"""The tile phase reads back the neighbourhoods its survey queried (heatcurv.tiles.neighbours)."""

import os

import numpy as np
import pytest
from scipy.spatial import cKDTree
from tiles_helpers import ALL_FIELDS, exact, read_fields

from heatcurv.geometry.neighbourhood import knn_neighbourhood
from heatcurv.geometry.validation import prepare_points
from heatcurv.tiles import compute, compute_file, neighbours, phase_survey, tasks


def _scratch_lists(tmp_path, points, offsets, k, missing=()):
    """Write every tile's lists from one query over the whole cloud (positions = rows of ``points``)."""
    rows = cKDTree(points).query(points, k + 1)[1][:, 1:]
    for tile in range(len(offsets) - 1):
        if tile not in missing:
            neighbours.write_lists(tmp_path, tile, rows[offsets[tile]:offsets[tile + 1]].astype(np.int32))


def _slab(seed: int, n: int):
    """``n`` random points of a slab along x, sorted by x, and the offsets of its three tiles of ``n / 3``."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(size=(n, 3)) * [n / 1000, 1.0, 0.2]
    return points[np.argsort(points[:, 0])], np.arange(0, n + 1, n // 3)


def _queried_rows(monkeypatch, tile_phase_only=False):
    """Record how many rows the provider leaves to the k-d tree (in the tile phase only, if asked)."""
    asked, in_tile = [], [not tile_phase_only]
    query, compute_tile = neighbours.knn_neighbourhood, compute.compute_tile

    def counting(points, k, tree=None, workers=-1, queries=None, **kwargs):
        if in_tile[0]:
            asked.append(len(points) if queries is None else len(queries))
        return query(points, k, tree=tree, workers=workers, queries=queries, **kwargs)

    def tile(*args, **kwargs):
        in_tile[0] = True
        try:
            return compute_tile(*args, **kwargs)
        finally:
            in_tile[0] = not tile_phase_only

    monkeypatch.setattr(neighbours, "knn_neighbourhood", counting)
    monkeypatch.setattr(compute, "compute_tile", tile)
    return asked


def _whole_cloud_read_back(tmp_path, points, offsets, k, monkeypatch):
    """Read every point's stored neighbourhood back over the whole cloud: the query's, bit for bit.

    Returns the rows left to the k-d tree, and the prepared points and their tree.
    """
    prepared = prepare_points(points)
    tree = cKDTree(prepared.points)
    asked = _queried_rows(monkeypatch)
    stored = neighbours.known_neighbours(tmp_path, offsets, np.arange(len(points)))(prepared, tree, k, 1)
    queried = knn_neighbourhood(prepared.points, k, tree=tree)
    np.testing.assert_array_equal(stored.indices, queried.indices)
    np.testing.assert_array_equal(stored.distances, queried.distances)
    return asked, prepared, tree


def test_stored_neighbourhoods_are_the_query_bit_for_bit(tmp_path, monkeypatch):
    # a slab cut into three tiles along x; the middle tile reads its core and a band of the others
    (points, offsets), k = _slab(0, 6000), 12
    _scratch_lists(tmp_path, points, offsets, k)
    low, high = points[2000, 0] - 0.4, points[3999, 0] + 0.4
    positions = np.flatnonzero((points[:, 0] >= low) & (points[:, 0] <= high))
    prepared = prepare_points(points[positions])
    tree = cKDTree(prepared.points)
    asked = _queried_rows(monkeypatch)
    stored = neighbours.known_neighbours(tmp_path, offsets, positions)(prepared, tree, k, 1)
    queried = knn_neighbourhood(prepared.points, k, tree=tree)
    np.testing.assert_array_equal(stored.indices, queried.indices)
    np.testing.assert_array_equal(stored.distances, queried.distances)  # the k-d tree's sum, bit for bit
    np.testing.assert_array_equal(stored.radius, queried.radius)
    # only the rim of the band is queried: rows whose nearest lie beyond what was read
    assert 0 < asked[0] < 0.15 * len(positions)


def test_a_tile_without_stored_lists_queries_and_agrees(tmp_path, monkeypatch):
    (points, offsets), k = _slab(1, 3000), 10
    _scratch_lists(tmp_path, points, offsets, k, missing=(0,))
    asked, prepared, tree = _whole_cloud_read_back(tmp_path, points, offsets, k, monkeypatch)
    assert asked == [1000]  # tile 0's rows, and only those
    # lists of another width than asked for: every row is queried
    asked.clear()
    neighbours.known_neighbours(tmp_path, offsets, np.arange(3000))(prepared, tree, k + 1, 1)
    assert asked == [3000]


@pytest.mark.parametrize("rounds", [1, 2])
def test_the_tiled_torus_is_the_same_with_and_without_the_stored_lists(torus_file, tmp_path, monkeypatch, rounds):
    # the survey in one round writes its operator's lists, in two rounds the keys' round does (and the
    # centres' round reads them)
    monkeypatch.setattr(phase_survey, "ONE_ROUND_TILES", 63 if rounds == 1 else 0)
    options = dict(tile_size=1200, scheduler="serial", dtype="float64", fields=ALL_FIELDS, max_memory="4G")
    asked = _queried_rows(monkeypatch, tile_phase_only=True)
    (tmp_path / "scratch").mkdir()
    stored = compute_file(torus_file[0], tmp_path / "stored.ply", scratch=tmp_path / "scratch", keep_scratch=True,
                          **options)
    files = sorted((tmp_path / "scratch").rglob("knn_*.npy"))
    assert len(files) == stored.tiles
    counts = [np.load(f).shape for f in files]
    assert sum(c[0] for c in counts) == 6000 and {c[1] for c in counts} == {60}
    # the tile phase queried the rims of the halos only (wide here: tiles of 1200 points)
    read = sum(core + halo for core, halo in stored.tile_points)
    assert sum(asked) < 0.25 * read, (asked, read)
    monkeypatch.setattr(tasks, "write_lists", lambda *args: None)
    queried = compute_file(torus_file[0], tmp_path / "queried.ply", **options)
    a, b = read_fields(tmp_path / "stored.ply"), read_fields(tmp_path / "queried.ply")
    for name in ALL_FIELDS:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    assert queried.tiles == stored.tiles


def test_a_short_key_bound_surveys_again_with_every_candidate(torus_file, torus_memory, tmp_path, monkeypatch):
    from heatcurv.choice import survey as survey_module
    from support.tiles import tiled_agreement

    monkeypatch.setattr(survey_module, "KEY_BOUND_SIGMAS", -10.0)  # no cloud holds its centres below this bound
    said = []
    report = compute_file(torus_file[0], tmp_path / "t.ply", tile_size=2000, scheduler="serial", dtype="float64",
                          max_memory="4G", log=said.append)
    assert any("surveying again with every tile's candidates" in str(s) for s in said), said
    agreement = tiled_agreement(tmp_path / "t.ply", torus_memory, rtol=0.0)
    assert exact(agreement) == dict.fromkeys(agreement, (0, 0.0))
    assert report.tiles == 4


def test_a_survey_reads_the_lists_of_the_tiles_surveyed_before_it(torus_file, tmp_path, monkeypatch):
    # serial: tile t's survey finds the lists of the tiles surveyed before it, for its halo (their cores') and its
    # core (their halos'), and queries only the rest
    calls, surveying = [], [False]
    query, survey_tile = neighbours.knn_neighbourhood, compute.survey_tile

    def counting(points, k, tree=None, workers=-1, queries=None, **kwargs):
        if surveying[0]:
            calls[-1][1] += len(points) if queries is None else len(queries)
        return query(points, k, tree=tree, workers=workers, queries=queries, **kwargs)

    def survey(points, core, *args, **kwargs):
        calls.append([len(points), 0, int(core.sum())])
        surveying[0] = True
        try:
            return survey_tile(points, core, *args, **kwargs)
        finally:
            surveying[0] = False

    monkeypatch.setattr(neighbours, "knn_neighbourhood", counting)
    monkeypatch.setattr(compute, "survey_tile", survey)
    (tmp_path / "scratch").mkdir()
    compute_file(torus_file[0], tmp_path / "t.ply", tile_size=1200, scheduler="serial", max_memory="4G",
                 scratch=tmp_path / "scratch", keep_scratch=True)
    read, asked, core = np.array(calls).T
    assert asked[0] == read[0]  # the first survey finds no list
    # the others query a fraction of their cores: the surveys before them queried the rest for their halos
    assert asked[1:].sum() < 0.4 * core[1:].sum() and asked.sum() < 1.3 * core.sum(), calls
    # once every tile is surveyed, the halos' lists are deleted: each tile's own lists hold them
    assert not list((tmp_path / "scratch").rglob("halo_*.npy"))
    assert len(list((tmp_path / "scratch").rglob("knn_*.npy"))) == len(calls)


def _slab_scratch(tmp_path, seed=2):
    """A slab in three tiles along x with every tile's lists and values as its survey would store them, the
    middle tile's points and halo (positions), their prepared points and the whole cloud's operator."""
    from heatcurv.flags.outliers import find_outliers
    from heatcurv.operators.areas import density_areas

    rng = np.random.default_rng(seed)
    points = rng.uniform(size=(6000, 3)) * [6.0, 1.0, 0.2]
    points[:40] = points[40:80] + [0.0, 0.0, 0.6]  # an island over the middle tile: outliers
    points = points[np.argsort(points[:, 0])]
    offsets, k = np.array([0, 2000, 4000, 6000]), 12
    whole = prepare_points(points)  # the points are distinct: prepared rows are the input rows
    nbhd = knn_neighbourhood(whole.points, k)
    areas, outliers = density_areas(nbhd), find_outliers(whole.points, nbhd)
    assert outliers.mask.any()
    _scratch_lists(tmp_path, points, offsets, k)
    for tile in range(3):
        core = np.zeros(len(points), dtype=bool)
        core[offsets[tile]:offsets[tile + 1]] = True
        stored_lists = np.load(neighbours.lists_path(tmp_path, tile))
        neighbours.write_values(tmp_path, tile, neighbours.core_values(whole, areas, outliers, core, stored_lists))
    positions = np.flatnonzero((points[:, 0] >= points[2000, 0] - 0.4) & (points[:, 0] <= points[3999, 0] + 0.4))
    return points, offsets, k, positions, areas, outliers


def test_a_tile_reads_its_points_areas_and_outlier_flags(tmp_path):
    points, offsets, k, positions, areas, outliers = _slab_scratch(tmp_path)
    prepared = prepare_points(points[positions])
    stored = neighbours.known_neighbours(tmp_path, offsets, positions)
    assert stored.areas(prepared) is None and stored.outliers(prepared) is None  # nothing read back yet
    stored(prepared, cKDTree(prepared.points), k, 1)
    rows = positions[prepared.first]
    np.testing.assert_array_equal(stored.areas(prepared), areas[rows])
    got = stored.outliers(prepared)
    for name in ("mask", "detached", "isolated", "sparse"):
        np.testing.assert_array_equal(getattr(got, name), getattr(outliers, name)[rows], err_msg=name)
    # lists of another width: neither is the tile's
    stored(prepared, cKDTree(prepared.points), k + 1, 1)
    assert stored.areas(prepared) is None and stored.outliers(prepared) is None


def test_no_stored_values_when_a_tile_lacks_them_or_a_ball_was_not_certain(tmp_path):
    points, offsets, k, positions, areas, outliers = _slab_scratch(tmp_path)
    prepared = prepare_points(points[positions])
    tree = cKDTree(prepared.points)
    path = neighbours.values_path(tmp_path, 2)
    values = np.load(path)
    values["area"][5] = np.nan  # a row whose list was not stored (its ball may reach past what was read)
    neighbours.write_values(tmp_path, 2, values)
    stored = neighbours.known_neighbours(tmp_path, offsets, positions)
    stored(prepared, tree, k, 1)
    assert stored.areas(prepared) is None and stored.outliers(prepared) is None
    os.unlink(path)
    stored = neighbours.known_neighbours(tmp_path, offsets, positions)
    stored(prepared, tree, k, 1)
    assert stored.areas(prepared) is None and stored.outliers(prepared) is None


def test_the_tile_phase_reads_the_surveys_areas_and_outliers(torus_file, tmp_path, monkeypatch):
    # a survey in one round stores its core points' areas and outlier flags; the tiles compute neither again,
    # and every field is the same as when they do
    from heatcurv import estimator
    from heatcurv.operators import operator

    options = dict(tile_size=1200, scheduler="serial", dtype="float64", fields=ALL_FIELDS, max_memory="4G")
    computed = {"outliers": 0, "areas": 0}
    find, areas = estimator.find_outliers, operator.density_areas
    in_tile = [False]

    def counted(name, fn):
        def wrapper(*args, **kwargs):
            computed[name] += in_tile[0]
            return fn(*args, **kwargs)
        return wrapper

    compute_tile = compute.compute_tile

    def tile(*args, **kwargs):
        in_tile[0] = True
        try:
            return compute_tile(*args, **kwargs)
        finally:
            in_tile[0] = False

    monkeypatch.setattr(estimator, "find_outliers", counted("outliers", find))
    monkeypatch.setattr(operator, "density_areas", counted("areas", areas))
    monkeypatch.setattr(compute, "compute_tile", tile)
    (tmp_path / "scratch").mkdir()
    stored = compute_file(torus_file[0], tmp_path / "stored.ply", scratch=tmp_path / "scratch", keep_scratch=True,
                          **options)
    assert len(list((tmp_path / "scratch").rglob("values_*.npy"))) == stored.tiles
    assert computed == {"outliers": 0, "areas": 0}
    monkeypatch.setattr(tasks, "write_values", lambda *args: None)
    again = compute_file(torus_file[0], tmp_path / "computed.ply", **options)
    assert computed["outliers"] == again.tiles and computed["areas"] == again.tiles
    a, b = read_fields(tmp_path / "stored.ply"), read_fields(tmp_path / "computed.ply")
    for name in ALL_FIELDS:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_a_tile_without_its_own_lists_reads_them_from_another_surveys_halo(tmp_path, monkeypatch):
    # tile 1 not surveyed yet: tile 0's survey stored the lists of tile 1's points in its halo, which the middle
    # tile's reader takes instead of querying them
    (points, offsets), k = _slab(4, 6000), 12
    _scratch_lists(tmp_path, points, offsets, k, missing=(1,))
    # tile 0 read its core and a band of tile 1: its survey's operator over those points
    band = np.flatnonzero(points[:, 0] <= points[2000, 0] + 0.6)
    prepared0 = prepare_points(points[band])
    nbhd0 = knn_neighbourhood(prepared0.points, k)
    core0 = band < 2000
    low, high = points[band].min(axis=0), points[band].max(axis=0)
    halo = neighbours.halo_lists(tmp_path, offsets, prepared0, nbhd0, core0, band, (low, high),
                                 (points.min(axis=0), points.max(axis=0)))
    assert halo is not None and np.all((halo[:, 0] >= 2000) & (halo[:, 0] < 4000))
    neighbours.write_halo_lists(tmp_path, 0, halo)
    asked, _, _ = _whole_cloud_read_back(tmp_path, points, offsets, k, monkeypatch)
    assert asked == [2000 - len(halo)]  # tile 1's points that no halo list holds
    neighbours.remove_halo_lists(tmp_path)
    assert not os.path.exists(neighbours.halo_path(tmp_path, 0))


def test_a_one_round_survey_runs_tiles_apart_at_once():
    # a 2 x 2 tiling: the diagonal tiles first, so that the two surveyed at once share a corner only
    from types import SimpleNamespace

    cells = {0: (0, 0), 1: (0, 1), 2: (1, 0), 3: (1, 1)}

    def box(t):
        low = np.array([*cells[t], 0.0])
        return low, low + 1.0

    tiling = SimpleNamespace(counts=[1] * 4, box=box)
    assert phase_survey.survey_order(tiling, 2) == [0, 3, 1, 2]
    assert sorted(phase_survey.survey_order(tiling, 4)) == [0, 1, 2, 3]


def test_lists_of_int32_and_int64_positions_read_together(tmp_path, monkeypatch):
    # a survey stores int32 positions where its tile's fit, int64 beyond 2^31 points: a reader of both keeps the wider
    (points, offsets), k = _slab(5, 3000), 10
    _scratch_lists(tmp_path, points, offsets, k)
    neighbours.write_lists(tmp_path, 2, np.load(neighbours.lists_path(tmp_path, 2)).astype(np.int64))
    asked, _, _ = _whole_cloud_read_back(tmp_path, points, offsets, k, monkeypatch)
    assert asked == []
