"""The recorded accuracy numbers the tests hold heatcurv to, and how they are regenerated.

Every error a test measures against an exact value (or against a reference
it can be judged by: a mesh's normals, the other half of a cloud) is checked
against one table, ``tests/records.json``, in both directions:

* worse: a measured error above ``WORSE`` x its record fails (a regression);
* better: a measured error below its record / ``BETTER`` fails too, until the
  record is regenerated, so that no record, and no bound derived from it,
  goes stale while the method improves.

Errors are recorded in the units the test reports (``%`` for relative errors,
degrees for angles; see :data:`FLOORS`). An error at the level of rounding
(below its unit's floor) is held below ``WORSE`` x the floor, and a change
within that level is not a drift. The samples are deterministic, so an
unchanged estimator reproduces every record to rounding.

Regenerate after a deliberate change (then review the diff of records.json,
and say in the commit what moved and why)::

    python -m pytest --update-records                         # every record
    python -m pytest --update-records tests/test_estimator.py # those of one file

In that mode the checks record instead of asserting; the other assertions of
the tests still run. Records of tests that did not run are kept.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import platform
import subprocess
from pathlib import Path

__all__ = ["BETTER", "FLOORS", "PATH", "WORSE", "Records"]

#: the table, next to this module
PATH = Path(__file__).with_name("records.json")
#: a measured error may be this many times its record
WORSE = 1.5
#: a measured error this many times below its record means the record is stale
BETTER = 2.0
#: rounding level of an error, by the metric's unit (its name's suffix): relative errors in % resolve
#: about 1e-9 of the value (the chord fit on a sphere: 2e-10 relative), angles 1e-7 deg (2e-9 rad)
FLOORS = {"_deg": 1e-7, "": 1e-7}
#: significant digits kept in the table
DIGITS = 4


def floor_of(metric: str) -> float:
    """The rounding level of ``metric``, by the suffix of its name (:data:`FLOORS`)."""
    return next(value for suffix, value in FLOORS.items() if metric.endswith(suffix))


def _rounded(value: float) -> float:
    return float(f"{value:.{DIGITS - 1}e}")


def _provenance() -> str:
    """``<short commit>[+dirty] on <machine>``, for the records a run writes."""
    here = Path(__file__).parent
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True, check=True
        ).stdout.strip()
        status = ["git", "status", "--porcelain", "--", "../src"]
        dirty = subprocess.run(status, cwd=here, capture_output=True, text=True)
        commit += "+dirty" if dirty.stdout.strip() else ""
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{commit} on {cpu} ({os.cpu_count()} cores)"


class Records:
    """The table of records, checked (default) or rewritten (``--update-records``).

    Parameters
    ----------
    update : bool
        Record every measured value instead of checking it.
    path : Path, optional
        The table (default :data:`PATH`).
    """

    def __init__(self, update: bool, path: Path = PATH):
        self.update, self.path = update, path
        self.table = json.loads(path.read_text()) if path.exists() else {}
        self.measured: dict[str, dict[str, float]] = {}

    def check(self, key: str, **errors: float) -> None:
        """Hold each error of case ``key`` to its record (or record it).

        Parameters
        ----------
        key : str
            The case, e.g. ``"estimator/torus-random-10000"``: one per
            measured cloud and estimator setting.
        **errors : float
            Metric name -> measured error (>= 0, smaller is better; signed
            errors are compared by magnitude). A name ending in ``_deg`` is an
            angle in degrees; any other is in %. NaN is an error: a metric
            that does not apply must not be passed.
        """
        for metric, value in errors.items():
            if not math.isfinite(value):
                raise AssertionError(f"{key}: {metric} is {value}")
        if self.update:
            self.measured[key] = {metric: _rounded(value) for metric, value in errors.items()}
            return
        if key not in self.table:
            raise AssertionError(f"no record for {key!r}: run python -m pytest --update-records on its test")
        record = self.table[key]
        stored = {m for m in record if not m.startswith("@")}
        if stored != set(errors):
            raise AssertionError(f"{key}: the record has {sorted(stored)}, the test measures {sorted(errors)}")
        problems = []
        for metric, value in errors.items():
            floor = floor_of(metric)
            was, now = abs(record[metric]), abs(value)
            if now > WORSE * max(was, floor):
                problems.append(f"{metric} worse: {value:.4g} against the record {record[metric]:.4g}")
            elif was > floor and now < was / BETTER:
                problems.append(
                    f"{metric} better: {value:.4g} against the record {record[metric]:.4g} (update the record)"
                )
        if problems:
            raise AssertionError(f"{key} (recorded at {record.get('@', '?')}): " + "; ".join(problems))

    def write(self) -> None:
        """Merge the measured records into the table (update mode), with their provenance."""
        if not self.measured:
            return
        made = _provenance()
        # the test workers (pytest-xdist) each merge their own records: one at a time
        with open(self.path, "a") as held:
            fcntl.flock(held, fcntl.LOCK_EX)
            text = self.path.read_text()
            table = json.loads(text) if text else {}
            for key, errors in self.measured.items():
                table[key] = {"@": made, **errors}
            self.path.write_text(json.dumps(dict(sorted(table.items())), indent=1) + "\n")
