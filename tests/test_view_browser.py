"""heatcurv.view in a real browser: headless Chromium (software WebGL) draws the page, and a field switch shows.

Skipped only where no Chromium is installed (``apt-get install -y chromium``
on Debian; CI installs it).
"""

import re
import shutil
import subprocess

import numpy as np
import pytest

from heatcurv.view import write_view

BROWSER = next((shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome")
                if shutil.which(name)), None)
pytestmark = pytest.mark.skipif(BROWSER is None, reason="no Chromium to draw the page (apt-get install -y chromium)")

WIDTH, HEIGHT = 800, 600


def _chromium(tmp_path, *args):
    profile = tmp_path / "profile"
    return subprocess.run(
        [BROWSER, "--headless", "--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
         "--hide-scrollbars", f"--user-data-dir={profile}", f"--window-size={WIDTH},{HEIGHT}", *map(str, args)],
        capture_output=True, text=True, timeout=180, cwd=tmp_path,
    )


def screenshot(tmp_path, page, field) -> np.ndarray:
    """RGB pixels (0-255) of the page showing ``field`` (``#field=`` in the address)."""
    from matplotlib.image import imread

    png = tmp_path / f"{field}.png"
    out = _chromium(tmp_path, f"--screenshot={png}", f"{page.resolve().as_uri()}#field={field}")
    assert png.exists(), out.stderr[-2000:]
    image = imread(png)
    assert image.shape[:2] == (HEIGHT, WIDTH)
    return np.round(image[..., :3] * 255).astype(int)


def red(pixels):
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    return (r > 120) & (r > g + 60) & (r > b + 60)


def blue(pixels):
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    return (b > 120) & (b > r + 60) & (b > g + 40)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """A flat 2 x 1 sheet in the x-y plane, normals +z, seen face-on: x to the right, y up.

    Field ``a`` is +1 right of the middle and -1 left of it, ``b`` the opposite;
    the top quarter is unreliable, grey in ``a`` only.
    """
    x, y = np.meshgrid(np.linspace(-1, 1, 300), np.linspace(-0.5, 0.5, 150))
    points = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    side = np.where(points[:, 0] > 0, 1.0, -1.0)
    normals = np.tile([0.0, 0.0, 1.0], (points.shape[0], 1))
    path = tmp_path_factory.mktemp("browser") / "sheet.html"
    write_view(points, {"a": side, "b": -side}, path, normals, reliable=points[:, 1] < 0.25, grey_unreliable=["a"])
    return path


# the sheet fills x 153-647, y 177-423 of the 800 x 600 window (the farthest point at 0.92 of the half
# height: 247 pixels per unit), its unreliable top quarter y 177-238
RIGHT = (slice(260, 400), slice(440, 620))
LEFT = (slice(260, 400), slice(180, 360))
TOP = (slice(185, 230), slice(180, 620))
BACKGROUND = (slice(200, 400), slice(700, 790))


def test_the_page_draws_the_field_and_a_switch_changes_the_pixels(tmp_path, page):
    a, b = screenshot(tmp_path, page, "a"), screenshot(tmp_path, page, "b")
    # the red end of the colour map where the field is +1, the blue end where it is -1
    assert red(a[RIGHT]).mean() > 0.95 and blue(a[LEFT]).mean() > 0.95
    assert blue(b[RIGHT]).mean() > 0.95 and red(b[LEFT]).mean() > 0.95
    # the white background beside the sheet
    assert (a[BACKGROUND] >= 250).all() and (b[BACKGROUND] >= 250).all()
    # the unreliable strip is grey in a (the missing colour #bbbbbb, lit face-on), coloured in b
    grey = np.all(np.abs(a[TOP] - 187) <= 3, axis=-1)
    assert grey.mean() > 0.95
    assert (red(b[TOP]) | blue(b[TOP])).mean() > 0.95
    changed = np.any(np.abs(a - b) > 60, axis=-1)
    assert changed.mean() > 0.25


def test_the_page_runs_its_script_without_error(tmp_path, page):
    out = _chromium(tmp_path, "--dump-dom", f"{page.resolve().as_uri()}#field=b")
    status = re.search(r'<body data-status="([^"]*)"', out.stdout)
    assert status is not None, out.stdout[:2000]
    assert status[1] == "drawn 45000 points, field b"
    assert re.search(r'<option value="b">b</option>', out.stdout)
