"""heatcurv.fits.principal: the curvature-tensor fit of section 3 (eq 3.1), constrained and free."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.fits.principal import PrincipalCurvatures, _disc_constrained_lsq, principal_fit
from heatcurv.geometry.neighbourhood import ball_neighbourhood
from heatcurv.operators.mean_curvature import edge_normal_curvatures


def synthetic_neighbourhood(k1, k2, angle, n_nb=40, seed=0):
    """One centre at the origin (normal +z) with neighbours whose chord curvatures obey
    Euler's formula exactly: kN(theta) = k1 cos^2(theta - angle) + k2 sin^2(theta - angle).

    One neighbour lies in the direction of d2. Each neighbour sits on the circle of curvature kN
    through the origin tangent to the plane z = 0, in its direction theta: height z = (-1 + sqrt(1 - kN^2 r^2)) / kN.
    """
    rng = np.random.default_rng(seed)
    # include the direction of d2, so the smallest edge curvature is k2 itself (see eq 3.1)
    theta = np.append(rng.uniform(0, 2 * np.pi, n_nb - 1), angle + np.pi / 2)
    r = rng.uniform(0.05, 0.2, n_nb)
    kN = k1 * np.cos(theta - angle) ** 2 + k2 * np.sin(theta - angle) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(np.abs(kN) > 1e-12, (-1 + np.sqrt(1 - kN**2 * r**2)) / kN, -0.5 * kN * r**2)
    pts = np.vstack([[0.0, 0.0, 0.0], np.c_[r * np.cos(theta), r * np.sin(theta), z]])
    nb = ball_neighbourhood(pts, 10.0, min_neighbours=3)
    return pts, nb


@pytest.mark.parametrize("k1, k2", [(2.0, 0.5), (1.0, -1.0), (0.0, -3.0), (1.5, 1.5)])
@pytest.mark.parametrize("constrained", [True, False])
def test_principal_fit_recovers_an_exact_tensor(k1, k2, constrained):
    angle = 0.7
    pts, nb = synthetic_neighbourhood(k1, k2, angle)
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    w = np.ones(nb.n_pairs)
    mean = np.full(len(pts), 0.5 * (k1 + k2))
    pc = principal_fit(pts, nb, normals, w, mean=mean, constrained=constrained)
    assert pc.k1[0] == pytest.approx(k1, abs=1e-9)
    assert pc.k2[0] == pytest.approx(k2, abs=1e-9)
    assert pc.gaussian[0] == pytest.approx(k1 * k2, abs=1e-8)
    if k1 != k2:
        d = np.array([np.cos(angle), np.sin(angle), 0.0])
        assert abs(pc.d1[0] @ d) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(np.cross(pc.d1[0], pc.d2[0]), [0, 0, 1.0], atol=1e-12)
    assert pc.well_posed[0]


def test_constrained_fit_is_bounded_by_the_smallest_edge_curvature(records):
    # Eq 3.1's lower bound reads k2 >= min_j kN_ij - eps. By Euler's theorem every edge
    # curvature lies in [k2, k1], so when no edge points along d2 the bound is active and
    # pulls k2 up to min kN: the literal constraint, kept in method="paper".
    pts, nb = synthetic_neighbourhood(2.0, 0.5, 0.7)
    pts, nb = pts[:-1], ball_neighbourhood(pts[:-1], 10.0, min_neighbours=3)  # drop the d2 edge
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    kN = edge_normal_curvatures(pts, nb, normals)[: nb.counts[0]]
    assert kN.min() > 0.5
    pc = principal_fit(pts, nb, normals, np.ones(nb.n_pairs), mean=np.full(len(pts), 1.25), constrained=True)
    # k2 ends just below the bound (eps, Newton): its distance in % of the bound
    records.check("principal/synthetic-bound", k2_below_bound=100 * (kN.min() - pc.k2[0]) / kN.min())
    free = principal_fit(pts, nb, normals, np.ones(nb.n_pairs), constrained=False)
    assert free.k2[0] == pytest.approx(0.5, abs=1e-9)


def test_constrained_fit_respects_the_lower_bound_of_eq_3_1():
    # kappa_M = 0.5 but all edge curvatures >= 0.8: eq 3.1 bounds k2 >= min kN - eps, so
    # with a + c = 2 kappa_M the tensor is forced to (nearly) umbilic 0.5.
    pts, nb = synthetic_neighbourhood(1.2, 0.8, 0.3)
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    kN = edge_normal_curvatures(pts, nb, normals)[: nb.counts[0]]
    pc = principal_fit(pts, nb, normals, np.ones(nb.n_pairs), mean=np.full(len(pts), 0.5), constrained=True)
    assert pc.k2[0] >= kN.min() - 1e-6 or pc.k1[0] - pc.k2[0] < 1e-9
    assert pc.k1[0] + pc.k2[0] == pytest.approx(1.0, abs=1e-12)
    det = pc.k1[0] * pc.k2[0]
    assert det <= 0.25 + 1e-12  # ac - b^2 <= kappa_M^2
    assert det >= 0.25 - ((kN.min() - 1e-9) - 0.5) ** 2 - 1e-9


def test_disc_constrained_least_squares_against_brute_force():
    rng = np.random.default_rng(5)
    n = 200
    A = rng.normal(size=(n, 2, 2))
    G = A @ A.transpose(0, 2, 1) + 0.01 * np.eye(2)
    r = rng.normal(size=(n, 2)) * 3
    radius = rng.uniform(0, 2, n)
    z = _disc_constrained_lsq(G, r, radius)
    assert np.all(np.linalg.norm(z, axis=1) <= radius * (1 + 1e-9) + 1e-12)
    # brute force: dense polar grid of the disc
    rho = np.linspace(0, 1, 401)[None, :, None] * radius[:, None, None]
    phi = np.linspace(0, 2 * np.pi, 721)[None, None, :]
    cand = np.stack([rho * np.cos(phi), rho * np.sin(phi)], -1).reshape(n, -1, 2)

    def obj(Z):
        return np.einsum("nki,nij,nkj->nk", Z, G, Z) - 2 * np.einsum("nki,ni->nk", Z, r)

    best = obj(cand).min(axis=1)
    got = obj(z[:, None, :])[:, 0]
    assert np.all(got <= best + 1e-6 * (1 + np.abs(best)))


def test_flipped_sees_the_surface_from_the_other_side():
    sample = surfaces.Ellipsoid().sample(3000, "random", seed=5)
    pc = heatcurv.estimate(sample.points)
    fitted = PrincipalCurvatures(pc.k1, pc.k2, pc.d1, pc.d2, pc.mean, pc.gaussian, pc.reliable)
    mask = np.arange(len(pc)) % 2 == 0
    flipped = fitted.flipped(mask)
    np.testing.assert_array_equal(flipped.k1[mask], -pc.k2[mask])
    np.testing.assert_array_equal(flipped.k2[mask], -pc.k1[mask])
    np.testing.assert_array_equal(flipped.mean[mask], -pc.mean[mask])
    np.testing.assert_array_equal(flipped.gaussian, pc.gaussian)
    np.testing.assert_array_equal(flipped.k1[~mask], pc.k1[~mask])
    assert np.all(flipped.k1 >= flipped.k2)
    # d1 x d2 = n for the reversed normals
    normals = np.where(mask[:, None], -pc.normals, pc.normals)
    np.testing.assert_allclose(np.cross(flipped.d1, flipped.d2), normals, atol=1e-9)
