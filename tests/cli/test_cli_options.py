"""heatcurv.cli.options: the estimator's flags and the estimate() keywords they give."""

import argparse
import dataclasses

import pytest

from heatcurv.cli.options import add_estimator_options, estimator_kwargs, option_flags
from heatcurv.options import Options, resolve_options


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
        "--method", "paper", "--alpha", "3.5", "--neighbours", "40", "--min-neighbours", "5", "--scale", "auto",
        "--viewpoint=-1,0,2", "-j", "2",
    ))
    assert kwargs["method"] == "paper" and kwargs["alpha"] == 3.5 and kwargs["scale"] == "auto"
    assert kwargs["neighbours"] == 40 and kwargs["min_neighbours"] == 5
    assert kwargs["viewpoint"] == (-1.0, 0.0, 2.0) and kwargs["workers"] == 2


def test_values_are_checked_as_the_command_line_is_parsed(capsys):
    # each flag runs its option's own check (heatcurv.options), before any file is read
    for argv, message in [
        (("--gamma", "2"), "argument --gamma: gamma = 2 is outside its range [0, 1]"),
        (("--alpha", "-1"), "argument --alpha: alpha = -1 is outside its range [0.5, 20]: the ball's radius"),
        (("--alpha", "1e9"), "argument --alpha: alpha = 1e+09 is outside its range [0.5, 20]"),
        (("--alpha", "nan"), "argument --alpha: expected a finite number, got 'nan'"),
        (("--m", "1e-300"), "argument --m: m = 1e-300 is outside its range [0.001, 10]"),
        (("--neighbours", "10"), "argument --neighbours: neighbours = 10 is outside its range [20, 1920]"),
        (("--neighbours", "1998"), "argument --neighbours: neighbours = 1998 is outside its range"),
        (("--neighbors", "40"), "unrecognized arguments: --neighbors 40"),
        (("--scale", "wide"), "argument --scale: expected 'auto' or a neighbour count, got 'wide'"),
        (("--scale", "1e9"), "argument --scale: expected 'auto' or a neighbour count, got '1e9'"),
        (("--scale", "2000000"), "argument --scale: scale = 2000000 is outside its range [20, 1000000]"),
        (("--k-local", "two"), "argument --k-local: expected an integer, got 'two'"),
        (("--min-neighbours", "2"), "argument --min-neighbours: min_neighbours = 2 is outside"),
        (("-j", "1e30"), "argument -j/--workers: expected an integer, got '1e30'"),
        (("-j", "0"), "argument -j/--workers: workers = 0 is outside its range -1 or [1, 1024]"),
        (("-j", "5000"), "argument -j/--workers: workers = 5000 is outside its range -1 or [1, 1024]"),
    ]:
        with pytest.raises(SystemExit):
            parse(*argv)
        assert message in capsys.readouterr().err


def test_every_cli_option_is_an_option_field():
    flags = option_flags()
    assert flags["neighbours"] == ["--neighbours"] and flags["min_neighbours"] == ["--min-neighbours"]
    assert set(flags) == {f.name for f in dataclasses.fields(Options) if f.metadata["cli"]}
    assert {"method", "workers", "taper", "scale_tuning"}.isdisjoint(flags)


def test_help_names_both_presets():
    parser = argparse.ArgumentParser()
    add_estimator_options(parser)
    text = " ".join(parser.format_help().split())
    assert "(default method: 2; paper: 4)" in text  # --alpha
    assert "(default: %(default)s)" not in text and "not used" in text  # the paper's fit has no kernel


def test_radius_flag(capsys):
    assert estimator_kwargs(parse("--radius", "0.25"))["radius"] == 0.25
    assert estimator_kwargs(parse())["radius"] is None
    with pytest.raises(SystemExit):
        parse("--radius", "-1")
    assert "argument --radius: radius must be a positive length (or None), got -1.0" in capsys.readouterr().err


def test_help_shows_the_ranges():
    parser = argparse.ArgumentParser()
    add_estimator_options(parser)
    text = " ".join(parser.format_help().split())
    for shown in ("0.5-20", "0.001-10", "20-1920", "-1 (all cores) or 1-1024"):
        assert shown in text, shown
