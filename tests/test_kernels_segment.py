"""heatcurv._kernels.segment: every compiled kernel against its numpy reference (tests/reference/segment.py).

A kernel and its reference differ only in the order floating-point terms are
summed (and the eigensolver), so they agree to rounding. Measured, and the bounds:
sums 3.6e-13 relative at most (bound 1e-10), taper sums 3.5e-16 (1e-12);
eigenvectors 4.6e-15, eigenvalues 7.1e-14 (1e-12, 1e-11); the stages with the
references 3.6e-13 (1e-10), their PCA normals 4.6e-15 (1e-12); the whole estimate
with every kernel and the chord fit replaced by its reference 8.7e-15 in the
curvatures and areas, 1.8e-14 in the normals (1e-11).
"""

import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
import heatcurv._kernels.segment as compiled
from heatcurv import surfaces
from heatcurv.fits.chordfit import chord_fit
from heatcurv.flags.border import centroid_offset
from heatcurv.flags.outliers import find_outliers, neighbour_medians
from heatcurv.flags.sheets import facing_pairs, second_sheet
from heatcurv.geometry.neighbourhood import Neighbourhood, knn_neighbourhood
from heatcurv.operators.areas import density_areas, taper_sums
from heatcurv.operators.kernel import TAPER_START, ball_taper, heat_kernel_weights, tapered_heat_weights
from heatcurv.operators.mean_curvature import mean_curvature_normal
from heatcurv.orient.normals import orient_normals, pca_normals
from reference import chordfit as reference_chordfit
from reference import segment as reference


@pytest.fixture(scope="module")
def torus_cloud():
    sample = surfaces.Torus().sample(6000, "random", seed=3)
    pts = sample.points
    return pts, sample.normals, knn_neighbourhood(pts, 40, tree=cKDTree(pts))


@pytest.fixture(scope="module")
def ball_cloud():
    """CSR ball neighbourhoods built here: rows of different lengths, ascending indices, five empty rows."""
    rng = np.random.default_rng(7)
    pts = rng.random((1500, 3)) * [1.0, 1.0, 0.05]
    pts[:5] += 10.0  # isolated: no neighbour within the ball
    rows = [sorted(set(r) - {i}) for i, r in enumerate(cKDTree(pts).query_ball_point(pts, 0.08))]
    indptr = np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64)
    indices = np.concatenate(rows).astype(np.int64)
    distances = np.linalg.norm(pts[indices] - pts[np.repeat(np.arange(1500), np.diff(indptr))], axis=1)
    nb = Neighbourhood(indptr, indices, distances, np.full(1500, 0.08), np.zeros(1500, dtype=bool))
    assert (nb.counts[:5] == 0).all() and nb.counts[5:].min() > 0 and nb.counts.max() > 2 * nb.counts[5:].min()
    normals = rng.normal(size=(1500, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    return pts, normals, nb


def close(actual, desired, rtol=1e-10):
    """Sums: relative to each value, and to the largest one for values near zero."""
    np.testing.assert_allclose(actual, desired, rtol=rtol, atol=1e-12 * np.nanmax(np.abs(desired)))


@pytest.mark.parametrize("cloud", ["torus_cloud", "ball_cloud"])
@pytest.mark.parametrize("index_dtype", [np.int32, np.int64])
def test_each_kernel_matches_its_reference(cloud, index_dtype, request):
    pts, normals, nb = request.getfixturevalue(cloud)
    indptr, indices, dist, radius = nb.indptr, nb.indices.astype(index_dtype), nb.distances, nb.radius
    rng = np.random.default_rng(1)
    areas = rng.uniform(0.5, 1.5, pts.shape[0])
    h = radius / 2
    args = {
        "orientation_costs": (pts, normals, indptr, indices, dist, radius),
        "tapered_heat_weights": (indptr, indices, dist, radius, 1.0 / h**2, areas, TAPER_START),
        "taper_sums": (indptr, dist, radius, TAPER_START),
        "kappa_normal_sums": (pts, indptr, indices, dist, 1.0 / h**2, np.empty(0), areas, False),
        "kappa_normal_sums/weights": (pts, indptr, indices, dist, 1.0 / h**2, rng.random(dist.size), areas, True),
    }
    for taper in (False, True):
        args[f"weighted_covariances/{taper}"] = (pts, indptr, indices, dist, radius, TAPER_START, taper)
        offset_args = (pts, pts + 0.01, indptr, indices, dist, radius, normals, TAPER_START, taper)
        args[f"centroid_offsets/{taper}"] = offset_args
    for key, a in args.items():
        name = key.split("/")[0]
        close(getattr(compiled, name)(*a), getattr(reference, name)(*a), rtol=1e-12 if name == "taper_sums" else 1e-10)


def test_eigenvectors_of_the_covariances_match_lapack(torus_cloud):
    pts, _, nb = torus_cloud
    for taper in (False, True):
        cov = compiled.weighted_covariances(pts, nb.indptr, nb.indices, nb.distances, nb.radius, TAPER_START, taper)
        vectors, values = compiled.smallest_eigenvectors(cov)
        ref_vectors, ref_values = reference.smallest_eigenvectors(cov)
        sign = np.sign(np.einsum("ij,ij->i", vectors, ref_vectors))
        np.testing.assert_allclose(vectors * sign[:, None], ref_vectors, rtol=0, atol=1e-12)
        np.testing.assert_allclose(values, ref_values, rtol=1e-11, atol=1e-12 * np.abs(ref_values).max())


def test_smallest_eigenvectors_against_lapack_on_hard_matrices():
    """The 3x3 Jacobi iteration against np.linalg.eigh.

    Random, near-planar (smallest eigenvalue 1e-12 of the largest), diagonal, zero and
    identity matrices: eigenvalues to 1e-12 of the largest, eigenvectors to 1e-10 wherever
    the smallest eigenvalue is separated (else any unit vector of its eigenspace is right).
    """
    rng = np.random.default_rng(11)
    A = rng.normal(size=(2000, 3, 3))
    cov = A @ A.transpose(0, 2, 1)
    flat = np.diag([1.0, 0.5, 1e-12])
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    cov[:100] = rot @ flat @ rot.T
    cov[100] = np.diag([3.0, 1.0, 2.0])
    cov[101] = 0.0
    cov[102] = np.eye(3)
    vectors, values = compiled.smallest_eigenvectors(cov)
    ref_vectors, ref_values = reference.smallest_eigenvectors(cov)
    scale = np.maximum(np.abs(ref_values).max(axis=1, keepdims=True), 1e-300)
    np.testing.assert_allclose(values / scale, ref_values / scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(vectors, axis=1), 1.0, rtol=1e-14)
    separated = (ref_values[:, 1] - ref_values[:, 0]) > 1e-6 * scale[:, 0]
    assert separated[:101].all() and not separated[101:103].any()
    alignment = np.abs(np.einsum("ij,ij->i", vectors, ref_vectors))
    np.testing.assert_allclose(alignment[separated], 1.0, rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.abs(vectors[100]), [0.0, 1.0, 0.0], rtol=0, atol=1e-15)


def with_references(monkeypatch, fit=False):
    """Make the stages call the numpy references instead of the kernels (and the reference chord fit).

    Returns the calls of each reference, filled in as the stages run.
    """
    calls = {}

    def counted(name, function):
        def call(*args, **kwargs):
            calls[name] = calls.get(name, 0) + 1
            return function(*args, **kwargs)

        return call

    for name in compiled.__all__:
        monkeypatch.setattr(compiled, name, counted(name, getattr(reference, name)))
    if fit:
        # chord_fit as imported by any heatcurv module (the scale choice, the estimator's blocks)
        for module in [m for name, m in sys.modules.items() if name.startswith("heatcurv") and m is not None]:
            if getattr(module, "chord_fit", None) is chord_fit:
                monkeypatch.setattr(module, "chord_fit", counted("chord_fit", reference_chordfit.chord_fit))
    return calls


def test_stages_give_the_same_with_the_references(torus_cloud, monkeypatch):
    pts, normals, nb = torus_cloud
    areas = density_areas(nb)
    h = nb.radius / 2
    scrambled = normals * np.where(np.arange(6000) % 3 == 0, -1.0, 1.0)[:, None]
    # the torus and a copy of it just inside, facing the other way: the two sides of a thin shell
    shell = np.vstack([pts, pts - 0.8 * np.median(h) * normals])
    shell_normals = np.vstack([normals, -normals])
    shell_nb = knn_neighbourhood(shell, 40)

    def stages():
        return dict(
            taper=taper_sums(nb),
            fit_weights=tapered_heat_weights(nb, h, areas),
            pca=pca_normals(pts, nb, taper=True),
            pca_plain=pca_normals(pts, nb),
            K=mean_curvature_normal(pts, nb, None, areas, h),
            K_given=mean_curvature_normal(pts, nb, heat_kernel_weights(nb, h), areas, h),
            offset=centroid_offset(pts, nb, normals, taper=True),
            oriented=orient_normals(pts, scrambled, nb),
            outliers=find_outliers(pts, nb).mask,
            medians=neighbour_medians(areas, nb),  # (find_outliers needs medians only for rows it cannot count)
            offset_centres=centroid_offset(pts, nb.rows_slice(10, 60), normals[10:60], centres=pts[10:60] + 0.01),
            sheets=second_sheet(shell, shell_normals, shell_nb, shell_nb.radius / 2),
            pairs=facing_pairs(shell, shell_normals, shell_nb, shell_nb.radius / 2),
        )

    b = stages()
    with monkeypatch.context() as patch:
        calls = with_references(patch)
        a = stages()
    assert set(calls) == set(compiled.__all__)
    np.testing.assert_allclose(b["taper"], a["taper"], rtol=1e-12)
    for key in ("pca", "pca_plain"):
        sign = np.sign(np.einsum("ij,ij->i", a[key][0], b[key][0]))
        np.testing.assert_allclose(b[key][0] * sign[:, None], a[key][0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(b[key][1], a[key][1], rtol=1e-12, atol=1e-12)
    expected = np.exp(-(nb.distances**2) / np.repeat(h, 40) ** 2) * ball_taper(nb) * areas[nb.indices]
    np.testing.assert_allclose(a["fit_weights"], expected, rtol=1e-13)
    assert np.array_equal(a["oriented"], b["oriented"]) and np.array_equal(a["sheets"], b["sheets"])
    assert a["sheets"].mean() > 0.5
    for got, want in zip(b["pairs"], a["pairs"]):
        np.testing.assert_allclose(got, want, rtol=1e-12)
    assert np.array_equal(a["outliers"], b["outliers"]) and np.array_equal(a["medians"], b["medians"])
    for key in ("K", "K_given", "offset", "offset_centres", "fit_weights"):
        np.testing.assert_allclose(b[key], a[key], rtol=1e-10, atol=1e-12 * np.abs(a[key]).max())
    # the taper used by the kernels is ball_taper's
    np.testing.assert_allclose(a["taper"], nb.segment_sum(ball_taper(nb)), rtol=1e-12)


def test_given_weights_take_the_numpy_path(torus_cloud):
    """pca_normals, centroid_offset with ``weights`` (numpy: no kernel takes them) give the kernels' taper results."""
    pts, normals, nb = torus_cloud
    taper = ball_taper(nb)
    n_w, planarity_w = pca_normals(pts, nb, weights=taper)
    n_t, planarity_t = pca_normals(pts, nb, taper=True)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", n_w, n_t)), 1.0, atol=1e-8)
    np.testing.assert_allclose(planarity_w, planarity_t, rtol=1e-8, atol=1e-12)
    close(centroid_offset(pts, nb, normals, weights=taper), centroid_offset(pts, nb, normals, taper=True))


@pytest.mark.parametrize("noise", [0.0, 0.004])
def test_estimate_same_with_the_references(noise, monkeypatch):
    """The whole default estimate with every kernel and the chord fit replaced by its numpy reference."""
    sample = surfaces.Sphere(radius=1.5).sample(4000, "random", seed=5)
    pts = sample.points + noise * np.random.default_rng(0).normal(size=sample.points.shape)
    b = heatcurv.estimate(pts)
    with monkeypatch.context() as patch:
        calls = with_references(patch, fit=True)
        a = heatcurv.estimate(pts)
    # the default estimate runs every kernel, and the chord fit (neighbour_medians only where the
    # outliers' counts leave a point undecided, which may be none; over_under_pairs only in a tile)
    assert set(calls) | {"neighbour_medians", "over_under_pairs"} == set(compiled.__all__) | {"chord_fit"}, calls
    assert a.info["scale"].fit == b.info["scale"].fit
    for name in ("mean", "gaussian", "k1", "k2", "area", "spacing", "mean_curvature_normal"):
        ref = getattr(a, name)
        np.testing.assert_allclose(getattr(b, name), ref, rtol=1e-11, atol=1e-11 * np.abs(ref).max())
    np.testing.assert_allclose(b.normals, a.normals, rtol=0, atol=1e-11)
    assert np.array_equal(a.reliable, b.reliable) and np.array_equal(a.border, b.border)


def test_importing_heatcurv_without_numba_says_numba_is_required():
    code = "import sys; sys.modules['numba'] = None\nimport heatcurv\n"  # makes `import numba` raise ImportError
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode != 0
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: heatcurv requires numba"), out.stderr
    assert "pip install numba" in last


@pytest.mark.parametrize("cloud", ["torus_cloud", "ball_cloud"])
@pytest.mark.parametrize("ties", [False, True])
def test_neighbour_medians(cloud, ties, request):
    # exact: a median is one of the values, or the mean of two (odd and even rows, empty rows NaN)
    pts, _, nb = request.getfixturevalue(cloud)
    values = pts[:, 0] + 2.0 * pts[:, 1]
    if ties:
        values = np.round(values * 4.0)  # many equal values: the quickselect's partition with duplicates
    got = compiled.neighbour_medians(values, nb.indptr, nb.indices)
    np.testing.assert_array_equal(got, reference.neighbour_medians(values, nb.indptr, nb.indices))


@pytest.mark.parametrize("cloud", ["torus_cloud", "ball_cloud"])
def test_counts_below_and_same_label_counts(cloud, request):
    pts, _, nb = request.getfixturevalue(cloud)
    values = np.round(4.0 * (pts[:, 0] + 2.0 * pts[:, 1]))  # ties: equal products are not below
    for factor in (1.0, 3.0):
        got = compiled.counts_below(values, factor, values, nb.indptr, nb.indices)
        assert got.dtype == np.int64
        np.testing.assert_array_equal(got, reference.counts_below(values, factor, values, nb.indptr, nb.indices))
    labels = (values % 5).astype(np.int64)
    np.testing.assert_array_equal(compiled.same_label_counts(labels, nb.indptr, nb.indices),
                                  reference.same_label_counts(labels, nb.indptr, nb.indices))


@pytest.mark.parametrize("cloud", ["torus_cloud", "ball_cloud"])
def test_orientation_conflicts(cloud, request):
    pts, normals, nb = request.getfixturevalue(cloud)
    signs = np.where(np.arange(len(pts)) % 3 == 0, -1.0, 1.0)[:, None]  # some neighbours point the other way
    args = pts, normals * signs, nb.indptr, nb.indices, nb.distances, 0.5, 0.7
    got = compiled.orientation_conflicts(*args)
    np.testing.assert_array_equal(got, reference.orientation_conflicts(*args))
    assert got[:, 1].sum() > 0


@pytest.mark.parametrize("cloud", ["torus_cloud", "ball_cloud"])
def test_opposite_sheet_counts(cloud, request):
    pts, normals, nb = request.getfixturevalue(cloud)
    signs = np.where(np.arange(len(pts)) % 3 == 0, -1.0, 1.0)[:, None]  # some neighbours face the other way
    reach = 0.8 * nb.radius
    args = pts, normals * signs, nb.indptr, nb.indices, nb.distances, reach, 0.05 * nb.radius, 0.5
    got = compiled.opposite_sheet_counts(*args)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, reference.opposite_sheet_counts(*args))


@pytest.mark.parametrize("cloud, found", [("torus_cloud", False), ("ball_cloud", True)])
def test_over_under_pairs(cloud, found, request):
    pts, normals, nb = request.getfixturevalue(cloud)
    signs = np.where(np.arange(len(pts)) % 3 == 0, -1.0, 1.0)[:, None]
    reach = 0.8 * nb.radius
    args = pts, normals * signs, nb.indptr, nb.indices, nb.distances, reach, 0.05 * nb.radius, 0.5
    got = compiled.over_under_pairs(*args)
    want = reference.over_under_pairs(*args)
    for a, b in zip(got, want):
        np.testing.assert_allclose(a, b, rtol=1e-12)
    # a smooth surface has none; the ball's points lie over and under each other, facing either way
    assert (got[0].size > 0 and (got[2] < 0).any() and (got[2] > 0).any()) == found
    # the opposite ones are those opposite_sheet_counts counts
    counts = np.bincount(got[0][got[2] < -0.5], minlength=len(pts))
    np.testing.assert_array_equal(counts, compiled.opposite_sheet_counts(*args))


@pytest.mark.parametrize("cloud", ["torus_cloud", "ball_cloud"])
def test_flagged_within(cloud, request):
    pts, _, nb = request.getfixturevalue(cloud)
    flags = np.arange(len(pts)) % 3 == 0
    reach = 0.8 * nb.radius
    got = compiled.flagged_within(flags, nb.indptr, nb.indices, nb.distances, reach)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, reference.flagged_within(flags, nb.indptr, nb.indices, nb.distances, reach))
    assert 0 < got[:, 1].sum() < got[:, 0].sum()


@pytest.mark.parametrize("cloud", ["torus_cloud", "ball_cloud"])
def test_quadric_residual_moments(cloud, request):
    pts, normals, nb = request.getfixturevalue(cloud)
    normals = np.array(normals, dtype=np.float64)
    normals[7] = np.nan  # no normal: no fit
    scale = nb.radius / 2
    got = compiled.quadric_residual_moments(pts, normals, nb.indptr, nb.indices, scale)
    want = reference.quadric_residual_moments(pts, normals, nb.indptr, nb.indices, scale)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    assert np.isnan(got[7]).all()
    # the normal equations against a least-squares solver: rounding of the fit's residuals
    np.testing.assert_allclose(got[:, 0], want[:, 0], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(got[:, 1], want[:, 1], rtol=1e-5)


def test_quadric_residual_moments_of_exact_shapes():
    # on a quadric the residual is rounding; two layers of equal size about the fitted mid surface give
    # residuals of +-d: a root mean square of d and a kurtosis of 1
    rng = np.random.default_rng(0)
    xy = rng.uniform(-1.0, 1.0, size=(400, 2))
    z = 0.3 * xy[:, 0] ** 2 - 0.2 * xy[:, 0] * xy[:, 1] + 0.1 * xy[:, 1] ** 2 + 0.05 * xy[:, 0]
    points = np.column_stack([xy, z])
    indptr = np.array([0, 399], dtype=np.int64)
    normals = np.array([[0.0, 0.0, 1.0]])
    got = compiled.quadric_residual_moments(points, normals, indptr, np.arange(1, 400), np.ones(1))
    assert got[0, 0] < 1e-12
    # every (x, y) once in each layer, the row's point included
    xy[0] = 0.0
    layers = np.vstack([np.column_stack([xy[:200], np.full(200, z)]) for z in (0.1, -0.1)])
    got = compiled.quadric_residual_moments(layers, normals, indptr, np.arange(1, 400), np.ones(1))
    assert got[0, 0] == pytest.approx(0.1, rel=1e-9) and got[0, 1] == pytest.approx(1.0, rel=1e-9)
