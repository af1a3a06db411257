"""Atomic file writes: a temporary file next to the target, moved over it when complete.

:func:`atomic_write` is what :func:`heatcurv.io.write_points` (and the image
writer of :mod:`heatcurv.render`) write through, so that a failure never
leaves a partial output and an existing file of the same name stays as it was.
:func:`check_writable` tells beforehand whether such a write can succeed, so
that a command fails before a long computation rather than after it.

Temporary files
---------------
The temporary file of a write to ``dir/NAME`` is
``dir/.NAME.heatcurv-HOST-PID-RANDOM.tmp`` (:func:`temporary_name_pattern`):
hidden, and naming the host and the process that writes it. An exception
(also Ctrl-C, and SIGTERM/SIGHUP in the ``heatcurv`` command, which turns them
into one) removes it. A process killed outright (``kill -9``, power loss)
cannot, so each :func:`atomic_write` first removes the stale temporary files
of the same target in its directory (:func:`remove_stale_temporaries`):

* those of this host whose process no longer exists (``os.kill(pid, 0)``
  raises ProcessLookupError);
* those of another host (a shared network directory) last modified more
  than :data:`STALE_AFTER` seconds (a day) ago: their process cannot be asked;

and never a file of a live process (also another user's, or this process's
own), a file of another host modified within the day, or any file that does
not follow the pattern. A dead writer's pid reused by a new process keeps its
file until that process ends: the rule errs on the side of keeping.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import tempfile
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from ..errors import HeatcurvError

__all__ = ["atomic_write", "check_writable", "remove_stale_temporaries", "temporary_name_pattern", "STALE_AFTER"]

#: Seconds after which another host's temporary file counts as stale (its process cannot be asked).
STALE_AFTER = 24 * 3600.0

#: The signals held back while a temporary file is removed (a second Ctrl-C must not leave it behind).
_HELD_SIGNALS = {getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)}


def _host() -> str:
    """This host's name as it appears in temporary names: letters, digits, dots and dashes."""
    try:
        name = socket.gethostname()
    except OSError:
        name = ""
    return re.sub(r"[^A-Za-z0-9.-]", "_", name) or "localhost"


def _prefix(name: str) -> str:
    """The start of a temporary name of this process for target ``name``: ``.NAME.heatcurv-HOST-PID-``."""
    return f".{name}.heatcurv-{_host()}-{os.getpid()}-"


def temporary_name_pattern(name: str) -> re.Pattern:
    """The temporary names of writes to a file called ``name``; groups ``host`` and ``pid``."""
    return re.compile(rf"\.{re.escape(name)}\.heatcurv-(?P<host>[A-Za-z0-9._-]+)-(?P<pid>\d+)-[a-z0-9_]+\.tmp")


def _process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host (another user's counts: it may be writing)."""
    if pid <= 0:
        return True  # not a process id heatcurv writes: keep the file
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True
    return True


def remove_stale_temporaries(path) -> list[Path]:
    """Remove the stale temporary files of writes to ``path`` (see the module's rule); return them.

    Errors (a directory that cannot be listed, a file removed meanwhile) are
    ignored: this is housekeeping, never a reason for a write to fail.
    """
    path = Path(path)
    pattern, host, now = temporary_name_pattern(path.name), _host(), time.time()
    removed = []
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return removed
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match is None:
            continue
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            if match["host"] == host:
                stale = not _process_alive(int(match["pid"]))
            else:
                stale = now - entry.stat(follow_symlinks=False).st_mtime > STALE_AFTER
            if stale:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


@contextmanager
def stop_signals_noted():
    """Note which of Ctrl-C, SIGTERM and SIGHUP arrive in the block; each still runs its own handler.

    Yields a list that receives the numbers of the signals. A library that
    calls back into Python (lazrs writing a LAZ file) may swallow the
    exception a handler raises and report a failed write instead; after it,
    :func:`raise_noted_stop` raises the interruption again. Only in the main
    thread (Python runs handlers there); elsewhere nothing is noted.
    """
    arrived: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield arrived
        return
    previous = {}

    def note(signum, frame):
        arrived.append(signum)
        handler = previous.get(signum)
        if callable(handler):
            handler(signum, frame)
        elif handler == signal.SIG_DFL:
            signal.signal(signum, signal.SIG_DFL)  # the default action: end the process, as without this block
            signal.raise_signal(signum)

    try:
        for signum in _HELD_SIGNALS:
            previous[signum] = signal.signal(signum, note)
        yield arrived
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)


def raise_noted_stop(arrived: list) -> None:
    """Raise the interruption of the first signal noted by :func:`stop_signals_noted` again (nothing if none).

    The signal's handler of the time runs once more (Ctrl-C's raises
    KeyboardInterrupt; the ``heatcurv`` command's SIGTERM handler its own
    interruption); a handler that raises nothing leaves a KeyboardInterrupt.
    """
    if not arrived:
        return
    handler = signal.getsignal(arrived[0])
    if callable(handler):
        handler(arrived[0], None)
    raise KeyboardInterrupt


@contextmanager
def _signals_held():
    """Hold back Ctrl-C, SIGTERM and SIGHUP for the block (delivered after it), where the platform can."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        yield
        return
    previous = mask(signal.SIG_BLOCK, _HELD_SIGNALS)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, previous)


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

    On any exception (also KeyboardInterrupt) the temporary file is removed and
    the exception re-raised; ``path`` is then as it was. The temporary file is
    ``.NAME.heatcurv-HOST-PID-RANDOM.tmp`` in ``path``'s directory; stale ones
    of earlier writes to ``path`` are removed first (:func:`remove_stale_temporaries`).
    """
    path = Path(path)
    remove_stale_temporaries(path)
    temporary = tempfile.NamedTemporaryFile(
        mode="w+b", delete=False, dir=path.parent, prefix=_prefix(path.name), suffix=".tmp"
    )
    try:
        with temporary as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary.name, _new_file_mode(path))
        os.replace(temporary.name, path)
    except BaseException:
        with _signals_held():
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
