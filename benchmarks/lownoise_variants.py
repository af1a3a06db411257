"""Very-low-noise band (issue 12, bullet 3): forms of the default fit at one fixed kernel width.

Measures, at fixed ``k`` and at up to ``--eval-points`` interior centres of the
low-noise table's clouds (``benchmarks/accuracy.py --tables lownoise``: random
sampler, n = 20 000, the same seed), the relative L1 errors of the mean and
principal curvatures and the d1 direction error of forms of the fit, written
in numpy with per-pair arrays (the weights ``W_ij A_j`` and the starting normals
as the default estimator's; areas and normals from ``heatcurv.estimate(scale=60)``):

* ``chord``: the default clean form (kN response, ``heatcurv.chordfit``);
* ``chord+z0``: the chord fit as a height fit weighted ``4 / D^4`` with a
  centre offset ``z0`` (the centre's own noise);
* ``denoised``: today's denoised form (plain height fit, then the refit with
  ``D^2 = r^2 + zhat^2``);
* ``denoised-exact``: idea (a), ``zhat`` consistent with the chord model,
  ``(1 - sqrt(1 - m^2 r^2)) / m``;
* ``lam<L>``: idea (b), the denoised refit with pair weights
  ``W lambda^4 / (D^4 + lambda^4)`` (``lambda = L`` ball radii; chord-like near
  the centre, height-like beyond ``lambda``);
* ``auto``: ``lambda^2 = sigma / S0`` from the height fit's residual ``sigma``
  (units of the ball radius), ``--s0``;
* suffix ``Q``: quartic terms ``r^2 c^4 ... r^2 s^4`` in the kN model, in the
  refit and (for ``D``) in the height fit.

Run ``python benchmarks/lownoise_variants.py --help``. These are the fits at the
centres themselves. The default estimator uses ``autoQ`` under very low noise
(:attr:`heatcurv.scale.ScaleChoice.low_noise`, :func:`heatcurv.chordfit._denoised_refit`),
fitted at anchors 24 per ball and regressed to every point (:mod:`heatcurv.anchors`),
with the kernel one doubling wider than Lepski's rule chose: on the torus at 1e-5
that reaches mean 0.162 %, k2 0.40 % (240 neighbours; 480 gave 0.135 % and 0.35 % but
was too wide at 3e-5 and 1e-4) against this script's 0.125 % and 0.23 % at 480 neighbours.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scipy.spatial import cKDTree

import heatcurv
from heatcurv.kernel import tapered_heat_weights
from heatcurv.neighbourhood import knn_neighbourhood
from heatcurv.normals import tangent_frames
from heatcurv.principal import tensor_to_principal

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # tests/reference: the numpy least squares
import accuracy as acc  # noqa: E402  (benchmarks/accuracy.py: the low-noise table's clouds and measures)
from reference.lstsq import segment_lstsq  # noqa: E402

#: The fixed forms (name -> keyword arguments of :func:`fit_form`); ``lam<L>`` and ``auto`` are parsed.
FORMS = {
    "chord": dict(form="chord"),
    "chord+z0": dict(form="height", denominator="observed", offset=True, lam=0.0),
    "denoised": dict(form="height", denominator="jet", offset=True),
    "denoised-exact": dict(form="height", denominator="exact", offset=True),
}


def form_arguments(name: str, s0: float) -> dict:
    """Keyword arguments of :func:`fit_form` for a form's name (see the module docstring)."""
    quartic = name.endswith("Q")
    base = name[:-1] if quartic else name
    if base in FORMS:
        kw = dict(FORMS[base])
    elif base == "auto":
        kw = dict(form="height", denominator="jet", offset=True, lam=-s0)
    elif base.startswith("lam"):
        kw = dict(form="height", denominator="jet", offset=True, lam=float(base[3:]))
    else:
        raise SystemExit(f"unknown form {name!r}")
    kw["quartic"] = quartic
    return kw


def shape_columns(x, y, quartic: bool):
    """kN model columns: tensor, tilt, cubic (``tests/reference/chordfit.py``) and optionally quartic."""
    r2 = x * x + y * y
    safe = np.where(r2 > 0, r2, 1.0)
    cols = [x * x / safe, 2 * x * y / safe, y * y / safe, x / safe, y / safe,
            x**3 / safe, x * x * y / safe, x * y * y / safe, y**3 / safe]
    if quartic:
        cols += [x**4 / safe, x**3 * y / safe, x * x * y * y / safe, x * y**3 / safe, y**4 / safe]
    return np.stack(cols, 1), r2


def unbiased_sigma(nbhd, weights, resid, p):
    """Weighted RMS residual per centre with the degrees-of-freedom correction of the compiled fit."""
    total = nbhd.segment_sum(weights)
    mean_sq = nbhd.segment_sum(weights * resid * resid) / np.maximum(total, 1e-300)
    n_eff = total * total / np.maximum(nbhd.segment_sum(weights * weights), 1e-300)
    return np.sqrt(mean_sq / np.maximum(1.0 - p / np.maximum(n_eff, 1e-300), 0.1))


def fit_form(case, k, form="chord", denominator="observed", offset=False, lam=None, quartic=False, passes=2):
    """One form's curvatures at the case's centres; ``lam``: None (weights W), > 0 (ball radii), < 0 (auto, -S0)."""
    nb = knn_neighbourhood(case.points, k, tree=case.tree, queries=case.points[case.at])
    w0 = tapered_heat_weights(nb, nb.radius / 2.0, case.areas)
    unit = np.repeat(nb.radius, nb.counts)
    rows = nb.rows
    nrm = case.normals
    for number in range(passes):
        e1, e2 = tangent_frames(nrm)
        d = case.points[nb.indices] - case.points[case.at][rows]
        x, y, z = (np.einsum("ij,ij->i", d, v[rows]) / unit for v in (e1, e2, nrm))
        cols, r2 = shape_columns(x, y, quartic)
        if form == "chord":
            D2 = r2 + z * z
            beta = segment_lstsq(nb, cols, -2 * z / np.where(D2 > 0, D2, 1.0), w0)[0]
        else:
            if denominator == "observed":
                D2 = r2 + z * z
            else:
                jet = np.concatenate([-0.5 * r2[:, None] * cols, np.ones((r2.size, 1))], 1)
                hb = segment_lstsq(nb, jet, z, w0)[0]
                model = np.einsum("ij,ij->i", cols, hb[rows, :-1])
                if denominator == "jet":
                    zhat = -0.5 * r2 * model
                else:  # chord-consistent heights of the jet's normal curvature
                    zhat = -r2 * model / (1 + np.sqrt(np.clip(1 - model * model * r2, 0, None)))
                D2 = r2 + zhat * zhat
            weights = w0
            if lam is not None:
                if lam < 0:
                    resid = z - np.einsum("ij,ij->i", jet, hb[rows])
                    lam4 = np.repeat((unbiased_sigma(nb, w0, resid, jet.shape[1]) / -lam) ** 2, nb.counts)
                else:
                    lam4 = lam**4
                weights = w0 / (D2 * D2 + lam4)
            design = -0.5 * D2[:, None] * cols
            if offset:
                design = np.concatenate([design, np.ones((r2.size, 1))], 1)
            beta = segment_lstsq(nb, design, z, weights)[0]
        if number < passes - 1:  # the tilt corrects the normal
            nrm = nrm + 0.5 * beta[:, 3, None] * e1 + 0.5 * beta[:, 4, None] * e2
            nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    a, b, dd = (beta[:, j] / nb.radius for j in range(3))
    pc = tensor_to_principal(0.5 * (a + dd), 0.5 * (a - dd), b, e1, e2, nrm)
    view = SimpleNamespace(normals=nrm, mean=pc.mean, gaussian=pc.gaussian, k1=pc.k1, k2=pc.k2, d1=pc.d1,
                           d2=pc.d2, reliable=np.ones(pc.mean.shape, bool))
    return acc.measure_view(acc.subset_sample(case.sample, case.at), view)


def make_case(surface: str, noise: float, n: int, seed: int | None, eval_points: int):
    """The low-noise table's cloud (its seed unless ``seed``), its evaluation centres, areas and normals."""
    seed = acc.seed_of(surface, "lownoise", n) if seed is None else seed
    sample = acc.make_surface(surface).sample(n, "random", noise=noise, seed=seed)
    at = acc.eval_rows(sample, acc.eval_margin(sample), eval_points, seed)
    res = heatcurv.estimate(sample.points, scale=60)
    points = sample.points - sample.points.mean(axis=0)
    return SimpleNamespace(sample=sample, at=at, points=points, tree=cKDTree(points),
                           areas=np.asarray(res.area), normals=np.asarray(res.normals)[at])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--surfaces", nargs="+", default=["torus"])
    parser.add_argument("--noises", nargs="+", type=float, default=[0.0, 1e-5, 1e-4])
    parser.add_argument("--ks", nargs="+", type=int, default=[60, 120, 240, 480])
    parser.add_argument("--forms", nargs="+", default=["chord", "denoised", "denoised-exact", "lam0.5Q", "autoQ"])
    parser.add_argument("--s0", type=float, default=6e-4, help="auto: lambda^2 = sigma / S0 (default 6e-4)")
    parser.add_argument("--n", type=int, default=acc.LOWNOISE_N)
    parser.add_argument("--seed", type=int, default=None, help="another seed than the low-noise table's")
    parser.add_argument("--eval-points", type=int, default=3000)
    args = parser.parse_args(argv)
    for surface in args.surfaces:
        for noise in args.noises:
            case = make_case(surface, noise, args.n, args.seed, args.eval_points)
            for k in args.ks:
                for name in args.forms:
                    tic = time.perf_counter()
                    m = fit_form(case, k, **form_arguments(name, args.s0))
                    print(f"{surface:7s} noise {noise:<7g} k {k:<5d} {name:15s} mean {m['mean']:.3g} % "
                          f"k1 {m['k1']:.3g} % k2 {m['k2']:.3g} % d1 {m['d1']:.3g} deg "
                          f"({time.perf_counter() - tic:.1f} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
