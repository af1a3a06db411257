"""A long-lived child process that runs functions under a memory and a time limit.

:class:`Worker` starts ``python -c ...`` with pipes, sends it pickled
``(function, args, kwargs)`` calls and reads back a pickled :class:`Reply`:
the value or the exception (its class names, message, whether a MemoryError
is in its chain, the traceback), the call's time and the growth of its peak
resident memory. The child sets ``RLIMIT_AS`` (its size after the imports plus
``memory_limit``) and no core files; a call that outlives its timeout is a
``"hang"`` (the child is killed), a child that dies is a ``"crash"`` (the
signal and its last words on stderr: a Rust panic, ``Fatal Python error``),
and the next call starts a fresh child. The fuzz campaign
(:mod:`support.fuzz`) and the property tests of ``tests/fuzz`` use it.
"""

from __future__ import annotations

import os
import pickle
import re
import select
import signal
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["MEMORY_LIMIT", "PRELOAD", "Reply", "TIMEOUT", "Worker"]

#: Address space the worker may add to its size after its imports (bytes): ``RLIMIT_AS``.
MEMORY_LIMIT = 1536 * 2**20
#: Seconds one call may take.
TIMEOUT = 10.0


@dataclass
class Reply:
    """What happened to one call in the :class:`Worker`.

    Attributes
    ----------
    kind : {"value", "raised", "crash", "hang"}
    value : object
        The function's return value (``kind == "value"``).
    types : tuple of str
        ``module.qualname`` of the exception's class and its bases (``"raised"``).
    message : str
        ``str(exception)``; for a crash, how the child ended and the last line of its stderr.
    memory_error : bool
        A MemoryError anywhere in the exception's chain (``__cause__``/``__context__``).
    traceback : str
    seconds : float
    peak : int
        Growth of the child's peak resident memory during the call, bytes.
    """

    kind: str
    value: object = None
    types: tuple = ()
    message: str = ""
    memory_error: bool = False
    traceback: str = ""
    seconds: float = 0.0
    peak: int = 0


def _send(stream, obj) -> None:
    payload = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(struct.pack("<Q", len(payload)) + payload)
    stream.flush()


def _receive(stream):
    size = stream.read(8)
    if len(size) < 8:
        return None
    return pickle.loads(stream.read(struct.unpack("<Q", size)[0]))


def _status(key: str) -> int:
    """A ``Vm*`` line of /proc/self/status in bytes (0 where there is none)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _run_one(function, args, kwargs) -> Reply:
    import resource
    import traceback

    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")  # reset the peak resident set: getrusage then reports this call's peak
    except OSError:
        pass
    before = _status("VmRSS") or resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    start = time.perf_counter()
    try:
        reply = Reply("value", value=function(*args, **kwargs))
    except BaseException as exc:  # noqa: B036 -- everything the function raises is the result
        chain, seen = [], exc
        while seen is not None and len(chain) < 20:
            chain.append(seen)
            seen = seen.__cause__ or seen.__context__
        reply = Reply("raised", types=tuple(f"{c.__module__}.{c.__qualname__}" for c in type(exc).__mro__),
                      message=str(exc), memory_error=any(isinstance(c, MemoryError) for c in chain),
                      traceback="".join(traceback.format_exception(exc))[-4000:])
    reply.seconds = time.perf_counter() - start
    # VmHWM, which the reset above clears; getrusage's ru_maxrss also keeps the high-water mark of
    # threads that have exited since the process started (numba's, from the warm-up), so after such
    # a thread it reported the warm-up's peak for every case (a constant 67 MiB in a long pytest run)
    peak = _status("VmHWM") or resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    reply.peak = max(0, peak - before)
    return reply


def _worker_main() -> None:
    """The child's loop: read pickled ``(function, args, kwargs)`` on stdin, answer a pickled :class:`Reply`."""
    import faulthandler
    import importlib
    import resource
    import warnings

    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # stray prints of the code under test go to stderr, not into the replies
    faulthandler.enable()
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    stream = sys.stdin.buffer
    init = _receive(stream)
    sys.path[:] = init["sys_path"]
    warnings.simplefilter("ignore")
    for name in init["preload"]:
        importlib.import_module(name)
    if init["warmup"] is not None:
        init["warmup"]()
    limit = _status("VmSize") + init["memory_limit"]
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
    _send(out, {"limit": limit})
    while True:
        try:
            request = _receive(stream)
        except Exception as exc:  # an unpicklable request (a function the child cannot import)
            _send(out, Reply("raised", types=(f"{type(exc).__module__}.{type(exc).__qualname__}",),
                             message=f"the worker could not load the call: {exc}"))
            continue
        if request is None:
            return
        reply = _run_one(*request)
        try:
            _send(out, reply)
        except Exception as exc:
            _send(out, Reply("raised", types=("pickle.PicklingError",), message=f"unpicklable result: {exc}",
                             seconds=reply.seconds, peak=reply.peak))


#: Lines of a dead child's stderr that say why it died.
_LAST_WORDS = re.compile(r"memory allocation of|panicked at|Fatal Python error|Segmentation fault|Aborted|"
                         r"terminate called|Assertion")
#: Modules the worker imports before its memory limit is set.
PRELOAD = ("numpy", "heatcurv", "heatcurv.io", "plyfile", "laspy", "lazrs")


class Worker:
    """A long-lived child process that runs picklable functions under a memory and a time limit.

    Parameters
    ----------
    memory_limit : int, optional
        Bytes of address space the child may add to its size after
        ``preload`` and ``warmup`` (``RLIMIT_AS``); an allocation past it
        raises MemoryError in the child.
    warmup : callable, optional
        A picklable function the child runs once before the limit is set
        (compiling the numba kernels: :func:`warm_estimate`).
    preload : tuple of str, optional
        Modules the child imports before the limit is set.
    startup_timeout : float, optional
        Seconds the child may take to start (imports, warmup).

    Notes
    -----
    The child gets the parent's ``sys.path``, so it can import the functions
    of a test module by reference. A call that outlives its timeout kills
    the child (``"hang"``); a child that dies is a ``"crash"``; either way
    the next call starts a new child (counted in :attr:`restarts`). Use as a
    context manager or call :meth:`close`.
    """

    def __init__(self, memory_limit: int = MEMORY_LIMIT, *, warmup=None, preload=PRELOAD,
                 startup_timeout: float = 600.0):
        self.memory_limit, self.warmup, self.preload = memory_limit, warmup, tuple(preload)
        self.startup_timeout = startup_timeout
        self.starts = 0
        self._proc = None
        self._stderr = None

    @property
    def restarts(self) -> int:
        """How many times the child was started again after a crash or a hang (or :meth:`start`)."""
        return max(0, self.starts - 1)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def start(self) -> None:
        """Start (or restart) the child and wait until it is ready."""
        self.close()
        self.starts += 1
        # the directory this module's top-level package lives in (tests/ for support.child), so the child finds it
        package_root = str(Path(__file__).resolve().parents[len(__name__.split(".")) - 1])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([package_root, os.environ.get("PYTHONPATH", "")]))
        self._stderr = tempfile.TemporaryFile()
        self._proc = subprocess.Popen(
            [sys.executable, "-c", f"from {__name__} import _worker_main; _worker_main()"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr, env=env)
        _send(self._proc.stdin, {"sys_path": list(sys.path), "preload": self.preload, "warmup": self.warmup,
                                 "memory_limit": int(self.memory_limit)})
        ready = self._read(time.monotonic() + self.startup_timeout)
        if not isinstance(ready, dict):
            raise RuntimeError(f"the fuzz worker did not start: {self._stderr_tail()}")

    def close(self) -> None:
        """Stop the child (it exits at the end of its input; killed if it does not within 5 s)."""
        proc, self._proc = self._proc, None
        if proc is not None:
            try:
                proc.stdin.close()
                proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait()
            proc.stdout.close()
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None

    def _stderr_tail(self, since: int = 0) -> str:
        """The child's last words on stderr after offset ``since``: a Rust panic or allocation failure, a
        ``Fatal Python error``, else the last line."""
        if self._stderr is None:
            return ""
        end = self._stderr.seek(0, 2)
        self._stderr.seek(max(since, end - 65536))
        lines = [line.strip() for line in self._stderr.read().decode("utf-8", "replace").splitlines()]
        notable = [line for line in lines if _LAST_WORDS.search(line)]
        return (notable or [line for line in lines if line] or [""])[0][:300]

    def _read(self, deadline: float):
        """The next reply, or raise TimeoutError / EOFError."""
        fd = self._proc.stdout.fileno()
        chunks, need, size = [], 8, None
        while need:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise TimeoutError
            chunk = os.read(fd, min(need, 1 << 20))
            if not chunk:
                raise EOFError
            chunks.append(chunk)
            need -= len(chunk)
            if need == 0 and size is None:
                size = struct.unpack("<Q", b"".join(chunks))[0]
                chunks, need = [], size
        return pickle.loads(b"".join(chunks))

    def _ended(self, start: float, since: int) -> Reply:
        proc = self._proc
        try:
            code = proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = proc.wait()
        how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exited with status {code}"
        tail = self._stderr_tail(since)
        self.close()
        return Reply("crash", message=how + (f": {tail}" if tail else ""), seconds=time.monotonic() - start)

    def call(self, function, *args, timeout: float = TIMEOUT, **kwargs) -> Reply:
        """Run ``function(*args, **kwargs)`` in the child.

        Returns
        -------
        Reply
            ``"value"`` or ``"raised"`` with the time and peak memory of the
            call; ``"crash"`` if the child died; ``"hang"`` if it took longer
            than ``timeout`` seconds (the child is killed).
        """
        if self._proc is None or self._proc.poll() is not None:
            self.start()
        start, since = time.monotonic(), self._stderr.seek(0, 2)
        try:
            _send(self._proc.stdin, (function, args, kwargs))
            return self._read(start + timeout)
        except (BrokenPipeError, EOFError, ConnectionError):
            return self._ended(start, since)
        except TimeoutError:
            self._proc.kill()
            self.close()
            return Reply("hang", message=f"no answer within {timeout:g} s", seconds=time.monotonic() - start)
