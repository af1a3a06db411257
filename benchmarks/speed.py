"""Speed and memory of heatcurv's default pipeline, with peer tools on the same clouds.

For each size n (default 100 000, 1 000 000 and 5 000 000) a random torus
(:class:`heatcurv.surfaces.Torus`, area-uniform points, input in random
order) is saved to a temporary ``.npy`` file, and every measurement runs in
a fresh subprocess, so that its wall time and its peak resident memory
(``VmHWM``, see ``benchmarks/peers.py``) are its own:

``knn40``       the reference: SciPy ``cKDTree`` build plus a ``k = 40``
                self-query with ``workers=-1`` (every curvature tool pays at
                least this);
``heatcurv``    ``heatcurv.estimate(points)`` with default options: oriented
                normals, areas, mean, Gaussian and principal curvatures and
                directions, border and reliability flags; the stage times
                come from ``res.info["timings"]`` (see ``COLUMNS``: the
                per-block stages of the chord fit are summed as ``fit``);
``heatcurv-noisy``  the same on the cloud with Gaussian noise of 0.12 % of
                the bounding-box diagonal (the kernel then widens to hundreds
                of neighbours; only at the sizes given by ``--noisy-sizes``);
``laz (mm rounding)``  what a user with a LAS/LAZ file runs, at the sizes of
                ``--laz-sizes``: the clean torus of the same size (the same
                points as the clean row) written by laspy to a ``.laz`` file
                (point format 6, LAS 1.4, scales 0.001 in x, y and z, offsets
                0: coordinates rounded to the millimetre if the unit is the
                metre, 1e-4 of the torus's diagonal of 9.7, the very-low-noise
                band of issue 12), then, in the child,
                :func:`heatcurv.io.read_points` (the command line's reader)
                plus ``heatcurv.estimate(cloud.points)`` with default options.
                The read is timed on its own (the ``read`` column) and counted
                in the row's total, ratio and us/point; laspy and lazrs are
                imported before the clock starts, as numba is compiled; the
                write is not timed. The command line would orient a LAS/LAZ
                cloud's normals up (+z); the row keeps the default options of
                the other rows, which on a closed torus are the right ones;
peers           where the optional extras are installed
                (``pip install "heatcurv[peers]"``): Open3D normals, PyMeshLab
                APSS curvature, robust-laplacian, and the project's k = 40
                quadric baseline (``benchmarks/peers.py``), at the sizes of
                ``--peer-sizes``.

heatcurv's children first run the pipeline on three small clouds (clean, noisy,
rounded: :func:`warmup_clouds`), so numba's compilation of every path (or
loading its cache) is not counted; the time of that warm-up is reported as
``warmup``. Everything else, including validation, the
duplicate merge and the map back to input order, is counted.

Run ``python benchmarks/speed.py`` (about 15 minutes on a 2-core machine with
the peers, plus the 1M-point LAZ row) or ``--sizes 100000 --peer-sizes 100000
--noisy-sizes 100000 --laz-sizes 100000`` for a quick look (``--noisy-sizes``,
``--peer-sizes`` or ``--laz-sizes`` with no value skips those runs); ``--out
FILE`` writes the tables as Markdown with the machine they came from (docs/speed.md
quotes them; writing over it would lose the page's text).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import peers  # noqa: E402  (benchmarks/peers.py)
from machine import commit, cpu_model, memory_text  # noqa: E402  (benchmarks/machine.py)

#: Table column -> the default estimator's stages (``res.info["timings"]``) it sums.
#: ``fit`` is the chord fit's per-block work; before the stages were named one
#: by one, ``kernel_choice`` + ``fit`` + ``border`` were reported as
#: ``principal`` and ``mean_curvature_normal`` as ``mean``.
COLUMNS = {
    "validate": ("validate",),
    "neighbours": ("neighbours",),
    "spacing": ("spacing",),
    "areas": ("areas",),
    "kernel_check": ("kernel_check",),
    "outliers": ("outliers",),
    "normals": ("normals",),
    "orientation": ("orientation",),
    "mean_curvature_normal": ("mean_curvature_normal",),
    "kernel_choice": ("kernel_choice",),
    "fit": ("fit_neighbourhood", "fit_weights", "normal_refinement", "curvature_fit", "area_correction"),
    "border": ("border",),
    "anchor_fit": ("anchor_fit",),
    "carry": ("carry",),
    "standard_errors": ("standard_errors",),
}
STAGES = tuple(s for stages in COLUMNS.values() for s in stages)


def column_times(timings: dict) -> dict:
    """Seconds per table column: the sum of its stages (None if none of them ran)."""
    out = {}
    for column, stages in COLUMNS.items():
        present = [timings[s] for s in stages if s in timings]
        out[column] = sum(present) if present else None
    return out


def _peak_rss_gb() -> float:
    """Peak resident memory of this process (VmHWM), GB: the peers' own measure."""
    return peers.peak_rss_bytes() / 1e9


def child(path: str) -> None:
    """Run the default pipeline on the points in ``path`` and print one JSON line.

    An ``.npy`` file is loaded before anything is timed; a ``.laz`` file is
    read with :func:`heatcurv.io.read_points` after the warm-up, timed as
    ``read_seconds`` (``None`` for ``.npy``).
    """
    import heatcurv

    laz = Path(path).suffix.lower() == ".laz"
    if laz:
        import laspy  # noqa: F401  (imported before the clock, as numba is compiled before it)
        import lazrs  # noqa: F401

        import heatcurv.io
    else:
        points = np.load(path)
    tic = time.perf_counter()
    for cloud in warmup_clouds():
        heatcurv.estimate(cloud)
    warmup = time.perf_counter() - tic
    read_seconds = None
    if laz:
        tic = time.perf_counter()
        points = heatcurv.io.read_points(path).points
        read_seconds = time.perf_counter() - tic
    rss_before = _peak_rss_gb()
    tic = time.perf_counter()
    res = heatcurv.estimate(points)
    seconds = time.perf_counter() - tic

    print(
        json.dumps(
            {
                "seconds": seconds,
                "read_seconds": read_seconds,
                "n_read": int(points.shape[0]),
                "warmup": warmup,
                "peak_rss_gb": _peak_rss_gb(),
                "rss_before_gb": rss_before,
                "timings": res.info["timings"],
                "scale": res.info["scale"].fit,
                "backend": "numba",
                "reliable": float(np.mean(res.reliable)),
            }
        )
    )


def run_heatcurv(path: Path, timeout: float) -> dict:
    """Run :func:`child` in a fresh process; the parsed JSON, or a status."""
    try:
        out = subprocess.run(
            [sys.executable, __file__, "--child", str(path)],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return {"status": f"timeout after {timeout:.0f} s"}
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode != 0 or not lines:
        tail = (out.stderr.strip().splitlines() or ["no output"])[-1]
        return {"status": f"failed: {tail}"}
    result = json.loads(lines[-1])
    result["status"] = "ok"
    return result


def warmup_clouds() -> list[np.ndarray]:
    """Small clouds that compile (or load from the cache) every path's numba kernels before the clock.

    A clean torus (the chord fit), one with 0.12 % noise (the anchors' fit and carry: 2000 points take
    a 120-neighbour kernel at 242 anchors) and one rounded to 1e-4 of its diagonal (the very-low-noise
    refit and regression: 5000 points take 240 neighbours at 512 anchors; 2000 fit every point).
    Without the last two, a fresh checkout's first noisy run counted the carry's compilation:
    31.6 s of a 52.8 s run at 1M points, against 2.9 s warm.
    """
    import heatcurv

    clean = heatcurv.surfaces.Torus().sample(2000, "random", seed=1).points
    return [clean, torus_cloud(2000, noise=0.0012, seed=3), np.round(torus_cloud(5000, seed=3) / LAZ_SCALE) * LAZ_SCALE]


def torus_cloud(n: int, noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """Random torus points in random order; Gaussian noise as a fraction of the diagonal."""
    import heatcurv

    pts = heatcurv.surfaces.Torus().sample(n, "random", seed=seed).points
    if noise:
        diag = np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))
        pts = pts + np.random.default_rng(seed + 1).normal(scale=noise * diag, size=pts.shape)
    return pts


#: LAS scale of the LAZ rows: a millimetre if the unit is the metre, 1e-4 of the torus's diagonal.
LAZ_SCALE = 0.001


def write_laz(path: Path, points: np.ndarray, scale: float = LAZ_SCALE) -> float:
    """Write ``points`` to a LAZ file (point format 6, LAS 1.4, offsets 0), rounded to ``scale``.

    Returns the largest rounding error of a coordinate (at most ``scale / 2``).
    """
    import laspy

    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = np.full(3, scale)
    header.offsets = np.zeros(3)
    las = laspy.LasData(header)
    ints = np.round(points / scale).astype(np.int32)
    las.X, las.Y, las.Z = ints[:, 0], ints[:, 1], ints[:, 2]
    las.write(str(path), laz_backend=laspy.LazBackend.Lazrs)
    return float(np.abs(ints * scale - points).max())


def machine() -> str:
    """One line naming this machine and the library versions."""
    cpu = cpu_model()
    mem = memory_text()
    import numba
    import scipy

    versions = (
        f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"numba {numba.__version__}"
    )
    return (f"{cpu}, {os.cpu_count()} cores{mem}; {platform.system()} {platform.release()}; {versions}; "
            f"heatcurv at commit {commit()}")


def fmt(x, digits=2):
    return "-" if x is None else f"{x:.{digits}f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000, 5_000_000])
    ap.add_argument("--noisy-sizes", type=int, nargs="*", default=[1_000_000], help="sizes of the 0.12 %% noise run")
    ap.add_argument("--peer-sizes", type=int, nargs="*", default=[100_000, 1_000_000], help="sizes the peers run at")
    ap.add_argument(
        "--laz-sizes", type=int, nargs="*", default=[1_000_000],
        help="sizes of the LAZ run (clean torus rounded to 0.001, read + estimate)",
    )
    ap.add_argument("--peer-timeout", type=float, default=300.0, help="seconds before a peer is stopped")
    ap.add_argument("--timeout", type=float, default=3600.0, help="seconds before a heatcurv run is stopped")
    ap.add_argument("--out", help="write the tables as Markdown to this file")
    args = ap.parse_args(argv)
    if args.child:
        child(args.child)
        return 0

    main_rows, peer_rows = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sorted(set(args.sizes) | set(args.noisy_sizes) | set(args.peer_sizes) | set(args.laz_sizes)):
            path = Path(tmp) / f"torus_{n}.npy"
            clean = torus_cloud(n)
            np.save(path, clean)
            ref = peers.run_peer("knn40", str(path), timeout=args.peer_timeout)
            knn = ref.get("seconds") if ref.get("status") == "ok" else None
            print(f"n={n}: knn40 {fmt(knn)} s", flush=True)
            runs = []
            if n in args.sizes:
                runs.append(("clean", path))
            if n in args.noisy_sizes:
                noisy = Path(tmp) / f"torus_{n}_noisy.npy"
                np.save(noisy, torus_cloud(n, noise=0.0012))
                runs.append(("noise 0.12 %", noisy))
            if n in args.laz_sizes:
                laz = Path(tmp) / f"torus_{n}.laz"
                err = write_laz(laz, clean)
                print(f"  wrote {laz.name}: {laz.stat().st_size / 1e6:.1f} MB, rounding up to {err:.2g}", flush=True)
                runs.append(("laz (mm rounding)", laz))
            del clean
            for label, p in runs:
                r = run_heatcurv(p, args.timeout)
                if r.get("status") == "ok" and r["n_read"] != n:
                    r = {"status": f"failed: read {r['n_read']} points, wrote {n}"}
                main_rows.append((n, label, knn, r))
                read = r.get("read_seconds")
                print(
                    f"  heatcurv {label}: {r.get('status')} {fmt(r.get('seconds'))} s"
                    + (f" + read {fmt(read)} s" if read is not None else "")
                    + f", {fmt(r.get('peak_rss_gb'))} GB",
                    flush=True,
                )
            if n in args.peer_sizes:
                for name in peers.PEERS:
                    if name == "knn40":
                        peer_rows.append((n, ref, knn))
                        continue
                    r = peers.run_peer(name, str(path), timeout=args.peer_timeout)
                    peer_rows.append((n, r, knn))
                    print(f"  {name}: {r.get('status')} {fmt(r.get('seconds'))} s", flush=True)

    lines = [f"Machine: {machine()}", ""]
    lines += [
        "heatcurv, default options, random torus (times in seconds; ratio = total / knn40 in the same run; "
        "the LAZ row's total includes its read)",
        "",
        "| n | cloud | read | "
        + " | ".join(COLUMNS)
        + " | total | us/point | knn40 | ratio | peak RSS GB | kernel | backend |",
        "|" + "---|" * (len(COLUMNS) + 10),
    ]
    unknown = set()
    for n, label, knn, r in main_rows:
        if r.get("status") != "ok":
            dashes = " | ".join("-" for _ in COLUMNS)
            lines.append(f"| {n:,} | {label} | - | {dashes} | {r['status']} | | {fmt(knn)} | | | | |")
            continue
        t = r["timings"]
        unknown |= set(t) - set(STAGES)
        stages = " | ".join(fmt(v) for v in column_times(t).values())
        read = r.get("read_seconds")
        total = r["seconds"] + (read or 0.0)
        ratio = total / knn if knn else None
        lines.append(
            f"| {n:,} | {label} | {fmt(read)} | {stages} | {fmt(total)} | {fmt(1e6 * total / n, 1)} | {fmt(knn)} | "
            f"{fmt(ratio)} | {fmt(r['peak_rss_gb'])} | {r['scale']} | {r['backend']} |"
        )
    lines += ["", "fit = " + " + ".join(COLUMNS["fit"]) + " (the chord fit's per-block stages)"]
    if any(label.startswith("laz") for _, label, _, _ in main_rows):
        lines.append(
            f"laz (mm rounding) = the clean torus written by laspy to LAZ with scales {LAZ_SCALE} "
            "(1e-4 of its diagonal), read with heatcurv.io.read_points (the read column) and estimated"
        )
    if unknown:
        lines.append("stages in no column (counted in total only): " + ", ".join(sorted(unknown)))
    if peer_rows:
        lines += ["", "Peers on the same clean clouds (each in its own process; ratio = time / knn40)", ""]
        lines += [
            "| n | tool | status | seconds | ratio | peak RSS GB | what it computes |",
            "|---|---|---|---|---|---|---|",
        ]
        for n, r, knn in peer_rows:
            sec = r.get("seconds")
            ratio = sec / knn if (sec is not None and knn) else None
            lines.append(
                f"| {n:,} | {r.get('name')} | {r.get('status')} | {fmt(sec)} | {fmt(ratio)} | "
                f"{fmt(r.get('peak_rss_gb'))} | {r.get('note', '')} |"
            )
    text = "\n".join(lines)
    print()
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
