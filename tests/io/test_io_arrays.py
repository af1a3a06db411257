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
