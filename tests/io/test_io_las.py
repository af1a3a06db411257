"""LAS/LAZ: round trips, source headers and colours kept, standard dimensions, truncated files."""

import laspy
import numpy as np
import pytest
from io_helpers import N, expanded, make_cloud

from heatcurv import HeatcurvError
from heatcurv.io import read_points, write_points


@pytest.fixture(scope="module")
def cloud():
    """Torus points far from the origin (UTM-like), with normals, colours and result-like fields."""
    return make_cloud()


@pytest.mark.parametrize("ext", [".las", ".laz"])
def test_round_trip_las(tmp_path, cloud, ext):
    points, normals, colors, fields = cloud
    path = tmp_path / f"out{ext}"
    write_points(path, points, fields, normals=normals, colours=colors)
    back = read_points(path)
    header = back.meta["las_header"]
    extent = np.ptp(points, axis=0).max()
    assert np.all(header.scales <= 1e-6 * extent)
    assert np.all(np.abs(back.points - points) <= header.scales)
    np.testing.assert_array_equal(back.normals, normals.astype(np.float32))  # float32 by default
    np.testing.assert_array_equal(back.colours, colors)
    for name, values in expanded(fields).items():
        expected = values.astype(np.float32) if values.dtype.kind == "f" else values
        np.testing.assert_array_equal(back.fields[name], expected, err_msg=name)
    assert back.fields["reliable"].dtype == np.uint8  # bools as uint8
    assert back.fields["weight32"].dtype == np.float32
    assert back.fields["count"].dtype == np.int32  # int64 narrowed where it fits
    written = laspy.read(path).point_format
    extra = list(written.extra_dimension_names)
    assert extra == ["nx", "ny", "nz"] + list(expanded(fields))
    assert {written.dimension_by_name(name).dtype for name in ("nx", "mean", "d1x", "area")} == {
        np.dtype(np.float32)
    }


def test_las_source_header_dimensions_and_colours_kept(tmp_path):
    rng = np.random.default_rng(1)
    n = 200
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.001])
    header.offsets = np.array([400000.0, 5000000.0, 100.0])
    header.add_extra_dims([laspy.ExtraBytesParams("amplitude", np.float32)])
    las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(n, header=header))
    las.x = 400000.0 + rng.random(n) * 50
    las.y = 5000000.0 + rng.random(n) * 50
    las.z = 100.0 + rng.random(n)
    las.intensity = rng.integers(0, 65535, n)
    las.classification = rng.integers(0, 31, n)
    las.gps_time = rng.random(n) * 1e5
    las.amplitude = rng.random(n).astype(np.float32)
    rgb16 = rng.integers(0, 65536, (n, 3)).astype(np.uint16)
    las.red, las.green, las.blue = rgb16.T
    source_path = tmp_path / "scan.las"
    las.write(source_path)

    source = read_points(source_path)
    np.testing.assert_array_equal(source.colours, np.round(rgb16 / 257).astype(np.uint8))
    np.testing.assert_array_equal(source.fields["intensity"], las.intensity)
    mean = rng.normal(size=n)
    out = tmp_path / "result.laz"
    write_points(out, source.points, {"mean": mean}, source=source)
    written = laspy.read(out)
    assert written.point_format.id == 3 and str(written.header.version) == "1.2"
    np.testing.assert_array_equal(written.header.scales, header.scales)
    np.testing.assert_array_equal(written.header.offsets, header.offsets)
    np.testing.assert_array_equal(written.X, las.X)  # same integers: no requantisation
    np.testing.assert_array_equal(
        np.column_stack([written.red, written.green, written.blue]), rgb16
    )
    for name in ("intensity", "classification", "gps_time", "amplitude"):
        np.testing.assert_array_equal(
            np.asarray(written[name]), np.asarray(las[name]), err_msg=name
        )
    assert list(written.point_format.extra_dimension_names) == ["amplitude", "mean"]
    np.testing.assert_array_equal(written.mean, mean.astype(np.float32))
    write_points(out, source.points, {"mean": mean}, source=source, dtype="float64")
    np.testing.assert_array_equal(laspy.read(out).mean, mean)


def test_las_extra_dimensions_kept_with_type_scale_and_description(tmp_path):
    rng = np.random.default_rng(11)
    n = 120
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.add_extra_dims(
        [
            laspy.ExtraBytesParams("temperature", "i2", description="degrees C",
                                   scales=np.array([0.01]), offsets=np.array([20.0])),
            laspy.ExtraBytesParams("deviation", "3f8", description="to the model"),
            laspy.ExtraBytesParams("echo", "u1"),
            laspy.ExtraBytesParams("range", "f8"),
        ]
    )
    las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(n, header=header))
    las.x, las.y, las.z = rng.random((3, n)) * 10
    las.temperature = 20.0 + np.round(rng.normal(size=n) * 300) / 100
    las.deviation = rng.normal(size=(n, 3))
    las.echo = rng.integers(0, 5, n)
    las.range = rng.random(n) * 1e5
    las.gps_time = rng.random(n) * 1e6
    las.write(tmp_path / "scan.laz")

    source = read_points(tmp_path / "scan.laz")
    out = tmp_path / "result.laz"
    gps = source.fields["gps_time"] + 0.125
    write_points(out, source.points, {"mean": rng.random(n), "gps_time": gps}, source=source)
    written = laspy.read(out)
    names = list(written.point_format.extra_dimension_names)
    assert names == ["temperature", "deviation", "echo", "range", "mean"]
    for name, kind in [("temperature", "i2"), ("echo", "u1"), ("range", "f8"), ("mean", "f4")]:
        assert written.point_format.dimension_by_name(name).dtype == np.dtype(kind), name
    temperature = written.point_format.dimension_by_name("temperature")
    assert temperature.description == "degrees C"
    np.testing.assert_array_equal(temperature.scales, [0.01])
    np.testing.assert_array_equal(temperature.offsets, [20.0])
    assert written.point_format.dimension_by_name("deviation").num_elements == 3
    for name in ("temperature", "deviation", "echo", "range"):
        np.testing.assert_array_equal(np.asarray(written[name]), np.asarray(las[name]), err_msg=name)
    np.testing.assert_array_equal(written.X, las.X)
    # a float64 field filling a standard double dimension is not narrowed
    np.testing.assert_array_equal(written.gps_time, gps)


def test_las_eight_bit_values_in_sixteen_bit_colour_fields(tmp_path):
    header = laspy.LasHeader(point_format=2, version="1.2")
    las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(3, header=header))
    las.x = [0.0, 1.0, 2.0]
    las.red, las.green, las.blue = [0, 128, 255], [1, 2, 3], [255, 255, 0]
    las.write(tmp_path / "c.las")
    np.testing.assert_array_equal(read_points(tmp_path / "c.las").colours[:, 0], [0, 128, 255])


def test_las_standard_dimensions_filled_from_fields(tmp_path):
    rng = np.random.default_rng(8)
    points = rng.random((30, 3)) * 10
    fields = {
        "intensity": np.arange(30.0) * 100,
        "classification": np.full(30, 2),
        "mean": rng.random(30),
    }
    write_points(tmp_path / "a.las", points, fields, colours=np.full((30, 3), 200))
    las = laspy.read(tmp_path / "a.las")
    assert las.point_format.id == 7  # LAS 1.4 with RGB
    np.testing.assert_array_equal(las.intensity, fields["intensity"])
    np.testing.assert_array_equal(las.classification, 2)
    assert list(las.point_format.extra_dimension_names) == ["mean"]
    np.testing.assert_array_equal(las.red, 200 * 257)
    with pytest.raises(HeatcurvError, match=r"field 'intensity' does not fit the LAS dimension"):
        write_points(tmp_path / "b.las", points, {"intensity": rng.random(30)})
    with pytest.raises(HeatcurvError, match=r"longer than the 32 bytes LAS allows"):
        write_points(tmp_path / "b.las", points, {"a" * 33: rng.random(30)})
    # a LAS source without RGB gets the point format with RGB when colours are given
    header = laspy.LasHeader(point_format=1, version="1.2")
    source_las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(30, header=header))
    source_las.x = points[:, 0]
    source_las.write(tmp_path / "src.las")
    source = read_points(tmp_path / "src.las")
    write_points(tmp_path / "c.las", source.points, colours=np.full((30, 3), 9), source=source)
    assert laspy.read(tmp_path / "c.las").point_format.id == 3
    assert not (tmp_path / "b.las").exists()


def test_truncated_las(tmp_path, cloud):
    points = cloud[0]
    write_points(tmp_path / "full.las", points)
    raw = (tmp_path / "full.las").read_bytes()
    record = laspy.read(tmp_path / "full.las").header.point_format.size
    (tmp_path / "cut.las").write_bytes(raw[: -3 * record])  # whole records missing
    with pytest.raises(
        HeatcurvError, match=rf"cut\.las: truncated: the header announces {N} points"
    ):
        read_points(tmp_path / "cut.las")
    (tmp_path / "cut2.las").write_bytes(raw[:-7])
    with pytest.raises(HeatcurvError, match=r"cut2\.las: "):
        read_points(tmp_path / "cut2.las")
    write_points(tmp_path / "full.laz", points)
    (tmp_path / "cut.laz").write_bytes((tmp_path / "full.laz").read_bytes()[:-100])
    with pytest.raises(HeatcurvError, match=r"cut\.laz: truncated: the chunk table .* would start at byte"):
        read_points(tmp_path / "cut.laz")
