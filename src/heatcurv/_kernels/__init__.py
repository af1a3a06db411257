"""Compiled (numba) kernels of the hot stages: the one implementation of each per-pair loop.

Every loop over the CSR neighbour pairs that the estimator runs lives here as
a numba kernel, parallel over points, with no per-pair temporaries:

=============  ==============================================================
``segment``    PCA covariances and their eigenvectors, orientation costs,
               taper sums, tapered heat weights, mean-curvature-normal sums,
               centroid offsets (border flags)
``chordfit``   the chord fit's normal equations, residuals and Cholesky solve
=============  ==============================================================

The kernels take and return plain arrays and import nothing from the rest of
heatcurv: the stage modules (``areas``, ``border``, ``chordfit``, ``kernel``,
``mean_curvature``, ``normals``) import them, never the reverse. Their numpy
reference implementations live in the tests (``tests/reference/``), which
compare every kernel with its reference on the same inputs.

numba is required (see :mod:`heatcurv.backend`); without it importing heatcurv
fails here with an ImportError that says so.
"""

try:
    import numba  # noqa: F401
except ImportError as exc:  # also raised by a numba too old or too new for the installed numpy
    raise ImportError(
        "heatcurv requires numba: its per-pair loops are compiled numba kernels and there is no "
        f"numpy fallback. Install a numba that supports this Python and numpy (pip install numba). ({exc})"
    ) from exc
