"""Which implementation of the per-pair loops runs: compiled (numba) or numpy.

The hot stages (PCA, areas, the mean-curvature normal, the chord fit, border
flags) loop over every neighbour pair. With numba installed they run as
compiled kernels over the CSR arrays, in parallel over points; without it the
same arithmetic runs as vectorised numpy on blocks of pairs. Both give the
same numbers (tests compare them to 1e-9).

Choose with the environment variable ``HEATCURV_BACKEND`` (``auto``,
``numba`` or ``numpy``) or :func:`set_backend`; ``auto`` (the default) uses
numba when it imports.
"""

from __future__ import annotations

import os
from contextlib import contextmanager

from .errors import HeatcurvError

__all__ = ["numba_available", "use_numba", "set_backend", "get_backend", "backend", "threads"]

_CHOICES = ("auto", "numba", "numpy")
_state = {"backend": os.environ.get("HEATCURV_BACKEND", "auto").strip().lower() or "auto"}
_numba = {}


def numba_available() -> bool:
    """Whether numba imports (checked once)."""
    if "ok" not in _numba:
        try:
            import numba  # noqa: F401

            _numba["ok"] = True
        except Exception:  # ImportError, or a numba too old/new for this numpy
            _numba["ok"] = False
    return _numba["ok"]


def get_backend() -> str:
    """The requested backend: ``"auto"``, ``"numba"`` or ``"numpy"``."""
    name = _state["backend"]
    if name not in _CHOICES:
        raise HeatcurvError(f"HEATCURV_BACKEND must be one of {', '.join(_CHOICES)}, got {name!r}")
    return name


def set_backend(name: str) -> None:
    """Select ``"auto"``, ``"numba"`` or ``"numpy"`` for later calls."""
    name = str(name).strip().lower()
    if name not in _CHOICES:
        raise HeatcurvError(f"backend must be one of {', '.join(_CHOICES)}, got {name!r}")
    if name == "numba" and not numba_available():
        raise HeatcurvError("backend 'numba' requested but numba is not installed (pip install numba)")
    _state["backend"] = name


@contextmanager
def backend(name: str):
    """Context manager: run a block with another backend, then restore the previous one."""
    previous = _state["backend"]
    set_backend(name)
    try:
        yield
    finally:
        _state["backend"] = previous


def use_numba() -> bool:
    """Whether the compiled kernels run now."""
    name = get_backend()
    if name == "numpy":
        return False
    if name == "numba" and not numba_available():
        raise HeatcurvError("HEATCURV_BACKEND=numba but numba is not installed (pip install numba)")
    return numba_available()


@contextmanager
def threads(workers: int | None):
    """Run a block with ``workers`` compiled-kernel threads (-1 or None: all cores).

    The k-d tree queries take ``workers`` themselves; this sets numba's
    thread count to match and restores it afterwards.
    """
    if workers is None or int(workers) < 0 or not numba_available():
        yield
        return
    import numba

    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(workers), numba.config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        numba.set_num_threads(previous)
