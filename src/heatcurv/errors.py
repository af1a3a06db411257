"""The one exception family heatcurv raises for bad input."""

__all__ = ["HeatcurvError", "HeatcurvWarning"]


class HeatcurvError(ValueError):
    """Raised when the input cannot give a meaningful result.

    The message names the problem (non-finite coordinates, wrong shape, too few
    points, collinear or coincident points, ...) and, where it can, what to do.
    It subclasses :class:`ValueError`, so ``except ValueError`` also catches it.
    """


class HeatcurvWarning(UserWarning):
    """Issued when a result is computed but should not be trusted as it stands.

    For example: the paper's area system ``H A = 1`` did not converge. The
    affected points are also marked in ``result.reliable``.
    """
