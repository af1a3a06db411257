"""Compiled (numba) kernels of the hot stages: the one implementation of each per-pair loop.

Every loop over the CSR neighbour pairs that the estimator runs lives here as
a numba kernel, with no per-pair temporaries:

=============  ==============================================================
``segment``    PCA covariances and their eigenvectors, orientation costs,
               taper sums, tapered heat weights, mean-curvature-normal sums,
               centroid offsets (border flags)
``chordfit``   the chord fit's normal equations, residuals and Cholesky solve
``graph``      minimum spanning forest (orientation; its scan on the threads)
               and connected components (outliers, serial)
``anchors``    carrying the anchors' fits to every point (:mod:`heatcurv.fits.anchors`)
``laplacian``  the default Laplacian's tangent-plane Voronoi cells and border
               moments (:mod:`heatcurv.operators.point_laplacian`), the heat
               method's gradient and divergence (:mod:`heatcurv.operators.geodesic`)
``neighbours`` a tiled run's stored neighbour lists read back as a tile's
               neighbourhood (:mod:`heatcurv.tiles.neighbours`)
``winding``    generalised winding numbers of labelled dipoles
               (:mod:`heatcurv.orient.enclosure`)
``dipoles``    the winding number of one dipole a point, its transpose and its
               gradient over a one-level grid (:mod:`heatcurv.orient.consistency`)
``visibility`` rays walked through a grid of discs: which escape
               (:mod:`heatcurv.orient.visibility`)
=============  ==============================================================

The kernels take and return plain arrays and import nothing from the rest of
heatcurv: the stage modules (``areas``, ``border``, ``chordfit``, ``kernel``,
``mean_curvature``, ``normals``) import them, never the reverse. Their numpy
reference implementations live in the tests (``tests/reference/``), which
compare every kernel with its reference on the same inputs.

numba is required (see :mod:`heatcurv.backend`); without it importing heatcurv
fails here with an ImportError that says so.

Compilation, once per machine
-----------------------------
numba compiles the kernels the first time they run and caches the machine
code (``cache=True``: next to these files in ``__pycache__``, or where
``NUMBA_CACHE_DIR`` points; a read-only install falls back to numba's per-user
cache). Compilation is what a fresh install's first run waits for, so the
kernels are written to compile fast (measured by ``benchmarks/first_run.py``):

* each kernel is a serial ``nogil`` loop over a range of rows,
  ``core(row0, row1, ...)``, and :func:`parallel_rows` runs the row ranges on
  threads. numba's ``parallel=True`` (``prange``) ran as fast but compiled
  every kernel about twice as slowly (it outlines the loop body and compiles
  it again as a "gufunc"). A row is computed by the same operations in the
  same order either way, so the results are bit for bit the same; the row
  cores use ``error_model="numpy"`` as ``prange`` bodies do (a division by
  zero gives inf or nan, not an exception);
* no array is assigned into an array slice: ``G[i] = np.dot(...)`` compiled
  numba's general broadcasting setitem, 5 s per call site; ``np.dot`` writes
  into its ``out`` argument instead;
* the wrappers pass each argument in one type (float64 and int64 contiguous
  arrays, int32 neighbour indices where they fit, Python scalars), so each
  kernel compiles once, whatever dtypes the caller used;
* arrays that travel together (a fit's pair geometry, the anchors' fits, a
  core's outputs or scratch space) are one tuple argument, unpacked on entry:
  no kernel takes more than 14 arguments.

Together they cut a fresh install's first run to about a third, at the same
run-time speed (docs/how_it_works.md, thresholds).

The first compilation in a process is announced once, before it starts, as an
INFO message on the ``heatcurv.kernels`` logger (:data:`COMPILE_NOTICE`):
silent unless the application configures logging. The ``heatcurv`` command
shows it on stderr, a terminal or not, unless ``--quiet``.
"""

try:
    import numba
    from numba.core import event as _numba_event
except ImportError as exc:  # also raised by a numba too old or too new for the installed numpy
    raise ImportError(
        "heatcurv requires numba: its per-pair loops are compiled numba kernels and there is no "
        f"numpy fallback. Install a numba that supports this Python and numpy (pip install numba). ({exc})"
    ) from exc

import logging
import os
import queue
import threading

import numpy as np

__all__ = [
    "COMPILE_NOTICE",
    "COMPILE_SECONDS",
    "LOGGER_NAME",
    "ROW_CORE",
    "as_floats",
    "as_indices",
    "as_pointers",
    "parallel_items",
    "parallel_rows",
    "SPLIT_ROWS",
]

#: The logger the compile notice goes to (a child of ``heatcurv``).
LOGGER_NAME = "heatcurv.kernels"
#: What compiling the clean path's kernels takes on the 2-core machine of ``benchmarks/first_run.py``.
COMPILE_SECONDS = 15
#: ... and the noisy path's on top (the anchors' fit and carry), on the same machine (docs/speed.md).
NOISY_COMPILE_SECONDS = 17
#: The notice, logged once per process when the first kernel starts compiling.
COMPILE_NOTICE = (
    f"compiling the numba kernels for this machine (first run only, about {COMPILE_SECONDS} s, "
    f"{NOISY_COMPILE_SECONDS} s more for a first noisy cloud; later runs load them from numba's cache)"
)

_logger = logging.getLogger(LOGGER_NAME)


class _CompileNotice(_numba_event.Listener):
    """Log :data:`COMPILE_NOTICE` when numba starts compiling one of these kernels, once per process.

    numba broadcasts ``numba:compile`` only for real compilations: a kernel
    loaded from the cache sends none, so a warm cache stays silent.
    """

    def __init__(self):
        self.told = False
        self._lock = threading.Lock()

    def on_start(self, event):
        if self.told:
            return
        dispatcher = event.data.get("dispatcher") if isinstance(event.data, dict) else None
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        if not module.startswith(__name__):
            return
        with self._lock:
            if self.told:
                return
            self.told = True
        _logger.info(COMPILE_NOTICE)

    def on_end(self, event):
        pass


_numba_event.register("numba:compile", _CompileNotice())

#: Options of the row cores: cached, run on threads, float errors as inf/nan (as numba's ``prange`` bodies were).
ROW_CORE = dict(cache=True, nogil=True, error_model="numpy")
#: Fewest rows a thread gets (smaller calls run on the calling thread alone).
MIN_ROWS_PER_CHUNK = 512
#: Chunks per thread: threads that finish early take more, evening out rows of different cost.
CHUNKS_PER_THREAD = 4
#: Fewest rows :func:`parallel_rows` splits over threads (two chunks); a smaller call runs on its caller alone.
SPLIT_ROWS = 2 * MIN_ROWS_PER_CHUNK


def parallel_rows(core, n: int, *args) -> None:
    """Run ``core(row0, row1, *args)`` over the rows ``0 <= i < n`` on numba's thread count.

    ``core`` is a ``nogil`` kernel that computes rows ``row0`` to ``row1 - 1``
    and writes them into its output arguments. The rows are cut into chunks
    that the calling thread and up to ``numba.get_num_threads() - 1`` helper
    threads take in turn; :func:`heatcurv.backend.threads` sets that count
    (numba's thread count of the calling thread, ``NUMBA_NUM_THREADS`` by
    default). The helpers are daemon threads started once per process and
    shared by all callers; the calling thread works too, so a call finishes
    even when every helper is busy with another call. An exception in a chunk
    is raised here once the chunks already started have finished.
    """
    n = int(n)
    if not getattr(core, "signatures", True):  # (a plain function under NUMBA_DISABLE_JIT=1)
        # compile (or load from the cache) on the calling thread, where ctrl-C can stop it
        core(0, 0, *args)
    threads = numba.get_num_threads()
    chunks = min(threads * CHUNKS_PER_THREAD, n // MIN_ROWS_PER_CHUNK)
    if threads <= 1 or chunks <= 1:
        core(0, n, *args)
        return
    _run_with_helpers(_Job(core, args, [n * c // chunks for c in range(chunks + 1)]), min(threads, chunks) - 1)


def parallel_items(function, items: list) -> list:
    """``[function(item) for item in items]``, the items side by side on the threads of :func:`parallel_rows`.

    For work whose every item is too small for :func:`parallel_rows` to split
    (fewer than :data:`SPLIT_ROWS` rows): the items, not their rows, are
    shared among the calling thread and up to ``numba.get_num_threads() - 1``
    of the same helper threads, so one pool owns every worker thread of
    heatcurv. ``function`` should spend its time in ``nogil`` kernels. The
    first exception is raised here once the items already started have
    finished.
    """
    results = [None] * len(items)

    def core(first, stop):
        for i in range(first, stop):
            results[i] = function(items[i])

    threads = min(numba.get_num_threads(), len(items))
    if threads <= 1:
        core(0, len(items))
        return results
    _run_with_helpers(_Job(core, (), list(range(len(items) + 1))), threads - 1)
    return results


def _run_with_helpers(job, helpers: int) -> None:
    """Run ``job``'s chunks on this thread and ``helpers`` helper threads; raise its first error once they stop."""
    _helpers.ask(job, helpers)
    try:
        job.run()
        job.wait()
    finally:
        job.stop()  # after ctrl-C: the helpers take no further chunk
    if job.errors:
        raise job.errors[0]


class _Job:
    """The chunks of one :func:`parallel_rows` call, taken in turn by whichever threads run it."""

    def __init__(self, core, args, bounds):
        self.core, self.args, self.bounds = core, args, bounds
        self.chunks = len(bounds) - 1
        self.taken = self.done = 0
        self.stopped = False
        self.errors = []
        self.condition = threading.Condition(threading.Lock())

    def run(self) -> None:
        """Compute chunks until none is left."""
        while True:
            with self.condition:
                if self.stopped or self.taken >= self.chunks:
                    return
                c = self.taken
                self.taken += 1
            error = None
            try:
                self.core(self.bounds[c], self.bounds[c + 1], *self.args)
            except BaseException as exc:  # raised by the calling thread
                error = exc
            with self.condition:
                self.done += 1
                if error is not None:
                    self.errors.append(error)
                    self.stopped = True
                self.condition.notify_all()

    def wait(self) -> None:
        """Until every chunk taken so far is computed."""
        with self.condition:
            while self.done < self.taken:
                self.condition.wait()

    def stop(self) -> None:
        with self.condition:
            self.stopped = True


class _Helpers:
    """Daemon threads that run :class:`_Job` s from a queue; started when first needed, again after a fork."""

    def __init__(self):
        self.lock = threading.Lock()
        self.pid = None
        self.queue = None
        self.count = 0

    def ask(self, job: _Job, helpers: int) -> None:
        """Let ``helpers`` threads join ``job`` (those still busy join it later, or find it finished)."""
        with self.lock:
            if self.pid != os.getpid():  # first call, or a child process: its parent's threads are not here
                self.pid, self.queue, self.count = os.getpid(), queue.SimpleQueue(), 0
            while self.count < helpers:
                threading.Thread(target=self._serve, args=(self.queue,), name="heatcurv-kernels", daemon=True).start()
                self.count += 1
            for _ in range(helpers):
                self.queue.put(job)

    @staticmethod
    def _serve(jobs) -> None:
        while True:
            jobs.get().run()


_helpers = _Helpers()


def as_floats(a) -> np.ndarray:
    """``a`` as a C-contiguous float64 array (no copy if it is one)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def as_pointers(indptr) -> np.ndarray:
    """CSR row pointers as a C-contiguous int64 array."""
    return np.ascontiguousarray(indptr, dtype=np.int64)


def as_indices(indices, n_points: int) -> np.ndarray:
    """CSR neighbour indices as int32 when ``n_points`` fit, else int64.

    :mod:`heatcurv.geometry.neighbourhood` makes them so.

    One index type means one compilation of each kernel; callers that pass
    int64 indices of a small cloud pay a copy instead.
    """
    dtype = np.int32 if n_points < np.iinfo(np.int32).max else np.int64
    return np.ascontiguousarray(indices, dtype=dtype)
