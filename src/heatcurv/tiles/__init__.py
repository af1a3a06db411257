"""Out-of-core and distributed runs: a cloud of any size computed in tiles with halos.

:func:`compute_file` reads a LAS/LAZ, binary PLY or NPY file a chunk at a
time, sorts its points into tiles in a scratch directory, computes every tile
with a halo wide enough for its values (a certificate checks each one), makes
the outward orientation agree across tiles, and writes the output in input
order, atomically. The tiles run in local processes (default), threads, a
local Dask cluster, or an existing Dask cluster (``tcp://host:port``).

=================  ==========================================================
``sources``        streaming readers (LAS/LAZ chunks, PLY and NPY maps)
``plan``           statistics, tiling (counting sort), memory budget, disk
``compute``        the ONE module that calls the numerical core
``tasks``          the tile and survey tasks, the halo certificate
``executors``      serial, processes, threads, Dask
``driver``         :func:`compute_file`: the phases, faults, resume
``orient``         outward orientation across tiles (flip bits)
``output``         index-addressed results, LAS/LAZ and PLY writers
``progressbar``    the tqdm bar over tiles
=================  ==========================================================

The numerical core never imports this package; see docs/tiles.md.
"""

from .driver import TiledReport, compute_file
from .plan import CloudStats, parse_size

__all__ = ["compute_file", "TiledReport", "CloudStats", "parse_size"]
