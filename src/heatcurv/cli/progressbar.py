"""The progress bar of the commands that estimate: one tqdm bar over the estimator's stages."""

from __future__ import annotations

import sys

from ..progress import PROGRESS_STAGES, PROGRESS_WEIGHTS

__all__ = ["StageProgress"]


class StageProgress:
    """One tqdm bar over the stages of :func:`heatcurv.estimate`, fed by its ``progress`` callback.

    Parameters
    ----------
    enabled : bool
        Draw the bar; otherwise calls do nothing.
    stream : file, optional
        Where the bar goes (stderr).
    method : {"default", "paper"}, optional
        The method whose stages run (:data:`heatcurv.progress.PROGRESS_STAGES`).

    Notes
    -----
    The bar runs 0-100 %, each stage weighted by its measured share of the
    run time (:data:`heatcurv.progress.PROGRESS_WEIGHTS`; the default
    method's fit, which reports its blocks, about half); the description
    names the running stage.
    """

    def __init__(self, enabled: bool, stream=None, method: str = "default"):
        self.bar = None
        self.done = 0.0
        self.order = list(PROGRESS_STAGES.get(method, PROGRESS_STAGES["default"]))
        self.weights = PROGRESS_WEIGHTS.get(method, PROGRESS_WEIGHTS["default"])
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(
                total=100, file=stream if stream is not None else sys.stderr, leave=False,
                bar_format="{desc:<12}{percentage:3.0f}%|{bar}| {elapsed}", mininterval=0.1,
                dynamic_ncols=True,
            )

    def position(self, stage: str, fraction: float) -> float:
        """Percent done when ``stage`` is ``fraction`` done (stages never move the bar back)."""
        if stage in self.order:
            before = sum(self.weights[s] for s in self.order[: self.order.index(stage)])
            return max(self.done, min(100.0, before + self.weights[stage] * float(fraction)))
        return self.done

    def __call__(self, stage: str, fraction: float) -> None:
        if self.bar is None:
            return
        self.done = self.position(stage, fraction)
        self.bar.set_description_str(stage, refresh=False)
        self.bar.n = self.done
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
