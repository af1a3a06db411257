"""The big fuzz campaign of the readers (issue 11): every format, hundreds of mutated files each.

Runs :func:`support.fuzz.run_campaign` (the test suite's
``tests/fuzz/test_fuzz_files.py`` runs the same with 48 files per variant)
and prints the machine, the outcome table (variant x outcome counts, the
accepted files that contradict their own header, the worst time and peak
memory growth of one case), then every failing case grouped by variant,
mutator and outcome, with one example message and the command that
reproduces it. Run ``python benchmarks/fuzz.py`` (``--per-format 400``, about
10 minutes on a 2-core machine with clean readers, plus 10 s per hang);
``--markdown`` for a Markdown table. The exit status is 1 when a case failed.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import sys
import time
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # tests/support: the fuzz harness

from machine import commit, cpu_model, memory_text, table  # noqa: E402  (benchmarks/machine.py)
from support import fuzz  # noqa: E402


def machine() -> str:
    """One line naming this machine and the reader libraries' versions."""
    from importlib.metadata import version

    versions = f"Python {platform.python_version()}, " + ", ".join(
        f"{name} {version(name)}" for name in ("numpy", "plyfile", "laspy", "lazrs"))
    return (f"{cpu_model()}, {os.cpu_count()} cores{memory_text()}; {platform.system()} {platform.release()}; "
            f"{versions}; heatcurv at commit {commit()}")


def grouped(results) -> list:
    """Rows ``variant, mutator, outcome, count, example`` of the failing (or contradicting) cases."""
    groups = defaultdict(list)
    for r in results:
        groups[(r.variant, r.mutator, r.outcome)].append(r)
    rows = []
    for (variant, mutator, outcome), cases in sorted(groups.items()):
        first = cases[0]
        message = re.sub(r"/\S*/heatcurv-fuzz-[^/\s]+/", "", first.contradiction or first.detail)
        rows.append([variant, mutator, outcome, str(len(cases)), message[:140],
                     first.reproduce])
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-format", type=int, default=400, help="mutated files per variant (default 400)")
    parser.add_argument("--seed", type=int, default=0, help="the campaign's seed (default 0)")
    parser.add_argument("--timeout", type=float, default=fuzz.TIMEOUT, help="seconds per case (default 10)")
    parser.add_argument("--variants", nargs="+", choices=sorted(fuzz.VARIANTS), help="only these variants")
    parser.add_argument("--markdown", action="store_true", help="Markdown tables")
    args = parser.parse_args(argv)

    done = [0]
    total = args.per_format * len(args.variants or fuzz.VARIANTS)

    def progress(result):
        done[0] += 1
        if done[0] % 200 == 0 or result.outcome in fuzz.FAILURES:
            print(f"  {done[0]}/{total}: {result}" if result.outcome in fuzz.FAILURES else f"  {done[0]}/{total}",
                  file=sys.stderr, flush=True)

    start = time.perf_counter()
    campaign = fuzz.run_campaign(args.per_format, args.seed, variants=args.variants, timeout=args.timeout,
                                 progress=progress)
    wall = time.perf_counter() - start
    print(f"Machine: {machine()}\n")
    print(f"{len(campaign.results)} mutated files ({args.per_format} per variant, seed {args.seed}) in {wall:.0f} s, "
          f"{campaign.restarts} worker restarts; timeout {args.timeout:g} s, address-space headroom "
          f"{fuzz.MEMORY_LIMIT / 2**30:.1f} GiB, memory threshold {fuzz.MEMORY_FACTOR} x file + "
          f"{fuzz.MEMORY_BASE // 2**20} MiB ("
          + ", ".join(f"{ext} {factor} x" for ext, factor in fuzz.COMPRESSED_MEMORY_FACTOR.items()) + ")\n")
    header, rows = campaign.rows()
    print(table("Outcomes by variant", header, rows, args.markdown))
    failures = campaign.failures()
    detail = ["variant", "mutator", "outcome", "cases", "first message", "reproduce"]
    if failures:
        print(table("Failing cases", detail, grouped(failures), args.markdown))
    contradictions = campaign.contradictions()
    if contradictions:
        rows = grouped(contradictions)
        for row in rows:
            row[2] = "contradiction"
        print(table("Accepted files that contradict their header", detail, rows, args.markdown))
    if not failures and not contradictions:
        print("No failing case.")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
