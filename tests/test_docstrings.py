"""The examples in the public docstrings run and print what they claim."""

import doctest

import pytest

import heatcurv.data
import heatcurv.estimator
import heatcurv.features
import heatcurv.operators.operator
import heatcurv.render
import heatcurv.shading
import heatcurv.view

MODULES = [
    heatcurv.estimator, heatcurv.features, heatcurv.operators.operator, heatcurv.render, heatcurv.shading,
    heatcurv.view,
    heatcurv.data,
]


@pytest.mark.parametrize("module", MODULES, ids=lambda m: m.__name__)
def test_docstring_examples(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0
    assert result.failed == 0
