"""Stage timing and progress reports of the pipeline.

:func:`heatcurv.estimate` and :func:`heatcurv.build_operator` accept a
``progress`` callable, called as ``progress(stage, fraction)``: with
``fraction = 0`` when a stage starts, ``1`` when it ends, and values in
between where a stage works in blocks (the curvature fit). The command line
draws its progress bars from these calls; a library user can pass any
callable (e.g. one that logs).

Stage names, in order: ``validate``, ``neighbours``, ``spacing``, ``areas``,
``normals``, ``orientation``, ``mean``, ``principal``.
"""

from __future__ import annotations

import time
from contextlib import contextmanager

__all__ = ["STAGES", "StageClock"]

#: The pipeline's stages, in the order they run.
STAGES = ("validate", "neighbours", "spacing", "areas", "normals", "orientation", "mean", "principal")


class StageClock:
    """Times named stages into a dict and forwards progress to an optional callback.

    Parameters
    ----------
    progress : callable, optional
        ``progress(stage, fraction)``.
    timings : dict, optional
        Where the seconds per stage go (a new dict by default).
    """

    def __init__(self, progress=None, timings: dict | None = None):
        self.progress = progress
        self.timings = {} if timings is None else timings

    def report(self, stage: str, fraction: float) -> None:
        """Tell the callback how far ``stage`` is (0..1)."""
        if self.progress is not None:
            self.progress(stage, float(min(max(fraction, 0.0), 1.0)))

    @contextmanager
    def stage(self, name: str):
        """Time the block as stage ``name`` (added to an earlier time of the same name)."""
        self.report(name, 0.0)
        tic = time.perf_counter()
        try:
            yield self
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - tic
        self.report(name, 1.0)
