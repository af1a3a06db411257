"""Geometry primitives: the input's boundary, neighbourhoods, spacing, subsets and PCA normals.

=================  ==========================================================
``validation``     input checks, centring, merging duplicates
``neighbourhood``  ball and k-nearest neighbourhoods as flat CSR arrays
``spacing``        the inherent distance ``h`` of the heat kernel (section 2.1)
``sampling``       subsets drawn from the geometry, independent of row order
``normals``        PCA normals of a neighbourhood (unoriented)
=================  ==========================================================

Nothing here knows about curvature; every other stage reads these arrays.
"""
