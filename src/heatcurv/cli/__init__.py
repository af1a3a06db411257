"""The ``heatcurv`` command line (``heatcurv ...`` or ``python -m heatcurv ...``).

Subcommands
-----------
``compute INPUT -o OUTPUT``
    Read a point cloud (PLY, LAS/LAZ, XYZ/TXT/CSV/PTS, OBJ, OFF, NPY/NPZ),
    run :func:`heatcurv.estimate` and write every field (``nx ny nz mean
    gaussian k1 k2 d1x d1y d1z d2x d2y d2z area reliable``, with
    ``--features`` also ``feature feature_score``) next to the input's own
    properties, in the format of OUTPUT's extension: computed values as
    float32 in PLY, LAS/LAZ and NPZ (``--float64`` keeps double precision),
    the input's properties in their own types, a PLY mesh's faces kept (a
    warning when the output format cannot hold them). OUTPUT is refused,
    before anything is read or computed, when it is the input file or cannot
    be written.
``render INPUT -o PICTURE``
    A picture of the cloud coloured by one field, read from INPUT if it holds
    it (a file written by ``compute``) or computed (:mod:`heatcurv.render`).
``features INPUT -o OUTPUT``
    Sharp-feature mask and score (:func:`heatcurv.sharp_features`).
``info INPUT``
    Point count, bounding box, spacing and the fields a file holds.
``view INPUT``
    An interactive 3-D view: one self-contained HTML page (WebGL) showing the
    cloud coloured by any of its fields (:mod:`heatcurv.view`), opened in the
    web browser when there is one.
``demo``
    The main job on a built-in example: an analytic surface (errors against
    the exact values and a picture), or with ``--bunny`` the Stanford bunny
    scan shipped with heatcurv.

Global options ``--quiet``, ``--verbose`` and ``--debug`` go before or after
the subcommand. Reports (what was read, computed and written; ``--verbose``:
stage timings and the kernel chosen) go to stdout; stderr holds only errors,
warnings and, when it is a terminal, a progress bar.

Exit status: 0 on success; 2 on bad input or options, with one line
``heatcurv: error: ...`` on stderr and no output file; 1 on an unexpected
error (a bug: one line, ``--debug`` shows the traceback); 130 when
interrupted (Ctrl-C); 143 when terminated (SIGTERM), 129 on SIGHUP, both
unwinding as Ctrl-C does, so that no temporary file is left behind.

Modules
-------
The data flow one way, from the helpers to the commands to :mod:`.main`:

=====================  ==========================================================
:mod:`.console`        exit statuses, the messages on stdout (:class:`~.console.Log`)
:mod:`.argtypes`       argparse types: numbers, points, ranges, picture sizes
:mod:`.fields`         the fields ``compute`` writes, and ``--fields`` shorthands
:mod:`.options`        the estimator's flags and the ``estimate`` keywords they give
:mod:`.progressbar`    the progress bar over the estimator's stages
:mod:`.steps`          read, estimate, detect features, write: shared by the commands
:mod:`.compute`        ``heatcurv compute``
:mod:`.features`       ``heatcurv features``
:mod:`.picture`        ``heatcurv render``
:mod:`.info`           ``heatcurv info``
:mod:`.view`           ``heatcurv view``
:mod:`.demo`           ``heatcurv demo``
:mod:`.parser`         the argument parser of every command
:mod:`.main`           :func:`main`: parse, run, turn errors into one line and a status
=====================  ==========================================================
"""

from __future__ import annotations

# also reachable here, as when the command line was one module (``X as X``: re-exported on purpose)
from .fields import COMPUTED_FIELDS as COMPUTED_FIELDS
from .fields import DEFAULT_FIELDS as DEFAULT_FIELDS
from .fields import EXTRA_FIELDS as EXTRA_FIELDS
from .fields import FEATURE_FIELDS as FEATURE_FIELDS
from .fields import FIELD_GROUPS as FIELD_GROUPS
from .info import describe_spacing as describe_spacing
from .main import main
from .parser import build_parser
from .progressbar import StageProgress as StageProgress

__all__ = ["main", "build_parser"]
