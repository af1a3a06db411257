"""Accuracy benchmark: heatcurv's estimators against the classical k-NN quadric fit.

Five tables (``--tables main noise lownoise mixed heldout``, default all, in
this order; ``--quick`` leaves out ``heldout`` unless named): the main table of
clean clouds, the noise table with a fixed-k quadric *oracle*, the
very-low-noise band, a cloud with mixed noise, and the held-out clouds.

Three estimators

* ``default`` -- ``heatcurv.estimate(points)``;
* ``paper``   -- ``heatcurv.estimate(points, method="paper")``;
* ``quadric`` -- :func:`support.baseline.quadric_curvature` with ``k = 40``
  (PCA normal, least-squares quadric, exact curvature of the quadric)

run on point clouds with exact ground truth (:mod:`heatcurv.surfaces`).

Main table

* surfaces: sphere (R = 1), ellipsoid (1, 0.8, 0.6), torus (r1 = 1, r2 = 2.3701)
  -- closed; paraboloid, saddle (a = 0.5 on [-1, 1]^2), cylinder (R = 1,
  H = 2) -- open;
* samplers: ``random`` (area-uniform), ``jittered`` (grid +-0.25 cell),
  ``scan`` (simulated 3-station scan: scan lines, overlaps, density fall-off,
  holes; see :meth:`heatcurv.surfaces.Surface.scan`);
* sizes n = 10000, 20000, 30000 (a scan gives exactly n; a jittered grid the
  nearest grid size);
* "any size and position": every case of the smallest size (all sizes with
  ``--transform-all``) is run a second time after a random rigid motion,
  scaled by 0.1, 1 or 100 (cycling over the cases, so the curvature radii of
  the copies span 0.1 to 237 units) and translated to coordinates of 1e6 to
  1e7.  The errors are scale-free, so the row shows the untransformed errors,
  the largest difference of any error column between the two runs (``dmax``,
  percentage points or degrees), and is judged on the *worse* of the two
  runs.

Noise table (issue 12, bullet 1).  Gaussian noise, standard deviation 0.12 %
and 0.6 % of the bounding-box diagonal (noise 0 is the row of the main
table), random sampler, on

* the six surfaces of the main table at n = 20000;
* issue 12's open patches at n = 30000: ``sinpatch``, the graph
  ``z = .25 sin(2x) sin(2y) + .1 x^2`` on [-1.5, 1.5]^2 (varying curvature of
  both signs), and ``saddle.4``, ``z = .4 (x^2 - y^2)`` on [-1, 1]^2;
* size rows: the torus at n = 100000 (``--noise-sizes N ...`` sets the sizes,
  ``--noise-sizes`` with no value drops them) and, with ``--big``, at
  1000000 points (several minutes per row).  The size rows run the default
  estimator and the oracle only (``paper`` and ``quadric`` up to 30000
  points).  ``--size-rows-only`` runs only the size rows.

Errors are measured at a fixed set of *evaluation points*: 3000
(``--eval-points``) interior points drawn with a seed of the case, the same
for every estimator whatever it does.  "Interior" here: no margin on closed
surfaces; on open ones farther than 10 % of the bounding-box diagonal from
the border (at least the main table's margin below), a fixed region, so the
evaluation points do not move as heatcurv's kernel changes.  (Before issue 12
the margin was heatcurv's widest ball; where that ball is wider than the
margin, heatcurv's values near the border are one-sided fits and count as
they are; the log prints the widest ball.)  heatcurv's estimators run on the
whole cloud and are read at the evaluation points.

The *oracle* is the classical quadric fit
(:func:`support.baseline.quadric_curvature`) at each fixed k of the ladder
60, 120, 240, 480, 960, 1920, 3840, capped at ``max(240, n / 10)``, evaluated
at the evaluation points only (``centres=``: each with its k nearest
neighbours in the whole cloud; the values equal those of a full evaluation at
those points), chosen *with hindsight* per cloud and per error column: each
error column of the ``oracle`` row is the smallest error over the ladder, and
the row ``(k)`` below it gives the k that achieved it, marked ``+`` when it
is the widest k tried (a wider fit might then do better: the oracle's error
is an upper bound of the best fixed-k error; ``--oracle-max-k K`` continues the
ladder by doubling, 7680, 15360, ..., up to K, still capped at n / 10, memory
~16 bytes x evaluation points x k).  ``t`` is the time of the whole ladder;
``target`` lists the ladder.  At 1M points with 0.6 % noise the best k is far
beyond 3840 (the fit's noise falls with the ball radius, which at 1M points
is small for k = 3840), so the default ladder gives a weak oracle there.  The ``oracle`` verdict of the
default row is PASS when its mean, k1, k2 and d1 errors are each at most the
oracle's (issue 12: "at least as accurate as the best fixed-k quadric fit
chosen with hindsight for that cloud, for the mean curvature, k1/k2 and
directions"); the columns it fails are listed.  A second verdict compares
with the single k best for the cloud as a whole (the smallest sum over mean,
k1, k2 and d1 of the error over that column's best): the issue's own table
quotes its oracle that way, one k per cloud; the per-column one is stricter.

Very-low-noise table (issue 12, bullet 3).  heatcurv default on sphere, torus
and saddle, n = 20000 random points, with noise 0, 1e-5, 3e-5 and 1e-4 of the
bounding-box diagonal (LAS rounding and the like) added to the *same* clean
points (one seed per surface).  Columns mean, k1, k2 and d1 errors (all
interior points, the noise table's margin), their ratios to the noise-0 row
(``x``), and a verdict: PASS when every ratio is at most 2 (issue 12: "within
2x of the clean error").  A ratio is ``n/a`` where the clean error is 0 or
``n/a``.  Note: heatcurv is exact on a clean sphere (errors ~1e-7 %), so no
estimator can stay within 2x of it under any noise; the row says so rather
than loosening the criterion.

Mixed-noise table (issue 12, bullet 2).  A torus of 40000 random points with
noise 0.05 % of the diagonal on the half x < 0 and 0.6 % on x > 0 (one set of
normal deviates, scaled per half), heatcurv default.  Per half: the errors of
its points (both halves in full: the points near x = 0 see both noise
levels); ``radius med``, the median per-point kernel ball radius when the
result has one (``result.fit_radius``), else ``n/a``; and, for reference, the
same half's mean error and median radius of heatcurv on the same clean points
with that half's noise everywhere (``uniform``): a per-point scale should
bring each half close to its uniform row.

Held-out table.  heatcurv's thresholds (noise gate, kernel ladder, Lepski
tau, low-noise band, ...) were tuned on the clouds of the other tables and of
the tests, so their errors flatter it.  ``HELDOUT`` is a fixed set of 16
clouds that differ from every tuned one in the surface's parameters
(ellipsoid 1 / 0.7 / 0.45, torus r1 = 1, r2 = 3, sphere of radius 2.5,
paraboloid a = 0.7 and saddle a = 0.25 on [-1.2, 1.2]^2, cylinder R = 0.6,
H = 2.5, and a Gaussian bump, :func:`bump_patch`), in size (7000, 15000,
50000) and in noise (0, 0.03 % and 0.3 % of the diagonal), with seeds
101-116 used nowhere else; it was fixed before any of its results was seen
and is not to be edited or tuned on.  It runs the default and the k = 40
quadric on every cloud and the paper's method on the clean ones (about 15 s
each).  Clean clouds are measured as in the main table (its margin, all
interior points, its targets); noisy ones as in the noise table (its margin,
scans at least the main table's margin from their holes, up to
``--eval-points`` evaluation points) against the mean-curvature target of the
smallest tuned noise level at or above theirs (0.03 %: 5 %, 0.3 %: 10 %).
``vs q40`` lists the columns among mean, k1, k2 and d1 where the default is
worse than the quadric; on noisy clouds the noise table's fixed-k oracle
(``run_oracle``) and its two verdicts (``oracle``) calibrate how hard the cloud
is.  About 3 minutes on the 2-core development machine (173 s beside other
jobs, load 7).

Error measures (on interior points; main table :func:`heatcurv.surfaces.accuracy.compare`,
the noise tables the same measures at their evaluation points)

``mean k1 k2 K``  relative L1 error ``mean|k - k*| / mean|k*|`` in %, after
                  aligning the exact values with the estimated orientation
                  (one global flip, :func:`heatcurv.surfaces.accuracy.aligned_exact`);
                  the noise tables, which compare estimators column by
                  column, turn each estimate into the exact orientation
                  instead (``k1`` is then always the exact ``k1``);
                  ``n/a`` where the exact field is 0 (cylinder: k2 and K);
``d1``            mean angle between estimated and exact principal direction
                  lines, degrees, non-umbilic interior points (``n/a`` on the
                  sphere, all umbilic);
``nrm``           mean normal angle, degrees;
``nrms_k1/k2``    noise table: PCPNet's normalised RMS error
                  ``sqrt(mean((|k - k*| / max(1, |k*|))^2))`` of k1 and k2
                  (aligned as above), a plain number.  It is not scale-free
                  (``max(1, |k*|)`` compares curvatures with 1 per unit
                  length): it is computed with the surfaces at their benchmark
                  size (unit sphere, torus r1 = 1, patches of half-width 1 and
                  1.5, ...);
``area``          ``|sum A_i / A* - 1|`` in %, closed surfaces with complete
                  samples only (scans have holes, open surfaces a border);
``orient``        % of normals on the aligned exact side (main table: all
                  points; noise table: the evaluation points);
``rel``           % of points the estimator marks reliable;
``NaN``           points with a NaN or inf in any output field;
``t``             wall time of the estimate call, seconds (``*``: it warned).

"Interior" in the main table means farther than a margin from the border of
open surfaces and from the holes of scans (``SurfaceSample.border_distance``).
The margin is the same for all estimators of a case: the 99th percentile over
the points of the distance to the 40th nearest neighbour (the quadric's
neighbourhood radius); heatcurv's own default margin (its largest ball) would
differ per estimator and explode on scans, whose sparse regions have large
spacings.

Targets (PASS/FAIL per row): mean <= 0.5 %, k1 and k2 <= 1 %, K <= 2 %,
d1 <= 0.5 deg, area <= 0.5 % (where measured), orientation >= 99.9 %, no NaN;
noise 0.12 %: mean <= 5 %, noise 0.6 %: mean <= 10 % (and no NaN); the oracle
and the low-noise verdicts above.  A ``n/a`` error is not judged.  The failed
criteria are listed.

Seeds are derived from the case (CRC-32 of its name), so every run draws the
same samples, motions, noise and evaluation points.

Usage::

    python benchmarks/accuracy.py --quick
    python benchmarks/accuracy.py --markdown tables.md --png docs/accuracy.png   # tables for docs/accuracy.md's end
    python benchmarks/accuracy.py --only quadric --sizes 10000
    python benchmarks/accuracy.py --tables noise lownoise mixed     # the noise tables only
    python benchmarks/accuracy.py --tables noise --noise-sizes      # no torus size rows
    python benchmarks/accuracy.py --tables noise --size-rows-only --big --noise-sizes   # the 1M rows alone
    python benchmarks/accuracy.py --tables heldout --markdown heldout.md   # the held-out clouds alone

``--quick`` runs small variants of every table: sphere, torus and saddle,
random and scan samplers, n = 5000; the noise table on the sphere, the
saddle and the sine patch at n = 4000 with 1000 evaluation points (oracle
ladder 60-240) and no size rows; the low-noise band on the saddle (n = 4000,
noise 0, 1e-5, 1e-4); the mixed torus at n = 8000: about 50 s at the time of
writing (up to ~80 s on a busy machine).

Run time.  By default only the 18 main-table cases of the smallest size get
a moved copy (with ``--transform-all`` every case, 1.7x the main table's
time); the main table then took 10-11 minutes on the 2-core development
machine before issue 12 (heatcurv's estimators are being reworked).  The
noise tables add about 10 minutes: per 20k-30k cloud three estimate calls
and the oracle ladder (6 quadric fits at 3000 points, ~8 s); the two 100k
torus rows; 12 low-noise and 3 mixed-noise calls.  ``--big`` adds the two
1M-point torus rows (heatcurv ~1.5 min each at the time of writing, the
oracle ~1 min).  The held-out table adds about 3 minutes.  The wall time is
printed at the end.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import os
import platform
import sys
import time
import warnings
import zlib
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import scipy

import heatcurv
from heatcurv import surfaces as hs
from heatcurv.surfaces.accuracy import aligned_exact, compare, direction_error_deg, neighbour_margin, relative_l1

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))  # tests/support
from machine import commit, cpu_model, memory_text, table  # noqa: E402  (benchmarks/machine.py)
from support.baseline import quadric_curvature  # noqa: E402

ESTIMATORS = {
    "default": lambda p: heatcurv.estimate(p),
    "paper": lambda p: heatcurv.estimate(p, method="paper"),
    "quadric": lambda p: quadric_curvature(p, k=40),
}
CLOSED = ("sphere", "ellipsoid", "torus")
OPEN = ("paraboloid", "saddle", "cylinder")
SURFACES = CLOSED + OPEN
SAMPLERS = ("random", "jittered", "scan")
SIZES = (10000, 20000, 30000)
SCALES = (0.1, 1.0, 100.0)
NOISE_N = 20000
NOISES = (0.0012, 0.006)
#: the tables, in the order they are printed (``--tables``)
TABLES = ("main", "noise", "lownoise", "mixed", "heldout")
#: the fixed-k quadric fits the oracle chooses from (capped at max(240, n / 10))
ORACLE_KS = (60, 120, 240, 480, 960, 1920, 3840)
#: evaluation points of the noise table (seeded from the case, interior)
EVAL_POINTS = 3000
#: interior margin of the noise tables on open surfaces, fraction of the bbox diagonal
EVAL_MARGIN = 0.1
#: the noise table's open patches of issue 12 (name -> n)
NOISE_EXTRA = (("sinpatch", 30000), ("saddle.4", 30000))
#: the torus size rows of the noise table (``--noise-sizes``; ``--big`` adds BIG_SIZE)
NOISE_SIZES = (100000,)
BIG_SIZE = 1000000
#: clouds up to this size also run the paper and quadric estimators in the noise table
NOISE_ALL_MAX = 30000
LOWNOISE_SURFACES = ("sphere", "torus", "saddle")
LOWNOISES = (0.0, 1e-5, 3e-5, 1e-4)
LOWNOISE_N = 20000
LOWNOISE_RATIO = 2.0
#: mixed-noise torus: n, noise on x < 0, noise on x > 0
MIXED_N = 40000
MIXED_NOISES = (0.0005, 0.006)
#: HELD OUT -- the "heldout" table's clouds.  No threshold of heatcurv was tuned on them: they differ from
#: every tuned cloud (the other tables, the tests) in the surface's parameters, in the size and in the noise,
#: and their seeds are used nowhere else.  The set was fixed before any of its results was seen.  Do not edit
#: it, and do not tune on it: judge a change of the estimator on it as it stands (a new held-out set is a new
#: constant and a new table).  Each cloud: (surface, constructor parameters, sampler, n, noise as a fraction
#: of the bounding-box diagonal, seed); "bump" is :func:`bump_patch` (height, width, size).
HELDOUT = (
    ("sphere", (("radius", 2.5),), "random", 7000, 0.0, 101),
    ("sphere", (("radius", 2.5),), "scan", 15000, 3e-4, 102),
    ("ellipsoid", (("a", 1.0), ("b", 0.7), ("c", 0.45)), "random", 15000, 0.0, 103),
    ("ellipsoid", (("a", 1.0), ("b", 0.7), ("c", 0.45)), "random", 15000, 3e-3, 104),
    ("torus", (("r1", 1.0), ("r2", 3.0)), "jittered", 15000, 0.0, 105),
    ("torus", (("r1", 1.0), ("r2", 3.0)), "random", 50000, 3e-4, 106),
    ("torus", (("r1", 1.0), ("r2", 3.0)), "random", 7000, 3e-3, 107),
    ("paraboloid", (("a", 0.7), ("size", 1.2)), "random", 15000, 0.0, 108),
    ("paraboloid", (("a", 0.7), ("size", 1.2)), "random", 15000, 3e-3, 109),
    ("saddle", (("a", 0.25), ("size", 1.2)), "jittered", 7000, 0.0, 110),
    ("saddle", (("a", 0.25), ("size", 1.2)), "random", 50000, 3e-4, 111),
    ("cylinder", (("radius", 0.6), ("height", 2.5)), "scan", 15000, 0.0, 112),
    ("cylinder", (("radius", 0.6), ("height", 2.5)), "random", 15000, 3e-3, 113),
    ("bump", (("height", 0.5), ("width", 0.6), ("size", 1.5)), "random", 15000, 0.0, 114),
    ("bump", (("height", 0.5), ("width", 0.6), ("size", 1.5)), "random", 15000, 3e-4, 115),
    ("ellipsoid", (("a", 1.0), ("b", 0.7), ("c", 0.45)), "scan", 7000, 0.0, 116),
)
#: held-out rows that also run the paper's method (about 15 s per cloud): the clean ones
HELDOUT_PAPER_NOISE = 0.0
QUICK = {
    "surfaces": ("sphere", "torus", "saddle"),
    "samplers": ("random", "scan"),
    "sizes": (5000,),
    "noise_surfaces": ("sphere", "saddle"),
    "noise_n": 4000,
    "noise_extra": (("sinpatch", 4000),),
    "noise_sizes": (),
    "eval_points": 1000,
    "lownoise_surfaces": ("saddle",),
    "lownoises": (0.0, 1e-5, 1e-4),
    "lownoise_n": 4000,
    "mixed_n": 8000,
}

#: error column -> (target, "max" or "min")
TARGETS = {
    "mean": (0.5, "max"),
    "k1": (1.0, "max"),
    "k2": (1.0, "max"),
    "gaussian": (2.0, "max"),
    "d1": (0.5, "max"),
    "area": (0.5, "max"),
    "orientation": (99.9, "min"),
}
NOISE_TARGETS = {0.0012: 5.0, 0.006: 10.0}
ERROR_KEYS = ("mean", "k1", "k2", "gaussian", "d1", "normal", "area")
FIELDS = ("normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "area")


# ---------------------------------------------------------------------------
# cases
# ---------------------------------------------------------------------------


def seed_of(*parts) -> int:
    """A stable seed from the case's name."""
    return zlib.crc32("/".join(map(str, parts)).encode()) & 0x7FFFFFFF


def rigid_motion(seed: int, scale: float):
    """A random proper rotation, the given scale and a translation of norm 1e6..1e7.

    Returns
    -------
    scale : float
    rotation : ndarray, shape (3, 3)
    translation : ndarray, shape (3,)
    """
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    direction = rng.normal(size=3)
    shift = direction / np.linalg.norm(direction) * 10 ** rng.uniform(6, 7)
    return scale, q, shift


def make_sample(surface: str, sampler: str, n: int, noise: float = 0.0):
    seed = seed_of(surface, sampler, n, noise)
    return make_surface(surface).sample(n, sampler, noise=noise, seed=seed), seed


def sin_patch() -> hs.Graph:
    """Issue 12's open patch ``z = .25 sin(2x) sin(2y) + .1 x^2`` on ``[-1.5, 1.5]^2``."""
    return hs.Graph(
        f=lambda x, y: 0.25 * np.sin(2 * x) * np.sin(2 * y) + 0.1 * x * x,
        fx=lambda x, y: 0.5 * np.cos(2 * x) * np.sin(2 * y) + 0.2 * x,
        fy=lambda x, y: 0.5 * np.sin(2 * x) * np.cos(2 * y),
        fxx=lambda x, y: -np.sin(2 * x) * np.sin(2 * y) + 0.2,
        fxy=lambda x, y: np.cos(2 * x) * np.cos(2 * y),
        fyy=lambda x, y: -np.sin(2 * x) * np.sin(2 * y),
        size=1.5,
        name="sinpatch",
    )


def make_surface(name: str) -> hs.Surface:
    """A surface of the registry, or one of the noise table's extra patches."""
    if name == "sinpatch":
        return sin_patch()
    if name == "saddle.4":
        return hs.Saddle(a=0.4, size=1.0)
    return hs.get(name)


# ---------------------------------------------------------------------------
# running and measuring
# ---------------------------------------------------------------------------


@dataclass
class Run:
    """One estimate call and its errors."""

    metrics: dict = field(default_factory=dict)
    seconds: float = float("nan")
    warned: bool = False
    error: str | None = None


def nan_rows(result) -> int:
    bad = np.zeros(len(result.mean), dtype=bool)
    for name in FIELDS:
        arr = np.asarray(getattr(result, name), dtype=np.float64)
        bad |= ~np.isfinite(arr.reshape(arr.shape[0], -1)).all(axis=1)
    return int(bad.sum())


def measure(sample, result, margin: float, area_judged: bool) -> dict:
    with np.errstate(invalid="ignore", divide="ignore"):
        c = compare(sample, result, margin=margin)
    return {
        "mean": 100 * c["rel_mean"],
        "k1": 100 * c["rel_k1"],
        "k2": 100 * c["rel_k2"],
        "gaussian": 100 * c["rel_gaussian"],
        "d1": c["d1_deg"],
        "normal": c["normal_deg"],
        "area": 100 * abs(c["area"]) if area_judged else float("nan"),
        "orientation": 100 * c["orientation"],
        "reliable": 100 * c["reliable"],
        "nan": nan_rows(result),
        "interior": 100 * float(np.mean(c["interior"])),
    }


def run_estimator(name: str, sample, margin: float, area_judged: bool, log) -> Run:
    run = Run()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tic = time.perf_counter()
        try:
            result = ESTIMATORS[name](sample.points)
        except Exception as exc:  # noqa: BLE001 -- report and go on with the other cases
            run.seconds = time.perf_counter() - tic
            run.error = f"{type(exc).__name__}: {exc}"
            log(f"    {name:8s} ERROR {run.error}")
            return run
        run.seconds = time.perf_counter() - tic
    run.warned = any(issubclass(w.category, Warning) for w in caught)
    run.metrics = measure(sample, result, margin, area_judged)
    m = run.metrics
    log(
        f"    {name:8s} {run.seconds:7.2f} s{'*' if run.warned else ' '} mean {m['mean']:.3g} % "
        f"k1 {m['k1']:.3g} % d1 {m['d1']:.3g} deg orient {m['orientation']:.4g} %"
    )
    return run


def verdict(metrics_list: list[dict], noise: float = 0.0) -> list[str]:
    """Failed criteria over the given runs (the worst of them counts)."""
    fails = []

    def worst(key, kind):
        vals = [m[key] for m in metrics_list if np.isfinite(m[key])]
        if not vals:
            return float("nan")
        return max(vals) if kind == "max" else min(vals)

    if noise == 0.0:
        for key, (limit, kind) in TARGETS.items():
            v = worst(key, kind)
            if np.isfinite(v) and (v > limit if kind == "max" else v < limit):
                fails.append(key if key != "gaussian" else "K")
    else:
        v = worst("mean", "max")
        if np.isfinite(v) and v > NOISE_TARGETS[noise]:
            fails.append("mean")
    if any(m["nan"] > 0 for m in metrics_list):
        fails.append("NaN")
    return fails


# ---------------------------------------------------------------------------
# formatting
# ---------------------------------------------------------------------------


def fmt(v, digits=3) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "n/a"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if v == 0:
        return "0"
    if abs(v) >= 1000:
        return f"{v:.0f}"
    return f"{v:.{digits}g}"


def render(title: str, header: list[str], rows: list[list[str]], markdown: bool) -> str:
    return table(title, header, rows, markdown)


def machine_info() -> list[str]:
    cpu = cpu_model()
    return [
        f"date (UTC)   {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M:%S}",
        f"machine      {platform.platform()}, {cpu}, {os.cpu_count()} logical CPUs",
        f"python       {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}",
        f"heatcurv     {heatcurv.__version__} (commit {commit()})",
    ]


# ---------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# the noise tables: evaluation points, PCPNet error, the fixed-k oracle
# ---------------------------------------------------------------------------

#: per-point arrays of a result that the noise tables measure
VIEW_FIELDS = ("normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "reliable")
#: error columns of the noise table (oracle: each chosen with hindsight)
NOISE_KEYS = ("mean", "k1", "k2", "gaussian", "d1", "normal", "nrms_k1", "nrms_k2")
#: the columns the oracle verdict compares
ORACLE_JUDGED = ("mean", "k1", "k2", "d1")


def timed(fn):
    """``fn()`` with warnings recorded: (result or None, seconds, warned, error text or None)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tic = time.perf_counter()
        try:
            result = fn()
        except Exception as exc:  # noqa: BLE001 -- report and go on with the other cases
            return None, time.perf_counter() - tic, False, f"{type(exc).__name__}: {exc}"
        seconds = time.perf_counter() - tic
    return result, seconds, any(issubclass(w.category, Warning) for w in caught), None


def bbox_diagonal(points: np.ndarray) -> float:
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def eval_margin(sample) -> float:
    """Interior margin of the noise tables: none on closed surfaces, else ``EVAL_MARGIN`` x diagonal.

    At least the main table's margin (``neighbour_margin`` of the clean points); the
    same for every estimator and every noise level of a surface.
    """
    if sample.surface.closed:
        return 0.0
    return max(neighbour_margin(sample.clean_points), EVAL_MARGIN * bbox_diagonal(sample.clean_points))


def eval_rows(sample, margin: float, count: int | None, seed: int) -> np.ndarray:
    """Sorted indices of ``count`` interior points drawn with ``seed`` (all interior points if None)."""
    inner = np.flatnonzero(sample.interior(margin))
    if count is None or inner.size <= count:
        return inner
    return np.sort(np.random.default_rng(seed).choice(inner, count, replace=False))


def subset_sample(sample, rows: np.ndarray):
    """The sample restricted to ``rows`` (every per-point array; scalars as they are)."""
    n = len(sample)
    per_point = {}
    for f in dataclasses.fields(sample):
        value = getattr(sample, f.name)
        if f.name != "viewpoints" and isinstance(value, np.ndarray) and value.shape[:1] == (n,):
            per_point[f.name] = value[rows]
    return dataclasses.replace(sample, **per_point)


def view_at(result, rows: np.ndarray | None) -> SimpleNamespace:
    """The measured fields of ``result`` at ``rows`` (None: the result already has one row per evaluation point)."""
    return SimpleNamespace(
        **{name: np.asarray(getattr(result, name)) if rows is None else np.asarray(getattr(result, name))[rows]
           for name in VIEW_FIELDS}
    )


def pcpnet_rms(estimate: np.ndarray, exact: np.ndarray) -> float:
    """PCPNet's normalised RMS error ``sqrt(mean((|k - k*| / max(1, |k*|))^2))`` (not scale-free)."""
    err = np.abs(estimate - exact) / np.maximum(1.0, np.abs(exact))
    return float(np.sqrt(np.mean(err**2))) if err.size else float("nan")


def in_exact_orientation(sub, view) -> SimpleNamespace:
    """``view`` turned over (one global flip, by majority) when its normals point against the exact ones.

    The noise tables compare estimators column by column with the oracle, so
    every estimate is expressed in the exact normals' orientation: the
    normal and mean curvature negated, ``k1' = -k2``, ``k2' = -k1``, ``d1`` and
    ``d2`` swapped. Otherwise a default that orients a graph up and a quadric
    fit that orients it down would have their ``k1`` columns measure
    different curvatures.
    """
    if not np.mean(np.sign(np.einsum("ij,ij->i", view.normals, sub.normals))) < 0:
        return view
    return SimpleNamespace(
        normals=-view.normals, mean=-view.mean, gaussian=view.gaussian, k1=-view.k2, k2=-view.k1, d1=view.d2,
        d2=view.d1, reliable=view.reliable,
    )


def measure_view(sub, view) -> dict:
    """The noise tables' error measures of ``view`` against the evaluation points ``sub``.

    Signed curvatures are compared in the exact normals' orientation
    (:func:`in_exact_orientation`; ``compare``, for one estimator at a time,
    aligns the exact values with the estimate instead).
    """
    view = in_exact_orientation(sub, view)
    with np.errstate(invalid="ignore", divide="ignore"):
        ex = aligned_exact(sub, view)
        dirs = ~sub.umbilic
        bad = np.zeros(len(view.mean), dtype=bool)
        for name in VIEW_FIELDS[:-1]:
            arr = np.asarray(getattr(view, name), dtype=np.float64)
            bad |= ~np.isfinite(arr.reshape(arr.shape[0], -1)).all(axis=1)
        return {
            "mean": 100 * relative_l1(view.mean, ex["mean"]),
            "k1": 100 * relative_l1(view.k1, ex["k1"]),
            "k2": 100 * relative_l1(view.k2, ex["k2"]),
            "gaussian": 100 * relative_l1(view.gaussian, ex["gaussian"]),
            "d1": direction_error_deg(view.d1[dirs], ex["d1"][dirs]),
            "normal": direction_error_deg(view.normals, ex["normals"]),
            "nrms_k1": pcpnet_rms(view.k1, ex["k1"]),
            "nrms_k2": pcpnet_rms(view.k2, ex["k2"]),
            "orientation": 100 * float(np.mean(np.einsum("ij,ij->i", view.normals, ex["normals"]) > 0)),
            "reliable": 100 * float(np.mean(view.reliable)),
            "nan": int(bad.sum()),
        }


def oracle_ks(n: int, max_k: int = ORACLE_KS[-1]) -> tuple[int, ...]:
    """The ladder of fixed k for a cloud of n points.

    ``ORACLE_KS``, continued by doubling up to ``max_k`` (``--oracle-max-k``), and capped at
    ``max(240, n / 10)``.
    """
    ladder = list(ORACLE_KS)
    while 2 * ladder[-1] <= max_k:
        ladder.append(2 * ladder[-1])
    cap = max(240, n // 10)
    return tuple(k for k in ladder if k <= min(cap, max(max_k, ORACLE_KS[0])))


def run_oracle(sample, rows: np.ndarray, sub, log, max_k: int = ORACLE_KS[-1]) -> dict:
    """The quadric fit at every k of the ladder, evaluated at ``rows``; per column the best k.

    Returns
    -------
    dict
        ``best`` (column -> error), ``k`` (column -> the k that gave it),
        ``seconds`` (the whole ladder), ``per_k`` (k -> metrics), ``error``.
    """
    per_k, seconds, error = {}, 0.0, None
    for k in oracle_ks(len(sample), max_k):
        res, t, _, err = timed(lambda k=k: quadric_curvature(sample.points, k=k, centres=rows))
        seconds += t
        if err:
            error = error or f"k={k}: {err}"
            log(f"    oracle k={k} ERROR {err}")
            continue
        per_k[k] = measure_view(sub, view_at(res, None))
        m = per_k[k]
        log(f"    quadric k={k:<5d} {t:6.2f} s  mean {m['mean']:.3g} % k1 {m['k1']:.3g} % k2 {m['k2']:.3g} % "
            f"d1 {m['d1']:.3g} deg")
    best, best_k = {}, {}
    for key in NOISE_KEYS:
        vals = [(m[key], k) for k, m in per_k.items() if np.isfinite(m[key])]
        best[key], best_k[key] = min(vals) if vals else (float("nan"), None)
    return {"best": best, "k": best_k, "seconds": seconds, "per_k": per_k, "error": error, "one_k": one_k(per_k, best)}


def one_k(per_k: dict, best: dict):
    """The one k best for the cloud as a whole: the smallest sum over the judged columns of error / column's best.

    The issue's own table reports the oracle this way (one k per cloud); the
    per-column best (``best``) is the stricter oracle the verdict uses first.
    """
    def score(m):
        parts = [m[c] / best[c] for c in ORACLE_JUDGED if np.isfinite(m[c]) and np.isfinite(best[c]) and best[c] > 0]
        return sum(parts) if parts else float("inf")

    return min(per_k, key=lambda k: score(per_k[k]), default=None)


def oracle_verdict(m: dict, oracle: dict) -> str:
    """PASS when the default's error is at most the oracle's on mean, k1, k2 and d1 (n/a: not judged)."""
    fails = [
        key for key in ORACLE_JUDGED
        if np.isfinite(oracle["best"][key]) and not (m[key] <= oracle["best"][key])
    ]
    return "PASS" if not fails else "FAIL " + ",".join(fails)


def oracle_verdicts(m: dict, oracle: dict) -> tuple[bool, bool, str] | None:
    """The default's two verdicts (best k per column; the one k best for the cloud) and their row text.

    None when no oracle fit ran.
    """
    if not oracle["per_k"]:
        return None
    per_column = oracle_verdict(m, oracle)
    one_k = oracle["one_k"]
    cloud_wide = oracle_verdict(m, {"best": oracle["per_k"][one_k]})
    return per_column == "PASS", cloud_wide == "PASS", f"{per_column}; one k ({one_k}): {cloud_wide}"


def noise_clouds(args, quick: bool, noise_surfaces, noise_n: int) -> list[tuple[str, int, float]]:
    """The noise table's clouds: (surface, n, noise)."""
    clouds = []
    if not args.size_rows_only:
        clouds += [(s, noise_n, lvl) for s in noise_surfaces for lvl in NOISES]
        extra = QUICK["noise_extra"] if quick else NOISE_EXTRA
        clouds += [(s, n, lvl) for s, n in extra for lvl in NOISES]
    if args.noise_sizes is not None:
        sizes = tuple(args.noise_sizes)
    else:
        sizes = QUICK["noise_sizes"] if quick else NOISE_SIZES
    if args.big and BIG_SIZE not in sizes:
        sizes += (BIG_SIZE,)
    clouds += [("torus", n, lvl) for n in sizes for lvl in NOISES]
    return clouds


def noise_table(bench, args, estimators, clouds, eval_points: int):
    """The noise table: heatcurv's estimators and the fixed-k oracle at the evaluation points."""
    header = ["surface", "noise%", "n", "est", "mean%", "k1%", "k2%", "K%", "d1deg", "nrmdeg", "nrms_k1", "nrms_k2",
              "orient%", "rel%", "NaN", "t[s]", "target", "verdict", "oracle"]
    keys = ("mean", "k1", "k2", "gaussian", "d1", "normal")
    rows = []
    for surface, n, noise in clouds:
        tic = time.perf_counter()
        sample, seed = make_sample(surface, "random", n, noise)
        margin = eval_margin(sample)
        at = eval_rows(sample, margin, eval_points, seed_of(surface, n, noise, "eval"))
        sub = subset_sample(sample, at)
        bench.log(f"{surface} random n={n} noise {100 * noise:g} %: sigma {sample.sigma:.3g}, margin {margin:.3g}, "
                  f"{at.size} evaluation points, sample {time.perf_counter() - tic:.1f} s")
        ests = [e for e in estimators if n <= NOISE_ALL_MAX or e == "default"]
        head = [surface, f"{100 * noise:g}", str(len(sample))]
        default_metrics = None
        for est in ests:
            res, t, warned, err = timed(lambda est=est, pts=sample.points: ESTIMATORS[est](pts))
            bench.calls += 1
            if err:
                bench.log(f"    {est:8s} ERROR {err}")
                rows.append(head + [est] + ["-"] * 12 + [f"mean <= {NOISE_TARGETS[noise]:g}", f"ERROR {err[:60]}",
                                                         "ERROR" if est == "default" else "-"])
                bench.passes[est][1] += 1
                if est == "default":
                    bench.oracle_passes[1] += 1
                continue
            m = measure_view(sub, view_at(res, at))
            scale = getattr(res, "info", {}).get("scale") if est != "quadric" else None
            ball = f", widest ball {scale.radius:.3g}" if getattr(scale, "radius", None) is not None else ""
            bench.log(f"    {est:8s} {t:7.2f} s{'*' if warned else ' '} mean {m['mean']:.3g} % k1 {m['k1']:.3g} % "
                      f"k2 {m['k2']:.3g} % d1 {m['d1']:.3g} deg{ball}")
            fails = verdict([m], noise)
            bench.passes[est][0 if not fails else 1] += 1
            row = head + [est] + [fmt(m[k]) for k in keys] + [fmt(m["nrms_k1"]), fmt(m["nrms_k2"])]
            row += [f"{m['orientation']:.2f}", f"{m['reliable']:.1f}", str(m["nan"])]
            row += [f"{t:.2f}" + ("*" if warned else ""), f"mean <= {NOISE_TARGETS[noise]:g}"]
            row += ["PASS" if not fails else "FAIL " + ",".join(fails), "-"]
            if est == "default":
                default_metrics, default_row = m, row
            rows.append(row)
        oracle = run_oracle(sample, at, sub, bench.log, args.oracle_max_k)
        bench.oracle_calls += len(oracle["per_k"])
        best, ks = oracle["best"], oracle["k"]
        if default_metrics is not None:
            verdicts = oracle_verdicts(default_metrics, oracle)
            default_row[-1] = "ERROR" if verdicts is None else verdicts[2]
            if verdicts is not None:
                bench.oracle_passes[0 if verdicts[0] else 1] += 1
                bench.one_k_passes[0 if verdicts[1] else 1] += 1
        ks_tried = oracle_ks(len(sample), args.oracle_max_k)
        ladder = "/".join(map(str, ks_tried))
        rows.append(head + ["oracle"] + [fmt(best[k]) for k in keys + ("nrms_k1", "nrms_k2")]
                    + ["-", "-", "-", f"{oracle['seconds']:.2f}", f"k {ladder}",
                       "ERROR " + oracle["error"][:60] if oracle["error"] else "-", "-"])
        top = max(oracle["per_k"], default=None)  # the widest fit that ran: "+", a wider one might do better
        rows.append(["", "", "", "(k)"] + [f"{ks[k]}{'+' if ks[k] == top else ''}" if ks[k] else "-"
                                           for k in keys + ("nrms_k1", "nrms_k2")]
                    + ["", "", "", "", "", "", ""])
    title = (
        f"Noise (random sampler; noise = std / bounding-box diagonal; errors at up to {eval_points} interior "
        "evaluation points; oracle: fixed-k quadric fit, best k per column with hindsight, k in row (k), "
        "+: the widest k tried; "
        "oracle verdict: default <= oracle on mean, k1, k2, d1; then the same against the one k best for the cloud "
        "as a whole, the smallest sum of error / column's best)"
    )
    return title, header, rows


def lownoise_table(bench, surfaces, noises, n: int, seed_offset: int = 0):
    """The very-low-noise band: heatcurv default on one clean cloud per surface plus tiny noise."""
    header = ["surface", "noise", "n", "mean%", "k1%", "k2%", "d1deg", "mean x", "k1 x", "k2 x", "d1 x", "t[s]",
              "verdict"]
    keys = ("mean", "k1", "k2", "d1")
    rows = []
    for surface in surfaces:
        # one seed: the same clean points at every noise level (``--lownoise-seed-offset``: other clouds)
        seed = seed_of(surface, "lownoise", n) + seed_offset
        clean = None
        for noise in noises:
            sample = make_surface(surface).sample(n, "random", noise=noise, seed=seed)
            margin = eval_margin(sample)
            at = eval_rows(sample, margin, None, seed)
            res, t, warned, err = timed(lambda sample=sample: heatcurv.estimate(sample.points))
            bench.calls += 1
            head = [surface, f"{noise:g}", str(len(sample))]
            if err:
                bench.log(f"{surface} n={n} noise {noise:g}: ERROR {err}")
                rows.append(head + ["-"] * 9 + [f"ERROR {err[:60]}"])
                bench.lownoise_passes[1] += 1
                continue
            m = measure_view(subset_sample(sample, at), view_at(res, at))
            bench.log(f"{surface} n={n} noise {noise:g} (sigma {sample.sigma:.3g}): {t:.2f} s, mean {m['mean']:.3g} % "
                      f"k1 {m['k1']:.3g} % k2 {m['k2']:.3g} % d1 {m['d1']:.3g} deg")
            if noise == 0.0:
                clean = m
            if clean is None:
                ratios = {k: float("nan") for k in keys}
            else:
                with np.errstate(invalid="ignore", divide="ignore"):
                    ratios = {k: m[k] / clean[k] if clean[k] > 0 else float("nan") for k in keys}
            row = head + [fmt(m[k]) for k in keys] + [fmt(ratios[k], 2) for k in keys]
            row += [f"{t:.2f}" + ("*" if warned else "")]
            if noise == 0.0:
                row.append("(clean)")
            elif clean is None:
                row.append("- (no clean row)")
            else:
                fails = [k for k in keys if np.isfinite(ratios[k]) and ratios[k] > LOWNOISE_RATIO]
                fails += ["NaN"] if m["nan"] else []
                row.append("PASS" if not fails else "FAIL " + ",".join(fails))
                bench.lownoise_passes[0 if not fails else 1] += 1
            rows.append(row)
    title = (
        f"Very-low-noise band (heatcurv default, random sampler, n = {n}; noise = std / bbox diagonal; "
        f"x: ratio to the noise-0 row of the same clean points; PASS: every ratio <= {LOWNOISE_RATIO:g})"
    )
    return title, header, rows


def mixed_sample(n: int, noises: tuple[float, float], uniform: float | None = None):
    """A torus of n random points, noise ``noises[0]`` on x < 0 and ``noises[1]`` on x > 0.

    ``uniform``: the same clean points and normal deviates with that level everywhere instead.
    """
    seed = seed_of("torus", "mixed", n, *noises)
    clean = hs.get("torus").sample(n, "random", seed=seed)
    diag = bbox_diagonal(clean.clean_points)
    deviates = np.random.default_rng(seed + 1).normal(size=(n, 3))
    west = clean.clean_points[:, 0] < 0
    level = np.full(n, uniform) if uniform is not None else np.where(west, noises[0], noises[1])
    points = clean.clean_points + deviates * (level * diag)[:, None]
    noise = uniform if uniform is not None else float("nan")
    return dataclasses.replace(clean, points=points, noise=noise, sigma=noise * diag), west


def mixed_table(bench, n: int, noises: tuple[float, float]):
    """Mixed noise: heatcurv default per half of the torus, against the same half with uniform noise."""
    header = ["half", "noise%", "points", "mean%", "k1%", "k2%", "d1deg", "radius med", "uniform mean%",
              "uniform radius", "t[s]"]
    sample, west = mixed_sample(n, noises)
    runs = {"mixed": sample}
    for lvl in noises:
        runs[lvl] = mixed_sample(n, noises, uniform=lvl)[0]
    out = {}
    for key, smp in runs.items():
        res, t, warned, err = timed(lambda smp=smp: heatcurv.estimate(smp.points))
        bench.calls += 1
        label = "mixed" if key == "mixed" else f"uniform {100 * key:g} %"
        if err:
            bench.log(f"torus n={n} {label}: ERROR {err}")
        else:
            radius = getattr(res, "fit_radius", None)
            bench.log(f"torus n={n} {label}: {t:.2f} s, per-point radius {'yes' if radius is not None else 'no'}")
        out[key] = (res, t, warned, err)
    rows = []
    for half, mask, lvl in (("x < 0", west, noises[0]), ("x > 0", ~west, noises[1])):
        at = np.flatnonzero(mask)
        sub = subset_sample(sample, at)
        res, t, warned, err = out["mixed"]
        row = [half, f"{100 * lvl:g}", str(at.size)]
        if err:
            row += [f"ERROR {err[:40]}"] + ["-"] * 4
        else:
            m = measure_view(sub, view_at(res, at))
            radius = getattr(res, "fit_radius", None)
            row += [fmt(m[k]) for k in ("mean", "k1", "k2", "d1")]
            row += [fmt(float(np.median(np.asarray(radius)[at]))) if radius is not None else "n/a"]
        ures, _, _, uerr = out[lvl]
        if uerr:
            row += [f"ERROR {uerr[:40]}", "-"]
        else:
            um = measure_view(subset_sample(runs[lvl], at), view_at(ures, at))
            uradius = getattr(ures, "fit_radius", None)
            row += [fmt(um["mean"]), fmt(float(np.median(np.asarray(uradius)[at]))) if uradius is not None else "n/a"]
        row += [f"{t:.2f}" + ("*" if warned else "") if not err else "-"]
        rows.append(row)
    title = (
        f"Mixed noise (heatcurv default; torus, n = {n} random points, noise {100 * noises[0]:g} % of the diagonal "
        f"on x < 0 and {100 * noises[1]:g} % on x > 0; uniform: the same points with that half's noise everywhere; "
        "radius: median per-point ball radius, result.fit_radius)"
    )
    return title, header, rows


def bump_patch(height: float, width: float, size: float) -> hs.Graph:
    """A Gaussian bump ``z = height exp(-(x^2 + y^2) / (2 width^2))`` on ``[-size, size]^2`` (curvature both signs)."""
    s2 = width * width

    def g(x, y):
        return height * np.exp(-(x * x + y * y) / (2.0 * s2))

    return hs.Graph(
        f=g,
        fx=lambda x, y: -x / s2 * g(x, y),
        fy=lambda x, y: -y / s2 * g(x, y),
        fxx=lambda x, y: (x * x / s2 - 1.0) / s2 * g(x, y),
        fxy=lambda x, y: x * y / (s2 * s2) * g(x, y),
        fyy=lambda x, y: (y * y / s2 - 1.0) / s2 * g(x, y),
        size=size,
        name="bump",
    )


def heldout_surface(name: str, params: tuple) -> hs.Surface:
    """The surface of a ``HELDOUT`` cloud: a registry surface with its parameters, or the bump."""
    if name == "bump":
        return bump_patch(**dict(params))
    return hs.get(name, **dict(params))


def heldout_label(name: str, params: tuple) -> str:
    return f"{name}({','.join(f'{v:g}' for _, v in params)})"


def heldout_target(noise: float) -> float:
    """The mean-curvature target of a noisy held-out cloud: that of the smallest tuned level at or above its noise."""
    above = [lvl for lvl in NOISES if lvl >= noise]
    return NOISE_TARGETS[min(above) if above else max(NOISES)]


def heldout_margin(sample) -> float:
    """Interior margin: the main table's on clean clouds, the noise table's on noisy ones (scans: at least main's)."""
    if sample.noise == 0.0:
        return neighbour_margin(sample.points)
    margin = eval_margin(sample)
    if sample.sampler == "scan":
        margin = max(margin, neighbour_margin(sample.clean_points))
    return margin


def heldout_table(bench, estimators, eval_points: int):
    """The held-out clouds (``HELDOUT``): heatcurv default, the k = 40 quadric and, on clean clouds, the paper."""
    header = ["cloud", "sampler", "n", "noise%", "seed", "est", "mean%", "k1%", "k2%", "K%", "d1deg", "nrmdeg",
              "area%", "orient%", "rel%", "NaN", "points", "t[s]", "target", "verdict", "vs q40", "oracle"]
    keys = ("mean", "k1", "k2", "gaussian", "d1", "normal", "area")
    rows = []
    for name, params, sampler, n, noise, seed in HELDOUT:
        tic = time.perf_counter()
        surf = heldout_surface(name, params)
        sample = surf.sample(n, sampler, noise=noise, seed=seed)
        label = heldout_label(name, params)
        margin = heldout_margin(sample)
        area_judged = noise == 0.0 and surf.closed and sampler != "scan"
        at = None
        if noise > 0.0:
            at = eval_rows(sample, margin, eval_points, seed_of("heldout", seed, "eval"))
            sub = subset_sample(sample, at)
        measured = int(np.count_nonzero(sample.interior(margin))) if at is None else at.size
        bench.log(f"heldout {label} {sampler} n={len(sample)} noise {100 * noise:g} % seed {seed}: margin "
                  f"{margin:.3g}, {measured} measured points, sample {time.perf_counter() - tic:.1f} s")
        head = [label, sampler, str(len(sample)), f"{100 * noise:g}", str(seed)]
        target = "main" if noise == 0.0 else f"mean <= {heldout_target(noise):g}"
        ests = [e for e in estimators if e != "paper" or noise == HELDOUT_PAPER_NOISE]
        found, default_row = {}, None
        for est in ests:
            res, t, warned, err = timed(lambda est=est, pts=sample.points: ESTIMATORS[est](pts))
            bench.calls += 1
            counts = bench.heldout_passes.setdefault(est, [0, 0])
            if err:
                bench.log(f"    {est:8s} ERROR {err}")
                rows.append(head + [est] + ["-"] * 12 + [target, f"ERROR {err[:60]}", "-", "-"])
                counts[1] += 1
                continue
            if at is None:
                m = measure(sample, res, margin, area_judged)
                fails = verdict([m], 0.0)
            else:
                m = measure_view(sub, view_at(res, at))
                m["area"] = float("nan")
                fails = ["mean"] if m["mean"] > heldout_target(noise) else []
                fails += ["NaN"] if m["nan"] else []
            found[est] = m
            counts[0 if not fails else 1] += 1
            bench.log(f"    {est:8s} {t:7.2f} s{'*' if warned else ' '} mean {m['mean']:.3g} % k1 {m['k1']:.3g} % "
                      f"k2 {m['k2']:.3g} % d1 {m['d1']:.3g} deg")
            row = head + [est] + [fmt(m[k]) for k in keys]
            row += [f"{m['orientation']:.2f}", f"{m['reliable']:.1f}", str(m["nan"]), str(measured)]
            row += [f"{t:.2f}" + ("*" if warned else ""), target]
            row += ["PASS" if not fails else "FAIL " + ",".join(fails), "-", "-"]
            if est == "default":
                default_row = row
            rows.append(row)
        if default_row is not None and "quadric" in found:
            d, q = found["default"], found["quadric"]
            worse = [k for k in ORACLE_JUDGED if np.isfinite(d[k]) and np.isfinite(q[k]) and d[k] > q[k]]
            default_row[-2] = "worse: " + ",".join(worse) if worse else "none worse"
        if at is not None:
            heldout_oracle_rows(bench, sample, at, sub, head, found.get("default"), default_row, rows)
    title = (
        "Held-out clouds (HELDOUT in benchmarks/accuracy.py: no threshold was tuned on them; noise = std / "
        "bounding-box diagonal; noise 0: the main table's interior margin, all interior points, its targets; "
        f"noise > 0: the noise table's margin (scans: at least the main table's), up to {eval_points} "
        "evaluation points, target mean <= that of the smallest tuned noise level at or above the cloud's; "
        "points: the points measured; paper: clean clouds only; vs q40: of mean, k1, k2, d1, the columns where "
        "the default's error exceeds the k = 40 quadric's; oracle, noise > 0 only: the noise table's fixed-k quadric "
        "oracle at the evaluation points, best k per column with hindsight, k in row (k), +: the widest k tried, and "
        "its two verdicts)"
    )
    return title, header, rows


def heldout_oracle_rows(bench, sample, at, sub, head, default_metrics, default_row, rows) -> None:
    """The noise table's oracle on a noisy held-out cloud: its rows, and its verdicts in the default's row."""
    oracle = run_oracle(sample, at, sub, bench.log)
    bench.oracle_calls += len(oracle["per_k"])
    best, ks = oracle["best"], oracle["k"]
    if default_metrics is not None and default_row is not None:
        verdicts = oracle_verdicts(default_metrics, oracle)
        default_row[-1] = "ERROR" if verdicts is None else verdicts[2]
        if verdicts is not None:
            bench.heldout_oracle_passes[0 if verdicts[0] else 1] += 1
            bench.heldout_one_k_passes[0 if verdicts[1] else 1] += 1
    keys = ("mean", "k1", "k2", "gaussian", "d1", "normal")
    ladder = "/".join(map(str, oracle_ks(len(sample))))
    rows.append(head + ["oracle"] + [fmt(best[k]) for k in keys] + ["n/a", "-", "-", "-", str(at.size)]
                + [f"{oracle['seconds']:.2f}", f"k {ladder}",
                   "ERROR " + oracle["error"][:60] if oracle["error"] else "-", "-", "-"])
    top = max(oracle["per_k"], default=None)  # the widest fit that ran: "+", a wider one might do better
    rows.append([""] * 5 + ["(k)"] + [f"{ks[k]}{'+' if ks[k] == top else ''}" if ks[k] else "-" for k in keys]
                + [""] * 10)


@dataclass
class Bench:
    """Counters shared by the tables."""

    log: object
    passes: dict
    calls: int = 0
    oracle_calls: int = 0
    oracle_passes: list = field(default_factory=lambda: [0, 0])
    one_k_passes: list = field(default_factory=lambda: [0, 0])
    lownoise_passes: list = field(default_factory=lambda: [0, 0])
    heldout_passes: dict = field(default_factory=dict)
    heldout_oracle_passes: list = field(default_factory=lambda: [0, 0])
    heldout_one_k_passes: list = field(default_factory=lambda: [0, 0])


# ---------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------


def parse_args(argv=None):
    p = argparse.ArgumentParser(
        description="Accuracy of heatcurv's default and paper estimators and of the k-NN quadric "
        "baseline on analytic surfaces (random, jittered and scan samplers, any size and position, "
        "noise, a fixed-k quadric oracle under noise, the very-low-noise band, mixed noise), with PASS/FAIL "
        "against the accuracy targets.",
        epilog="See the module docstring for the definitions of the error columns and targets.",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="small variants of every table: sphere, torus, saddle; random, scan; n = 5000; noise on sphere, "
        "saddle and the sine patch at n = 4000 (1000 evaluation points, no torus size rows); low noise on "
        "the saddle, n = 4000; mixed noise n = 8000 (~1 minute)",
    )
    p.add_argument(
        "--tables", nargs="+", choices=TABLES, metavar="TABLE",
        help=f"run only these tables ({', '.join(TABLES)}; default all; --quick: all but heldout)",
    )
    p.add_argument("--only", action="append", choices=sorted(ESTIMATORS), help="run only this estimator (repeatable; "
                   "main and noise tables; the oracle always runs, the low-noise and mixed tables use the default)")
    p.add_argument("--markdown", metavar="PATH", help="also write the tables as markdown to PATH")
    p.add_argument("--png", metavar="PATH", help="plot mean-curvature error vs n to PATH (needs matplotlib)")
    p.add_argument("--surfaces", nargs="+", choices=SURFACES, help="restrict the surfaces (main and noise tables)")
    p.add_argument("--samplers", nargs="+", choices=SAMPLERS, help="restrict the samplers")
    p.add_argument("--sizes", nargs="+", type=int, help="point counts (default 10000 20000 30000; --quick: 5000)")
    p.add_argument("--no-transform", action="store_true", help="skip the rigidly moved and scaled copies")
    p.add_argument(
        "--transform-all",
        action="store_true",
        help="moved copies of every size, not only the smallest (full run: ~1.7x the time)",
    )
    p.add_argument("--no-noise", action="store_true", help="skip the noise table (same as leaving it out of --tables)")
    p.add_argument(
        "--noise-sizes", nargs="*", type=int, metavar="N",
        help=f"sizes of the noise table's torus rows (default {' '.join(map(str, NOISE_SIZES))}; --quick: none; "
        "give no value for none)",
    )
    p.add_argument("--big", action="store_true", help=f"add the {BIG_SIZE}-point torus rows to the noise table "
                   "(slow: minutes per row)")
    p.add_argument("--oracle-max-k", type=int, default=ORACLE_KS[-1], metavar="K",
                   help=f"continue the oracle's k ladder by doubling up to K (default {ORACLE_KS[-1]}; always capped "
                   "at max(240, n/10); memory ~16 bytes x evaluation points x K)")
    p.add_argument("--size-rows-only", action="store_true",
                   help="noise table: only the torus size rows (--noise-sizes, --big)")
    p.add_argument("--eval-points", type=int, metavar="M",
                   help=f"evaluation points of the noise table (default {EVAL_POINTS}; --quick: "
                   f"{QUICK['eval_points']})")
    p.add_argument("--lownoise-seed-offset", type=int, default=0, metavar="K",
                   help="add K to every seed of the low-noise table (other clouds of the same surfaces)")
    p.add_argument("--without-low-noise-path", action="store_true",
                   help="ablation: the default estimator with its very-low-noise gate "
                   "(heatcurv.choice.scale.in_low_noise_band) answering no, to measure what the path wins")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    return p.parse_args(argv)


def main_table(bench, args, estimators, surfaces, samplers, sizes, plot):
    """The main table: clean clouds, every sampler and size, moved copies."""
    log = bench.log
    header = ["surface", "sampler", "n", "est", "mean%", "k1%", "k2%", "K%", "d1deg", "nrmdeg", "area%",
              "orient%", "rel%", "NaN", "t[s]"]
    if not args.no_transform:
        header += ["scale", "dmax", "t'[s]"]
    header += ["verdict"]
    rows = []
    case_index = 0
    for surface in surfaces:
        for sampler in samplers:
            for n in sizes:
                tic = time.perf_counter()
                sample, seed = make_sample(surface, sampler, n)
                margin = neighbour_margin(sample.points)
                area_judged = surface in CLOSED and sampler != "scan"
                log(
                    f"{surface} {sampler} n={n}: {len(sample)} points, "
                    f"sample {time.perf_counter() - tic:.1f} s, margin {margin:.3g}"
                )
                moved = None
                if not args.no_transform and (args.transform_all or n == min(sizes)):
                    scale, rot, shift = rigid_motion(seed + 1, SCALES[case_index % len(SCALES)])
                    moved = sample.transformed(scale, rot, shift)
                case_index += 1
                for est in estimators:
                    base = run_estimator(est, sample, margin, area_judged, log)
                    bench.calls += 1
                    runs = [base]
                    if moved is not None:
                        log(f"    (scale {scale:g}, |shift| {np.linalg.norm(shift):.2g})")
                        runs.append(run_estimator(est, moved, margin * scale, area_judged, log))
                        bench.calls += 1
                    row = [surface, sampler, str(len(sample)), est]
                    if any(r.error for r in runs):
                        err = next(r.error for r in runs if r.error)
                        row += ["-"] * (len(header) - len(row) - 1) + [f"ERROR {err[:60]}"]
                        bench.passes[est][1] += 1
                        rows.append(row)
                        continue
                    m = base.metrics
                    row += [fmt(m[k]) for k in ("mean", "k1", "k2", "gaussian", "d1", "normal", "area")]
                    row += [f"{m['orientation']:.2f}", f"{m['reliable']:.1f}", str(m["nan"])]
                    row += [f"{base.seconds:.2f}" + ("*" if base.warned else "")]
                    if args.no_transform:
                        pass
                    elif moved is None:
                        row += ["-", "-", "-"]
                    else:
                        t = runs[1].metrics
                        diffs = [
                            abs(t[k] - m[k])
                            for k in ERROR_KEYS + ("orientation",)
                            if np.isfinite(t[k]) and np.isfinite(m[k])
                        ]
                        row += [
                            f"{scale:g}",
                            fmt(max(diffs) if diffs else float("nan"), 2),
                            f"{runs[1].seconds:.2f}" + ("*" if runs[1].warned else ""),
                        ]
                    fails = verdict([r.metrics for r in runs])
                    row += ["PASS" if not fails else "FAIL " + ",".join(fails)]
                    bench.passes[est][0 if not fails else 1] += 1
                    rows.append(row)
                    plot.append((surface, sampler, len(sample), est, m))
    return "Accuracy (interior points; dmax: largest change of an error column for the moved copy)", header, rows


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.without_low_noise_path:
        import heatcurv.choice.scale

        heatcurv.choice.scale.in_low_noise_band = lambda relative_noise: False  # the ablation: the gate never opens
    wall = time.perf_counter()
    quick = args.quick
    chosen = args.tables or [t for t in TABLES if not (quick and t == "heldout")]
    which = [t for t in TABLES if t in chosen and not (t == "noise" and args.no_noise)]
    estimators = [e for e in ESTIMATORS if not args.only or e in args.only]
    surfaces = args.surfaces or (QUICK["surfaces"] if quick else SURFACES)
    samplers = args.samplers or (QUICK["samplers"] if quick else SAMPLERS)
    sizes = tuple(args.sizes) if args.sizes else (QUICK["sizes"] if quick else SIZES)
    noise_n = QUICK["noise_n"] if quick else NOISE_N
    if args.sizes and quick:
        noise_n = sizes[0]
    noise_surfaces = surfaces
    if quick and not args.surfaces:
        noise_surfaces = QUICK["noise_surfaces"]
    eval_points = args.eval_points or (QUICK["eval_points"] if quick else EVAL_POINTS)

    def log(msg):
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    bench = Bench(log=log, passes={e: [0, 0] for e in estimators})
    info = machine_info()
    if "heldout" in which:
        info.append(f"{'memory':13s}{memory_text().lstrip(', ')}")
        info.append("command      python " + " ".join([os.path.relpath(__file__)] + sys.argv[1:]))
    print("heatcurv accuracy benchmark" + (" (--quick)" if quick else ""))
    print("\n".join(info))
    print(
        f"tables       {', '.join(which)}; estimators {', '.join(estimators)}; surfaces {', '.join(surfaces)}; "
        f"samplers {', '.join(samplers)}; n {', '.join(map(str, sizes))}"
    )
    print()

    tables, plot = [], []
    if "main" in which:
        tables.append(main_table(bench, args, estimators, surfaces, samplers, sizes, plot))
    if "noise" in which:
        clouds = noise_clouds(args, quick, noise_surfaces, noise_n)
        tables.append(noise_table(bench, args, estimators, clouds, eval_points))
    if "lownoise" in which:
        tables.append(lownoise_table(
            bench,
            QUICK["lownoise_surfaces"] if quick else LOWNOISE_SURFACES,
            QUICK["lownoises"] if quick else LOWNOISES,
            QUICK["lownoise_n"] if quick else LOWNOISE_N,
            args.lownoise_seed_offset,
        ))
    if "mixed" in which:
        tables.append(mixed_table(bench, QUICK["mixed_n"] if quick else MIXED_N, MIXED_NOISES))
    if "heldout" in which:
        tables.append(heldout_table(bench, estimators, eval_points))

    elapsed = time.perf_counter() - wall
    summary = [f"{est}: {p[0]} PASS, {p[1]} FAIL" for est, p in bench.passes.items()]
    if "noise" in which:
        summary.append(f"default vs oracle: {bench.oracle_passes[0]} PASS, {bench.oracle_passes[1]} FAIL")
        one_pass, one_fail = bench.one_k_passes
        summary.append(f"default vs oracle, one k per cloud: {one_pass} PASS, {one_fail} FAIL")
    if "lownoise" in which:
        summary.append(f"low noise: {bench.lownoise_passes[0]} PASS, {bench.lownoise_passes[1]} FAIL")
    if "heldout" in which:
        summary += [f"heldout {est}: {p[0]} PASS, {p[1]} FAIL" for est, p in bench.heldout_passes.items()]
        summary.append(f"heldout default vs oracle: {bench.heldout_oracle_passes[0]} PASS, "
                       f"{bench.heldout_oracle_passes[1]} FAIL; one k per cloud: {bench.heldout_one_k_passes[0]} "
                       f"PASS, {bench.heldout_one_k_passes[1]} FAIL")
    targets = (
        "targets: mean <= 0.5 %, k1/k2 <= 1 %, K <= 2 %, d1 <= 0.5 deg, area <= 0.5 % (closed, complete "
        "samples), orientation >= 99.9 %, no NaN; noise 0.12 %: mean <= 5 %, 0.6 %: mean <= 10 %; "
        "noise: default <= oracle on mean, k1, k2, d1; low noise: <= 2x the clean errors"
    )
    for title, head, body in tables:
        print(render(title, head, body, markdown=False))
    print(targets)
    print("summary: " + "; ".join(summary))
    print(f"{bench.calls} estimate calls, {bench.oracle_calls} oracle quadric fits, wall time {elapsed:.1f} s")

    if args.markdown:
        with open(args.markdown, "w") as fh:
            fh.write("# heatcurv accuracy benchmark\n\n")
            fh.write("Generated by `benchmarks/accuracy.py" + (" --quick" if quick else "") + "`.\n\n")
            fh.write("```\n" + "\n".join(info) + "\n```\n\n")
            for title, head, body in tables:
                fh.write(render(title, head, body, markdown=True) + "\n")
            fh.write(targets + "\n\n")
            fh.write(
                "Summary: " + "; ".join(summary)
                + f". {bench.calls} estimate calls, {bench.oracle_calls} oracle quadric fits, "
                f"wall time {elapsed:.1f} s.\n"
            )
        print(f"markdown written to {args.markdown}")
    if args.png:
        if plot:
            write_png(args.png, plot, samplers)
        else:
            print(f"--png {args.png} skipped: the main table was not run")
    return 0


def write_png(path: str, plot: list, samplers) -> None:
    """Mean-curvature error vs n, one panel per sampler, one line per estimator and surface."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: --png {path} skipped (pip install matplotlib)")
        return
    fig, axes = plt.subplots(1, len(samplers), figsize=(5.5 * len(samplers), 4.5), squeeze=False)
    styles = {"default": "-", "paper": "--", "quadric": ":"}
    colours = dict(zip(SURFACES, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    for ax, sampler in zip(axes[0], samplers):
        series = {}
        for surface, smp, n, est, m in plot:
            if smp == sampler and np.isfinite(m["mean"]) and m["mean"] > 0:
                series.setdefault((est, surface), []).append((n, m["mean"]))
        for (est, surface), pts in sorted(series.items()):
            pts.sort()
            ax.plot(
                *zip(*pts), styles.get(est, "-"), marker="o", ms=3, color=colours.get(surface), label=f"{est} {surface}"
            )
        ax.axhline(0.5, color="k", lw=0.8, alpha=0.5)
        ax.set_yscale("log")
        ax.set_xlabel("n")
        ax.set_ylabel("mean-curvature error, rel. L1 %")
        ax.set_title(f"{sampler} sampler")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"plot written to {path}")


if __name__ == "__main__":
    sys.exit(main())
