"""Size of the page ``heatcurv view`` writes, the time to write it, and the time a browser takes to draw it.

The cloud is a random torus with the fields ``heatcurv compute`` writes by
default (15: normals, curvatures, directions, area, reliable) and the
normals for shading, as ``heatcurv view result.ply`` embeds them. The
browser time is headless Chromium (software WebGL, SwiftShader) from start
to the page's first picture (``--dump-dom`` returns once the page has run
its script), where Chromium is installed.

    python benchmarks/view_page.py --sizes 100000 1000000
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
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


def browser_seconds(path: Path) -> float | None:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        return None
    with tempfile.TemporaryDirectory() as profile:
        tic = time.perf_counter()
        out = subprocess.run(
            [browser, "--headless", "--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
             f"--user-data-dir={profile}", "--window-size=800,600", "--dump-dom", path.resolve().as_uri()],
            capture_output=True, text=True, timeout=600,
        )
        seconds = time.perf_counter() - tic
    return seconds if 'data-status="drawn' in out.stdout else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    args = parser.parse_args()
    print(f"{'points':>10s} {'fields':>6s} {'page MB':>8s} {'bytes/point':>11s} {'write s':>8s} {'browser s':>9s}")
    with tempfile.TemporaryDirectory() as directory:
        for n in args.sizes:
            path, size, seconds = page(n, Path(directory))
            shown = browser_seconds(path)
            browser = "-" if shown is None else f"{shown:.1f}"
            print(f"{n:>10d} {len(FIELDS):>6d} {size / 1e6:>8.1f} {size / n:>11.1f} {seconds:>8.1f} {browser:>9s}")
            path.unlink()


if __name__ == "__main__":
    main()
