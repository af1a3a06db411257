"""Deprecated: the error measures moved to :mod:`heatcurv.testing` (:mod:`heatcurv.testing.errors`).

Kept so that old scripts still run; importing it warns.  Use
``from heatcurv.testing import compare`` (etc.) instead.
"""

import warnings

warnings.warn("heatcurv.evaluation is deprecated; use heatcurv.testing", DeprecationWarning, stacklevel=2)

from .testing.errors import aligned_exact, compare, direction_error_deg, paper_error, relative_l1  # noqa: E402

__all__ = ["aligned_exact", "relative_l1", "paper_error", "direction_error_deg", "compare"]
