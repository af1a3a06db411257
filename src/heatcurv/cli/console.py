"""Exit statuses and the messages the commands print on stdout."""

from __future__ import annotations

import sys

__all__ = ["EXIT_OK", "EXIT_BUG", "EXIT_BAD_INPUT", "EXIT_INTERRUPTED", "Log"]

EXIT_OK = 0
EXIT_BUG = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130


class Log:
    """Messages on stdout: ``info`` unless ``--quiet``, ``detail`` only with ``--verbose``.

    stderr holds only errors, warnings, the progress bar and the first run's
    compile notice, so a failed run leaves one line there (two on a cold
    numba cache).
    """

    def __init__(self, quiet: bool = False, verbose: bool = False, stream=None):
        self.quiet, self.verbose = quiet, verbose and not quiet
        self.stream = stream if stream is not None else sys.stdout

    def info(self, message: str) -> None:
        if not self.quiet:
            print(message, file=self.stream, flush=True)

    def detail(self, message: str) -> None:
        if self.verbose:
            print(message, file=self.stream, flush=True)
