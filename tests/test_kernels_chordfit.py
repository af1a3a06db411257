"""heatcurv._kernels.chordfit: the compiled chord fit against its numpy reference (tests/reference/chordfit.py)."""

import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree

from heatcurv import surfaces
from heatcurv._kernels.chordfit import solve_compiled
from heatcurv.fits.chordfit import chord_fit, refine_normals
from heatcurv.geometry.neighbourhood import Neighbourhood, ball_neighbourhood
from heatcurv.operators.kernel import ball_taper
from heatcurv.orient.normals import tangent_frames
from reference import chordfit as reference
from reference.lstsq import solve_normal_equations

# The reference (tests/reference/chordfit.py) shares no code with the compiled fit: it solves each
# centre's least squares by the SVD of W^(1/2) X where the compiled fit accumulates X^T W X and
# solves it by Cholesky, so they differ by rounding amplified by the normal matrices' condition
# numbers. Measured (largest |compiled - reference| / (|reference| + max |reference|) over every
# case below): curvatures 4.2e-14, sigma 6.5e-14, normals 5.5e-14, principal directions 9.0e-14,
# the model's values 1.1e-13. RTOL = 1e-11 is 90x the largest (room for another CPU's summation
# order and LAPACK); the smallest real difference tried, a ridge twice as large (2e-10), moves the
# mean curvature by 6e-9 to 4e-7.
RTOL = 1e-11
# the grid under a saddle (test_compiled_fit_matches_reference_on_degenerate_rows), whose quartic
# fits are the worst conditioned: measured 4.9e-12 (sigma, mean curvature), 1.8e-12 (the model)
RTOL_DEGENERATE = 1e-10
#: Tangent directions, as angles from the reference's e1, along which the two fits' models are compared.
ANGLES = 2 * np.pi * np.arange(12) / 12 + 0.1


def cloud(sample, k=60, queries=None):
    """Points, the k-neighbour ball neighbourhood of ``queries`` (default all) and heat-kernel weights."""
    pts = sample.points
    tree = cKDTree(pts)
    q = pts if queries is None else queries
    d, _ = tree.query(q, k=k + 1)
    nb = ball_neighbourhood(pts, d[:, -1], tree=tree, queries=q)
    w = np.exp(-(nb.distances**2) / np.repeat(nb.radius / 2, nb.counts) ** 2) * ball_taper(nb)
    return pts, nb, w


#: The forms compared: chord, denoised, and the denoised form's low-noise refit (heatcurv.fits.chordfit.chord_fit).
FORMS = [(False, False), (True, False), (True, True)]


def both(*args, **kwargs):
    """The numpy reference's fit and the compiled one."""
    return reference.chord_fit(*args, **kwargs), chord_fit(*args, **kwargs)


def model_parts(coefficients, e1, e2, directions):
    """The fitted model's tensor, tilt, cubic (and quartic) parts along tangent ``directions``.

    ``coefficients`` (shape (n, 9) or (n, 14)) in the frame ``(e1, e2)``; ``directions`` shape (n, k, 3).
    Returns shape (n, k, parts): ``a c^2 + 2 b c s + d s^2``, ``t1 c + t2 s``, ``g0 c^3 + .. + g3 s^3``
    (and ``q0 c^4 + .. + q4 s^4``), with ``c, s`` the directions' components along ``e1, e2``.
    """
    c = np.einsum("nkj,nj->nk", directions, e1)
    s = np.einsum("nkj,nj->nk", directions, e2)
    k = coefficients[:, None, :]
    parts = [
        k[..., 0] * c * c + 2 * k[..., 1] * c * s + k[..., 2] * s * s,
        k[..., 3] * c + k[..., 4] * s,
        k[..., 5] * c**3 + k[..., 6] * c * c * s + k[..., 7] * c * s * s + k[..., 8] * s**3,
    ]
    if coefficients.shape[1] == 14:
        q = [k[..., 9 + a] * c ** (4 - a) * s**a for a in range(5)]
        parts.append(sum(q))
    return np.stack(parts, axis=-1)


def assert_same_model(ref, fit, rtol):
    """The two fits' models agree along common tangent directions, each in its own documented frame.

    The compiled coefficients are given in ``heatcurv.orient.normals.tangent_frames(fit.normals)``; comparing
    the models' values rather than the coefficients keeps the check valid where the two normals, equal
    to rounding, pick different frames (a normal with two equal smallest components, e.g. (0, 0, 1)).
    """
    assert fit.coefficients.shape == ref.coefficients.shape
    r1, r2 = reference.tangent_frames(ref.normals)
    directions = np.cos(ANGLES)[None, :, None] * r1[:, None] + np.sin(ANGLES)[None, :, None] * r2[:, None]
    expected = model_parts(ref.coefficients, r1, r2, directions)
    got = model_parts(fit.coefficients, *tangent_frames(fit.normals), directions)
    # rounding scales with each centre's largest coefficient
    scale = np.abs(ref.coefficients).max(axis=1)[:, None, None]
    apart = np.abs(got - expected) / np.maximum(scale, 1e-300)
    worst = np.unravel_index(np.argmax(apart), apart.shape)
    assert apart.max() <= rtol, f"models {apart.max():.2e} apart (centre, direction, part: {worst})"


def assert_same_fit(ref, fit, rtol=RTOL):
    """Every field of two ChordFits agrees to ``rtol`` (directions up to sign, the model in any frame)."""
    a, b = ref.principal, fit.principal
    np.testing.assert_array_equal(b.well_posed, a.well_posed)
    for name in ("k1", "k2", "mean", "gaussian"):
        x, y = getattr(a, name), getattr(b, name)
        # values near zero (k2 on the torus' top circles) are compared on the field's scale
        np.testing.assert_allclose(y, x, rtol=rtol, atol=rtol * np.abs(x).max(), err_msg=name)
    np.testing.assert_allclose(fit.sigma, ref.sigma, rtol=rtol, atol=rtol * ref.sigma.max())
    # unit vectors: absolute differences are relative ones
    np.testing.assert_allclose(fit.normals, ref.normals, rtol=0, atol=rtol)
    # principal directions up to sign, where k1 - k2 leaves them defined
    sign = np.where(np.einsum("ij,ij->i", a.d1, b.d1) < 0, -1.0, 1.0)[:, None]
    distinct = (a.k1 - a.k2) > 1e-3 * np.abs(a.mean)
    assert distinct.mean() > 0.9
    np.testing.assert_allclose((b.d1 * sign)[distinct], a.d1[distinct], rtol=0, atol=rtol)
    np.testing.assert_allclose((b.d2 * sign)[distinct], a.d2[distinct], rtol=0, atol=rtol)
    assert_same_model(ref, fit, rtol)
    # the variance factor c^T G^-1 G2 G^-1 c: where a neighbour nearly coincides with the centre
    # (under 1 % of the ball radius) its (2 / D^2)^2 dominates G2 and the compiled quadratic form loses
    # digits (the reference sums the pairs' squared sensitivities instead: against exact rational
    # arithmetic on the same columns, at the torus' three worst centres, the compiled factor is off by
    # 8e-11 to 1.7e-10, the reference's by 9e-12 at most); measured: 99th percentile 3.5e-12, largest 1.8e-10
    x, y = ref.mean_variance_factor, fit.mean_variance_factor
    rel = np.abs(y - x) / np.maximum(np.abs(x), 1e-300)
    assert np.quantile(rel, 0.99) < 1e-10
    assert rel.max() < 1e-8
    assert_same_noise_factors(ref, fit, distinct)


def assert_same_noise_factors(ref, fit, distinct):
    """The five noise factors (the sandwich covariance carried to mean, k1, k2, K and the normal) agree.

    The reference propagates its own covariance (pair sensitivities) through numpy's
    eigenvectors; the principal columns are compared where ``k1 - k2`` defines the directions.
    Measured on these clouds: 99th percentile 1e-11 or less, largest 4e-9 (the mean's own case above).
    """
    assert fit.noise_factors.shape == ref.noise_factors.shape == (len(fit.sigma), 5)
    for column, name in enumerate(("mean", "k1", "k2", "gaussian", "normal")):
        rows = distinct if name in ("k1", "k2") else slice(None)
        x, y = ref.noise_factors[rows, column], fit.noise_factors[rows, column]
        rel = np.abs(y - x) / np.maximum(np.abs(x), 1e-300)
        assert np.quantile(rel, 0.99) < 1e-10, name
        assert rel.max() < 1e-8, name


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
    ref, fit = both(pts, nb, normals, w, denoise=denoise, low_noise=low_noise)
    assert_same_fit(ref, fit)
    if low_noise:  # the clean torus takes the low-noise refit at almost every centre (99.7 %), the noisy sphere at none
        refit = (ref.coefficients[:, 9:] != 0).any(axis=1).mean()
        assert refit > 0.95 if case == "torus" else refit == 0


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
        np.testing.assert_allclose(y_, x_, rtol=RTOL_DEGENERATE, atol=RTOL_DEGENERATE * np.abs(x_).max(), err_msg=name)
    np.testing.assert_allclose(fit.normals, ref.normals, rtol=0, atol=RTOL_DEGENERATE)
    np.testing.assert_allclose(fit.sigma, ref.sigma, rtol=RTOL_DEGENERATE, atol=RTOL_DEGENERATE * ref.sigma.max())
    assert_same_model(ref, fit, RTOL_DEGENERATE)
    # without neighbours the variance is undefined: NaN in both; elsewhere measured 8.5e-13 apart
    assert np.isnan(ref.mean_variance_factor[empty]) and np.isnan(fit.mean_variance_factor[empty])
    np.testing.assert_allclose(fit.mean_variance_factor, ref.mean_variance_factor, rtol=1e-11)
    assert np.isnan(ref.noise_factors[empty]).all() and np.isnan(fit.noise_factors[empty, :4]).all()
    np.testing.assert_allclose(fit.noise_factors, ref.noise_factors, rtol=1e-11)


@pytest.mark.parametrize("denoise", [False, True])
@pytest.mark.parametrize("tilt, cubic", [(True, True), (True, False), (False, True)])
def test_compiled_refinement_matches_reference(torus, tilt, cubic, denoise):
    # the stage normal_refinement from normals tilted by about 3.5 degrees (measured 2.5e-14 apart at most)
    normals, pts, nb, w = torus
    tilted = normals + 0.05 * np.random.default_rng(2).normal(size=normals.shape)
    tilted /= np.linalg.norm(tilted, axis=1)[:, None]
    args = pts, nb, tilted, w
    got = refine_normals(*args, tilt=tilt, cubic=cubic, denoise=denoise)
    expected = reference.refine_normals(*args, tilt=tilt, cubic=cubic, denoise=denoise)
    np.testing.assert_allclose(got, expected, rtol=0, atol=RTOL)


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


def ridge_solution(G, r, yy, c, G2, ridge=1e-10):
    """The documented solve, written out: ``(G + ridge trace(G) / p I) beta = r``, the residual
    ``y^T W y - 2 beta . r + beta^T G beta``, ``well_posed = lambda_min(G) > 1e-10 lambda_max(G)`` and
    the variance factor ``u^T G2 u`` with ``u = (G + ridge trace(G) / p I)^-1 c``; LAPACK's LU and eigh."""
    p = G.shape[1]
    Greg = G + (ridge * np.trace(G, axis1=1, axis2=2) / p)[:, None, None] * np.eye(p)
    beta = np.linalg.solve(Greg, r[:, :, None])[:, :, 0]
    rss = yy - 2 * np.einsum("np,np->n", beta, r) + np.einsum("np,npq,nq->n", beta, G, beta)
    evals = np.linalg.eigvalsh(G)
    u = np.linalg.solve(Greg, np.broadcast_to(c, r.shape)[:, :, None])[:, :, 0]
    return beta, np.maximum(rss, 0.0), evals[:, 0] > 1e-10 * evals[:, -1], np.einsum("np,npq,nq->n", u, G2, u)


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
    beta, rss, ok, var = ridge_solution(G, r, yy, c, G2)
    cbeta, crss, cok, cvar = solve_compiled(G, r, yy, contrast=c, G2=G2)
    assert np.array_equal(ok, cok)
    assert 0 < ok[:200].sum() < 200  # the threshold really lies inside the tested range
    good = ok
    # well-posed rows: kappa <= 1e10, so the two solves agree to ~kappa * eps (measured: 3.9e-7)
    np.testing.assert_allclose(cbeta[good], beta[good], rtol=1e-5, atol=1e-9 * np.abs(beta[good]).max())
    # well-conditioned rows, measured: beta 2.7e-12, rss 4.5e-13, variance 2.3e-15
    np.testing.assert_allclose(cbeta[210:], beta[210:], rtol=1e-10)
    np.testing.assert_allclose(crss[210:], rss[210:], rtol=1e-11)
    np.testing.assert_allclose(cvar[210:], var[210:], rtol=1e-13)
    # the numpy helper of heatcurv.fits.chordfit solves the same equations (measured: identical)
    np.testing.assert_allclose(solve_normal_equations(G, r, yy, contrast=c, G2=G2)[0][210:], beta[210:], rtol=1e-12)
