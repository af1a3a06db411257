"""Tests of heatcurv.surfaces._util (and the constructors): argument checks and their messages.
"""

from __future__ import annotations

import numpy as np
import pytest

from heatcurv import surfaces as hs
from heatcurv.errors import HeatcurvError


def test_errors():
    surf = hs.Sphere()
    with pytest.raises(HeatcurvError, match="grid, fibonacci, random, jittered, scan"):
        surf.sample(100, "poisson")
    for bad in (3, 0, -5):
        with pytest.raises(HeatcurvError, match="at least 4"):
            surf.sample(bad)
    with pytest.raises(HeatcurvError):
        surf.sample(10.5)
    with pytest.raises(HeatcurvError):
        surf.sample(100, noise=-0.1)
    with pytest.raises(HeatcurvError):
        surf.sample(100, noise=float("nan"))
    with pytest.raises(HeatcurvError, match="sphere.*torus|torus.*sphere"):
        hs.get("klein_bottle")
    with pytest.raises(HeatcurvError):
        hs.get("sphere", radius=-1)
    with pytest.raises(HeatcurvError):
        hs.get("sphere", radus=1)
    with pytest.raises(HeatcurvError):
        hs.Torus(r1=2.0, r2=1.0)
    with pytest.raises(HeatcurvError):
        hs.FoldedSquare(interior_angle=0)
    with pytest.raises(HeatcurvError):
        hs.FoldedSquare(interior_angle=200)
    with pytest.raises(HeatcurvError):
        surf.position([0.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(HeatcurvError):
        surf.position([np.nan], [0.0])
    assert issubclass(HeatcurvError, ValueError)
