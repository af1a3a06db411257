"""The same answer after a rigid motion or a change of unit: default options on moved copies of clouds.

A curvature estimate of a cloud must not depend on where the cloud lies, how it
is turned or in which unit it is written, except where a documented convention
reads the coordinates (``orient="auto"`` says "up" for terrain over the
horizontal plane, and a nearly flat open sheet gets a side by a convention on
its axis: such points are counted in ``info["orientation"].by_convention``).
Each cloud is estimated with the default options as given and in four moved
copies; every copy is compared with the cloud as given, point by point, after
mapping its normals back by the motion.

Copies

``turned a``, ``turned b``  ``Rotation.random(random_state=3 / 6)`` (scipy);
``utm``                     moved by (512 345, 4 123 456, 250), a UTM position
                            (float64 rounding of 2e-10 there);
``x1000``                   coordinates times 1000 (metres to millimetres).

Clouds (``heatcurv.surfaces``, random sampling unless said; noise = std over
the bounding-box diagonal)

``sphere 20k``, ``torus 20k``        clean, and with 0.8 % noise (strong: the
                                     anchors orient their own normals);
``paraboloid 20k 1 %``, ``saddle 20k 0.8 %``   open sheets under strong noise;
``fold 10k``                         two exact planes at 90 degrees
                                     (``FoldedSquare``);
``sphere 100:1``                     30 000 points of a unit sphere a hundred
                                     times denser above its equator;
``cube 24k``                         random points on the faces of the cube
                                     ``[-1, 1]^3`` (exact planes: every height in
                                     a face's plane is 0);
``sphere & torus apart``             a unit sphere (5000) and a torus scaled into
                                     the unit ball (8000), 64 diameters apart;
``spheres through each other``       two unit spheres of 8000 points one radius
                                     apart (surfaces passing through each other:
                                     their parts inside each other are flagged);
``UV sphere 128 x 62``               the vertices of a UV sphere: 62 rings of 128
                                     and the poles (a symmetric cloud: its keys
                                     come from positions, which a turn changes);
``lidar``                            :func:`heatcurv.surfaces.lidar_tile` (20 000).

Columns

``fit``          the fit of the cloud as given (``info["scale"].fit``); ``*``
                 where a copy took another;
``rel %``        reliable points of the cloud as given;
``rel moved %``  the largest share, over the copies, of points reliable in one
                 run and not in the other (the winding number's sources and
                 the sample centres are drawn by a rank of the coordinates, so
                 the flags near its thresholds move with the draw);
``side moved %`` the largest share of points whose normal points the other
                 way in a copy (after mapping back), less those counted by
                 convention in either run;
``conv %``       the largest share counted by convention (``by_convention``);
``H moved``      the largest relative change of the mean curvature over the
                 points reliable in both runs, ``|H' s - H| / max |H|`` (``s``
                 the scale; ``H'`` turned with the normal where the side was);
``wrong & rel %`` the largest share, over all five runs, of points whose normal
                 faces away from the surface's own (outward on closed
                 surfaces; on open ones the side the run chose for most points)
                 and that are reliable: a silently wrong sign.

The clouds were chosen where a sweep of such copies found heatcurv reading a
coordinate it should not (2026-12-07: an anchors' reference of +z under strong
noise, a noise gate that compared two float64 roundings, a down share counted
per point on a cloud of uneven density; a winding query on its own source where
a plane's heights are exactly 0, the winding field's widths taken from the box
of the whole cloud, sampling keys that took a symmetric cloud's rings whole);
see docs/robustness.md.

Usage::

    python benchmarks/invariance.py               # about 3 minutes on the 2-core machine
    python benchmarks/invariance.py --markdown
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import heatcurv
from heatcurv import surfaces

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # tests/support
from machine import markdown_arguments, run_header, table, warm_up  # noqa: E402  (benchmarks/machine.py)
from support.solids import cube_faces, uv_sphere  # noqa: E402

UTM = np.array([512345.0, 4123456.0, 250.0])


def _sample(name: str, n: int, noise: float = 0.0, seed: int = 3):
    def load():
        s = surfaces.get(name).sample(n, "random", noise=noise, seed=seed)
        return s.points, s.normals

    return load


def _fold():
    s = surfaces.FoldedSquare().sample(10_000, "random", seed=3)
    return s.points, s.normals


def _uneven_sphere():
    rng = np.random.default_rng(7)
    points = rng.normal(size=(200_000, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    points = points[(points[:, 2] > 0) | (rng.uniform(size=len(points)) < 0.01)][:30_000]
    return points, points.copy()


def _cube():
    return cube_faces(24_000)


def _uv_sphere():
    points = uv_sphere(62, 128)
    return points, points.copy()


def _apart():
    sphere = surfaces.get("sphere").sample(5000, "random", seed=1)
    torus = surfaces.get("torus").sample(8000, "random", seed=2)
    return (np.vstack([sphere.points, torus.points / 3.37 + [130.0, 0.0, 0.0]]),
            np.vstack([sphere.normals, torus.normals]))


def _through():
    first = surfaces.get("sphere").sample(8000, "random", seed=1)
    second = surfaces.get("sphere").sample(8000, "random", seed=2)
    return np.vstack([first.points, second.points + [1.0, 0.0, 0.0]]), np.vstack([first.normals, second.normals])


def _lidar():
    tile = surfaces.lidar_tile(20000)
    return tile.points, tile.normals


CLOUDS = {
    "sphere 20k": _sample("sphere", 20000), "sphere 20k 0.8 %": _sample("sphere", 20000, 0.008),
    "torus 20k": _sample("torus", 20000), "torus 20k 0.8 %": _sample("torus", 20000, 0.008),
    "paraboloid 20k 1 %": _sample("paraboloid", 20000, 0.01), "saddle 20k 0.8 %": _sample("saddle", 20000, 0.008),
    "fold 10k": _fold, "sphere 100:1": _uneven_sphere, "cube 24k": _cube, "sphere & torus apart": _apart,
    "spheres through each other": _through, "UV sphere 128 x 62": _uv_sphere,
    "lidar": _lidar,
}

COPIES = {
    "turned a": (Rotation.random(random_state=3).as_matrix(), np.zeros(3), 1.0),
    "turned b": (Rotation.random(random_state=6).as_matrix(), np.zeros(3), 1.0),
    "utm": (np.eye(3), UTM, 1.0),
    "x1000": (np.eye(3), np.zeros(3), 1000.0),
}

COLUMNS = ["cloud", "fit", "rel %", "rel moved %", "side moved %", "conv %", "H moved", "wrong & rel %"]


def _wrong_and_reliable(res, truth: np.ndarray) -> float:
    """Share of points reliable and facing away from ``truth`` (flipped as a whole to the run's majority)."""
    cosine = np.einsum("ij,ij->i", res.normals, truth)
    if np.mean(cosine > 0) < 0.5:
        cosine = -cosine
    return float(np.mean((cosine < 0) & res.reliable))


def measure(load) -> list:
    points, truth = load()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", heatcurv.HeatcurvWarning)
        base = heatcurv.estimate(points)
        runs = {}
        for name, (rotation, shift, scale) in COPIES.items():
            runs[name] = (heatcurv.estimate(scale * points @ rotation.T + shift), rotation, scale)
    n = len(points)
    fits, rel_moved, side_moved, conv, h_moved = set(), 0.0, 0.0, base.info["orientation"].by_convention / n, 0.0
    wrong = _wrong_and_reliable(base, truth)
    scale_h = float(np.max(np.abs(base.mean[base.reliable]))) if base.reliable.any() else 1.0
    for res, rotation, scale in runs.values():
        fits.add(res.info["scale"].fit)
        back = res.normals @ rotation  # the copy's normals in the cloud's frame
        conv_either = max(base.info["orientation"].by_convention, res.info["orientation"].by_convention)
        flipped = np.einsum("ij,ij->i", back, base.normals) < 0
        side_moved = max(side_moved, (int(flipped.sum()) - conv_either) / n if conv_either < n else 0.0)
        conv = max(conv, res.info["orientation"].by_convention / n)
        rel_moved = max(rel_moved, float(np.mean(res.reliable != base.reliable)))
        both = res.reliable & base.reliable
        if both.any():
            side = np.where(flipped, -1.0, 1.0)[both]  # a side turned by convention turns the sign of H with it
            h_moved = max(h_moved, float(np.max(np.abs(side * res.mean[both] * scale - base.mean[both]))) / scale_h)
        wrong = max(wrong, _wrong_and_reliable(res, truth @ rotation.T))
    fit = base.info["scale"].fit + ("" if fits <= {base.info["scale"].fit} else " *")
    return [fit, f"{100 * base.reliable.mean():.1f}", f"{100 * rel_moved:.2f}", f"{100 * max(side_moved, 0.0):.2f}",
            f"{100 * conv:.0f}", f"{h_moved:.1e}", f"{100 * wrong:.2f}"]


def main(argv=None) -> int:
    args = markdown_arguments(__doc__, argv)
    warm_up()
    start = time.perf_counter()
    rows = []
    for name, load in CLOUDS.items():
        rows.append([name, *measure(load)])
        print(f"  {name}: done", file=sys.stderr, flush=True)
    print(run_header())
    print(table("Moved, turned and rescaled copies", COLUMNS, rows, args.markdown))
    print(f"wall time {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
