"""The compiled kernels' thread count.

Why there is no backend to choose:

* numba is required. Every hot stage (PCA covariances and eigenvectors,
  orientation costs, areas, fit weights, the mean-curvature normal, the chord
  fit, border flags) loops over every neighbour pair, and runs as one numba
  kernel over the CSR arrays, parallel over points (:mod:`heatcurv._kernels`:
  serial ``nogil`` row kernels that :func:`heatcurv._kernels.parallel_rows`
  runs on threads, which compile twice as fast as numba's ``prange``).
  Without numba, importing heatcurv fails with an ImportError naming it.
* One implementation per hot stage. There is no numpy twin to select and no
  process-global backend switch, which would change the code other threads run.
* The numpy reference implementations live in the tests (``tests/reference/``)
  as oracles: the tests run every kernel and its reference on the same inputs.

What remains is :func:`threads`, which matches numba's thread count, the
number of threads the kernels run on, to a call's ``workers``, and
:func:`map_blocks`, which runs small blocks side by side. Both use one pool of
worker threads, the row pool of :func:`heatcurv._kernels.parallel_rows`: a
kernel call of :data:`SPLIT_ROWS` rows or more is split over it, smaller
blocks share it.
"""

from __future__ import annotations

from contextlib import contextmanager

from ._kernels import SPLIT_ROWS

__all__ = ["threads", "map_blocks", "SPLIT_ROWS"]


@contextmanager
def threads(workers: int | None):
    """Run a block with ``workers`` compiled-kernel threads (-1 or None: all cores).

    The k-d tree queries take ``workers`` themselves; this sets numba's
    thread count to match and restores it afterwards. The kernels run on as
    many threads as numba's thread count of the thread that calls them
    (:func:`heatcurv._kernels.parallel_rows`).

    numba's thread count is thread-local (numba masks its pool per calling
    thread): setting it here limits only the kernels this thread launches,
    so concurrent calls from other threads keep their own count, and a thread
    started inside the block begins with numba's default
    (``NUMBA_NUM_THREADS``), not with ``workers``.
    """
    if workers is None or int(workers) < 0:
        yield
        return
    import numba  # required; imported here so that a missing numba is reported by heatcurv._kernels

    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(workers), numba.config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def map_blocks(function, blocks: list, rows: int):
    """``function(block)`` for every block, in order; the blocks side by side when each is too small to split.

    Parameters
    ----------
    function : callable
        Computes one block; its compiled kernels release the GIL.
    blocks : list
        The blocks' arguments.
    rows : int
        Rows of the largest block: below :data:`SPLIT_ROWS` no kernel call of a
        block is split over threads (:func:`heatcurv._kernels.parallel_rows`), so
        the blocks share the same threads instead
        (:func:`heatcurv._kernels.parallel_items`); from it on they run one after
        the other, each on every thread.

    Returns
    -------
    iterator
        The results, in the order of ``blocks``. Side by side, every block is
        computed before the first result is returned: keep what ``function``
        returns small.
    """
    from ._kernels import parallel_items

    if rows >= SPLIT_ROWS or len(blocks) < 2:
        return map(function, blocks)
    return iter(parallel_items(function, blocks))
