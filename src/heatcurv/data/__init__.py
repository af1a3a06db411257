"""Example data shipped with heatcurv.

``bunny_scan_1839.ply``
    1839 vertices of a decimated range scan of the Stanford bunny (Stanford 3D
    Scanning Repository, via the npm package ``bunny`` 1.0.1; see
    ``README.md`` in this folder). ASCII PLY, float ``x y z``, no normals,
    about 10 length units across (y is up), median nearest-neighbour
    distance 0.28, a few holes and an open base: a small real scan, the
    example of ``heatcurv demo --bunny``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["BUNNY_ATTRIBUTION", "bunny_path", "load_bunny"]

#: File name of the bunny scan inside this package.
BUNNY_FILE = "bunny_scan_1839.ply"

#: The attribution line carried in the bunny file's PLY header.
BUNNY_ATTRIBUTION = (
    "Stanford bunny (Stanford 3D Scanning Repository), decimated scan vertices, "
    "via the npm package bunny 1.0.1"
)


def bunny_path() -> Path:
    """Path of the packaged Stanford bunny scan (``bunny_scan_1839.ply``).

    Returns
    -------
    pathlib.Path
        A file on disk. heatcurv is installed as plain files (no zipped
        installs), so this is the file inside the installed package.

    Raises
    ------
    FileNotFoundError
        If the installation is missing its package data.
    """
    path = Path(str(resources.files(__name__).joinpath(BUNNY_FILE)))
    if not path.is_file():
        raise FileNotFoundError(f"heatcurv's example data {BUNNY_FILE} is missing from {path.parent}")
    return path


def load_bunny():
    """Read the packaged bunny scan.

    Returns
    -------
    heatcurv.io.PointCloud
        1839 points, no normals.

    Examples
    --------
    >>> from heatcurv.data import load_bunny
    >>> len(load_bunny())
    1839
    """
    from ..io import read_points

    return read_points(bunny_path())
