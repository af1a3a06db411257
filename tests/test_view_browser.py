"""heatcurv.view in a real browser: headless Chromium (software WebGL) draws the page and answers the mouse.

Skipped only where no Chromium is installed (``apt-get install -y chromium``
on Debian; CI installs it).
"""

import io

import numpy as np
import pytest

from heatcurv.view import write_view
from support.browser import BROWSER, Chromium

pytestmark = pytest.mark.skipif(BROWSER is None, reason="no Chromium to draw the page (apt-get install -y chromium)")

STATUS = "String(document.body && document.body.dataset.status)"
FRAMES = "Number(document.body && document.body.dataset.frames || 0)"
#: The page has drawn, and its WebGL context is live (software WebGL may lose it; the page then draws again).
READY = (f"{STATUS}.startsWith('drawn') && !document.getElementById('view').getContext('webgl').isContextLost() "
         f"&& {FRAMES}")


def pixels(png) -> np.ndarray:
    """RGB values 0-255 of a PNG (a path or bytes)."""
    from matplotlib.image import imread

    image = imread(io.BytesIO(png) if isinstance(png, bytes) else png, format="png")
    return np.round(image[..., :3] * 255).astype(int)


def red(rgb):
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (r > 120) & (r > g + 60) & (r > b + 60)


def blue(rgb):
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (b > 120) & (b > r + 60) & (b > g + 40)


def grey(rgb):
    return np.all(np.abs(rgb - 187) <= 3, axis=-1)  # the missing colour #bbbbbb, lit face-on


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


def regions(browser, rgb) -> dict:
    """Parts of a picture of the sheet seen face-on, from the viewport's size.

    The page draws the cloud above a band at the bottom (its colour bar's box
    and a margin), the farthest point of the sheet (a corner, at sqrt(1.25)
    from its centre) at 0.92 of the half of the smaller side of the rest: the
    sheet spans ``2 s x s`` pixels about the middle of the rest, its
    unreliable top quarter the top ``s / 4``. The regions keep clear of the
    page's panel (top left).
    """
    height, width = rgb.shape[:2]
    band = browser.evaluate("Math.min(document.getElementById('legend').offsetHeight + 20, window.innerHeight / 2)")
    assert 40 < band < 200
    s = 0.92 * min(width, height - band) / 2 / np.sqrt(1.25)
    cx, cy = width / 2, (height - band) / 2

    def box(top, bottom, left, right):
        return slice(round(cy + top * s), round(cy + bottom * s)), slice(round(cx + left * s), round(cx + right * s))

    return {"right": box(-0.15, 0.4, 0.15, 0.85), "left": box(-0.15, 0.4, -0.85, -0.15),
            "top": box(-0.47, -0.28, 0.1, 0.85), "top_left": box(-0.47, -0.28, -0.85, -0.1),
            "background": box(-0.3, 0.3, 1.1, 1.15), "scale": s, "middle": (cx, cy)}


def width_of_sheet(rgb, part) -> int:
    """Columns of the picture's row through the sheet's middle that are not background (white)."""
    return int((rgb[round(part["middle"][1])] < 240).any(axis=-1).sum())


def choose(browser, menu: str, value: str) -> None:
    """Pick ``value`` in the page's menu ``menu`` as a user would (the change event follows)."""
    browser.evaluate(f"(() => {{ const m = document.getElementById('{menu}'); m.value = '{value}'; "
                     "m.dispatchEvent(new Event('change')); })()")


def _redrawn(browser, before: int) -> None:
    browser.wait_for(f"{FRAMES} > {before}", timeout=30)


def picture(browser) -> np.ndarray:
    """A screenshot of the page once it has drawn with a live WebGL context (taken again if it was lost meanwhile)."""
    for _ in range(5):
        frames = browser.wait_for(READY)
        png = browser.screenshot()
        if browser.wait_for(READY) == frames:
            return pixels(png)
    raise AssertionError("the page kept losing its WebGL context")


def open_page(tmp_path, page, field=None) -> Chromium:
    """Chromium showing the page (``#field=`` naming ``field``) in a window whose viewport keeps the sheet
    clear of the page's panel (the viewport is smaller than the window)."""
    address = page.resolve().as_uri() + (f"#field={field}" if field else "")
    return Chromium(address, tmp_path / f"profile-{field}", 1000, 900)


def test_the_page_draws_the_field_named_in_its_address(tmp_path, page):
    with open_page(tmp_path, page, "a") as browser:
        a = picture(browser)
        part = regions(browser, a)
    with open_page(tmp_path, page, "b") as browser:
        b = picture(browser)
    # the red end of the colour map where the field is +1, the blue end where it is -1
    assert red(a[part["right"]]).mean() > 0.95 and blue(a[part["left"]]).mean() > 0.95
    assert blue(b[part["right"]]).mean() > 0.95 and red(b[part["left"]]).mean() > 0.95
    # the white background beside the sheet
    assert (a[part["background"]] >= 250).all() and (b[part["background"]] >= 250).all()
    # the unreliable strip is grey in a, coloured in b
    assert grey(a[part["top"]]).mean() > 0.95
    assert blue(b[part["top"]]).mean() > 0.95 and red(b[part["top_left"]]).mean() > 0.95
    assert width_of_sheet(a, part) == pytest.approx(2 * part["scale"], abs=4)


def test_the_menus_and_the_mouse_change_the_picture(tmp_path, page):
    with open_page(tmp_path, page) as browser:
        assert browser.wait_for(f"{STATUS}.startsWith('drawn') && {STATUS}") == "drawn 45000 points, field a"
        first = picture(browser)
        part = regions(browser, first)
        right, left, top = part["right"], part["left"], part["top"]
        assert red(first[right]).mean() > 0.95 and blue(first[left]).mean() > 0.95 and grey(first[top]).mean() > 0.95

        # the field menu: the colours swap, the address follows
        choose(browser, "field", "b")
        assert browser.evaluate(STATUS) == "drawn 45000 points, field b"
        assert browser.evaluate("window.location.hash") == "#field=b"
        switched = picture(browser)
        assert blue(switched[right]).mean() > 0.95 and red(switched[left]).mean() > 0.95
        # every pixel of the sheet (2 s x s) changes: the colours swap, the grey strip takes colours
        assert np.any(np.abs(first - switched) > 60, axis=-1).sum() > 0.95 * 2 * part["scale"] ** 2

        # the unreliable points of a: hidden (background), then coloured
        choose(browser, "field", "a")
        choose(browser, "unreliable", "hidden")
        hidden = picture(browser)
        assert (hidden[top] >= 250).all() and red(hidden[right]).mean() > 0.95
        choose(browser, "unreliable", "coloured")
        coloured = picture(browser)
        assert red(coloured[top]).mean() > 0.95 and blue(coloured[part["top_left"]]).mean() > 0.95

        # drag 100 pixels to the right: a turn about the vertical by 180 degrees per smaller side of the
        # window, the sheet cos(turn) as wide
        face_on = width_of_sheet(coloured, part)
        assert face_on == pytest.approx(2 * part["scale"], abs=4)
        frames = browser.evaluate(FRAMES)
        browser.drag((400, 200), (500, 200))
        _redrawn(browser, frames)
        turned_picture = picture(browser)
        turned = width_of_sheet(turned_picture, part)
        assert turned == pytest.approx(face_on * np.cos(np.pi * 100 / min(first.shape[:2])), abs=6)
        assert turned < face_on - 20

        # the wheel zooms about the pointer, exp(0.3) times for 200 pixels up: the sheet grows by that
        # factor, and its point under the pointer (near its left edge, on its middle row) stays put
        def edges(rgb):
            cx, cy = part["middle"]
            row = np.flatnonzero((rgb[round(cy)] < 240).any(axis=-1))
            column = np.flatnonzero((rgb[:, round(cx + 0.6 * part["scale"])] < 240).any(axis=-1))
            return int(row[0]), int(column[0]), int(row.size)  # left edge, top edge, width

        left, top, width = edges(turned_picture)
        pointer = (left + 40, part["middle"][1])
        frames = browser.evaluate(FRAMES)
        browser.mouse("mouseWheel", *pointer, deltaX=0, deltaY=-200)
        _redrawn(browser, frames)
        zoomed = edges(picture(browser))
        factor = np.exp(0.3)
        assert zoomed[2] == pytest.approx(width * factor, abs=6)
        assert zoomed[0] == pytest.approx(pointer[0] - (pointer[0] - left) * factor, abs=3)
        assert zoomed[1] == pytest.approx(pointer[1] - (pointer[1] - top) * factor, abs=3)

        # a double click goes back to the first view
        frames = browser.evaluate(FRAMES)
        browser.mouse("mousePressed", 400, 200, button="left", buttons=1, clickCount=2)
        browser.mouse("mouseReleased", 400, 200, button="left", buttons=0, clickCount=2)
        _redrawn(browser, frames)
        assert abs(width_of_sheet(picture(browser), part) - face_on) <= 2
