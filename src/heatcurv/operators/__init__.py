"""Operators of the heat kernel: weights, areas, the Laplace-Beltrami operator, ``K = L x`` (paper section 2).

=====================  ======================================================
``kernel``             heat-kernel weights on the neighbour pairs (eqs 2.2-2.9)
``areas``              per-point areas from the kernel's unit mass (section 2.2)
``laplace_beltrami``   the paper's operator as a sparse matrix (eqs 2.4, 2.5, 2.9)
``mean_curvature``     the mean-curvature normal ``K = L x`` and its signed
                       length (eqs 2.10-2.12)
``operator``           :class:`~heatcurv.operators.operator.HeatKernelOperator`:
                       neighbours, spacing, areas and weights as one object
``point_laplacian``    the accurate operator of :func:`heatcurv.laplacian`
``geodesic``           geodesic distance on it by the heat method
=====================  ======================================================

Imports only :mod:`heatcurv.geometry` of the core's subpackages.
"""
