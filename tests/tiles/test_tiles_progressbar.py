"""The tiles' progress bar: points per second, tiles done, time left."""

import io

from heatcurv.tiles.progressbar import TileProgress


def test_bar_shows_rate_tiles_and_time_left():
    stream = io.StringIO()
    bar = TileProgress(True, 1000, 4, stream=stream)
    bar.skip(250, 1)  # a resumed tile: not counted in the rate
    bar(250)
    bar.close()
    text = stream.getvalue()
    assert "2/4 tiles" in text and "pt/s" in text and "left" in text and "tiles" in text


def test_disabled_bar_does_nothing():
    bar = TileProgress(False, 1000, 4)
    bar(10)
    bar.stage("writing")
    bar.close()
    assert bar.bar is None and bar.done == 1
