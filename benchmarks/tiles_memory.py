"""Where a tiled run's peak memory comes from: resident memory of the driver and of each worker, per phase.

Runs :func:`heatcurv.tiles.compute_file` on a terrain LAZ of ``benchmarks/tiles.py``
(16 points per m^2) in a fresh process and samples, every 0.2 s with psutil,
the resident memory of that process (the driver) and of each of its children
(the survey's workers, then the tiles' workers: a new pool each), and their
sum (what ``benchmarks/tiles.py`` reports as the peak). The phases are placed
on the timeline from the report's timings. Prints one line per phase: the
largest sum, the driver's largest, the largest worker, and the run's plan.

    python benchmarks/tiles_memory.py --points 3e6 --tile-size 199393 --budget 3G --workers 2
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from tiles import generate  # noqa: E402

CHILD = r"""
import json, sys, time
arg = json.loads(sys.argv[3])
if __name__ == "__main__":
    from heatcurv.tiles import compute_file
    print("START " + repr(time.time()), flush=True)
    report = compute_file(sys.argv[1], sys.argv[2], progress=False, **arg)
    print("RESULT " + json.dumps({"tiles": report.tiles, "tile_size": report.tile_size, "workers": report.workers,
                                  "halo": report.halo, "timings": report.timings, "peak": report.peak_memory,
                                  "budget": report.budget}), flush=True)
"""

PHASES = ("stats", "tiling", "scatter", "survey", "tiles", "reliability", "orientation", "write")


def sample(process, every: float = 0.2) -> list:
    """``(time, driver rss, {child pid: rss})`` every ``every`` seconds until ``process`` ends."""
    import psutil

    root = psutil.Process(process.pid)
    out = []
    while process.poll() is None:
        try:
            driver = root.memory_info().rss
            kids = {}
            for child in root.children(recursive=True):
                try:
                    kids[child.pid] = child.memory_info().rss
                except psutil.Error:
                    pass
            out.append((time.time(), driver, kids))
        except psutil.Error:
            pass
        time.sleep(every)
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--points", type=float, default=3e6)
    parser.add_argument("--tile-size", type=int, default=None)
    parser.add_argument("--budget", default="3G")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dir", default=None)
    parser.add_argument("--timeline", default=None, help="write the samples as JSON lines here")
    args = parser.parse_args(argv)
    n = int(args.points)
    work = Path(args.dir or tempfile.mkdtemp(prefix="heatcurv_tiles_memory_"))
    work.mkdir(parents=True, exist_ok=True)
    src = work / f"terrain_{n}.laz"
    if not src.exists():
        generate(src, n)
    dst = work / f"out_{n}.laz"
    arg = {"max_memory": args.budget, "tile_workers": args.workers, "scratch": str(work)}
    if args.tile_size:
        arg["tile_size"] = args.tile_size
    script = Path(tempfile.gettempdir()) / "heatcurv_tiles_memory_child.py"
    script.write_text(CHILD)
    process = subprocess.Popen([sys.executable, str(script), str(src), str(dst), json.dumps(arg)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    samples = sample(process)
    out, err = process.communicate()
    starts = [float(line.split()[1]) for line in out.splitlines() if line.startswith("START ")]
    results = [json.loads(line[7:]) for line in out.splitlines() if line.startswith("RESULT ")]
    if process.returncode != 0 or not results:
        raise SystemExit(f"run failed ({process.returncode}): {err.strip()[-2000:]}")
    report, t0 = results[0], starts[0]
    dst.unlink(missing_ok=True)
    if args.timeline:
        with open(args.timeline, "w") as stream:
            for t, d, kids in samples:
                stream.write(json.dumps({"t": t - t0, "driver": d, "workers": kids}) + "\n")
    print(f"{n:,d} points, {report['tiles']} tiles of <= {report['tile_size']}, {report['workers']} at once, "
          f"halo {report['halo']:.2f}, budget {report['budget'] / 1e9:.2f} GB; report's peaks "
          f"{ {k: round(v / 1e9, 3) for k, v in report['peak'].items()} } GB")
    edges, at = [], 0.0
    for phase in PHASES:
        seconds = report["timings"].get(phase, 0.0)
        edges.append((phase, at, at + seconds))
        at += seconds
    edges.append(("after", at, float("inf")))
    edges.insert(0, ("start", -float("inf"), 0.0))
    print("| phase | seconds | peak sum (GB) | driver peak (GB) | largest worker (GB) | workers seen |")
    print("|---|---|---|---|---|---|")
    for phase, a, b in edges:
        mine = [(d, kids) for t, d, kids in samples if a <= t - t0 < b]
        if not mine:
            continue
        total = max(d + sum(k.values()) for d, k in mine)
        driver = max(d for d, _ in mine)
        worker = max((max(k.values()) for _, k in mine if k), default=0)
        pids = len({p for _, k in mine for p in k})
        print(f"| {phase} | {min(b, samples[-1][0] - t0) - max(a, samples[0][0] - t0):.0f} | {total / 1e9:.3f} | "
              f"{driver / 1e9:.3f} | {worker / 1e9:.3f} | {pids} |")
    overall = max(d + sum(k.values()) for _, d, k in samples)
    print(f"overall peak (driver + workers): {overall / 1e9:.3f} GB against a budget of "
          f"{report['budget'] / 1e9:.3f} GB")


if __name__ == "__main__":
    main()
