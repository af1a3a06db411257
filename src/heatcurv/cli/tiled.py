"""``heatcurv compute`` on clouds that do not fit in memory: the flags of tiled runs and when to tile.

``compute`` tiles by itself when the cloud would not fit the memory budget
(``--max-memory``, default 60 % of the memory available), and whenever one of
``--tile-size``, ``--scheduler``, ``--scratch`` or ``--resume`` is given;
otherwise the in-memory path runs as before. ``-j/--workers`` is the cores to
use either way: threads of one in-memory estimate, or in a tiled run at most N
tiles computed at once, the N cores shared among them (one thread each when
the budget holds N workers). See :func:`heatcurv.tiles.compute_file`.
"""

from __future__ import annotations

import argparse

from ..errors import HeatcurvError
from .console import Log

__all__ = ["add_tile_options", "wants_tiles", "run_tiled"]


def _size(text: str) -> int:
    from ..tiles.plan import parse_size

    try:
        return parse_size(text)
    except HeatcurvError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of points, got {text!r}") from None
    if value < 1000:
        raise argparse.ArgumentTypeError(f"a tile must hold at least 1000 points, got {value}")
    return value


def _scheduler(text: str) -> str:
    from ..tiles.executors import SCHEDULERS

    if text in SCHEDULERS or text.startswith("tcp://"):
        return text
    raise argparse.ArgumentTypeError(f"choose {', '.join(SCHEDULERS)} or tcp://host:port, got {text!r}")


def add_tile_options(parser) -> None:
    """The group "large clouds (tiles)" of ``compute``."""
    group = parser.add_argument_group(
        "large clouds (tiles)",
        "A cloud that does not fit the memory budget is computed in tiles with halos, streamed from and to "
        "disk (LAS/LAZ, binary PLY, NPY in; LAS/LAZ, PLY out); -j is then the tiles computed at once.",
    )
    group.add_argument("--max-memory", type=_size, metavar="SIZE",
                       help="memory budget of the whole run, all workers together, e.g. 3G or 500M "
                       "(default: 60%% of the memory available)")
    group.add_argument("--tile-size", type=_count, metavar="N",
                       help="core points per tile (default: what the budget holds, at most 2000000); tiles")
    group.add_argument("--scheduler", type=_scheduler, metavar="NAME",
                       help="processes (default), threads, dask (a local Dask cluster), serial, or "
                       "tcp://HOST:PORT (a running 'dask scheduler'); tiles")
    group.add_argument("--scratch", metavar="DIR",
                       help="directory for the scratch files (default: the output's directory); tiles")
    group.add_argument("--resume", action="store_true",
                       help="resume an interrupted tiled run (also automatic when the scratch directory holds "
                       "its plan); tiles")


def wants_tiles(args, log: Log) -> bool:
    """Whether ``compute`` runs in tiles: a tile flag given, or the cloud does not fit the budget."""
    if args.tile_size or args.scheduler or args.scratch or args.resume:
        return True
    from ..tiles.plan import default_budget, in_memory_bytes, size_text

    budget = args.max_memory or default_budget()
    count, need = in_memory_bytes(args.input)
    if need <= budget:
        return False
    log.info(f"{args.input}: {count} points need about {size_text(need)} in memory, more than the budget of "
             f"{size_text(budget)}: computing in tiles")
    return True


def run_tiled(args, log: Log, output, wanted) -> None:
    """``compute`` in tiles: :func:`heatcurv.tiles.compute_file` with the command line's options."""
    import sys

    from ..tiles import compute_file
    from .options import estimator_kwargs

    if getattr(args, "normals_from_input", False):
        raise HeatcurvError("--normals-from-input is not available in tiled runs; drop it, or raise --max-memory "
                            "to compute in memory")
    options = estimator_kwargs(args)
    threads = options.pop("workers")
    report = compute_file(
        # -j caps the cores: the tiles at once, and the threads the workers share (heatcurv.tiles.job.task_threads)
        args.input, output, max_memory=args.max_memory, tile_size=args.tile_size, tile_workers=threads, workers=threads,
        scheduler=args.scheduler or "processes", scratch=args.scratch, resume=True if args.resume else None,
        fields=wanted, dtype="float64" if args.float64 else None, skip_nonfinite=args.skip_nonfinite,
        progress=not log.quiet and sys.stderr.isatty(), log=log.info, **options,
    )
    log.detail(f"  tiles: {report.tiles} of at most {report.tile_size} points, halo {report.halo:.4g}, "
               f"{report.workers} at once ({report.scheduler}); {report.widened} widened, {report.resumed} resumed")
    log.detail("  timings: " + ", ".join(f"{k} {v:.1f} s" for k, v in report.timings.items()))
    peak = report.peak_memory
    log.detail(f"  peak memory: driver {peak['driver'] / 1e6:.0f} MB, largest worker {peak['worker'] / 1e6:.0f} MB")
