"""heatcurv.choice.choices: the whole cloud's frame, streamed in chunks or taken in memory, is one frame."""

import numpy as np
import pytest

import heatcurv
from heatcurv.choice.choices import FrameStats, frame_of
from heatcurv.errors import HeatcurvError
from heatcurv.geometry.validation import prepare_points


def test_streamed_frame_equals_the_in_memory_frame():
    pts = heatcurv.surfaces.Sphere(3.0).sample(2000, "random", seed=1).points + [6.1e5, 4.2e6, 35.0]
    # parts as a tiled run has them: every duplicate in its twin's part
    parts = [np.vstack([part, part[:5], part[:2]]) for part in np.array_split(pts, 9)]
    whole = np.vstack(parts)
    rows = FrameStats()
    for part in parts:
        rows.add(part)
    box = rows.frame()  # pass 1: the box (offset and unit)
    streamed = FrameStats()
    for part in parts:
        streamed.add_distinct(part, box)
    streamed, held = streamed.frame(), frame_of(prepare_points(whole))
    np.testing.assert_array_equal(streamed.offset, held.offset)  # min and max are exact in any order
    assert streamed.unit == held.unit and streamed.n_points == held.n_points == len(pts)  # duplicates once
    np.testing.assert_allclose(streamed.centroid, held.centroid, atol=1e-9)
    assert streamed.rms_radius == pytest.approx(held.rms_radius, rel=1e-12)
    # a sphere sampled uniformly: rms radius = R about its centre
    assert held.rms_radius == pytest.approx(3.0, rel=1e-3)
    # counting rows would weigh the duplicates: another frame
    assert rows.frame().n_points == len(whole)
    # the stages' coordinates of a part are those of the whole
    part = prepare_points(pts[:300], frame=streamed)
    np.testing.assert_array_equal(part.points, streamed.to_stage(pts[:300]))


def test_frame_stats_refuse_bad_chunks():
    stats = FrameStats()
    with pytest.raises(HeatcurvError, match="shape"):
        stats.add(np.zeros((4, 2)))
    with pytest.raises(HeatcurvError, match="NaN"):
        stats.add(np.array([[0.0, np.nan, 1.0]]))
    with pytest.raises(HeatcurvError, match="empty"):
        stats.frame()
