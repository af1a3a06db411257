"""Helpers shared by the command-line test modules (imported by name: pytest puts tests/cli on sys.path)."""

import subprocess
import sys

import numpy as np

from heatcurv._kernels import COMPILE_NOTICE

#: The line a process that compiles the numba kernels prints on stderr once (a cold numba cache: a fresh install).
NOTICE_LINE = f"heatcurv: {COMPILE_NOTICE}"

#: Scalar fields compute writes by default, in the written order.
WRITTEN = [
    "nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area", "reliable",
]


def run(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "heatcurv", *map(str, args)], capture_output=True, text=True, timeout=180, cwd=cwd
    )


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
