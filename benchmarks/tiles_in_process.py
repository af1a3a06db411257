"""A tile in the driver's process against one worker process: measured peaks and the plan's memory model.

Generates the terrain of ``benchmarks/tiles.py`` (clean, NPY) and runs it tiled twice, each in a fresh
process, with one tile at a time in the driver's process (``scheduler="serial"``) and in one worker
process (a child started by a large process inherits its peak), and prints each run's
peak resident memory (driver, worker) beside the model's estimate for the largest tile with the survey's
halo and with the tiles' (:func:`heatcurv.tiles.plan.in_process_memory`, :func:`heatcurv.tiles.plan.worker_memory`).

    python benchmarks/tiles_in_process.py               # 200k points, tiles of 50000
    python benchmarks/tiles_in_process.py --points 1e6 --tile-size 200000
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))


def run(src: Path, out: Path, scheduler: str, tile_size: int) -> str:
    from heatcurv.tiles import compute_file, plan
    from heatcurv.tiles.tasks import load_plan

    report = compute_file(src, out, scheduler=scheduler, tile_workers=1, tile_size=tile_size, max_memory="3G",
                          keep_scratch=True)
    saved = load_plan(report.scratch)
    tiling = plan.Tiling.from_json(saved["tiling"])
    stats = plan.CloudStats(**{k: tuple(v) if isinstance(v, list) else v for k, v in saved["stats"].items()})
    survey = int(plan.halo_points(tiling, stats, saved["survey_halos"]).max())
    tiles = int(plan.halo_points(tiling, stats, report.halo).max())
    shutil.rmtree(report.scratch)
    peak = report.peak_memory
    if scheduler == "serial":
        model = (f"model {plan.in_process_memory(survey) / 1e6:.0f} MB (survey), "
                 f"{plan.in_process_memory(tiles) / 1e6:.0f}")
        measured = f"driver's process {peak['driver'] / 1e6:.0f} MB"
    else:
        model = (f"model {(plan.DRIVER_MEMORY + plan.worker_memory(survey)) / 1e6:.0f} MB (survey), "
                 f"{(plan.DRIVER_MEMORY + plan.worker_memory(tiles)) / 1e6:.0f}")
        measured = f"driver {peak['driver'] / 1e6:.0f} MB + worker {peak['worker'] / 1e6:.0f} MB"
    return (f"{scheduler}: {report.tiles} tiles, largest with the survey's halo {survey} points, with the tiles' "
            f"{tiles}; {measured}; {model} MB (tiles)")


def main(argv=None) -> None:
    import subprocess

    import tiles as generator

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=float, default=2e5)
    parser.add_argument("--tile-size", type=int, default=50_000)
    parser.add_argument("--run", nargs=2, metavar=("SCHEDULER", "FILE"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.run:  # one run in a fresh process: a process's peak counts what it held before, a child's its parent's
        src = Path(args.run[1])
        print(run(src, src.with_name(f"{args.run[0]}.ply"), args.run[0], args.tile_size), flush=True)
        return
    with tempfile.TemporaryDirectory() as directory:
        src = Path(directory) / "terrain.npy"
        generator.generate_clean(src, int(args.points))
        for scheduler in ("serial", "processes"):
            subprocess.run([sys.executable, __file__, "--tile-size", str(args.tile_size), "--run", scheduler,
                            str(src)], check=True)


if __name__ == "__main__":
    main()
