"""LAS/LAZ files built to hurt: counts and sizes that contradict the file, truncations, flipped bytes.

Every mutated file is read in a child process limited to 2 GB of address space
(and a timeout), so that a regression that makes laspy/lazrs allocate without
bound or loop cannot kill or hang pytest: it shows as a CRASH or HANG outcome.
"""

import json
import math
import os
import random
import re
import struct
import subprocess
import sys

import laspy
import numpy as np
import pytest

from heatcurv import HeatcurvError
from heatcurv.io import read_points

N = 120
# (name, point format, version): the formats the fuzzing campaign used
VARIANTS = [
    ("f0_12", 0, "1.2"),
    ("f1_12", 1, "1.2"),
    ("f2_12", 2, "1.2"),
    ("f3_12", 3, "1.2"),
    ("f3_14", 3, "1.4"),
    ("f6_14", 6, "1.4"),
    ("f7_14", 7, "1.4"),
]

CHILD = r"""
import json, resource, sys, time
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
from heatcurv import HeatcurvError
from heatcurv.io import read_points
for line in sys.stdin:
    path = line.rstrip("\n")
    start = time.perf_counter()
    try:
        cloud = read_points(path)
        outcome = ["ok", cloud.points.shape[0], cloud.points.tolist()[:3]]
    except HeatcurvError as exc:
        outcome = ["error", str(exc), None]
    except BaseException as exc:
        outcome = ["OTHER", type(exc).__name__ + ": " + str(exc)[:300], None]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps([path, *outcome, time.perf_counter() - start, rss]), flush=True)
"""


def read_in_child(paths, timeout=120.0):
    """{path: (kind, value, first_points, seconds, peak_rss_kb)}; kind CRASH/HANG for the culprit."""
    env = dict(os.environ, RAYON_NUM_THREADS="2")
    results, todo = {}, list(paths)
    while todo:
        child = subprocess.Popen(
            [sys.executable, "-c", CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, env=env,
        )
        try:
            out, err = child.communicate("".join(f"{p}\n" for p in todo), timeout=timeout)
            failure = f"CRASH rc={child.returncode}: {err.strip()[-300:]}"
        except subprocess.TimeoutExpired:
            child.kill()
            out, err = child.communicate()
            failure = "HANG"
        for line in out.splitlines():
            path, *rest = json.loads(line)
            results[path] = tuple(rest)
        todo = [p for p in todo if p not in results]
        if todo:  # the first unanswered file killed or hung the child
            results[todo.pop(0)] = (failure.split(" ")[0], failure, None, None, None)
    return results


def build(path, fmt, version, n=N, extra=False, evlr=False, seed=0):
    rng = np.random.default_rng(seed)
    header = laspy.LasHeader(point_format=fmt, version=version)
    header.scales = np.array([0.001, 0.001, 0.01])
    header.offsets = np.array([512000.0, 5400000.0, 300.0])
    if extra:
        header.add_extra_dims(
            [laspy.ExtraBytesParams("a", "u1"), laspy.ExtraBytesParams("b", "f4")]
        )
    las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(n, header=header))
    las.x = 512000.0 + rng.random(n) * 50
    las.y = 5400000.0 + rng.random(n) * 50
    las.z = 300.0 + rng.random(n) * 5
    las.intensity = rng.integers(0, 4000, n)
    if extra:
        las.b = rng.random(n).astype(np.float32)
    if evlr:
        las.evlrs = laspy.vlrs.vlrlist.VLRList([laspy.VLR("heatcurv", 7, "test", b"x" * 40)])
    las.write(path)
    return las


def build_variable_chunks(path, valid_laz: bytes, splits=(50, 110)):
    """``valid_laz`` recompressed in chunks of variable size (as COPC files are): 50, 60, 10 points."""
    import io

    import lazrs

    lay = Layout(valid_laz)
    las = laspy.read(io.BytesIO(valid_laz))
    items = struct.unpack_from("<H", valid_laz, lay.laszip + 32)[0]
    head = bytearray(valid_laz[: lay.offset])
    struct.pack_into("<I", head, lay.laszip + 12, 0xFFFFFFFF)  # chunk size: variable
    vlr = lazrs.LazVlr(bytes(head[lay.laszip : lay.laszip + 34 + 6 * items]))
    out = io.BytesIO()
    out.write(bytes(head))
    compressor = lazrs.LasZipCompressor(out, vlr)
    raw = np.frombuffer(las.points.array.tobytes(), np.uint8)
    bounds = [0, *splits, len(las.points)]
    rl = lay.record_length
    compressor.compress_chunks([raw[a * rl : b * rl] for a, b in zip(bounds, bounds[1:])])
    compressor.done()
    path.write_bytes(out.getvalue())


class Layout:
    """Byte positions of the fields the mutations change."""

    def __init__(self, data: bytes):
        self.data = data
        self.header_size, self.offset, self.vlrs = struct.unpack_from("<HII", data, 94)
        self.record_length = struct.unpack_from("<H", data, 105)[0]
        self.minor = data[25]
        self.laszip = None  # position of the laszip VLR's data
        position = self.header_size
        for _ in range(self.vlrs):
            record_id, length = struct.unpack_from("<HH", data, position + 18)
            if data[position + 2 : position + 16] == b"laszip encoded":
                self.laszip = position + 54
            position += 54 + length
        if self.laszip is not None:
            self.table = struct.unpack_from("<q", data, self.offset)[0]

    def set(self, fmt, position, value) -> bytes:
        data = bytearray(self.data)
        struct.pack_into(fmt, data, position, value)
        return bytes(data)


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    """{name.ext: bytes}: small valid LAS and LAZ files of every variant."""
    directory = tmp_path_factory.mktemp("valid")
    out = {}
    for name, fmt, version in VARIANTS:
        for ext in ("las", "laz"):
            path = directory / f"{name}.{ext}"
            build(path, fmt, version)
            out[path.name] = path.read_bytes()
    path = directory / "evlr_14.las"
    build(path, 6, "1.4", evlr=True)
    out[path.name] = path.read_bytes()
    path = directory / "var_14.laz"
    build_variable_chunks(path, out["f7_14.laz"])
    out[path.name] = path.read_bytes()
    return out


def mutations(samples):
    """(file name, bytes, expected message regex or None for 'read as the original') each."""
    cases = []

    def add(name, data, pattern):
        cases.append((name, data, pattern))

    for source in ("f3_12.las", "f3_12.laz", "f7_14.las", "f7_14.laz"):
        lay = Layout(samples[source])
        stem, ext = source.split(".")
        add(f"{stem}_vlrs_ffffffff.{ext}", lay.set("<I", 100, 0xFFFFFFFF),
            r"the header announces 4294967295 VLRs, the \d+ bytes between the header and the "
            r"point data hold at most \d+")
        add(f"{stem}_vlrs_plus1.{ext}", lay.set("<I", 100, lay.vlrs + 1),
            r"VLR|hold at most")
        add(f"{stem}_offset_past_end.{ext}", lay.set("<I", 96, len(lay.data) + 1000),
            rf"truncated before the point data: it would start at byte {len(lay.data) + 1000}, "
            rf"the file has {len(lay.data)} bytes")
        add(f"{stem}_offset_in_header.{ext}", lay.set("<I", 96, 100),
            r"the point data would start at byte 100, inside the \d+-byte header")
        add(f"{stem}_header_size_small.{ext}", lay.set("<H", 94, 100),
            r"the header size field says 100 bytes, less than the \d+ of a LAS 1\.\d header")
        add(f"{stem}_record_0.{ext}", lay.set("<H", 105, 0),
            r"the point record length \(0 bytes\) is shorter than the \d+ bytes of point format")
        add(f"{stem}_format_35.{ext}", lay.set("<B", 104, 35 | (0x80 if ext == "laz" else 0)),
            r"unknown point format 35")
        add(f"{stem}_record_huge.{ext}", lay.set("<H", 105, 0xFFFF),
            r"the point record length \(65535 bytes\) is not the \d+ bytes of point format \d, and no "
            r"ExtraBytes VLR describes the rest")
        for k, axis in enumerate("XYZ"):
            add(f"{stem}_scale{axis}_0.{ext}", lay.set("<d", 131 + 8 * k, 0.0),
                rf"the {axis} scale factor is 0: every {axis} coordinate would be 0")
        for value, word in ((math.nan, "nan"), (math.inf, "inf"), (-math.inf, "-inf")):
            add(f"{stem}_scaleY_{word}.{ext}", lay.set("<d", 139, value),
                rf"the Y scale factor is {word}, not a finite number")
            add(f"{stem}_offsetZ_{word}.{ext}", lay.set("<d", 171, value),
                rf"the Z offset is {word}, not a finite number")
        # the points mirrored about the offset: outside the header's box (a mirrored file's box mirrors too)
        add(f"{stem}_scaleX_negative.{ext}", lay.set("<d", 131, -0.001),
            r"point record 1 of 120 lies outside the header's bounding box: its X \(5119\d\d\.\d+\) is "
            r"[\d.]+ below the box's X minimum \(5120\d\d\.\d+\), more than one scale step \(0\.001\); "
            r"120 of the 120 points are outside")
        # point counts
        count_at = 247 if lay.minor >= 4 else 107
        count_fmt = "<Q" if lay.minor >= 4 else "<I"
        for huge in (N + 1, 0xFFFFFFFF, 2**40 if lay.minor >= 4 else 2**31):
            data = lay.set(count_fmt, count_at, huge)
            if lay.minor >= 4 and struct.unpack_from("<I", data, 107)[0]:
                data = Layout(data).set("<I", 107, 0)  # keep the legacy count out of the way
            if ext == "las":
                pattern = (
                    rf"truncated: the header announces {huge} points of \d+ bytes, "
                    rf"the file holds room for {N}"
                )
            elif huge == N + 1:
                pattern = r"truncated: the header announces 121 points|chunk|compressed"
            else:
                pattern = (
                    rf"the header announces {huge} points, far more than the \d+ bytes of "
                    r"compressed points can hold"
                )
            add(f"{stem}_count_{huge}.{ext}", data, pattern)
        if lay.minor >= 4 and source.startswith("f3"):  # format 3 in 1.4 keeps a legacy count
            add(f"{stem}_legacy_disagrees.{ext}", lay.set("<I", 107, N - 1),
                r"the legacy point count \(119\) and the 64-bit point count \(120\) of the "
                r"LAS 1\.4 header disagree")
        # truncations: in the header, the VLRs, the points (and the chunk table)
        cuts = {"header": 200, "vlrs": lay.header_size + 30, "points": lay.offset + 40}
        if ext == "las":
            cuts["last_record"] = len(lay.data) - 7
        else:
            cuts["chunk_table"] = len(lay.data) - 3
            cuts["compressed"] = (lay.offset + lay.table) // 2
        expected = {
            "header": r"truncated inside the header",
            "vlrs": r"truncated before the point data" if lay.offset > cuts["vlrs"]
            else r"truncated: the header announces 120 points of \d+ bytes, the file holds room "
            r"for 0$",
            "points": (r"truncated: the header announces 120 points of \d+ bytes, the file holds "
                       r"room for 1$") if ext == "las" else r"truncated: the chunk table",
            "last_record": r"truncated: the header announces 120 points of \d+ bytes, the file "
                           r"holds room for 119$",
            "chunk_table": r"the chunk table is corrupt or truncated \(lazrs: ",
            "compressed": r"truncated: the chunk table of the compressed points would start at "
                          rf"byte {lay.laszip and lay.table}",
        }
        for where, size in cuts.items():
            add(f"{stem}_cut_{where}.{ext}", lay.data[:size], expected[where])

    for source in ("f3_12.laz", "f7_14.laz"):
        lay = Layout(samples[source])
        stem = source.split(".")[0]
        number_of_chunks = lay.table + 4
        for chunks in (0xFFFFFFFF, 0x7FFFFFFF, 1000, 2):
            add(f"{stem}_chunks_{chunks}.laz", lay.set("<I", number_of_chunks, chunks),
                rf"the chunk table lists {chunks} chunks, ")
        add(f"{stem}_chunks_0.laz", lay.set("<I", number_of_chunks, 0),
            r"the chunk table lists no chunks for 120 points")
        add(f"{stem}_table_past_end.laz", lay.set("<q", lay.offset, 10**12),
            r"truncated: the chunk table of the compressed points would start at byte "
            r"1000000000000")
        # a streaming writer stores the chunk table's offset after the table, at the end
        streamed = lay.set("<q", lay.offset, -1)
        add(f"{stem}_table_at_end.laz", streamed + struct.pack("<q", lay.table), None)
        add(f"{stem}_table_streaming.laz", streamed + struct.pack("<q", -1),
            r"the LAZ file has no chunk table")
        add(f"{stem}_table_in_vlrs.laz",
            Layout(lay.set("<q", lay.offset, lay.offset + 4)).data,
            r"the chunk table of the compressed points would start at byte \d+, outside the "
            r"point data")
        add(f"{stem}_laszip_missing.laz", lay.set("<H", lay.laszip - 54 + 18, 1),
            r"the point format says compressed \(LAZ\), but the laszip VLR that describes the "
            r"compression is missing")
        add(f"{stem}_compressor_1.laz", lay.set("<H", lay.laszip, 1),
            r"old point-wise LAZ compression \(laszip compressor 1\)")
        add(f"{stem}_chunk_size_0.laz", lay.set("<I", lay.laszip + 12, 0),
            r"the laszip VLR's chunk size is 0")
        add(f"{stem}_chunk_size_10.laz", lay.set("<I", lay.laszip + 12, 10),
            r"the chunk table lists 1 chunks, 120 points in chunks of 10 need 12")
        add(f"{stem}_chunk_size_variable.laz", lay.set("<I", lay.laszip + 12, 0xFFFFFFFF),
            r"chunk|compressed")
        # a legal but huge fixed chunk size: the parallel decoder would allocate 2**31 points
        add(f"{stem}_chunk_size_huge.laz", lay.set("<I", lay.laszip + 12, 0x7FFFFFFF), None)
    # variable-size chunks: the chunk table stores the point count of every chunk
    lay = Layout(samples["var_14.laz"])
    add("var_14_count_121.laz", lay.set("<Q", 247, N + 1),
        r"the chunk table counts 120 points, the header 121")
    add("var_14_count_huge.laz", lay.set("<Q", 247, 2**40), r"far more than the \d+ bytes")
    add("var_14_chunks_ffffffff.laz", lay.set("<I", lay.table + 4, 0xFFFFFFFF),
        r"the chunk table lists 4294967295 chunks, the \d+ bytes of compressed points hold at "
        r"most \d+")
    add("var_14_chunks_100.laz", lay.set("<I", lay.table + 4, 100),
        r"the chunk table lists 100 chunks for only 120 points|hold at most")
    # without lazrs's trailing empty chunk: still a valid file
    add("var_14_chunks_3.laz", lay.set("<I", lay.table + 4, 3), None)
    # layered chunks (LAS 1.4 formats 6-10): the raw first point, the count, the layer sizes
    lay = Layout(samples["f7_14.laz"])
    chunk = lay.offset + 8
    sizes = chunk + lay.record_length + 4
    add("f7_14_layer_huge.laz", lay.set("<I", sizes, 0xFFFFFFF0),
        r"chunk 1 of 1 of the compressed points announces layers of \d+ bytes in \d+ bytes")
    add("f7_14_layer_gps_huge.laz", lay.set("<I", sizes + 4 * 8, 0x7FFFFFFF),
        r"announces layers of")
    add("f7_14_chunk_count.laz", lay.set("<I", chunk + lay.record_length, 0xFFFFFFFF),
        r"chunk 1 of 1 of the compressed points says it holds 4294967295 points, the chunk "
        r"table and header give 120")
    # extended VLRs (LAS 1.4)
    lay = Layout(samples["evlr_14.las"])
    start = struct.unpack_from("<Q", lay.data, 235)[0]
    add("evlr_count_ffffffff.las", lay.set("<I", 243, 0xFFFFFFFF),
        r"the header announces 4294967295 extended VLRs, the \d+ bytes from byte \d+ to the end "
        r"of the file hold at most 1")
    add("evlr_start_past_end.las", lay.set("<Q", 235, 2**40),
        r"truncated: the extended VLRs would start at byte 1099511627776")
    add("evlr_start_in_header.las", lay.set("<Q", 235, 10),
        r"the extended VLRs would start at byte 10, before the point data")
    add("evlr_length_huge.las", lay.set("<Q", start + 20, 2**62),
        r"extended VLR 1 of 1 \('heatcurv', record 7\) announces 4611686018427387904 bytes of "
        r"data, running past the end of the file")
    add("evlr_cut.las", lay.data[: start + 30],
        r"the header announces 1 extended VLRs, the 30 bytes from byte \d+ to the end of the "
        r"file hold at most 0")
    return cases


@pytest.fixture(scope="module")
def outcomes(samples, tmp_path_factory):
    directory = tmp_path_factory.mktemp("hostile")
    cases = mutations(samples)
    names = [name for name, _data, _pattern in cases]
    assert len(names) == len(set(names))
    paths = []
    for name, data, _pattern in cases:
        (directory / name).write_bytes(data)
        paths.append(str(directory / name))
    results = read_in_child(paths)
    return {name: (results[path], pattern, path) for (name, _d, pattern), path in zip(cases, paths)}


def _assert_one_line_error(outcome, path, pattern):
    kind, message = outcome[0], outcome[1]
    assert kind == "error", f"{path}: {kind} {message}"
    assert "\n" not in message
    assert message.startswith(f"cannot read {path}: "), message
    problem = message[len(f"cannot read {path}: "):]
    assert re.search(pattern, problem), f"{problem!r} does not match {pattern!r}"
    for opaque in ("(MemoryError)", "(35)", "Errno", "buffer size must be", "Traceback"):
        assert opaque not in problem
    return problem


def test_targeted_mutations(outcomes, samples, tmp_path):
    """Each targeted mutation: one HeatcurvError line naming the file and saying what is wrong."""
    failures = []
    for name, (outcome, pattern, path) in outcomes.items():
        try:
            if pattern is None:  # legal: reads as the original
                source = re.sub(r"_(chunk_size_huge|table_at_end|chunks_3)", "", name)
                original = tmp_path / source
                original.write_bytes(samples[source])
                assert outcome[0] == "ok" and outcome[1] == N, outcome
                np.testing.assert_array_equal(outcome[2], read_points(original).points[:3])
            else:
                _assert_one_line_error(outcome, path, pattern)
            assert outcome[3] < 10, f"{outcome[3]:.1f} s"
        except AssertionError as exc:
            failures.append(f"{name}: {exc}")
    assert not failures, "\n".join(failures)
    rss = max(outcome[4] or 0 for outcome, _p, _path in outcomes.values())
    assert rss < 1 << 20, f"peak memory of the child {rss} kB"  # the 2 GB limit was far away


def test_truncations_everywhere(samples, tmp_path):
    """Every cut of a small LAS and LAZ (header, VLRs, points, chunk table): one clean error."""
    cut_paths = []
    for source in ("f0_12.laz", "f6_14.laz", "f1_12.las", "f7_14.las"):
        data = samples[source]
        lay = Layout(data)
        ends = set(range(1, lay.offset + 16)) | set(range(lay.offset + 16, len(data), 7))
        ends |= set(range(len(data) - 12, len(data)))
        for end in sorted(ends):
            path = tmp_path / f"cut{end}_{source}"
            path.write_bytes(data[:end])
            cut_paths.append(str(path))
    results = read_in_child(cut_paths)
    for path in cut_paths:
        _assert_one_line_error(results[path], path, r".")


@pytest.mark.parametrize("source", ["f3_12.laz", "f7_14.laz", "var_14.laz"])
def test_flipped_bytes_of_a_small_laz(samples, tmp_path, source):
    """Every byte of a small LAZ inverted, and a seeded sample of other values: no crash, no hang.

    Flips inside the compressed points may still decode (LAZ has no checksum):
    those give 120 points of garbage; anything else is one HeatcurvError line.
    """
    data = samples[source]
    rng = random.Random(11)
    changes = [(k, data[k] ^ 0xFF) for k in range(len(data))]
    changes += [(rng.randrange(len(data)), rng.choice([0, 1, 0x80, 0xFF, rng.randrange(256)]))
                for _ in range(300)]
    paths = []
    for k, (position, value) in enumerate(changes):
        mutated = bytearray(data)
        mutated[position] = value
        path = tmp_path / f"flip{k}_{position}_{value}.laz"
        path.write_bytes(bytes(mutated))
        paths.append(str(path))
    results = read_in_child(paths)
    bad = []
    for path in paths:
        outcome = results[path]
        if outcome[0] == "ok":
            if outcome[1] != N:
                bad.append(f"{path}: {outcome[1]} points")
            continue
        try:
            problem = _assert_one_line_error(outcome, path, r".")
            assert "not enough memory" not in problem
            assert outcome[3] < 10
        except AssertionError as exc:
            bad.append(f"{path}: {exc}")
    assert not bad, "\n".join(bad[:20])


@pytest.mark.parametrize("name", [f"{v[0]}.{ext}" for v in VARIANTS for ext in ("las", "laz")])
def test_valid_files_read_as_laspy_reads_them(samples, tmp_path, name):
    path = tmp_path / name
    path.write_bytes(samples[name])
    cloud = read_points(path)
    las = laspy.read(path)
    np.testing.assert_array_equal(cloud.points, np.column_stack([las.x, las.y, las.z]))
    np.testing.assert_array_equal(cloud.fields["intensity"], las.intensity)


def test_valid_multi_chunk_laz_with_extra_bytes(tmp_path):
    """Several chunks, extra bytes, RGB/NIR and wave packets: the chunk checks accept real files."""
    for fmt, version in ((3, "1.2"), (8, "1.4"), (10, "1.4")):
        path = tmp_path / f"multi{fmt}.laz"
        las = build(path, fmt, version, n=110_000, extra=True)
        cloud = read_points(path)
        assert cloud.points.shape == (110_000, 3)
        np.testing.assert_array_equal(cloud.points[:, 2], las.z)
        np.testing.assert_array_equal(cloud.fields["b"], las.b)


def test_variable_size_chunks_read(samples, tmp_path):
    """Variable-size chunks (COPC, lazrs with a trailing empty chunk): read like the fixed ones."""
    (tmp_path / "var_14.laz").write_bytes(samples["var_14.laz"])
    (tmp_path / "f7_14.laz").write_bytes(samples["f7_14.laz"])
    back = read_points(tmp_path / "var_14.laz")
    np.testing.assert_array_equal(back.points, read_points(tmp_path / "f7_14.laz").points)


def test_more_points_than_memory(samples, tmp_path, monkeypatch):
    from heatcurv.io import las_header

    monkeypatch.setattr(las_header, "_physical_memory", lambda: 4000)
    (tmp_path / "f7_14.laz").write_bytes(samples["f7_14.laz"])
    with pytest.raises(
        HeatcurvError,
        match=r"f7_14\.laz: the header announces 120 points of 36 bytes \(4\.32 kB decompressed\), "
        r"more than the 4 kB of memory of this machine",
    ):
        read_points(tmp_path / "f7_14.laz")


def test_evlr_file_reads(samples, tmp_path):
    path = tmp_path / "evlr_14.las"
    path.write_bytes(samples["evlr_14.las"])
    cloud = read_points(path)
    assert cloud.points.shape == (N, 3)
    assert cloud.meta["las_header"].evlrs[0].record_data == b"x" * 40


def test_in_process_error_type(samples, tmp_path):
    """The same checks raise HeatcurvError in the calling process (no child) for a safe mutation."""
    lay = Layout(samples["f3_12.las"])
    path = tmp_path / "zero.las"
    path.write_bytes(lay.set("<d", 147, 0.0))
    with pytest.raises(HeatcurvError, match=r"zero\.las: the Z scale factor is 0"):
        read_points(path)


# ------------------------------------------- files written by heatcurv, altered in one way
def heatcurv_file(directory, ext):
    """120 points in the box 8-12 with normals (extra bytes), colours and a field, written by write_points."""
    from heatcurv.io import write_points

    rng = np.random.default_rng(3)
    points = 8 + 4 * rng.random((N, 3))
    normals = rng.normal(size=(N, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    path = directory / f"heatcurv.{ext}"
    write_points(path, points, {"mean": rng.random(N)}, normals=normals,
                 colours=rng.integers(0, 256, (N, 3)))
    return path


def _insert(data, at, extra):
    return data[:at] + extra + data[at:]


def _altered(data, kind):
    """``data`` (a heatcurv LAS/LAZ: format 7, 16 bytes of extra dimensions) altered in one way."""
    lay = Layout(data)
    inside = lay.offset + 5 * lay.record_length + 3  # in record 6 (LAS); in the first chunk (LAZ)
    return {
        "insert_1": lambda: _insert(data, inside, b"\x00"),
        "insert_6": lambda: _insert(data, inside, b"\x07" * 6),
        "appended_5": lambda: data + b"\x00" * 5,
        "appended_40": lambda: data + b"\x01" * 40,
        # one byte in, the last one out: the size fits, records 6 on are read one byte late
        "shifted": lambda: _insert(data, inside, b"\x00")[:-1],
        "count_1": lambda: lay.set("<Q", 247, 1),
        "count_119": lambda: lay.set("<Q", 247, N - 1),
        "scaleY_1e-300": lambda: lay.set("<d", 139, 1e-300),
        "scaleY_5e-324": lambda: lay.set("<d", 139, 5e-324),
        "scaleZ_1e300": lambda: lay.set("<d", 147, 1e300),
        **{f"format_{f}": (lambda f=f: lay.set("<B", 104, f | (data[104] & 0xC0))) for f in (0, 1, 2, 3, 6)},
        "vlr_count_0": lambda: lay.set("<I", 100, 0),
        "vlr_count_less": lambda: lay.set("<I", 100, lay.vlrs - 1),
        "box_x_max_10": lambda: lay.set("<d", 179, 10.0),
        "box_y_max_nan": lambda: lay.set("<d", 195, math.nan),
        "box_x_min_13": lambda: lay.set("<d", 187, 13.0),
    }[kind]()


_SIZES = (r"the point data holds \d+ bytes, {extra} more than the {count} points of 52 bytes the header "
          r"announces \({why}\): the point count, the record length or the offset to the points is wrong, "
          r"or bytes were inserted$")
_BOX = (r"point record {record} of 120 lies outside the header's bounding box: its {axis} \([\d.]+\) is [\d.]+ "
        r"{side} the box's {axis} {word} \({bound}\), more than one scale step \(1e-06\); {many} of the 120 "
        r"points are outside: the records are misaligned, or the header does not describe these points$")
_FORMAT = (r"the point record length \(52 bytes\) is not the {size} bytes of point format {f} plus the 16 its "
           r"ExtraBytes VLR describes \({total}\)$")
_COMMON = {
    "scaleY_1e-300": r"the Y scale factor 1e-300 is finer than double precision resolves at the coordinates' "
                     r"magnitude \(1[01]\.\d\): every Y would collapse onto a few values around the offset$",
    "scaleY_5e-324": r"the Y scale factor 4\.94e-324 is finer than double precision resolves",
    "scaleZ_1e300": r"the Z scale factor 1e\+300 is so large that a record's Z can be beyond the range of "
                    r"double precision$",
    **{f"format_{f}": _FORMAT.format(size=size, f=f, total=size + 16)
       for f, size in ((0, 20), (1, 28), (2, 26), (3, 34), (6, 30))},
    "box_x_max_10": _BOX.format(record=r"\d+", axis="X", side="above", word="maximum", bound="10", many=r"\d+"),
    "box_y_max_nan": r"the header's bounding box is not finite \(Y from [\d.]+ to nan\)$",
    "box_x_min_13": r"the header's bounding box has an X minimum \(13\) above its maximum \([\d.]+\)$",
}
EXPECTED = {
    "las": {
        **_COMMON,
        "insert_1": _SIZES.format(extra=1, count=120, why="not a whole number of records"),
        "insert_6": _SIZES.format(extra=6, count=120, why="not a whole number of records"),
        "appended_5": _SIZES.format(extra=5, count=120, why="not a whole number of records"),
        "appended_40": _SIZES.format(extra=40, count=120, why="not a whole number of records"),
        "shifted": _BOX.format(record=6, axis=r"[XYZ]", side=r"(above|below)", word=r"(maximum|minimum)",
                               bound=r"[\d.]+", many=r"\d+"),
        "count_1": _SIZES.format(extra=119 * 52, count=1, why="room for 119 more"),
        "count_119": _SIZES.format(extra=52, count=119, why="room for 1 more"),
        "vlr_count_0": r"the header counts 0 VLRs, but the 822 bytes after the header, before the points, hold "
                       r"1 more VLR \('LASF_Spec' record 4\): the VLR count is wrong$",
    },
    "laz": {
        **_COMMON,
        "insert_1": r"the chunk table lists 256 chunks, the 4053 bytes of compressed points hold at most 78",
        "insert_6": r"the chunk table lists no chunks for 120 points$",
        "shifted": r"the chunk table lists 256 chunks, the 4053 bytes of compressed points hold at most 78",
        # liblas leaves 32 bytes after the chunk table: up to that, accepted (test below)
        "appended_40": r"the 40 bytes between the chunk table and the end of the file are unexplained \(a LAZ "
                       r"writer leaves at most 32\)$",
        "count_1": r"chunk 1 of 1 of the compressed points says it holds 120 points, the chunk table and header "
                   r"give 1$",
        "count_119": r"chunk 1 of 1 of the compressed points says it holds 120 points, the chunk table and "
                     r"header give 119$",
        "vlr_count_0": r"the header counts 0 VLRs, but the 928 bytes after the header, before the points, hold "
                       r"2 more VLRs \('LASF_Spec' record 4, 'laszip encoded' record 22204\): the VLR count is "
                       r"wrong$",
        "vlr_count_less": r"the header counts 1 VLR, but the 106 bytes after them, before the points, hold 1 "
                          r"more VLR \('laszip encoded' record 22204\): the VLR count is wrong$",
    },
}


@pytest.mark.parametrize("ext,kind", [(ext, kind) for ext in EXPECTED for kind in EXPECTED[ext]])
def test_heatcurv_file_altered_in_one_way(tmp_path, ext, kind):
    """Each alteration of a file heatcurv wrote: one error saying what does not add up."""
    data = heatcurv_file(tmp_path, ext).read_bytes()
    path = tmp_path / f"{kind}.{ext}"
    path.write_bytes(_altered(data, kind))
    with pytest.raises(HeatcurvError) as caught:
        read_points(path)
    message = str(caught.value)
    assert message.startswith(f"cannot read {path}: "), message
    problem = message[len(f"cannot read {path}: "):]
    assert re.search(EXPECTED[ext][kind], problem), f"{problem!r} does not match {EXPECTED[ext][kind]!r}"


def test_bytes_after_a_laz_chunk_table_up_to_what_liblas_leaves(tmp_path):
    """liblas writes 32 bytes after the chunk table: accepted; the points read as without them."""
    path = heatcurv_file(tmp_path, "laz")
    data = path.read_bytes()
    expected = read_points(path).points
    path.write_bytes(data + b"\x01" * 32)
    np.testing.assert_array_equal(read_points(path).points, expected)
    path.write_bytes(data + b"\x01" * 33)
    with pytest.raises(HeatcurvError, match=r"the 33 bytes between the chunk table and the end of the file"):
        read_points(path)


def test_heatcurv_file_layout_the_expectations_assume(tmp_path):
    """The messages above quote this layout: LAS 1.4 format 7, 36 + 16 bytes a record, its VLRs."""
    for ext, vlrs, offset in (("las", 1, 1197), ("laz", 2, 1303)):
        lay = Layout(heatcurv_file(tmp_path, ext).read_bytes())
        assert (lay.minor, lay.data[104] & 0x3F, lay.record_length, lay.vlrs, lay.offset) == (4, 7, 52, vlrs, offset)


def test_mirrored_axis_with_its_own_box_reads(tmp_path):
    """A negative scale is legal LAS: the points mirrored about the offset, the box with them."""
    path = tmp_path / "mirrored.las"
    las = build(path, 3, "1.2")
    lay = Layout(path.read_bytes())
    mirrored = lay.set("<d", 131, -0.001)
    high, low = struct.unpack_from("<2d", mirrored, 179)
    mirrored = Layout(Layout(mirrored).set("<d", 179, 2 * 512000.0 - low)).set("<d", 187, 2 * 512000.0 - high)
    path.write_bytes(mirrored)
    # 1e-9: a few units in the last place of coordinates near 5e5 (spacing 1.2e-10)
    np.testing.assert_allclose(read_points(path).points[:, 0], 2 * 512000.0 - np.asarray(las.x), rtol=0, atol=1e-9)


def test_box_of_the_unscaled_integers_reads(tmp_path):
    """Some writers (ALSXX_PP) store the record integers' box, unscaled: accepted, the points as stored."""
    path = tmp_path / "unscaled.las"
    las = build(path, 3, "1.2")
    data = path.read_bytes()
    integers = (las.X, las.Y, las.Z)
    box = [float(f(v)) for v in integers for f in (np.max, np.min)]
    path.write_bytes(data[:179] + struct.pack("<6d", *box) + data[227:])
    np.testing.assert_array_equal(read_points(path).points[:, 2], las.z)
    # the same box one unit too small is not the integers' box: refused
    box[0] -= 2
    path.write_bytes(data[:179] + struct.pack("<6d", *box) + data[227:])
    with pytest.raises(HeatcurvError, match=r"lies outside the header's bounding box: its X"):
        read_points(path)


def test_laszip_items_of_another_point_format(tmp_path):
    """The laszip VLR says RGBNIR14 where the header's format 7 has RGB14 (same sizes): refused."""
    data = heatcurv_file(tmp_path, "laz").read_bytes()
    lay = Layout(data)
    second_item = lay.laszip + 34 + 6
    assert struct.unpack_from("<HH", data, second_item) == (11, 6)
    path = tmp_path / "items.laz"
    path.write_bytes(lay.set("<H", second_item, 12))
    with pytest.raises(HeatcurvError, match=r"the laszip VLR compresses POINT14 RGBNIR14 items, point format 7 is "
                                            r"POINT14 RGB14: the header's point format is not the compressed one$"):
        read_points(path)


def test_waveform_record_of_las_13_is_accounted_for(tmp_path):
    """LAS 1.3 keeps its waveform data packets after the points: not unexplained bytes, but bytes after it are."""
    path = tmp_path / "wave.las"
    build(path, 1, "1.3")
    data = bytearray(path.read_bytes())
    struct.pack_into("<Q", data, 227, len(data))
    record = struct.pack("<H16sHQ32s", 0, b"LASF_Spec", 65535, 100, b"waveforms") + b"w" * 100
    path.write_bytes(bytes(data) + record)
    assert read_points(path).points.shape == (N, 3)
    path.write_bytes(bytes(data) + record + b"\x00" * 3)
    with pytest.raises(HeatcurvError, match=r"the 3 bytes after the last extended VLR \(from byte \d+ to the end "
                                            r"of the file\) are unexplained$"):
        read_points(path)


def test_undescribed_extra_bytes_are_refused(tmp_path):
    """Record bytes beyond the point format that no ExtraBytes VLR describes: refused, not read as garbage."""
    path = tmp_path / "undescribed.las"
    build(path, 6, "1.4")
    data = path.read_bytes()
    lay = Layout(data)
    head = bytearray(data[: lay.offset])
    struct.pack_into("<H", head, 105, 34)
    records = np.frombuffer(data[lay.offset:], np.uint8).reshape(N, 30)
    padded = np.hstack([records, np.zeros((N, 4), np.uint8)])
    path.write_bytes(bytes(head) + padded.tobytes())
    with pytest.raises(HeatcurvError, match=r"the point record length \(34 bytes\) is not the 30 bytes of point "
                                            r"format 6, and no ExtraBytes VLR describes the rest$"):
        read_points(path)
