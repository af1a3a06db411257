"""heatcurv: mesh-free differential geometry of point clouds with the heat kernel.

The main entry point is :func:`estimate`; the stages it chains are public
building blocks (see the module of each). The numerical core:

=====================  ======================================================
``options``            every option, declared once; the method presets
``validation``         checks, centring, duplicate merging
``spacing``            the distance parameter h (eqs 2.6, 2.7)
``neighbourhood``      ball neighbourhoods as CSR arrays; the block-size policy
``kernel``             heat-kernel weights, t = m h^2 (eq 2.8)
``areas``              per-point areas from H A = 1 (section 2.2) or density
``laplace_beltrami``   the Laplace-Beltrami matrix (eq 2.9)
``point_laplacian``    the default Laplacian: accurate on any sampling, with
                       eigenpairs and heat diffusion (:class:`PointCloudLaplacian`)
``operator``           the shared heat-kernel operator (the stages above)
``mean_curvature``     mean-curvature normal and mean curvature (eqs 2.10-2.12)
``normals``            PCA normals and their orientation
``principal``          the curvature-tensor fit (section 3, eq 3.1)
``chordfit``           the default's fit: chord curvatures with tilt and cubic terms
``scale``              the default's kernel width: noise estimate, Lepski's rule
``choices``            what a run decides once for the whole cloud (frame, widths)
``survey``             the kernel choice measured part by part (a tiled run)
``reliability``        the flags that compare a point with cloud-wide medians
``border``             border points of open surfaces
``estimator``          :func:`estimate`: the stages above as a named list
``results``            :class:`CurvatureResult`
``features``           sharp-feature detection from the mean curvature
``progress``           stage names, timing and progress reports
``backend``            numba threads (numba is required: one implementation per stage)
=====================  ======================================================

Around the core, which imports none of them:

=====================  ======================================================
``io``                 scan formats: PLY, LAS/LAZ, text, meshes, NumPy arrays
``tiles``              out-of-core and Dask runs: :func:`compute_file`
``cli``                the ``heatcurv`` command
``render``             pictures of a field
``surfaces``           analytic surfaces with exact values, samplers, simulated
                       scans, and error measures against those values (eqs 4.1, 5.1)
=====================  ======================================================

The test harness (the quadric baseline, the real-scan fetchers, the fuzz campaign)
lives in the repository's ``tests/support/`` and is not installed.
"""

from . import surfaces
from .errors import HeatcurvError, HeatcurvWarning
from .estimator import estimate
from .features import FeatureResult, sharp_features
from .operators.point_laplacian import PointCloudLaplacian, laplacian
from .options import METHODS, Options, ScaleTuning
from .results import CurvatureResult

__version__ = "0.1.0"


def compute_file(src, dst, **options):
    """Every curvature field of a point-cloud file of any size, in tiles: :func:`heatcurv.tiles.compute_file`.

    Imported on first use (the tiled machinery is not needed by :func:`estimate`).
    """
    from .tiles import compute_file as tiled

    return tiled(src, dst, **options)


#: The public API: the estimator and its result, the Laplacian and its precomputed form, sharp features,
#: out-of-core runs, the options and the errors; ``surfaces``, the analytic surfaces every example samples. Every
#: building block is imported from its own module
#: (``heatcurv.geometry.neighbourhood.ball_neighbourhood``, ``heatcurv.operators.operator.build_operator`` ...).
__all__ = [
    "CurvatureResult",
    "FeatureResult",
    "HeatcurvError",
    "HeatcurvWarning",
    "METHODS",
    "Options",
    "PointCloudLaplacian",
    "ScaleTuning",
    "compute_file",
    "estimate",
    "laplacian",
    "sharp_features",
    "surfaces",
]
