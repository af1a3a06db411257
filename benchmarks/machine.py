"""Shared by the benchmark scripts: what machine a benchmark ran on, and its tables as text or Markdown."""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
from pathlib import Path


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (Linux), else what :mod:`platform` knows."""
    cpu = platform.processor() or platform.machine() or "unknown"
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return cpu


def memory_text() -> str:
    """``", 24 GiB RAM"``: the machine's memory from /proc/meminfo (Linux), else ``""``."""
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
    except (OSError, ValueError, IndexError):
        return ""
    return f", {kb / 1024**2:.0f} GiB RAM"


def commit() -> str:
    """The commit this checkout is at: ``"bbc4b93"``, ``"bbc4b93+dirty"`` if src/ or benchmarks/ have uncommitted
    changes, ``"unknown"`` outside a git checkout (or without git)."""
    here = Path(__file__).resolve().parent

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=here, capture_output=True, text=True, timeout=30,
                              check=True).stdout.strip()

    try:
        head = git("rev-parse", "--short", "HEAD")
        dirty = git("status", "--porcelain", "--", ":/src", ":/benchmarks")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (head + "+dirty" if dirty else head) or "unknown"


def table(title: str, header: list, rows: list, markdown: bool, heading: str = "### {}") -> str:
    """A table of text cells: Markdown (``heading`` formats the title) or right-aligned plain text."""
    if markdown:
        out = [heading.format(title), "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        out += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(out) + "\n"
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(header)]
    line = "  ".join(h.rjust(w) for h, w in zip(header, widths))
    out = [title, "=" * len(title), line, "-" * len(line)]
    out += ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(out) + "\n"


def run_header() -> str:
    """The lines a benchmark's output starts with: date, machine, Python and numpy, heatcurv and its commit."""
    import numpy as np

    import heatcurv

    system = f"{platform.system()} {platform.release()}"
    return "\n".join([
        f"date (UTC)   {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}",
        f"machine      {cpu_model()}, {os.cpu_count()} cores{memory_text()}; {system}",
        f"python       {platform.python_version()}, numpy {np.__version__}",
        f"heatcurv     {heatcurv.__version__} (commit {commit()})",
    ]) + "\n"


def markdown_arguments(doc: str, argv=None) -> argparse.Namespace:
    """The arguments of a benchmark whose only option is ``--markdown``; ``doc`` its help text."""
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--markdown", action="store_true", help="print the tables as Markdown")
    return parser.parse_args(argv)


def warm_up() -> None:
    """Compile heatcurv's kernels on a small cloud, so that no timed call pays for it."""
    import heatcurv
    from heatcurv import surfaces

    heatcurv.estimate(surfaces.get("sphere").sample(500, "fibonacci").points)
