"""heatcurv._kernels.chordfit: the compiled chord fit against its numpy reference (tests/reference/chordfit.py)."""

import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree

from heatcurv import surfaces
from heatcurv._kernels.chordfit import solve_compiled
from heatcurv.chordfit import chord_fit, solve_normal_equations
from heatcurv.kernel import ball_taper
from heatcurv.neighbourhood import Neighbourhood, ball_neighbourhood
from reference import chordfit as reference

# Both sum the same per-pair terms, in another order (blocked matrix products
# against a loop over the pairs): they differ by rounding, amplified by the
# condition number of the normal matrices (up to about 1e6 measured for the
# 9-column fit; measured differences up to 1e-10 relative). 1e-9 leaves a margin,
# while any real difference (a column, a weight, a pass) shows at 1e-3 or more.
RTOL = 1e-9


def cloud(sample, k=60, queries=None):
    """Points, the k-neighbour ball neighbourhood of ``queries`` (default all) and heat-kernel weights."""
    pts = sample.points
    tree = cKDTree(pts)
    q = pts if queries is None else queries
    d, _ = tree.query(q, k=k + 1)
    nb = ball_neighbourhood(pts, d[:, -1], tree=tree, queries=q)
    w = np.exp(-(nb.distances**2) / np.repeat(nb.radius / 2, nb.counts) ** 2) * ball_taper(nb)
    return pts, nb, w


#: The forms compared: chord, denoised, and the denoised form's low-noise refit (heatcurv.chordfit.chord_fit).
FORMS = [(False, False), (True, False), (True, True)]


def both(*args, **kwargs):
    """The numpy reference's fit and the compiled one."""
    return reference.chord_fit(*args, **kwargs), chord_fit(*args, **kwargs)


def assert_same_fit(ref, fit):
    """Every field of two ChordFits agrees to RTOL (directions up to sign)."""
    a, b = ref.principal, fit.principal
    np.testing.assert_array_equal(b.well_posed, a.well_posed)
    for name in ("k1", "k2", "mean", "gaussian"):
        x, y = getattr(a, name), getattr(b, name)
        # values near zero (k2 on the torus' top circles) are compared on the field's scale
        np.testing.assert_allclose(y, x, rtol=RTOL, atol=RTOL * np.abs(x).max(), err_msg=name)
    np.testing.assert_allclose(fit.sigma, ref.sigma, rtol=RTOL, atol=RTOL * ref.sigma.max())
    # unit vectors: absolute differences are relative ones
    np.testing.assert_allclose(fit.normals, ref.normals, rtol=0, atol=RTOL)
    # principal directions up to sign, where k1 - k2 leaves them defined
    sign = np.where(np.einsum("ij,ij->i", a.d1, b.d1) < 0, -1.0, 1.0)[:, None]
    distinct = (a.k1 - a.k2) > 1e-3 * np.abs(a.mean)
    assert distinct.mean() > 0.9
    np.testing.assert_allclose((b.d1 * sign)[distinct], a.d1[distinct], rtol=0, atol=RTOL)
    np.testing.assert_allclose((b.d2 * sign)[distinct], a.d2[distinct], rtol=0, atol=RTOL)
    # the variance factor is c^T G^-1 G2 G^-1 c: where a neighbour nearly coincides with
    # the centre (0.3 % of the ball radius) its (2 / D^2)^2 dominates G2 and the form
    # cancels up to 1e9-fold (measured), in either path; elsewhere it agrees to RTOL
    x, y = ref.mean_variance_factor, fit.mean_variance_factor
    rel = np.abs(y - x) / np.maximum(np.abs(x), 1e-300)
    assert np.quantile(rel, 0.99) < RTOL
    assert rel.max() < 1e-4


@pytest.fixture(scope="module")
def torus():
    sample = surfaces.Torus().sample(2000, "random", seed=3)
    return (sample.normals,) + cloud(sample)


@pytest.fixture(scope="module")
def noisy_sphere():
    # noise 0.5 % of the bounding-box diagonal
    sample = surfaces.Sphere().sample(2000, "random", seed=4, noise=0.005)
    return (sample.normals,) + cloud(sample)


@pytest.mark.parametrize("denoise, low_noise", FORMS)
@pytest.mark.parametrize("case", ["torus", "noisy_sphere"])
def test_compiled_fit_matches_reference(case, denoise, low_noise, request):
    normals, pts, nb, w = request.getfixturevalue(case)
    assert_same_fit(*both(pts, nb, normals, w, denoise=denoise, low_noise=low_noise))


@pytest.mark.parametrize("denoise, low_noise", FORMS)
@pytest.mark.parametrize("tilt, cubic, passes", [(False, False, 1), (True, False, 2), (False, True, 2)])
def test_compiled_fit_matches_reference_without_terms(torus, tilt, cubic, passes, denoise, low_noise):
    normals, pts, nb, w = torus
    assert_same_fit(*both(pts, nb, normals, w, tilt=tilt, cubic=cubic, passes=passes, denoise=denoise,
                          low_noise=low_noise))


@pytest.mark.parametrize("denoise, low_noise", FORMS)
def test_compiled_fit_matches_reference_on_given_centres(denoise, low_noise):
    # a subset of the points as centres, as select_scale fits them
    sample = surfaces.Torus().sample(3000, "random", seed=5, noise=0.002)
    sub = np.sort(np.random.default_rng(0).choice(3000, 500, replace=False))
    pts, nb, w = cloud(sample, queries=sample.points[sub])
    ref, fit = both(pts, nb, sample.normals[sub], w, denoise=denoise, low_noise=low_noise, centres=pts[sub])
    assert_same_fit(ref, fit)


@pytest.mark.parametrize("denoise, low_noise", FORMS)
def test_compiled_fit_matches_reference_on_degenerate_rows(denoise, low_noise):
    # centres straight above the points of a grid on a saddle, normals (0, 0, 1):
    # the point below each centre has r = 0 exactly (its direction is a convention)
    g = np.arange(-10, 11) * 0.05
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    pts = np.c_[x, y, 0.3 * (x * x - y * y)]
    inner = np.flatnonzero((np.abs(x) < 0.3) & (np.abs(y) < 0.3))
    centres = pts[inner] + [0.0, 0.0, 0.01]
    normals = np.tile([0.0, 0.0, 1.0], (len(inner), 1))
    nb = ball_neighbourhood(pts, 0.2, queries=centres)
    # and one centre without any neighbour
    empty = 7
    keep = nb.rows != empty
    counts = nb.counts.copy()
    counts[empty] = 0
    nb = Neighbourhood(
        np.concatenate([[0], np.cumsum(counts)]), nb.indices[keep], nb.distances[keep], nb.radius, nb.augmented
    )
    w = np.exp(-(nb.distances**2) / np.repeat(nb.radius / 2, nb.counts) ** 2)
    ref, fit = both(pts, nb, normals, w, denoise=denoise, low_noise=low_noise, centres=centres)
    assert not ref.principal.well_posed[empty] and ref.principal.mean[empty] == 0
    np.testing.assert_array_equal(fit.principal.well_posed, ref.principal.well_posed)
    for name in ("k1", "k2", "mean", "gaussian"):
        x_, y_ = getattr(ref.principal, name), getattr(fit.principal, name)
        np.testing.assert_allclose(y_, x_, rtol=RTOL, atol=RTOL * np.abs(x_).max(), err_msg=name)
    np.testing.assert_allclose(fit.normals, ref.normals, rtol=0, atol=RTOL)
    np.testing.assert_allclose(fit.sigma, ref.sigma, rtol=RTOL, atol=RTOL * ref.sigma.max())
    np.testing.assert_allclose(fit.mean_variance_factor, ref.mean_variance_factor, rtol=1e-6)


def test_compiled_fit_is_exact_on_a_sphere():
    sample = surfaces.Sphere(radius=2.0).sample(3000, "random", seed=0)
    pts, nb, w = cloud(sample)
    fit = chord_fit(pts, nb, pts / 2.0, w)
    # exact up to the solver's ridge
    np.testing.assert_allclose(fit.principal.mean, 0.5, rtol=1e-5)
    np.testing.assert_allclose(fit.principal.k1, 0.5, rtol=1e-5)
    np.testing.assert_allclose(fit.principal.k2, 0.5, rtol=1e-5)
    assert np.median(fit.sigma) < 1e-9


def test_kernels_import_nothing_from_the_stages():
    """Imports go one way, stage -> _kernels: the kernels load (and run) without the rest of heatcurv.

    ``import heatcurv._kernels.chordfit`` runs heatcurv/__init__, which imports every
    stage; a bare package module stands in for it here, so whatever else gets loaded
    was imported by the kernels themselves.
    """
    code = (
        "import importlib.util, sys, types\n"
        "import numpy as np\n"
        "package = types.ModuleType('heatcurv')\n"
        "package.__path__ = list(importlib.util.find_spec('heatcurv').submodule_search_locations)\n"
        "sys.modules['heatcurv'] = package\n"
        "import heatcurv._kernels.chordfit as c, heatcurv._kernels.segment as s\n"
        "G = np.eye(3)[None].repeat(2, 0)\n"
        "beta = c.solve_compiled(G, np.ones((2, 3)), np.ones(2))[0]\n"
        "assert np.allclose(beta, 1.0) and s.taper_sums(np.array([0, 1]), np.array([0.5]), np.ones(1), 0.7)[0] == 1.0\n"
        "print(' '.join(sorted(m for m in sys.modules if m.startswith('heatcurv'))))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    loaded = out.stdout.split()
    assert loaded == ["heatcurv", "heatcurv._kernels", "heatcurv._kernels.chordfit", "heatcurv._kernels.segment"]


def test_compiled_solve_matches_numpy_and_decides_well_posedness_exactly():
    """Cholesky solve and the trace bracket of the condition number against LU and eigenvalues."""
    rng = np.random.default_rng(0)
    n, p = 3000, 9
    X = rng.normal(size=(n, 30, p))
    # condition numbers across the 1e10 threshold, and exactly singular matrices
    for i, eps in enumerate(np.logspace(-9, -2, 200)):
        X[i, :, 8] = X[i, :, 7] + eps * rng.normal(size=30)
    X[200:210, :, 8] = X[200:210, :, 7]
    G = np.einsum("nkp,nkq->npq", X, X)
    r = np.einsum("nkp,nk->np", X, rng.normal(size=(n, 30)))
    yy = 100 * np.abs(rng.normal(size=n))
    G2 = np.einsum("nkp,nkq->npq", X, 2 * X)
    c = np.zeros(p)
    c[[0, 2]] = 0.5
    beta, rss, ok, var = solve_normal_equations(G, r, yy, contrast=c, G2=G2)
    cbeta, crss, cok, cvar = solve_compiled(G, r, yy, contrast=c, G2=G2)
    assert np.array_equal(ok, cok)
    assert 0 < ok[:200].sum() < 200  # the threshold really lies inside the tested range
    good = ok
    # well-posed rows: kappa <= 1e10, so the two solves agree to ~kappa * eps
    np.testing.assert_allclose(cbeta[good], beta[good], rtol=1e-5, atol=1e-9 * np.abs(beta[good]).max())
    np.testing.assert_allclose(cbeta[210:], beta[210:], rtol=1e-9)
    np.testing.assert_allclose(crss[210:], rss[210:], rtol=1e-8)
    np.testing.assert_allclose(cvar[210:], var[210:], rtol=1e-8)
