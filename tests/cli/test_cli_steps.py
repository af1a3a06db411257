"""heatcurv.cli.steps: bad input files fail with one line, status 2 and no output file."""

import numpy as np
import pytest
from cli_helpers import assert_one_line_error, run

from heatcurv import io


def _write_bad_inputs(directory):
    """Bad input files by case name."""
    rng = np.random.default_rng(0)
    files = {}
    good = rng.normal(size=(3000, 3))
    for ext in (".ply", ".las"):
        full = directory / f"full{ext}"
        io.write_points(full, good)
        data = full.read_bytes()
        (directory / f"truncated{ext}").write_bytes(data[: len(data) // 2])
        files[f"truncated{ext}"] = directory / f"truncated{ext}"
    (directory / "garbage.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\n" + rng.bytes(500))
    (directory / "garbage.las").write_bytes(rng.bytes(3000))
    (directory / "empty.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    (directory / "zero_bytes.xyz").write_bytes(b"")
    (directory / "nan_rows.xyz").write_text("0 0 0\n1 0 0\nnan 1 1\n0 1 0\n1 1 1\n0.5 0.5 0\n")
    (directory / "too_few.xyz").write_text("0 0 0\n1 0 0\n0 1 0\n")
    np.save(directory / "line.npy", np.outer(np.arange(100.0), [1.0, 2.0, 3.0]))
    (directory / "table.csv").write_text("name,age\nbob,42\nalice,37\n")
    (directory / "image.ply").write_bytes(b"\x89PNG\r\n\x1a\n" + rng.bytes(300))
    (directory / "scan.e57").write_bytes(b"not supported")
    for name in ("garbage.ply", "garbage.las", "empty.ply", "zero_bytes.xyz", "nan_rows.xyz", "too_few.xyz",
                 "line.npy", "table.csv", "image.ply", "scan.e57"):
        files[name] = directory / name
    files["missing"] = directory / "missing.ply"
    files["directory"] = directory / "a_directory.ply"
    files["directory"].mkdir()
    return files


@pytest.fixture(scope="module")
def bad_inputs(tmp_path_factory):
    return _write_bad_inputs(tmp_path_factory.mktemp("bad"))


BAD_FILES = {
    "missing": "no such file",
    "directory": "directory",
    "scan.e57": "unknown extension '.e57'; supported: .ply .las",
    "zero_bytes.xyz": "empty",
    "truncated.ply": "the header announces 3000 vertices of 24 bytes",
    "garbage.ply": "not a valid PLY file",
    "truncated.las": "truncated: the header announces 3000 points of 30 bytes, the file holds room for 1493",
    "garbage.las": "not a LAS/LAZ file: it starts with",
    "empty.ply": "no points",
    "nan_rows.xyz": "NaN or infinite coordinates (rows 2,",
    "too_few.xyz": "too few points",
    "line.npy": "lie on one line",
    "table.csv": "cannot read",
    "image.ply": "not a valid PLY file",
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_input_files(tmp_path, bad_inputs, case):
    output = tmp_path / "out.ply"
    out = run("compute", bad_inputs[case], "-o", output)
    assert_one_line_error(out)
    assert BAD_FILES[case] in out.stderr
    assert list(tmp_path.iterdir()) == []  # no output, no temporary file
