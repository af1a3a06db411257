"""Out-of-core and distributed runs: a cloud of any size computed in tiles with halos.

:func:`compute_file` reads a LAS/LAZ, binary PLY or NPY file a chunk at a
time, sorts its points into tiles in a scratch directory, computes every tile
with a halo wide enough for its values (a certificate checks each one), makes
the outward orientation agree across tiles, and writes the output in input
order, atomically. The tiles run in local processes (default), threads, a
local Dask cluster, or an existing Dask cluster (``tcp://host:port``).

One module per phase, in the order :func:`compute_file` (``driver``) runs them,
and the tools they use:

==================  ========================================================
``driver``          :func:`compute_file`: the arguments, the phases, the report
``job``             what every phase shares: the job, a phase's workers, the
                    one loop that submits tasks to any executor
``phase_plan``      plan: statistics, tiles that fit the budget, scratch;
                    or the plan of a run to resume
``phase_survey``    survey: the cloud-wide kernel choice every tile gets
``phase_tiles``     run: every tile with its halo, stored as it finishes;
                    the flags against the whole cloud's medians
``phase_orient``    orientation: the seams' flips, the winding number
``phase_write``     write: the output in input order, atomically
------------------  --------------------------------------------------------
``sources``         streaming readers (LAS/LAZ chunks, PLY and NPY maps)
``plan``            statistics, tiling (counting sort), memory budget, disk;
                    the typed :class:`~heatcurv.tiles.plan.TilePlan`
``context``         the survey's typed result every tile gets
``compute``         the ONE module that calls the numerical core
``tasks``           the tile and survey tasks, the halo certificate
``executors``       serial, processes, threads, Dask
``medians``         exact medians of columns too long to hold
``orient``          outward orientation across tiles (flip bits)
``winding``         inside and outside across tiles (the winding number)
``output``          index-addressed results, LAS/LAZ and PLY writers
``progressbar``     the tqdm bar over tiles
==================  ========================================================

The numerical core never imports this package; see docs/tiles.md.
"""

from .driver import TiledReport, compute_file
from .plan import CloudStats, parse_size

__all__ = ["compute_file", "TiledReport", "CloudStats", "parse_size"]
