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
number of threads the kernels run on, to a call's ``workers``.
"""

from __future__ import annotations

from contextlib import contextmanager

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


#: Blocks of fewer rows than this run side by side (:func:`map_blocks`): the compiled kernels split
#: one call's rows over threads only from 1024 rows on (:data:`heatcurv._kernels.MIN_ROWS_PER_CHUNK`
#: per thread), and a wide kernel's block of a million pairs holds a few hundred rows.
SPLIT_ROWS = 1024


def map_blocks(function, blocks: list, rows: int):
    """``function(block)`` for every block, in order, on the kernels' threads when the blocks are small.

    Parameters
    ----------
    function : callable
        Computes one block; its compiled kernels release the GIL.
    blocks : list
        The blocks' arguments.
    rows : int
        Rows of the largest block: below :data:`SPLIT_ROWS` the blocks run side by side on
        numba's thread count of the calling thread (:func:`threads`), else one after the other
        (each already runs on every thread).

    Returns
    -------
    iterator
        The results, in the order of ``blocks``. Every block is submitted at once:
        keep what ``function`` returns small.
    """
    import numba

    count = numba.get_num_threads() if rows < SPLIT_ROWS and len(blocks) > 1 else 1
    if count <= 1:
        return map(function, blocks)
    from concurrent.futures import ThreadPoolExecutor

    def run(pool_function, items):
        with ThreadPoolExecutor(count) as pool:
            yield from pool.map(pool_function, items)

    return run(function, blocks)
