"""NPY and NPZ: plain arrays, normals, extra per-point arrays, missing points."""

import numpy as np
import pytest

from heatcurv import HeatcurvError
from heatcurv.io import read_points


def test_npy(tmp_path):
    array = np.random.default_rng(4).random((20, 6))
    np.save(tmp_path / "a.npy", array)
    got = read_points(tmp_path / "a.npy")
    np.testing.assert_array_equal(got.points, array[:, :3])
    np.testing.assert_array_equal(got.normals, array[:, 3:])
    np.save(tmp_path / "b.npy", array[:, :4])
    assert list(read_points(tmp_path / "b.npy").fields) == ["column_4"]
    np.save(tmp_path / "c.npy", array[:, :2])
    with pytest.raises(HeatcurvError, match=r"c\.npy.*shape \(20, 2\)"):
        read_points(tmp_path / "c.npy")


def test_npz_xyz_key_and_extras(tmp_path):
    rng = np.random.default_rng(5)
    np.savez(
        tmp_path / "a.npz",
        xyz=rng.random((10, 3)),
        label=np.arange(10),
        offset=np.zeros(2),
        dirs=rng.random((10, 3)),
    )
    got = read_points(tmp_path / "a.npz")
    assert list(got.fields) == ["label", "dirsx", "dirsy", "dirsz"]  # non-per-point arrays ignored
    np.savez(tmp_path / "b.npz", coords=rng.random((10, 3)))
    with pytest.raises(
        HeatcurvError, match=r"b\.npz: no 'points' or 'xyz' array \(arrays: coords\)"
    ):
        read_points(tmp_path / "b.npz")


@pytest.mark.parametrize("points_rows, field_rows", [(1, 120), (120, 119), (120, 121), (120, 5)])
def test_npz_per_point_arrays_of_another_length_are_refused(tmp_path, points_rows, field_rows):
    # a truncated or mismatched member used to be dropped as "metadata", or the cloud cut to the points' rows
    rng = np.random.default_rng(6)
    path = tmp_path / "a.npz"
    np.savez(path, points=rng.random((points_rows, 3)), mean=rng.random(field_rows), offset=np.zeros(3))
    with pytest.raises(HeatcurvError, match=rf"a\.npz: 'mean' has {field_rows} rows but 'points' has {points_rows}"):
        read_points(path)
    # up to 4 rows is metadata (an offset, a viewpoint, a 4 x 4 transform), as beside matching fields
    np.savez(path, points=rng.random((120, 3)), mean=rng.random(120), offset=np.zeros(3), pose=np.eye(4))
    assert list(read_points(path).fields) == ["mean"]


def test_npz_members_that_are_not_arrays_are_skipped(tmp_path):
    import zipfile

    path = tmp_path / "a.npz"
    np.savez(path, points=np.ones((4, 3)), label=np.arange(4))
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("meta.json", '{"units": "m"}')
    got = read_points(path)
    assert got.points.shape == (4, 3) and list(got.fields) == ["label"]


def test_npy_and_npz_sizes_must_match_their_headers(tmp_path):
    np.save(tmp_path / "a.npy", np.ones((4, 3)))
    (tmp_path / "b.npy").write_bytes((tmp_path / "a.npy").read_bytes() + b"\0")
    with pytest.raises(HeatcurvError, match=r"b\.npy: the header announces an array of shape \(4, 3\) float64 "
                       r"\(96 bytes\) after the header, the file holds 97$"):
        read_points(tmp_path / "b.npy")
