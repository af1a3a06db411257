"""Atomic writes: a failing writer or library leaves nothing behind, ordinary permissions."""

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import plyfile
import pytest
from io_helpers import N, leftovers, make_cloud

import heatcurv.io as hio
from heatcurv import HeatcurvError
from heatcurv.io import SUPPORTED_WRITE, write_points
from heatcurv.io.atomic import STALE_AFTER, _host, atomic_write, remove_stale_temporaries, temporary_name_pattern


@pytest.fixture(scope="module")
def cloud():
    """Torus points far from the origin (UTM-like), with normals, colours and result-like fields."""
    return make_cloud()


@pytest.mark.parametrize("ext", SUPPORTED_WRITE)
def test_failing_write_leaves_nothing(tmp_path, monkeypatch, cloud, ext):
    points, normals, colors, fields = cloud
    path = tmp_path / f"out{ext}"

    def broken(stream, output, target):
        stream.write(b"partial output " * 100)
        raise RuntimeError("disk on fire")

    monkeypatch.setitem(hio._WRITERS, ext, broken)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_points(path, points, fields, normals=normals)
    assert leftovers(tmp_path) == []

    # an existing output survives a failed rewrite unchanged
    path.write_bytes(b"previous result")
    with pytest.raises(RuntimeError):
        write_points(path, points, fields)
    assert leftovers(tmp_path) == [path.name] and path.read_bytes() == b"previous result"


def test_failing_library_write_leaves_nothing(tmp_path, monkeypatch, cloud):
    points = cloud[0]

    def write_then_fail(self, stream):
        stream.write(b"ply\n")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(plyfile.PlyData, "write", write_then_fail)
    with pytest.raises(HeatcurvError, match=r"cannot write .*out\.ply: No space left on device"):
        write_points(tmp_path / "out.ply", points)
    assert leftovers(tmp_path) == []
    with pytest.raises(HeatcurvError, match=r"field 'mean' has shape"):
        write_points(tmp_path / "out.las", points, {"mean": np.zeros(N - 1)})
    assert leftovers(tmp_path) == []


def test_written_file_has_ordinary_permissions(tmp_path):
    umask = os.umask(0o022)
    os.umask(umask)
    write_points(tmp_path / "out.csv", np.zeros((2, 3)))
    assert (tmp_path / "out.csv").stat().st_mode & 0o777 == 0o666 & ~umask


def test_atomic_write_is_public_and_replaces_only_when_complete(tmp_path):
    path = tmp_path / "image.png"
    atomic_write(path, lambda stream: stream.write(b"first"))
    assert path.read_bytes() == b"first" and leftovers(tmp_path) == [path.name]

    def fail(stream):
        stream.write(b"half")
        raise KeyboardInterrupt  # BaseException too: the temporary file is removed

    with pytest.raises(KeyboardInterrupt):
        atomic_write(path, fail)
    assert path.read_bytes() == b"first" and leftovers(tmp_path) == [path.name]


def test_check_writable_refuses_at_once(tmp_path, monkeypatch):
    from heatcurv.io import check_writable

    assert check_writable(tmp_path / "new.ply") == tmp_path / "new.ply"
    (tmp_path / "a_file").write_text("not a directory")
    cases = [
        (tmp_path / "missing" / "out.ply", "the directory .*missing does not exist"),
        (tmp_path / "a_file" / "out.ply", ".*a_file is not a directory"),  # works as root too
        (tmp_path, "it is a directory"),
    ]
    for path, message in cases:
        with pytest.raises(HeatcurvError, match=rf"^cannot write {re.escape(str(path))}: {message}$"):
            check_writable(path)
    assert leftovers(tmp_path) == ["a_file"]  # the probe file is removed


def test_read_only_output_file_is_refused_before_writing(tmp_path, monkeypatch):
    from heatcurv.io import check_writable

    path = tmp_path / "kept.ply"
    path.write_bytes(b"a result the user protected")
    real_access = os.access
    # os.access as for an ordinary user (root may write anything): the file is read-only
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(path) else real_access(p, mode))
    with pytest.raises(HeatcurvError, match=r"kept\.ply: the file exists and is read-only"):
        check_writable(path)
    with pytest.raises(HeatcurvError, match=r"kept\.ply: the file exists and is read-only"):
        write_points(path, np.zeros((3, 3)))
    assert path.read_bytes() == b"a result the user protected" and leftovers(tmp_path) == ["kept.ply"]


def test_unwritable_directory_is_refused(tmp_path, monkeypatch):
    import tempfile

    from heatcurv.io import check_writable

    # a directory where no file can be created (read-only file system, ...): works as root
    def read_only_fs(*args, **kwargs):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(tempfile, "NamedTemporaryFile", read_only_fs)
    with pytest.raises(HeatcurvError, match=r"out\.ply: cannot create a file in .* \(Read-only file system\)$"):
        check_writable(tmp_path / "out.ply")
    monkeypatch.undo()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(tmp_path) else real_access(p, mode))
    with pytest.raises(HeatcurvError, match=rf"out\.ply: no permission to create files in {re.escape(str(tmp_path))}$"):
        write_points(tmp_path / "out.ply", np.zeros((3, 3)))
    assert leftovers(tmp_path) == []


def test_read_only_permissions_are_refused(tmp_path, monkeypatch):
    # permission bits, seen through os.access (as root, CI's user, chmod alone would not stop a write)
    from heatcurv.io import check_writable

    path = tmp_path / "kept.ply"
    path.write_bytes(b"protected")
    path.chmod(0o444)
    real_access = os.access
    read_only = {str(path)} if os.geteuid() == 0 else set()
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) in read_only else real_access(p, mode))
    with pytest.raises(HeatcurvError, match=r"the file exists and is read-only"):
        check_writable(path)
    assert path.read_bytes() == b"protected"


# ----------------------------------------------------------------- killed writers and their temporary files

_CHILD = """
import sys, time
from pathlib import Path
from heatcurv.cli.main import Terminated, signals_as_interrupts
from heatcurv.io.atomic import STALE_AFTER, _host, atomic_write, remove_stale_temporaries, temporary_name_pattern

def slow(stream):
    stream.write(b"x" * (16 << 20))  # 16 MB written, then the writer waits to be killed
    stream.flush()
    print("writing", flush=True)
    # short sleeps: a signal that lands between the print and a long sleep's system call would wait for the
    # whole sleep (Python runs its handler between bytecodes); here it runs within 0.1 s
    for _ in range(1200):
        time.sleep(0.1)

try:
    with signals_as_interrupts():
        atomic_write(Path(sys.argv[1]), slow)
except Terminated as exc:
    sys.exit(128 + exc.signum)
"""


def _start_writer(path):
    """A child process in the middle of atomic_write(path): returns once its temporary file holds 16 MB."""
    child = subprocess.Popen([sys.executable, "-c", _CHILD, str(path)], stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "writing"
    return child


def _temporaries(directory):
    return sorted(p.name for p in directory.iterdir() if p.name.endswith(".tmp"))


def test_terminated_writer_leaves_no_temporary_file(tmp_path):
    path = tmp_path / "result.ply"
    path.write_bytes(b"previous result")
    child = _start_writer(path)
    (temporary,) = _temporaries(tmp_path)
    assert temporary_name_pattern(path.name).fullmatch(temporary)["pid"] == str(child.pid)
    child.send_signal(signal.SIGTERM)
    assert child.wait(timeout=60) == 128 + signal.SIGTERM
    assert leftovers(tmp_path) == [path.name] and path.read_bytes() == b"previous result"


def test_killed_writers_temporary_file_is_removed_by_the_next_write(tmp_path):
    path = tmp_path / "result.ply"
    path.write_bytes(b"previous result")
    child = _start_writer(path)
    child.kill()  # SIGKILL: no cleanup can run
    child.wait(timeout=60)
    (temporary,) = _temporaries(tmp_path)
    assert (tmp_path / temporary).stat().st_size == 16 << 20 and path.read_bytes() == b"previous result"
    atomic_write(path, lambda stream: stream.write(b"new result"))
    assert leftovers(tmp_path) == [path.name] and path.read_bytes() == b"new result"


def test_only_stale_temporary_files_are_removed(tmp_path):
    path = tmp_path / "result.ply"
    host = _host()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    try:
        names = {
            "dead": f".result.ply.heatcurv-{host}-{dead.pid}-abc123_x.tmp",
            "live": f".result.ply.heatcurv-{host}-{live.pid}-abc123_x.tmp",
            "mine": f".result.ply.heatcurv-{host}-{os.getpid()}-abc123_x.tmp",
            "other host, recent": f".result.ply.heatcurv-elsewhere.example-{dead.pid}-abc123_x.tmp",
            "other host, old": f".result.ply.heatcurv-far-away-{dead.pid}-abc123_x.tmp",
            "other target": f".other.ply.heatcurv-{host}-{dead.pid}-abc123_x.tmp",
            "not ours": f".result.ply.{dead.pid}.tmp",
        }
        for name in names.values():
            (tmp_path / name).write_bytes(b"partial")
        old = time.time() - STALE_AFTER - 3600
        os.utime(tmp_path / names["other host, old"], (old, old))
        removed = remove_stale_temporaries(path)
        assert sorted(p.name for p in removed) == sorted([names["dead"], names["other host, old"]])
        kept = {key for key, name in names.items() if (tmp_path / name).exists()}
        assert kept == {"live", "mine", "other host, recent", "other target", "not ours"}
        # atomic_write does the same before it writes, and leaves the live process's file alone
        atomic_write(path, lambda stream: stream.write(b"result"))
        assert (tmp_path / names["live"]).exists() and path.read_bytes() == b"result"
    finally:
        live.kill()
        live.wait()


def test_temporary_name_names_heatcurv_the_host_and_the_process(tmp_path):
    seen = []

    def look(stream):
        seen.append(Path(stream.name).name)
        stream.write(b"data")

    atomic_write(tmp_path / "my-file.v2.png", look)
    match = temporary_name_pattern("my-file.v2.png").fullmatch(seen[0])
    assert match and match["host"] == _host() and match["pid"] == str(os.getpid())
    assert seen[0].startswith(".my-file.v2.png.heatcurv-") and seen[0].endswith(".tmp")


_LAZ_CHILD = """
import os, signal, sys, threading
import laspy
import numpy as np
from pathlib import Path
from heatcurv.cli.main import Terminated, signals_as_interrupts
from heatcurv.io import write_points

write = laspy.LasData.write

def write_then_signal(self, *args, **kwargs):
    # the signal arrives 0.3 s into laspy's write, while lazrs compresses (about 2 s for 6 M points)
    threading.Timer(0.3, os.kill, (os.getpid(), getattr(signal, sys.argv[2]))).start()
    return write(self, *args, **kwargs)

laspy.LasData.write = write_then_signal
points = np.random.default_rng(0).random((6_000_000, 3)) * 100.0
try:
    with signals_as_interrupts():
        write_points(Path(sys.argv[1]), points)
except Terminated as exc:
    sys.exit(128 + exc.signum)
except KeyboardInterrupt:
    sys.exit(130)
print("finished", flush=True)
"""


@pytest.mark.parametrize("name, status", [("SIGTERM", 143), ("SIGINT", 130)])
def test_an_interrupted_laz_write_is_an_interruption_not_a_write_error(tmp_path, name, status):
    # lazrs calls back into Python to write: the handler's exception came back as "IoError: Failed to call
    # write", a write error (exit 2) instead of the interruption
    path = tmp_path / "result.laz"
    path.write_bytes(b"previous result")
    child = subprocess.Popen([sys.executable, "-c", _LAZ_CHILD, str(path), name], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    out, err = child.communicate(timeout=120)
    assert child.returncode == status, (out, err)
    assert "Failed to call write" not in err
    assert leftovers(tmp_path) == [path.name] and path.read_bytes() == b"previous result"
