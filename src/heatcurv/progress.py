"""The estimator's named stages: their order, their timing, and progress reports.

:func:`heatcurv.estimate` and :func:`heatcurv.operators.operator.build_operator` accept a
``progress`` callable, called as ``progress(stage, fraction)``: with
``fraction = 0`` when a stage starts, ``1`` when it ends. The default
estimator's fit streams over blocks of points (so its memory stays bounded):
its stages run once per block and report together as the group ``"fit"``,
with the fraction of points done. The command line draws its progress bar
from these calls; a library user can pass any callable (e.g. one that logs).

Every stage is timed under its own name into ``result.info["timings"]``
(seconds, summed over blocks), which ``heatcurv compute --verbose`` prints.
:data:`STAGES` lists them in the order they run; a run has only the stages of
its method (``"default"`` or ``"paper"``).
"""

from __future__ import annotations

import time
from contextlib import contextmanager

__all__ = ["STAGES", "FIT_STAGES", "ANCHOR_STAGES", "PROGRESS_STAGES", "PROGRESS_WEIGHTS", "StageClock"]

#: Every stage, in the order it runs, with what it computes.
STAGES = {
    # the shared heat-kernel operator (heatcurv.operators.operator)
    "validate": "checks, centring, duplicate merging, k-d tree order",
    "neighbours": "ball neighbourhood of radius alpha h (density spacing: the k nearest)",
    "spacing": "spacing h (eq 2.6, 2.7, or the density radius d_k / alpha)",
    "areas": "per-point areas (H A = 1, section 2.2, or the density estimate)",
    "kernel_check": "the fit's kernel has enough effective neighbours (heatcurv.choice.kernel_check)",
    "outliers": "stray points and islands that no surface explains (heatcurv.flags.outliers)",
    # normals
    "normals": "PCA normals (or the caller's normals)",
    "orientation": "one consistent orientation (spanning tree) or towards the viewpoint",
    "mean_curvature_normal": "K = L x (eq 2.10)",
    # method "paper"
    "mean": "mean curvature from K and the normal (eq 2.11 / 2.12)",
    "principal": "tensor fit of the edge curvatures (section 3, eq 3.1)",
    # method "default": the kernel, then the fit block by block
    "kernel_choice": "noise estimate and kernel width of the chord fit (heatcurv.choice.scale)",
    "fit_neighbourhood": "the fit kernel's own neighbours (k nearest)",
    "fit_weights": "tapered heat-kernel weights of the fit (eq 2.8)",
    "normal_refinement": "a first chord fit whose tilt corrects the normals",
    "curvature_fit": "the chord fit at the refined normals: k1, k2, d1, d2, mean",
    "anchor_fit": "noisy clouds: the fit at anchors, each with all the points of its wide ball (heatcurv.fits.anchors)",
    "carry": "noisy clouds: the anchors' fits carried to every point (normals, curvatures, border, areas)",
    # both
    "border": "border points of open surfaces (the offset of the ball's centroid)",
    # method "default"
    "area_correction": "areas on the fit's kernel, corrected by the fitted curvatures and the border's cut",
    "standard_errors": "standard errors: the fit's noise, and its bias from refits at twice the kernel",
}

#: The default method's stages that run once per block of points (clean clouds).
FIT_STAGES = ("fit_neighbourhood", "fit_weights", "normal_refinement", "curvature_fit", "border", "area_correction")
#: The default method's fit stages on noisy clouds (the wide kernel fitted at anchors).
ANCHOR_STAGES = ("anchor_fit", "carry", "area_correction")

#: Names ``progress`` is called with, in order, per method (the fit's block stages report as ``"fit"``).
PROGRESS_STAGES = {
    "paper": (
        "validate", "spacing", "neighbours", "areas", "kernel_check", "outliers", "normals", "orientation",
        "mean_curvature_normal", "mean", "principal", "border",
    ),
    "default": (
        "validate", "neighbours", "spacing", "areas", "kernel_check", "outliers", "normals", "orientation",
        "mean_curvature_normal", "kernel_choice", "fit", "standard_errors",
    ),
}

#: Share (%) of a run's time per progress stage, for progress bars: measured on a 200 000-point
#: random torus on the project's 2-core machine (default: clean; the fit's share grows with noise).
PROGRESS_WEIGHTS = {
    "paper": {
        "validate": 1, "spacing": 1, "neighbours": 5, "areas": 76, "kernel_check": 0, "outliers": 7, "normals": 0,
        "orientation": 5, "mean_curvature_normal": 0, "mean": 0, "principal": 5, "border": 0,
    },
    "default": {
        "validate": 2, "neighbours": 20, "spacing": 0, "areas": 2, "kernel_check": 0, "outliers": 10, "normals": 6,
        "orientation": 8, "mean_curvature_normal": 2, "kernel_choice": 2, "fit": 45, "standard_errors": 3,
    },
}


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
    def stage(self, name: str, report: bool = True):
        """Time the block as stage ``name`` (added to an earlier time of the same name).

        ``report=False`` times it without progress calls: a stage that runs
        once per block, whose group reports the fraction done.
        """
        if report:
            self.report(name, 0.0)
        tic = time.perf_counter()
        try:
            yield self
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - tic
        if report:
            self.report(name, 1.0)
