"""heatcurv.errors: one exception family."""

import pytest

import heatcurv
from heatcurv.errors import HeatcurvError, HeatcurvWarning


def test_errors_are_value_errors_and_warnings_user_warnings():
    assert issubclass(HeatcurvError, ValueError) and issubclass(HeatcurvWarning, UserWarning)
    with pytest.raises(ValueError, match="points must have shape"):
        heatcurv.estimate([[0.0, 1.0]])
