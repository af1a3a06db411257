"""Options: one declaration, the presets, validation, unknown names answered with the name meant."""

import dataclasses

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.options import (
    METHODS,
    RANGES,
    Options,
    ScaleTuning,
    check_options_for_cloud,
    option_help,
    range_problem,
    resolve_options,
)


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
        ({"alpha": 0}, r"^alpha = 0 is outside its range \[0.5, 20\]: the ball's radius in spacings"),
        ({"alpha": 1e9}, r"^alpha = 1e\+09 is outside its range \[0.5, 20\]: .*paper uses 3.5-4.5\)$"),
        ({"alpha": float("nan")}, r"^alpha must be a number in \[0.5, 20\], got nan$"),
        ({"alpha": float("inf")}, r"^alpha must be a number in \[0.5, 20\], got inf$"),
        ({"alpha": True}, r"^alpha must be a number in \[0.5, 20\], got True$"),
        ({"m": -1}, r"^m = -1 is outside its range \[0.001, 10\]: t = m h\^2"),
        ({"m": 1e-300}, r"^m = 1e-300 is outside its range \[0.001, 10\]"),
        ({"m": 11.0}, r"^m = 11 is outside its range \[0.001, 10\]"),
        ({"gamma": 2}, r"^gamma = 2 is outside its range \[0, 1\]"),
        ({"gamma": "half"}, r"^gamma must be a number in \[0, 1\], got 'half'$"),
        ({"spacing": "exact"}, "spacing must be one of 'global', 'local', 'density', got 'exact'"),
        ({"fit": "jet"}, "fit must be one of"),
        ({"area_solver": "lu"}, "area_solver must be one of"),
        ({"neighbours": 10}, r"^neighbours = 10 is outside its range \[20, 1920\]: the chord fit has 9 unknowns"),
        ({"neighbours": 1921}, r"^neighbours = 1921 is outside its range \[20, 1920\]"),
        ({"neighbours": "many"}, r"^neighbours must be a whole number in \[20, 1920\], got 'many'$"),
        ({"neighbours": 40.5}, r"^neighbours must be a whole number in \[20, 1920\], got 40.5$"),
        ({"neighbours": np.float64("nan")}, r"^neighbours must be a whole number in \[20, 1920\], got nan$"),
        ({"k_local": 1}, r"^k_local = 1 is outside its range \[2, 1000\]"),
        ({"k_local": 1001}, r"^k_local = 1001 is outside its range \[2, 1000\]"),
        ({"workers": 0}, r"^workers = 0 is outside its range -1 or \[1, 1024\]"),
        ({"workers": -2}, r"^workers = -2 is outside its range -1 or \[1, 1024\]"),
        ({"workers": 10**30}, r"^workers = 1e\+30 is outside its range -1 or \[1, 1024\]"),
        ({"workers": 2.0}, r"^workers must be -1 \(all cores\) or a whole thread count in \[1, 1024\], got 2.0$"),
        ({"workers": True}, r"^workers must be -1 \(all cores\) or a whole thread count in \[1, 1024\], got True$"),
        ({"min_neighbours": 2}, r"^min_neighbours = 2 is outside its range \[3, 1920\]"),
        ({"scale": 10}, r"^scale = 10 is outside its range \[20, 1000000\]"),
        ({"scale": 10**7}, r"^scale = 10000000 is outside its range \[20, 1000000\]"),
        ({"scale": 60.0}, r"^scale must be 'auto' or a neighbour count in \[20, 1000000\], got 60.0$"),
        ({"scale": "wide"}, r"^scale must be 'auto' or a neighbour count in \[20, 1000000\], got 'wide'$"),
        ({"radius": -1.0}, r"^radius must be a positive length \(or None\), got -1.0$"),
        ({"radius": float("inf")}, r"^radius must be a positive length \(or None\), got inf$"),
        ({"scale_tuning": {"tau": 2}}, "scale_tuning must be a heatcurv.options.ScaleTuning"),
        ({"scale_tuning": ScaleTuning(tau=-1.0)}, r"^scale_tuning.tau = -1 is outside its range \[1e-06, 100\]"),
        ({"scale_tuning": ScaleTuning(tau=float("nan"))}, r"^scale_tuning.tau must be a number in \[1e-06, 100\]"),
        ({"scale_tuning": ScaleTuning(k_fit=5)}, r"^scale_tuning.k_fit = 5 is outside its range \[20, 1920\]"),
        ({"scale_tuning": ScaleTuning(n_sub=5)}, r"^scale_tuning.n_sub = 5 is outside its range \[10, 1000000\]"),
        ({"scale_tuning": ScaleTuning(clean_ratio=50.0)}, r"^scale_tuning.clean_ratio = 50 is outside its range"),
        ({"scale_tuning": ScaleTuning(max_k=10)}, r"^scale_tuning.max_k = 10 is outside its range \[20, 1000000\]"),
        ({"scale_tuning": ScaleTuning(seed=-1)}, r"^scale_tuning.seed = -1 is outside its range \[0, "),
        ({"scale_tuning": ScaleTuning(max_k=40)}, r"^scale_tuning.max_k = 40 is below neighbours = 60: "),
        ({"colour": "red"}, r"unknown option\(s\) colour"),
    ],
)
def test_bad_options_are_named(overrides, message):
    with pytest.raises(HeatcurvError, match=message) as caught:
        resolve_options(**overrides)
    assert "\n" not in str(caught.value)


def test_every_numeric_option_has_a_documented_range():
    numeric = {
        f.name for f in dataclasses.fields(Options)
        if f.name not in ("method", "taper", "scale_tuning", "radius") and f.metadata["choices"] is None
    }
    assert numeric == {"alpha", "m", "gamma", "k_local", "neighbours", "min_neighbours", "scale", "workers"}
    tuning = {f"scale_tuning.{f.name}" for f in dataclasses.fields(ScaleTuning)}
    assert set(RANGES) == numeric | tuning
    for name, limits in RANGES.items():
        assert limits.low < limits.high and len(limits.why) > 20, name
        if "." not in name:
            assert f"``{name}``" in Options.__doc__, name  # the table of the Notes
    # the presets and the defaults lie inside the ranges
    for preset in METHODS.values():
        resolve_options(preset.method)
    tuning_defaults = ScaleTuning()
    assert tuning_defaults.check() is None
    # both ends are accepted
    for name in numeric - {"workers", "scale"}:
        for end in (RANGES[name].low, RANGES[name].high):
            assert getattr(resolve_options(**{name: end}), name) == end
    assert resolve_options(workers=1024).workers == 1024 and resolve_options(workers=-1).workers == -1
    assert resolve_options(scale=1_000_000).scale == 1_000_000
    assert resolve_options(neighbours=40.0).neighbours == 40.0  # a whole number given as a float, as before
    assert resolve_options(method="paper", scale_tuning=ScaleTuning(max_k=20)).fit == "constrained"


def test_range_problem_is_the_one_check():
    assert range_problem("alpha", 2.0) is None
    assert range_problem("alpha", np.float32(3.5)) is None and range_problem("k_local", np.int64(8)) is None
    assert range_problem("alpha", np.bool_(True)).endswith("got True")


@pytest.mark.parametrize(
    ("overrides", "n", "extent", "message"),
    [
        ({"neighbours": 1918}, 1920, None, None),
        ({"neighbours": 1920}, 1921, None, r"^neighbours = 1920 is too many for a cloud of 1921 distinct points: "
                                          r"at most 1919 "),
        ({"neighbours": 60}, 61, None, r"^neighbours = 60 is too many for a cloud of 61 distinct points"),
        ({"min_neighbours": 30, "radius": 0.1}, 31, None, r"^min_neighbours = 30 is too many"),
        ({"scale": 500}, 502, None, None),
        ({"scale": 501}, 502, None, r"^scale = 501 is too many for a cloud of 502 distinct points"),
        ({"method": "paper", "neighbours": 100}, 80, None, None),  # the paper's spacing has no k-NN ball
        ({"spacing": "local", "fit": "constrained", "k_local": 50}, 50, None, r"^k_local = 50 is too many"),
        ({"radius": 1.7}, 2000, 3.46, None),
        ({"radius": 2.5}, 2000, 3.46, r"^radius = 2.5 is larger than the cloud: at most half its bounding-box "
                                      r"diagonal \(1.73\)"),
        ({"radius": 1e-12}, 2000, 3.46, r"^radius = 1e-12 is too small for a cloud of diagonal 3.46"),
        ({"radius": 1e9}, 2000, None, None),  # no extent: no radius check
    ],
)
def test_check_options_for_cloud(overrides, n, extent, message):
    options = resolve_options(**overrides)
    if message is None:
        check_options_for_cloud(options, n, extent)
    else:
        with pytest.raises(HeatcurvError, match=message):
            check_options_for_cloud(options, n, extent)


def test_check_options_for_cloud_on_a_sphere():
    # the limits the fuzzing met: neighbours = n - 2 passes, more than the cloud does not; a ball larger than it
    points = surfaces.Sphere().sample(2000, "random").points
    n = np.unique(points, axis=0).shape[0]
    extent = float(np.linalg.norm(np.ptp(points, axis=0)))
    check_options_for_cloud(resolve_options(), n, extent)
    check_options_for_cloud(resolve_options(radius=0.5), n, extent)
    with pytest.raises(HeatcurvError, match="radius = 5 is larger than the cloud"):
        check_options_for_cloud(resolve_options(radius=5.0), n, extent)
    with pytest.raises(HeatcurvError, match=f"scale = {n - 1} is too many for a cloud of {n} distinct points"):
        check_options_for_cloud(resolve_options(scale=n - 1), n, extent)


def test_unknown_method():
    with pytest.raises(HeatcurvError, match="unknown method 'fast'; choose one of default, paper"):
        resolve_options("fast")


@pytest.mark.parametrize(
    ("given", "meant"), [("neighbors", "neighbours"), ("min_neighbors", "min_neighbours"), ("orientation", "orient")]
)
def test_american_and_misspelt_options_name_the_option_meant(given, meant):
    with pytest.raises(HeatcurvError, match=rf"^unknown option\(s\) {given} \(did you mean {meant}\?\)$"):
        resolve_options(**{given: 40})


def test_estimate_refuses_an_unknown_option_before_the_work():
    pts = surfaces.Sphere().sample(800, "fibonacci").points
    with pytest.raises(HeatcurvError, match=r"^unknown option\(s\) colour, neighbors \(did you mean neighbours\?\)$"):
        heatcurv.estimate(pts, neighbors=40, colour="red")
    assert heatcurv.estimate(pts, neighbours=40).options.neighbours == 40


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
    with pytest.raises(HeatcurvError, match=r"alpha = -1 is outside its range \[0.5, 20\]"):
        heatcurv.estimate(pts, alpha=-1)
    with pytest.raises(HeatcurvError, match=r"m = 0 is outside its range \[0.001, 10\]"):
        heatcurv.estimate(pts, m=0)
    with pytest.raises(HeatcurvError, match="gamma = 2 is outside its range"):
        heatcurv.estimate(pts, spacing="local", gamma=2)
    with pytest.raises(HeatcurvError, match="spacing must be one of"):
        heatcurv.estimate(pts, spacing="adaptive")
    with pytest.raises(HeatcurvError, match="fit must be one of"):
        heatcurv.estimate(pts, fit="cubic")
