"""Atomic file writes: a temporary file next to the target, moved over it when complete.

:func:`atomic_write` is what :func:`heatcurv.io.write_points` (and the image
writer of :mod:`heatcurv.render`) write through, so that a failure never
leaves a partial output and an existing file of the same name stays as it was.
:func:`check_writable` tells beforehand whether such a write can succeed, so
that a command fails before a long computation rather than after it.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..errors import HeatcurvError

__all__ = ["atomic_write", "check_writable"]


def _new_file_mode(path: Path) -> int:
    """Permissions for the output: the replaced file's, else ``0o666`` minus the umask."""
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        pass
    umask = None
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("Umask:"):
                    umask = int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    if umask is None:
        umask = os.umask(0o022)
        os.umask(umask)
    return 0o666 & ~umask


def atomic_write(path: Path, write) -> None:
    """Call ``write(stream)`` on a temporary file next to ``path``, then move it over ``path``.

    On any exception the temporary file is removed and the exception re-raised.
    """
    temporary = tempfile.NamedTemporaryFile(
        mode="w+b", delete=False, dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix
    )
    try:
        with temporary as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary.name, _new_file_mode(path))
        os.replace(temporary.name, path)
    except BaseException:
        try:
            os.unlink(temporary.name)
        except FileNotFoundError:
            pass
        raise


def check_writable(path) -> Path:
    """Fail now, with one line, if :func:`atomic_write` could not write ``path``.

    Checks that ``path`` is not a directory, that its directory exists and is a
    directory, that an existing file there is not read-only (the atomic
    replacement would otherwise go through a file the user protected), and
    that a file can be created in the directory (a temporary file is created
    and removed: this also catches read-only file systems and, unlike
    permission bits, holds for root too).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    HeatcurvError
        ``cannot write PATH: <the problem>``.
    """
    path = Path(path)
    directory = path.parent

    def refuse(problem: str):
        return HeatcurvError(f"cannot write {path}: {problem}")

    if path.is_dir():
        raise refuse("it is a directory")
    if not directory.exists():
        raise refuse(f"the directory {directory} does not exist")
    if not directory.is_dir():
        raise refuse(f"{directory} is not a directory")
    if path.exists() and not os.access(path, os.W_OK):
        raise refuse("the file exists and is read-only")
    if not os.access(directory, os.W_OK | os.X_OK):
        raise refuse(f"no permission to create files in {directory}")
    try:
        probe = tempfile.NamedTemporaryFile(
            mode="w+b", dir=directory, prefix=f".{path.name}.", suffix=".probe"
        )
        probe.close()  # deletes it
    except OSError as exc:
        raise refuse(f"cannot create a file in {directory} ({exc.strerror or exc})") from None
    return path
