""":func:`main`: parse the command line, run the command, turn every failure into one line and an exit status."""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import warnings
from contextlib import contextmanager

from .._kernels import LOGGER_NAME as KERNELS_LOGGER
from ..errors import HeatcurvError, HeatcurvWarning
from .console import EXIT_BAD_INPUT, EXIT_BUG, EXIT_INTERRUPTED, EXIT_OK, Log
from .parser import UsageError, build_parser, join_negative_values

__all__ = ["main", "EXIT_OK", "EXIT_BUG", "EXIT_BAD_INPUT", "EXIT_INTERRUPTED", "Terminated", "signals_as_interrupts"]

#: The signals that stop the command as Ctrl-C does (SIGHUP: the terminal closed), where the platform has them.
_STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived: unwinds like Ctrl-C (files being written are removed), exit 128 + signal."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum

    @property
    def name(self) -> str:
        try:
            return signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"


def _raise_terminated(signum, frame):
    raise Terminated(signum)


@contextmanager
def signals_as_interrupts():
    """In the block, SIGTERM and SIGHUP raise :class:`Terminated` (a KeyboardInterrupt), as Ctrl-C does.

    So ``kill`` (SIGTERM), a closed terminal (SIGHUP) and Ctrl-C all unwind
    through the ``finally`` and ``except`` blocks, and
    :func:`heatcurv.io.atomic.atomic_write` removes its temporary file. Only
    in the main thread (Python delivers signals there); the previous handlers
    are restored afterwards (the command may run inside a test or a program).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    try:
        for signum in _STOP_SIGNALS:
            previous[signum] = signal.signal(signum, _raise_terminated)
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)


def _warning_printer(show_all: bool, stream):
    """``warnings.showwarning`` printing one line ``heatcurv: warning: ...``."""

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, HeatcurvWarning) or show_all:
            text = " ".join(str(message).split())
            print(f"heatcurv: warning: {text}", file=stream, flush=True)

    return show


class _NoticeLine(logging.Handler):
    """A log record as one line ``heatcurv: ...`` on ``stream``, written around any progress bar there."""

    def __init__(self, stream):
        super().__init__(logging.INFO)
        self.stream = stream

    def emit(self, record):
        try:
            from tqdm import tqdm

            tqdm.write(f"heatcurv: {' '.join(record.getMessage().split())}", file=self.stream)
        except Exception:
            self.handleError(record)


def notice_stream(quiet: bool, stderr):
    """Where the compile notice goes: stderr, terminal or not, unless ``--quiet``; None for nowhere.

    The first run's wait for the compiler is explained also when stderr is a
    pipe or a log file (a script, CI, ``2> log``): the notice is one line,
    printed once per process, and only when numba really compiles.
    """
    if quiet or stderr is None:
        return None
    return stderr


@contextmanager
def compile_notice(stream):
    """Show the compiled kernels' notice (logged once, when numba starts compiling them) on ``stream``.

    The library logs it at INFO on the ``heatcurv.kernels`` logger, which an
    application that does not configure logging never shows; the command
    prints it, so that the first run's wait for the compiler is explained.
    ``stream`` None shows nothing.
    """
    if stream is None:
        yield
        return
    logger = logging.getLogger(KERNELS_LOGGER)
    handler, level = _NoticeLine(stream), logger.level
    logger.addHandler(handler)
    if logger.getEffectiveLevel() > logging.INFO:
        logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line (its type's name if it has none)."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def main(argv=None) -> int:
    """Run the ``heatcurv`` command.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 success, 2 bad input or options, 1 unexpected error
        (a bug), 130 interrupted (Ctrl-C), 128 + the signal's number when
        terminated by SIGTERM (143) or SIGHUP (129): these unwind as Ctrl-C
        does, so no temporary file is left behind.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    try:
        args = build_parser().parse_args(join_negative_values(argv))
    except UsageError as exc:
        print(f"heatcurv: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else EXIT_OK
    debug = args.debug
    if args.quiet and args.verbose:
        print("heatcurv: error: --quiet and --verbose exclude each other", file=sys.stderr)
        return EXIT_BAD_INPUT
    log = Log(quiet=args.quiet, verbose=args.verbose)
    with signals_as_interrupts():
        return _run(args, log, debug)


def _run(args, log: Log, debug: bool) -> int:
    """Run the parsed command; every failure becomes one line on stderr and an exit status."""
    try:
        notices = notice_stream(args.quiet, sys.stderr)
        with warnings.catch_warnings(), compile_notice(notices):
            if not debug:
                warnings.showwarning = _warning_printer(args.verbose, sys.stderr)
            return args.run(args, log)
    except Terminated as exc:
        if debug:
            raise
        print(f"heatcurv: terminated by {exc.name}", file=sys.stderr)
        return 128 + exc.signum
    except HeatcurvError as exc:
        if debug:
            raise
        print(f"heatcurv: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        if debug:
            raise
        print("heatcurv: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. 'heatcurv info big.ply | head'
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return EXIT_OK
    except MemoryError:
        if debug:
            raise
        print("heatcurv: error: out of memory; try a smaller cloud, or fewer --workers", file=sys.stderr)
        return EXIT_BUG
    except Exception as exc:
        if debug:
            raise
        print(
            f"heatcurv: error: unexpected {type(exc).__name__}: {_one_line(exc)} "
            "(this is a bug in heatcurv; rerun with --debug to see the traceback, and please report it)",
            file=sys.stderr,
        )
        return EXIT_BUG
