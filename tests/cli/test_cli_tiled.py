"""``heatcurv compute`` in tiles: the flags, the automatic choice, the same fields as in memory."""

import argparse
import subprocess
import sys

import numpy as np
import pytest

import heatcurv
from heatcurv.cli import tiled
from heatcurv.cli.console import Log
from heatcurv.io import read_points


def _run(*args):
    return subprocess.run([sys.executable, "-m", "heatcurv", *map(str, args)], capture_output=True, text=True,
                           timeout=300)


def test_compute_in_tiles_writes_the_in_memory_fields(tmp_path):
    sample = heatcurv.surfaces.Sphere().sample(4000, "random", seed=9)
    np.save(tmp_path / "sphere.npy", sample.points)
    out = _run("compute", tmp_path / "sphere.npy", "-o", tmp_path / "tiled.ply", "--tile-size", "1500", "-j", "2",
               "--scheduler", "threads", "-v")
    assert out.returncode == 0, out.stderr
    assert "tiled sphere.npy: 4000 points in " in out.stdout + out.stderr
    memory = _run("compute", tmp_path / "sphere.npy", "-o", tmp_path / "memory.ply")
    assert memory.returncode == 0, memory.stderr
    a, b = read_points(tmp_path / "tiled.ply"), read_points(tmp_path / "memory.ply")
    assert list(a.fields) == list(b.fields) == ["mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y",
                                                "d2z", "area", "reliable"]
    # float32 output: the tiles give the in-memory values to float32's rounding on this clean sphere
    assert np.allclose(a.normals, b.normals, atol=1e-6)
    assert np.allclose(a.fields["mean"], b.fields["mean"], rtol=1e-5)


def test_a_tight_budget_runs_in_this_process_and_below_the_minimum_is_refused(tmp_path):
    """700M holds no 400 MB worker process beside the driver's 600 MB (this was refused), but one tile at a time in
    the command's own process; below 630 MB no tile fits and the message names the least --max-memory."""
    np.save(tmp_path / "c.npy", heatcurv.surfaces.Sphere().sample(3000, "random", seed=1).points)
    out = _run("compute", tmp_path / "c.npy", "-o", tmp_path / "o.ply", "--tile-size", "1000", "--max-memory",
               "700M", "-j", "2", "-v")
    assert out.returncode == 0, out.stderr
    assert "1 at once (serial)" in out.stdout + out.stderr
    assert len(read_points(tmp_path / "o.ply").points) == 3000
    out = _run("compute", tmp_path / "c.npy", "-o", tmp_path / "p.ply", "--tile-size", "1000", "--max-memory", "600M")
    assert out.returncode != 0 and not (tmp_path / "p.ply").exists()
    assert "a memory budget of 629 MB is too small for a tiled run" in out.stderr
    assert "pass a --max-memory of at least 602M" in out.stderr


def test_features_are_refused_in_tiles(tmp_path):
    np.save(tmp_path / "c.npy", heatcurv.surfaces.Sphere().sample(3000, "random", seed=1).points)
    out = _run("compute", tmp_path / "c.npy", "-o", tmp_path / "o.ply", "--tile-size", "1000", "--features")
    assert out.returncode != 0 and "sharp features are computed in memory only" in out.stderr
    assert not (tmp_path / "o.ply").exists()
    out = _run("compute", tmp_path / "c.npy", "-o", tmp_path / "o.ply", "--max-memory", "3X")
    assert out.returncode == 2 and "expected a memory size such as 3G" in out.stderr


def test_j_caps_the_cores_of_a_tiled_run(monkeypatch, tmp_path):
    """-j 1: one tile at a time on one thread, not one worker process with every core's threads."""
    from heatcurv.cli.main import main
    from heatcurv.tiles import job

    shares = []

    def spy(threads, cpus, workers):
        shares.append((threads, workers, job_threads(threads, cpus, workers)))
        return shares[-1][-1]

    job_threads = job.task_threads
    monkeypatch.setattr(job, "task_threads", spy)
    np.save(tmp_path / "c.npy", heatcurv.surfaces.Sphere().sample(3000, "random", seed=1).points)
    assert main(["compute", str(tmp_path / "c.npy"), "-o", str(tmp_path / "o.ply"), "--tile-size", "1000", "-j", "1",
                 "-q"]) == 0
    # the worker process started while the driver tiles, which the survey and the tiles then use: one thread,
    # not -1 (all)
    assert shares == [(1, 1, 1)] * 3
    assert read_points(tmp_path / "o.ply").fields["mean"].shape == (3000,)


def test_tiles_when_the_cloud_does_not_fit(monkeypatch, tmp_path):
    from heatcurv.tiles import plan

    args = argparse.Namespace(input=tmp_path / "big.laz", tile_size=None, scheduler=None, scratch=None, resume=False,
                              max_memory=3 * 2**30)
    monkeypatch.setattr(plan, "in_memory_bytes", lambda path: (12_000_000, 17 * 10**9))
    assert tiled.wants_tiles(args, Log(quiet=True))
    monkeypatch.setattr(plan, "in_memory_bytes", lambda path: (1_000_000, 2 * 10**9))
    assert not tiled.wants_tiles(args, Log(quiet=True))
    assert tiled.wants_tiles(argparse.Namespace(**{**vars(args), "scheduler": "threads"}), Log(quiet=True))


@pytest.mark.parametrize("flag, value, problem", [("--tile-size", "10", "a tile must hold at least 1000 points"),
                                                  ("--scheduler", "mpi", "choose processes, threads, dask, serial")])
def test_bad_tile_flags(flag, value, problem, tmp_path):
    out = _run("compute", tmp_path / "c.npy", "-o", tmp_path / "o.ply", flag, value)
    assert out.returncode == 2 and problem in out.stderr


def test_a_tiled_run_writes_the_standard_errors_of_the_in_memory_run(tmp_path):
    points = heatcurv.surfaces.Sphere().sample(2000, "random", seed=9).points
    np.save(tmp_path / "sphere.npy", points)
    out = _run("compute", tmp_path / "sphere.npy", "-o", tmp_path / "tiled.ply", "--tile-size", "1000",
               "--fields", "default,errors", "--float64")
    assert out.returncode == 0, out.stderr
    written = read_points(tmp_path / "tiled.ply").fields
    memory = heatcurv.estimate(points)
    for name in ("mean_se", "k1_se", "k2_se", "gaussian_se", "normal_se"):
        np.testing.assert_allclose(written[name], getattr(memory, name), rtol=1e-12, err_msg=name)
