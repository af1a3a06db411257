"""Geometry primitives, no policy: the input's boundary, neighbourhoods, spacing and subsets.

=================  ==========================================================
``validation``     input checks, centring, merging duplicates
``neighbourhood``  ball and k-nearest neighbourhoods as flat CSR arrays
``spacing``        the inherent distance ``h`` of the heat kernel (section 2.1)
``sampling``       subsets drawn from the geometry, independent of row order
=================  ==========================================================

The lowest layer of the core: it imports no other subpackage.
"""
