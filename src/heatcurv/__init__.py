"""heatcurv: mesh-free differential geometry of point clouds with the heat kernel."""

from .errors import HeatcurvError

__version__ = "0.1.0"
__all__ = ["HeatcurvError", "__version__"]
