"""The plan's memory model: each phase's workers are budgeted with that phase's halo, the survey's included."""

import numpy as np
import pytest
from tiles_helpers import read_fields

from heatcurv.errors import HeatcurvError
from heatcurv.tiles import plan
from heatcurv.tiles.plan import (
    DRIVER_MEMORY,
    CloudStats,
    Tiling,
    fitting_workers,
    halo_points,
    read_rows,
    worker_memory,
)


def _two_tiles():
    """A 40 x 10 x 1 slab of 4000 points cut into two 20 x 10 x 1 tiles of 2000 (uniform density 10 per m^3)."""
    tiling = Tiling((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (40, 10, 1), [(0, 0, 0, 20, 10, 1), (20, 0, 0, 40, 10, 1)],
                    [2000, 2000])
    stats = CloudStats(4000, 4000, (0.0, 0.0, 0.0), (40.0, 10.0, 1.0), (20.0, 5.0, 0.5))
    return tiling, stats


def test_halo_points_count_what_a_halo_box_adds_inside_the_cloud():
    tiling, stats = _two_tiles()
    # a halo of 5: each tile's box grows by 5 towards the other tile only (the cloud's box clips the rest),
    # 20 -> 25 along x: 2000 x 25 / 20 points
    assert halo_points(tiling, stats, 5.0).tolist() == [2500, 2500]
    # one halo per tile (the survey's are measured tile by tile); NaN is no halo
    assert halo_points(tiling, stats, [5.0, 0.0]).tolist() == [2500, 2000]
    assert halo_points(tiling, stats, float("nan")).tolist() == [2000, 2000]
    # a halo past the whole cloud: every point
    assert halo_points(tiling, stats, 100.0).tolist() == [4000, 4000]


def test_the_survey_halo_is_budgeted_as_the_tiles_halo_is():
    tiling, stats = _two_tiles()
    tiles_halo, survey_halo = 2.0, 10.0  # a survey's halo is the widest candidate's ball: wider
    tiles_points, survey_points = halo_points(tiling, stats, tiles_halo), halo_points(tiling, stats, survey_halo)
    assert survey_points.tolist() == [3000, 3000] and tiles_points.tolist() == [2200, 2200]
    # a budget holding the driver and two workers of the tiles' halo, but not two of the survey's
    budget = DRIVER_MEMORY + 2 * worker_memory(2200)
    assert budget < DRIVER_MEMORY + 2 * worker_memory(3000)
    assert fitting_workers(tiles_points, budget, 2, 2, 2000) == 2
    assert fitting_workers(survey_points, budget, 2, 2, 2000, "survey") == 1
    # each worker's estimate is the model's: overhead plus bytes per point of core and halo
    assert worker_memory(3000) == plan.WORKER_OVERHEAD + plan.BYTES_PER_POINT * 3000


def test_a_survey_halo_that_leaves_no_worker_is_an_error():
    tiling, stats = _two_tiles()
    budget = DRIVER_MEMORY + worker_memory(2500)
    assert fitting_workers(halo_points(tiling, stats, 5.0), budget, 2, 2, 2000, "survey") == 1
    with pytest.raises(HeatcurvError, match=r"a tile of about 3000 points \(core and halo, the survey\) needs about "
                                            r".*pass a smaller --tile-size \(now 2000\)"):
        fitting_workers(halo_points(tiling, stats, 10.0), budget, 2, 2, 2000, "survey")


def test_the_plan_holds_each_tiles_survey_halo_and_the_survey_runs_within_it(torus_file, tmp_path, monkeypatch):
    """compute_file decides the survey's halos before the survey, from each core, and budgets its workers with them."""
    from heatcurv.tiles import compute, driver

    phases = []
    real_run = driver._run

    def run(executor, workers, fn, specs, on_done, say, what, total):
        phases.append((fn.__name__, workers, {t: spec.get("halo") for t, spec in specs.items()}))
        return real_run(executor, workers, fn, specs, on_done, say, what, total)

    monkeypatch.setattr(driver, "_run", run)
    monkeypatch.setattr(driver, "ONE_ROUND_TILES", 2)  # the survey in two rounds (the default for 64+ tiles)
    out = tmp_path / "torus.ply"
    report = driver.compute_file(torus_file[0], out, tile_size=1200, tile_workers=2, scheduler="threads",
                                 max_memory="4G", keep_scratch=True)
    saved = driver.load_plan(report.scratch)
    tiling, stats = Tiling.from_json(saved["tiling"]), CloudStats(**{
        k: tuple(v) if isinstance(v, list) else v for k, v in saved["stats"].items()})
    expected = []
    for t in range(len(tiling.counts)):
        core, _ = read_rows(report.scratch, int(tiling.offsets[t]), int(tiling.offsets[t + 1]))
        expected.append(compute.survey_halo(core, stats, report.parameters["options"]))
    assert saved["survey_halos"] == expected
    # they are wider than the tiles' (the widest candidate against the chosen) and the keys' (one operator ball),
    # which the survey's first round got
    assert min(expected) > report.halo
    keys = [p for p in phases if p[0] == "run_keys"][0]
    assert [keys[2][t] for t in range(len(expected))] == saved["key_halos"]
    assert max(h / s for h, s in zip(saved["key_halos"], expected)) < 0.5
    # the same run with a model whose survey tiles no longer fit two at once runs the survey one at a time
    points = halo_points(tiling, stats, expected)
    tiles_points = halo_points(tiling, stats, report.halo)
    assert points.max() > tiles_points.max()
    per_point = 10_000
    budget = DRIVER_MEMORY + 2 * (plan.WORKER_OVERHEAD + per_point * int(tiles_points.max())) + 1
    assert budget < DRIVER_MEMORY + 2 * (plan.WORKER_OVERHEAD + per_point * int(points.max()))
    monkeypatch.setattr(plan, "BYTES_PER_POINT", per_point)
    phases.clear()
    again = driver.compute_file(torus_file[0], tmp_path / "again.ply", tile_size=1200, tile_workers=2,
                                scheduler="threads", max_memory=budget)
    assert [(name, workers) for name, workers, _ in phases] == [("run_keys", 1), ("run_centres", 1), ("run_tile", 2)]
    assert again.workers == 2
    first, second = read_fields(out), read_fields(tmp_path / "again.ply")  # the budget changes no value
    assert first.keys() == second.keys()
    for name in first:
        np.testing.assert_array_equal(first[name], second[name], err_msg=name)
