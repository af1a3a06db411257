"""Small vectorised helpers and argument checks shared by the surface modules.

Private to :mod:`heatcurv.surfaces`.  Every array helper works on ``(n, 3)``
float64 arrays row by row; the checks raise :class:`~heatcurv.errors.HeatcurvError`
with a message naming the argument.
"""

from __future__ import annotations

import functools
import math
from numbers import Integral, Real

import numpy as np

from heatcurv.errors import HeatcurvError

_TWO_PI = 2.0 * math.pi


def _as_uv(u, v) -> tuple[np.ndarray, np.ndarray]:
    """Return ``u`` and ``v`` as equally long, finite, 1-D float64 arrays."""
    try:
        u = np.asarray(u, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise HeatcurvError(f"u and v must be numeric arrays: {exc}") from exc
    try:
        u, v = np.broadcast_arrays(u, v)
    except ValueError:
        raise HeatcurvError(
            f"u and v must have the same length, got shapes {u.shape} and {v.shape}"
        ) from None
    u = np.ascontiguousarray(u.reshape(-1))
    v = np.ascontiguousarray(v.reshape(-1))
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(v))):
        raise HeatcurvError("u and v must be finite (found NaN or inf)")
    return u, v


def _vec(n: int, x, y, z) -> np.ndarray:
    """Stack three broadcastable components into an ``(n, 3)`` float64 array."""
    out = np.empty((n, 3), dtype=np.float64)
    out[:, 0] = x
    out[:, 1] = y
    out[:, 2] = z
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.linalg.norm(a, axis=1)[:, None]


def _positive(name: str, value) -> float:
    """Validate a finite, strictly positive real parameter."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise HeatcurvError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise HeatcurvError(f"{name} must be finite and > 0, got {value!r}")
    return value


def _finite(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise HeatcurvError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise HeatcurvError(f"{name} must be finite, got {value!r}")
    return value


def _check_n(n) -> int:
    """Validate a requested point count (an integer >= 4)."""
    if isinstance(n, bool) or not isinstance(n, Integral):
        raise HeatcurvError(f"n must be an integer, got {n!r}")
    n = int(n)
    if n < 4:
        raise HeatcurvError(f"n must be at least 4, got {n}")
    return n


def _wrap(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Wrap values periodically into ``[lo, hi)``."""
    period = hi - lo
    y = np.mod(x - lo, period)
    y = np.where(y >= period, 0.0, y)  # np.mod(-tiny, p) can round to p
    return lo + y


def _as_points(points, name: str = "points") -> np.ndarray:
    """Return ``points`` as a finite float64 array of shape (n, 3)."""
    try:
        p = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise HeatcurvError(f"{name} must be a numeric array of shape (n, 3): {exc}") from exc
    if p.ndim == 1 and p.shape[0] == 3:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 3:
        raise HeatcurvError(f"{name} must have shape (n, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise HeatcurvError(f"{name} must be finite (found NaN or inf)")
    return p


def _longitude(p: np.ndarray) -> np.ndarray:
    """Angle of the points ``p`` (shape (n, 3)) about the z axis, in ``[0, 2 pi)``."""
    return _wrap(np.arctan2(p[:, 1], p[:, 0]), 0.0, _TWO_PI)


def _radial(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit vectors ``(cos v cos u, cos v sin u, sin v)``, shape (n, 3)."""
    cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
    return _vec(u.size, cv * cu, cv * su, sv)


def _east(u: np.ndarray) -> np.ndarray:
    """Unit vectors ``(-sin u, cos u, 0)`` along the parallels, shape (n, 3)."""
    return _vec(u.size, -np.sin(u), np.cos(u), 0.0)


def _cached_in(attr: str):
    """Decorator: keep the result of an argument-less method in ``self.<attr>``.

    The value is computed on the first call (or whenever the attribute is
    missing or None) and returned from the attribute afterwards.
    """

    def decorate(method):
        @functools.wraps(method)
        def cached(self):
            value = getattr(self, attr, None)
            if value is None:
                value = method(self)
                setattr(self, attr, value)
            return value

        return cached

    return decorate
