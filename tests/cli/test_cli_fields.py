"""heatcurv.cli.fields: the ``--fields`` list."""

import argparse

import pytest

from heatcurv.cli.fields import COMPUTED_FIELDS, DEFAULT_FIELDS, field_list


def test_field_list_expands_groups_in_the_written_order():
    assert field_list("k1,mean") == ("mean", "k1")
    assert field_list("d1 curvatures") == ("mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z")
    assert field_list("ny") == ("nx", "ny", "nz")  # normals come as a triple
    assert field_list("default") == DEFAULT_FIELDS and field_list("all") == COMPUTED_FIELDS


@pytest.mark.parametrize("text, message", [("", "comma-separated"), ("mean,colour", "unknown field 'colour'")])
def test_field_list_errors(text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        field_list(text)
