"""Rounded coordinates: the time and accuracy of the default on a torus stored in float32 or as text.

A cloud whose only noise is the rounding of its coordinates (float32 files, text exports with a few
decimals, LAS/LAZ scales) should cost about what the float64 cloud costs, at its accuracy. This runs
the default estimator on one random torus (exact values known) stored as float64, as float32 and
rounded to 6, 5, 4 and 3 decimals (the torus is 6.7 units across: 3 decimals are a LAZ file's
millimetres on a 6.7 m object), in one process after a warm-up, and prints per cloud the measured noise
(``relative_noise``), the fit plan, the time and its ratio to the float64 cloud's, and the median
relative errors of the mean curvature and ``k1`` over the reliable points.

    python benchmarks/rounding.py                 # a million points, about 3 minutes on 2 cores
    python benchmarks/rounding.py --points 200000
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

import heatcurv
from heatcurv.surfaces import Torus

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import commit, cpu_model, memory_text  # noqa: E402  (benchmarks/machine.py)


def clouds(points: np.ndarray) -> dict:
    """The same points stored as each kind of rounded coordinates, as float64 arrays."""
    stored = {"float64": points, "float32": points.astype(np.float32).astype(np.float64)}
    stored.update({f"{d} decimals": np.round(points, d) for d in (6, 5, 4, 3)})
    return stored


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    surface = Torus().sample(args.points, "random", seed=args.seed)
    heatcurv.estimate(np.round(surface.points[:20_000], 3))  # compile (or load) the kernels of every path
    scale_mean, scale_k1 = np.median(np.abs(surface.mean)), np.median(np.abs(surface.k1))
    rows, base = [], None
    for name, points in clouds(surface.points).items():
        start = time.perf_counter()
        res = heatcurv.estimate(points)
        seconds = time.perf_counter() - start
        base = seconds if base is None else base
        ok = res.reliable
        mean_error = np.median(np.abs(res.mean - surface.mean)[ok]) / scale_mean
        k1_error = np.median(np.abs(res.k1 - surface.k1)[ok]) / scale_k1
        rows.append(f"| {name} | {res.info['scale'].relative_noise:.2g} | {res.info['plan'].label} | {seconds:.1f} | "
                    f"{seconds / base:.2f} | {100 * mean_error:.2g} | {100 * k1_error:.2g} | {100 * ok.mean():.2f} |")
        print(rows[-1], flush=True)
    print()
    import numba

    print(f"Machine: {cpu_model()}, {os.cpu_count()} cores{memory_text()}; Python {platform.python_version()}, "
          f"numpy {np.__version__}, numba {numba.__version__}; heatcurv at commit {commit()}")
    print()
    print(f"Random torus (tube radius 1 around a circle of radius 2.37), {args.points:,} points, default options; "
          "errors: median over the reliable points, relative to the median exact value")
    print()
    print("| coordinates | relative noise | plan | time s | x float64 | mean error % | k1 error % | reliable % |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
