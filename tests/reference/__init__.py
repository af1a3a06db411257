"""numpy reference implementations (oracles) of heatcurv's compiled kernels.

heatcurv runs one implementation per hot stage, the numba kernels of
:mod:`heatcurv._kernels`; the numpy code that used to run the same arithmetic
as a selectable backend lives here, for the tests only:

* :mod:`reference.segment` mirrors :mod:`heatcurv._kernels.segment` function by
  function, with the same arguments and returns, so a test calls both on the
  same arrays (``tests/test_kernels_segment.py``);
* :mod:`reference.chordfit` is the whole chord fit in numpy, with the
  signature of :func:`heatcurv.fits.chordfit.chord_fit`
  (``tests/test_kernels_chordfit.py``);
* :mod:`reference.lstsq` is the per-point weighted least squares on padded
  numpy blocks that the compiled fit's Cholesky solve is checked against.

Both are written from the formulas the kernels and the paper document and share
no code with what they check: they import from heatcurv only containers
(``ChordFit``, ``PrincipalCurvatures``) and the method's documented parameters
(thresholds, listed in each module's docstring), so a wrong formula in a helper
of heatcurv cannot hide by appearing on both sides of a comparison.

Import as ``from reference import segment``: pytest's default ``prepend``
import mode puts ``tests/`` (the directory of ``conftest.py`` and of the test
modules, which has no ``__init__.py``) on ``sys.path``, so this package is
importable from every test module under ``tests/``, subdirectories included.
"""
