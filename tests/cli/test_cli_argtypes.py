"""heatcurv.cli.argtypes: the argparse types of the command line's values."""

import argparse

import pytest

from heatcurv.cli.argtypes import (
    finite_float,
    int_at_least,
    pair,
    percentile_pair,
    picture_size,
    point3,
    positive_float,
)


def test_good_values():
    assert point3("-1, 2 3") == (-1.0, 2.0, 3.0)
    assert pair("0.5,2") == (0.5, 2.0)
    assert percentile_pair("2,98") == (2.0, 98.0)
    assert int_at_least(3)("7") == 7
    assert positive_float("1e-3") == 0.001 and finite_float("-2") == -2.0
    assert picture_size("1600x800") == (1600, 800)


@pytest.mark.parametrize(
    ("parse", "text", "message"),
    [
        (point3, "1,2", "expected three numbers X,Y,Z, got '1,2'"),
        (point3, "1,nan,2", "expected three numbers"),
        (pair, "3,1", "expected LOW < HIGH"),
        (percentile_pair, "-1,50", r"percentiles must lie in 0\.\.100"),
        (int_at_least(3), "2", "must be at least 3, got 2"),
        (int_at_least(3), "two", "expected an integer, got 'two'"),
        (positive_float, "0", "expected a positive number"),
        (finite_float, "inf", "expected a finite number"),
        (picture_size, "big", "expected WIDTHxHEIGHT in pixels"),
    ],
)
def test_bad_values_are_argparse_errors(parse, text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        parse(text)
