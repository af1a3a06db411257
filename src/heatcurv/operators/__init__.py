"""Operators of the heat kernel: weights, areas and the Laplace-Beltrami operator (paper section 2).

=====================  ======================================================
``kernel``             heat-kernel weights on the neighbour pairs (eqs 2.2-2.9)
``areas``              per-point areas from the kernel's unit mass (section 2.2)
``operator``           :class:`~heatcurv.operators.operator.HeatKernelOperator`:
                       neighbours, spacing, areas and weights as one object
``laplace_beltrami``   the paper's operator as a sparse matrix (eqs 2.4, 2.5, 2.9)
``point_laplacian``    the accurate operator of :func:`heatcurv.laplacian`
=====================  ======================================================
"""
