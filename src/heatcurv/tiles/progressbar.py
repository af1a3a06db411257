"""The progress bar of a tiled run: one tqdm bar over the points of the finished tiles."""

from __future__ import annotations

import sys

__all__ = ["TileProgress"]


class TileProgress:
    """A tqdm bar counting computed points, with tiles done, points per second and the time left.

    Parameters
    ----------
    enabled : bool
        Draw the bar (on a terminal); otherwise calls do nothing.
    points : int
        Points to compute (the finished tiles' points of a resumed run are
        counted at once and left out of the rate).
    tiles : int
        Tiles to compute.
    stream : file, optional
        Where the bar goes (stderr).
    """

    def __init__(self, enabled: bool, points: int, tiles: int, stream=None):
        self.bar, self.tiles, self.done = None, tiles, 0
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(
                total=points, file=stream if stream is not None else sys.stderr, leave=False, unit="pt",
                unit_scale=True, dynamic_ncols=True, mininterval=0.5, smoothing=0.1,
                bar_format="{desc:<12}{percentage:3.0f}%|{bar}| {postfix} {rate_fmt}, {remaining} left",
            )
            self._describe()

    def _describe(self) -> None:
        self.bar.set_description_str("tiles", refresh=False)
        self.bar.set_postfix_str(f"{self.done}/{self.tiles} tiles", refresh=True)

    def skip(self, points: int, tiles: int) -> None:
        """Finished tiles of a resumed run: advance without counting them in the rate."""
        self.done += tiles
        if self.bar is not None:
            self.bar.total -= points
            self.bar.refresh()
            self._describe()

    def __call__(self, points: int) -> None:
        """One more tile of ``points`` points done."""
        self.done += 1
        if self.bar is not None:
            self.bar.update(points)
            self._describe()

    def stage(self, text: str) -> None:
        """Name what runs before and after the tiles (tiling, survey, writing)."""
        if self.bar is not None:
            self.bar.set_description_str(text, refresh=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
