"""Issue 11: mutated files of every format read in a child process never crash, hang or take unbounded memory.

A seeded campaign (:func:`support.fuzz.run_campaign`) mutates the
120-point seed of each variant ``CASES`` times and reads every file in a
worker under a 1.5 GiB address-space headroom and a 10 s timeout; every
rejection must be one line that names the file and the problem. The unit
tests of the harness below make sure it cannot pass silently: a reader that
aborts is a crash, one that sleeps a hang, one that allocates is memory.

``HEATCURV_FUZZ_CASES`` changes the campaign's size (``benchmarks/fuzz.py``
runs a bigger one); each failing case prints the command that reproduces it.
"""

import os
import time

import numpy as np
import pytest

from heatcurv.errors import HeatcurvError
from heatcurv.io import read_points
from support import fuzz

#: Mutated files per variant (17 variants, 2040 files): about 45 s on the 2-core CI machine when no case fails
#: (20 ms a file); each hang adds its 10 s timeout and each crash or hang 2 s to start a new worker.
CASES = int(os.environ.get("HEATCURV_FUZZ_CASES", "120"))
SEED = 11


@pytest.fixture(scope="module")
def campaign():
    return fuzz.run_campaign(CASES, seed=SEED)


def _listing(results, limit=60):
    lines = [str(r) for r in results[:limit]]
    if len(results) > limit:
        lines.append(f"... and {len(results) - limit} more")
    return "\n".join(lines)


def test_no_reader_crashes_hangs_takes_unbounded_memory_or_says_too_little(campaign):
    failures = campaign.failures()
    header, rows = campaign.rows()
    table = "\n".join("  ".join(f"{c:>9}" for c in row) for row in [header, *rows])
    assert not failures, (
        f"{len(failures)} of {len(campaign.results)} mutated files (seed {SEED}, {CASES} per variant) broke the "
        f"readers' promise:\n{_listing(failures)}\n\n{table}"
    )


def test_accepted_files_agree_with_their_own_headers(campaign):
    found = campaign.contradictions()
    assert not found, f"files read although their header says otherwise:\n{_listing(found)}"


def test_every_variant_and_mutator_ran(campaign):
    assert set(campaign.counts()) == set(fuzz.VARIANTS)
    for variant in fuzz.VARIANTS:
        ran = {r.mutator for r in campaign.results if r.variant == variant}
        wanted = {m.name for m in fuzz.mutators_for(variant)}
        assert ran == wanted or len(ran) == CASES, (variant, sorted(wanted - ran))
    # the campaign is not all rejections: the mild mutations must still read
    assert sum(counts["ok"] for counts in campaign.counts().values()) > 0


def test_seed_files_read_back(tmp_path):
    files = fuzz.seed_files(tmp_path)
    assert set(files) == set(fuzz.VARIANTS)
    for name, path in files.items():
        cloud = read_points(path)
        assert cloud.points.shape == (fuzz.N_SEED, 3), name
        assert np.isfinite(cloud.points).all(), name
        assert fuzz.announced_points(fuzz.VARIANTS[name].family, path.read_bytes()) in (None, {fuzz.N_SEED}), name
    assert read_points(files["ply-ascii-faces"]).meta["faces"] == fuzz.N_SEED - 2
    assert read_points(files["laz-1.4-fmt7"]).normals is not None
    assert read_points(files["las-1.2-fmt3"]).colours is not None


def test_mutators_are_pure_and_deterministic(tmp_path):
    files = fuzz.seed_files(tmp_path)
    for name, path in files.items():
        data = path.read_bytes()
        for mutator in fuzz.mutators_for(name):
            if mutator.name == "npz-bomb":
                continue  # built once per process (lru_cache); checked below
            first, second = fuzz.mutate(data, mutator.name, 5), fuzz.mutate(data, mutator.name, 5)
            assert isinstance(first, bytes) and first == second, (name, mutator.name)
        assert path.read_bytes() == data
    assert fuzz.mutate(b"PK", "truncate-random", 1) == fuzz.mutate(b"PK", "truncate-random", 1)


def test_every_format_family_has_its_own_mutators():
    own = {family: {m.name for m in fuzz.MUTATORS.values() if m.families and family in m.families}
           for family in {v.family for v in fuzz.VARIANTS.values()}}
    for family, names in own.items():
        if family not in ("text", "obj"):  # the text formats get the encoding and token mutators
            assert names, family
    assert {"npz-bomb", "npz-member"} <= own["npz"]
    assert {"las-point-count", "las-vlr-count", "las-point-offset", "las-record-length", "las-scale",
            "las-point-format", "las-misalign"} <= own["las"]
    assert "laz-chunk-table" in own["laz"]
    assert fuzz.EXACT_OR_REFUSED <= set(fuzz.MUTATORS)


# ------------------------------------------------------------------------ the harness itself can fail
def reader_aborts(path):
    os.abort()


def reader_sleeps(path):
    time.sleep(60)


def reader_allocates(path):
    return np.ones(2**31).sum()  # 16 GiB: past the worker's address-space limit


def reader_touches(path):
    return float(np.ones(40 * 2**20).sum())  # 320 MiB touched: under the limit, over the threshold


def reader_raises_value_error(path):
    raise ValueError("could not convert string to float: 'x'")


def reader_opaque(path):
    raise HeatcurvError(f"cannot read {path}: not a valid LAS/LAZ file (35)")


def reader_two_lines(path):
    raise HeatcurvError(f"cannot read {path}: bad header\n  line 3: 'x'")


def reader_nameless(path):
    raise HeatcurvError("cannot read the file: it is truncated")


def reader_wraps_memory_error(path):
    try:
        np.ones(2**31)
    except MemoryError:
        raise HeatcurvError(f"cannot read {path}: the header announces too many points") from None


def reader_fine(path):
    raise HeatcurvError(f"cannot read {path}: truncated: the header announces 2000 points, the file holds 120")


@pytest.fixture(scope="module")
def worker():
    with fuzz.Worker(preload=("numpy", "heatcurv")) as worker:
        yield worker


def _outcome(worker, reader, timeout=10.0, size=1000):
    path = "/tmp/some file.ply"
    return fuzz.classify(worker.call(reader, path, timeout=timeout), path, size)


def test_an_aborting_reader_is_a_crash_and_the_worker_restarts(worker):
    before = worker.restarts
    outcome, detail = _outcome(worker, reader_aborts)
    assert outcome == "crash" and "SIGABRT" in detail
    assert _outcome(worker, reader_fine)[0] == "error"
    assert worker.restarts == before + 1


def test_a_sleeping_reader_is_a_hang(worker):
    start = time.monotonic()
    outcome, detail = _outcome(worker, reader_sleeps, timeout=1.0)
    assert outcome == "hang" and time.monotonic() - start < 8
    assert _outcome(worker, reader_fine)[0] == "error"


def test_an_allocating_reader_is_memory(worker):
    assert _outcome(worker, reader_allocates)[0] == "memory"
    # a MemoryError hidden behind a good message (raise ... from None) is still found
    assert _outcome(worker, reader_wraps_memory_error)[0] == "memory"
    outcome, detail = _outcome(worker, reader_touches)
    assert outcome == "memory" and "MiB" in detail
    assert _outcome(worker, reader_touches, size=100 * 2**20)[0] == "ok"  # in proportion to a big file


def test_messages_are_judged(worker):
    assert _outcome(worker, reader_raises_value_error)[0] == "exception"
    assert _outcome(worker, reader_opaque)[0] == "bad-message"
    assert _outcome(worker, reader_two_lines)[0] == "bad-message"
    assert _outcome(worker, reader_nameless)[0] == "bad-message"
    assert _outcome(worker, reader_fine) == (
        "error", "cannot read /tmp/some file.ply: truncated: the header announces 2000 points, the file holds 120")


def test_message_problem():
    path = "/data/scan.laz"
    for fine in ["not a valid LAZ file (the chunk table is cut short)",
                 "the laszip VLR names an unknown compressor (99)",
                 "the legacy point count (65535) and the 64-bit point count (120) disagree",
                 "the header announces an array of shape () float64, the file holds 5760 bytes"]:
        assert fuzz.message_problem(f"cannot read {path}: {fine}", path) is None, fine
    for problem in ["not a valid LAS/LAZ file (35)", "not a valid PLY file (MemoryError)", "not a valid PLY file ('x')",
                    "bad data (-3)", "invalid file ()", "it failed (KeyError) while reading", "x\ny", "",
                    "bad \x00 byte", "not valid (<object at 0x7f>)", "x" * 401]:
        assert fuzz.message_problem(f"cannot read {path}: {problem}", path), problem
    assert fuzz.message_problem("cannot read the file: truncated", path) == "does not name the file"


def test_announced_points():
    header = b"ply\nformat ascii 1.0\nelement vertex 7\nproperty float x\nend_header\n"
    assert fuzz.announced_points("ply", header) == {7}
    assert fuzz.announced_points("off", b"OFF\n5 2 0\n") == {5}
    assert fuzz.announced_points("off", b"OFF 5 2 0\n") == {5}
    assert fuzz.announced_points("pts", b"12\n1 2 3\n") == {12}
    assert fuzz.announced_points("pts", b"1 2 3\n") is None
    assert fuzz.announced_points("text", b"1 2 3\n") is None


# ------------------------------------------------------------- accepted files compared attribute by attribute
def test_attribute_differences_name_every_changed_missing_and_new_attribute(tmp_path):
    files = fuzz.seed_files(tmp_path)
    cloud = read_points(files["las-1.4-fmt6"])
    original = fuzz.attribute_digests(cloud)
    assert {"points", "normals", "field intensity", "field mean"} <= set(original)
    assert fuzz.attribute_differences(original, dict(original)) == ""
    cloud.fields["intensity"] = cloud.fields["intensity"].copy()
    cloud.fields["intensity"][7] += 1
    cloud.fields["ExtraBytes"] = np.zeros(fuzz.N_SEED, np.uint8)
    cloud.normals = None
    assert fuzz.attribute_differences(original, fuzz.attribute_digests(cloud)) == (
        "attributes differ from the original: field intensity; missing: normals; new: field ExtraBytes")
    # same values in another dtype are another attribute
    cloud = read_points(files["las-1.4-fmt6"])
    cloud.points = cloud.points.astype(np.float32)
    assert fuzz.attribute_differences(original, fuzz.attribute_digests(cloud)) == (
        "attributes differ from the original: points")


def test_cross_check_catches_a_misread_point_format(tmp_path, monkeypatch):
    """Without the header checks, a changed point format reads the same coordinates and garbage attributes:
    the campaign's cross-check reports it although the point count agrees."""
    import struct

    from heatcurv.io import las
    from heatcurv.io.las_header import LasLayout

    seed = fuzz.seed_files(tmp_path)["las-1.4-fmt6"]
    data = seed.read_bytes()
    original = fuzz.attribute_digests(read_points(seed))
    path = tmp_path / "format1.las"
    path.write_bytes(data[:104] + bytes([1]) + data[105:])
    record_length = struct.unpack_from("<H", data, 105)[0]
    monkeypatch.setattr(las, "check_las_file", lambda p: LasLayout((1, 4), 1, record_length, fuzz.N_SEED, False))
    summary = fuzz.read_summary(path)
    assert summary["points"] == fuzz.N_SEED
    contradiction = fuzz._contradiction(fuzz.VARIANTS["las-1.4-fmt6"], path.read_bytes(), summary,
                                        "las-point-format", original)
    # the coordinates and the count agree; the normals and the field behind them are garbage
    assert contradiction == (
        "attributes differ from the original: normals, field mean; missing: field overlap, field scanner_channel, "
        "field scan_angle; new: field scan_angle_rank, field ExtraBytes_0, field ExtraBytes_1")
    # the same file through the reader as it is: refused
    monkeypatch.undo()
    with pytest.raises(HeatcurvError, match=r"the point record length \(46 bytes\) is not the 28 bytes of point "
                                            r"format 1 plus the 16 its ExtraBytes VLR describes \(44\)"):
        read_points(path)


def test_a_case_replays_from_the_repository_root_with_its_printed_command():
    import subprocess
    import sys
    from pathlib import Path

    case = fuzz.CaseResult("npy", "npy-header", 2457833082, "rejected", "", 0, 0.0, 0)
    assert case.reproduce == "PYTHONPATH=tests python -m support.fuzz npy npy-header 2457833082"
    root = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    command = case.reproduce.replace(" python ", f" {sys.executable} ", 1)  # the Python heatcurv is installed in
    out = subprocess.run(command, shell=True, cwd=root, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 1, out.stderr
    assert "npy-npy-header-2457833082.npy (" in out.stdout
    assert out.stderr.rstrip().splitlines()[-1].endswith(
        "not a valid NPY file (the header is not a Python dictionary literal)")
