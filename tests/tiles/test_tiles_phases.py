"""The phases of a tiled run, one module each: the plan found again for a resume, the orientation phase only for
``outward``, the write phase's parameters in the output's report."""

import numpy as np
import pytest

import heatcurv.tiles.driver as driver
from heatcurv.errors import HeatcurvError
from heatcurv.tiles import compute_file, phase_orient, phase_plan, phase_write
from heatcurv.tiles.plan import TilePlan


@pytest.fixture(scope="module")
def kept(torus_file, tmp_path_factory):
    """The torus in tiles with its scratch kept: (output, report)."""
    out = tmp_path_factory.mktemp("phases") / "torus.ply"
    return out, compute_file(torus_file[0], out, tile_size=1500, scheduler="serial", keep_scratch=True)


def test_the_plan_phase_finds_its_plan_again_and_only_for_the_same_input_and_options(torus_file, kept, monkeypatch):
    import dataclasses
    from pathlib import Path

    from heatcurv.tiles.driver import _settle

    out, report = kept
    job = _settle(torus_file[0], out, "default", None, None, None, "serial", None, None, None, False, None, {})
    job = dataclasses.replace(job, work=Path(report.scratch))
    identity = phase_plan.identity_of(job, 1500, False)
    assert identity["version"] == phase_plan.PLAN_VERSION and identity["tile_size"] == 1500
    plan = phase_plan.find_plan(job, identity, 1500, None)
    assert isinstance(plan, TilePlan) and plan.tile_size == 1500 and len(plan.tiling.counts) == report.tiles
    assert plan.stats.count == 6000
    # other options: nothing to resume, and resume=True says so
    other = dict(identity, options="another options hash")
    with pytest.raises(HeatcurvError, match="nothing to resume"):
        phase_plan.find_plan(job, other, 1500, True)


def _spied(monkeypatch, name, function):
    """Replace the driver's phase ``name`` by a spy of ``function``; the list of what it returned."""
    calls = []

    def spy(*args):
        calls.append(function(*args))
        return calls[-1]

    monkeypatch.setattr(driver, name, spy)
    return calls


def test_the_orientation_phase_runs_for_outward_only(torus_file, tmp_path, monkeypatch):
    calls = _spied(monkeypatch, "orient_cloud", phase_orient.orient_cloud)
    outward = compute_file(torus_file[0], tmp_path / "out.ply", tile_size=1500, scheduler="serial")
    up = compute_file(torus_file[0], tmp_path / "up.ply", tile_size=1500, scheduler="serial", orient="up")
    (flips, report), (no_flips, no_report) = calls
    assert flips and report is not None and report["closed"] is True and outward.orientation is report
    assert no_flips is None and no_report is None and up.orientation is None
    assert outward.timings["orientation"] > 0 and up.timings["orientation"] == 0


def test_the_write_phase_writes_the_runs_parameters(torus_file, tmp_path, monkeypatch):
    from heatcurv.io import read_points

    calls = _spied(monkeypatch, "write", phase_write.write)
    out = tmp_path / "torus.ply"
    report = compute_file(torus_file[0], out, tile_size=1500, scheduler="serial")
    (params,) = calls
    assert params is report.parameters and params["tiled"] is True and params["tiles"] == report.tiles
    assert params["tile_size"] == 1500 and params["source"] == "torus.npy" and params["halo"] == report.halo
    cloud = read_points(out)
    assert cloud.points.shape == (6000, 3) and np.isfinite(cloud.fields["mean"]).all()


def test_cleanup_removes_stray_temporaries_and_keeps_finished_tiles(tmp_path):
    from heatcurv.tiles.phase_tiles import _cleanup

    (tmp_path / "tiles").mkdir()
    (tmp_path / "knn").mkdir()
    done, lists = tmp_path / "tiles" / "tile_00000.npz", tmp_path / "knn" / "knn_00000.npy"
    strays = [tmp_path / "tiles" / "tile_00001.npz.7.tmp.npz", tmp_path / "knn" / "knn_00001.npy.7.tmp.npy"]
    for path in (done, lists, *strays):
        path.write_bytes(b"x")
    message = _cleanup(tmp_path, keep_done=True)
    assert "1 finished tile(s) are kept" in message
    assert done.exists() and lists.exists() and not any(path.exists() for path in strays)
    assert _cleanup(tmp_path, keep_done=False) == "" and not tmp_path.exists()


def test_a_few_halo_points_of_another_object_do_not_join_it_to_the_tiles_piece():
    """A tile's seam pieces (connected components): five halo points of a far object have a spacing as long as
    the way to this tile's grid, so an edge must be short for both its ends to join them."""
    from heatcurv.tiles.compute import _patches

    grid = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0), [0.0]), axis=-1).reshape(-1, 3)
    far = np.array([[40.0, 0, 0], [40.5, 0, 0], [41.0, 0, 0], [40.0, 0.5, 0], [40.5, 0.5, 0]])
    points = np.vstack([grid, far])
    # each point's spacing as the tile measures it: the grid's 1; the far group's from its 10 nearest, mostly grid
    spacing = np.concatenate([np.ones(len(grid)), np.full(len(far), 15.0)])
    label = _patches(points, spacing, {})
    assert np.unique(label[:400]).size == 1 and np.unique(label[400:]).size == 1 and label[0] != label[400]
