"""The compiled kernels' thread count.

Decision (recorded here because this module used to hold the switch it replaces):

* numba is required. Every hot stage (PCA covariances and eigenvectors,
  orientation costs, areas, fit weights, the mean-curvature normal, the chord
  fit, border flags) loops over every neighbour pair, and runs as one numba
  kernel over the CSR arrays, parallel over points (:mod:`heatcurv._kernels`:
  serial ``nogil`` row kernels that :func:`heatcurv._kernels.parallel_rows`
  runs on threads, which compile twice as fast as numba's ``prange``).
  Without numba, importing heatcurv fails with an ImportError naming it.
* One implementation per hot stage. There is no numpy twin to select and no
  process-global backend switch (formerly ``set_backend``, ``backend()`` and
  ``HEATCURV_BACKEND``), which changed the code other threads ran.
* The numpy reference implementations live in the tests (``tests/reference/``)
  as oracles: the tests run every kernel and its reference on the same inputs.

What remains is :func:`threads`, which matches numba's thread count, the
number of threads the kernels run on, to a call's ``workers``.
"""

from __future__ import annotations

from contextlib import contextmanager

__all__ = ["threads"]


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
