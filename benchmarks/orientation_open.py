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
                   :func:`support.scans.fetch_pymeshlab_samples`;
                   truth: the range map's vertex normals (either sign);
``torus, top``     one scan of the torus (R = 1, r = 0.4; 20 000 rays) from
                   (0, 0, 5), and ``torus, side`` from (5, 0, 0)
                   (:meth:`heatcurv.surfaces.Surface.scan`); truth: outward.

Columns

``policy``            what ``info["orientation"]`` says was used (``mode``, and
                      for ``outward`` whether the winding number found the
                      cloud closed; ``up, own axis``: along the cloud's own
                      axis, its convex side or by the convention);
``vertical %``        of the 2000 sample centres' normals, those within 45
                      degrees of vertical, or of the cloud's own axis
                      (``info["orientation"].policy``; "up" needs 50 %);
``down %``            once the sample is consistently oriented, the share of
                      the flat centres' ``sum |n_z|`` facing down ("up"
                      needs at most 3 %);
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
``half off, reliable %``  the same among the points reliable in both runs
                      (``res.reliable``): the sides heatcurv stands behind;
``s``                 seconds of the whole cloud's call (numba compiled by
                      a warm-up).

The second table turns the LiDAR tile, the face, the torus (closed, 20 000
random points) and the bunny scan shipped with heatcurv (closed, 1839
points) into 8 random poses (``Rotation.random(random_state=i)``) and counts
the policies chosen and the worst ``mixed %``, ``half off %`` (separately over
the poses oriented up, along their own axis and outward; ``-`` where no pose
was), ``half off, axes %``
and ``half off, reliable %`` over the poses ("rotating an open cloud changes
nothing except where the convention is up").

Usage::

    python benchmarks/orientation_open.py            # about 4 minutes on the 2-core machine
    python benchmarks/orientation_open.py --markdown
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import heatcurv
from heatcurv import surfaces
from heatcurv.data import load_bunny

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # tests/support: the real scans
from machine import markdown_arguments, run_header, warm_up  # noqa: E402  (benchmarks/machine.py)

TURN = (30.0, 50.0, 20.0)


def lidar():
    tile = surfaces.lidar_tile(22000)
    keep = tile.labels != surfaces.VEGETATION
    return tile.points, tile.normals, keep, True


def face():
    from support.scans import fetch_pymeshlab_samples, read_mesh

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
    if report.policy is not None and report.policy.towards is not None:
        return "up, own axis (convex)" if report.policy.convex else "up, own axis (convention)"
    return report.mode


def closed_sample(points_of):
    def load():
        points = points_of()
        return points, None, np.zeros(len(points), bool), False

    return load


POSES = {
    "lidar": lidar, "face": face, "torus (closed)": closed_sample(
        lambda: surfaces.get("torus").sample(20000, "random", seed=1).points),
    "bunny scan (closed)": closed_sample(lambda: load_bunny().points),
}


def measure(name: str, load=None, rotation=None) -> dict:
    if load is None:
        load, turn = CLOUDS[name]
        rotation = Rotation.from_euler("xyz", TURN, degrees=True).as_matrix() if turn else None
    points, truth, keep, sided = load()
    if rotation is not None:
        points = (points - points.mean(axis=0)) @ rotation.T
        truth = None if truth is None else truth @ rotation.T
    tic = time.perf_counter()
    whole = heatcurv.estimate(points)
    seconds = time.perf_counter() - tic
    half = np.sort(np.random.default_rng(1).choice(len(points), len(points) // 2, replace=False))
    part = heatcurv.estimate(points[half])
    agree = np.einsum("ij,ij->i", whole.normals[keep], truth[keep]) > 0 if keep.any() else None
    cosine = np.einsum("ij,ij->i", whole.normals[half], part.normals)
    axes = np.abs(cosine) >= np.cos(np.radians(30.0))
    both = whole.reliable[half] & part.reliable
    policy = whole.info["orientation"].policy
    return {
        "cloud": name, "points": len(points), "policy": policy_of(whole),
        "vertical": 100 * policy.vertical, "down": 100 * policy.down,
        "mixed": None if agree is None else 100 * min(agree.mean(), 1 - agree.mean()),
        "wrong": 100 * (1 - agree.mean()) if sided else None,
        "half": 100 * np.mean(cosine < 0), "half_axes": 100 * np.mean(cosine[axes] < 0),
        "half_reliable": 100 * np.mean(cosine[both] < 0), "s": seconds,
    }


COLUMNS = ["cloud", "points", "policy", "vertical %", "down %", "mixed %", "wrong %", "half off %",
           "half off, axes %", "half off, reliable %", "s"]
POSE_COLUMNS = ["cloud", "poses", "up", "up, own axis", "outward (open)", "outward (closed)", "worst mixed %",
                "worst half off %, up / own axis / outward", "worst half off, axes %", "worst half off, reliable %"]


def cells(r: dict) -> list[str]:
    wrong = "-" if r["wrong"] is None else f"{r['wrong']:.2f}"
    return [r["cloud"], str(r["points"]), r["policy"], f"{r['vertical']:.0f}", f"{r['down']:.1f}",
            f"{r['mixed']:.2f}", wrong, f"{r['half']:.2f}", f"{r['half_axes']:.2f}", f"{r['half_reliable']:.2f}",
            f"{r['s']:.1f}"]


def pose_cells(name: str, results: list) -> list[str]:
    def group(r: dict) -> str:
        return "own axis" if r["policy"].startswith("up, own axis") else r["policy"].split(" ")[0]

    count = [sum(r["policy"] == "up" for r in results), sum(group(r) == "own axis" for r in results),
             *(sum(r["policy"] == p for r in results) for p in ("outward (open)", "outward (closed)"))]
    mixed = [r["mixed"] for r in results if r["mixed"] is not None]

    def worst_half(kind: str) -> str:
        half = [r["half"] for r in results if group(r) == kind]
        return f"{max(half):.2f}" if half else "-"

    return [name, str(len(results)), *map(str, count), f"{max(mixed):.2f}" if mixed else "-",
            " / ".join(worst_half(k) for k in ("up", "own axis", "outward")),
            f"{max(r['half_axes'] for r in results):.2f}", f"{max(r['half_reliable'] for r in results):.2f}"]


def show(header: list, rows: list, markdown: bool) -> None:
    if markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
        for r in rows:
            print("| " + " | ".join(r) + " |")
    else:
        widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(header)]
        print("  ".join(c.rjust(w) for c, w in zip(header, widths)))
        for r in rows:
            print("  ".join(c.rjust(w) for c, w in zip(r, widths)))
    print()


def main(argv=None) -> int:
    args = markdown_arguments(__doc__, argv)
    warm_up()
    start = time.perf_counter()
    rows = []
    for name in CLOUDS:
        rows.append(cells(measure(name)))
        print(f"  {name}: done", file=sys.stderr, flush=True)
    poses = []
    for name, load in POSES.items():
        results = [measure(name, load, Rotation.random(random_state=i).as_matrix()) for i in range(8)]
        poses.append(pose_cells(name, results))
        print(f"  {name} in 8 poses: done", file=sys.stderr, flush=True)
    print(run_header())
    show(COLUMNS, rows, args.markdown)
    show(POSE_COLUMNS, poses, args.markdown)
    print(f"wall time {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
