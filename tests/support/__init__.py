"""Test support, not installed with heatcurv: the helpers the tests and the benchmarks share.

Importable as ``support`` from every test (pytest puts ``tests/``, the directory of
``conftest.py``, on ``sys.path``) and from the benchmarks, which put ``tests/`` on
``sys.path`` themselves. The error measures against exact values are not here: the
demo uses them, so they ship in :mod:`heatcurv.surfaces.accuracy`.

=====================  ======================================================
``baseline``           the classical k-NN quadric fit, for comparison, at
                       every point or at chosen centres only (``centres=``)
``scans``              the real-scan test set: pymeshlab's sample meshes,
                       fetched (never shipped), and a mesh reader giving
                       their areas, normals and components
``cgal``               CGAL's closed models, fetched from Debian's
                       ``libcgal-demo``
``_fetching``          the download-check-extract skeleton of both caches
``tiles``              a tiled output compared with an in-memory result
``mesh_laplacian``     the cotangent Laplacian of a torus mesh (the
                       reference spectrum of docs/laplacian.md)
``terminal``           run a command with stderr on a pseudo-terminal, as
                       in a user's shell (the compile notice's test, the
                       first-run benchmark)
``fuzz``, ``mutators``  the fuzz campaign of the readers and the mutators
                       that break a file's bytes; replay one case from the
                       repository's root with ``PYTHONPATH=tests python -m
                       support.fuzz VARIANT MUTATOR SEED``
``child``              the child process that runs a call under memory and
                       time limits
``view_page``          read back the data block of a ``heatcurv view`` page
``browser``            headless Chromium driven over the DevTools protocol
                       on a pipe: wait for a page, evaluate JavaScript, send
                       mouse input, take screenshots (the viewer's tests)
``scenes``             clouds of several objects apart (terrain beside a
                       closed or an open object), for the orientation tests
``solids``             a cube of exact planes and a UV sphere's vertices (a
                       symmetric cloud), for the tests and the invariance
                       benchmark
=====================  ======================================================
"""
