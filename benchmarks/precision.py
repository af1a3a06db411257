"""Coordinate precision: float32 clouds against the same points in float64, and what ``reliable`` says of them.

The clouds are those of the float32 property of ``tests/fuzz/test_fuzz_properties.py``: sphere,
torus, paraboloid and saddle, random and Fibonacci samples, noise 0 and 0.003, here of 574 and 2000
points, moved 10^0 ... 10^4 of their size from the origin and stored as float32. Each is estimated

* from the float64 points before rounding (the values the rounding is judged against),
* from the float32 points with ``coordinate_precision=0`` (``reliable`` without the precision flag),
* from the float32 points (the precision flag of :mod:`heatcurv.flags.reliability`).

A point is **off** when its ``k1``, ``k2`` or mean curvature moved by more than
``TUNING.precision_tolerance`` of its curvature scale (the larger of ``|k1|``,
``|k2|`` and ``TUNING.flat_curvature`` over its fit's radius). The table counts the off points reliable
without and with the flag, those of them that moved by more than :data:`COVERAGE` standard errors of the move
too (``k1_se``, ``k2_se``, ``mean_se`` of the float32 and float64 estimates combined: the tolerance
docs/robustness.md states), and
the points the flag took out that were not off ("needlessly").
"same fit" splits the clouds whose float32 estimate kept the float64 fit's form and anchor count
from those where the rounding changed them: the kernel choice saw the rounding as noise, or a
sampling key (:mod:`heatcurv.geometry.sampling`) crossed its threshold and the anchors changed.

    python benchmarks/precision.py            # 160 clouds, about 10 minutes on 2 cores
    python benchmarks/precision.py --quick    # the noise-free 2000-point clouds, about 3 minutes
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import heatcurv
from heatcurv import surfaces
from heatcurv.tuning import TUNING

#: Standard errors a reliable value may move by under the rounding, beyond the share of its scale.
COVERAGE = 5.0

SURFACES = {"sphere": lambda: surfaces.Sphere(radius=1.0), "torus": lambda: surfaces.Torus(),
            "paraboloid": lambda: surfaces.Paraboloid(), "saddle": lambda: surfaces.Saddle()}


def measure(kind: str, sampler: str, noise: float, n: int, seed: int, exponent: int) -> dict:
    points = SURFACES[kind]().sample(n, sampler, noise=noise, seed=seed).points
    moved = points + float(np.linalg.norm(np.ptp(points, axis=0))) * 10.0**exponent
    single = moved.astype(np.float32)
    exact, rounded = heatcurv.estimate(moved), heatcurv.estimate(single)
    unflagged = heatcurv.estimate(single, coordinate_precision=0).reliable
    scale = np.maximum(np.maximum(np.abs(exact.k1), np.abs(exact.k2)), TUNING.flat_curvature / exact.fit_radius)
    moved_by = np.maximum.reduce([np.abs(rounded.k1 - exact.k1), np.abs(rounded.k2 - exact.k2),
                                  np.abs(rounded.mean - exact.mean)])
    off = moved_by > TUNING.precision_tolerance * scale
    beyond = np.maximum.reduce([np.abs(getattr(rounded, name) - getattr(exact, name))
                                / np.hypot(getattr(rounded, f"{name}_se"), getattr(exact, f"{name}_se"))
                                for name in ("mean", "k1", "k2")]) > COVERAGE
    a, b = exact.info["scale"], rounded.info["scale"]
    return {"points": n, "off": int(off.sum()), "before": int((off & unflagged).sum()),
            "after": int((off & rounded.reliable).sum()), "beyond": int((off & beyond & rounded.reliable).sum()),
            "needless": int((unflagged & ~rounded.reliable & ~off).sum()),
            "same": a.fit == b.fit and a.anchors == b.anchors}


def table(rows: list, groups: dict) -> str:
    lines = ["| clouds | n | points | off | off & reliable, no flag | off & reliable, flag | "
             f"of which beyond {COVERAGE:g} SE | flagged needlessly |",
             "|---|---|---|---|---|---|---|---|"]
    for label, keep in groups.items():
        sel = [r for r in rows if keep(r)]
        if sel:
            total = {key: sum(r[key] for r in sel) for key in ("points", "off", "before", "after", "beyond",
                                                               "needless")}
            lines.append(f"| {label} | {len(sel)} | {total['points']} | {total['off']} | {total['before']} | "
                         f"{total['after']} | {total['beyond']} | {total['needless']} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the noise-free 2000-point clouds only")
    parser.add_argument("--seed", type=int, default=1, help="draws the clouds' sampling seeds")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(args.seed)
    rows = []
    for kind in SURFACES:
        for sampler in ("random", "fibonacci"):
            for noise in (0.0,) if args.quick else (0.0, 0.003):
                for n in (2000,) if args.quick else (574, 2000):
                    seed = int(rng.integers(0, 2**16))
                    for exponent in range(5):
                        row = measure(kind, sampler, noise, n, seed, exponent)
                        rows.append({"noise": noise, "exponent": exponent, **row})
                        print(f"{kind} {sampler} noise {noise} n {n} seed {seed} 10^{exponent}: {row}", flush=True)
    groups = {f"noise {noise}, {n} points": (lambda r, noise=noise, n=n: r["noise"] == noise and r["points"] == n)
              for noise in (0.0, 0.003) for n in (574, 2000)}
    groups.update({f"noise-free, 10^{e} sizes away": (lambda r, e=e: r["noise"] == 0.0 and r["exponent"] == e)
                   for e in range(5)})
    for noise, label in ((0.0, "noise-free"), (0.003, "noise 0.003")):
        groups[f"{label}, same fit"] = lambda r, noise=noise: r["noise"] == noise and r["same"]
        groups[f"{label}, the rounding changed the fit"] = lambda r, noise=noise: r["noise"] == noise and not r["same"]
    groups["noise-free 2000 points, same fit"] = lambda r: r["noise"] == 0.0 and r["points"] == 2000 and r["same"]
    print(table(rows, groups))


if __name__ == "__main__":
    main()
