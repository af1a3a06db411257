"""Atomic file writes: a temporary file next to the target, moved over it when complete.

:func:`atomic_write` is what :func:`heatcurv.io.write_points` (and the image
writer of :mod:`heatcurv.render`) write through, so that a failure never
leaves a partial output and an existing file of the same name stays as it was.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


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
