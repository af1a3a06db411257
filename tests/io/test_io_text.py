"""Text tables (XYZ/TXT/CSV/PTS): headers, delimiters, column meanings, errors naming the line."""

import numpy as np
import pytest

from heatcurv import HeatcurvError
from heatcurv.io import read_points

TEXT_CASES = {
    "plain.xyz": ("1 2 3\n4 5 6\n", None, None, []),
    "header.csv": ("X,Y,Z,Intensity\n1,2,3,7\n4,5,6,8\n", None, None, ["Intensity"]),
    "spaces.csv": ("x, y, z\n1, 2, 3\n4, 5, 6\n", None, None, []),
    "semicolon.txt": ("x;y;z;nx;ny;nz\n1;2;3;0;0;1\n4;5;6;0;1;0\n", "normals", None, []),
    "decimal_comma.txt": ("1,0;2;3\n4;5,0;6\n", None, None, []),
    "tabs.txt": (
        "x\ty\tz\tred\tgreen\tblue\n1\t2\t3\t255\t0\t9\n4\t5\t6\t0\t1\t2\n",
        None,
        "colors",
        [],
    ),
    "cc_header.txt": (
        "//X,Y,Z,R,G,B,Dist\n1,2,3,255,0,9,0.5\n4,5,6,0,1,2,0.25\n",
        None,
        "colors",
        ["Dist"],
    ),
    "hash_header.xyz": (
        "# some tool\n# x y z nx ny nz\n1 2 3 0 0 1\n4 5 6 0 1 0\n",
        "normals",
        None,
        [],
    ),
    "rgb6.xyz": ("1 2 3 255 0 9\n4 5 6 0 1 2\n", None, "colors", []),
    "normals6.xyz": ("1 2 3 0 0 1\n4 5 6 0.6 0.8 0\n", "normals", None, []),
    "unit_ints6.xyz": ("1 2 3 0 0 1\n4 5 6 0 1 0\n", "normals", None, []),
    "count.pts": ("2\n1 2 3 -120 255 0 9\n4 5 6 17 0 1 2\n", None, "colors", ["intensity"]),
    "two_scans.pts": ("1\n1 2 3 -120 255 0 9\n1\n4 5 6 17 0 1 2\n", None, "colors", ["intensity"]),
    "crlf_blank.xyz": ("1 2 3\r\n\r\n4 5 6 // trailing comment\r\n", None, None, []),
    "whitespace_lines.csv": ("x,y,z\r\n \r\n1,2,3\r\n\t \r\n4,5,6\r\n   \r\n  ", None, None, []),
    "count_crlf.pts": ("2\r\n1 2 3 -120 255 0 9\r\n4 5 6 17 0 1 2\r\n \r\n", None, "colors", ["intensity"]),
    "four.xyz": ("1 2 3 0.5\n4 5 6 0.25\n", None, None, ["column_4"]),
}


@pytest.mark.parametrize("name", list(TEXT_CASES))
def test_text_variants(tmp_path, name):
    content, normals, colors, fields = TEXT_CASES[name]
    path = tmp_path / name
    path.write_bytes(content.encode())
    got = read_points(path)
    np.testing.assert_array_equal(got.points, [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    assert (got.normals is not None) == (normals is not None)
    assert (got.colours is not None) == (colors is not None)
    if colors:
        np.testing.assert_array_equal(got.colours, [[255, 0, 9], [0, 1, 2]])
    if normals:
        np.testing.assert_array_equal(got.normals[0], [0, 0, 1])
    assert list(got.fields) == fields


def test_text_nan_rows_are_kept(tmp_path):
    (tmp_path / "nan.xyz").write_text("1 2 3\nnan 5 NaN\n7 8 9\n")
    got = read_points(tmp_path / "nan.xyz")
    assert np.isnan(got.points[1, [0, 2]]).all() and got.points[1, 1] == 5


@pytest.mark.parametrize(
    "name,content,message",
    [
        ("cols.xyz", "1 2 3\n4 5 6\n7 8 9 10\n", r"cols\.xyz: line 3: expected 3 values, found 4"),
        ("short.csv", "x,y,z\n1,2,3\n\n4,5\n", r"short\.csv: line 4: expected 3 values, found 2"),
        (
            "word.txt",
            "# c\n1 2 3\n4 five 6\n",
            r"word\.txt: line 3: column 2 holds 'five', not a number",
        ),
        ("gap.csv", "x,y,z\n1,,3\n", r"gap\.csv: line 2: column 2 holds an empty value"),
        ("two.xyz", "1 2\n3 4\n", r"two\.xyz: line 1: expected at least 3 values"),
        (
            "noxyz.csv",
            "a,b,c\n1,2,3\n",
            r"noxyz\.csv: no x/y/z coordinate column \(columns: a, b, c\)",
        ),
        ("noz.csv", "x,y,h\n1,2,3\n", r"no z coordinate column"),
        ("count.pts", "3\n1 2 3 4\n4 5 6 7\n", r"count\.pts: line 1: the count line says 3 points, 2 follow$"),
        (
            "hdr.csv",
            "x,y,z,w\n1,2,3\n",
            r"hdr\.csv: line 1: the header names 4 columns but line 2 has 3",
        ),
    ],
)
def test_text_errors_name_the_line(tmp_path, name, content, message):
    (tmp_path / name).write_text(content)
    with pytest.raises(HeatcurvError, match=message):
        read_points(tmp_path / name)
