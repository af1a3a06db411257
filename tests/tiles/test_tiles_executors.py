"""The executors: a process pool (with a killed worker), a Dask cluster in process, and `dask scheduler` + workers."""

import multiprocessing
import os
import socket
import subprocess
import sys
import time
from functools import partial
from pathlib import Path

import distributed  # the test extra installs dask[distributed]: these tests never skip
import numpy as np
import pytest
from tiles_helpers import ALL_FIELDS, read_fields

from heatcurv.errors import HeatcurvError
from heatcurv.tiles import compute_file, executors, job, tasks
from heatcurv.tiles.executors import SerialExecutor, open_executor
from heatcurv.tiles.job import task_threads
from heatcurv.tiles.tasks import FAULT_VARIABLE


def _same_output(a, b):
    fa, fb = read_fields(a), read_fields(b)
    assert list(fa) == list(fb)
    for name in fb:
        assert np.array_equal(fa[name], fb[name], equal_nan=True), name


def test_processes_retry_a_killed_worker_and_match_threads(torus_file, torus_threads, tmp_path, monkeypatch):
    marker = tmp_path / "killed"
    monkeypatch.setenv(FAULT_VARIABLE, f"kill:3:{marker}")  # the worker computing tile 3 dies once
    messages = []
    out = tmp_path / "processes.ply"
    report = compute_file(torus_file[0], out, tile_size=1200, tile_workers=2, scheduler="processes",
                          dtype="float64", fields=ALL_FIELDS, max_memory="4G", log=messages.append)
    assert marker.exists() and report.scheduler == "processes" and report.workers == 2
    assert any("a worker process died; restarting the pool" in m for m in messages)
    _same_output(out, torus_threads[0])


def test_one_worker_process_gets_the_run_s_threads_and_the_same_output(torus_file, torus_threads, tmp_path):
    # a budget or tile_workers that holds fewer worker processes than cores: each takes a share of the cores
    assert [task_threads(-1, 4, w) for w in (1, 2, 3, 4, 8)] == [4, 2, 1, 1, 1]
    assert [task_threads(1, 4, 1), task_threads(2, 8, 1), task_threads(6, 8, 2)] == [1, 2, 3]
    with executors.thread_environment(3):
        child = subprocess.run([sys.executable, "-c", "import os; print(os.environ['NUMBA_NUM_THREADS'])"],
                               capture_output=True, text=True, check=True)
    assert child.stdout.strip() == "3" and os.environ.get("NUMBA_NUM_THREADS") != "3"
    out = tmp_path / "one.ply"
    compute_file(torus_file[0], out, tile_size=1200, tile_workers=1, workers=2, scheduler="processes",
                 dtype="float64", fields=ALL_FIELDS, max_memory="4G")
    _same_output(out, torus_threads[0])


def test_dask_client_in_process(torus_file, torus_threads, tmp_path):
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None)
    out = tmp_path / "dask.ply"
    with cluster, distributed.Client(cluster) as client:
        report = compute_file(torus_file[0], out, tile_size=1200, scheduler=client, dtype="float64",
                              fields=ALL_FIELDS, max_memory="4G")
    assert report.scheduler == "dask client" and report.tiles == torus_threads[1].tiles
    _same_output(out, torus_threads[0])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_dask_scheduler_and_two_workers(torus_file, torus_threads, tmp_path):
    """`dask scheduler` and two `dask worker` processes on 127.0.0.1, as on a cluster (shared file system)."""
    dask = str(Path(sys.executable).parent / "dask")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    logs = open(tmp_path / "dask.log", "w")
    started = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                                stdout=logs, stderr=subprocess.STDOUT, env=env)]
    try:
        for _ in range(2):
            started.append(subprocess.Popen(
                [dask, "worker", address, "--nthreads", "1", "--memory-limit", "2GB", "--no-dashboard",
                 "--host", "127.0.0.1"], stdout=logs, stderr=subprocess.STDOUT, env=env))
        with distributed.Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        out = tmp_path / "cluster.ply"
        report = compute_file(torus_file[0], out, tile_size=1200, scheduler=address, dtype="float64",
                              fields=ALL_FIELDS, max_memory="4G")
        assert report.scheduler == f"dask at {address}" and report.workers >= 1
        _same_output(out, torus_threads[0])
    finally:
        for process in reversed(started):  # only the processes this test started, by their handles
            process.terminate()
        deadline = time.monotonic() + 20
        for process in started:
            try:
                process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                process.kill()
        logs.close()


def _worker_pid(barrier):
    barrier.wait(timeout=60)  # every task of the phase running at once: each in a worker of its own
    return os.getpid()


def _pids(pools, workers, manager):
    """The worker processes of one phase of ``workers`` tasks (the phase's executor from ``pools``)."""
    found, barrier = {}, manager.Barrier(workers)
    job.submit(partial(pools.open, "processes", budget=1 << 30), workers, _worker_pid,
               dict.fromkeys(range(workers), barrier), found.__setitem__, print, "task", workers)
    assert len(set(found.values())) == workers
    return set(found.values())


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_phases_asking_for_the_same_workers_share_their_processes():
    pools = executors.Pools()
    with multiprocessing.Manager() as manager:
        try:
            survey = _pids(pools, 2, manager)
            assert _pids(pools, 2, manager) == survey and os.getpid() not in survey  # the next phase: the same
            fewer = _pids(pools, 1, manager)  # other workers: a new pool, the old one shut down
            assert fewer.isdisjoint(survey) and not any(map(_alive, survey))
            with pytest.raises(RuntimeError, match="a tile failed"):
                with pools.open("processes", 1, 1 << 30):
                    raise RuntimeError("a tile failed")  # a failed phase (a broken pool, a task) closes its executor
            assert _pids(pools, 1, manager).isdisjoint(fewer) and not any(map(_alive, fewer))
        finally:
            pools.close()
    pools.close()  # closing twice is nothing


def test_serial_executor_and_errors(monkeypatch):
    future = SerialExecutor().submit(divmod, 7, 2)
    assert future.done() and future.result() == (3, 1)
    failed = SerialExecutor().submit(divmod, 1, 0)
    assert isinstance(failed.exception(), ZeroDivisionError)
    with pytest.raises(HeatcurvError, match="unknown scheduler 'mpi'"):
        with open_executor("mpi", 1, 1 << 30):
            pass
    monkeypatch.setattr(executors, "CONNECT_TIMEOUT", "2s")
    with pytest.raises(HeatcurvError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:"):
        with open_executor(f"tcp://127.0.0.1:{_free_port()}", 1, 1 << 30):
            pass


def _worker_environment():
    return {name: os.environ.get(name) for name in ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS")}


def test_local_dask_workers_keep_the_adaptive_malloc():
    """Dask's nannies would give each worker a fixed trim threshold (slower numpy temporaries); the rest is kept."""
    import dask

    key = "distributed.nanny.pre-spawn-environ"
    assert "MALLOC_TRIM_THRESHOLD_" in dask.config.get(key)  # Dask's default, which the local cluster leaves out
    with open_executor("dask", 1, 1 << 30) as (executor, slots, name):
        seen = executor.submit(_worker_environment).result(timeout=60)
    assert (name, slots) == ("dask", 1)
    assert seen == {"MALLOC_TRIM_THRESHOLD_": None, "OMP_NUM_THREADS": "1"}
    assert "MALLOC_TRIM_THRESHOLD_" in dask.config.get(key)  # the configuration is as it was


def test_every_task_hands_back_the_memory_it_freed(torus_file, torus_threads, tmp_path, monkeypatch):
    """Survey and tile tasks end with glibc's ``malloc_trim`` (a worker keeps only what it holds), same output."""
    tasks._malloc_trim()  # the real one runs (a no-op where there is no glibc)
    calls = []
    monkeypatch.setattr(tasks, "_malloc_trim", lambda: calls.append(1))
    out = tmp_path / "serial.ply"
    report = compute_file(torus_file[0], out, tile_size=1200, scheduler="serial", tile_workers=1,
                          dtype="float64", fields=ALL_FIELDS, max_memory="4G")
    assert report.tiles == 8 and len(calls) == 2 * report.tiles  # one survey and one tile task each
    _same_output(out, torus_threads[0])


def test_missing_dask_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(HeatcurvError, match=r'pip install "heatcurv\[dask\]"'):
        with open_executor("dask", 1, 1 << 30):
            pass


def test_the_survey_s_worker_processes_start_while_the_driver_tiles(torus_file, torus_threads, tmp_path, monkeypatch):
    # the pool the driver starts before tiling (its workers import heatcurv meanwhile) is the one the survey and
    # the tiles use: one pool for the whole run, the same output
    opened, started = [], []
    open_pool, start = executors.open_executor, executors.Pools.start

    def counting(scheduler, workers, *args, **kwargs):
        opened.append((scheduler, workers))
        return open_pool(scheduler, workers, *args, **kwargs)

    def starting(self, *args, **kwargs):
        started.append(args[:2])
        return start(self, *args, **kwargs)

    monkeypatch.setattr(executors, "open_executor", counting)
    monkeypatch.setattr(executors.Pools, "start", starting)
    out = tmp_path / "warm.ply"
    compute_file(torus_file[0], out, tile_size=1200, tile_workers=2, scheduler="processes", dtype="float64",
                 fields=ALL_FIELDS, max_memory="4G")
    assert started == [("processes", 2)] and opened == [("processes", 2)]
    _same_output(out, torus_threads[0])
    # nothing to start ahead for threads, the serial scheduler, or a cloud of one tile
    for scheduler, tile_size in (("threads", 1200), ("serial", 1200), ("processes", 10_000)):
        started.clear()
        compute_file(torus_file[0], tmp_path / f"{scheduler}.ply", tile_size=tile_size, tile_workers=2,
                     scheduler=scheduler, max_memory="4G")
        assert started == [], scheduler
