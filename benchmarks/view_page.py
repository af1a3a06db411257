"""Size of the page ``heatcurv view`` writes, the time to write it, and the time a browser takes to draw it.

The cloud is a random torus with the fields ``heatcurv compute`` writes by
default (15: normals, curvatures, directions, area, reliable) and the
normals for shading, as ``heatcurv view result.ply`` embeds them. The
browser time is headless Chromium (software WebGL, SwiftShader) from its
start to a screenshot of the page's first picture, where Chromium is
installed (a desktop browser with a GPU draws faster; it reads the page alike).

    python benchmarks/view_page.py --sizes 100000 1000000
    python benchmarks/view_page.py --sizes --picture docs/viewer.png

``--picture`` also writes a screenshot of the page of the packaged bunny
scan's curvature (``heatcurv compute`` then ``heatcurv view``), the picture
of docs/viewer.md.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from heatcurv import surfaces
from heatcurv.view import write_view

FIELDS = ("nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area",
          "reliable")


def page(n: int, directory: Path) -> tuple:
    sample = surfaces.Torus().sample(n, "random", seed=0)
    rng = np.random.default_rng(0)
    fields = {name: rng.standard_normal(n) for name in FIELDS}
    fields["reliable"] = rng.uniform(size=n) > 0.05
    path = directory / f"torus_{n}.html"
    tic = time.perf_counter()
    view = write_view(sample.points, fields, path, sample.normals, reliable=fields["reliable"], max_points=n)
    return path, view.size, time.perf_counter() - tic


def _browser() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def screenshot(path: Path, png: Path, profile: str, size: str = "800,600") -> None:
    subprocess.run(
        [_browser(), "--headless", "--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
         "--hide-scrollbars", f"--user-data-dir={profile}", f"--window-size={size}", f"--screenshot={png}",
         path.resolve().as_uri()],
        capture_output=True, text=True, timeout=600,
    )


def browser_seconds(path: Path) -> float | None:
    if _browser() is None:
        return None
    from matplotlib.image import imread

    with tempfile.TemporaryDirectory() as profile:
        png = Path(profile) / "page.png"
        tic = time.perf_counter()
        screenshot(path, png, profile)
        seconds = time.perf_counter() - tic
        # drawn: the torus covers a good part of the window (the background is white)
        drawn = png.exists() and (imread(png)[..., :3] < 0.9).any(axis=-1).mean() > 0.2
    return seconds if drawn else float("nan")


def bunny_picture(png: Path) -> None:
    """The page of the bunny scan's curvature, as ``heatcurv view`` writes it, in a 900 x 600 window."""
    from heatcurv.data import bunny_path

    if _browser() is None:
        raise SystemExit("--picture needs Chromium (apt-get install -y chromium)")
    with tempfile.TemporaryDirectory() as directory:
        result, page = Path(directory) / "bunny_curvature.ply", Path(directory) / "bunny_curvature.html"
        for command in (["compute", str(bunny_path()), "-o", str(result)], ["view", str(result), "--no-browser"]):
            subprocess.run([sys.executable, "-m", "heatcurv", *command, "-q"], check=True)
        from matplotlib.image import imread

        for _ in range(3):  # software WebGL may lose its context at start-up, before the screenshot
            screenshot(page, png.resolve(), directory, "900,600")
            if (imread(png)[..., :3] < 0.9).any(axis=-1).mean() > 0.1:
                break
        else:
            raise SystemExit(f"Chromium did not draw the page in three attempts: see {png}")
    print(f"wrote {png}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[100_000, 1_000_000])
    parser.add_argument("--picture", type=Path, help="also write a screenshot of the bunny's page here")
    args = parser.parse_args()
    if args.picture is not None:
        bunny_picture(args.picture)
    if not args.sizes:
        return
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from machine import commit, cpu_model, memory_text  # benchmarks/machine.py

    print(f"Machine: {cpu_model()}, {os.cpu_count()} cores{memory_text()}; load average "
          f"{os.getloadavg()[0]:.1f} at the start; heatcurv at commit {commit()}\n")
    print(f"{'points':>10s} {'fields':>6s} {'page MB':>8s} {'bytes/point':>11s} {'write s':>8s} {'browser s':>9s}")
    with tempfile.TemporaryDirectory() as directory:
        for n in args.sizes:
            path, size, seconds = page(n, Path(directory))
            shown = browser_seconds(path)
            browser = "-" if shown is None else f"{shown:.1f}"
            print(f"{n:>10d} {len(FIELDS):>6d} {size / 1e6:>8.1f} {size / n:>11.1f} {seconds:>8.1f} {browser:>9s}")
            path.unlink()
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
