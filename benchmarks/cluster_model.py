"""A cost model of a tiled run, fitted here: the time on N workers, and where the driver or the file system limits it.

Runs, each in a fresh process (the LiDAR-like terrain and the runner of ``benchmarks/tiles.py``, tiles of
``--tile-size`` core points, one thread a worker): the 1M-point terrain with one worker process at two tile sizes,
the 2M-point terrain with one worker, then the 1M terrain with two worker processes and on a local Dask cluster of
two single-thread workers. The model is fitted to the one-worker runs only and then predicts the two-worker
runs; both are printed beside each other. Then it extrapolates to clusters.

The model, seconds, for ``n`` points cut into ``T`` tiles on ``N`` workers (tile ``t``: ``m_t`` core points,
``h_t`` halo points computed with them):

* driver, one thing at a time: ``D = d n + e T`` (the passes over the input, the scatter into tile files, the
  survey's merge, the seam vote, the ordered write);
* survey tasks: ``S = R (s0 + s1 n / T)``, ``R = ceil(T / N)`` rounds of equal tasks;
* tile tasks: ``P = R (a + b (m + h))``, with the mean tile's ``m + h``;
* a scheduler's overhead per round of tasks, ``o`` (Dask against the process pool; two phases of tasks);
* the file system: the workers read ``q_in`` and write ``q_out`` bytes a point (core and halo coordinates in,
  fields out); a shared file system of aggregate bandwidth ``B`` gives the tasks at least
  ``n (q_in + q_out) / B`` seconds, and the driver's own reads and writes (``n q_drv`` bytes) at least
  ``n q_drv / B_1``, ``B_1`` what one client gets.

``T(N) = D + max(S + P + 2 o R, file-system floor)``. The driver becomes the bottleneck when ``D`` exceeds the
tasks' share; the speed-up over one worker is then bounded by ``(D + S + P)(1) / D``.

    python benchmarks/cluster_model.py            # about 4 minutes on 2 cores
    python benchmarks/cluster_model.py --markdown # the tables of docs/tiles.md
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tiles  # noqa: E402  benchmarks/tiles.py: the terrain and the runner
from machine import commit, cpu_model, memory_text, table  # noqa: E402

DRIVER_PHASES = ("stats", "tiling", "scatter", "reliability", "orientation", "write")


def run(src: Path, work: Path, tile_size: int, workers: int, scheduler: str = "processes") -> dict:
    """One tiled run in a fresh process: its report's numbers and the scratch directory's peak size.

    Each worker computes with one thread (``workers=1``), as a cluster's workers started with ``--nthreads 1``:
    a lone local worker would otherwise take every core's threads, and the one-worker costs the model is
    fitted to would not be one core's.
    """
    dst = work / f"out_{src.stem}_{tile_size}_{workers}_{scheduler}.laz"
    arg = {"tile_size": tile_size, "tile_workers": workers, "workers": 1, "scheduler": scheduler,
           "scratch": str(work)}
    r = tiles.measure("tiled", src, dst, arg, work / f".{dst.name}.heatcurv-tiles")
    r["n"], r["bytes_out"] = r["points"], dst.stat().st_size
    r["bytes_in"] = src.stat().st_size
    dst.unlink(missing_ok=True)
    r["driver"] = sum(r["timings"].get(p, 0.0) for p in DRIVER_PHASES)
    kind = "Dask workers" if scheduler == "dask" else ("processes" if workers > 1 else "process")
    r["label"] = f"{r['n'] / 1e6:.0f}M, tiles of {tile_size:,d}, {workers} {kind}"
    return r


class Model:
    """The fitted constants (module docstring) and the predictions they make."""

    def __init__(self, ones: list):
        from scipy.optimize import nnls  # least squares with constants >= 0

        # driver: D = d n + e T over the one-worker runs
        self.d, self.e = nnls(np.array([[r["n"], r["tiles"]] for r in ones], dtype=float),
                              np.array([r["driver"] for r in ones]))[0]
        # tiles: each tile's seconds against its core + halo points
        sizes = np.concatenate([[c + h for c, h in r["tile_points"]] for r in ones]).astype(float)
        seconds = np.concatenate([r["tile_seconds"] for r in ones])
        self.a, self.b = nnls(np.column_stack([np.ones_like(sizes), sizes]), seconds)[0]
        # survey: S = T s0 + s1 n with one worker
        self.s0, self.s1 = nnls(np.array([[r["tiles"], r["n"]] for r in ones], dtype=float),
                                np.array([r["timings"]["survey"] for r in ones]))[0]
        self.o = 0.0
        # bytes a point: the scratch holds the tiles' points and results once; the workers read the one and
        # write the other, the driver writes and reads both and reads the input, writes the output
        self.q_tasks = float(np.mean([r["scratch_peak"] / r["n"] for r in ones]))
        self.q_driver = float(np.mean([(r["scratch_peak"] + r["bytes_in"] + r["bytes_out"]) / r["n"] for r in ones]))

    def phases(self, n: float, T: int, N: int, halo: float, dask: bool = False) -> dict:
        """Seconds of each phase: ``n`` points in ``T`` tiles on ``N`` workers, ``halo`` points per core point."""
        rounds = math.ceil(T / N)
        core = n / T
        extra = self.o * rounds if dask else 0.0
        return {
            "driver": self.d * n + self.e * T,
            "survey": rounds * (self.s0 + self.s1 * core) + extra,
            "tiles": rounds * (self.a + self.b * core * (1 + halo)) + extra,
        }

    def total(self, n: float, T: int, N: int, halo: float, bandwidth: float | None = None,
              client: float | None = None) -> dict:
        """The whole run: the driver (at least its bytes at ``client`` B/s), then the tasks (at least their bytes at
        ``bandwidth`` B/s shared)."""
        p = self.phases(n, T, N, halo)
        tasks = p["survey"] + p["tiles"]
        driver = p["driver"] if client is None else max(p["driver"], n * self.q_driver / client)
        floor = 0.0 if bandwidth is None else n * self.q_tasks / bandwidth
        return {"total": driver + max(tasks, floor), "driver": driver, "tasks": tasks, "fs_bound": floor > tasks}


def halo_share(r: dict) -> float:
    """Halo points computed per core point in a run."""
    return sum(h for _, h in r["tile_points"]) / r["n"]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tile-size", type=int, default=337_157, help="core points a tile (3 GB, 2 workers)")
    parser.add_argument("--markdown", action="store_true", help="print Markdown tables")
    parser.add_argument("--dir", default=None, help="directory for the files and the scratch (default: a temp dir)")
    args = parser.parse_args(argv)
    import heatcurv

    work = Path(args.dir or tempfile.mkdtemp(prefix="heatcurv_cluster_model_"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"Machine: {cpu_model()}, {os.cpu_count()} cores{memory_text()}; load average "
          f"{os.getloadavg()[0]:.1f} at the start; heatcurv {heatcurv.__version__} at commit {commit()}\n", flush=True)
    clouds = {}
    for millions in (1, 2):
        clouds[millions] = work / f"terrain_{millions}M.laz"
        if not clouds[millions].exists():
            tiles.generate(clouds[millions], millions * 1_000_000)
    size = args.tile_size
    # a first small run compiles the kernels into numba's cache (a fresh checkout has none), untimed
    warm = work / "terrain_warm.laz"
    if not warm.exists():
        tiles.generate(warm, 50_000)
    run(warm, work, 20_000, 1)
    ones = [run(clouds[1], work, size, 1), run(clouds[1], work, size // 2, 1), run(clouds[2], work, size, 1)]
    twos = [run(clouds[1], work, size, 2), run(clouds[1], work, size, 2, "dask")]
    model = Model(ones)
    process, dask = twos
    # Dask's overhead per round of tasks: what its run took beyond the process pool's, over both phases' rounds
    model.o = max(0.0, (dask["seconds"] - process["seconds"]) / (2 * math.ceil(dask["tiles"] / 2)))

    rows = []
    for r, role in [(r, "fitted") for r in ones] + [(r, "predicted") for r in twos]:
        workers = 2 if r in twos else 1
        p = model.phases(r["n"], r["tiles"], workers, halo_share(r), dask=r is dask)
        predicted = sum(p.values())
        t = r["timings"]
        rows.append([r["label"], str(r["tiles"]), role, f"{r['seconds']:.1f}", f"{predicted:.1f}",
                     f"{r['driver']:.1f} / {p['driver']:.1f}", f"{t['survey']:.1f} / {p['survey']:.1f}",
                     f"{t['tiles']:.1f} / {p['tiles']:.1f}"])
    print(table("Measured and modelled (seconds; phases measured / modelled)",
                ["run", "tiles", "model", "measured", "modelled", "driver", "survey", "tiles"], rows, args.markdown))
    print(f"\nConstants: driver d = {model.d * 1e6:.2f} us a point, e = {model.e:.2f} s a tile; survey "
          f"s0 = {model.s0:.2f} s a task, s1 = {model.s1 * 1e6:.2f} us a core point; tiles a = {model.a:.2f} s a task, "
          f"b = {model.b * 1e6:.2f} us a computed point; Dask "
          f"o = {model.o:.2f} s a round; scratch {model.q_tasks:.0f} B a point (the tasks' reads and writes), "
          f"{model.q_driver:.0f} B a point through the driver (scratch, input, output)\n")

    share = float(np.mean([halo_share(r) for r in ones if r["n"] / r["tiles"] > 0.7 * size]))
    contention = (process["timings"]["survey"] + process["timings"]["tiles"]) / sum(
        v for k, v in model.phases(process["n"], process["tiles"], 2, halo_share(process)).items() if k != "driver")
    print(f"Two workers on this machine's {os.cpu_count()} cores: their tasks took {contention:.2f} times the "
          f"one-worker cost (shared cores and memory); tiles of {size:,d} points carry {100 * share:.0f} % halo.\n")
    rows = []
    for n in (12e6, 100e6, 1e9):
        T = math.ceil(n / size)
        one = model.total(n, T, 1, share)["total"]
        for N in (1, 4, 16, 64, 256, 1024):
            if N > 4 * T:
                continue
            cells = [f"{n / 1e6:,.0f}M", str(T), str(N)]
            for bandwidth, client in ((None, None), (1e9, 0.5e9), (0.2e9, 0.1e9)):
                m = model.total(n, T, N, share, bandwidth, client)
                note = " (FS)" if m["fs_bound"] else (" (driver)" if m["driver"] > m["tasks"] else "")
                cells.append(f"{m['total'] / 3600:.2f} h, {one / m['total']:.1f}x{note}")
            rows.append(cells)
    print(table("Predicted time and speed-up over one worker (tiles of the given size; '(driver)': the driver's "
                "serial share is the larger, '(FS)': the file system's floor binds)",
                ["points", "tiles", "workers", "no file-system limit", "1 GB/s shared, 0.5 GB/s a client",
                 "0.2 GB/s shared, 0.1 GB/s a client"], rows, args.markdown))
    ceiling = [(n, (model.total(n, math.ceil(n / size), 1, share)["total"])
                / (model.d * n + model.e * math.ceil(n / size))) for n in (12e6, 1e9)]
    print("\nSpeed-up ceiling (the driver alone left): " + ", ".join(f"{n / 1e6:,.0f}M {c:.1f}x" for n, c in ceiling)
          + f". Whole run: load average {os.getloadavg()[0]:.1f} at the end.", flush=True)


if __name__ == "__main__":
    tic = time.perf_counter()
    main()
    print(f"({time.perf_counter() - tic:.0f} s)")
