"""Output of tiled runs: LAS/LAZ keeps every input dimension and the raw integers, PLY keeps the properties."""

import json
import os

import laspy
import numpy as np
import pytest
from tiles_helpers import exact, read_fields

import heatcurv
from heatcurv.cli.fields import DEFAULT_FIELDS, EXTRA_FIELDS
from heatcurv.io import read_points, write_points
from heatcurv.tiles import compute_file
from heatcurv.tiles import output as tiled_output
from support.tiles import tiled_agreement


@pytest.fixture(scope="module")
def terrain_laz(tmp_path_factory):
    """Smooth LiDAR-like terrain (a tilt, a hill, a valley) of 6000 points with intensity and classes, LAZ."""
    rng = np.random.default_rng(7)
    x = 500000.0 + rng.uniform(-30, 30, 6000)
    y = 5000000.0 + rng.uniform(-30, 30, 6000)
    z = heatcurv.surfaces.lidar_terrain(x, y)
    path = tmp_path_factory.mktemp("terrain") / "terrain.laz"
    write_points(path, np.column_stack([x, y, z]), {"intensity": rng.integers(0, 4000, 6000).astype(np.uint16),
                                                     "classification": np.full(6000, 2, np.uint8)})
    return path


def test_field_names_are_those_of_compute():
    assert tiled_output.DEFAULT_FIELDS == DEFAULT_FIELDS and tiled_output.EXTRA_FIELDS == EXTRA_FIELDS


def test_las_keeps_dimensions_raw_integers_and_records_the_run(terrain_laz, tmp_path):
    out = tmp_path / "out.laz"
    report = compute_file(terrain_laz, out, tile_size=1200, tile_workers=2, scheduler="threads", dtype="float64")
    assert report.tiles >= 6 and report.parameters["options"]["orient"] == "up"  # LAS: up, as the CLI
    source, written = laspy.read(terrain_laz), laspy.read(out)
    for name in source.point_format.dimension_names:  # every input dimension, raw integers included
        assert np.array_equal(np.asarray(source[name]), np.asarray(written[name])), name
    assert np.array_equal(written.header.scales, source.header.scales)
    assert np.array_equal(written.header.offsets, source.header.offsets)
    extra = list(written.point_format.extra_dimension_names)
    assert extra == ["nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z",
                     "area", "reliable"]
    assert written.point_format.dimension_by_name("reliable").dtype == np.uint8
    vlr = [v for v in written.header.vlrs if v.user_id == "heatcurv"]
    assert len(vlr) == 1 and vlr[0].record_id == 13
    parameters = json.loads(vlr[0].record_data)
    assert parameters["tiles"] == report.tiles and parameters["halo"] == pytest.approx(report.halo)
    # the standard errors are not written, so not computed
    assert parameters["options"] == {"method": "default", "orient": "up", "se": False} and parameters["heatcurv"]
    # every normal up, and every field as in memory, bit for bit (measured; float64 output)
    assert np.all(np.asarray(written.nz) > 0)
    res = heatcurv.estimate(read_points(terrain_laz).points, orient="up")
    agreement = tiled_agreement(out, res, rtol=0.0)
    assert exact(agreement) == dict.fromkeys(agreement, (0, 0.0))


def test_float32_by_default_and_nan_rows_skipped(tmp_path):
    sample = heatcurv.surfaces.Sphere().sample(6000, "random", seed=2)
    rows = np.array(sample.points)
    rows[[5, 77]] = np.nan
    src = tmp_path / "holes.npy"
    np.save(src, rows)
    with pytest.raises(heatcurv.HeatcurvError, match=r"rows 5, 77, counted from 0\); remove them or pass"):
        compute_file(src, tmp_path / "out.ply", tile_size=2000)
    report = compute_file(src, tmp_path / "out.ply", tile_size=2000, skip_nonfinite=True, scheduler="threads",
                          fields=("mean", "reliable", "neighbours"))
    assert report.points == 6000 and report.computed == 5998
    cloud = read_points(tmp_path / "out.ply")
    assert cloud.fields["mean"].dtype == np.float32 and cloud.fields["neighbours"].dtype == np.int32
    assert np.isnan(cloud.fields["mean"][[5, 77]]).all() and cloud.fields["reliable"][[5, 77]].tolist() == [0, 0]
    assert np.isfinite(np.delete(cloud.fields["mean"], [5, 77])).all()


def test_ply_keeps_properties_faces_and_records_the_run(tmp_path):
    sample = heatcurv.surfaces.Sphere().sample(5000, "fibonacci")
    src = tmp_path / "mesh.ply"
    faces = np.array([(0, 1, 2), (2, 3, 4)])
    import plyfile

    vertices = np.empty(5000, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("quality", "<f4")])
    for k, a in enumerate("xyz"):
        vertices[a] = sample.points[:, k]
    vertices["quality"] = np.arange(5000)
    face = np.empty(2, dtype=[("vertex_indices", "i4", (3,))])
    face["vertex_indices"] = faces
    plyfile.PlyData([plyfile.PlyElement.describe(vertices, "vertex"), plyfile.PlyElement.describe(face, "face")],
                    text=False, byte_order="<").write(str(src))
    compute_file(src, tmp_path / "out.ply", tile_size=2000, scheduler="threads", fields=("mean",))
    written = plyfile.PlyData.read(str(tmp_path / "out.ply"))
    assert written["vertex"].data.dtype.names == ("x", "y", "z", "quality", "mean")
    assert written["vertex"].data["x"].dtype == np.float32  # stored as the source stored them
    assert np.array_equal(written["vertex"].data["quality"], vertices["quality"])
    assert np.array_equal(np.stack(written["face"].data["vertex_indices"]), faces)
    comments = [c for c in written.comments if c.startswith("heatcurv-tiles ")]
    assert len(comments) == 1 and json.loads(comments[0].split(" ", 1)[1])["tiles"] >= 3
    assert read_fields(tmp_path / "out.ply")["mean"].shape == (5000,)


def test_las_from_ply_carries_the_properties(tmp_path):
    sample = heatcurv.surfaces.Sphere().sample(3000, "random", seed=1)
    write_points(tmp_path / "s.ply", sample.points, {"quality": np.arange(3000, dtype=np.float32)})
    compute_file(tmp_path / "s.ply", tmp_path / "s.las", tile_size=1000, scheduler="threads", fields=("mean",))
    las = laspy.read(tmp_path / "s.las")
    assert list(las.point_format.extra_dimension_names) == ["quality", "mean"]
    assert np.array_equal(np.asarray(las.quality), np.arange(3000, dtype=np.float32))
    # LAS 1.4 format 6 at the scale write_points chooses (1e-6 of the largest side or finer)
    assert np.abs(read_points(tmp_path / "s.las").points - sample.points).max() <= 1e-6


def _tile_file(path, rows: np.ndarray) -> None:
    """A finished tile's result file holding ``rows`` (each row's ``mean`` half its number, its patch 1)."""
    from heatcurv.tiles.compute import RESULT_FIELDS

    n = len(rows)
    data = {name: np.zeros((n, cols) if cols > 1 else n, dtype=dt) for name, (cols, dt) in RESULT_FIELDS.items()}
    data.update(rows=rows, mean=rows * 0.5, patch=np.ones(n, np.int64), winding=np.zeros(n, np.int64),
                winding_fine=np.zeros(n, np.int64), vote_weight=np.zeros(n), vote_normal=np.zeros((n, 3), np.float32))
    np.savez(path, **data)


def test_buckets_put_every_stored_row_in_place(tmp_path, monkeypatch):
    """Tiles appended to buckets of 64 input rows, one tile stored twice (a resume), a record cut short at a
    bucket's end (a crash mid-append), a second tile stored after a first merge: every row lands at its input row
    with its tile's patch key, the other rows stay uncomputed, the buckets are gone."""
    monkeypatch.setattr(tiled_output, "BUCKET_ROWS", 64)
    path, buckets = tmp_path / "results.rec", tmp_path / "buckets"
    tiled_output.create_results(path, 1000)
    tiled_output.prepare_buckets(buckets, keep=False)
    rows = np.random.default_rng(5).permutation(1000)[:500]
    first, second = rows[:300], rows[300:]
    _tile_file(tmp_path / "a.npz", first)
    _tile_file(tmp_path / "b.npz", second)
    assert tiled_output.store_tile(buckets, tmp_path / "a.npz", 3) == 300
    tiled_output.store_tile(buckets, tmp_path / "a.npz", 3)
    assert len(os.listdir(buckets)) == len(np.unique(first // 64)) > 1
    torn = tiled_output.bucket_path(buckets, int(first[0] // 64))
    with open(torn, "ab") as stream:
        stream.write(b"\x01" * 100)
    tiled_output.prepare_buckets(buckets, keep=True)
    assert os.path.getsize(torn) % tiled_output.BUCKET_RECORD.itemsize == 0
    tiled_output.merge_buckets(path, buckets)
    assert os.listdir(buckets) == []
    tiled_output.store_tile(buckets, tmp_path / "b.npz", 4)
    tiled_output.merge_buckets(path, buckets)  # the first tile's rows stay where the first merge put them
    records = tiled_output.read_results(path, 0, 1000)
    assert np.array_equal(records["mean"][rows], rows * 0.5) and records["computed"][rows].all()
    assert np.array_equal(records["patch"][first], np.full(300, (3 << tiled_output.PATCH_SHIFT) | 1))
    assert np.array_equal(records["patch"][second], np.full(200, (4 << tiled_output.PATCH_SHIFT) | 1))
    assert not records["computed"][np.setdiff1d(np.arange(1000), rows)].any()
    assert os.path.getsize(path) == 1000 * tiled_output.RECORD.itemsize
    tiled_output.prepare_buckets(buckets, keep=False)  # a run started afresh empties them
    tiled_output.store_tile(buckets, tmp_path / "b.npz", 4)
    tiled_output.prepare_buckets(buckets, keep=False)
    assert os.listdir(buckets) == []


def test_cloud_flags_rewrite_only_the_rows_they_turn(tmp_path, monkeypatch):
    """The cloud-wide misfit flags over 1000 rows in chunks of 64: the rows whose residual is far above their width's
    median lose ``reliable``, the others keep their local flag, and only the rows that turn are written back (the
    other pages of a 25 GB ``results.rec`` at 100M points are not rewritten)."""
    from heatcurv.flags.reliability import misfits
    from heatcurv.tiles.medians import apply_cloud_flags

    path = tmp_path / "results.rec"
    tiled_output.create_results(path, 1000)
    rng = np.random.default_rng(8)
    block = np.zeros(1000, dtype=tiled_output.RECORD)
    block["computed"] = block["counted"] = 1
    block["fit_width"] = rng.integers(0, 2, 1000)
    block["misfit_residual"] = rng.uniform(0.5, 1.5, 1000)
    far = rng.choice(1000, 25, replace=False)
    block["misfit_residual"][far] = 100.0
    local = rng.random(1000) > 0.1
    block["reliable"] = local
    tiled_output.write_records(path, block, np.arange(1000))
    written = []
    real = tiled_output.write_records
    monkeypatch.setattr(tiled_output, "write_records", lambda p, r, rows: (written.append(rows), real(p, r, rows)))
    out = apply_cloud_flags(path, 1000, 1000, chunk=64)
    bad = misfits(block["misfit_residual"], block["fit_width"], out["baselines"])
    assert set(np.flatnonzero(bad)) == set(far.tolist())
    records = tiled_output.read_results(path, 0, 1000)
    assert np.array_equal(records["reliable"] == 1, local & ~bad)
    assert np.array_equal(np.concatenate(written), np.flatnonzero(local & bad))  # the turned rows alone


def test_records_written_and_gathered_window_by_window(tmp_path, monkeypatch):
    """Rows written and gathered across several windows of results.rec come back as written, the rest zero."""
    monkeypatch.setattr(tiled_output, "WINDOW_ROWS", 64)
    path = tmp_path / "results.rec"
    tiled_output.create_results(path, 1000)
    rows = np.sort(np.random.default_rng(3).choice(1000, 300, replace=False))
    block = np.zeros(300, dtype=tiled_output.RECORD)
    block["mean"] = rows * 0.5
    block["computed"] = 1
    for lo in range(0, 300, 64):  # a window at a time
        tiled_output.write_records(path, block[lo:lo + 64], rows[lo:lo + 64])
    gathered = tiled_output.gather_records(path, rows)
    assert np.array_equal(gathered["mean"], rows * 0.5) and gathered["computed"].all()
    others = np.setdiff1d(np.arange(1000), rows)
    assert not tiled_output.gather_records(path, others)["computed"].any()
    assert np.array_equal(tiled_output.read_results(path, 0, 1000)["mean"][rows], rows * 0.5)
