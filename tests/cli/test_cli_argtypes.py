"""heatcurv.cli.argtypes: the argparse types of the command line's values."""

import argparse

import pytest

from heatcurv.cli.argtypes import (
    finite_float,
    in_range,
    pair,
    percentile_pair,
    picture_size,
    point3,
)


def test_good_values():
    assert point3("-1, 2 3") == (-1.0, 2.0, 3.0)
    assert pair("0.5,2") == (0.5, 2.0)
    assert percentile_pair("2,98") == (2.0, 98.0)
    assert finite_float("-2") == -2.0
    assert picture_size("1600x800") == (1600, 800)


@pytest.mark.parametrize(
    ("parse", "text", "message"),
    [
        (point3, "1,2", "expected three numbers X,Y,Z, got '1,2'"),
        (point3, "1,nan,2", "expected three numbers"),
        (pair, "3,1", "expected LOW < HIGH"),
        (percentile_pair, "-1,50", r"percentiles must lie in 0\.\.100"),
        (finite_float, "inf", "expected a finite number"),
        (picture_size, "big", "expected WIDTHxHEIGHT in pixels"),
    ],
)
def test_bad_values_are_argparse_errors(parse, text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        parse(text)


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("views", "0", r"^views = 0 is outside its range \[1, 36\]: "),
        ("views", "2.5", r"^expected an integer, got '2.5'$"),
        ("dpi", "1e9", r"^expected an integer, got '1e9'$"),
        ("dpi", "5000", r"^dpi = 5000 is outside its range \[10, 2400\]"),
        ("max_points", "0", r"^max_points = 0 is outside its range \[1, 100000000\]"),
        ("point_size", "1e30", r"^point_size = 1e\+30 is outside its range \[0.01, 1000\]"),
        ("point_size", "nan", r"^point_size must be a number in \[0.01, 1000\], got nan$"),
        ("elevation", "100", r"^elevation = 100 is outside its range \[-90, 90\]"),
        ("threshold", "-1", r"^threshold = -1 is outside its range \[0, 180\]"),
        ("min_angle", "inf", r"^min_angle must be a number in \[0, 180\], got inf$"),
        ("n", "3", r"^n = 3 is outside its range \[4, 10000000\]"),
        ("noise", "2", r"^noise = 2 is outside its range \[0, 1\]"),
        ("seed", "-1", r"^seed = -1 is outside its range \[0, "),
    ],
)
def test_range_types_name_the_value_and_the_range(name, text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        in_range(name)(text)


def test_range_types_accept_their_ends():
    assert in_range("views")("36") == 36 and in_range("elevation")("-90") == -90.0
    assert in_range("dpi")("2400") == 2400 and in_range("point_size")("0.01") == 0.01
