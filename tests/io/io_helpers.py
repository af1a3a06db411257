"""Helpers shared by the io test modules (imported by name: pytest puts tests/io on sys.path)."""

import os

import numpy as np

from heatcurv import surfaces

N = 300


def make_cloud():
    """Torus points far from the origin (UTM-like), with normals, colours and result-like fields."""
    sample = surfaces.Torus().sample(N, "fibonacci")
    rng = np.random.default_rng(7)
    points = sample.points + np.array([512345.25, 5.4e6, 312.5])
    fields = {
        "mean": sample.mean,
        "gaussian": sample.gaussian,
        "k1": sample.k1,
        "k2": sample.k2,
        "d1": sample.d1,
        "d2": sample.d2,
        "area": rng.random(N),
        "reliable": rng.random(N) > 0.3,
        "count": rng.integers(-1000, 1000, N),
        "weight32": rng.random(N).astype(np.float32),
    }
    colors = rng.integers(0, 256, (N, 3)).astype(np.uint8)
    return points, sample.normals, colors, fields


def expanded(fields):
    """The scalar properties a fields dict is written as."""
    out = {}
    for name, values in fields.items():
        values = np.asarray(values)
        if values.ndim == 2:
            out.update({name + axis: values[:, k] for k, axis in enumerate("xyz")})
        else:
            out[name] = values
    return out


def leftovers(directory):
    """Every file in ``directory``, hidden ones too (temporaries are ``.NAME.heatcurv-HOST-PID-RANDOM.tmp``)."""
    return sorted(os.listdir(directory))
