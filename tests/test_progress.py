"""The estimator as a straight list of named stages: order, timings and progress reports."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.progress import FIT_STAGES, PROGRESS_STAGES, PROGRESS_WEIGHTS, STAGES, StageClock

OPERATOR = ["validate", "neighbours", "spacing", "areas"]
CHECK = ["kernel_check", "outliers"]
NORMALS = ["normals", "orientation", "mean_curvature_normal"]


@pytest.mark.parametrize("method", ["default", "paper"])
def test_the_declared_stages(method):
    assert set(FIT_STAGES) <= set(STAGES)
    assert tuple(PROGRESS_WEIGHTS[method]) == PROGRESS_STAGES[method]
    assert sum(PROGRESS_WEIGHTS[method].values()) == 100
    assert set(PROGRESS_STAGES[method]) - {"fit"} <= set(STAGES)


def test_default_method_times_every_stage_under_its_own_name():
    sample = surfaces.Sphere().sample(3000, "random", seed=2)
    calls = []
    res = heatcurv.estimate(sample.points, progress=lambda stage, fraction: calls.append((stage, fraction)))
    started = [s for s, f in calls if f == 0.0]
    assert started == OPERATOR + CHECK + NORMALS + ["kernel_choice", "standard_errors"]
    assert all(0.0 <= f <= 1.0 for _, f in calls) and calls[-1] == ("standard_errors", 1.0)
    assert ("fit", 1.0) in calls
    assert all(s in PROGRESS_STAGES["default"] for s, _ in calls)
    assert list(res.info["timings"]) == OPERATOR + CHECK + NORMALS + ["kernel_choice", *FIT_STAGES, "standard_errors"]
    assert list(res.info["timings"]) == [s for s in STAGES if s in res.info["timings"]]  # the declared order
    assert all(t >= 0 for t in res.info["timings"].values())
    single = heatcurv.estimate(sample.points, workers=1)
    np.testing.assert_allclose(single.mean, res.mean, rtol=1e-12)


def test_given_normals_skip_orientation_and_refinement():
    sample = surfaces.Sphere().sample(2000, "fibonacci")
    res = heatcurv.estimate(sample.points, normals=sample.normals)
    assert "orientation" not in res.info["timings"] and "normal_refinement" not in res.info["timings"]
    np.testing.assert_allclose(res.normals, sample.normals, atol=1e-12)


def test_paper_method_stages():
    sample = surfaces.Sphere().sample(2000, "fibonacci")
    calls = []
    res = heatcurv.estimate(sample.points, method="paper", progress=lambda s, f: calls.append((s, f)))
    expected = ["validate", "spacing", "neighbours", "areas", *CHECK, *NORMALS, "mean", "principal", "border"]
    assert [s for s, f in calls if f == 0.0] == expected == list(PROGRESS_STAGES["paper"])
    assert list(res.info["timings"]) == expected


def test_fit_blocks_report_their_fraction(monkeypatch):
    import heatcurv.geometry.neighbourhood as neighbourhood_module

    monkeypatch.setattr(neighbourhood_module, "BLOCK_PAIRS", 20_000)  # 333 points x 60 pairs a block
    calls = []
    points = surfaces.Sphere().sample(3000, "random", seed=2).points
    heatcurv.estimate(points, progress=lambda s, f: calls.append((s, f)))
    fractions = [f for s, f in calls if s == "fit"]
    assert fractions == [min(3000, 333 * b) / 3000 for b in range(1, 11)]


def test_stage_clock_adds_up_repeated_stages():
    calls = []
    clock = StageClock(lambda s, f: calls.append((s, f)))
    for _ in range(3):
        with clock.stage("x", report=False):
            pass
    with clock.stage("y"):
        clock.report("y", 7.0)  # clipped to 1
    assert set(clock.timings) == {"x", "y"} and clock.timings["x"] >= 0
    assert calls == [("y", 0.0), ("y", 1.0), ("y", 1.0)]


def test_a_failing_stage_is_still_timed():
    clock = StageClock()
    with pytest.raises(RuntimeError), clock.stage("boom"):
        raise RuntimeError
    assert "boom" in clock.timings
