"""heatcurv._deprecation: the one helper behind every deprecated American spelling."""

import warnings

import pytest

from heatcurv import HeatcurvError
from heatcurv._deprecation import renamed_keyword


def caller(value=None, alias=None):
    return renamed_keyword("f", "colours", value, "colors", alias)


def test_the_new_name_passes_silently():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert caller(3) == 3 and caller() is None


def test_the_alias_warns_at_the_callers_line_and_is_used():
    with pytest.warns(DeprecationWarning, match=r"f: colors= is deprecated, use colours= \(British spelling\)") as rec:
        assert caller(alias=5) == 5
    assert rec[0].filename == __file__


def test_both_spellings_are_an_error():
    with pytest.raises(HeatcurvError, match="f: give colours= or its deprecated alias colors=, not both"):
        caller(1, 2)
