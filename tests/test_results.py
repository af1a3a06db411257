"""heatcurv.results: the CurvatureResult record."""

import numpy as np

from heatcurv import surfaces
from heatcurv.estimator import estimate
from heatcurv.results import CurvatureResult


def test_result_record():
    pts = surfaces.Sphere(radius=2.0).sample(1000, "fibonacci").points
    res = estimate(np.vstack([pts, pts[:3]]))  # three exact duplicates
    assert isinstance(res, CurvatureResult) and len(res) == 1003
    assert repr(res).startswith("CurvatureResult(n=1003, method='default', total_area=")
    arrays = res.as_dict()
    assert list(arrays) == [*CurvatureResult.FIELDS, "reliable"]
    assert all(a.shape[0] == 1003 for a in arrays.values())
    # duplicates get their twin's values and share its area: the total is the surface's
    np.testing.assert_array_equal(res.mean[-3:], res.mean[:3])
    np.testing.assert_allclose(res.area.sum(), 4 * np.pi * 4, rtol=0.005)
    assert res.info["n_distinct"] == 1000 and set(res.info) == {
        "n_distinct", "area_solve", "plan", "scale", "timings", "orientation", "outliers", "second_sheet",
        "resolution",
    }
    assert res.info["plan"].label == res.info["scale"].fit == "chord-60"
