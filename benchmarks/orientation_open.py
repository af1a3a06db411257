"""Open clouds without orientation options: the side ``orient="auto"`` picks, and whether a random half agrees.

Each cloud is run with the default options (``heatcurv.estimate(points)``),
then a random half of it (``numpy.random.default_rng(1)``, ``n // 2`` points
without replacement), and turned by 30, 50 and 20 degrees about x, y and z
(``scipy.spatial.transform.Rotation.from_euler("xyz", ...)``) where the row
says so.

Clouds

``lidar``          :func:`heatcurv.surfaces.lidar_tile` (22 000 points: terrain,
                   three buildings, trees; 3 cm noise); truth: its up normals
                   (walls out of their buildings), vegetation left out;
``face``           the pymeshlab range map ``rangemaps/face000.ply`` (a face
                   seen along +z; 62k vertices), fetched by
                   :func:`heatcurv.testing.scans.fetch_pymeshlab_samples`;
                   truth: the range map's vertex normals (either sign);
``torus, top``     one scan of the torus (R = 1, r = 0.4; 20 000 rays) from
                   (0, 0, 5), and ``torus, side`` from (5, 0, 0)
                   (:meth:`heatcurv.surfaces.Surface.scan`); truth: outward.

Columns

``policy``            what ``info["orientation"]`` says was used (``mode``, and
                      for ``outward`` whether the winding number found the
                      cloud closed);
``mixed %``           points on the smaller side against the truth, either
                      sign (one sheet in two minds);
``wrong %``           points facing away from the truth's side (lidar:
                      up and out of the buildings; torus: outward); ``-``
                      where the truth has no side;
``half off %``        points of the half whose normal points the other way
                      from the whole cloud's normal at the same point;
``half off, axes %``  the same among the points whose two normal *axes*
                      agree within 30 degrees (a tree crown's PCA axis moves
                      with the sample; its side is then undefined);
``s``                 seconds of the whole cloud's call (numba compiled by
                      a warm-up).

Usage::

    python benchmarks/orientation_open.py            # about a minute on the 2-core machine
    python benchmarks/orientation_open.py --markdown
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import heatcurv
from heatcurv import surfaces

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import commit, cpu_model, memory_text  # noqa: E402  (benchmarks/machine.py)

TURN = (30.0, 50.0, 20.0)


def lidar():
    tile = surfaces.lidar_tile(22000)
    keep = tile.labels != surfaces.VEGETATION
    return tile.points, tile.normals, keep, True


def face():
    from heatcurv.testing.scans import fetch_pymeshlab_samples, read_mesh

    mesh = read_mesh(fetch_pymeshlab_samples() / "rangemaps" / "face000.ply")
    return mesh.vertices[mesh.used], mesh.vertex_normals()[mesh.used], np.ones(int(mesh.used.sum()), bool), False


def torus_scan(viewpoint):
    def load():
        sample = surfaces.get("torus").scan(20000, viewpoints=[viewpoint], seed=0)
        return sample.points, sample.normals, np.ones(len(sample.points), bool), True

    return load


CLOUDS = {
    "lidar": (lidar, False), "lidar, turned": (lidar, True), "face": (face, False), "face, turned": (face, True),
    "torus, top": (torus_scan((0.0, 0.0, 5.0)), False), "torus, side": (torus_scan((5.0, 0.0, 0.0)), False),
}


def policy_of(res) -> str:
    report = res.info["orientation"]
    if report.mode == "outward":
        return "outward (closed)" if report.closed else "outward (open)"
    return report.mode


def measure(name: str) -> dict:
    load, turn = CLOUDS[name]
    points, truth, keep, sided = load()
    if turn:
        rotation = Rotation.from_euler("xyz", TURN, degrees=True).as_matrix()
        points, truth = (points - points.mean(axis=0)) @ rotation.T, truth @ rotation.T
    tic = time.perf_counter()
    whole = heatcurv.estimate(points)
    seconds = time.perf_counter() - tic
    half = np.sort(np.random.default_rng(1).choice(len(points), len(points) // 2, replace=False))
    part = heatcurv.estimate(points[half])
    agree = np.einsum("ij,ij->i", whole.normals[keep], truth[keep]) > 0
    cosine = np.einsum("ij,ij->i", whole.normals[half], part.normals)
    axes = np.abs(cosine) >= np.cos(np.radians(30.0))
    return {
        "cloud": name, "points": len(points), "policy": policy_of(whole),
        "mixed": 100 * min(agree.mean(), 1 - agree.mean()), "wrong": 100 * (1 - agree.mean()) if sided else None,
        "half": 100 * np.mean(cosine < 0), "half_axes": 100 * np.mean(cosine[axes] < 0), "s": seconds,
    }


COLUMNS = ["cloud", "points", "policy", "mixed %", "wrong %", "half off %", "half off, axes %", "s"]


def cells(r: dict) -> list[str]:
    wrong = "-" if r["wrong"] is None else f"{r['wrong']:.2f}"
    return [r["cloud"], str(r["points"]), r["policy"], f"{r['mixed']:.2f}", wrong, f"{r['half']:.2f}",
            f"{r['half_axes']:.2f}", f"{r['s']:.1f}"]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    args = parser.parse_args(argv)
    heatcurv.estimate(surfaces.get("sphere").sample(500, "fibonacci").points)  # compile the kernels first
    start = time.perf_counter()
    rows = []
    for name in CLOUDS:
        rows.append(cells(measure(name)))
        print(f"  {name}: done", file=sys.stderr, flush=True)
    print(f"date (UTC)   {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}")
    system = f"{platform.system()} {platform.release()}"
    print(f"machine      {cpu_model()}, {os.cpu_count()} cores{memory_text()}; {system}")
    print(f"python       {platform.python_version()}, numpy {np.__version__}")
    print(f"heatcurv     {heatcurv.__version__} (commit {commit()})\n")
    if args.markdown:
        print("| " + " | ".join(COLUMNS) + " |")
        print("|" + "---|" * len(COLUMNS))
        for r in rows:
            print("| " + " | ".join(r) + " |")
    else:
        widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(COLUMNS)]
        print("  ".join(c.rjust(w) for c, w in zip(COLUMNS, widths)))
        for r in rows:
            print("  ".join(c.rjust(w) for c, w in zip(r, widths)))
    print(f"\nwall time {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
