"""heatcurv.cli.progressbar: the progress bar over the estimator's stages."""

import io as stdio

import pytest

from heatcurv import surfaces
from heatcurv.cli.progressbar import StageProgress
from heatcurv.estimator import estimate
from heatcurv.progress import PROGRESS_STAGES


@pytest.mark.parametrize("method", ["default", "paper"])
def test_progress_bar_runs_over_the_stages(method):
    stream = stdio.StringIO()
    bar = StageProgress(enabled=True, stream=stream, method=method)
    seen = []
    for stage in PROGRESS_STAGES[method]:
        for fraction in (0.0, 0.5, 1.0):
            bar(stage, fraction)
            seen.append(bar.done)
    assert seen == sorted(seen) and 0 < seen[1] < 50 < seen[-1]  # never back, 0 -> 100 %
    assert bar.done == pytest.approx(100.0)
    bar.close()
    assert PROGRESS_STAGES[method][-1] in stream.getvalue()
    StageProgress(enabled=False)("mean", 0.5)  # does nothing


@pytest.mark.parametrize("method", ["default", "paper"])
def test_a_real_run_fills_the_bar_and_never_moves_it_back(method):
    bar = StageProgress(enabled=True, stream=stdio.StringIO(), method=method)
    seen = []

    def progress(stage, fraction):
        bar(stage, fraction)
        seen.append(bar.done)

    estimate(surfaces.Sphere().sample(1500, "fibonacci").points, method=method, progress=progress)
    assert seen == sorted(seen) and seen[-1] == pytest.approx(100.0)
    bar.close()
