"""heatcurv.cli.progressbar: the progress bar over the estimator's stages."""

import io as stdio

import pytest

from heatcurv.cli.progressbar import StageProgress


def test_progress_bar_runs_over_the_stages():
    from heatcurv.progress import STAGES

    stream = stdio.StringIO()
    bar = StageProgress(enabled=True, stream=stream)
    for stage in STAGES:
        bar(stage, 0.0)
        bar(stage, 0.5)
        bar(stage, 1.0)
    assert bar.done == pytest.approx(100.0)
    bar.close()
    assert "principal" in stream.getvalue()
    StageProgress(enabled=False)("mean", 0.5)  # does nothing
