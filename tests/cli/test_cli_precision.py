"""``heatcurv compute`` on a LAS file: its scale is the coordinates' precision (heatcurv.flags.reliability)."""

import numpy as np
import pytest
from cli_helpers import run

from heatcurv import io, surfaces


def write_las(path, points, scale):
    laspy = pytest.importorskip("laspy")
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales, header.offsets = np.full(3, scale), np.zeros(3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = points.T
    las.write(path)


@pytest.mark.parametrize("scale, largest, n_reliable", [(0.01, "0.005", 0), (1e-6, "5e-07", 1998)])
def test_a_las_files_scale_makes_points_too_coarse_for_their_curvature_unreliable(tmp_path, scale, largest,
                                                                                   n_reliable):
    # the torus of tests/test_precision.py: on a 0.01 grid every point can move by more than 1 %; on a
    # 1e-6 grid two points with a neighbour much nearer than the spacing can (read as float64: all reliable)
    points = surfaces.Torus(r1=1.0, r2=3.0).sample(2000, "random", seed=1).points
    write_las(tmp_path / "torus.las", points, scale)
    out = run("compute", tmp_path / "torus.las", "-o", tmp_path / "out.npz", "--orient", "outward")
    assert out.returncode == 0, out.stderr
    reliable = io.read_points(tmp_path / "out.npz").fields["reliable"].astype(bool)
    assert int(reliable.sum()) == n_reliable
    assert (f"coordinates too coarse for the curvature: coordinate_precision, errors up to {largest}: "
            f"{2000 - n_reliable} point(s) unreliable") in out.stdout
