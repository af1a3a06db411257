"""Issue 13, bullet 3: a cloud forced into tiles against the same cloud in memory, field by field.

For each cloud the script runs :func:`heatcurv.estimate` in memory, then
:func:`heatcurv.compute_file` with a tile size that forces several tiles
(float64 output, so the comparison is not limited by float32), and prints
per field the share of points within ``1e-6`` relative of the in-memory value
(the target: >= 99.99 % on every field), the worst relative error, and how
the tiled run was planned (tiles, halo, kernel chosen)::

    python benchmarks/tiled_identity.py                  # 1M noisy torus (outward), terrain and LiDAR tile (up)
    python benchmarks/tiled_identity.py --n 200000       # smaller, quicker
    python benchmarks/tiled_identity.py --only lidar --tiles 8   # the LiDAR tile alone, in about 8 tiles

The LiDAR tile (:func:`heatcurv.surfaces.lidar_tile`: ground, three
buildings, five tree crowns, 60 m x 60 m) is the case a global orientation
got wrong in tiles: walls and crowns took their side along the spanning tree
of the whole cloud (99.95 % of 40 000 points in 8 tiles); ``"up"`` is now
decided within each point's reach (:func:`heatcurv.orient.orientation.local_sides`).

Relative error as in :mod:`support.tiles` (directions up to sign;
masks exactly).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import heatcurv
from machine import commit, cpu_model, memory_text, table  # noqa: E402  (benchmarks/machine.py)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # tests/support: the tiled comparison
from support.tiles import tiled_agreement  # noqa: E402


def torus(n: int, noise: float, seed: int = 1) -> np.ndarray:
    """A torus (r 0.6, R 1.4) with Gaussian noise of ``noise`` x its diagonal, in UTM-like coordinates."""
    s = heatcurv.surfaces.Torus(0.6, 1.4).sample(n, "random", seed=seed)
    rng = np.random.default_rng(seed)
    diagonal = np.linalg.norm(np.ptp(s.points, axis=0))
    return s.points + rng.normal(scale=noise * diagonal, size=s.points.shape) + [5.0e5, 4.2e6, 120.0]


def terrain(n: int, seed: int = 2) -> np.ndarray:
    """Rolling ground 1 km x 1 km, 2 cm of noise: an aerial LiDAR tile's shape (orient up)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, 1000.0, size=(n, 2))
    z = 8 * np.sin(xy[:, 0] / 90.0) * np.cos(xy[:, 1] / 130.0) + 0.004 * xy[:, 0] + rng.normal(0, 0.02, n)
    return np.column_stack([xy + [6.1e5, 5.3e6], z + 300.0])


def lidar(n: int, seed: int = 0) -> np.ndarray:
    """The simulated aerial LiDAR tile with buildings and trees (orient up), ``n`` points."""
    return heatcurv.surfaces.lidar_tile(n, seed=seed).points


CLOUDS = {
    "torus": ("torus 0.12 % noise", lambda n: torus(n, 0.0012), {}),
    "terrain": ("terrain", terrain, {"orient": "up"}),
    "lidar": ("lidar tile", lidar, {"orient": "up"}),
}


def run(name: str, points: np.ndarray, tile_size: int, options: dict, workdir: Path) -> list:
    src, dst = workdir / f"{name}.npy", workdir / f"{name}_out.ply"
    np.save(src, points)
    tic = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        memory = heatcurv.estimate(points, **options)
    t_memory = time.perf_counter() - tic
    tic = time.perf_counter()
    report = heatcurv.compute_file(src, dst, tile_size=tile_size, dtype="float64", progress=False,
                                   fields=("nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z",
                                           "d2x", "d2y", "d2z", "area", "reliable", "border", "outlier",
                                           "fit_radius"), **options)
    t_tiled = time.perf_counter() - tic
    agreement = tiled_agreement(dst, memory, rtol=1e-6)
    rows = []
    for field, a in agreement.items():
        rows.append((name, len(points), report.tiles, f"{report.halo:.4g}", field, f"{100 * a['share']:.4f}",
                     a["bad"], f"{a['worst']:.2g}", f"{t_memory:.1f}", f"{t_tiled:.1f}"))
    print(f"{name}: kernel {report.context.get('kernel')}, widths {report.context.get('widths')}, "
          f"orientation {report.orientation}, halo widened {report.widened} times; phases (s) "
          + ", ".join(f"{k} {v:.1f}" for k, v in report.timings.items()), flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=1_000_000, help="points per cloud")
    parser.add_argument("--tiles", type=int, default=6, help="about this many tiles per cloud")
    parser.add_argument("--only", action="append", choices=sorted(CLOUDS), help="run only this cloud (repeatable)")
    parser.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    args = parser.parse_args()
    tile_size = args.n // args.tiles
    header = ("cloud", "n", "tiles", "halo", "field", "within 1e-6 %", "points off", "worst", "memory s", "tiled s")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for key in args.only or list(CLOUDS):
            name, make, options = CLOUDS[key]
            rows += run(name, make(args.n), tile_size, options, Path(tmp))
    machine = (f"{cpu_model()}, {os.cpu_count()} cores{memory_text()}, 1-minute load {os.getloadavg()[0]:.1f}; "
               f"heatcurv {heatcurv.__version__} at commit {commit()}")
    print()
    print(table(f"Tiled against in-memory ({machine})", list(header), [[str(x) for x in r] for r in rows],
                args.markdown))


if __name__ == "__main__":
    main()
