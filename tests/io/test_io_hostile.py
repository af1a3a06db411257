"""Untrusted files (issue 11): counts the file cannot hold, bombs, self-contradicting sizes, encodings.

Every rejection must be one line ``cannot read PATH: <problem>``. Files whose counts
announce more memory than the machine has (bombs, huge counts) and the random byte
mutations are read in a child process under a 2 GB address-space limit and a timeout,
so that a regression fails these tests instead of taking pytest down.
"""

import io
import json
import os
import re
import struct
import subprocess
import sys
import textwrap
import zipfile
import zlib

import numpy as np
import plyfile
import pytest

from heatcurv import HeatcurvError
from heatcurv.io import read_points, write_points

N = 120
GB = 1 << 30

# ----------------------------------------------------------------------------- helpers


def _points(n=N):
    return np.random.default_rng(11).random((n, 3)) * 10.0


def _colours(n=N):
    return np.random.default_rng(12).integers(0, 256, (n, 3)).astype(np.uint8)


def _binary_ply(tmp_path, name="v.ply"):
    """A heatcurv PLY: x y z double, red green blue uchar: 27 bytes a vertex."""
    path = tmp_path / name
    write_points(path, _points(), colours=_colours())
    return path


def _header_end(data: bytes) -> int:
    return data.index(b"end_header\n") + len(b"end_header\n")


def _refused(path, pattern=None):
    """Read ``path``; it must be refused with one line naming it (and matching ``pattern``)."""
    with pytest.raises(HeatcurvError) as info:
        read_points(path)
    message = str(info.value)
    assert "\n" not in message, message
    assert message.startswith(f"cannot read {path}: "), message
    if pattern is not None:
        problem = message[len(f"cannot read {path}: "):]
        assert re.search(pattern, problem), problem
    return message


def _read_isolated(paths, limit=2 * GB, timeout=120, per_file=20):
    """Read files in a child process under an address-space limit: {path: ("ok", n) | ("error", msg) | ...}."""
    script = textwrap.dedent(
        f"""
        import json, resource, signal, sys, traceback
        resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit}))
        from heatcurv.errors import HeatcurvError
        from heatcurv.io import read_points

        def alarm(*_):
            raise TimeoutError("took more than {per_file} s")

        signal.signal(signal.SIGALRM, alarm)
        for line in sys.stdin:
            path = line.rstrip("\\n")
            signal.alarm({per_file})
            try:
                result = ["ok", len(read_points(path))]
            except HeatcurvError as exc:
                result = ["error", str(exc)]
            except BaseException as exc:
                result = ["bug", type(exc).__name__ + ": " + traceback.format_exc()[-800:]]
            signal.alarm(0)
            print(json.dumps([path, *result]), flush=True)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        input="".join(f"{p}\n" for p in paths),
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    results = {}
    for line in done.stdout.splitlines():
        path, kind, value = json.loads(line)
        results[path] = (kind, value)
    missing = [str(p) for p in paths if str(p) not in results]
    assert not missing, f"the child stopped (rc {done.returncode}) before {missing[:3]}: {done.stderr[-2000:]}"
    return results


def _assert_refused(results, path, pattern):
    kind, message = results[str(path)]
    assert kind == "error", (path, kind, message)
    assert "\n" not in message and message.startswith(f"cannot read {path}: "), message
    assert re.search(pattern, message), message


def _npy_header(shape, descr="<f8") -> bytes:
    stream = io.BytesIO()
    np.lib.format.write_array_header_1_0(stream, {"descr": descr, "fortran_order": False, "shape": shape})
    return stream.getvalue()


def _zip(path, members, aliases=0):
    """Write a zip by hand: ``members`` are ``(name, stored_bytes, method, crc, declared_size)``.

    ``aliases`` more central-directory entries point at the first member's data (an
    overlapping zip bomb).
    """
    out, central = bytearray(), bytearray()
    entries = []
    for name, data, method, crc, size in members:
        entries.append((name.encode(), len(out), method, crc, len(data), size))
        out += struct.pack("<4s5H3L2H", b"PK\x03\x04", 20, 0, method, 0, 0, crc, len(data), size,
                           len(name.encode()), 0) + name.encode() + data
    first = entries[0]
    entries += [(f"alias{k}.npy".encode(), *first[1:]) for k in range(aliases)]
    for name, offset, method, crc, csize, size in entries:
        central += struct.pack("<4s6H3L5H2L", b"PK\x01\x02", 20, 20, 0, method, 0, 0, crc, csize, size,
                               len(name), 0, 0, 0, 0, 0, offset) + name
    eocd = struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, len(entries), len(entries), len(central), len(out), 0)
    path.write_bytes(bytes(out + central + eocd))
    return path


def _zeros_deflate(header: bytes, megabytes: int):
    """A genuine raw-deflate stream of ``header`` and ``megabytes`` MiB of zeros, made in milliseconds.

    Returns ``(compressed, crc, size)``: the zeros are compressed once per MiB with a full
    flush, whose output repeats.
    """
    block = bytes(1 << 20)
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    start = compressor.compress(header) + compressor.flush(zlib.Z_FULL_FLUSH)
    chunk = compressor.compress(block) + compressor.flush(zlib.Z_FULL_FLUSH)
    again = compressor.compress(block) + compressor.flush(zlib.Z_FULL_FLUSH)
    assert chunk == again
    end = compressor.flush()
    crc = zlib.crc32(header)
    for _ in range(megabytes):
        crc = zlib.crc32(block, crc)
    return start + chunk * megabytes + end, crc, len(header) + megabytes * (1 << 20)


# ----------------------------------------------------------------------------- PLY


def test_binary_ply_size_must_match_the_header(tmp_path):
    path = _binary_ply(tmp_path)
    data = path.read_bytes()
    body = len(data) - _header_end(data)
    assert body == N * 27 and read_points(path).points.shape == (N, 3)
    for extra in (1, 7, 1000):
        (tmp_path / "long.ply").write_bytes(data + b"\0" * extra)
        _refused(
            tmp_path / "long.ply",
            rf"^the header announces 120 vertices of 27 bytes \(3240 bytes\) after the header, "
            rf"the file holds {3240 + extra}$",
        )
    (tmp_path / "short.ply").write_bytes(data[:-40])
    _refused(tmp_path / "short.ply", r"^the header announces 120 vertices of 27 bytes \(3240 bytes\) after the "
             r"header, the file holds 3200$")
    # a changed property type changes the record size
    (tmp_path / "type.ply").write_bytes(data.replace(b"property uchar red", b"property short red"))
    _refused(tmp_path / "type.ply", r"120 vertices of 28 bytes \(3360 bytes\) after the header, the file holds 3240")
    (tmp_path / "one.ply").write_bytes(data.replace(b"element vertex 120", b"element vertex 1"))
    _refused(tmp_path / "one.ply", r"^the header announces 1 vertex of 27 bytes \(27 bytes\)")
    (tmp_path / "neg.ply").write_bytes(data.replace(b"element vertex 120", b"element vertex -5"))
    _refused(tmp_path / "neg.ply", r"element 'vertex' has a negative count \(-5\)")


def test_ply_with_lists_lower_bound_and_trailing_bytes(tmp_path):
    vertex = np.zeros(4, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    faces = np.empty(2, dtype=[("vertex_indices", "O")])
    faces["vertex_indices"] = [np.array([0, 1, 2, 3], "i4"), np.array([1, 2, 3], "i4")]
    path = tmp_path / "quads.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex"), plyfile.PlyElement.describe(faces, "face")],
                    byte_order="<").write(str(path))
    data = path.read_bytes()
    assert read_points(path).meta["faces"] == 2
    (tmp_path / "tail.ply").write_bytes(data + b"junk")
    _refused(tmp_path / "tail.ply",
             rf"^trailing bytes after the last element: the elements end at byte {len(data)}, "
             rf"the file holds {len(data) + 4}$")
    (tmp_path / "many.ply").write_bytes(data.replace(b"element face 2", b"element face 1000"))
    _refused(tmp_path / "many.ply", r"^the header announces 4 vertices of 12 bytes and 1000 faces of at least 1 bytes "
             r"\(at least 1048 bytes\) after the header, the file holds \d+$")


def test_ply_header_problems_in_plain_words(tmp_path):
    data = _binary_ply(tmp_path).read_bytes()
    (tmp_path / "latin.ply").write_bytes(data.replace(b"written by heatcurv", b"\xe9crit par heatcurv"))
    _refused(tmp_path / "latin.ply", r"^not a valid PLY file \(header line 3 holds the non-ASCII byte 0xe9\)$")
    (tmp_path / "noend.ply").write_bytes(data.replace(b"end_header", b"end_headr"))
    _refused(tmp_path / "noend.ply", r"^not a valid PLY file \(the header has no 'end_header' line\)$")
    (tmp_path / "big.ply").write_bytes(b"ply\nformat ascii 1.0\ncomment " + b"a" * (2 << 20) + b"\n")
    _refused(tmp_path / "big.ply", r"no 'end_header' line in its first 1024 KiB")
    ascii_path = tmp_path / "a.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(np.ones(3, [("x", "f4"), ("y", "f4"), ("z", "f4")]), "vertex")],
                    text=True).write(str(ascii_path))
    text = ascii_path.read_bytes()
    (tmp_path / "abig.ply").write_bytes(text.replace(b"element vertex 3", b"element vertex 1000000000000"))
    _refused(tmp_path / "abig.ply", r"^the header announces 1000000000000 vertices of 3 values "
             r"\(at least 5999999999999 bytes of text\) after the header, the file holds 18$")
    (tmp_path / "alatin.ply").write_bytes(text[:-4] + b"\xe9 1\n")
    _refused(tmp_path / "alatin.ply", r"the ASCII data holds the non-ASCII byte 0xe9")


def test_ply_truncated_anywhere(tmp_path):
    data = _binary_ply(tmp_path).read_bytes()
    cut = tmp_path / "cut.ply"
    for size in [*range(1, _header_end(data) + 2), *range(_header_end(data) + 2, len(data), 97)]:
        cut.write_bytes(data[:size])
        _refused(cut)


# ----------------------------------------------------------------------------- NPY / NPZ


def test_npy_size_must_match_the_header(tmp_path):
    path = tmp_path / "a.npy"
    np.save(path, _points())
    data = path.read_bytes()
    header = len(data) - N * 24
    (tmp_path / "long.npy").write_bytes(data + b"\0" * 8)
    _refused(tmp_path / "long.npy", r"^the header announces an array of shape \(120, 3\) float64 \(2880 bytes\) "
             r"after the header, the file holds 2888$")
    (tmp_path / "short.npy").write_bytes(data[:-80])
    _refused(tmp_path / "short.npy", r"\(2880 bytes\) after the header, the file holds 2800$")
    for size in range(1, header + 3):
        (tmp_path / "cut.npy").write_bytes(data[:size])
        _refused(tmp_path / "cut.npy")
    neg = data.replace(b"(120, 3)", b"(-12, 3)")
    (tmp_path / "neg.npy").write_bytes(neg)
    _refused(tmp_path / "neg.npy", r"shape \(-12, 3\) has a negative dimension")
    (tmp_path / "obj.npy").write_bytes(data.replace(b"'<f8'", b"'|O' "))
    _refused(tmp_path / "obj.npy", r"^the array holds Python objects, not numbers$")
    np.save(tmp_path / "mask.npy", _points() > 0)
    _refused(tmp_path / "mask.npy", r"^the array holds booleans \(a mask\?\), not coordinates$")
    np.save(tmp_path / "complex.npy", _points() * 1j)
    _refused(tmp_path / "complex.npy", r"^the array holds complex128 values, not numbers$")
    np.savez(tmp_path / "mask.npz", points=_points() > 0)
    _refused(tmp_path / "mask.npz", r"^'points' has shape \(\d+, 3\) and dtype bool; expected \(n, 3\) numbers$")
    text = b"{'descr': '<f8', 'fortran_order': False, 'shape': " + b"(" * 3000 + b")" * 3000 + b"}\n"
    (tmp_path / "nest.npy").write_bytes(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text)
    _refused(tmp_path / "nest.npy", r"^not a valid NPY file \(")
    fortran = np.asfortranarray(_points())
    np.save(tmp_path / "f.npy", fortran)
    np.testing.assert_array_equal(read_points(tmp_path / "f.npy").points, fortran)


def test_npz_non_array_members_are_skipped(tmp_path):
    path = tmp_path / "a.npz"
    np.savez(path, points=_points(), label=np.arange(N))
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("meta.json", '{"units": "m"}')
        archive.writestr("README", "made by hand")
        archive.writestr("docs/", "")
    got = read_points(path)
    assert got.points.shape == (N, 3) and list(got.fields) == ["label"]
    pickled = tmp_path / "p.npz"
    np.savez(pickled, points=_points(), meta=np.array([{"a": 1}], dtype=object))
    assert read_points(pickled).fields == {}  # an object array is never unpickled, and is not per point
    np.savez(tmp_path / "q.npz", points=np.array([None] * 3, dtype=object))
    _refused(tmp_path / "q.npz", r"'points' holds Python objects \(pickled\), not numbers")


def test_npz_damaged_members(tmp_path):
    path = tmp_path / "a.npz"
    np.savez_compressed(path, points=_points())
    data = bytearray(path.read_bytes())
    bad_crc = bytearray(data)
    bad_crc[14] ^= 0xFF  # local header CRC
    central = data.rindex(b"PK\x01\x02")
    bad_crc[central + 16] ^= 0xFF  # and the directory's
    (tmp_path / "crc.npz").write_bytes(bytes(bad_crc))
    _refused(tmp_path / "crc.npz", r"the CRC-32 check fails for member 'points\.npy'")
    flipped = bytearray(data)
    flipped[60] ^= 0xFF  # inside the deflate stream
    (tmp_path / "flip.npz").write_bytes(bytes(flipped))
    _refused(tmp_path / "flip.npz", r"^not a valid NPZ file \(")
    encrypted = bytearray(data)
    encrypted[central + 8] |= 1
    (tmp_path / "enc.npz").write_bytes(bytes(encrypted))
    _refused(tmp_path / "enc.npz", r"^member 'points\.npy' is encrypted$")
    for size in range(4, len(data), 7):
        (tmp_path / "cut.npz").write_bytes(bytes(data[:size]))
        _refused(tmp_path / "cut.npz")
    (tmp_path / "offset.npz").write_bytes(bytes(data[:central]) + struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, 1, 1,
                                                                               46, 10**9, 0))
    _refused(tmp_path / "offset.npz", r"^not a valid NPZ file \(")
    # a member whose header disagrees with its size
    honest = _points()
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, honest)
    npy = buffer.getvalue().replace(b"(120, 3)", b"(121, 3)")
    _zip(tmp_path / "hdr.npz", [("points.npy", npy, 0, zlib.crc32(npy), len(npy))])
    _refused(tmp_path / "hdr.npz", r"^member 'points\.npy': the header announces an array of shape \(121, 3\) float64 "
             r"\(2904 bytes\) after the header, the archive's directory declares 2880$")
    # stored members: what the directory declares is what is stored
    _zip(tmp_path / "stored.npz", [("points.npy", npy, 0, zlib.crc32(npy), len(npy) + 24)])
    _refused(tmp_path / "stored.npz", r"stored uncompressed in \d+ bytes but declares \d+")


def test_npz_within_the_ratio_but_beyond_the_memory(tmp_path, monkeypatch):
    from heatcurv.io import arrays

    path = tmp_path / "a.npz"
    write_points(path, _points())
    monkeypatch.setattr(arrays, "_memory_budget", lambda: 5000)
    _refused(path, r"^the arrays need 3008 bytes once decompressed \(about 9024 bytes while read\), "
             r"more than the 5000 bytes of memory available$")
    monkeypatch.setattr(arrays, "_memory_budget", lambda: None)
    assert len(read_points(path)) == N


def test_bombs_and_huge_counts_in_a_child_process(tmp_path):
    """Files announcing far more than they hold: refused before allocating, under a 2 GB limit."""
    cases = {}

    def case(name, content, pattern):
        (tmp_path / name).write_bytes(content)
        cases[tmp_path / name] = pattern

    # NPZ: a member declaring 3.2 GB, compressed with deflate in a few kB
    rows = 134_217_728  # 3.2 GB of float64 triples
    header = _npy_header((rows, 3))
    stream, _, _ = _zeros_deflate(header, 4)
    _zip(tmp_path / "lying.npz", [("points.npy", stream, 8, 0, len(header) + rows * 24)])
    assert (tmp_path / "lying.npz").stat().st_size < 10_000
    cases[tmp_path / "lying.npz"] = (r"member 'points\.npy' declares 3\.22 GB uncompressed from \d+ bytes "
                                     r"\(\d+:1; at most 1100:1 is read\): a zip bomb or a damaged archive")
    # NPZ: a genuine 1000:1 member of 64 MiB that 40 directory entries share (overlapping zip bomb)
    header = _npy_header(((64 << 20) // 24, 3))
    stream, crc, size = _zeros_deflate(header, 64)
    _zip(tmp_path / "overlap.npz", [("points.npy", stream, 8, crc, size)], aliases=40)
    cases[tmp_path / "overlap.npz"] = (r"^cannot read \S+: the arrays declare 2\.\d+ GB uncompressed in a file of "
                                       r"[\d.]+ kB \(more than 200:1 over the archive")
    # NPZ: a genuine 1000:1 member of 1.2 GB: within the ratio, beyond the child's memory
    rows = (1200 << 20) // 24
    header = _npy_header((rows, 3))
    stream, crc, size = _zeros_deflate(header, 1200)
    size = len(header) + rows * 24
    _zip(tmp_path / "genuine.npz", [("points.npy", stream, 8, crc, size)])
    cases[tmp_path / "genuine.npz"] = r"the arrays declare 1\.\d+ GB uncompressed .*more than 200:1 over the archive"
    # NPY: shape (10**12, 3)
    np.save(tmp_path / "a.npy", _points())
    data = (tmp_path / "a.npy").read_bytes()
    case("huge.npy", data.replace(b"(120, 3)", b"(1000000000000, 3)", 1).replace(b" " * 10 + b"\n", b"\n", 1),
         r"shape \(1000000000000, 3\) float64 \(24000000000000 bytes\) after the header, the file holds 2880$")
    npy = _npy_header((10**12, 3)) + bytes(2880)
    _zip(tmp_path / "hugemember.npz", [("points.npy", npy, 0, zlib.crc32(npy), len(npy))])
    cases[tmp_path / "hugemember.npz"] = r"member 'points\.npy': the header announces an array of shape \(1000000000000"
    # PLY: element vertex 1000000000000
    ply = _binary_ply(tmp_path).read_bytes()
    case("huge.ply", ply.replace(b"element vertex 120", b"element vertex 1000000000000"),
         r"1000000000000 vertices of 27 bytes \(27000000000000 bytes\) after the header, the file holds 3240$")
    # OFF: counts of 1e12 and 1e23
    vertices = "".join(f"{x} {y} {z}\n" for x, y, z in _points(5))
    case("e12.off", f"OFF\n1000000000000 0 0\n{vertices}".encode(),
         r"truncated: the header announces 1000000000000 vertices, the file has 5 lines after line 2$")
    case("e23.off", f"OFF\n100000000000000000000000 0 0\n{vertices}".encode(),
         r"announces 100000000000000000000000 vertices")
    case("faces.off", f"OFF\n5 1000000000000 0\n{vertices}".encode(),
         r"the header announces 1000000000000 faces, the file has 0 lines after its 5 vertices$")
    case("pts.pts", f"1000000000000\n{vertices}".encode(),
         r"line 1: the count line says 1000000000000 points, 5 follow")

    results = _read_isolated(list(cases), limit=2 * GB)
    for path, pattern in cases.items():
        _assert_refused(results, path, pattern)


# ----------------------------------------------------------------------------- OFF, PTS, text


@pytest.mark.parametrize(
    "counts,pattern",
    [
        ("1e12 0 0", r"^line 2: '1e12' is not a vertex count \(a whole number\)$"),
        ("1e23 0 0", r"'1e23' is not a vertex count"),
        ("-5 0 0", r"^line 2: the vertex count -5 is negative$"),
        ("3.5 0 0", r"'3\.5' is not a vertex count"),
        ("3 -5 0", r"^line 2: the face count -5 is negative$"),
        ("3 3.5 0", r"'3\.5' is not a face count"),
        ("4 0 0", r"^truncated: the header announces 4 vertices, the file has 3 lines after line 2$"),
        ("3 1 0", r"^the header announces 1 face, the file has 0 lines after its 3 vertices$"),
    ],
)
def test_off_counts(tmp_path, counts, pattern):
    path = tmp_path / "m.off"
    path.write_text(f"OFF\n{counts}\n0 0 0\n1 0 0\n0 1 0\n")
    _refused(path, pattern)


def test_pts_count_lines_must_match_the_rows(tmp_path):
    rows = "".join(f"{x} {y} {z} 7\n" for x, y, z in _points(N))
    path = tmp_path / "a.pts"
    path.write_text(f"{N}\n{rows}")
    assert len(read_points(path)) == N
    path.write_text(f"{N}\n" + "".join(rows.splitlines(keepends=True)[:-1]))
    _refused(path, r"^line 1: the count line says 120 points, 119 follow$")
    path.write_text(f"{N}\n{rows}5\n1 2 3 4\n")
    _refused(path, r"^line 122: the count line says 5 points, 1 follow$")
    path.write_bytes(f"{N}\r\n{rows}".replace("\n", "\r\n").encode() + b"  \t\r\n\r\n")
    assert len(read_points(path)) == N


@pytest.mark.parametrize("ext", [".csv", ".xyz", ".txt", ".pts"])
def test_whitespace_only_lines_are_blank(tmp_path, ext):
    sep = "," if ext == ".csv" else " "
    rows = [sep.join(map(str, row)) for row in ([1, 2, 3], [4, 5, 6])]
    path = tmp_path / f"w{ext}"
    path.write_bytes(("x,y,z\r\n" if ext == ".csv" else "").encode()
                     + f"{rows[0]}\r\n \t \r\n{rows[1]}\r\n   \r\n\t".encode())
    np.testing.assert_array_equal(read_points(path).points, [[1, 2, 3], [4, 5, 6]])


def test_text_encodings(tmp_path):
    content = "x,y,z,température\r\n1,2,3,4\r\n5,6,7,8\r\n"
    for name, raw in [
        ("utf16.csv", content.encode("utf-16")),
        ("utf16be.csv", b"\xfe\xff" + content.encode("utf-16-be")),
        ("bom.csv", content.encode("utf-8-sig")),
        ("latin1.csv", content.encode("latin-1")),
    ]:
        (tmp_path / name).write_bytes(raw)
        got = read_points(tmp_path / name)
        np.testing.assert_array_equal(got.points, [[1, 2, 3], [5, 6, 7]])
        assert list(got.fields) == ["température"], name
    (tmp_path / "le.csv").write_bytes(content.encode("utf-16-le"))
    _refused(tmp_path / "le.csv",
             r"^binary data, not a text file \(UTF-16 without a byte-order mark\? save it as UTF-8\)$")
    (tmp_path / "bad16.csv").write_bytes(b"\xff\xfe" + content.encode("utf-16-le")[:-1])
    _refused(tmp_path / "bad16.csv", r"UTF-16 byte-order mark but is not UTF-16 text")
    far = "1 2 3\n" * 20000 + "4 5\x006\n"
    (tmp_path / "nul.xyz").write_bytes(far.encode())
    _refused(tmp_path / "nul.xyz", r"^binary data, not a text file$")
    for ext in (".off", ".obj"):
        (tmp_path / f"nul{ext}").write_bytes(b"OFF\n1 0 0\n0 0 \x000\n" if ext == ".off" else b"v 0 0 \x000\n")
        _refused(tmp_path / f"nul{ext}", r"^binary data, not a text file$")


# ----------------------------------------------------------------------------- random mutations


def _valid_files(tmp_path):
    """A small valid file of every non-LAS format."""
    points, colours = _points(), _colours()
    files = []
    for ext in (".ply", ".npz", ".csv", ".xyz", ".txt"):
        path = tmp_path / f"valid{ext}"
        write_points(path, points, {"mean": points[:, 0]}, colours=colours)
        files.append(path)
    ascii_ply = tmp_path / "ascii.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(np.ones(N, [("x", "f4"), ("y", "f4"), ("z", "f4")]), "vertex")],
                    text=True).write(str(ascii_ply))
    np.save(tmp_path / "valid.npy", points)
    np.savez_compressed(tmp_path / "deflate.npz", points=points, label=np.arange(N))
    rows = "".join(f"{x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in points)
    (tmp_path / "valid.pts").write_text(f"{N}\n" + rows.replace("\n", " 7 1 2 3\n"))
    (tmp_path / "valid.off").write_text(f"OFF\n{N} 1 0\n{rows}3 0 1 2\n")
    (tmp_path / "valid.obj").write_text("".join(f"v {line}\n" for line in rows.splitlines()) + "f 1 2 3\n")
    files += [ascii_ply, tmp_path / "valid.npy", tmp_path / "deflate.npz", tmp_path / "valid.pts",
              tmp_path / "valid.off", tmp_path / "valid.obj"]
    return files


def test_random_mutations_give_a_cloud_or_one_line(tmp_path):
    """Byte flips, insertions, deletions, truncations, appended bytes: read under the limit in a child."""
    rng = np.random.default_rng(2024)
    originals = _valid_files(tmp_path)
    for path in originals:
        assert len(read_points(path)) == N, path
    mutated = []
    for path in originals:
        data = path.read_bytes()
        for k in range(40):
            raw = bytearray(data)
            kind = k % 5
            at = int(rng.integers(0, len(raw)))
            if kind == 0:
                raw[at] = int(rng.integers(0, 256))
            elif kind == 1:
                raw[at:at] = bytes(rng.choice(list(b"0123456789-.e \n\xff\x00"), int(rng.integers(1, 12))))
            elif kind == 2:
                del raw[at : at + int(rng.integers(1, 40))]
            elif kind == 3:
                raw = raw[:at]
            else:
                raw += bytes(rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8))
            if not raw:
                continue
            out = tmp_path / f"m{k}_{path.stem}{path.suffix}"
            out.write_bytes(bytes(raw))
            mutated.append(out)
    results = _read_isolated(mutated, limit=2 * GB)
    bugs = {path: value for path, (kind, value) in results.items() if kind == "bug"}
    assert not bugs, bugs
    for path, (kind, value) in results.items():
        if kind == "error":
            assert "\n" not in value and value.startswith(f"cannot read {path}: "), value
            assert "Errno" not in value and "(MemoryError)" not in value, value
    assert os.path.exists(originals[0])


def test_an_npz_of_zeros_past_the_archive_ratio_is_refused(tmp_path):
    # a genuine deflate bomb: 32 MiB of zeros in about 32 kB (1000:1), which the member's
    # own ratio allows but no point cloud archive needs (before: read, 3 copies in memory)
    path = tmp_path / "zeros.npz"
    np.savez_compressed(path, points=np.zeros(((1 << 22) // 3, 3)))
    assert path.stat().st_size < 200_000
    with pytest.raises(HeatcurvError, match=r"more than 200:1 over the archive"):
        read_points(path)


def test_an_npz_of_real_points_with_constant_fields_is_read(tmp_path):
    # twenty constant float64 fields beside random points compress about 8:1 overall: read
    pts = np.random.default_rng(0).random((20000, 3))
    path = tmp_path / "fields.npz"
    np.savez_compressed(path, points=pts, **{f"f{k}": np.zeros(20000) for k in range(20)})
    assert read_points(path).points.shape == (20000, 3)


def test_an_npz_beyond_the_memory_available_is_refused(tmp_path, monkeypatch):
    # within every ratio, but three copies of its arrays would not fit (here: a budget of 1 MB)
    import heatcurv.io.arrays as arrays

    path = tmp_path / "big.npz"
    np.savez(path, points=np.random.default_rng(1).random((20000, 3)))
    monkeypatch.setattr(arrays, "_memory_budget", lambda: 1_000_000)
    with pytest.raises(HeatcurvError, match=r"the arrays need 480 kB once decompressed .* of memory available$"):
        read_points(path)


def test_counts_python_cannot_convert_are_refused_in_plain_words(tmp_path):
    # before: a count of a million digits escaped as "Exceeds the limit (4300 digits) for integer
    # string conversion" (OFF), and a 20-digit PTS count was taken for a data row
    off = tmp_path / "long.off"
    off.write_text("OFF\n" + "9" * 5000 + " 0 0\n0 0 0\n")
    with pytest.raises(HeatcurvError, match=r"line 2: the vertex count has 5000 digits$"):
        read_points(off)
    pts = tmp_path / "long.pts"
    rows = "\n".join(f"{k} {k % 7} {k % 5}" for k in range(10))
    pts.write_text("18446744073709551615\n" + rows + "\n")
    with pytest.raises(HeatcurvError, match=r"line 1: the count line says more than 10\*\*18 points, 10 follow$"):
        read_points(pts)
    pts.write_text("9" * 1_000_000 + "\n" + rows + "\n")
    with pytest.raises(HeatcurvError, match=r"the count line says more than 10\*\*18 points"):
        read_points(pts)


def test_a_long_bad_value_is_quoted_short(tmp_path):
    # before: the whole 300-character token was quoted (a 416-character message, fuzz seed 4277590463)
    path = tmp_path / "long.csv"
    path.write_text("x,y,z\n0,0,0\n1,0," + "7q" * 150 + "\n")
    with pytest.raises(HeatcurvError) as info:
        read_points(path)
    message = str(info.value)
    assert re.search(r"line 3: column 3 holds '(7q){20}'\.\.\., not a number$", message), message
    assert len(message) < 120 + len(str(path))


@pytest.mark.parametrize(
    "variant, mutator, seed, expected",
    [
        # regressions found by benchmarks/fuzz.py (seeds 1 and 2 of 400 per format)
        ("npy", "npy-header", 2457833082, r"not a valid NPY file \(the header is not a Python dictionary literal\)$"),
        ("npz", "special-run", 4219308783, r"not a valid NPZ file \(unsupported zip feature: zip file version"),
        ("ply-ascii-faces", "header-bytes", 2077071451, r"no x coordinate column \(columns: '\\x17', y, z,"),
        ("xyz", "header-bytes", 1903873274, r"no x/y/z coordinate column \(columns: .*'\\x86'"),
    ],
)
def test_fuzz_findings_read_as_one_plain_line(tmp_path, variant, mutator, seed, expected):
    from support import fuzz

    seeds = fuzz.seed_files(tmp_path)
    path = tmp_path / f"case{fuzz.VARIANTS[variant].ext}"
    path.write_bytes(fuzz.mutate(seeds[variant].read_bytes(), mutator, seed))
    with pytest.raises(HeatcurvError) as info:
        read_points(path)
    message = str(info.value)
    assert "\n" not in message and message.isprintable() and message.startswith(f"cannot read {path}: ")
    assert re.search(expected, message), message


def test_fields_float32_cannot_hold_stay_float64(tmp_path):
    # before: the mean curvature of a cloud spanning 1e100 (about 1e-100) was written as 0 and its
    # area (1e200) as inf in the default float32 PLY, silently
    pts = np.random.default_rng(0).random((50, 3)) * 1e100
    fields = {"mean": np.full(50, 1e-100), "area": np.full(50, 1e200), "ok": np.full(50, 0.5)}
    write_points(tmp_path / "out.ply", pts, fields)
    back = read_points(tmp_path / "out.ply")
    assert back.fields["mean"].dtype == np.float64 and back.fields["mean"][0] == 1e-100
    assert back.fields["area"][0] == 1e200
    assert back.fields["ok"].dtype == np.float32  # the others keep the compact default
    with pytest.raises(HeatcurvError, match=r"field 'mean' holds values float32 cannot represent"):
        write_points(tmp_path / "strict.ply", pts, fields, dtype="float32")
    assert not (tmp_path / "strict.ply").exists()
