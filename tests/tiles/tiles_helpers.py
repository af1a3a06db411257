"""Helpers of the tiled-run tests (imported by name: pytest puts tests/tiles on sys.path)."""

#: Every field a tiled run writes (float64 so that the comparison sees the computation, not float32).
ALL_FIELDS = ("nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area",
              "reliable", "border", "outlier", "spacing", "neighbours", "fit_radius")


def exact(agreement):
    """Per field of a ``tiled_agreement(..., rtol=0.0)`` report, (points that differ, largest relative difference)."""
    return {name: (a["bad"], a["worst"]) for name, a in agreement.items()}


def read_fields(path):
    """Every column of an output file, by name (x y z too)."""
    from heatcurv.io import read_points

    cloud = read_points(path)
    columns = {a: cloud.points[:, k] for k, a in enumerate("xyz")}
    if cloud.normals is not None:
        columns.update({a: cloud.normals[:, k] for k, a in enumerate(("nx", "ny", "nz"))})
    columns.update(cloud.fields)
    return columns
