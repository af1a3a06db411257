"""heatcurv.io._common and heatcurv.io._textparse: the helpers every format shares."""

from pathlib import Path

import numpy as np
import pytest

from heatcurv import HeatcurvError
from heatcurv.io._common import PointCloud, _canonical, _colours_to_uint8, _is_integral, _native
from heatcurv.io._textparse import _guess_delimiter, _is_number, _load_table, _split, _strip_comment


def test_property_names_compare_canonically():
    assert _canonical("Normal_X") == "normalx" and _canonical("scalar Red") == "scalarred"


def test_native_byte_order_copy():
    big = np.arange(4, dtype=">f4")
    out = _native(big)
    assert out.dtype.byteorder in ("=", "<", "|") and np.array_equal(out, big) and out.flags.c_contiguous


def test_colours_to_uint8():
    assert _is_integral(np.array([1.0, 2.0])) and not _is_integral(np.array([1.5]))
    np.testing.assert_array_equal(_colours_to_uint8(np.array([[0.0, 0.5, 1.0]]), text=False), [[0, 128, 255]])
    np.testing.assert_array_equal(_colours_to_uint8(np.array([[0, 128, 255]]), text=True), [[0, 128, 255]])
    np.testing.assert_array_equal(_colours_to_uint8(np.array([[0, 32896, 65535]]), text=True), [[0, 128, 255]])
    assert _colours_to_uint8(np.array([[-1.0, 0.0, 0.0]]), text=True) is None
    assert _colours_to_uint8(np.array([[np.nan, 0.0, 0.0]]), text=False) is None


def test_point_cloud_record():
    cloud = PointCloud(np.zeros((2, 3)), colours=np.zeros((2, 3), np.uint8))
    assert len(cloud) == 2 and cloud.fields == {} and cloud.meta == {}


def test_text_tokens():
    assert _strip_comment("1 2 3 # note") == "1 2 3" and _strip_comment("// all") == ""
    assert _split(' "1";2 ', ";") == ["1", "2"] and _split("1 \t2", None) == ["1", "2"]
    assert _is_number("1e-3") and not _is_number("x")
    assert _guess_delimiter("1;2,3") == ";" and _guess_delimiter("1,2") == "," and _guess_delimiter("1 2") is None


def test_load_table_names_the_bad_line(tmp_path: Path):
    good = tmp_path / "good.xyz"
    good.write_text("# x y z\n0 0 0\n1 2 3\n")
    text = good.read_text()
    table = _load_table(good, text, skip=1, ncols=3, delimiter=None)
    np.testing.assert_array_equal(table, [[0, 0, 0], [1, 2, 3]])
    bad = "0 0 0\n1 2 3\n4 five 6\n"
    with pytest.raises(HeatcurvError, match=r"bad\.xyz.*line 3"):
        _load_table(tmp_path / "bad.xyz", bad, skip=0, ncols=3, delimiter=None)
