"""heatcurv.cli.main: help, version, exit statuses, one-line errors and warnings, --debug."""

import subprocess

import pytest
from cli_helpers import assert_one_line_error, run

import heatcurv
from heatcurv.cli import info, main


def test_bad_arguments_give_one_line_and_status_2():
    out = run("demo", "-n", "3")
    assert out.returncode == 2
    assert out.stderr.strip() == "heatcurv: error: n must be at least 4, got 3"
    assert "Traceback" not in out.stderr


def test_debug_shows_the_traceback():
    out = run("--debug", "demo", "-n", "3", "--no-picture")
    assert out.returncode != 0 and "Traceback" in out.stderr


def test_help_and_version():
    assert "demo" in run("--help").stdout
    assert run("--version").stdout.startswith("heatcurv ")
    assert run().returncode == 2  # a subcommand is required


@pytest.mark.parametrize(
    "command, option",
    [
        ("compute", "--normals-from-input"), ("render", "--views"), ("features", "--threshold"), ("info", "input"),
        ("demo", "--surface"), ("compute", "--float64"), ("features", "--float64"),
    ],
)
def test_help_of_every_subcommand(command, option, capsys):
    # in this process: the real process's --help is tested above
    assert main([command, "--help"]) == 0
    out = capsys.readouterr()
    assert out.out.startswith(f"usage: heatcurv {command}") and out.err == ""
    assert option in out.out


BAD_OPTIONS = {
    "viewpoint with two numbers": (
        ["--viewpoint", "1,2"], "argument --viewpoint: expected three numbers X,Y,Z, got '1,2'"
    ),
    "viewpoint not numbers": (["--viewpoint", "a,b,c"], "expected three numbers"),
    "negative alpha": (["--alpha", "-1"], "argument --alpha"),
    "unknown method": (["--method", "fast"], "invalid choice: 'fast'"),
    "workers zero": (["-j", "0"], "argument -j/--workers"),
    "small scale": (["--scale", "5"], "at least 20"),
    "unknown field": (["--fields", "mean,colour"], "unknown field 'colour'"),
    "gamma out of range": (["--gamma", "2"], "gamma must lie in [0, 1]"),
    "output extension": (["-o", "{tmp}/out.e57"], "unknown output extension '.e57'"),
    "output directory": (["-o", "{tmp}/no/such/dir/out.ply"], "does not exist"),
    "viewpoint and input normals": (["--viewpoint", "0,0,1", "--normals-from-input"], "not allowed with argument"),
    "no input normals": (["--normals-from-input"], "has no normals"),
    "quiet and verbose": (["-q", "-v"], "--quiet and --verbose exclude each other"),
}


def test_bad_option_value_in_a_real_process(tmp_path, sphere_ply):
    out = run("compute", sphere_ply, "-o", tmp_path / "out.ply", "--viewpoint", "1,2")
    assert_one_line_error(out)
    assert "argument --viewpoint: expected three numbers X,Y,Z, got '1,2'" in out.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("case", sorted(BAD_OPTIONS))
def test_bad_options(tmp_path, sphere_ply, capsys, case):
    # in this process (argparse and option checks; the real process is tested above)
    extra, message = BAD_OPTIONS[case]
    extra = [arg.replace("{tmp}", str(tmp_path)) for arg in extra]
    args = ["compute", str(sphere_ply)] + (extra if "-o" in extra else ["-o", str(tmp_path / "out.ply")] + extra)
    status = main(args)
    captured = capsys.readouterr()
    assert_one_line_error(subprocess.CompletedProcess(args, status, captured.out, captured.err))
    assert message in captured.err
    assert list(tmp_path.iterdir()) == []


def test_unexpected_errors_and_interrupts(monkeypatch, capsys, sphere_ply):
    def bug(args, log):
        raise RuntimeError("something broke\nsecond line")

    monkeypatch.setattr(info, "run", bug)
    assert main(["info", str(sphere_ply)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("heatcurv: error: unexpected RuntimeError: something broke")
    assert "--debug" in err
    with pytest.raises(RuntimeError):
        main(["info", str(sphere_ply), "--debug"])

    def interrupted(args, log):
        raise KeyboardInterrupt

    monkeypatch.setattr(info, "run", interrupted)
    assert main(["info", str(sphere_ply)]) == 130
    assert "Traceback" not in capsys.readouterr().err


def test_warnings_are_one_line_on_stderr(monkeypatch, capsys, sphere_ply):
    import warnings

    def warns(args, log):
        warnings.warn(heatcurv.HeatcurvWarning("the area system did not converge\nafter 500 iterations"), stacklevel=2)
        warnings.warn(RuntimeWarning("invalid value in divide"), stacklevel=2)  # library noise: only with --verbose
        return 0

    monkeypatch.setattr(info, "run", warns)
    assert main(["info", str(sphere_ply), "--quiet"]) == 0
    assert capsys.readouterr().err == "heatcurv: warning: the area system did not converge after 500 iterations\n"
