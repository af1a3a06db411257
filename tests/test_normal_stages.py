"""heatcurv.normal_stages: the orientation policy of a call, and the reason its report gives."""

import pytest

import heatcurv
from heatcurv.errors import HeatcurvError
from heatcurv.normal_stages import explained, orientation_mode
from heatcurv.orient.orientation import OrientationReport


@pytest.mark.parametrize("option, normals, viewpoint, mode", [
    ("auto", None, None, "auto"), ("auto", None, (0, 0, 5), "viewpoint"), ("auto", "given", None, "given"),
    ("outward", None, None, "outward"), ("up", None, None, "up"), ("viewpoint", None, (0, 0, 5), "viewpoint"),
])
def test_the_policy_of_a_call(option, normals, viewpoint, mode):
    assert orientation_mode(option, normals, viewpoint) == mode


@pytest.mark.parametrize("option, normals, viewpoint, message", [
    ("auto", "given", (0, 0, 5), "either normals or a viewpoint"),
    ("up", "given", None, "given normals are kept"),
    ("viewpoint", None, None, "needs viewpoint"),
    ("outward", None, (0, 0, 5), "cannot be combined with orient='outward'"),
])
def test_contradicting_orientation_options_are_refused(option, normals, viewpoint, message):
    with pytest.raises(HeatcurvError, match=message):
        orientation_mode(option, normals, viewpoint)


def test_the_reason_says_why_the_sides_are_what_they_are():
    assert explained(OrientationReport("given"), None, 10).reason == "the given normals, as they are"
    assert explained(OrientationReport("viewpoint"), None, 10).reason == "towards the viewpoint"
    assert explained(OrientationReport("up"), None, 10).reason == "orient='up': towards +z"
    crowns = explained(OrientationReport("viewpoint", axisless=3), None, 10).reason
    assert crowns == ("towards the viewpoint; 3 points whose ball has no normal axis (a tree crown, a wire, strong "
                      "noise) start from it")
    closed = explained(OrientationReport("outward", closed=True), None, 10)
    assert closed.reason.startswith("encloses a volume")
    part = explained(OrientationReport("outward", closed=None), None, 10)
    assert "a part of a cloud" in part.reason
    # the estimator's report carries the same reason: a closed torus encloses a volume
    res = heatcurv.estimate(heatcurv.surfaces.Torus().sample(3000, "random", seed=1).points)
    assert res.info["orientation"].reason.endswith("encloses a volume: away from it (winding number)")
