"""heatcurv._kernels: compiled once per machine, announced once, run on threads with the same results.

The first run of a fresh install waits for numba to compile the kernels
(``benchmarks/first_run.py`` measures it). These tests run Python in a
subprocess with ``NUMBA_CACHE_DIR`` pointing at an empty directory, so that
it compiles as a fresh install does, then again with that cache filled.
"""

import io
import json
import logging
import os
import subprocess
import sys
import threading

import numba
import numpy as np
import pytest

from heatcurv import backend
from heatcurv._kernels import COMPILE_NOTICE, LOGGER_NAME, chordfit, parallel_rows, segment
from heatcurv.cli.main import compile_notice, notice_stream
from support.terminal import run_on_a_terminal

NOTICE_LINE = f"heatcurv: {COMPILE_NOTICE}"


def run_python(code: str, cache_dir, *args):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    out = subprocess.run([sys.executable, *args, "-c", code] if code else [sys.executable, *args],
                         capture_output=True, text=True, timeout=600, env=env)
    assert out.returncode == 0, out.stderr
    return out


#: The kernels :func:`heatcurv._kernels.parallel_rows` runs.
ROW_CORES = {
    "_orientation_costs", "_tapered_heat_weights", "_taper_sums", "_weighted_covariances", "_kappa_normal_sums",
    "_centroid_offsets", "_smallest_eigenvectors", "_assemble_normal_equations", "_weighted_height_residual",
    "_assemble_full_model", "_residual_full_model", "_solve_normal_equations", "_neighbour_medians",
    "_counts_below", "_same_label_counts", "_orientation_conflicts", "_two_height_residuals",
    "_two_residuals_full_model", "_opposite_sheet_counts", "_flagged_within", "_quadric_residual_moments",
    "_over_under_counts", "_over_under_fill",
}
#: The chord fit's general cores, for fits without the tilt or the cubic terms: the estimator runs
#: the full model's cores only, so these compile only when such a fit is asked for.
OTHER_MODELS = {"_assemble_normal_equations", "_weighted_height_residual", "_two_height_residuals"}
#: Run only by the low-noise refit, for clouds in the very-low-noise band (heatcurv.fits.chordfit, low_noise=True).
LOW_NOISE = {"_two_residuals_full_model"}
#: Run only for the points the outliers' counts leave undecided (heatcurv.flags.outliers.exceeds_neighbour_median),
#: and by the tiles of a run oriented outward (heatcurv.flags.sheets.over_under_pairs).
SOMETIMES = {"_neighbour_medians", "_over_under_counts", "_over_under_fill"}


def test_row_cores_are_the_kernels_dispatchers():
    cores = {name for module in (segment, chordfit) for name, value in vars(module).items()
             if isinstance(value, numba.core.registry.CPUDispatcher) and value.targetoptions.get("nogil")}
    assert cores == ROW_CORES


LIBRARY_RUN = """
import json, logging
import numpy as np
notices = []
class Keep(logging.Handler):
    def emit(self, record):
        notices.append(record.getMessage())
logging.getLogger("heatcurv.kernels").addHandler(Keep())
logging.getLogger("heatcurv.kernels").setLevel(logging.INFO)
from heatcurv._kernels import segment as s
d, r = np.array([0.5, 0.2]), np.ones(2)
s.taper_sums(np.array([0, 1, 2]), d, r, 0.7)
s.taper_sums(np.array([0, 1, 2], dtype=np.int32), d.astype(np.float32), r, 0.7)  # converted, not compiled again
for index in (np.int64, np.int32):
    s.orientation_costs(np.eye(3)[:2], np.eye(3)[:2], np.array([0, 1, 2]), np.array([1, 0], dtype=index), d, r)
print(json.dumps(dict(
    notices=notices,
    signatures=[len(s._taper_sums.signatures), len(s._orientation_costs.signatures)],
    hits=sum(s._taper_sums.stats.cache_hits.values()) + sum(s._orientation_costs.stats.cache_hits.values()),
)))
"""


def test_library_logs_the_compile_notice_once_and_not_when_cached(tmp_path):
    first = json.loads(run_python(LIBRARY_RUN, tmp_path).stdout)
    assert first["notices"] == [COMPILE_NOTICE]  # two kernels compiled, one notice
    assert first["signatures"] == [1, 1]  # one compilation whatever the index and float dtypes
    assert first["hits"] == 0
    second = json.loads(run_python(LIBRARY_RUN, tmp_path).stdout)
    assert second["notices"] == [] and second["hits"] == 2 and second["signatures"] == [1, 1]


def test_library_notice_is_silent_unless_logging_is_configured(tmp_path):
    code = "import numpy as np\nfrom heatcurv._kernels import segment as s\n"
    code += "s.taper_sums(np.array([0, 1]), np.array([0.5]), np.ones(1), 0.7)\n"
    out = run_python(code, tmp_path)
    assert out.stdout == "" and out.stderr == ""


CLI_RUN = """
import json, sys
import numba
from heatcurv.cli import main
status = main(["demo", "-n", "1500", "--no-picture"])
from heatcurv._kernels import chordfit, segment
counts = {name: len(value.signatures) for module in (segment, chordfit) for name, value in vars(module).items()
          if isinstance(value, numba.core.registry.CPUDispatcher) and value.signatures}
print(json.dumps(dict(status=status, counts=counts)))
"""


def run_code_on_a_terminal(code: str, cache_dir):
    """Run ``code`` with stderr on a pseudo-terminal (as a user's shell has it); its stdout and stderr."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    status, out, err = run_on_a_terminal([sys.executable, "-c", code], env=env, timeout=600)
    assert status == 0, err
    return out, err.replace("\r\n", "\n")


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_command_says_once_that_it_compiles_and_compiles_each_kernel_once(tmp_path):
    """A fresh install's first ``heatcurv demo`` in a terminal: one line on stderr before the wait; none once cached."""
    out, err = run_code_on_a_terminal(CLI_RUN, tmp_path)
    assert err.splitlines().count(NOTICE_LINE) == 1, err
    report = json.loads(out.splitlines()[-1])
    assert report["status"] == 0
    # the demo (default and paper methods) runs every row core the estimator uses; each compiled for one signature
    assert set(report["counts"]) >= ROW_CORES - OTHER_MODELS - SOMETIMES - LOW_NOISE
    assert not set(report["counts"]) & OTHER_MODELS
    assert set(report["counts"].values()) == {1}, report["counts"]
    out, err = run_code_on_a_terminal(CLI_RUN, tmp_path)
    assert "heatcurv: compiling" not in err


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_command_prints_the_notice_on_stderr_terminal_or_not_unless_quiet():
    """A script's or CI's first run is told why it waits, as a terminal is; --quiet silences it."""
    terminal, pipe = Terminal(), io.StringIO()
    assert notice_stream(False, terminal) is terminal
    assert notice_stream(False, pipe) is pipe
    assert notice_stream(True, terminal) is None
    assert notice_stream(True, pipe) is None
    assert notice_stream(False, None) is None
    logger = logging.getLogger(LOGGER_NAME)
    level, handlers = logger.level, list(logger.handlers)
    with compile_notice(pipe):
        logger.info(COMPILE_NOTICE)
    with compile_notice(None):
        logger.info(COMPILE_NOTICE)
    assert pipe.getvalue() == NOTICE_LINE + "\n"
    assert logger.level == level and logger.handlers == handlers


#: The command line with ``info``'s work replaced by compiling two kernels (what any computing command does first).
COMPILING_COMMAND = """
import sys
import numpy as np
from heatcurv.cli import info, main
from heatcurv.data import bunny_path

def compiles(args, log):
    from heatcurv._kernels import segment as s
    d, r = np.array([0.5, 0.2]), np.ones(2)
    s.taper_sums(np.array([0, 1, 2]), d, r, 0.7)
    s.orientation_costs(np.eye(3)[:2], np.eye(3)[:2], np.array([0, 1, 2]), np.array([1, 0]), d, r)
    return 0

info.run = compiles
sys.exit(main(["info", str(bunny_path()), *sys.argv[1:]]))
"""


@pytest.mark.parametrize("quiet", [False, True])
def test_command_says_once_that_it_compiles_when_stderr_is_a_pipe(tmp_path, quiet):
    """Two kernels compiled with stderr a pipe (an empty numba cache): the notice once, and nothing with --quiet."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", COMPILING_COMMAND, *(["--quiet"] if quiet else [])],
                         capture_output=True, text=True, timeout=600, env=env)  # stderr: a pipe
    assert out.stdout == ""
    assert out.stderr == ("" if quiet else NOTICE_LINE + "\n")
    assert out.returncode == 0


@numba.njit(nogil=True)
def _row_numbers(lo, hi, out):
    for i in range(lo, hi):
        out[i] = i + 1


@numba.njit(nogil=True)
def _fails_at_row_1500(lo, hi, out):
    for i in range(lo, hi):
        if i == 1500:
            raise ValueError("row 1500")
        out[i] = i


@pytest.mark.parametrize("n", [0, 1, 511, 513, 1024, 5001, 100_003])
@pytest.mark.parametrize("workers", [1, 2, 3])
def test_parallel_rows_runs_every_row_once(n, workers):
    out = np.zeros(n, dtype=np.int64)
    with backend.threads(workers):
        parallel_rows(_row_numbers, n, out)
    assert np.array_equal(out, np.arange(1, n + 1))


def test_parallel_rows_from_several_threads_at_once():
    """Callers share the helper threads; each call still computes all of its rows."""
    outs = [np.zeros(20_000 + k, dtype=np.int64) for k in range(6)]

    def call(out):
        for _ in range(20):
            parallel_rows(_row_numbers, len(out), out)

    threads = [threading.Thread(target=call, args=(out,)) for out in outs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for out in outs:
        assert np.array_equal(out, np.arange(1, len(out) + 1))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_parallel_rows_in_a_forked_child():
    """A child process forked after the helpers started has none of them: it starts its own."""
    parallel_rows(_row_numbers, 10_000, np.zeros(10_000, dtype=np.int64))
    code = (
        "import json, multiprocessing as mp, os\n"
        "import numpy as np\n"
        "from test_kernels_cache import _row_numbers\n"
        "from heatcurv._kernels import _helpers, parallel_rows\n"
        "def child(q):\n"
        "    out = np.zeros(10_000, dtype=np.int64)\n"
        "    parallel_rows(_row_numbers, len(out), out)\n"
        "    q.put([int(out.sum()), _helpers.pid == os.getpid()])\n"
        "if __name__ == '__main__':\n"
        "    parallel_rows(_row_numbers, 10_000, np.zeros(10_000, dtype=np.int64))\n"
        "    ctx = mp.get_context('fork')\n"
        "    q = ctx.Queue()\n"
        "    p = ctx.Process(target=child, args=(q,))\n"
        "    p.start()\n"
        "    print(json.dumps(q.get(timeout=120)))\n"
        "    p.join()\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.dirname(__file__), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert out.returncode == 0, out.stderr
    total, own_helpers = json.loads(out.stdout)
    assert total == 10_000 * 10_001 // 2
    assert own_helpers or numba.config.NUMBA_NUM_THREADS == 1  # (one thread: no helpers at all)


def test_parallel_rows_raises_the_error_of_a_row():
    with pytest.raises(ValueError, match="row 1500"):
        parallel_rows(_fails_at_row_1500, 8000, np.zeros(8000))


def test_results_do_not_depend_on_the_thread_count(torus_cloud):
    """Each row is computed by the same operations whichever thread runs it: bit for bit the same."""
    pts, _, nb = torus_cloud
    normals, _ = segment.smallest_eigenvectors(
        segment.weighted_covariances(pts, nb.indptr, nb.indices, nb.distances, nb.radius, 0.7, True)
    )

    def everything():
        areas = np.full(len(pts), 1e-3)
        weights = segment.tapered_heat_weights(nb.indptr, nb.indices, nb.distances, nb.radius, 1 / nb.radius**2,
                                               areas, 0.7)
        return [
            segment.taper_sums(nb.indptr, nb.distances, nb.radius, 0.7),
            weights,
            segment.orientation_costs(pts, normals, nb.indptr, nb.indices, nb.distances, nb.radius),
            segment.kappa_normal_sums(pts, nb.indptr, nb.indices, nb.distances, 1 / nb.radius**2, weights, areas, True),
            segment.centroid_offsets(pts, pts, nb.indptr, nb.indices, nb.distances, nb.radius, normals, 0.7, True),
            *segment.smallest_eigenvectors(
                segment.weighted_covariances(pts, nb.indptr, nb.indices, nb.distances, nb.radius, 0.7, True)
            ),
        ]

    with backend.threads(1):
        one = everything()
    with backend.threads(3):
        several = everything()
    for a, b in zip(one, several):
        assert np.array_equal(a, b)
