"""Outward orientation of closed objects with thin parts: CGAL's twelve models, their vertices as the cloud.

The truth is each mesh's outward vertex normals. A point is *wrong* when its
normal points into the object, *wrong and reliable* when it is also flagged
reliable: the silent error. ``benchmarks/orientation.py`` prints the same
numbers beside Open3D's, with noisy and half-sampled variants and the split by
thickness; docs/orientation.md has the table.
"""

import numpy as np
import pytest

import heatcurv
from support.scans import CGAL_MESHES, read_mesh

MODELS = sorted(name.removesuffix(".off") for name in CGAL_MESHES)


@pytest.fixture(scope="module")
def oriented(cgal_meshes):
    """Per model: (wrong, reliable, what info["orientation"] reported), over the used vertices."""
    out = {}
    for name in MODELS:
        mesh = read_mesh(cgal_meshes / f"{name}.off")
        used = mesh.used
        res = heatcurv.estimate(mesh.vertices[used])
        cosine = np.einsum("ij,ij->i", res.normals, mesh.outward_vertex_normals()[used])
        out[name] = (cosine < 0, res.reliable, res.info["orientation"], cosine < -0.5)
    return out


@pytest.mark.parametrize("name", MODELS)
def test_each_model(name, oriented, records):
    wrong, reliable, report, inward = oriented[name]
    # inward: within 60 degrees of the inward normal, the side turned over; the rest of the wrong ones are
    # axes more than 60 degrees off (coarse features), which the side cannot mend
    records.check(f"real_orientation/{name}", wrong=100 * wrong.mean(), wrong_reliable=100 * (wrong & reliable).mean(),
                  inward_reliable=100 * (inward & reliable).mean(), flagged=100 * (1 - reliable.mean()))
    if name != "elk":
        assert report.closed is True and not report.undecided
    else:  # the coarsest (1645 points, legs 2-3 spacings thick): closed or not cannot be told, so all is flagged
        assert report.closed is False and report.undecided and not reliable.any()


def test_what_the_winding_number_fixed(oriented):
    # measured at 83bead8, before the winding number (the spanning tree alone), over the 120,974 points:
    # 5.58 % inside out and 3.96 % inside out but reliable; each model: camel 10.38 %, elephant 14.52 %,
    # bull 10.02 %, cow 10.30 %, dino 14.40 % inside out and reliable
    wrong = np.concatenate([w for w, _, _, _ in oriented.values()])
    silent = np.concatenate([w & r for w, r, _, _ in oriented.values()])
    assert wrong.mean() < 0.04 and silent.mean() < 0.01  # today 3.66 % and 0.55 % (the elk: undecided, all flagged)
    for name, before in (("camel", 10.38), ("elephant", 14.52), ("bull", 10.02), ("cow", 10.30), ("dino", 14.40)):
        w, r, _, _ = oriented[name]
        assert 100 * (w & r).mean() < before / 2, name
    # nothing lost where the tree was right
    for name in ("bear", "diplodocus"):
        w, r, _, _ = oriented[name]
        assert w.mean() < 0.007 and (w & r).mean() < 0.0002, name  # before: 0.00 and 0.01 %
