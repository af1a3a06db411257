"""Streaming readers: chunks give exactly the coordinates read_points gives; formats that cannot stream are refused."""

import numpy as np
import plyfile
import pytest

from heatcurv.errors import HeatcurvError
from heatcurv.io import read_points, write_points
from heatcurv.tiles.sources import open_source


def _streamed(path, size):
    source = open_source(path)
    chunks = list(source.chunks(size))
    assert [start for start, _, _ in chunks] == list(range(0, source.count, size))
    return source, np.concatenate([points for _, points, _ in chunks])


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(1)
    return np.column_stack([500000 + rng.uniform(0, 50, 2500), 5e6 + rng.uniform(0, 50, 2500),
                            200 + rng.uniform(0, 5, 2500)])


@pytest.mark.parametrize("ext", [".las", ".laz", ".ply", ".npy"])
def test_chunks_equal_read_points(points, tmp_path, ext):
    path = tmp_path / f"cloud{ext}"
    if ext == ".npy":
        np.save(path, points)
    else:
        write_points(path, points, {"intensity": np.arange(2500) % 700})
    source, streamed = _streamed(path, 1000)
    assert source.count == 2500
    assert np.array_equal(streamed, read_points(path).points)  # z included: LAS decodes Z in coordinate passes
    if ext != ".npy":
        records = next(source.chunks(1000, coordinates_only=False))[2]
        assert np.array_equal(source.properties(records)["intensity"], np.arange(1000) % 700)


def test_big_endian_ply_and_structured_npy(points, tmp_path):
    vertices = np.empty(2500, dtype=[("x", ">f8"), ("y", ">f8"), ("z", ">f8"), ("q", ">i2")])
    for k, a in enumerate("xyz"):
        vertices[a] = points[:, k]
    vertices["q"] = -np.arange(2500)
    plyfile.PlyData([plyfile.PlyElement.describe(vertices, "vertex")], byte_order=">").write(str(tmp_path / "b.ply"))
    source, streamed = _streamed(tmp_path / "b.ply", 999)
    assert np.array_equal(streamed, points)
    records = next(source.chunks(10, coordinates_only=False))[2]
    assert source.properties(records)["q"].tolist() == list(range(0, -10, -1))
    np.save(tmp_path / "s.npy", vertices.astype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("q", "<i2")]))
    assert np.array_equal(_streamed(tmp_path / "s.npy", 700)[1], points)


def test_refused_formats(points, tmp_path):
    write_points(tmp_path / "a.xyz", points)
    with pytest.raises(HeatcurvError, match=r"cannot tile .*a\.xyz: \.xyz files are read whole; a tiled run streams"):
        open_source(tmp_path / "a.xyz")
    vertices = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    plyfile.PlyData([plyfile.PlyElement.describe(vertices, "vertex")], text=True).write(str(tmp_path / "t.ply"))
    with pytest.raises(HeatcurvError, match="ASCII PLY is read whole; convert it to binary PLY or LAZ"):
        open_source(tmp_path / "t.ply")
    np.save(tmp_path / "bad.npy", np.zeros((4, 2)))
    with pytest.raises(HeatcurvError, match=r"expected an \(n, >=3\) array of numbers, got shape \(4, 2\)"):
        open_source(tmp_path / "bad.npy")
    with pytest.raises(HeatcurvError, match="no such file"):
        open_source(tmp_path / "missing.laz")


@pytest.mark.parametrize("layout", ["C", "F", ">f4"])
def test_npy_layouts_read_in_chunks(points, tmp_path, layout):
    """C- and Fortran-order and big-endian (n, 5) NPY: every chunk and its extra columns as in the array."""
    table = np.column_stack([points, np.arange(2500.0), -np.arange(2500.0)])
    stored = np.asfortranarray(table) if layout == "F" else table.astype(layout) if layout != "C" else table
    np.save(tmp_path / "t.npy", stored)
    source, streamed = _streamed(tmp_path / "t.npy", 700)
    assert np.array_equal(streamed, stored[:, :3].astype(np.float64))
    start, _, records = list(source.chunks(700, coordinates_only=False))[2]
    assert start == 1400
    properties = source.properties(records)
    assert np.array_equal(properties["column_4"], stored[1400:2100, 3])
    assert np.array_equal(properties["column_5"], stored[1400:2100, 4])


def test_chunks_are_read_not_mapped(points, tmp_path, monkeypatch):
    """A pass over a PLY or NPY reads each chunk: no memory map of the file, whose walked pages would count as the
    driver's resident memory (a 100M-point NPY's stats pass: 2.58 GB, the 2.4 GB file included)."""
    np.save(tmp_path / "c.npy", points)
    write_points(tmp_path / "c.ply", points)

    def no_map(*args, **kwargs):
        raise AssertionError("memory-mapped")

    sources = [open_source(tmp_path / "c.npy"), open_source(tmp_path / "c.ply")]
    monkeypatch.setattr(np, "memmap", no_map)
    monkeypatch.setattr(np, "load", no_map)
    for source in sources:
        streamed = np.concatenate([p for _, p, _ in source.chunks(600)])
        assert np.array_equal(streamed, points)


def test_truncated_ply_and_npy_are_refused(points, tmp_path):
    np.save(tmp_path / "c.npy", points)
    raw = (tmp_path / "c.npy").read_bytes()
    (tmp_path / "t.npy").write_bytes(raw[:-80])
    with pytest.raises(HeatcurvError, match=r"cannot read .*t\.npy: not a valid NPY file"):
        open_source(tmp_path / "t.npy")
    write_points(tmp_path / "c.ply", points)
    raw = (tmp_path / "c.ply").read_bytes()
    (tmp_path / "t.ply").write_bytes(raw[:-80])
    with pytest.raises(HeatcurvError, match=r"cannot read .*t\.ply: truncated"):
        open_source(tmp_path / "t.ply")


@pytest.mark.parametrize("ext", [".las", ".laz"])
def test_las_chunks_name_the_first_point_outside_the_box(tmp_path, ext):
    """A streamed LAS/LAZ is checked against its header's box chunk by chunk; the record is the file's."""
    import struct

    rng = np.random.default_rng(5)
    points = 8 + 4 * rng.random((2500, 3))
    points[:1000, 0] = 8 + 2.9 * rng.random(1000)  # the first chunk inside X <= 11
    path = tmp_path / f"box{ext}"
    write_points(path, points)
    data = bytearray(path.read_bytes())
    struct.pack_into("<d", data, 179, 11.0)  # X maximum: 11 instead of about 12
    path.write_bytes(bytes(data))
    first = int(np.argmax(points[:, 0] > 11.0 + 1e-6))  # in the second chunk
    source = open_source(path)
    chunks = source.chunks(1000)
    start, block, _ = next(chunks)
    assert start == 0 and block.shape == (1000, 3)
    with pytest.raises(HeatcurvError, match=rf"box{ext}: point record {first + 1} of 2500 lies outside the header's "
                                            r"bounding box: its X \([\d.]+\) is [\d.]+ above the box's X maximum "
                                            r"\(11\), more than one scale step \(1e-06\); \d+ of the 1000 points of "
                                            r"records 1001-2000 are outside"):
        next(chunks)
