"""heatcurv.cli.main: help, version, exit statuses, one-line errors and warnings, --debug."""

import re
import subprocess

import pytest
from cli_helpers import assert_one_line_error, run, run_process, stderr_lines

import heatcurv
from heatcurv.cli import info, main


def test_bad_arguments_give_one_line_and_status_2():
    out = run("demo", "-n", "3")
    assert out.returncode == 2
    assert out.stderr.strip().startswith("heatcurv: error: argument -n: n = 3 is outside its range [4, 10000000]: ")
    assert len(out.stderr.strip().splitlines()) == 1
    assert "Traceback" not in out.stderr


def test_debug_shows_the_traceback():
    # the interpreter prints the traceback of the exception --debug lets through: a process of its own
    out = run_process("--debug", "info", "no_such_file.ply")
    assert out.returncode != 0 and "Traceback" in out.stderr


def test_the_in_process_runner_gives_what_a_process_gives(tmp_path, sphere_ply):
    # the other command-line tests run main() in their own process (cli_helpers.run): it must report the
    # status, stdout and stderr a separate process reports, a warning (the paper's kernel cut short) and an
    # error included
    commands = [("info", sphere_ply), ("demo", "-n", "3"), ("info", tmp_path / "missing.ply"),
                ("compute", sphere_ply, "-o", tmp_path / "{}.ply", "--method", "paper", "--alpha", "4", "--m", "1")]

    def same(text):  # the output's name and the time taken aside
        return re.sub(r" in \d+(\.\d+)? s\b", " in ... s", text.replace("in_this_process", "in_a_new_one"))

    for command in commands:
        here = run(*(str(arg).format("in_this_process") for arg in command))
        there = run_process(*(str(arg).format("in_a_new_one") for arg in command))
        assert here.returncode == there.returncode, command
        assert same(here.stdout) == same(there.stdout), command
        assert [same(line) for line in stderr_lines(here)] == [same(line) for line in stderr_lines(there)], command
    assert "heatcurv: warning: " in there.stderr and (tmp_path / "in_a_new_one.ply").exists()


def test_help_and_version():
    assert "demo" in run_process("--help").stdout  # the module's entry point, python -m heatcurv
    assert run("--version").stdout.startswith("heatcurv ")
    assert run().returncode == 2  # a subcommand is required


@pytest.mark.parametrize(
    "command, option",
    [
        ("compute", "--normals-from-input"), ("render", "--views"), ("features", "--threshold"), ("info", "input"),
        ("demo", "--surface"), ("compute", "--float64"), ("features", "--float64"), ("view", "--max-points"),
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
    "small scale": (["--scale", "5"], "scale = 5 is outside its range [20, 1000000]"),
    "unknown field": (["--fields", "mean,colour"], "unknown field 'colour'"),
    "gamma out of range": (["--gamma", "2"], "gamma = 2 is outside its range [0, 1]"),
    "alpha too large": (["--alpha", "1e9"], "alpha = 1e+09 is outside its range [0.5, 20]"),
    "m too small": (["--m", "1e-300"], "m = 1e-300 is outside its range [0.001, 10]"),
    "workers overflow": (["--workers", "1e30"], "argument -j/--workers: expected an integer, got '1e30'"),
    "neighbours too many": (["--neighbours", "1998"], "neighbours = 1998 is outside its range [20, 1920]"),
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


@pytest.mark.parametrize("name, status", [("SIGTERM", 143), ("SIGHUP", 129)])
def test_termination_is_handled_like_ctrl_c(monkeypatch, capsys, sphere_ply, name, status):
    import os
    import signal

    signum = getattr(signal, name, None)
    if signum is None:
        pytest.skip(f"no {name} here")
    before = signal.getsignal(signum)
    unwound = []

    def terminated(args, log):
        try:
            os.kill(os.getpid(), signum)
            for _ in range(1000):  # the handler raises at the next bytecode; never reaches the end
                pass
            raise AssertionError("the signal did not stop the command")
        finally:
            unwound.append(True)

    monkeypatch.setattr(info, "run", terminated)
    assert main(["info", str(sphere_ply)]) == status
    assert capsys.readouterr().err == f"heatcurv: terminated by {name}\n"
    assert unwound == [True] and signal.getsignal(signum) == before  # the caller's handler is back


_KILLED_COMPUTE = """
import sys, time
import heatcurv.io as hio
from heatcurv.cli import main

def slow(stream, output, target):
    stream.write(b"x" * (32 << 20))  # 32 MB of the output written, then wait to be terminated
    stream.flush()
    print("writing", flush=True)
    # Short sleeps: a process-directed SIGTERM may land on another thread (numba's, tqdm's), and
    # Python runs its handler only when the main thread next wakes up.
    for _ in range(1200):
        time.sleep(0.1)

hio._WRITERS[".ply"] = slow
sys.exit(main(["compute", sys.argv[1], "-o", sys.argv[2], "--quiet"]))
"""


def test_terminated_compute_leaves_no_temporary_file_and_the_old_output(tmp_path, sphere_ply):
    import signal
    import sys

    output = tmp_path / "out.ply"
    output.write_bytes(b"previous result")
    child = subprocess.Popen(
        [sys.executable, "-c", _KILLED_COMPUTE, str(sphere_ply), str(output)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    assert child.stdout.readline().strip() == "writing"
    assert len([p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]) == 1  # mid-write
    child.send_signal(signal.SIGTERM)
    _, err = child.communicate(timeout=60)
    assert child.returncode == 143
    assert err == "heatcurv: terminated by SIGTERM\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.ply"]
    assert output.read_bytes() == b"previous result"
