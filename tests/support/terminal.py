"""Run a command with its stderr on a pseudo-terminal, as in a user's shell.

The command line prints some messages (the one-time compile notice) only when
stderr is a terminal; the test of that notice and ``benchmarks/first_run.py``
both need to see what a user sees.
"""

from __future__ import annotations

import os
import subprocess

__all__ = ["run_on_a_terminal"]


def run_on_a_terminal(command, env=None, cwd=None, timeout: float | None = None) -> tuple[int, str, str]:
    """Run ``command`` with stdout piped and stderr on a pseudo-terminal.

    Parameters
    ----------
    command : list of str
    env : dict, optional
    cwd : path, optional
    timeout : float, optional
        Seconds to wait for the exit once the terminal is closed.

    Returns
    -------
    status : int
    stdout, stderr : str
        Where the platform has no pseudo-terminals, stderr is a pipe.
    """
    if not hasattr(os, "openpty"):
        out = subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout)
        return out.returncode, out.stdout, out.stderr
    master, slave = os.openpty()
    process = subprocess.Popen(command, env=env, cwd=cwd, stdout=subprocess.PIPE, stderr=slave, text=True)
    os.close(slave)
    err = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        err += chunk
    out = process.stdout.read()
    status = process.wait(timeout=timeout)
    os.close(master)
    return status, out, err.decode(errors="replace")
