"""The fit plan: one per path of the estimator, and each says what ran.

Every test runs :func:`heatcurv.estimate` with the stage functions of :mod:`heatcurv.fit_stages` wrapped
by spies, and checks the plan in ``info["plan"]`` against the calls the estimator made: the fit form
(chord or denoised; the paper's tensor fit with or without its constraint), at every point or at
anchors, how many anchors per ball, the anchors' own normals, the low-noise refit and the carry.
"""

import numpy as np
import pytest

import heatcurv
from heatcurv import fit_stages, surfaces
from heatcurv.choice.plan import FORMS, FitPlan, plan_fit
from heatcurv.choice.scale import ScaleChoice
from heatcurv.fits.balls import Scale
from heatcurv.options import ScaleTuning, resolve_options
from heatcurv.tuning import TUNING

SPIED = ("principal_fit", "chord_fit", "refine_normals", "anchor_rows", "anchor_normals", "fit_anchors", "carry_fits")


@pytest.fixture
def calls(monkeypatch):
    """The spied stage functions' calls, by name: lists of (args, kwargs)."""
    seen = {name: [] for name in SPIED}
    for name in SPIED:
        original = getattr(fit_stages, name)

        def spy(*args, _name=name, _original=original, **kwargs):
            seen[_name].append((args, kwargs))
            return _original(*args, **kwargs)

        monkeypatch.setattr(fit_stages, name, spy)
    return seen


def torus(n=3000, noise=0.0, seed=1):
    return surfaces.Torus().sample(n, "random", noise=noise, seed=seed).points


def regular_sphere():
    """A regular sample, the paper's case (its method refuses or warns on random ones)."""
    return surfaces.Sphere(radius=2.0).sample(4000, "fibonacci").points


def test_the_papers_constrained_fit(calls):
    res = heatcurv.estimate(regular_sphere(), method="paper")
    plan = res.info["plan"]
    assert plan.form == "paper-constrained" and plan.label == "paper-constrained" and not plan.anchored
    assert [kw["constrained"] for _, kw in calls["principal_fit"]] == [True]
    assert not calls["chord_fit"] and not calls["fit_anchors"]
    assert "kernel_choice" not in res.info["timings"] and "scale" not in res.info
    # the constrained fit keeps the operator's mean curvature, 1/2 |K| (eq 2.11)
    np.testing.assert_array_equal(np.abs(res.mean), 0.5 * np.linalg.norm(res.mean_curvature_normal, axis=1))


def test_the_papers_free_fit_takes_its_own_mean(calls):
    res = heatcurv.estimate(regular_sphere(), method="paper", fit="unconstrained")
    assert res.info["plan"].form == "paper-free"
    assert [kw["constrained"] for _, kw in calls["principal_fit"]] == [False]
    # the free fit's own mean, not the operator's 1/2 |K| (on this sphere they differ by up to 0.27)
    assert np.abs(np.abs(res.mean) - 0.5 * np.linalg.norm(res.mean_curvature_normal, axis=1)).max() > 0.1
    np.testing.assert_allclose(res.mean, 0.5 * (res.k1 + res.k2), rtol=1e-15)


def test_a_clean_cloud_gets_the_chord_fit_at_every_point(calls):
    res = heatcurv.estimate(torus())
    plan = res.info["plan"]
    assert (plan.form, plan.k, plan.anchored, plan.label) == ("chord", 60, False, "chord-60")
    assert calls["chord_fit"] and all(kw["denoise"] is False for _, kw in calls["chord_fit"])
    assert all(kw["denoise"] is False for _, kw in calls["refine_normals"])
    assert not calls["fit_anchors"] and not calls["carry_fits"]
    assert res.info["scale"].fit == plan.label and res.info["scale"].anchors == 0
    assert "curvature_fit" in res.info["timings"] and "anchor_fit" not in res.info["timings"]


def test_one_radius_keeps_the_gates_form_at_every_point(calls):
    clean = heatcurv.estimate(torus(), radius=0.6)
    plan = clean.info["plan"]
    assert (plan.form, plan.radius, plan.anchored, plan.label) == ("chord", 0.6, False, "chord-r0.6")
    assert all(kw["denoise"] is False for _, kw in calls["chord_fit"])
    calls["chord_fit"].clear()
    noisy = heatcurv.estimate(torus(noise=0.005), radius=0.6)
    plan = noisy.info["plan"]
    assert (plan.form, plan.anchored, plan.label) == ("denoised", False, "denoised-r0.6")
    assert calls["chord_fit"] and all(kw["denoise"] is True for _, kw in calls["chord_fit"])
    assert not calls["fit_anchors"]
    assert noisy.info["scale"].fit == "denoised-r0.6" and noisy.info["scale"].candidates == ["denoised-r0.6"]


def test_a_noisy_cloud_is_fitted_at_anchors_and_carried(calls):
    res = heatcurv.estimate(torus(noise=0.005))
    plan = res.info["plan"]
    assert plan.form == "denoised" and plan.anchored and plan.k > 60
    assert (plan.anchors_per_ball, plan.anchor_normals, plan.refit, plan.carry_degree) == (16, False, False, 0)
    assert [args[3] for args, _ in calls["anchor_rows"]] == [16]
    assert [(kw["denoise"], kw["low_noise"]) for _, kw in calls["fit_anchors"]] == [(True, False)]
    assert [kw["degree"] for _, kw in calls["carry_fits"]] == [0]
    assert not calls["anchor_normals"] and not calls["chord_fit"]
    assert res.info["scale"].fit == plan.label == f"denoised-{plan.k}" and res.info["scale"].anchors > 0


def test_a_clean_cloud_with_a_kernel_wider_than_k_fit_is_denoised_at_anchors_and_says_so(calls):
    # the anchors fit the denoised form whatever the gate said: the label is the form that ran
    res = heatcurv.estimate(torus(), scale=480)
    plan = res.info["plan"]
    assert (plan.form, plan.k, plan.anchored, plan.label) == ("denoised", 480, True, "denoised-480")
    assert "wider than k_fit = 240" in plan.reason
    assert [kw["denoise"] for _, kw in calls["fit_anchors"]] == [True]
    assert res.info["scale"].fit == "denoised-480"


def test_strong_noise_orients_the_anchors_own_normals_unless_normals_are_given(calls):
    points = torus(n=4000, noise=0.08, seed=2)
    res = heatcurv.estimate(points)
    plan = res.info["plan"]
    assert res.info["scale"].relative_noise > TUNING.strong_noise
    assert plan.anchor_normals and len(calls["anchor_normals"]) == 1
    assert res.info["orientation"].on_anchors == res.info["scale"].anchors
    for name in SPIED:
        calls[name].clear()
    given = heatcurv.estimate(points, normals=res.normals)
    plan = given.info["plan"]
    assert plan.keep_normals and not plan.anchor_normals and not calls["anchor_normals"]
    assert [kw["refine"] for _, kw in calls["fit_anchors"]] == [False]


def test_very_low_noise_takes_the_refit_denser_anchors_and_the_regression(calls):
    res = heatcurv.estimate(torus(n=8000, noise=1e-5, seed=3))
    plan = res.info["plan"]
    assert res.info["scale"].low_noise and plan.refit
    assert (plan.anchors_per_ball, plan.carry_degree) == (24, 3)
    assert [args[3] for args, _ in calls["anchor_rows"]] == [24]
    assert [(kw["denoise"], kw["low_noise"]) for _, kw in calls["fit_anchors"]] == [(True, True)]
    assert [kw["degree"] for _, kw in calls["carry_fits"]] == [3]
    assert "very low noise" in plan.reason and "low-noise refit" in plan.describe()


def choice(k, denoise, relative_noise=0.1, low_noise=False, k_per_point=None):
    return ScaleChoice(Scale(k, denoise), sigma=0.01, relative_noise=relative_noise, low_noise=low_noise,
                       k_per_point=k_per_point)


def test_plan_fit_alone_on_every_branch():
    options = resolve_options("default")
    assert plan_fit(options, choice(60, False)) == FitPlan("chord", 60, 60, 60, reason="clean")
    assert plan_fit(options, choice(240, False)).anchored is False  # k_fit itself is fitted at every point
    wide = plan_fit(options, choice(480, False))
    assert wide.anchored and wide.form == "denoised" and wide.carry_degree == 0
    regions = plan_fit(options, choice(480, True, k_per_point=np.array([240, 480, 960])))
    assert (regions.k_min, regions.k_max) == (240, 960) and "240-960 neighbours by region" in regions.describe()
    assert plan_fit(options, choice(480, True, relative_noise=0.6)).anchor_normals
    assert not plan_fit(options, choice(480, True, relative_noise=0.6), keep_normals=True).anchor_normals
    low = plan_fit(options, choice(960, True, relative_noise=0.005, low_noise=True))
    assert (low.refit, low.anchors_per_ball, low.carry_degree) == (True, 24, 3)
    assert plan_fit(resolve_options("default", radius=2.0), choice(60, True)).label == "denoised-r2"
    wider_k_fit = resolve_options("default", scale_tuning=ScaleTuning(k_fit=960))
    assert plan_fit(wider_k_fit, choice(480, False)).anchored is False
    assert plan_fit(resolve_options("paper")).form == "paper-constrained"
    assert {plan_fit(options, choice(60, False)).form, wide.form, plan_fit(resolve_options("paper")).form,
            plan_fit(resolve_options("default", fit="unconstrained")).form} == set(FORMS)
    with pytest.raises(ValueError, match="needs the kernel choice"):
        plan_fit(options)


def test_the_plan_says_where_standard_errors_are_computed():
    options = resolve_options("default")
    assert plan_fit(options, choice(60, False)).standard_errors and plan_fit(options, choice(480, True)).standard_errors
    assert not plan_fit(resolve_options("default", se=False), choice(60, False)).standard_errors
    assert not plan_fit(resolve_options("default", radius=2.0), choice(60, True)).standard_errors
    assert not plan_fit(resolve_options("paper")).standard_errors
