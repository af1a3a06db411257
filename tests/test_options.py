"""Options: one declaration, the presets, validation, the deprecated American spellings."""

import dataclasses
import warnings

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.options import DEPRECATED_ALIASES, METHODS, Options, ScaleTuning, option_help, resolve_options


def test_every_option_is_documented_once_in_its_declaration():
    helps = option_help()
    assert list(helps) == [f.name for f in dataclasses.fields(Options)]
    assert all(isinstance(text, str) and len(text) > 10 for text in helps.values())
    # the class docstring documents every field too (numpydoc Attributes)
    for name in helps:
        assert f"\n    {name} :" in Options.__doc__, name


def test_presets():
    assert METHODS["default"] == Options()
    paper = METHODS["paper"]
    expect = (4.0, 0.25, "global", "system", "constrained")
    assert (paper.alpha, paper.m, paper.spacing, paper.area_method, paper.fit) == expect
    assert resolve_options("paper", alpha=3.5).alpha == 3.5
    assert resolve_options("default", alpha=None) == Options()  # None leaves the preset's value
    assert resolve_options(fit="chord", scale=None).scale == "auto"


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"alpha": 0}, r"alpha must be a positive number \(paper: 3.5-4.5\), got 0"),
        ({"alpha": float("nan")}, "alpha must be a positive number"),
        ({"m": -1}, r"m must be a positive number \(paper: 1/4\), got -1"),
        ({"gamma": 2}, r"gamma must lie in \[0, 1\]"),
        ({"gamma": "half"}, r"gamma must lie in \[0, 1\] \(paper: 0.1-0.5\), got 'half'"),
        ({"spacing": "exact"}, "spacing must be one of 'global', 'local', 'density', got 'exact'"),
        ({"fit": "jet"}, "fit must be one of"),
        ({"area_solver": "lu"}, "area_solver must be one of"),
        ({"neighbours": 10}, "neighbours must be at least 20"),
        ({"neighbours": "many"}, "neighbours must be a whole number, got .many."),
        ({"k_local": 1}, "k_local must be at least 2"),
        ({"workers": 0}, r"workers must be -1 \(all cores\) or a thread count >= 1, got 0"),
        ({"min_neighbours": 2}, "min_neighbours must be at least 3"),
        ({"scale": 10}, "scale must be 'auto' or a neighbour count of at least 20, got 10"),
        ({"scale": "wide"}, "scale must be 'auto' or a neighbour count"),
        ({"scale_tuning": {"tau": 2}}, "scale_tuning must be a heatcurv.options.ScaleTuning"),
        ({"scale_tuning": ScaleTuning(tau=-1.0)}, "scale_tuning.tau must be a positive number"),
        ({"scale_tuning": ScaleTuning(k_fit=5)}, "scale_tuning.k_fit must be at least 20"),
        ({"colour": "red"}, r"unknown option\(s\) colour"),
    ],
)
def test_bad_options_are_named(overrides, message):
    with pytest.raises(HeatcurvError, match=message):
        resolve_options(**overrides)


def test_unknown_method():
    with pytest.raises(HeatcurvError, match="unknown method 'fast'; choose one of default, paper"):
        resolve_options("fast")


@pytest.mark.parametrize(("alias", "name"), sorted(DEPRECATED_ALIASES.items()))
def test_american_spellings_are_deprecated_aliases(alias, name):
    with pytest.warns(DeprecationWarning, match=f"{alias}= is deprecated, use {name}="):
        opts = resolve_options(**{alias: 40})
    assert getattr(opts, name) == 40
    with pytest.raises(HeatcurvError, match=f"give {name}= or its deprecated alias {alias}=, not both"):
        resolve_options(**{alias: 40, name: 40})


def test_estimate_accepts_the_alias_and_points_the_warning_at_the_caller():
    pts = surfaces.Sphere().sample(800, "fibonacci").points
    with pytest.warns(DeprecationWarning) as record:
        old = heatcurv.estimate(pts, neighbors=40)
    assert record[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        new = heatcurv.estimate(pts, neighbours=40)
    np.testing.assert_array_equal(old.mean, new.mean)
    assert new.options.neighbours == 40


def test_scale_tuning_reaches_the_kernel_choice():
    # a noisy sphere: Lepski's rule widens the kernel; a tiny tolerance refuses every widening
    sample = surfaces.Sphere().sample(6000, "random", seed=1)
    noisy = sample.points + np.random.default_rng(2).normal(scale=0.01, size=sample.points.shape)
    wide = heatcurv.estimate(noisy)
    narrow = heatcurv.estimate(noisy, scale_tuning=ScaleTuning(tau=1e-6))
    assert wide.info["scale"].k > 60
    assert narrow.info["scale"].k == 60 and narrow.info["scale"].fit == "denoised-60"


def test_bad_options():
    pts = surfaces.Sphere().sample(500, "fibonacci").points
    with pytest.raises(HeatcurvError, match="unknown method"):
        heatcurv.estimate(pts, method="magic")
    with pytest.raises(HeatcurvError, match="alpha must be a positive"):
        heatcurv.estimate(pts, alpha=-1)
    with pytest.raises(HeatcurvError, match="m must be a positive"):
        heatcurv.estimate(pts, m=0)
    with pytest.raises(HeatcurvError, match="gamma must lie in"):
        heatcurv.estimate(pts, spacing="local", gamma=2)
    with pytest.raises(HeatcurvError, match="spacing must be one of"):
        heatcurv.estimate(pts, spacing="adaptive")
    with pytest.raises(HeatcurvError, match="fit must be one of"):
        heatcurv.estimate(pts, fit="cubic")
