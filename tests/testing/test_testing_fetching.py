"""support._fetching: one download-check-extract-rename skeleton for every test-data cache."""

import hashlib
import json
import re

import pytest

from support._fetching import _MARKER, ScanDataUnavailable, fetch_into


def _archive(directory):
    path = directory / "archive.bin"
    path.write_bytes(b"pretend archive")
    return path


SHA = hashlib.sha256(b"pretend archive").hexdigest()


def _extract(archive, tree):
    (tree / "mesh.off").write_text("OFF\n0 0 0\n")
    return ["mesh.off"]


def _complete(directory):
    return (directory / _MARKER).is_file()


def _fetch(target, **changes):
    calls = []

    def download(directory):
        calls.append(directory)
        return _archive(directory)

    options = dict(what="test meshes", cache_name="test mesh", is_complete=_complete, download=download,
                   sha256=SHA, extract=_extract, record={"package": "demo"})
    options.update(changes)
    return fetch_into(target, **options), calls


def test_a_fetch_leaves_the_files_and_the_marker_and_nothing_else(tmp_path):
    target = tmp_path / "cache"
    path, calls = _fetch(target)
    assert path == target and len(calls) == 1
    assert sorted(p.name for p in target.iterdir()) == sorted([_MARKER, "mesh.off"])
    assert json.loads((target / _MARKER).read_text()) == {"package": "demo", "files": ["mesh.off"]}
    assert [p.name for p in tmp_path.iterdir()] == ["cache"]  # the work directory is gone
    _, again = _fetch(target)
    assert again == []  # a complete cache is not fetched again


def test_a_wrong_checksum_leaves_no_cache(tmp_path):
    target = tmp_path / "cache"
    with pytest.raises(ScanDataUnavailable, match="has SHA-256 .*, expected 0+"):
        _fetch(target, sha256="0" * 64)
    assert list(tmp_path.iterdir()) == []


def test_an_occupied_directory_is_refused_but_a_nested_cache_is_kept(tmp_path):
    target = tmp_path / "cache"
    target.mkdir()
    (target / "stray.txt").write_text("x")
    with pytest.raises(ScanDataUnavailable, match="not a complete test mesh cache"):
        _fetch(target)
    (target / "stray.txt").unlink()
    (target / "other-1.0").mkdir()
    (target / "other-1.0" / "kept.off").write_text("OFF")
    _fetch(target, nested=re.compile(r"other-\d+\.\d+"))
    assert _complete(target) and (target / "other-1.0" / "kept.off").is_file() and (target / "mesh.off").is_file()


def test_a_failing_download_says_what_failed(tmp_path):
    def download(directory):
        raise OSError("network unreachable")

    with pytest.raises(ScanDataUnavailable, match="fetching the test meshes into .* failed: network unreachable"):
        _fetch(tmp_path / "cache", download=download)
    assert list(tmp_path.iterdir()) == []


def _slow_fetch(target, log):
    """One test process's fetch (:func:`test_processes_fetching_together_download_once`)."""
    import time

    def download(directory):
        with open(log, "a") as out:
            out.write("download\n")
        time.sleep(0.5)  # long enough for the other process to arrive while this one holds the lock
        return _archive(directory)

    fetch_into(target, what="test meshes", cache_name="test mesh", is_complete=_complete, download=download,
               sha256=SHA, extract=_extract, record={"package": "demo"})


def test_processes_fetching_together_download_once(tmp_path):
    """Test workers that start together on a fresh machine: one downloads, the other finds the cache."""
    import multiprocessing

    target, log = tmp_path / "cache", tmp_path / "log.txt"
    context = multiprocessing.get_context("spawn")
    workers = [context.Process(target=_slow_fetch, args=(target, log)) for _ in range(2)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(60)
    assert [worker.exitcode for worker in workers] == [0, 0]
    assert log.read_text() == "download\n" and _complete(target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache", "log.txt"]
