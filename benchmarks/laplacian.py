"""Benchmark of the point-cloud Laplacians: heatcurv's default, the paper's eq 2.9, robust-laplacian.

Prints markdown tables (docs/laplacian.md carries them):

1. spectra against exact values (or a fine cotangent mesh for the torus),
   generalised problem ``S v = lam diag(area) v`` (robust-laplacian: ``L v = lam M v``):
   mean relative error per sphere degree l = 1..5, or over the first eigenvalues;
2. pointwise residuals: ``|L Y - lam Y| / |lam Y|`` for spherical harmonics and
   ``|L x - 2 H n| / |2 H n|`` (the mean-curvature normal, eq 2.10, heatcurv's
   positive convention), including ``heatcurv.estimate(points).mean_curvature_normal``;
3. time and peak memory (each run in a fresh child process) at 10k, 100k, 1M points;
4. eigenpairs at peer speed: build + k smallest eigenpairs on random sphere points (20k: 50, 100k: 100),
   heatcurv's ``PointCloudLaplacian.eigenpairs`` against robust-laplacian with scipy's ``eigsh`` called
   as its documentation shows (shift-invert, scipy's own SuperLU factorisation) and with the
   factorisation heatcurv uses (:func:`heatcurv.operators.point_laplacian.spd_factor`), each in a fresh
   process, errors against the exact ``l (l + 1)``;
5. geodesic distance from one point on random sphere and torus points: heatcurv's
   ``PointCloudLaplacian.geodesic_distance`` and potpourri3d's ``PointCloudHeatSolver`` (both the heat
   method), precomputation and time per source, mean relative error against the great circle (sphere)
   and exact polyhedral geodesics (torus, pygeodesic).

Run:  python benchmarks/laplacian.py  [--quick] [--sizes 10000,100000,1000000] [--eigen 20000:50,100000:100]
      [--geodesic sphere:20000,sphere:100000,torus:20000,torus:40000]
Needs the ``peers`` extra (robust-laplacian, potpourri3d), the ``bench`` extra (psutil, pygeodesic).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import heatcurv
from heatcurv import surfaces
from heatcurv.operators.point_laplacian import spd_factor

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))  # tests/support
from support.mesh_laplacian import torus_reference_eigenvalues  # noqa: E402


def robust(points):
    """robust-laplacian's (L, M) as (stiffness, area)."""
    import robust_laplacian

    L, M = robust_laplacian.point_cloud_laplacian(np.asarray(points, dtype=np.float64))
    return L.tocsr(), np.asarray(M.diagonal()).ravel()


def smallest(stiffness, area, k, plain=False):
    """The k smallest eigenvalues of stiffness v = lam diag(area) v (symmetric, area > 0).

    Shift-invert Lanczos about a small negative shift; the shifted matrix is factorised as heatcurv does
    (``spd_factor``), or with ``plain`` by scipy's ``eigsh`` itself, as a user calls it.
    """
    M = sp.diags(area).tocsc()
    sigma = -1e-3 * float(np.median(stiffness.diagonal() / area))
    if plain:
        return np.sort(spla.eigsh(stiffness.tocsc(), k=k, M=M, sigma=sigma, which="LM", return_eigenvectors=False))
    lu = spd_factor(stiffness - sigma * M)
    op = spla.LinearOperator(stiffness.shape, matvec=lu.solve, dtype=np.float64)
    return np.sort(spla.eigsh(stiffness, k=k, M=M, sigma=sigma, OPinv=op, which="LM", return_eigenvectors=False))


def spectrum(method, points, k):
    """(eigenvalues, seconds, area sum) of one method; eigenvalues None where the method fails."""
    start = time.perf_counter()
    try:
        if method == "default":
            lap = heatcurv.PointCloudLaplacian(points)
            values, total = lap.eigenpairs(k)[0], float(lap.area.sum())
        elif method == "robust":
            S, A = robust(points)
            values, total = smallest(S, A, k), float(A.sum())
        else:  # the paper's L is not symmetric and its areas may be negative: non-symmetric shift-invert
            L, A = heatcurv.laplacian(points, method="paper")
            total = float(A.sum())
            sigma = -1e-3 * float(np.median(L.diagonal()))
            # capped: on clouds where H A = 1 failed the operator is so ill-conditioned that ARPACK may not converge
            values = spla.eigs(
                L.tocsc(), k=k, sigma=sigma, which="LM", return_eigenvectors=False, maxiter=300, tol=1e-8
            )
            values = np.sort(values.real)
    except Exception as exc:  # a failing method is a row of the table, not the end of the run
        return None, f"{type(exc).__name__}", None
    return values, time.perf_counter() - start, total


def clouds(quick):
    n = 4000 if quick else 10000
    sphere = surfaces.Sphere()
    ls = np.concatenate([[d * (d + 1)] * (2 * d + 1) for d in range(1, 6)]).astype(float)
    rng = np.random.default_rng(7)
    dense = sphere.sample(3 * n, "random", seed=5).points
    keep = rng.random(len(dense)) < (0.1 + 0.9 * (dense[:, 2] + 1) / 2) * 0.6  # 10:1 from pole to pole
    square = np.sort([np.pi**2 * (i * i + j * j) / 4 for i in range(8) for j in range(8)])[:31].astype(float)
    torus_n = 8000 if quick else 20000
    torus = surfaces.Torus(0.6, 1.4)
    out = [
        ("sphere random", sphere.sample(n, "random", seed=1).points, ls, "sphere"),
        ("sphere Fibonacci", sphere.sample(n, "fibonacci").points, ls, "sphere"),
        ("sphere jittered", sphere.sample(n, "jittered", seed=1).points, ls, "sphere"),
        ("sphere density 10:1", dense[keep], ls, "sphere"),
        ("torus random (0.6, 1.4)", torus.sample(torus_n, "random", seed=1).points,
         torus_reference_eigenvalues(0.6, 1.4, 31, 128 if quick else 256)[1:], "first 30"),
        ("square random (Neumann)", surfaces.Plane(1.0).sample(n, "random", seed=1).points, square[1:], "first 30"),
        ("square jittered (Neumann)", surfaces.Plane(1.0).sample(n, "jittered", seed=1).points, square[1:],
         "first 30"),
        # a simulated scan can hit one spot twice: a Laplacian needs distinct points
        ("square scan (Neumann)", np.unique(surfaces.Plane(1.0).sample(n, "scan", seed=1).points, axis=0), square[1:],
         "first 30"),
    ]
    surface_area = {"sphere": 4 * np.pi, "torus": torus.area(), "square": 4.0}
    return [(name, pts, exact, kind, surface_area[name.split()[0]]) for name, pts, exact, kind in out]


def spectra_table(quick, only=None):
    print("## Spectra: mean relative eigenvalue error (%)\n")
    print("| cloud | n | method | l=1 | l=2 | l=3 | l=4 | l=5 | all | area sum % | seconds |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, pts, exact, kind, surface_area in clouds(quick):
        if only and not any(word in name for word in only):
            continue
        for method in ("default", "paper", "robust"):
            if method == "paper" and "density" in name:
                # its eigensolve did not finish in 5-7 minutes in two runs (H A = 1 failed: areas near 0)
                print(f"| {name} | {len(pts)} | paper | not run (no result in 7 min) | | | | | | | |", flush=True)
                continue
            values, secs, total = spectrum(method, pts, exact.size + 1)
            if values is None:
                print(f"| {name} | {len(pts)} | {method} | failed ({secs}) | | | | | | | |", flush=True)
                continue
            err = np.abs(values[1:] - exact) / exact * 100
            if kind == "sphere":
                cells = [f"{err[d * d - 1:(d + 1) ** 2 - 1].mean():.2f}" for d in range(1, 6)]
            else:
                cells = ["", "", "", "", ""]
            area = f"{(total / surface_area - 1) * 100:+.2f}"
            print(f"| {name} | {len(pts)} | {method} | " + " | ".join(cells) + f" | {err.mean():.2f} | {area} "
                  f"| {secs:.1f} |", flush=True)
    print()


def residual_table(quick):
    n = 4000 if quick else 10000
    print("## Pointwise residuals (relative 2-norm, %)\n")
    print("| cloud | operator | L z - 2 z | L xy - 6 xy | L x - 2 H n |")
    print("|---|---|---|---|---|")
    cases = [("sphere random", surfaces.Sphere().sample(n, "random", seed=1)),
             ("sphere Fibonacci", surfaces.Sphere().sample(n, "fibonacci")),
             ("torus random", surfaces.Torus(0.6, 1.4).sample(n, "random", seed=1))]
    for name, sample in cases:
        pts = sample.points
        target = 2 * sample.mean[:, None] * sample.normals
        ops = {}
        ops["default"] = heatcurv.laplacian(pts)[0]
        ops["paper"] = heatcurv.laplacian(pts, method="paper")[0]
        S, A = robust(pts)
        ops["robust"] = sp.diags(1 / A) @ S
        for label, L in ops.items():
            cells = []
            if name.startswith("sphere"):
                x, y, z = pts.T
                for f, lam in ((z, 2.0), (x * y, 6.0)):
                    cells.append(f"{np.linalg.norm(L @ f - lam * f) / np.linalg.norm(lam * f) * 100:.1f}")
            else:
                cells += ["", ""]
            K = L @ (pts - pts.mean(axis=0))
            cells.append(f"{np.linalg.norm(K - target) / np.linalg.norm(target) * 100:.1f}")
            print(f"| {name} | {label} | " + " | ".join(cells) + " |", flush=True)
        K = heatcurv.estimate(pts).mean_curvature_normal
        print(f"| {name} | estimate().mean_curvature_normal | | | "
              f"{np.linalg.norm(K - target) / np.linalg.norm(target) * 100:.1f} |", flush=True)
    print()


def one_timing(method, n, eig):
    """Run in a child: build (and eigensolve) one method on n random torus points; print JSON."""
    import psutil

    pts = surfaces.Torus(0.6, 1.4).sample(n, "random", seed=2).points
    base = psutil.Process().memory_info().rss
    start = time.perf_counter()
    if method == "default":
        lap = heatcurv.PointCloudLaplacian(pts)
        if eig:
            _ = lap.stiffness  # the assembled second-order matrix, as heatcurv.laplacian returns it
        build = time.perf_counter() - start
        if eig:
            lap.eigenpairs(10)
    else:
        S, A = robust(pts)
        build = time.perf_counter() - start
        if eig:
            smallest(S, A, 10)
    total = time.perf_counter() - start
    print(json.dumps({"build": build, "total": total, "peak_gb": peak_rss() / 1e9, "base_gb": base / 1e9}))


#: the eigenpair timing's methods: (label, what it runs)
EIGEN_METHODS = {
    "heatcurv": "PointCloudLaplacian(points).eigenpairs(k)",
    "robust-plain": "robust_laplacian.point_cloud_laplacian + scipy eigsh(L, k, M, sigma) (scipy's own factorisation)",
    "robust-spd": "robust_laplacian.point_cloud_laplacian + eigsh with heatcurv's spd_factor",
}


def sphere_eigenvalues(k: int) -> np.ndarray:
    """The k smallest eigenvalues of the unit sphere, l (l + 1) with multiplicity 2 l + 1."""
    degrees = np.repeat(np.arange(int(np.sqrt(k)) + 2), 2 * np.arange(int(np.sqrt(k)) + 2) + 1)
    return (degrees * (degrees + 1.0))[:k]


def one_eigen_timing(method, n, k):
    """Run in a child: build and solve k eigenpairs of one method on n random unit-sphere points; print JSON."""
    pts = surfaces.Sphere().sample(n, "random", seed=0).points
    start = time.perf_counter()
    if method == "heatcurv":
        lap = heatcurv.PointCloudLaplacian(pts)
        build = time.perf_counter() - start
        values = lap.eigenpairs(k)[0]
    else:
        S, A = robust(pts)
        build = time.perf_counter() - start
        values = smallest(S, A, k, plain=method == "robust-plain")
    total = time.perf_counter() - start
    exact = sphere_eigenvalues(k)
    error = float(np.mean(np.abs(values[1:] - exact[1:]) / exact[1:]))
    print(json.dumps({"build": build, "total": total, "error": error, "peak_gb": peak_rss() / 1e9}))


def eigen_table(cases):
    print("## Eigenpairs: build + the k smallest (random unit-sphere points, fresh process each)\n")
    for method, what in EIGEN_METHODS.items():
        print(f"- `{method}`: {what}")
    print("\n| n | k | method | build s | eigenpairs s | total s | mean error % | peak RSS GB |")
    print("|---|---|---|---|---|---|---|---|")
    for n, k in cases:
        for method in EIGEN_METHODS:
            try:
                r = child_result("--one-eigen", method, n, k)
                print(f"| {n} | {k} | {method} | {r['build']:.1f} | {r['total'] - r['build']:.1f} | {r['total']:.1f} | "
                      f"{100 * r['error']:.2f} | {r['peak_gb']:.2f} |", flush=True)
            except Exception as exc:  # report, go on
                print(f"| {n} | {k} | {method} | failed ({type(exc).__name__}) | | | | |", flush=True)
    print()


#: Sources of the geodesic table: the first one's time includes the factorisations.
GEODESIC_SOURCES = (0, 1, 2)
#: The geodesic table's methods: heatcurv's default operator, heatcurv's sparser one (the ``neighbours`` whose
#: distance sets the ball radius: 30 instead of 60), potpourri3d.
GEODESIC_METHODS = {"heatcurv": 60, "heatcurv, neighbours=30": 30, "potpourri3d": None}


def geodesic_cloud(surface: str, n: int) -> np.ndarray:
    """The geodesic table's cloud: ``n`` random points of the unit sphere or of the default torus."""
    shape = surfaces.Sphere() if surface == "sphere" else surfaces.Torus()
    return shape.sample(n, "random", seed=0).points


def exact_geodesics(surface: str, n: int) -> np.ndarray:
    """Exact distances from each of :data:`GEODESIC_SOURCES`, shape (sources, n).

    The sphere's great circle; the torus's exact polyhedral geodesic on a fine triangulation through
    the cloud's points (pygeodesic, tests/support/geodesics.py).
    """
    points = geodesic_cloud(surface, n)
    if surface == "sphere":
        return np.arccos(np.clip(points[list(GEODESIC_SOURCES)] @ points.T, -1.0, 1.0))
    from support.geodesics import exact_distances

    sample = surfaces.Torus().sample(n, "random", seed=0)
    return np.stack([exact_distances(sample, source) for source in GEODESIC_SOURCES])


def one_geodesic_timing(method: str, surface: str, n: int, exact_path: str):
    """Run in a child: one method's geodesic distance from each source; print JSON."""
    points = geodesic_cloud(surface, n)
    start = time.perf_counter()
    if method.startswith("heatcurv"):
        solver = heatcurv.PointCloudLaplacian(points, neighbours=GEODESIC_METHODS[method])
        distance_from = solver.geodesic_distance
    else:
        import potpourri3d

        solver = potpourri3d.PointCloudHeatSolver(points)
        distance_from = solver.compute_distance
    precompute = time.perf_counter() - start
    seconds, distances = [], []
    for source in GEODESIC_SOURCES:
        start = time.perf_counter()
        distances.append(distance_from(source))
        seconds.append(time.perf_counter() - start)
    peak = peak_rss()
    exact = np.load(exact_path)
    errors = []
    for source, distance, truth in zip(GEODESIC_SOURCES, distances, exact):
        others = np.arange(n) != source
        errors.append(float(np.mean(np.abs(distance[others] - truth[others]) / truth[others])))
    print(json.dumps({"precompute": precompute, "first": seconds[0], "each": float(np.mean(seconds[1:])),
                      "error": float(np.mean(errors)), "peak_gb": peak / 1e9}))


def geodesic_table(cases):
    """Geodesic distance from one point, heatcurv against potpourri3d; ``cases`` are (surface, n) pairs."""
    import tempfile

    print("## Geodesic distance from one point (random points, fresh process each)\n")
    print(f"Mean over sources {', '.join(map(str, GEODESIC_SOURCES))} of the mean relative error against the "
          "exact distance (every point but the source): the great circle on the unit sphere, exact polyhedral "
          "geodesics through the cloud's points on the torus (r1 = 1, r2 = 2.3701). `precompute s` is the "
          "solver's construction (heatcurv: the Laplacian, by default over balls of 60 neighbours; "
          "`neighbours=30` is the sparser operator `PointCloudLaplacian(points, neighbours=30)`), "
          "`first source s` includes the factorisations, "
          "`each further source s` is the mean of the others.\n")
    print("| surface | n | method | precompute s | first source s | each further source s | mean error % | "
          "peak RSS GB |")
    print("|---|---|---|---|---|---|---|---|")
    for surface, n in cases:
        with tempfile.TemporaryDirectory() as folder:
            exact_path = os.path.join(folder, "exact.npy")
            np.save(exact_path, exact_geodesics(surface, n))
            for method in GEODESIC_METHODS:
                try:
                    r = child_result("--one-geodesic", method, surface, n, exact_path)
                    print(f"| {surface} | {n} | {method} | {r['precompute']:.2f} | {r['first']:.2f} | "
                          f"{r['each']:.3f} | {100 * r['error']:.2f} | {r['peak_gb']:.2f} |", flush=True)
                except Exception as exc:  # report, go on
                    print(f"| {surface} | {n} | {method} | failed ({type(exc).__name__}) | | | | |", flush=True)
    print()


def child_result(*args, timeout: float = 1800) -> dict:
    """Run this script with ``args`` in a fresh process and return the JSON of its last line (errors raise)."""
    cmd = [sys.executable, __file__, *map(str, args)]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def peak_rss() -> float:
    """Peak resident set size of this process, bytes.

    Linux's ``ru_maxrss`` survives fork and exec: a child started by a parent holding 1.3 GB reported
    1.3 GB for a 10k cloud. ``VmHWM`` belongs to the process's own address space.
    """
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def timing_table(sizes):
    print("## Time and peak memory (random torus points, fresh process each)\n")
    print("| n | method | build s | with 10 eigenpairs s | peak RSS GB |")
    print("|---|---|---|---|---|")
    for n in sizes:
        eig = n <= 10_000  # a 100k eigensolve takes many minutes with SuperLU on this 2-core box
        for method in ("default", "robust"):
            try:
                r = child_result("--one", method, n, "1" if eig else "0", timeout=900)
                total = f"{r['total']:.1f}" if eig else "not run"
                print(f"| {n} | {method} | {r['build']:.1f} | {total} | {r['peak_gb']:.2f} |", flush=True)
            except Exception as exc:  # report, go on
                print(f"| {n} | {method} | failed ({type(exc).__name__}) | | |", flush=True)
    print()


def pictures(folder):
    """Heat diffused from one point, an eigenfunction and the geodesic distance on the packaged bunny scan.

    Writes docs/laplacian_bunny_heat.png, _eigen.png and _geodesic.png into ``folder``.
    """
    from heatcurv.data import load_bunny
    from heatcurv.render import FieldStyle, render_field

    pts = np.asarray(load_bunny().points, dtype=np.float64)
    pts = np.unique(pts, axis=0)
    lap = heatcurv.PointCloudLaplacian(pts)
    source = int(np.argmax(pts[:, 1]))  # the top of an ear (y is up)
    spike = np.zeros(len(pts))
    spike[source] = 1.0 / lap.area[source]
    heat = lap.heat(spike, time=4.0, steps=8)
    normals = heatcurv.estimate(pts).normals  # oriented: they shade the points and hide the far side
    # the heat of a unit spike is a density: 1/length^2, its total over the surface 1
    heat_style = FieldStyle("log10 of the heat", "heat in 1/{L}²", "sequential")
    render_field(pts, np.log10(np.maximum(heat, 1e-12)), f"{folder}/laplacian_bunny_heat.png", field=heat_style,
                 views=2, size=(1600, 800), normals=normals,
                 title=f"heat diffused from the ear's tip, time 4 (bunny scan, {len(pts)} points)")
    values, vectors = lap.eigenpairs(12)
    # eigenfunctions of unit norm in the area inner product (sum of area * v^2 = 1): 1/length
    eigen_style = FieldStyle("eigenfunction", "1/{L}", "signed")
    render_field(pts, vectors[:, 11], f"{folder}/laplacian_bunny_eigen.png", field=eigen_style, views=2,
                 size=(1600, 800), normals=normals,
                 title=f"12th Laplace-Beltrami eigenfunction, lambda = {values[11]:.3f} (bunny scan)")
    distance = lap.geodesic_distance(source)
    render_field(pts, distance, f"{folder}/laplacian_bunny_geodesic.png", field="geodesic_distance", views=2,
                 size=(1600, 800), normals=normals, percentiles=(0.0, 100.0),
                 title=f"geodesic distance from the ear's tip, heat method (bunny scan, {len(pts)} points)")
    print(f"pictures: bunny {len(pts)} points, h = {lap.h:.3f}, first eigenvalues {np.round(values[:6], 4)}, "
          f"geodesic distance up to {distance.max():.2f}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller clouds")
    parser.add_argument("--sizes", default="10000,100000,1000000")
    parser.add_argument("--only", default="spectra,residuals,timing,eigen,geodesic")
    parser.add_argument("--eigen", default="20000:50,100000:100", help="n:k cases of the eigenpair timing")
    parser.add_argument("--one-eigen", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--geodesic", default="sphere:20000,sphere:100000,torus:20000,torus:40000",
                        help="surface:n cases of the geodesic table")
    parser.add_argument("--one-geodesic", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--clouds", default="", help="comma-separated words: only the spectra of clouds named so")
    parser.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--pictures", metavar="FOLDER", help="only draw the bunny pictures into FOLDER")
    args = parser.parse_args()
    if args.pictures:
        pictures(args.pictures)
        return
    if args.one:
        one_timing(args.one[0], int(args.one[1]), args.one[2] == "1")
        return
    if args.one_eigen:
        one_eigen_timing(args.one_eigen[0], int(args.one_eigen[1]), int(args.one_eigen[2]))
        return
    if args.one_geodesic:
        method, surface, n, exact_path = args.one_geodesic
        one_geodesic_timing(method, surface, int(n), exact_path)
        return
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from machine import commit, cpu_model, memory_text  # benchmarks/machine.py

    print(f"Machine: {cpu_model()}, {os.cpu_count()} cores{memory_text()}; load average "
          f"{os.getloadavg()[0]:.1f} at the start; heatcurv {heatcurv.__version__} at commit {commit()}\n")
    start = time.perf_counter()
    if "spectra" in args.only:
        spectra_table(args.quick, [w for w in args.clouds.split(",") if w])
    if "residuals" in args.only:
        residual_table(args.quick)
    if "timing" in args.only:
        timing_table([int(s) for s in args.sizes.split(",")])
    if "eigen" in args.only:
        eigen_table([tuple(int(x) for x in case.split(":")) for case in args.eigen.split(",") if case])
    if "geodesic" in args.only:
        geodesic_table([(case.split(":")[0], int(case.split(":")[1])) for case in args.geodesic.split(",") if case])
    print(f"Whole run: {time.perf_counter() - start:.0f} s, load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
