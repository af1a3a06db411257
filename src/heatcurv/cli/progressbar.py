"""The progress bar of the commands that estimate: one tqdm bar over the estimator's stages."""

from __future__ import annotations

import sys

__all__ = ["StageProgress"]

# share of the run time of each stage of estimate(), for the progress bar
_STAGE_WEIGHTS = {
    "validate": 1, "neighbours": 6, "spacing": 1, "areas": 10,
    "normals": 4, "orientation": 4, "mean": 6, "principal": 68,
}


class StageProgress:
    """One tqdm bar over the stages of :func:`heatcurv.estimate`, fed by its ``progress`` callback.

    Parameters
    ----------
    enabled : bool
        Draw the bar; otherwise calls do nothing.
    stream : file, optional
        Where the bar goes (stderr).

    Notes
    -----
    The bar runs 0-100 %, each stage weighted by its usual share of the run
    time (the curvature fit, which reports its blocks, about two thirds); the
    description names the running stage.
    """

    def __init__(self, enabled: bool, stream=None):
        self.bar = None
        self.done = 0.0
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(
                total=100, file=stream if stream is not None else sys.stderr, leave=False,
                bar_format="{desc:<12}{percentage:3.0f}%|{bar}| {elapsed}", mininterval=0.1,
                dynamic_ncols=True,
            )

    def __call__(self, stage: str, fraction: float) -> None:
        if self.bar is None:
            return
        from ..progress import STAGES

        order = list(STAGES)  # the stage names in the order they run (STAGES maps them to descriptions)
        before = sum(_STAGE_WEIGHTS.get(s, 0) for s in order[: order.index(stage)]) if stage in order else self.done
        position = min(100.0, before + _STAGE_WEIGHTS.get(stage, 0) * float(fraction))
        self.done = max(self.done, position)
        self.bar.set_description_str(stage, refresh=False)
        self.bar.n = self.done
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
