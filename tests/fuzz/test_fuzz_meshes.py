"""The OFF, OBJ and NPZ mutations of the fuzz campaign one by one, each with the error it must give.

The campaign (``test_fuzz_files.py``) only checks that a mutated file is read or refused in one
line; here each kind of contradiction is applied to the 120-point seed and the message asserted.
"""

import io
import re
import zipfile

import numpy as np
import pytest

from heatcurv.errors import HeatcurvError
from heatcurv.io import read_points
from support import fuzz
from support.mutators import _OBJ_FACE_EDITS, _OFF_LINE_EDITS, mutate, obj_face_edit, off_line_edit

N = fuzz.N_SEED  # 120 vertices; the OFF seed: lines 4-123 vertices, 124-241 its 118 faces
EXPECTED_FACE = r"line \d+: (expected a face \('k i1 \.\.\. ik'\) after the 120 vertices the header announces, found" \
                r" '[\d. ]+'|the face announces \d+ vertices, the line holds 6 values after it)$"


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    files = fuzz.seed_files(tmp_path_factory.mktemp("seeds"))
    return {name: path.read_bytes() for name, path in files.items()}


def _refusal(path, data):
    path.write_bytes(data)
    with pytest.raises(HeatcurvError) as caught:
        read_points(path)
    message = str(caught.value)
    assert message.startswith(f"cannot read {path}: ") and "\n" not in message
    return message[len(f"cannot read {path}: "):]


@pytest.mark.parametrize(
    "counts,expected",
    [
        ("1 118 0", r"line 5: expected a face \('k i1 \.\.\. ik'\) after the 1 vertex the header announces, found "
                    r"'975\.161 1977\.25 50\.5522 127 151 153 255'$"),
        ("119 118 0", r"line 123: expected a face \('k i1 \.\.\. ik'\) after the 119 vertices the header announces"),
        ("121 118 0", r"^line 124: expected 7 values, found 4 \(vertex 121 of the 121 the header announces\)$"),
        ("120 117 0", r"^line 241: more lines than the header announces \(120 vertices and 117 faces\)$"),
        ("120 119 0", r"^the header announces 119 faces, the file has 118 lines after its 120 vertices$"),
        ("120 0 0", r"^line 124: more lines than the header announces \(120 vertices and 0 faces\)$"),
    ],
)
def test_off_counts_that_do_not_match_the_lines_are_refused(tmp_path, seeds, counts, expected):
    data = seeds["off"].replace(b"\n120 118 0\n", f"\n{counts}\n".encode())
    assert data != seeds["off"]
    assert re.search(expected, _refusal(tmp_path / "m.off", data))


def test_off_edge_count_is_ignored(tmp_path, seeds):
    path = tmp_path / "m.off"
    path.write_bytes(seeds["off"].replace(b"\n120 118 0\n", b"\n120 118 4242\n"))
    assert len(read_points(path)) == N


OFF_EXPECTED = {
    "vertex-duplicated": EXPECTED_FACE,
    "vertex-deleted": r"^line 123: expected 7 values, found 4 \(vertex 120 of the 120 the header announces\)$",
    "face-duplicated": r"^line 242: more lines than the header announces \(120 vertices and 118 faces\)$",
    "face-deleted": r"^the header announces 118 faces, the file has 117 lines after its 120 vertices$",
    "index-out-of-range": r"^line \d+: face vertex index (120|-1|4294967296) is out of range \(the header announces "
                          r"120 vertices, numbered 0 to 119\)$",
    "index-not-whole": r"^line \d+: face vertex index '(1\.5|x|1e3|0x10|9{30})' is not a whole number$",
    "corner-count": r"^line \d+: (a face of (0|-3) vertices|the face announces [45] vertices, the line holds 3 values "
                    r"after it)$",
    "face-values": r"^line \d+: ((2|5) values after the face's 3 vertex indices \(a face colour is 1, 3 or 4 values\)"
                   r"|face colour value 'red' is not a number)$",
    "line-appended": r"^line 242: more lines than the header announces \(120 vertices and 118 faces\)$",
}


@pytest.mark.parametrize("edit", sorted(_OFF_LINE_EDITS))
def test_every_off_line_edit_gives_its_error(tmp_path, seeds, edit):
    for case in range(12):
        data = off_line_edit(seeds["off"], edit, np.random.default_rng(case))
        assert data != seeds["off"]
        path = tmp_path / f"{edit}-{case}.off"
        if edit == "harmless":  # comments, blank lines, face colours, counts on the keyword's line: read
            path.write_bytes(data)
            cloud = read_points(path)
            assert len(cloud) == N and cloud.meta["faces"] == N - 2
            continue
        message = _refusal(path, data)
        assert re.search(OFF_EXPECTED[edit], message), (case, message)


OBJ_EXPECTED = {
    "index-out-of-range": r"^line \d+: vertex index 121 is out of range: the file has 120 v lines$",
    "index-before-the-start": r"^line \d+: vertex index -121 is out of range: the face follows 120 v lines$",
    "index-zero": r"^line \d+: vertex index 0 \(OBJ indices start at 1, or count back from -1\)$",
    "index-not-whole": r"^line \d+: '(1\.5|x|)//\d+' is not a face corner \(a vertex index, then optionally",
    "corner-malformed": r"^line \d+: '1/2/3/4//\d+' is not a face corner",
    "vertex-deleted": r"^line \d+: vertex index 120 is out of range: the file has 119 v lines$",
}


@pytest.mark.parametrize("edit", sorted(_OBJ_FACE_EDITS))
def test_every_obj_face_edit_gives_its_error(tmp_path, seeds, edit):
    for case in range(6):
        data = obj_face_edit(seeds["obj"], edit, np.random.default_rng(case))
        assert data != seeds["obj"]
        path = tmp_path / f"{edit}-{case}.obj"
        if edit == "relative":  # every index counted back from the last vertex: the same file
            path.write_bytes(data)
            assert b"f -" in data and len(read_points(path)) == N
            continue
        message = _refusal(path, data)
        assert re.search(OBJ_EXPECTED[edit], message), (case, message)


def test_an_npz_of_one_point_beside_per_point_fields_is_refused(tmp_path, seeds):
    # the npz-member mutation that puts a (1, 3) 'points' beside the seed's 120-row fields
    for case in range(200):
        data = mutate(seeds["npz"], "npz-member", case)
        path = tmp_path / "one.npz"
        path.write_bytes(data)
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            names = archive.namelist()
            points = archive.read("points.npy") if names.count("points.npy") == 1 else b""
        if b"(1, 3)" in points[:128]:
            break
    else:
        pytest.fail("no npz-member case put a one-row 'points'")
    message = _refusal(path, data)
    assert re.search(r"^'\w+' has 120 rows but 'points' has 1: every per-point array of an NPZ cloud", message)
