"""The pymeshlab_samples fixture skips without the scans, or fails when CI requires them.

Runs pytest on a copy of this directory's conftest with ``HEATCURV_TEST_DATA``
pointing at a directory of other files, which the fetch refuses at once
(no network involved).
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent


@pytest.mark.parametrize("require", [False, True], ids=["skip", "fail"])
def test_fixture_skips_or_fails_with_the_reason(tmp_path, require):
    shutil.copy(HERE / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_uses_scans.py").write_text("def test_it(pymeshlab_samples):\n    pass\n")
    occupied = tmp_path / "occupied"
    occupied.mkdir()
    (occupied / "other.txt").write_text("not a sample cache")
    # the copied conftest imports the fetchers from tests/support, which is not installed
    path = os.pathsep.join(p for p in [str(HERE.parent), os.environ.get("PYTHONPATH", "")] if p)
    env = dict(os.environ, HEATCURV_TEST_DATA=str(occupied), PYTHONPATH=path)
    env.pop("HEATCURV_REQUIRE_REAL_SCANS", None)
    if require:
        env["HEATCURV_REQUIRE_REAL_SCANS"] = "1"
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", "--rootdir", str(tmp_path),
         str(tmp_path)],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120,
    )
    out = proc.stdout + proc.stderr
    assert "not a complete pymeshlab sample cache" in out, out
    if require:
        assert proc.returncode == 1 and "1 error" in out and "HEATCURV_REQUIRE_REAL_SCANS=1" in out, out
    else:
        assert proc.returncode == 0 and "1 skipped" in out and "real scans not available" in out, out
