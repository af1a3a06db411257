"""Tiled runs (issue 13): time and peak memory against the in-memory estimate, workers, Dask's overhead.

Generates LiDAR-like terrain (the smooth ground of :func:`heatcurv.surfaces.lidar_terrain`,
uniform in x and y, 1 cm of height noise, quantised to 1 mm as a LAS file stores it) as a
LAZ file in a temporary directory, a chunk at a time, and prints tables:

1. in memory: :func:`heatcurv.estimate` on the 1M-point file (the clouds up to ``--memory-up-to``
   points) with ``se=False`` (a tiled run writes no standard errors unless asked), one thread and
   all cores, and each tiled run's time over the in-memory one of its size; also the whole
   in-memory job on all cores, ``heatcurv compute`` (read, estimate, write the same fields to a LAZ
   file: what a tiled run does), and each tiled run's time over that;
2. tiled within a budget (default 3 GB), 1 and 2 process workers, 1M and 12M points;
3. the same with ``--scheduler dask`` (a local cluster of 2 workers): Dask's overhead per tile;
4. ``--huge``: 100M points, generated on the fly (scratch and files: about 45 GB for ``--cloud clean``,
   62 GB for the LiDAR-like LAZ, whose disk check asks 82 GB; ``--out-dir`` puts the output elsewhere).

``--cloud clean`` runs the same terrain without noise or rounding, as a float64 NPY, oriented up:
the clean path's narrow kernel makes a 100M run take hours instead of a day on 2 cores.

Peak memory is the resident memory summed over this process and its children
(workers, Dask nannies), sampled every 0.2 s with psutil; a tiled run's peak is
also given per phase (the sum, the driver's and the largest worker's). Every run is a fresh
subprocess, so one run's caches do not help the next.

    python benchmarks/tiles.py                # 1M rows of every table
    python benchmarks/tiles.py --sizes 1e6 12e6
    python benchmarks/tiles.py --sizes 4e6 --workers 2 --no-dask --memory-up-to 4e6
    python benchmarks/tiles.py --huge --dir /big/scratch --out-dir /other/disk
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

SIDE_PER_MILLION = 250.0  # metres of terrain side per million points: 16 points per square metre


def _terrain_chunks(n: int, seed: int, noise: float, chunk: int):
    """The terrain's points ``(x, y, z)``, a chunk at a time: uniform in x and y, ``noise`` metres of height noise."""
    from heatcurv.surfaces import lidar_terrain

    side = SIDE_PER_MILLION * np.sqrt(n / 1e6)
    rng = np.random.default_rng(seed)
    for start in range(0, n, chunk):
        k = min(chunk, n - start)
        x = ORIGIN[0] + rng.uniform(-side / 2, side / 2, k)
        y = ORIGIN[1] + rng.uniform(-side / 2, side / 2, k)
        # the terrain's hill and valley are 30 m wide: repeat them every 60 m so every tile has relief
        lx = (x - ORIGIN[0] + 30) % 60 - 30 + ORIGIN[0]
        ly = (y - ORIGIN[1] + 30) % 60 - 30 + ORIGIN[1]
        z = lidar_terrain(lx, ly, ORIGIN) + 0.002 * (x - ORIGIN[0])
        if noise:
            z = z + rng.normal(0, noise, k)
        yield x, y, z, rng


ORIGIN = (500000.0, 5000000.0, 200.0)


def generate(path: Path, n: int, seed: int = 0, chunk: int = 2_000_000) -> None:
    """A LAZ of ``n`` points of terrain (1 cm noise, millimetre rounding), written a chunk at a time."""
    import laspy

    side = SIDE_PER_MILLION * np.sqrt(n / 1e6)
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.array([ORIGIN[0] - side / 2, ORIGIN[1] - side / 2, 0.0])
    with laspy.open(path, mode="w", header=header, do_compress=True) as writer:
        for x, y, z, rng in _terrain_chunks(n, seed, 0.01, chunk):
            record = laspy.ScaleAwarePointRecord.zeros(len(x), header=header)
            record.x, record.y, record.z = x, y, z
            record.intensity = rng.integers(0, 4000, len(x)).astype(np.uint16)
            writer.write_points(record)


def generate_clean(path: Path, n: int, seed: int = 0, chunk: int = 2_000_000) -> None:
    """An NPY (float64, shape (n, 3)) of ``n`` points of the same terrain, no noise, no rounding, a chunk at a time.

    The clean path's narrow kernel (60 neighbours) makes it the cheap cloud: the one the 100M run can afford.
    """
    out = np.lib.format.open_memmap(path, mode="w+", dtype=np.float64, shape=(n, 3))
    start = 0
    for x, y, z, _ in _terrain_chunks(n, seed, 0.0, chunk):
        out[start:start + len(x)] = np.column_stack([x, y, z])
        start += len(x)
    out.flush()
    del out


class PeakSampler:
    """Resident memory of a process and its children, summed, sampled in a thread.

    ``samples`` keeps ``(time, process's rss, largest child's rss, sum)`` of every sample,
    so that :func:`phase_peaks` can say which phase made the peak.
    """

    def __init__(self, pid: int, every: float = 0.2):
        import psutil

        self.process, self.every, self.peak, self._stop = psutil.Process(pid), every, 0, threading.Event()
        self.samples = []
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        import psutil

        while not self._stop.is_set():
            try:
                own = self.process.memory_info().rss
                children = []
                for p in self.process.children(recursive=True):
                    try:
                        children.append(p.memory_info().rss)
                    except psutil.Error:
                        pass
                total = own + sum(children)
                self.peak = max(self.peak, total)
                self.samples.append((time.time(), own, max(children, default=0), total))
            except psutil.Error:
                pass
            time.sleep(self.every)

    def stop(self) -> int:
        self._stop.set()
        self.thread.join()
        return self.peak


CHILD = r"""
import json, sys, time
import numpy as np
kind, src, dst, arg = sys.argv[1], sys.argv[2], sys.argv[3], json.loads(sys.argv[4])
if __name__ == "__main__":
    tic = time.perf_counter()
    if kind == "memory":
        import heatcurv
        from heatcurv.io import read_points
        cloud = read_points(src)
        # the fields a tiled run writes by default: no standard errors (se=False changes no other field)
        res = heatcurv.estimate(cloud.points, orient="up", workers=arg["workers"], se=False)
        out = {"seconds": time.perf_counter() - tic, "points": len(res)}
    elif kind == "compute":
        from heatcurv.cli.main import main
        status = main(["compute", src, "-o", dst, "-q", "-j", str(arg["workers"])])
        if status != 0:
            sys.exit(status)
        out = {"seconds": time.perf_counter() - tic}
    else:
        from heatcurv.tiles import compute_file
        print("START " + repr(time.time()), flush=True)
        # resume=False: a scratch left by a killed run must not turn a timing into a resume
        report = compute_file(src, dst, progress=False, resume=False, **arg)
        out = {"seconds": time.perf_counter() - tic, "points": report.points, "tiles": report.tiles,
               "tile_size": report.tile_size, "workers": report.workers, "halo": report.halo,
               "timings": report.timings, "peak": report.peak_memory, "scheduler": report.scheduler,
               "tile_seconds": report.tile_seconds, "tile_points": report.tile_points}
    import resource
    # CPU seconds of this process and of its reaped children (the workers): a number a busy machine inflates
    # far less than the wall time
    out["cpu"] = sum(getattr(resource.getrusage(who), f) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
                     for f in ("ru_utime", "ru_stime"))
    print("RESULT " + json.dumps(out))
"""


def measure(kind: str, src, dst, arg: dict, scratch_dir: Path | None = None) -> dict:
    """Run one measurement in a fresh process; its time, report and sampled peak memory."""
    script = Path(tempfile.gettempdir()) / "heatcurv_tiles_bench_child.py"
    script.write_text(CHILD)
    process = subprocess.Popen([sys.executable, str(script), kind, str(src), str(dst), json.dumps(arg)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    sampler = PeakSampler(process.pid)
    scratch_peak = 0
    while process.poll() is None:
        if scratch_dir is not None:
            scratch_peak = max(scratch_peak, _tree_size(scratch_dir))
        time.sleep(1.0)
    out, err = process.communicate()
    peak = sampler.stop()
    lines = [line for line in out.splitlines() if line.startswith("RESULT ")]
    if process.returncode != 0 or not lines:
        raise RuntimeError(f"{kind} run failed ({process.returncode}): {err.strip()[-2000:]}")
    result = json.loads(lines[-1][7:])
    result["sampled_peak"] = peak
    result["scratch_peak"] = scratch_peak
    starts = [float(line.split()[1]) for line in out.splitlines() if line.startswith("START ")]
    if starts and "timings" in result:
        result["phase_peaks"] = phase_peaks(sampler.samples, starts[0], result["timings"])
    return result


PHASES = ("stats", "tiling", "scatter", "survey", "tiles", "reliability", "orientation", "write")


def phase_peaks(samples: list, start: float, timings: dict) -> dict:
    """Per phase of a tiled run (placed by its timings from ``start``): the peak sum, the driver's, a worker's, GB."""
    out, at = {}, 0.0
    for phase in PHASES:
        end = at + timings.get(phase, 0.0)
        mine = [s for s in samples if at <= s[0] - start < end]
        if mine:
            out[phase] = {"sum": max(s[3] for s in mine) / 1e9, "driver": max(s[1] for s in mine) / 1e9,
                          "worker": max(s[2] for s in mine) / 1e9}
        at = end
    return out


def _tree_size(path: Path) -> int:
    total = 0
    for root, _, files in os.walk(path):
        for name in files:
            try:
                total += os.stat(os.path.join(root, name)).st_blocks * 512
            except OSError:
                pass
    return total


def _gb(x) -> str:
    return f"{x / 1e9:.2f}"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e6], help="points of the tiled runs (1e6 12e6)")
    parser.add_argument("--budget", default="3G", help="memory budget of the tiled runs (default 3G)")
    parser.add_argument("--workers", nargs="+", type=int, default=[1, 2], help="process workers to compare")
    parser.add_argument("--no-memory", action="store_true", help="skip the in-memory runs")
    parser.add_argument("--memory-up-to", type=float, default=1e6,
                        help="run in memory the clouds of at most this many points (default 1e6; about 1.8 GB a "
                             "million points)")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask runs")
    parser.add_argument("--huge", action="store_true", help="also 100M points, 2 workers (long: hours)")
    parser.add_argument("--cloud", choices=("lidar", "clean"), default="lidar",
                        help="lidar: LAZ, 1 cm noise, mm rounding (default); clean: the same terrain as a float64 NPY, "
                             "no noise (the narrow clean kernel: the cloud a 100M run can afford)")
    parser.add_argument("--dir", default=None, help="directory for the files and the scratch (default: a temp dir)")
    parser.add_argument("--out-dir", default=None,
                        help="directory for the output files (default: --dir), on another file system when one "
                             "disk cannot hold the scratch and the output of a large run")
    args = parser.parse_args(argv)

    import platform

    import heatcurv

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from machine import commit  # benchmarks/machine.py

    work = Path(args.dir or tempfile.mkdtemp(prefix="heatcurv_tiles_bench_"))
    work.mkdir(parents=True, exist_ok=True)
    out = Path(args.out_dir) if args.out_dir else work
    out.mkdir(parents=True, exist_ok=True)
    print(f"heatcurv {heatcurv.__version__} (commit {commit()}); {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores; files in {work}" + (f", outputs in {out}" if out != work else ""), flush=True)
    sizes = [int(s) for s in args.sizes] + ([100_000_000] if args.huge else [])
    rows = []
    orient = {} if args.cloud == "lidar" else {"orient": "up"}  # a LAZ is oriented up by default, an NPY outward
    for n in sizes:
        src = work / (f"terrain_{n // 1_000_000}M.laz" if args.cloud == "lidar" else f"clean_{n // 1_000_000}M.npy")
        if not src.exists():
            tic = time.perf_counter()
            (generate if args.cloud == "lidar" else generate_clean)(src, n)
            print(f"generated {src.name}: {n} points, {src.stat().st_size / 1e6:.0f} MB in "
                  f"{time.perf_counter() - tic:.0f} s", flush=True)
        if n <= args.memory_up_to and not args.no_memory:
            for threads in (1, -1):
                r = measure("memory", src, "-", {"workers": threads})
                rows.append(("in memory", n, f"{threads if threads > 0 else os.cpu_count()} thr", "-", r))
                _print_row(*rows[-1])
            if args.cloud == "lidar":  # the command line writes what it read: a LAZ, as the tiled runs
                dst = out / f"out_{n}_memory.laz"
                r = measure("compute", src, dst, {"workers": -1})
                rows.append(("compute", n, f"{os.cpu_count()} thr", "-", r))
                _print_row(*rows[-1])
                dst.unlink(missing_ok=True)
        for w in (args.workers if n < 100_000_000 else [max(args.workers)]):
            dst = out / f"out_{n}_{w}.laz"
            arg = {"max_memory": args.budget, "tile_workers": w, "scratch": str(work), **orient}
            r = measure("tiled", src, dst, arg, work / f".{dst.name}.heatcurv-tiles")
            rows.append(("tiled", n, f"{w} proc", args.budget, r))
            _print_row(*rows[-1])
            dst.unlink(missing_ok=True)
        if not args.no_dask and n <= 1_000_000:
            dst = out / f"out_{n}_dask.laz"
            r = measure("tiled", src, dst, {"max_memory": args.budget, "tile_workers": 2, "scheduler": "dask",
                                            "scratch": str(work), **orient})
            rows.append(("tiled dask", n, "2 dask", args.budget, r))
            _print_row(*rows[-1])
            dst.unlink(missing_ok=True)
        if n >= 100_000_000:
            src.unlink(missing_ok=True)
    _summary(rows)


def _print_row(what, n, workers, budget, r):
    per = r["seconds"] / n * 1e6
    extra = ""
    if "tiles" in r:
        t = r["timings"]
        extra = (f" tiles {r['tiles']:3d} of <= {r['tile_size']} pts, halo {r['halo']:.2f} m; passes "
                 f"{t['stats'] + t['tiling'] + t['scatter']:.0f} s, survey {t['survey']:.0f} s, "
                 f"tiles {t['tiles']:.0f} s, write {t['write']:.0f} s; scratch peak {_gb(r['scratch_peak'])} GB")
    cpu = f" cpu {r['cpu']:8.1f} s |" if "cpu" in r else ""
    print(f"| {what:10s} | {n:>11,d} | {workers:7s} | {budget:>4s} | {r['seconds']:8.1f} s | {per:6.1f} us/pt |{cpu} "
          f"peak {_gb(r['sampled_peak'])} GB |{extra}", flush=True)
    for phase, p in r.get("phase_peaks", {}).items():
        print(f"    {phase:12s} peak {p['sum']:.2f} GB (driver {p['driver']:.2f}, largest worker {p['worker']:.2f})",
              flush=True)


def _summary(rows):
    memory = [r for r in rows if r[0] == "in memory"]
    tiled = {(r[1], r[2]): r[4] for r in rows if r[0] == "tiled"}
    dask = [r for r in rows if r[0] == "tiled dask"]
    if memory:
        one = [r for r in memory if r[2].startswith("1 ")]
        if one:
            for r in one:
                print(f"in-memory time per point (1 thread, {r[1]:,d} points): {r[4]['seconds'] / r[1] * 1e6:.1f} us")
    jobs = {r[1]: r for r in rows if r[0] == "compute"}
    for (n, w), r in sorted(tiled.items()):
        same = [m for m in memory if m[1] == n and not m[2].startswith("1 ")]
        if same:
            print(f"{n:,d} points: tiled ({w}) / in memory ({same[0][2]}): "
                  f"{r['seconds'] / same[0][4]['seconds']:.2f}x")
        if n in jobs:
            print(f"{n:,d} points: tiled ({w}) / heatcurv compute in memory ({jobs[n][2]}, read, estimate, write): "
                  f"{r['seconds'] / jobs[n][4]['seconds']:.2f}x")
    for (n, w), r in sorted(tiled.items()):
        base = tiled.get((n, "1 proc"))
        if base is not None and w != "1 proc":
            print(f"{n:,d} points: speed-up {w} vs 1 proc: {base['seconds'] / r['seconds']:.2f}x")
    for row in dask:
        proc = tiled.get((row[1], "2 proc"))
        if proc is not None:
            overhead = (row[4]["seconds"] - proc["seconds"]) / row[4]["tiles"]
            print(f"{row[1]:,d} points: Dask (local cluster, 2 workers) {row[4]['seconds']:.1f} s vs processes "
                  f"{proc['seconds']:.1f} s: {overhead:+.2f} s per tile ({row[4]['tiles']} tiles, cluster start "
                  "included)")


if __name__ == "__main__":
    main()
