"""heatcurv.cli.options: the estimator's flags and the estimate() keywords they give."""

import argparse

import pytest

import heatcurv
from heatcurv.cli.options import add_estimator_options, estimator_kwargs
from heatcurv.options import resolve_options


def parse(*argv):
    parser = argparse.ArgumentParser()
    add_estimator_options(parser)
    return parser.parse_args(list(argv))


def test_defaults_leave_every_option_to_the_method():
    kwargs = estimator_kwargs(parse())
    assert kwargs.pop("method") == "default" and kwargs.pop("workers") == -1
    assert all(value is None for value in kwargs.values()), kwargs
    resolve_options(**{k: v for k, v in kwargs.items() if k != "viewpoint"})  # every name is an option


def test_flags_become_estimate_keywords():
    kwargs = estimator_kwargs(parse(
        "--method", "paper", "--alpha", "3.5", "--neighbors", "40", "--min-neighbors", "5", "--scale", "auto",
        "--viewpoint=-1,0,2", "-j", "2",
    ))
    assert kwargs["method"] == "paper" and kwargs["alpha"] == 3.5 and kwargs["scale"] == "auto"
    assert kwargs["neighbours"] == 40 and kwargs["min_neighbours"] == 5  # the options' British names
    assert kwargs["viewpoint"] == (-1.0, 0.0, 2.0) and kwargs["workers"] == 2


def test_values_are_checked_before_any_file_is_read():
    with pytest.raises(heatcurv.HeatcurvError, match=r"gamma must lie in \[0, 1\]"):
        estimator_kwargs(parse("--gamma", "2"))


def test_help_names_both_presets():
    parser = argparse.ArgumentParser()
    add_estimator_options(parser)
    text = " ".join(parser.format_help().split())
    assert "(default method: 2; paper: 4)" in text  # --alpha
    assert "(default: %(default)s)" not in text and "not used" in text  # the paper's fit has no kernel
