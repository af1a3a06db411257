"""Reliability: the points whose values cannot be vouched for, and why.

===============  ============================================================
``outliers``     stray points and islands no surface passes through
``border``       border points of open surfaces
``sheets``       balls holding both sides of a thin part
``reliability``  misfits against the whole cloud, the resolution check, the
                 rounding of the input
===============  ============================================================

Each module returns boolean masks; :mod:`heatcurv.estimator` combines them into
``CurvatureResult.reliable``. Imports :mod:`heatcurv.geometry` and :mod:`heatcurv.operators` only.
"""
