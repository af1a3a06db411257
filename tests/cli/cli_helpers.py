"""Helpers shared by the command-line test modules (imported by name: pytest puts tests/cli on sys.path)."""

import contextlib
import io
import os
import subprocess
import sys

import numpy as np

from heatcurv._kernels import COMPILE_NOTICE
from heatcurv.cli import main

#: The line a process that compiles the numba kernels prints on stderr once (a cold numba cache: a fresh install).
NOTICE_LINE = f"heatcurv: {COMPILE_NOTICE}"

#: Scalar fields compute writes by default, in the written order.
WRITTEN = [
    "nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area", "reliable",
]


def run(*args, cwd=None):
    """``heatcurv ARGS`` run in this process by :func:`heatcurv.cli.main`, returned as :func:`subprocess.run` would.

    The command's own entry point, as a separate process would run it, but
    without starting Python and loading numpy, scipy and the compiled kernels
    again (1-3 s a command). stdout and stderr are decoded as ``text=True``
    decodes them (a lone ``\r`` of a progress bar becomes a new line).
    :func:`run_process` starts ``python -m heatcurv`` where the process is
    what is tested: the module entry point, signals, a cold numba cache.
    """
    argv = [str(arg) for arg in args]
    stdout, stderr = _captured_stream(), _captured_stream()
    previous = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            try:
                status = main(argv)
            except SystemExit as exc:  # what the interpreter would make of it
                status = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    finally:
        os.chdir(previous)
    return subprocess.CompletedProcess([sys.executable, "-m", "heatcurv", *argv], status, _text(stdout), _text(stderr))


def run_process(*args, cwd=None):
    """``python -m heatcurv ARGS`` in a new process, its output captured as text."""
    return subprocess.run(
        [sys.executable, "-m", "heatcurv", *map(str, args)], capture_output=True, text=True, timeout=180, cwd=cwd
    )


def _captured_stream():
    """A text stream over bytes, as a pipe is (it has ``.buffer``, it is not a terminal)."""
    return io.TextIOWrapper(io.BytesIO(), encoding="utf-8", write_through=True)


def _text(stream) -> str:
    stream.flush()
    return stream.buffer.getvalue().decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")


def stderr_lines(out) -> list:
    """The lines of a run's stderr but the compile notice, which only a cold numba cache prints."""
    return [line for line in out.stderr.splitlines() if line != NOTICE_LINE]


def assert_one_line_error(out, *, status=2):
    assert out.returncode == status, (out.returncode, out.stderr)
    lines = stderr_lines(out)
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("heatcurv: error: "), out.stderr
    assert "Traceback" not in out.stderr + out.stdout


def read_image(path):
    from matplotlib.image import imread

    return imread(path)


def distinct_colours(image) -> int:
    pixels = np.round(np.asarray(image)[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    return np.unique(pixels, axis=0).shape[0]
