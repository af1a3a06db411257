"""heatcurv.flags.border: the border flags of open surfaces from the tapered centroid offset."""

import numpy as np
from scipy.spatial import cKDTree

from heatcurv import surfaces
from heatcurv.flags.border import border_points, centroid_offset
from heatcurv.geometry.neighbourhood import ball_neighbourhood
from heatcurv.operators.kernel import ball_taper
from heatcurv.tuning import TUNING


def test_border_points_of_an_open_patch():
    sample = surfaces.Plane().sample(10000, "random", seed=5)
    pts = sample.points
    tree = cKDTree(pts)
    d, _ = tree.query(pts, k=61)
    nb = ball_neighbourhood(pts, d[:, -1], tree=tree)
    normals = np.tile([0, 0, 1.0], (len(pts), 1))
    offset = centroid_offset(pts, nb, normals, ball_taper(nb))
    flagged = border_points(pts, nb, normals, weights=ball_taper(nb))
    R = np.median(nb.radius)
    # every point on the border is flagged, no point deeper than one ball radius is
    edge = sample.border_distance < 0.05 * R
    assert flagged[edge].all()
    assert not flagged[sample.border_distance > R].any()
    assert np.median(offset[sample.border_distance > R]) < 0.1 < TUNING.border_offset
