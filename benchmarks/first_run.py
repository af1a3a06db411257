"""How long a fresh install's first ``heatcurv demo -n 5000`` takes, and the runs after it.

The first run of a fresh install waits for numba to compile heatcurv's
kernels (:mod:`heatcurv._kernels`); later runs load the machine code from
numba's cache. Each run here is a fresh ``heatcurv demo -n 5000`` process
(picture included, written to a temporary directory), timed from outside:

``--cache`` (default)  the installed heatcurv with ``NUMBA_CACHE_DIR`` pointing
                       at a new empty directory: the first run compiles
                       everything, as after ``pip install``;
``--fresh-venv``       a new virtual environment with a non-editable
                       ``pip install`` of this checkout (a minute or two),
                       its own cache in site-packages ``__pycache__``: what a
                       user gets.

The table gives each run's wall and CPU time (the children's user + system
time), whether it printed the compile notice (``heatcurv: compiling ...`` on
stderr, which is a pseudo-terminal here as in a user's shell) and the demo's
own time for the default method. Run ``python benchmarks/first_run.py`` (about 30 s) or
``--fresh-venv``; ``--runs 3`` times three runs after the first.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # tests/support: test-only helpers

from machine import commit, cpu_model  # noqa: E402  (benchmarks/machine.py)
from support.terminal import run_on_a_terminal  # noqa: E402

ROOT = HERE.parent
NOTICE = "heatcurv: compiling"


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run(command, env, cwd):
    """Run ``command`` with stderr on a pseudo-terminal, as in a user's shell (the notice is shown there only)."""
    return run_on_a_terminal(command, env=env, cwd=cwd)


def timed(command, env, cwd) -> dict:
    """Run ``command`` once; wall and CPU seconds, the compile notice, the demo's time for the default method."""
    cpu, tic = children_cpu(), time.perf_counter()
    status, out, err = run(command, env, cwd)
    wall, cpu = time.perf_counter() - tic, children_cpu() - cpu
    if status != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{err}")
    default = re.search(r"^default\s.*\s(\d+\.\d+)\s*$", out, re.MULTILINE)
    return dict(wall=wall, cpu=cpu, notices=err.count(NOTICE), default=float(default.group(1)) if default else None)


def fresh_venv(where: Path) -> Path:
    """A new venv with heatcurv installed from this checkout (not editable); its ``heatcurv`` script."""
    print(f"creating a virtual environment in {where} and installing {ROOT} into it ...", flush=True)
    subprocess.run([sys.executable, "-m", "venv", str(where)], check=True)
    python = where / ("Scripts" if os.name == "nt" else "bin") / "python"
    subprocess.run([str(python), "-m", "pip", "install", "-q", str(ROOT)], check=True)
    return python


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    how = parser.add_mutually_exclusive_group()
    how.add_argument("--cache", action="store_true", help="empty NUMBA_CACHE_DIR, installed heatcurv (default)")
    how.add_argument("--fresh-venv", action="store_true", help="a new venv with a non-editable install")
    parser.add_argument("--runs", type=int, default=1, help="runs after the first (default 1)")
    parser.add_argument("-n", type=int, default=5000, help="points of the demo (default 5000)")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="heatcurv-first-run-") as tmp:
        tmp = Path(tmp)
        env = dict(os.environ)
        if args.fresh_venv:
            env.pop("NUMBA_CACHE_DIR", None)
            python = fresh_venv(tmp / "venv")
            where = "fresh venv, non-editable install, numba's cache in site-packages"
        else:
            env["NUMBA_CACHE_DIR"] = str(tmp / "numba-cache")
            python = Path(sys.executable)
            where = "installed heatcurv, empty NUMBA_CACHE_DIR"
        command = [str(python), "-m", "heatcurv", "demo", "-n", str(args.n)]
        rows = []
        for k in range(1 + args.runs):
            rows.append(("first" if k == 0 else f"warm {k}", timed(command, env, tmp)))
            print(f"  {rows[-1][0]}: {rows[-1][1]['wall']:.1f} s", flush=True)

    import numba
    import numpy

    print()
    print(f"Machine: {cpu_model()}, {os.cpu_count()} cores; {platform.system()} {platform.release()}; "
          f"Python {platform.python_version()}, numpy {numpy.__version__}, numba {numba.__version__}; "
          f"heatcurv at commit {commit()}")
    print(f"`heatcurv demo -n {args.n}` ({where}), each run a new process:")
    print()
    print("| run | wall s | CPU s | compile notice | demo's time for default s |")
    print("|---|---|---|---|---|")
    for name, r in rows:
        default = "-" if r["default"] is None else f"{r['default']:.2f}"
        print(f"| {name} | {r['wall']:.1f} | {r['cpu']:.1f} | {'yes' if r['notices'] else 'no'} | {default} |")
    first, warm = rows[0][1]["wall"], min(r["wall"] for _, r in rows[1:]) if len(rows) > 1 else float("nan")
    print()
    print(f"compilation costs the first run {first - warm:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
